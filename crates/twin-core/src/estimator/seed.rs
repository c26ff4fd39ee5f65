//! The seed's method as an estimator base: the kinematic model of
//! docs/model.md section 3 in the adaptive filter, its inputs (acceleration
//! along the track and course rate) derived from the GNSS track, and the
//! seed's step 4 from input faults to per-thruster values (kept for
//! comparison: docs/model.md section 5 explains why it cannot see a thrust
//! loss).

use nalgebra::{SMatrix, SVector, Vector4};

use super::{CourseGate, Learnt, LocalFix};
use crate::aekf::{Aekf, AekfConfig, AekfError, AekfState, GainSensitivity, StepReport};
use crate::inputs::{Butterworth, InputConfigError, InputDerivationConfig, InputDeriver, LowPass};
use crate::model::Measurement;
use crate::models::kinematic::{KinematicInput, KinematicModel};
use crate::vessel::{VesselParams, seed_thruster_faults};

/// The seed's method.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SeedConfig {
    /// The filter's tuning.
    pub filter: AekfConfig<4, 4, 2>,
    /// How inputs are derived from GNSS.
    pub inputs: InputDerivationConfig,
    /// Low-pass cut-off for the yaw acceleration of step 4, Hz (thesis: 0.9).
    pub yaw_accel_cutoff_hz: f64,
    /// Step 4's guard: thrusts below this give no per-thruster fault, N.
    pub min_thrust_n: f64,
}

impl SeedConfig {
    /// The seed's tuning (docs/model.md section 4) at its 5 Hz, with the
    /// forgetting as the time constant it implies there (40 s) and the
    /// thesis' inputs.
    pub fn seed() -> Self {
        let dt = 0.2;
        Self {
            filter: AekfConfig {
                process_noise_density: SMatrix::identity() * (0.01 / dt),
                measurement_noise: SMatrix::identity() * 0.04,
                forgetting_time_constant_s: -dt / 0.995_f64.ln(),
                fault_memory_factor: SVector::repeat(1.0),
                initial_fault_covariance: SMatrix::identity() * 0.1,
                anti_windup_ratio: 0.1,
                excitation_sigma: 0.02,
                noise_adaptation: None,
                gain_sensitivity: GainSensitivity::Omitted,
                gain_sensitivity_faults: [true; _],
            },
            inputs: InputDerivationConfig::thesis(),
            yaw_accel_cutoff_hz: 0.9,
            min_thrust_n: 5.0,
        }
    }
}

/// The seed's base: its filter, measurement and prior.
#[derive(Debug, Clone)]
pub struct SeedBase {
    filter: Aekf<KinematicModel, 4, 4, 2>,
    gate: CourseGate,
}

impl SeedBase {
    /// The base with `config`, masking the course below `gate`'s speed.
    pub fn new(config: &SeedConfig, gate: CourseGate) -> Result<Self, AekfError> {
        Ok(Self {
            filter: Aekf::new(KinematicModel, config.filter)?,
            gate,
        })
    }

    /// The filter.
    pub fn filter(&self) -> &Aekf<KinematicModel, 4, 4, 2> {
        &self.filter
    }

    /// `[north, east, sog, cog]`, each where measured, the course only
    /// above the gate's speed.
    pub fn measurement(&self, fix: &LocalFix) -> Measurement<4> {
        Measurement {
            values: Vector4::new(
                fix.position.north_m,
                fix.position.east_m,
                fix.sog_mps.unwrap_or(0.0),
                fix.cog_rad.unwrap_or(0.0),
            ),
            available: [
                fix.position_measured,
                fix.position_measured,
                fix.sog_mps.is_some(),
                self.gate.course_available(fix),
            ],
        }
    }

    /// The first estimate from a fix: the state as measured, its covariance
    /// the measurement noise, the faults from `restored` (else none, with the
    /// configured covariance).
    pub fn prior(&self, fix: &LocalFix, restored: Option<&Learnt<2>>) -> AekfState<4, 4, 2> {
        let x0 = Vector4::new(
            fix.position.north_m,
            fix.position.east_m,
            fix.sog_mps.unwrap_or(0.0),
            fix.cog_rad.unwrap_or(0.0),
        );
        let config = &self.filter.config;
        let theta0 = restored.map(|r| r.theta).unwrap_or_default();
        let mut state = AekfState::new(config, x0, config.measurement_noise, theta0);
        if let Some(r) = restored {
            state.s = r.covariance;
            state.held_information = r.held_information;
        }
        state
    }

    /// One step to `fix`, `dt_s` after the estimate, driven by `input`.
    pub fn step(
        &self,
        state: &mut AekfState<4, 4, 2>,
        input: &KinematicInput,
        fix: &LocalFix,
        dt_s: f64,
    ) -> Result<StepReport<4, 2>, AekfError> {
        self.filter.step(state, input, &self.measurement(fix), dt_s)
    }
}

/// The seed's inputs from the GNSS track: derived by differences and a
/// low-pass (docs/model.md section 3), and step 4's yaw acceleration.
#[derive(Debug, Clone)]
pub struct SeedInputs {
    config: InputDerivationConfig,
    deriver: InputDeriver,
    yaw_accel: YawAcceleration,
    /// The input of the last step (held when a fix gives none).
    last: KinematicInput,
}

impl SeedInputs {
    /// Inputs derived as `config` says; step 4's yaw acceleration low-passed
    /// at `yaw_accel_cutoff_hz`.
    pub fn new(config: &SeedConfig) -> Result<Self, InputConfigError> {
        let rate = match config.inputs.low_pass {
            LowPass::Butterworth { sample_rate_hz, .. } => sample_rate_hz,
            _ => 5.0,
        };
        Ok(Self {
            config: config.inputs,
            deriver: InputDeriver::new(config.inputs)?,
            yaw_accel: YawAcceleration {
                filter: Butterworth::new(5, config.yaw_accel_cutoff_hz, rate)?,
                last: None,
            },
            last: KinematicInput::default(),
        })
    }

    /// Takes the next fix's speed and course; a new track starts the
    /// differences over. Returns the input for the interval that ends at
    /// the fix, or `None` when the fix gives none (the first of a track, no
    /// speed or course).
    pub(crate) fn push(
        &mut self,
        fix: &LocalFix,
        new_track: bool,
    ) -> Result<Option<KinematicInput>, InputConfigError> {
        let (Some(sog), Some(cog)) = (fix.sog_mps, fix.cog_rad) else {
            return Ok(None);
        };
        if new_track {
            self.deriver = InputDeriver::new(self.config)?;
        }
        Ok(self.deriver.push(fix.time_s, sog, cog))
    }

    /// The input of the last step.
    pub fn last(&self) -> KinematicInput {
        self.last
    }

    /// Records `input` as the one that drove the last step, and returns step
    /// 4's yaw acceleration at `time_s`.
    pub(crate) fn record(&mut self, time_s: f64, input: KinematicInput) -> f64 {
        self.last = input;
        self.yaw_accel.push(time_s, input.course_rate_radps)
    }
}

/// The seed's yaw acceleration for step 4: differences of the derived course
/// rate, low-passed (thesis eq. 3.18, 0.9 Hz).
#[derive(Debug, Clone)]
struct YawAcceleration {
    filter: Butterworth,
    last: Option<(f64, f64)>,
}

impl YawAcceleration {
    fn push(&mut self, time_s: f64, rate: f64) -> f64 {
        let raw = match self.last {
            Some((t0, r0)) if time_s > t0 => (rate - r0) / (time_s - t0),
            _ => 0.0,
        };
        self.last = Some((time_s, rate));
        self.filter.step(raw)
    }
}

/// The seed's step 4 at the current estimate: per-thruster values from the
/// input faults (`None` where the thrust is too small for the ratio).
pub(crate) fn step_four(
    params: &VesselParams,
    config: &SeedConfig,
    state: &AekfState<4, 4, 2>,
    input: &KinematicInput,
    yaw_accel_radps2: f64,
) -> [Option<f64>; 2] {
    seed_thruster_faults(
        params,
        state.x[2],
        input.course_rate_radps,
        input.accel_mps2,
        yaw_accel_radps2,
        state.theta,
        config.min_thrust_n,
    )
    .loss
}
