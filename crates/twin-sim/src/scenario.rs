//! Scenarios: what a simulated trial is, as a user writes it in TOML, and its
//! validation into the plan the simulator runs.
//!
//! [`Scenario`] mirrors the file (`config/scenarios/README.md` explains every
//! key); unknown keys are errors, and every section but the trial's duration
//! and its path (or manual propeller commands) has defaults. Loading is in two
//! steps: TOML into [`Scenario`] (type errors name the key and line), then
//! [`Scenario::validate`] into a [`Plan`] (range and consistency errors name the
//! key, e.g. `sensors.gnss.position_sigma_m`). Angles are degrees and shaft
//! speeds rpm in the file; the plan holds SI units.

use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};
use toml::value::{Datetime, Offset};
use twin_core::geodesy::{LatLon, LocalFrame, compass_deg_to_rad};
use twin_core::sample::RADPS_PER_RPM;

use crate::control::AutopilotTuning;
use crate::disturbance::{DisturbanceSettings, UPDATES_PER_CORRELATION_TIME};
use crate::environment::{CurrentModel, WindModel};
use crate::otter::{OtterParams, VesselScales};
use crate::sensors::{GnssSettings, HeadingSettings, PropellerSettings, YawRateSettings};

/// Why a scenario cannot be loaded or run.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// The text is not TOML, or a key is unknown, missing or of the wrong
    /// type. The message names the key and shows the line.
    #[error("invalid scenario TOML: {0}")]
    Toml(#[from] toml::de::Error),
    /// A value is out of range or inconsistent with another one.
    #[error("scenario key `{key}`: {reason}")]
    Invalid {
        /// The dotted path of the offending key, e.g. `path.waypoints[2]`.
        key: String,
        /// What is wrong with it.
        reason: String,
    },
    /// The scenario could not be written as TOML.
    #[error("scenario cannot be written as TOML: {0}")]
    Serialize(#[from] toml::ser::Error),
    /// The scenario file could not be read.
    #[error("cannot read scenario {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
}

fn invalid(key: impl Into<String>, reason: impl Into<String>) -> ScenarioError {
    ScenarioError::Invalid {
        key: key.into(),
        reason: reason.into(),
    }
}

/// A simulated trial, as written in a scenario file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Short name, e.g. `s-manoeuvre_new-broken`.
    #[serde(default)]
    pub name: String,
    /// Free text.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub description: String,
    /// Length of the trial, s.
    pub duration_s: f64,
    /// Seed of every random stream (sensor noise, disturbance).
    #[serde(default = "default_seed")]
    pub seed: u64,
    /// UTC time of the trial's start (a TOML date-time with `Z` or an offset).
    #[serde(default = "default_start_time")]
    pub start_time: Datetime,
    /// Largest integration step, s.
    #[serde(default = "default_step_s")]
    pub step_s: f64,
    /// Origin of the local north/east frame.
    #[serde(default)]
    pub origin: Origin,
    /// Way-point mode: the path and the speed. Exactly one of `path` and
    /// `manual` is given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub path: Option<PathSpec>,
    /// Manual mode: propeller speed commands over time, no autopilot.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub manual: Option<ManualSpec>,
    /// Where and how the craft starts; defaults to the first way-point,
    /// heading for the second, at the desired speed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub initial: Option<InitialSpec>,
    /// Autopilot tuning.
    #[serde(default)]
    pub control: ControlSpec,
    /// The two propellers and their losses.
    #[serde(default)]
    pub propellers: PropellersSpec,
    /// Water current; none if absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub current: Option<CurrentSpec>,
    /// Wind; none if absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wind: Option<WindSpec>,
    /// Random disturbance (waves, wakes, gusts); none if absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub disturbance: Option<DisturbanceSpec>,
    /// Sensor settings.
    #[serde(default)]
    pub sensors: SensorsSpec,
    /// The simulated craft's departures from the Otter's numbers (none if
    /// absent): the vessel a twin's model is wrong about.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vessel: Option<VesselSpec>,
}

/// Scale factors on the Otter's numbers (1 = the Otter). A twin whose model
/// is the Otter's is then wrong about the vessel by these factors; the
/// trust tests draw them.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VesselSpec {
    /// Rigid-body mass and inertia (hull and payload).
    pub mass_scale: f64,
    /// Added mass and added inertia.
    pub added_mass_scale: f64,
    /// Linear surge damping `X_u` (hull resistance; fouling raises it).
    pub surge_damping_scale: f64,
    /// Linear sway damping `Y_v`.
    pub sway_damping_scale: f64,
    /// Linear and quadratic yaw damping.
    pub yaw_damping_scale: f64,
    /// Cross-flow drag.
    pub crossflow_drag_scale: f64,
    /// Both propellers' thrust coefficients, ahead and astern (the same
    /// factor on both sides: a difference between the sides is a loss).
    pub thrust_scale: f64,
    /// Every length of the hull: length, pontoon beam, draft, the centre of
    /// gravity's offset and the radii of gyration (the yaw inertias by its
    /// square). A hull `s` times as long wants `mass_scale` and
    /// `added_mass_scale` near `s^3`.
    pub size_scale: f64,
    /// The propellers' lateral distance from the centre line.
    pub propeller_arm_scale: f64,
}

impl Default for VesselSpec {
    fn default() -> Self {
        Self {
            mass_scale: 1.0,
            added_mass_scale: 1.0,
            surge_damping_scale: 1.0,
            sway_damping_scale: 1.0,
            yaw_damping_scale: 1.0,
            crossflow_drag_scale: 1.0,
            thrust_scale: 1.0,
            size_scale: 1.0,
            propeller_arm_scale: 1.0,
        }
    }
}

fn default_seed() -> u64 {
    1
}

fn default_start_time() -> Datetime {
    // 2022-05-20T10:00:00Z, spring 2022 when the seed's trials were run.
    "2022-05-20T10:00:00Z".parse().unwrap_or(Datetime {
        date: None,
        time: None,
        offset: None,
    })
}

fn default_step_s() -> f64 {
    0.01
}

/// Origin of the local frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Origin {
    /// Latitude, degrees north.
    pub lat_deg: f64,
    /// Longitude, degrees east.
    pub lon_deg: f64,
}

impl Default for Origin {
    /// Near Alesund, Norway, where the seed's trials were run.
    fn default() -> Self {
        Self {
            lat_deg: 62.47,
            lon_deg: 6.15,
        }
    }
}

/// The path in way-point mode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PathSpec {
    /// Desired speed over ground, m/s.
    pub speed_mps: f64,
    /// Way-points in order; the craft starts at (or near) the first.
    pub waypoints: Vec<Waypoint>,
}

/// A way-point: either `north_m`/`east_m` in the local frame or
/// `lat_deg`/`lon_deg`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Waypoint {
    /// Metres north of the origin.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub north_m: Option<f64>,
    /// Metres east of the origin.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub east_m: Option<f64>,
    /// Latitude, degrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lat_deg: Option<f64>,
    /// Longitude, degrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lon_deg: Option<f64>,
}

impl Waypoint {
    /// A way-point in the local frame.
    pub fn north_east(north_m: f64, east_m: f64) -> Self {
        Self {
            north_m: Some(north_m),
            east_m: Some(east_m),
            ..Self::default()
        }
    }
}

/// Manual mode: a schedule of shaft speed commands.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ManualSpec {
    /// Commands in time order; each holds until the next. Before the first
    /// the shafts are commanded to stop.
    pub commands: Vec<ManualCommand>,
}

/// One manual command.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ManualCommand {
    /// Elapsed time from which the command holds, s.
    pub time_s: f64,
    /// Port shaft speed, rpm (saturated to the shaft's limits).
    pub port_rpm: f64,
    /// Starboard shaft speed, rpm (saturated to the shaft's limits).
    pub starboard_rpm: f64,
}

/// The craft's initial state. Missing values default as described.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct InitialSpec {
    /// North, m (default: the first way-point, or 0).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub north_m: Option<f64>,
    /// East, m (default: the first way-point, or 0).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub east_m: Option<f64>,
    /// Heading, degrees (default: toward the second way-point, or 0).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub heading_deg: Option<f64>,
    /// Surge speed, m/s, with the shafts turning as needed to hold it in
    /// still water (default: the path's speed, or 0 in manual mode).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub speed_mps: Option<f64>,
}

/// Autopilot and guidance tuning.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ControlSpec {
    /// Rate of the control loop, Hz.
    pub rate_hz: f64,
    /// LOS lookahead distance, m.
    pub lookahead_m: f64,
    /// Radius of the circle of acceptance around each way-point, m.
    pub acceptance_radius_m: f64,
    /// Integral LOS gain (0 = plain LOS); compensates a cross current.
    pub ilos_gain: f64,
    /// Largest turn rate of the heading reference, deg/s.
    pub max_turn_rate_deg_s: f64,
    /// Largest angular acceleration of the heading reference, deg/s^2.
    pub max_turn_accel_deg_s2: f64,
    /// Natural frequency of the heading reference model, rad/s.
    pub reference_bandwidth_radps: f64,
    /// Closed-loop natural frequency of the heading PID, rad/s.
    pub heading_bandwidth_radps: f64,
    /// Closed-loop natural frequency of the speed PI, rad/s.
    pub speed_bandwidth_radps: f64,
}

impl Default for ControlSpec {
    fn default() -> Self {
        Self {
            rate_hz: 10.0,
            lookahead_m: 6.0,
            acceptance_radius_m: 5.0,
            ilos_gain: 0.0,
            max_turn_rate_deg_s: 12.0,
            max_turn_accel_deg_s2: 8.0,
            reference_bandwidth_radps: 0.8,
            heading_bandwidth_radps: 1.5,
            speed_bandwidth_radps: 0.8,
        }
    }
}

/// Both propellers.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PropellersSpec {
    /// The port propeller (y = -0.395 m).
    pub port: PropellerSpec,
    /// The starboard propeller (y = +0.395 m).
    pub starboard: PropellerSpec,
}

/// One propeller: what it is, and the loss of effectiveness it has.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PropellerSpec {
    /// What is fitted (`original`, `new`, `broken`, ...): a label only.
    pub label: String,
    /// Loss of effectiveness, 0..1: effective thrust `(1 - loss) T`.
    pub loss: f64,
    /// Elapsed time at which the loss starts, s (0 = from the start).
    pub onset_s: f64,
}

impl Default for PropellerSpec {
    fn default() -> Self {
        Self {
            label: "original".to_string(),
            loss: 0.0,
            onset_s: 0.0,
        }
    }
}

/// A uniform water current.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CurrentSpec {
    /// Mean speed, m/s.
    pub speed_mps: f64,
    /// Direction the water flows toward, degrees clockwise from north.
    pub toward_deg: f64,
    /// Rate at which that direction turns, deg/s (positive clockwise).
    #[serde(default)]
    pub rotation_deg_s: f64,
    /// Amplitude of a sinusoidal speed variation, m/s (at most `speed_mps`).
    #[serde(default)]
    pub speed_amplitude_mps: f64,
    /// Period of the speed variation, s.
    #[serde(default = "default_current_period_s")]
    pub speed_period_s: f64,
}

fn default_current_period_s() -> f64 {
    600.0
}

/// A uniform wind and the craft's windage.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WindSpec {
    /// True wind speed, m/s.
    pub speed_mps: f64,
    /// Direction the wind comes from, degrees clockwise from north.
    pub from_deg: f64,
    /// Frontal projected area above water, m^2 (default 0.3: the Otter's
    /// 1.08 m beam by about 0.3 m of hull, box and mast).
    #[serde(default = "default_frontal_area_m2")]
    pub frontal_area_m2: f64,
    /// Lateral projected area above water, m^2 (default 0.5).
    #[serde(default = "default_lateral_area_m2")]
    pub lateral_area_m2: f64,
    /// Surge coefficient `c_x` (default 0.6; Fossen: 0.5-0.9).
    #[serde(default = "default_c_x")]
    pub c_x: f64,
    /// Sway coefficient `c_y` (default 0.8; Fossen: 0.7-0.95).
    #[serde(default = "default_c_y")]
    pub c_y: f64,
    /// Yaw coefficient `c_n` (default 0.08; Fossen: 0.05-0.2).
    #[serde(default = "default_c_n")]
    pub c_n: f64,
    /// Air density, kg/m^3.
    #[serde(default = "default_air_density")]
    pub air_density_kgpm3: f64,
}

fn default_frontal_area_m2() -> f64 {
    0.3
}
fn default_lateral_area_m2() -> f64 {
    0.5
}
fn default_c_x() -> f64 {
    0.6
}
fn default_c_y() -> f64 {
    0.8
}
fn default_c_n() -> f64 {
    0.08
}
fn default_air_density() -> f64 {
    1.225
}

/// Random disturbance from waves, boat wakes and wind gusts: a force in
/// surge and in sway and a moment in yaw on the hull (body frame), each an
/// independent first-order Gauss-Markov process (exponentially correlated
/// coloured noise) with its own standard deviation and a common correlation
/// time. See [`crate::disturbance`] for the process and its integration.
///
/// # Default: a small USV in sheltered harbour water
/// [`Default`] is the level chosen for the seed's trials at the Sunnmore
/// Museum dock in Alesund, sheltered water with short, low chop and light,
/// gusty wind:
///
/// - `surge_force_sigma_n = 3.0`, `sway_force_sigma_n = 4.0`. Wind gusts: a
///   4 m/s harbour wind with 20 % turbulence (0.8 m/s) on the Otter's windage
///   (0.3 m^2 frontal, 0.5 m^2 lateral, `c_x = 0.6`, `c_y = 0.8`) at 1.5 m/s
///   makes about 1 N of fluctuating force on each axis. Chop of 2-5 cm and
///   boat wakes add the slowly varying part of the wave loads, of the same
///   order (the wave-frequency part, at about 0.5 Hz, mostly moves the hull
///   with the water by a few centimetres and is not what this models). Sway
///   is larger than surge: the side presents more area to wind and waves.
///   For scale: 3 N is 1.3 % of the Otter's 2 x 119.7 N bollard thrust and
///   2.6 % of the 116 N it needs at the trials' 1.5 m/s (`-X_u u`, with
///   `X_u = -77.55 N s/m`). Open loop (fixed shaft speeds) it makes the
///   surge speed wander with a standard deviation of about 0.031 m/s
///   (`(sigma / M11) tau sqrt(T / (T + tau))`, `tau = M11 / |X_u| = 1.10 s`),
///   2 % of the trial speed; sway speed about 0.02 m/s.
/// - `yaw_moment_sigma_nm = 0.5`: the sway force acting about 0.12 m off the
///   body origin (the CG is 0.15 m ahead of it), and the gusts' own moment of
///   about 0.4 N m (`c_n = 0.08` over the 2 m hull).
/// - `correlation_s = 2.0`: gusts last a few seconds, and the chop's wave
///   groups and the wakes pass in 1-3 s; 2 s is also above the hull's own
///   time constants (about 1 s), so the hull follows the disturbance rather
///   than averaging it out.
///
/// Under the autopilot on the shipped paths (60-120 s runs, several seeds)
/// this gives a speed over ground wandering by about 0.015 m/s (standard
/// deviation), a heading by 1.2-2 deg and a yaw rate by 0.6-1.1 deg/s, the
/// track by 0.05-0.1 m across a straight line and 0.2 m on the S, and the
/// shafts by about 20 rpm: a craft visibly, but mildly, pushed about. The
/// heading wander comes mostly from the sway force through the hull's Munk
/// moment (`(a22 - a11) u v`, about 2 N m for 0.02 m/s of sway at 1.5 m/s),
/// not from the yaw moment itself.
///
/// A scenario without the section has no disturbance; every scenario file
/// shipped in `config/scenarios` spells this level out.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DisturbanceSpec {
    /// Stationary standard deviation of the surge force, N.
    pub surge_force_sigma_n: f64,
    /// Stationary standard deviation of the sway force, N.
    pub sway_force_sigma_n: f64,
    /// Stationary standard deviation of the yaw moment, N m.
    pub yaw_moment_sigma_nm: f64,
    /// Correlation time of all three, s: the autocorrelation is
    /// `sigma^2 e^{-|tau| / correlation_s}`. At least 0.1 s; the
    /// disturbance is updated every twentieth of it.
    pub correlation_s: f64,
}

impl Default for DisturbanceSpec {
    /// Sheltered harbour water; see the type's documentation.
    fn default() -> Self {
        Self {
            surge_force_sigma_n: 3.0,
            sway_force_sigma_n: 4.0,
            yaw_moment_sigma_nm: 0.5,
            correlation_s: 2.0,
        }
    }
}

impl DisturbanceSpec {
    /// No disturbance: every sigma zero (the correlation time at its
    /// default). Running it is the same as leaving the section out.
    pub fn calm() -> Self {
        Self {
            surge_force_sigma_n: 0.0,
            sway_force_sigma_n: 0.0,
            yaw_moment_sigma_nm: 0.0,
            ..Self::default()
        }
    }

    /// The standard deviations `[surge N, sway N, yaw N m]`.
    pub fn sigmas(&self) -> [f64; 3] {
        [
            self.surge_force_sigma_n,
            self.sway_force_sigma_n,
            self.yaw_moment_sigma_nm,
        ]
    }

    /// Whether every sigma is zero.
    pub fn is_calm(&self) -> bool {
        self.sigmas().iter().all(|s| *s == 0.0)
    }

    /// Standard deviation of the acceleration each component gives on its
    /// own axis, `F / m`: `[surge m/s^2, sway m/s^2, yaw rad/s^2]`, for the
    /// mass matrix diagonal `[M11 kg, M22 kg, M33 kg m^2]` (rigid body plus
    /// added mass; [`OtterParams::mass_matrix_diagonal`]).
    pub fn acceleration_sigma(&self, mass_matrix_diag: [f64; 3]) -> [f64; 3] {
        let sigma = self.sigmas();
        std::array::from_fn(|i| sigma[i] / mass_matrix_diag[i])
    }

    /// The equivalent white-noise acceleration density of the disturbance,
    /// for an estimator's process noise:
    /// `[surge m^2/s^3, sway m^2/s^3, yaw rad^2/s^3]`.
    ///
    /// A Gauss-Markov force of standard deviation `F` and correlation time
    /// `T` has the autocorrelation `F^2 e^{-|tau|/T}` and the two-sided power
    /// spectral density `2 F^2 T / (1 + (omega T)^2)`; below its corner
    /// frequency `1 / (2 pi T)` it is white noise of density `2 F^2 T`. On a
    /// body of (added-)mass `m` the acceleration `F / m` is then white of
    /// density
    ///
    /// ```text
    /// q = 2 sigma_a^2 T,   sigma_a = F / m
    /// ```
    ///
    /// i.e. the intensity of the continuous white noise `w` driving a
    /// velocity state, `E[w(t) w(s)] = q delta(t - s)`: over a filter step
    /// `dt` it adds about `q dt` to the velocity's variance. `m` is the
    /// diagonal of the mass matrix: for the Otter of docs/model.md section 6,
    /// `[85.5, 162.5, 42.65]` ([`Self::otter_acceleration_density`]). This
    /// neglects the sway-yaw coupling `M23 = 12.25 kg m`, which in the
    /// simulator also turns the sway force into yaw acceleration; see
    /// [`Self::acceleration_density_matrix`] for the exact value.
    ///
    /// For the default: `[4.92e-3, 2.42e-3, 5.50e-4]`.
    pub fn acceleration_density(&self, mass_matrix_diag: [f64; 3]) -> [f64; 3] {
        let sigma_a = self.acceleration_sigma(mass_matrix_diag);
        sigma_a.map(|s| 2.0 * s * s * self.correlation_s)
    }

    /// [`Self::acceleration_density`] with the simulator's Otter (docs/model.md
    /// section 6, mass matrix diagonal `[85.5, 162.5, 42.65]`).
    pub fn otter_acceleration_density(&self) -> [f64; 3] {
        self.acceleration_density(OtterParams::default().mass_matrix_diagonal())
    }

    /// The low-frequency two-sided spectral density matrix of the body
    /// accelerations `[u', v', r']` the disturbance causes through the full
    /// mass matrix, `M^-1 diag(2 F_i^2 T) M^-T`. Its diagonal is what
    /// [`Self::acceleration_density`] approximates; the off-diagonal terms
    /// are the correlation between the axes that the coupling creates. A
    /// singular `mass_matrix` gives zeros.
    pub fn acceleration_density_matrix(&self, mass_matrix: &Matrix3<f64>) -> Matrix3<f64> {
        let m_inv = mass_matrix.try_inverse().unwrap_or_else(Matrix3::zeros);
        let s = Matrix3::from_diagonal(
            &Vector3::from(self.sigmas()).map(|f| 2.0 * f * f * self.correlation_s),
        );
        m_inv * s * m_inv.transpose()
    }
}

/// All sensors.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SensorsSpec {
    /// The GNSS receiver.
    pub gnss: GnssSpec,
    /// The heading sensor (off by default: the seed's Otter logged none).
    pub heading: HeadingSpec,
    /// The shaft tachometers.
    pub propellers: PropellerSensorSpec,
    /// A rate gyro or rate-of-turn sensor (off by default).
    pub yaw_rate: YawRateSpec,
}

/// Rate-gyro settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct YawRateSpec {
    /// Whether yaw rates are produced.
    pub enabled: bool,
    /// Rate, Hz.
    pub rate_hz: f64,
    /// Noise, standard deviation, deg/s.
    pub sigma_deg_s: f64,
    /// Constant bias (reported minus true), deg/s.
    pub bias_deg_s: f64,
    /// Scale factor (reported over true, before the bias): a gyro's scale
    /// error.
    pub scale: f64,
}

impl Default for YawRateSpec {
    fn default() -> Self {
        Self {
            enabled: false,
            rate_hz: 10.0,
            sigma_deg_s: 0.2,
            bias_deg_s: 0.0,
            scale: 1.0,
        }
    }
}

/// GNSS settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GnssSpec {
    /// Whether fixes are produced.
    pub enabled: bool,
    /// Fix rate, Hz.
    pub rate_hz: f64,
    /// Position noise, standard deviation per axis (north, east), m.
    pub position_sigma_m: f64,
    /// Correlation time of the position noise, s (0 = white).
    pub position_correlation_s: f64,
    /// Velocity noise, standard deviation per axis, m/s (= SOG noise).
    pub sog_sigma_mps: f64,
    /// Below this SOG no COG is reported, m/s.
    pub cog_min_sog_mps: f64,
    /// Stamp = true time of the sample minus this, s (negative: later).
    pub latency_s: f64,
    /// Antenna position in the body frame.
    pub lever_arm: LeverArm,
    /// Reported SOG = scale x true SOG.
    pub sog_scale: f64,
    /// HDOP reported with every fix; negative for none.
    pub hdop: f64,
}

impl Default for GnssSpec {
    fn default() -> Self {
        Self {
            enabled: true,
            rate_hz: 5.0,
            position_sigma_m: 0.3,
            position_correlation_s: 0.0,
            sog_sigma_mps: 0.05,
            cog_min_sog_mps: 0.2,
            latency_s: 0.0,
            lever_arm: LeverArm::default(),
            sog_scale: 1.0,
            hdop: 0.9,
        }
    }
}

/// A point in the body frame.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LeverArm {
    /// Forward of the body origin (midships), m.
    pub x_m: f64,
    /// To starboard of the centre line, m.
    pub y_m: f64,
}

/// Heading sensor settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HeadingSpec {
    /// Whether heading is produced.
    pub enabled: bool,
    /// Rate, Hz.
    pub rate_hz: f64,
    /// Noise, standard deviation, degrees.
    pub sigma_deg: f64,
    /// Constant offset (reported minus true), degrees.
    pub offset_deg: f64,
}

impl Default for HeadingSpec {
    fn default() -> Self {
        Self {
            enabled: false,
            rate_hz: 5.0,
            sigma_deg: 0.5,
            offset_deg: 0.0,
        }
    }
}

/// Shaft tachometer settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PropellerSensorSpec {
    /// Whether measured and commanded shaft speeds are produced.
    pub enabled: bool,
    /// Rate, Hz.
    pub rate_hz: f64,
    /// Noise of the measured speeds, standard deviation, rpm.
    pub sigma_rpm: f64,
}

impl Default for PropellerSensorSpec {
    fn default() -> Self {
        Self {
            enabled: true,
            rate_hz: 10.0,
            sigma_rpm: 2.0,
        }
    }
}

/// How the craft is driven.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Drive {
    /// Way-point mode.
    Waypoints {
        /// Way-points, north/east m.
        waypoints: Vec<[f64; 2]>,
        /// Desired speed over ground, m/s.
        speed_mps: f64,
    },
    /// Manual shaft commands: (from elapsed s, [port, starboard] rad/s).
    Manual(Vec<(f64, [f64; 2])>),
}

/// A loss of effectiveness that starts at a time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct LossStep {
    pub loss: f64,
    pub onset_s: f64,
}

impl LossStep {
    pub fn at(&self, elapsed_s: f64) -> f64 {
        if elapsed_s >= self.onset_s {
            self.loss
        } else {
            0.0
        }
    }
}

/// A validated scenario in SI units: what [`crate::simulate`] runs.
#[derive(Debug, Clone)]
pub struct Plan {
    pub(crate) name: String,
    pub(crate) duration_s: f64,
    pub(crate) seed: u64,
    pub(crate) start_unix_s: f64,
    pub(crate) step_s: f64,
    pub(crate) frame: LocalFrame,
    pub(crate) drive: Drive,
    /// Initial north, east, heading (rad), surge speed (m/s).
    pub(crate) initial: [f64; 4],
    pub(crate) control_period_s: f64,
    pub(crate) lookahead_m: f64,
    pub(crate) acceptance_radius_m: f64,
    pub(crate) ilos_gain: f64,
    pub(crate) tuning: AutopilotTuning,
    pub(crate) losses: [LossStep; 2],
    pub(crate) current: CurrentModel,
    pub(crate) wind: Option<WindModel>,
    /// `None` if absent or calm.
    pub(crate) disturbance: Option<DisturbanceSettings>,
    pub(crate) gnss: Option<GnssSettings>,
    pub(crate) heading: Option<HeadingSettings>,
    pub(crate) propellers: Option<PropellerSettings>,
    pub(crate) yaw_rate: Option<YawRateSettings>,
    pub(crate) vessel: OtterParams,
}

impl Plan {
    /// The local frame of the trial.
    pub fn frame(&self) -> LocalFrame {
        self.frame
    }

    /// Unix time of the trial's start, s.
    pub fn start_unix_s(&self) -> f64 {
        self.start_unix_s
    }

    /// Way-points in the local frame (north, east), m; empty in manual mode.
    pub fn waypoints_m(&self) -> &[[f64; 2]] {
        match &self.drive {
            Drive::Waypoints { waypoints, .. } => waypoints,
            Drive::Manual(_) => &[],
        }
    }
}

fn finite(key: &str, value: f64) -> Result<f64, ScenarioError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(invalid(
            key,
            format!("must be a finite number, got {value}"),
        ))
    }
}

fn positive(key: &str, value: f64) -> Result<f64, ScenarioError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(invalid(key, format!("must be greater than 0, got {value}")))
    }
}

fn non_negative(key: &str, value: f64) -> Result<f64, ScenarioError> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(invalid(key, format!("must be 0 or more, got {value}")))
    }
}

/// Longest trial, s (one day: about 9 million integration steps).
const MAX_DURATION_S: f64 = 86_400.0;

/// Shortest correlation time of the disturbance, s.
const MIN_CORRELATION_S: f64 = 0.1;

/// Highest rate of any sensor or of the control loop, Hz.
const MAX_RATE_HZ: f64 = 1000.0;

/// The period of a rate, which must be positive and at most [`MAX_RATE_HZ`].
fn period_of(key: &str, rate_hz: f64) -> Result<f64, ScenarioError> {
    let rate_hz = positive(key, rate_hz)?;
    if rate_hz > MAX_RATE_HZ {
        return Err(invalid(
            key,
            format!("{rate_hz} Hz is above the limit of {MAX_RATE_HZ} Hz"),
        ));
    }
    Ok(1.0 / rate_hz)
}

/// Seconds since the Unix epoch of a TOML date-time with an offset.
fn unix_seconds(key: &str, dt: &Datetime) -> Result<f64, ScenarioError> {
    let (Some(date), Some(time), Some(offset)) = (dt.date, dt.time, dt.offset) else {
        return Err(invalid(
            key,
            format!("`{dt}` needs a date, a time and a UTC offset, e.g. 2022-05-20T10:00:00Z"),
        ));
    };
    let days = days_since_unix_epoch(i64::from(date.year), date.month, date.day);
    let offset_min = match offset {
        Offset::Z => 0,
        Offset::Custom { minutes } => i64::from(minutes),
    };
    let seconds = days * 86_400
        + i64::from(time.hour) * 3600
        + i64::from(time.minute) * 60
        + i64::from(time.second)
        - offset_min * 60;
    Ok(seconds as f64 + f64::from(time.nanosecond) * 1e-9)
}

fn is_leap_year(year: i64) -> bool {
    (year % 4 == 0 && year % 100 != 0) || year % 400 == 0
}

/// Days from 1970-01-01 to the given date of the proleptic Gregorian calendar.
fn days_since_unix_epoch(year: i64, month: u8, day: u8) -> i64 {
    const DAYS_BEFORE_MONTH: [i64; 12] = [0, 31, 59, 90, 120, 151, 181, 212, 243, 273, 304, 334];
    let whole_years: i64 = if year >= 1970 {
        (1970..year)
            .map(|y| if is_leap_year(y) { 366 } else { 365 })
            .sum()
    } else {
        -(year..1970)
            .map(|y| if is_leap_year(y) { 366 } else { 365 })
            .sum::<i64>()
    };
    let month_index = usize::from(month.clamp(1, 12) - 1);
    let leap_day = i64::from(month > 2 && is_leap_year(year));
    whole_years + DAYS_BEFORE_MONTH[month_index] + leap_day + i64::from(day) - 1
}

impl Scenario {
    /// Parses and validates a scenario from TOML text.
    pub fn from_toml_str(text: &str) -> Result<Self, ScenarioError> {
        let scenario: Scenario = toml::from_str(text)?;
        scenario.validate()?;
        Ok(scenario)
    }

    /// Reads, parses and validates a scenario file.
    pub fn from_path(path: &Path) -> Result<Self, ScenarioError> {
        let text = std::fs::read_to_string(path).map_err(|source| ScenarioError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_toml_str(&text)
    }

    /// Writes the scenario as TOML (reads back to an equal scenario).
    pub fn to_toml_string(&self) -> Result<String, ScenarioError> {
        Ok(toml::to_string_pretty(self)?)
    }

    /// A scenario in way-point mode along `waypoints` at `speed_mps`, with
    /// every other setting at its default.
    pub fn waypoint_mode(
        name: &str,
        duration_s: f64,
        speed_mps: f64,
        waypoints: Vec<Waypoint>,
    ) -> Self {
        Self {
            name: name.to_string(),
            description: String::new(),
            duration_s,
            seed: default_seed(),
            start_time: default_start_time(),
            step_s: default_step_s(),
            origin: Origin::default(),
            path: Some(PathSpec {
                speed_mps,
                waypoints,
            }),
            manual: None,
            initial: None,
            control: ControlSpec::default(),
            propellers: PropellersSpec::default(),
            current: None,
            wind: None,
            disturbance: None,
            sensors: SensorsSpec::default(),
            vessel: None,
        }
    }

    /// A scenario in manual mode with the given commands, starting at rest
    /// at the origin heading north, every other setting at its default.
    pub fn manual_mode(name: &str, duration_s: f64, commands: Vec<ManualCommand>) -> Self {
        Self {
            path: None,
            manual: Some(ManualSpec { commands }),
            ..Self::waypoint_mode(name, duration_s, 0.0, Vec::new())
        }
    }

    /// Checks every value and converts the scenario to SI units.
    pub fn validate(&self) -> Result<Plan, ScenarioError> {
        let duration_s = positive("duration_s", self.duration_s)?;
        if duration_s > MAX_DURATION_S {
            return Err(invalid(
                "duration_s",
                format!("{duration_s} s is longer than the limit of one day ({MAX_DURATION_S} s)"),
            ));
        }
        let step_s = positive("step_s", self.step_s)?;
        if step_s > 0.1 {
            return Err(invalid(
                "step_s",
                format!(
                    "{step_s} s is too long for the propeller lag of 0.1 s; use 0.05 s or less"
                ),
            ));
        }
        let start_unix_s = unix_seconds("start_time", &self.start_time)?;
        let frame = LocalFrame::new(LatLon {
            lat_deg: self.origin.lat_deg,
            lon_deg: self.origin.lon_deg,
        })
        .map_err(|e| invalid("origin", e.to_string()))?;

        let drive = match (&self.path, &self.manual) {
            (Some(_), Some(_)) => {
                return Err(invalid(
                    "manual",
                    "give either [path] or [manual], not both",
                ));
            }
            (None, None) => {
                return Err(invalid(
                    "path",
                    "missing: give [path] (way-points) or [manual]",
                ));
            }
            (Some(path), None) => self.validate_path(path, &frame)?,
            (None, Some(manual)) => Self::validate_manual(manual)?,
        };

        let initial = self.validate_initial(&drive)?;

        let control = self.validate_control()?;
        let losses = self.validate_losses()?;
        let current = self.validate_current()?;
        let vessel = match &self.vessel {
            None => OtterParams::default(),
            Some(v) => OtterParams::default().scaled(&v.validated()?),
        };
        let wind = self.validate_wind(vessel.length_m)?;

        let disturbance = match &self.disturbance {
            None => None,
            Some(d) => Self::validate_disturbance(d)?,
        };

        let (gnss, heading, propellers, yaw_rate) = self.validate_sensors()?;

        Ok(Plan {
            name: self.name.clone(),
            duration_s,
            seed: self.seed,
            start_unix_s,
            step_s,
            frame,
            drive,
            initial,
            control_period_s: control.period_s,
            lookahead_m: control.lookahead_m,
            acceptance_radius_m: control.acceptance_radius_m,
            ilos_gain: control.ilos_gain,
            tuning: control.tuning,
            losses,
            current,
            wind,
            disturbance,
            gnss,
            heading,
            propellers,
            yaw_rate,
            vessel,
        })
    }

    /// The autopilot's settings, validated.
    fn validate_control(&self) -> Result<ControlSettings, ScenarioError> {
        let c = &self.control;
        let period_s = period_of("control.rate_hz", c.rate_hz)?;
        let lookahead_m = positive("control.lookahead_m", c.lookahead_m)?;
        let acceptance_radius_m = positive("control.acceptance_radius_m", c.acceptance_radius_m)?;
        let ilos_gain = non_negative("control.ilos_gain", c.ilos_gain)?;
        let tuning = AutopilotTuning {
            heading_bandwidth_radps: positive(
                "control.heading_bandwidth_radps",
                c.heading_bandwidth_radps,
            )?,
            reference_bandwidth_radps: positive(
                "control.reference_bandwidth_radps",
                c.reference_bandwidth_radps,
            )?,
            max_turn_rate_radps: positive("control.max_turn_rate_deg_s", c.max_turn_rate_deg_s)?
                .to_radians(),
            max_turn_accel_radps2: positive(
                "control.max_turn_accel_deg_s2",
                c.max_turn_accel_deg_s2,
            )?
            .to_radians(),
            speed_bandwidth_radps: positive(
                "control.speed_bandwidth_radps",
                c.speed_bandwidth_radps,
            )?,
        };
        Ok(ControlSettings {
            period_s,
            lookahead_m,
            acceptance_radius_m,
            ilos_gain,
            tuning,
        })
    }

    /// Each propeller's loss and its onset, port then starboard.
    fn validate_losses(&self) -> Result<[LossStep; 2], ScenarioError> {
        let mut losses = [LossStep {
            loss: 0.0,
            onset_s: 0.0,
        }; 2];
        for (i, (side, spec)) in [
            ("port", &self.propellers.port),
            ("starboard", &self.propellers.starboard),
        ]
        .into_iter()
        .enumerate()
        {
            let loss_key = format!("propellers.{side}.loss");
            if !(spec.loss.is_finite() && (0.0..=1.0).contains(&spec.loss)) {
                return Err(invalid(
                    loss_key,
                    format!("must be in 0..1, got {}", spec.loss),
                ));
            }
            let onset_s = non_negative(&format!("propellers.{side}.onset_s"), spec.onset_s)?;
            losses[i] = LossStep {
                loss: spec.loss,
                onset_s,
            };
        }
        Ok(losses)
    }

    /// The current, none if not given.
    fn validate_current(&self) -> Result<CurrentModel, ScenarioError> {
        let Some(cur) = &self.current else {
            return Ok(CurrentModel::none());
        };
        let speed_mps = non_negative("current.speed_mps", cur.speed_mps)?;
        let amplitude = non_negative("current.speed_amplitude_mps", cur.speed_amplitude_mps)?;
        if amplitude > speed_mps {
            return Err(invalid(
                "current.speed_amplitude_mps",
                format!(
                    "{amplitude} exceeds current.speed_mps {speed_mps}: the speed would turn negative"
                ),
            ));
        }
        Ok(CurrentModel {
            speed_mps,
            toward_rad: compass_deg_to_rad(finite("current.toward_deg", cur.toward_deg)?),
            rotation_radps: finite("current.rotation_deg_s", cur.rotation_deg_s)?.to_radians(),
            speed_amplitude_mps: amplitude,
            speed_period_s: positive("current.speed_period_s", cur.speed_period_s)?,
        })
    }

    /// The wind, none if not given; `length_m` is the hull's.
    fn validate_wind(&self, length_m: f64) -> Result<Option<WindModel>, ScenarioError> {
        let Some(w) = &self.wind else {
            return Ok(None);
        };
        Ok(Some(WindModel {
            speed_mps: non_negative("wind.speed_mps", w.speed_mps)?,
            from_rad: compass_deg_to_rad(finite("wind.from_deg", w.from_deg)?),
            frontal_area_m2: non_negative("wind.frontal_area_m2", w.frontal_area_m2)?,
            lateral_area_m2: non_negative("wind.lateral_area_m2", w.lateral_area_m2)?,
            length_m,
            c_x: finite("wind.c_x", w.c_x)?,
            c_y: finite("wind.c_y", w.c_y)?,
            c_n: finite("wind.c_n", w.c_n)?,
            air_density_kgpm3: positive("wind.air_density_kgpm3", w.air_density_kgpm3)?,
        }))
    }

    /// The disturbance's settings, `None` if every sigma is zero.
    fn validate_disturbance(
        d: &DisturbanceSpec,
    ) -> Result<Option<DisturbanceSettings>, ScenarioError> {
        let sigma = [
            non_negative("disturbance.surge_force_sigma_n", d.surge_force_sigma_n)?,
            non_negative("disturbance.sway_force_sigma_n", d.sway_force_sigma_n)?,
            non_negative("disturbance.yaw_moment_sigma_nm", d.yaw_moment_sigma_nm)?,
        ];
        let correlation_s = positive("disturbance.correlation_s", d.correlation_s)?;
        if correlation_s < MIN_CORRELATION_S {
            return Err(invalid(
                "disturbance.correlation_s",
                format!(
                    "{correlation_s} s is below {MIN_CORRELATION_S} s: the hull (time constants \
                     about 1 s) cannot tell so short a correlation from white noise, and the \
                     simulation would update the disturbance every {} s",
                    correlation_s / UPDATES_PER_CORRELATION_TIME
                ),
            ));
        }
        Ok((!d.is_calm()).then_some(DisturbanceSettings {
            sigma,
            correlation_s,
        }))
    }

    fn validate_path(&self, path: &PathSpec, frame: &LocalFrame) -> Result<Drive, ScenarioError> {
        let speed_mps = positive("path.speed_mps", path.speed_mps)?;
        if speed_mps > 3.0 {
            return Err(invalid(
                "path.speed_mps",
                format!("{speed_mps} m/s is beyond the Otter's top speed of about 3 m/s"),
            ));
        }
        if path.waypoints.len() < 2 {
            return Err(invalid("path.waypoints", "needs at least two way-points"));
        }
        let mut waypoints: Vec<[f64; 2]> = Vec::with_capacity(path.waypoints.len());
        for (i, wp) in path.waypoints.iter().enumerate() {
            let key = format!("path.waypoints[{i}]");
            let ne = match (wp.north_m, wp.east_m, wp.lat_deg, wp.lon_deg) {
                (Some(n), Some(e), None, None) => [finite(&key, n)?, finite(&key, e)?],
                (None, None, Some(lat), Some(lon)) => {
                    let ll = LatLon {
                        lat_deg: lat,
                        lon_deg: lon,
                    };
                    if !ll.is_valid() {
                        return Err(invalid(
                            key,
                            format!("{lat}, {lon} is not a latitude/longitude"),
                        ));
                    }
                    let p = frame.to_local(ll);
                    if p.north_m.hypot(p.east_m) > 50_000.0 {
                        return Err(invalid(key, "is more than 50 km from the origin"));
                    }
                    [p.north_m, p.east_m]
                }
                _ => {
                    return Err(invalid(
                        key,
                        "give either north_m and east_m, or lat_deg and lon_deg",
                    ));
                }
            };
            if let Some(prev) = waypoints.last()
                && (ne[0] - prev[0]).hypot(ne[1] - prev[1]) < 0.5
            {
                return Err(invalid(key, "is within 0.5 m of the previous way-point"));
            }
            waypoints.push(ne);
        }
        Ok(Drive::Waypoints {
            waypoints,
            speed_mps,
        })
    }

    fn validate_manual(manual: &ManualSpec) -> Result<Drive, ScenarioError> {
        if manual.commands.is_empty() {
            return Err(invalid("manual.commands", "needs at least one command"));
        }
        let mut out = Vec::with_capacity(manual.commands.len());
        let mut last = f64::NEG_INFINITY;
        for (i, c) in manual.commands.iter().enumerate() {
            let time_s = non_negative(&format!("manual.commands[{i}].time_s"), c.time_s)?;
            if time_s <= last {
                return Err(invalid(
                    format!("manual.commands[{i}].time_s"),
                    "commands must be in increasing time order",
                ));
            }
            last = time_s;
            let port = finite(&format!("manual.commands[{i}].port_rpm"), c.port_rpm)?;
            let stb = finite(
                &format!("manual.commands[{i}].starboard_rpm"),
                c.starboard_rpm,
            )?;
            out.push((time_s, [port * RADPS_PER_RPM, stb * RADPS_PER_RPM]));
        }
        Ok(Drive::Manual(out))
    }

    fn validate_initial(&self, drive: &Drive) -> Result<[f64; 4], ScenarioError> {
        let spec = self.initial.unwrap_or_default();
        let (default_pos, default_heading_rad, default_speed) = match drive {
            Drive::Waypoints {
                waypoints,
                speed_mps,
            } => {
                let [n0, e0] = waypoints[0];
                let [n1, e1] = waypoints[1];
                ([n0, e0], (e1 - e0).atan2(n1 - n0), *speed_mps)
            }
            Drive::Manual(_) => ([0.0, 0.0], 0.0, 0.0),
        };
        let north = finite("initial.north_m", spec.north_m.unwrap_or(default_pos[0]))?;
        let east = finite("initial.east_m", spec.east_m.unwrap_or(default_pos[1]))?;
        let heading = match spec.heading_deg {
            Some(deg) => finite("initial.heading_deg", deg)?.to_radians(),
            None => default_heading_rad,
        };
        let speed = spec.speed_mps.unwrap_or(default_speed);
        if !(speed.is_finite() && (0.0..=3.0).contains(&speed)) {
            return Err(invalid(
                "initial.speed_mps",
                format!("must be in 0..3 m/s, got {speed}"),
            ));
        }
        Ok([north, east, heading, speed])
    }

    #[allow(clippy::type_complexity)]
    fn validate_sensors(
        &self,
    ) -> Result<
        (
            Option<GnssSettings>,
            Option<HeadingSettings>,
            Option<PropellerSettings>,
            Option<YawRateSettings>,
        ),
        ScenarioError,
    > {
        let g = &self.sensors.gnss;
        let gnss = if g.enabled {
            let scale = positive("sensors.gnss.sog_scale", g.sog_scale)?;
            Some(GnssSettings {
                period_s: period_of("sensors.gnss.rate_hz", g.rate_hz)?,
                position_sigma_m: non_negative(
                    "sensors.gnss.position_sigma_m",
                    g.position_sigma_m,
                )?,
                position_correlation_s: non_negative(
                    "sensors.gnss.position_correlation_s",
                    g.position_correlation_s,
                )?,
                sog_sigma_mps: non_negative("sensors.gnss.sog_sigma_mps", g.sog_sigma_mps)?,
                cog_min_sog_mps: non_negative("sensors.gnss.cog_min_sog_mps", g.cog_min_sog_mps)?,
                latency_s: finite("sensors.gnss.latency_s", g.latency_s)?,
                lever_arm_m: [
                    finite("sensors.gnss.lever_arm.x_m", g.lever_arm.x_m)?,
                    finite("sensors.gnss.lever_arm.y_m", g.lever_arm.y_m)?,
                ],
                sog_scale: scale,
                hdop: (finite("sensors.gnss.hdop", g.hdop)? >= 0.0).then_some(g.hdop),
            })
        } else {
            None
        };
        let y = &self.sensors.yaw_rate;
        let yaw_rate = if y.enabled {
            Some(YawRateSettings {
                period_s: period_of("sensors.yaw_rate.rate_hz", y.rate_hz)?,
                sigma_radps: non_negative("sensors.yaw_rate.sigma_deg_s", y.sigma_deg_s)?
                    .to_radians(),
                bias_radps: finite("sensors.yaw_rate.bias_deg_s", y.bias_deg_s)?.to_radians(),
                scale: positive("sensors.yaw_rate.scale", y.scale)?,
            })
        } else {
            None
        };
        let h = &self.sensors.heading;
        let heading = if h.enabled {
            Some(HeadingSettings {
                period_s: period_of("sensors.heading.rate_hz", h.rate_hz)?,
                sigma_rad: non_negative("sensors.heading.sigma_deg", h.sigma_deg)?.to_radians(),
                offset_rad: finite("sensors.heading.offset_deg", h.offset_deg)?.to_radians(),
            })
        } else {
            None
        };
        let p = &self.sensors.propellers;
        let propellers = if p.enabled {
            Some(PropellerSettings {
                period_s: period_of("sensors.propellers.rate_hz", p.rate_hz)?,
                sigma_radps: non_negative("sensors.propellers.sigma_rpm", p.sigma_rpm)?
                    * RADPS_PER_RPM,
            })
        } else {
            None
        };
        Ok((gnss, heading, propellers, yaw_rate))
    }
}

impl VesselSpec {
    /// The scales, each checked to be positive.
    fn validated(&self) -> Result<VesselScales, ScenarioError> {
        Ok(VesselScales {
            mass: positive("vessel.mass_scale", self.mass_scale)?,
            added_mass: positive("vessel.added_mass_scale", self.added_mass_scale)?,
            surge_damping: positive("vessel.surge_damping_scale", self.surge_damping_scale)?,
            sway_damping: positive("vessel.sway_damping_scale", self.sway_damping_scale)?,
            yaw_damping: positive("vessel.yaw_damping_scale", self.yaw_damping_scale)?,
            crossflow_drag: positive("vessel.crossflow_drag_scale", self.crossflow_drag_scale)?,
            thrust: positive("vessel.thrust_scale", self.thrust_scale)?,
            size: positive("vessel.size_scale", self.size_scale)?,
            propeller_arm: positive("vessel.propeller_arm_scale", self.propeller_arm_scale)?,
        })
    }
}

/// The autopilot's settings of a plan, validated.
struct ControlSettings {
    period_s: f64,
    lookahead_m: f64,
    acceptance_radius_m: f64,
    ilos_gain: f64,
    tuning: AutopilotTuning,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unix_time_of_toml_datetimes() {
        let dt: Datetime = "2022-05-20T10:00:00Z".parse().unwrap();
        assert_eq!(unix_seconds("t", &dt).unwrap(), 1_653_040_800.0);
        let dt: Datetime = "2022-05-20T12:00:00.5+02:00".parse().unwrap();
        assert_eq!(unix_seconds("t", &dt).unwrap(), 1_653_040_800.5);
        let dt: Datetime = "1970-01-01T00:00:00Z".parse().unwrap();
        assert_eq!(unix_seconds("t", &dt).unwrap(), 0.0);
        let dt: Datetime = "2000-03-01T00:00:00Z".parse().unwrap();
        assert_eq!(unix_seconds("t", &dt).unwrap(), 951_868_800.0);
        let dt: Datetime = "1969-12-31T23:59:59Z".parse().unwrap();
        assert_eq!(unix_seconds("t", &dt).unwrap(), -1.0);
        let local: Datetime = "2022-05-20T10:00:00".parse().unwrap();
        let err = unix_seconds("start_time", &local).unwrap_err().to_string();
        assert!(err.contains("start_time"), "{err}");
    }
}
