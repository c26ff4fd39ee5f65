//! The twin's output payloads, as published by the daemon on
//! `{prefix}/{vessel}/twin/{state,fault,prediction,alarm,stats,finding}`
//! (and the daemon's own `{prefix}/@twind/{daemon}/stats`) and as printed by
//! the offline tools. JSON ([`CONTENT_TYPE`]), with times in RFC 3339 UTC
//! and units in every field name. Built from `twin_core`'s plain reports; the core
//! never sees these types.

use std::collections::BTreeMap;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use twin_core::decision::{StatusChange, ThrusterStatus};
use twin_core::twin::{
    FaultReport, FaultSource, ForecastPoint, ProfileMismatch, StateReport, ThrusterEstimate,
};

use crate::time::format_rfc3339;

/// The content type of every output payload: the daemon sets it as the
/// Zenoh encoding of each put and query reply, so that a generic client
/// (the Zenoh REST plugin, a bridge) shows them as JSON.
pub const CONTENT_TYPE: &str = "application/json";

fn time_string(time_s: f64) -> String {
    format_rfc3339(time_s).unwrap_or_else(|_| "invalid".to_string())
}

fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

/// Which estimator produced an output.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ModelName {
    /// The extended twin (propeller speeds, kinetic model).
    Kinetic,
    /// The seed's method (GNSS-derived inputs, kinematic model).
    SeedMethod,
}

impl From<FaultSource> for ModelName {
    fn from(s: FaultSource) -> Self {
        match s {
            FaultSource::Kinetic => ModelName::Kinetic,
            FaultSource::SeedMethod => ModelName::SeedMethod,
        }
    }
}

/// Standard deviations of the state estimate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct StateSigma {
    /// North, m.
    pub north_m: f64,
    /// East, m.
    pub east_m: f64,
    /// Speed over ground, m/s.
    pub sog_mps: f64,
    /// Course over ground, rad.
    pub cog_rad: f64,
}

/// A water current estimate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct CurrentMessage {
    /// North component, m/s.
    pub north_mps: f64,
    /// East component, m/s.
    pub east_mps: f64,
    /// Speed, m/s.
    pub speed_mps: f64,
    /// Direction the water flows toward, degrees true.
    pub toward_deg: f64,
}

/// `twin/state`: the state estimate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct StateMessage {
    /// Vessel id.
    pub vessel: String,
    /// Time of the estimate (the last fix), RFC 3339.
    pub time: String,
    /// Latitude, degrees.
    pub lat_deg: f64,
    /// Longitude, degrees.
    pub lon_deg: f64,
    /// North of the twin's local origin, m.
    pub north_m: f64,
    /// East of the twin's local origin, m.
    pub east_m: f64,
    /// Speed over ground, m/s.
    pub sog_mps: f64,
    /// Course over ground, rad in [0, 2 pi).
    pub cog_rad: f64,
    /// Heading, rad, where the estimator has it.
    pub heading_rad: Option<f64>,
    /// Standard deviations.
    pub sigma: StateSigma,
    /// Normalised innovation squared of the last update.
    pub nis: f64,
    /// Its degrees of freedom.
    pub nis_dof: usize,
    /// The water current, where estimated.
    pub current: Option<CurrentMessage>,
    /// The estimator.
    pub model: ModelName,
    /// True when no fix arrived for longer than the daemon's stale limit:
    /// the state is a prediction from the last fix.
    pub stale: bool,
    /// True when the inputs were replayed from a log.
    pub replay: bool,
}

impl StateMessage {
    /// From the core's report.
    pub fn new(vessel: &str, s: &StateReport, stale: bool, replay: bool) -> Self {
        Self {
            vessel: vessel.to_string(),
            time: time_string(s.time_s),
            lat_deg: s.position.lat_deg,
            lon_deg: s.position.lon_deg,
            north_m: s.local.north_m,
            east_m: s.local.east_m,
            sog_mps: s.sog_mps,
            cog_rad: s.cog_rad,
            heading_rad: s.heading_rad,
            sigma: StateSigma {
                north_m: s.position_sigma_m[0],
                east_m: s.position_sigma_m[1],
                sog_mps: s.sog_sigma_mps,
                cog_rad: s.cog_sigma_rad,
            },
            nis: s.nis,
            nis_dof: s.nis_dof,
            current: s.current_mps.map(|c| CurrentMessage {
                north_mps: c[0],
                east_mps: c[1],
                speed_mps: c[0].hypot(c[1]),
                toward_deg: twin_core::geodesy::rad_to_compass_deg(c[1].atan2(c[0])),
            }),
            model: s.source.into(),
            stale,
            replay,
        }
    }
}

/// One thruster in `twin/fault`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ThrusterMessage {
    /// Estimated loss of effectiveness, clamped to [0, 1] (null when unknown).
    pub loss: Option<f64>,
    /// Its standard deviation (null for the seed's method, which has none).
    pub sigma: Option<f64>,
    /// The raw estimate before clamping.
    pub loss_raw: Option<f64>,
    /// Whether the recent data can tell this thruster's loss.
    pub excited: bool,
    /// `not_excited`, `nominal`, `suspect` or `fault`.
    pub status: ThrusterStatusName,
    /// Onset of the current suspect/fault episode, RFC 3339.
    pub onset: Option<String>,
}

/// A thruster status as written in payloads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ThrusterStatusName {
    /// The data have not yet been able to tell, or a `nominal` was
    /// withdrawn: the profile no longer describes the vessel, or the loss,
    /// no longer told, has moved out of the nominal band.
    NotExcited,
    /// No loss.
    Nominal,
    /// A loss beyond the suspect level.
    Suspect,
    /// A confirmed loss.
    Fault,
}

impl From<ThrusterStatus> for ThrusterStatusName {
    fn from(s: ThrusterStatus) -> Self {
        match s {
            ThrusterStatus::NotExcited => ThrusterStatusName::NotExcited,
            ThrusterStatus::Nominal => ThrusterStatusName::Nominal,
            ThrusterStatus::Suspect => ThrusterStatusName::Suspect,
            ThrusterStatus::Fault => ThrusterStatusName::Fault,
        }
    }
}

/// Both thrusters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Thrusters {
    /// The port thruster.
    pub port: ThrusterMessage,
    /// The starboard thruster.
    pub starboard: ThrusterMessage,
}

/// A value with its standard deviation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ValueSigma {
    /// The value.
    pub value: f64,
    /// Its standard deviation.
    pub sigma: f64,
}

/// `twin/fault`: the fault picture.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct FaultMessage {
    /// Vessel id.
    pub vessel: String,
    /// Time, RFC 3339.
    pub time: String,
    /// Port and starboard.
    pub thrusters: Thrusters,
    /// The worst thruster status: `nominal`, `suspect` or `fault`
    /// (`not_excited` until the data have told anything, or while a
    /// `nominal` is withdrawn: a profile that no longer describes the
    /// vessel, or a loss no longer told that has left the nominal band).
    pub status: ThrusterStatusName,
    /// True while both thrusters' losses can be told from recent data.
    pub excited: bool,
    /// Onset of the earliest current episode, RFC 3339.
    pub onset: Option<String>,
    /// The estimator.
    pub model: ModelName,
    /// `(1 - loss_port) / (1 - loss_starboard)`: what even a straight run
    /// can tell (extended twin only).
    pub effectiveness_ratio: Option<ValueSigma>,
    /// The seed's method's input faults `[a, r]` (for comparison).
    pub seed_input_faults: [f64; 2],
    /// True when the inputs were replayed from a log.
    pub replay: bool,
    /// Why the propellers' losses are not excited although the data move:
    /// the profile does not describe this vessel (`null` where it does, or
    /// for the seed's method). A controller reads it as "the twin knows it
    /// cannot tell": calibrate or identify the vessel's profile.
    #[serde(default)]
    pub profile_mismatch: Option<ProfileMismatchMessage>,
}

/// The figures that show a profile does not describe the vessel: how far
/// the filter moved the profile's yaw damping, mass and thrust
/// coefficient, and how well the model fits, each with its bound
/// (docs/model.md section 10).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ProfileMismatchMessage {
    /// The relative error of the profile's yaw damping the filter reached.
    pub yaw_damping_error: f64,
    /// The largest it may be (`KineticConfig::plausible_profile_sigmas`,
    /// two and a half, of its prior standard deviation).
    pub yaw_damping_bound: f64,
    /// The relative error of the profile's mass the filter reached.
    pub mass_error: f64,
    /// The largest it may be.
    pub mass_bound: f64,
    /// The relative error of the profile's thrust coefficient the filter
    /// reached (read as 0 from a payload without it).
    #[serde(default)]
    pub thrust_error: f64,
    /// The largest it may be (read as 0 from a payload without it).
    #[serde(default)]
    pub thrust_bound: f64,
    /// The NIS per degree of freedom over the filter's memory.
    pub nis_per_dof: f64,
    /// The largest it may be.
    pub max_nis_per_dof: f64,
}

/// One line for people: each figure with its bound (`twin analyze`'s text,
/// the ROS 2 diagnostics).
impl std::fmt::Display for ProfileMismatchMessage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "yaw damping error {:+.2}, at most +-{:.2}; mass error {:+.2}, at most +-{:.2}; thrust coefficient error {:+.2}, at most +-{:.2}; NIS per dof over the last minute {:.2}, at most {:.1}",
            self.yaw_damping_error,
            self.yaw_damping_bound,
            self.mass_error,
            self.mass_bound,
            self.thrust_error,
            self.thrust_bound,
            self.nis_per_dof,
            self.max_nis_per_dof
        )
    }
}

impl From<&ProfileMismatch> for ProfileMismatchMessage {
    fn from(m: &ProfileMismatch) -> Self {
        Self {
            yaw_damping_error: m.yaw_damping_error,
            yaw_damping_bound: m.yaw_damping_bound,
            mass_error: m.mass_error,
            mass_bound: m.mass_bound,
            thrust_error: m.thrust_error,
            thrust_bound: m.thrust_bound,
            nis_per_dof: m.nis_per_dof,
            max_nis_per_dof: m.max_nis_per_dof,
        }
    }
}

fn thruster(t: &ThrusterEstimate) -> ThrusterMessage {
    ThrusterMessage {
        loss: finite(t.loss).map(|l| l.clamp(0.0, 1.0)),
        sigma: finite(t.sigma),
        loss_raw: finite(t.loss),
        excited: t.excited,
        status: t.decision.status.into(),
        onset: t.decision.onset_time_s.map(time_string),
    }
}

impl FaultMessage {
    /// From the core's report.
    pub fn new(vessel: &str, f: &FaultReport, replay: bool) -> Self {
        let onset = f
            .thrusters
            .iter()
            .filter_map(|t| t.decision.onset_time_s)
            .reduce(f64::min)
            .map(time_string);
        let ratio = (f.source == FaultSource::Kinetic).then(|| {
            let (value, sigma) = f.effectiveness_ratio();
            ValueSigma { value, sigma }
        });
        Self {
            vessel: vessel.to_string(),
            time: time_string(f.time_s),
            thrusters: Thrusters {
                port: thruster(&f.thrusters[0]),
                starboard: thruster(&f.thrusters[1]),
            },
            status: f.status.into(),
            excited: f.thrusters.iter().all(|t| t.excited),
            onset,
            model: f.source.into(),
            effectiveness_ratio: ratio.filter(|r| r.value.is_finite() && r.sigma.is_finite()),
            seed_input_faults: [f.seed_input_faults[0], f.seed_input_faults[1]],
            replay,
            profile_mismatch: f.profile_mismatch.as_ref().map(Into::into),
        }
    }
}

/// One point of `twin/prediction`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct PredictionPoint {
    /// Time, RFC 3339.
    pub time: String,
    /// Latitude, degrees.
    pub lat_deg: f64,
    /// Longitude, degrees.
    pub lon_deg: f64,
    /// North, m.
    pub north_m: f64,
    /// East, m.
    pub east_m: f64,
    /// Speed over ground, m/s.
    pub sog_mps: f64,
    /// Course over ground, rad.
    pub cog_rad: f64,
    /// Position standard deviation, m: the RMS of the north and east ones.
    pub position_sigma_m: f64,
    /// North standard deviation, m.
    pub sigma_north_m: f64,
    /// East standard deviation, m.
    pub sigma_east_m: f64,
}

/// `twin/prediction`: the forecast from the last fix, with the inputs held
/// at their last values (the extended twin's shaft speeds, or the seed
/// method's derived inputs). Its position sigma covers the water's
/// disturbance and what the twin does not know of the vessel, not a change
/// of command: where the vessel's autopilot changes the shaft speeds, the
/// forecast is off by what the change does.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct PredictionMessage {
    /// Vessel id.
    pub vessel: String,
    /// Start of the forecast (the last fix), RFC 3339.
    pub start: String,
    /// Horizon, s.
    pub horizon_s: f64,
    /// Step between points, s.
    pub step_s: f64,
    /// The estimator.
    pub model: ModelName,
    /// The points.
    pub points: Vec<PredictionPoint>,
    /// True when the inputs were replayed from a log.
    pub replay: bool,
}

impl PredictionMessage {
    /// From the core's forecast.
    pub fn new(
        vessel: &str,
        start_s: f64,
        horizon_s: f64,
        step_s: f64,
        model: FaultSource,
        points: &[ForecastPoint],
        replay: bool,
    ) -> Self {
        Self {
            vessel: vessel.to_string(),
            start: time_string(start_s),
            horizon_s,
            step_s,
            model: model.into(),
            points: points
                .iter()
                .map(|p| PredictionPoint {
                    time: time_string(p.time_s),
                    lat_deg: p.position.lat_deg,
                    lon_deg: p.position.lon_deg,
                    north_m: p.local.north_m,
                    east_m: p.local.east_m,
                    sog_mps: p.sog_mps,
                    cog_rad: p.cog_rad,
                    position_sigma_m: ((p.position_sigma_m[0].powi(2)
                        + p.position_sigma_m[1].powi(2))
                        / 2.0)
                        .sqrt(),
                    sigma_north_m: p.position_sigma_m[0],
                    sigma_east_m: p.position_sigma_m[1],
                })
                .collect(),
            replay,
        }
    }
}

/// `twin/alarm`: a change of a thruster's status, published on change only.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct AlarmMessage {
    /// Vessel id.
    pub vessel: String,
    /// When the change was declared, RFC 3339.
    pub time: String,
    /// What changed, in words.
    pub what: String,
    /// `port` or `starboard`.
    pub side: String,
    /// Status before.
    pub from: ThrusterStatusName,
    /// Status now.
    pub to: ThrusterStatusName,
    /// When the evidence first appeared, RFC 3339.
    pub onset: String,
    /// How sure: the probability, under the estimate's uncertainty, that the
    /// loss is on the side of the suspect level the change says (for a
    /// `nominal` withdrawn to `not_excited`, below it: how sure the claim
    /// withdrawn was).
    pub confidence: f64,
    /// True when the inputs were replayed from a log.
    pub replay: bool,
}

impl AlarmMessage {
    /// From a status change.
    pub fn new(vessel: &str, c: &StatusChange, replay: bool) -> Self {
        Self {
            vessel: vessel.to_string(),
            time: time_string(c.time_s),
            what: format!(
                "{} thruster {} -> {}",
                c.side.name(),
                c.from.name(),
                c.to.name()
            ),
            side: c.side.name().to_string(),
            from: c.from.into(),
            to: c.to.into(),
            onset: time_string(c.onset_time_s),
            confidence: c.confidence,
            replay,
        }
    }
}

/// `twin/stats`: what the twin of one vessel received, used and refused.
///
/// Every input message ends one way: used by the twin (`accepted`, per
/// topic) or refused (`rejected`, one reason per message), so that per
/// message `received = accepted + rejected` (summed over topics and
/// reasons). A GNSS fix or an actuator command is accepted only once the
/// twin has taken it (a duplicate, a time going backwards or a position
/// jump is a rejection). An NMEA payload is accepted when at least one of
/// its sentences gave a record; one with none is rejected with the first
/// sentence's reason (`empty_nmea` when it holds no sentence at all). What
/// the sentences of accepted NMEA payloads then gave is in [`NmeaStats`].
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
pub struct StatsMessage {
    /// Vessel id.
    pub vessel: String,
    /// The vessel profile the twin runs on, `name@fingerprint`
    /// (`twin_wire::profile::VesselProfile::identity`).
    #[serde(default)]
    pub profile: String,
    /// Messages received per input topic (`gnss`, `nmea`, `actuators`).
    #[serde(default)]
    pub received: BTreeMap<String, u64>,
    /// Messages the twin used, per input topic.
    pub accepted: BTreeMap<String, u64>,
    /// Messages refused, per reason.
    pub rejected: BTreeMap<String, u64>,
    /// What the sentences of the accepted NMEA payloads gave.
    #[serde(default, skip_serializing_if = "NmeaStats::is_empty")]
    pub nmea: NmeaStats,
}

/// The sentences of a vessel's accepted NMEA payloads: how many were
/// refused (a payload can hold good and bad ones), and the fixes and shaft
/// speeds assembled from the rest, with the twin's refusals of those fixes.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
pub struct NmeaStats {
    /// Sentences refused inside accepted payloads, per reason.
    #[serde(default)]
    pub sentences_rejected: BTreeMap<String, u64>,
    /// Fixes assembled and used by the twin.
    #[serde(default)]
    pub fixes: u64,
    /// Fixes assembled and refused by the twin, per reason.
    #[serde(default)]
    pub fixes_rejected: BTreeMap<String, u64>,
    /// Shaft speeds (or thrusts) assembled and used by the twin.
    #[serde(default)]
    pub propellers: u64,
    /// Shaft speeds assembled and refused by the twin, per reason.
    #[serde(default)]
    pub propellers_rejected: BTreeMap<String, u64>,
}

impl NmeaStats {
    /// Nothing counted (the vessel sent no NMEA).
    pub fn is_empty(&self) -> bool {
        *self == Self::default()
    }
}

impl StatsMessage {
    /// Total rejections.
    pub fn total_rejected(&self) -> u64 {
        self.rejected.values().sum()
    }

    /// Total messages received.
    pub fn total_received(&self) -> u64 {
        self.received.values().sum()
    }

    /// Total messages accepted.
    pub fn total_accepted(&self) -> u64 {
        self.accepted.values().sum()
    }
}

/// `{prefix}/@twind/{daemon}/stats`: what a daemon refused before a
/// message could reach a vessel's twin (a key that is no vessel's input, a
/// vessel not admitted, too many vessels), published every
/// `stats_interval_s` of wall clock. `received = routed + refused` (summed
/// over reasons).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
pub struct DaemonStatsMessage {
    /// The daemon's id (`[daemon] id`, else its Zenoh session id).
    pub daemon: String,
    /// Wall-clock time of the statistics, RFC 3339.
    pub time: String,
    /// Vessels admitted and running.
    pub vessels: usize,
    /// The most vessels it serves at once (`[vessels] max_vessels`).
    pub max_vessels: usize,
    /// Messages received on its input subscription.
    pub received: u64,
    /// Of those, handed to a vessel's twin.
    pub routed: u64,
    /// Of those, refused by the daemon, per reason.
    pub refused: BTreeMap<String, u64>,
    /// The most recently refused senders, newest first (at most a few
    /// dozen: enough to see which vessel is being refused, bounded whatever
    /// a flood sends).
    pub refused_recently: Vec<RefusedSender>,
    /// Calibration saves that failed.
    pub save_failures: u64,
    /// ROS 2 input messages their publishers numbered but that never
    /// arrived (the gaps in each publisher's sequence numbers): lost on the
    /// sender's side, as rmw_zenoh drops under congestion on all but
    /// KEEP_ALL + TRANSIENT_LOCAL topics. Not in `received`.
    #[serde(default)]
    pub ros2_missed: u64,
}

/// A vessel id (or, when no id could be read, the key) the daemon refused.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct RefusedSender {
    /// The vessel id, or the key (at most 128 bytes) when it names none.
    pub sender: String,
    /// The reason of its last refusal.
    pub reason: String,
    /// Its refusals while it has been in the list.
    pub count: u64,
    /// Wall-clock time of its last refusal, RFC 3339.
    pub last: String,
}

/// One finding of a diagnosis, as published on `twin/finding` and printed by
/// `twin diagnose --json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct FindingJson {
    /// The cause: `current`, `thruster_loss`, `heading_offset`, `sog_scale`,
    /// `gnss_latency`, `lever_arm`, `stw_scale`, `sideslip`,
    /// `sideslip_with_speed`, `yaw_rate_scale`, `yaw_rate_bias`, `surge_damping`, `yaw_damping`,
    /// `mass`.
    pub cause: String,
    /// Its parameters (numbers, and `side` for a thruster loss).
    pub parameters: BTreeMap<String, serde_json::Value>,
    /// Standard deviation of each numeric parameter.
    pub uncertainty: BTreeMap<String, f64>,
    /// What in the nominal residuals points at it.
    pub evidence: Vec<String>,
    /// What the model gains with it on held-out data.
    pub gain: GainJson,
}

/// A finding's gain on held-out data.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct GainJson {
    /// Held-out log-likelihood gain.
    pub heldout_nll_gain: f64,
    /// Held-out steps.
    pub heldout_steps: usize,
    /// NIS per degree of freedom before and after.
    pub nis_per_dof: BeforeAfter,
    /// Position prediction RMSE per horizon.
    pub prediction_rmse_m: Vec<HorizonRmse>,
}

/// Two numbers, without and with a finding.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct BeforeAfter {
    /// Without the finding.
    pub before: f64,
    /// With it.
    pub after: f64,
}

/// Prediction RMSE at one horizon, without and with a finding.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct HorizonRmse {
    /// Horizon, s.
    pub horizon_s: f64,
    /// RMSE without the finding, m.
    pub before: f64,
    /// With it, m.
    pub after: f64,
}

impl From<&twin_core::diagnose::Finding> for FindingJson {
    fn from(f: &twin_core::diagnose::Finding) -> Self {
        let mut parameters = BTreeMap::new();
        let mut uncertainty = BTreeMap::new();
        if let Some(side) = f.side {
            parameters.insert("side".to_string(), serde_json::Value::from(side));
        }
        for (name, value, sigma) in &f.parameters {
            parameters.insert(name.to_string(), serde_json::Value::from(*value));
            if sigma.is_finite() {
                uncertainty.insert(name.to_string(), *sigma);
            }
        }
        let g = &f.gain;
        Self {
            cause: f.cause.name().to_string(),
            parameters,
            uncertainty,
            evidence: f.evidence.clone(),
            gain: GainJson {
                heldout_nll_gain: g.heldout_nll_gain,
                heldout_steps: g.heldout_steps,
                nis_per_dof: BeforeAfter {
                    before: g.nis_per_dof_before,
                    after: g.nis_per_dof_after,
                },
                prediction_rmse_m: g
                    .prediction_rmse_before_m
                    .iter()
                    .zip(&g.prediction_rmse_after_m)
                    .map(|((h, b), (_, a))| HorizonRmse {
                        horizon_s: *h,
                        before: *b,
                        after: *a,
                    })
                    .collect(),
            },
        }
    }
}

/// What the findings leave unexplained: the extended model's held-out
/// residuals are still well outside what the filter expects, so the model
/// is wrong in a way no cause of the catalogue describes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct UnexplainedJson {
    /// Held-out NIS per degree of freedom with every finding (consistent:
    /// near 1; unexplained above the bar, 2 by default).
    pub nis_per_dof: f64,
    /// The components whose held-out innovation mean is still biased
    /// beyond the bar (10 standard errors by default).
    pub biased: Vec<BiasedComponent>,
}

/// A measurement component whose innovations stay biased.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct BiasedComponent {
    /// `north`, `east`, `sog`, `cog`, `heading`, `stw` or `yaw_rate`.
    pub component: String,
    /// The innovation mean in standard errors of the mean.
    pub bias_z: f64,
}

impl From<&twin_core::diagnose::Unexplained> for UnexplainedJson {
    fn from(u: &twin_core::diagnose::Unexplained) -> Self {
        Self {
            nis_per_dof: u.nis_per_dof,
            biased: u
                .biased
                .iter()
                .map(|(component, bias_z)| BiasedComponent {
                    component: component.to_string(),
                    bias_z: *bias_z,
                })
                .collect(),
        }
    }
}

/// `twin/finding`: what the daemon's residual monitor concluded about a
/// vessel's recent data, published when it changes (an empty list when the
/// nominal model explains the data again).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct FindingsMessage {
    /// Vessel id.
    pub vessel: String,
    /// Time of the last fix diagnosed, RFC 3339.
    pub time: String,
    /// Seconds of data diagnosed.
    pub window_s: f64,
    /// `kinetic` (propeller data) or `water`.
    pub base_model: String,
    /// The nominal model's NIS per degree of freedom on the held-out part.
    pub nominal_nis_per_dof: f64,
    /// What triggered the diagnosis: `routine` or `residuals` (the live
    /// twin's recent NIS left its band).
    pub trigger: String,
    /// The findings; empty when no cause clears the bars (the nominal model
    /// explains the data, or `unexplained` says what it leaves).
    pub findings: Vec<FindingJson>,
    /// Set when the findings leave the data unexplained (the model is wrong
    /// in a way the catalogue has no cause for); absent or null otherwise.
    #[serde(default)]
    pub unexplained: Option<UnexplainedJson>,
    /// True when the inputs were replayed from a log.
    pub replay: bool,
}

impl FindingsMessage {
    /// The causes named, sorted, and `unexplained` when the verdict is (to
    /// tell whether a new diagnosis changed anything).
    pub fn causes(&self) -> Vec<String> {
        let mut v: Vec<String> = self
            .findings
            .iter()
            .map(
                |f| match f.parameters.get("side").and_then(|s| s.as_str()) {
                    Some(side) => format!("{}:{side}", f.cause),
                    None => f.cause.clone(),
                },
            )
            .collect();
        if self.unexplained.is_some() {
            v.push("unexplained".to_string());
        }
        v.sort();
        v
    }
}

/// Formats a time for payloads (RFC 3339, or `invalid`).
pub fn payload_time(time_s: f64) -> String {
    time_string(time_s)
}
