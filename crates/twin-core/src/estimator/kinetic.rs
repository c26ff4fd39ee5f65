//! The extended twin as an estimator base: the Otter's kinetic model
//! ([`OtterTwin`]) driven by the measured shaft speeds, estimating each
//! propeller's loss together with what the vessel's profile may have wrong
//! (its surge and yaw damping), the water current and a heading sensor's
//! offset; optionally with sensor effects in its measurement (`diagnose`'s
//! hypotheses). It also reads the losses off an estimate as a controller
//! needs them ([`LossReading`]): each loss with its honest uncertainty, and
//! each propeller's effectiveness relative to the other, which the yaw
//! balance measures even when the losses' common part cannot be told from
//! the hull's drag.

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

use super::{CourseGate, Learnt, LocalFix, Surroundings};
use crate::aekf::{Aekf, AekfConfig, AekfError, AekfState, GainSensitivity, StepReport};
use crate::model::Measurement;
use crate::models::effects::SensorEffects;
use crate::models::otter_twin::{
    FAULTS, Faults, MEASUREMENTS, OtterTwin, STATES, ShaftSpeeds, State, fault, idx, meas,
};
use crate::sample::PropellerSpeeds;
use crate::vessel::VesselParams;

/// The kinetic base's filter.
pub type KineticFilter = Aekf<OtterTwin, STATES, MEASUREMENTS, FAULTS>;
/// The kinetic base's estimate.
pub type KineticState = AekfState<STATES, MEASUREMENTS, FAULTS>;
/// The kinetic base's step report.
pub type KineticReport = StepReport<MEASUREMENTS, FAULTS>;

/// The extended twin's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KineticConfig {
    /// The vessel's parameters.
    pub params: VesselParams,
    /// The filter's tuning.
    pub filter: AekfConfig<STATES, MEASUREMENTS, FAULTS>,
    /// Initial standard deviation of the water current estimate, m/s.
    pub initial_current_sigma_mps: f64,
    /// Estimate the water current (off: the current is held at zero).
    pub estimate_current: bool,
    /// Initial standard deviation of the heading sensor's offset, rad.
    pub initial_heading_bias_sigma_rad: f64,
    /// Initial standard deviation of the rate sensor's bias, rad/s.
    pub initial_yaw_rate_bias_sigma_radps: f64,
    /// Estimate the rate sensor's bias (off: the rate sensor is read as
    /// exact, for one calibrated on this vessel).
    pub estimate_yaw_rate_bias: bool,
    /// How far the profile's surge damping, yaw damping, thrust coefficient
    /// and mass may be from the vessel's, as standard deviations of their
    /// relative errors: the prior of the profile-error faults. An
    /// uncalibrated profile is uncertain by some 25 %; one identified from a
    /// trial by what the identification says.
    pub profile_sigma: [f64; 4],
    /// How many times the harbour water's random forces the velocities'
    /// process noise allows (see [`Self::otter_with`]).
    pub unmodelled_force_factor: f64,
    /// The same for a forecast's uncertainty
    /// ([`Self::forecast_process_noise_density`]): what the profile does
    /// not model over the forecast's horizon. It stays at
    /// [`Self::UNMODELLED_FORCE_FACTOR`] when the profile is identified
    /// ([`Self::with_identified_profile`]), which fits the hull's surge
    /// and yaw damping and its mass but not its sway and cross-flow drag,
    /// and those carry a 30-60 s forecast's error.
    pub forecast_force_factor: f64,
    /// Propeller data older than this stop the extended twin, s.
    pub max_propeller_age_s: f64,
    /// A propeller's loss counts as excited while the data pin it down to
    /// this standard deviation or better, with the other faults (the other
    /// loss, the profile's errors) unknown.
    pub excitation_sigma: f64,
    /// The same for its loss relative to the other propeller.
    pub relative_excitation_sigma: f64,
    /// Once the comparison of the propellers has been told, it stays told
    /// while its standard deviation is within this (and the yaw balance is
    /// still told): a loss that starts widens the filter's uncertainty
    /// while it moves to the new value, and that is when the comparison
    /// must be heard, not when the data have stopped telling it. Within
    /// it, a comparison not told is told weakly
    /// ([`LossReading::relative_weakly_told`]): the decision then takes
    /// its fault only after half a minute of evidence (`twin_core::decision`).
    pub relative_release_sigma: f64,
    /// With the current estimated, a loss both propellers share and a
    /// current along the track slow the vessel alike: only turning
    /// separates them, and a filter linearised along that ridge claims more
    /// than it knows. The losses count as excited on their own only while
    /// the heading over the filter's memory has spread at least this much:
    /// `1 - |mean of (cos psi, sin psi)|`, 0.05 being about a 65 deg arc.
    /// Their comparison (the yaw balance) needs no turn, only yaw rates
    /// that are not all one ([`Self::min_yaw_rate_spread`]).
    pub min_heading_spread: f64,
    /// On a steady turn a yaw damping error and a difference of the
    /// losses move the yaw balance alike (`N_r r` against `l (T_p - T_s)`,
    /// one equation at one yaw rate), and the filter's own noise, read as
    /// dynamics, drives the yaw damping error away with a one-sided loss to
    /// balance it. The comparison of the propellers counts as excited only
    /// while the yaw rate over the filter's memory is either near zero (a
    /// straight run: `rms(r) <= straight_yaw_rate_radps` over at least
    /// [`Self::straight_run_min_fill`] of a memory, where the yaw damping
    /// moment vanishes) or spread: `std(r) >= min_yaw_rate_spread rms(r)`
    /// (at 0.8, `|mean(r)| <= 0.6 rms(r)`), the yaw balance seen at rates
    /// unlike each other, with each way of turning holding at least
    /// [`Self::min_turn_share`] of the mean square. The damping moment is
    /// odd in `r` and a loss's is not, so what separates them robustly, on
    /// a vessel whose unmodelled sway damping, cross-flow drag and added
    /// mass also load the yaw balance, is turning both ways (docs/model.md
    /// section 10).
    pub min_yaw_rate_spread: f64,
    /// The spread alone does not say that the vessel has turned both
    /// ways: a straight leg and the first third of a turn one way spread
    /// the rates too (a share `f` of the memory at one rate gives
    /// `std / rms = sqrt(1 - f)`, 0.8 up to `f = 0.36`). Each way of
    /// turning must therefore hold at least this share of the yaw rate's
    /// mean square over the memory, `E[r^2; r > 0]` and `E[r^2; r < 0]`
    /// each against `E[r^2]` (a lawn-mower's alternate turns give about
    /// a half each; a turn one way after a straight leg, the heading's
    /// small corrections only, a few hundredths).
    pub min_turn_share: f64,
    /// The yaw rate below which a run counts as straight for
    /// [`Self::min_yaw_rate_spread`], rad/s.
    pub straight_yaw_rate_radps: f64,
    /// A straight run tells the yaw balance only once its rates fill this
    /// much of the filter's memory (their weights sum to `1 - e^(-t / T)`
    /// after `t` of a memory `T`; `1 - 1/e` is one memory's worth): the
    /// first 30-45 s of a trial's first leg hold a straight run's rates
    /// alone, but too few of them to average out the yaw moments of the
    /// water and of the hull's unmodelled sway.
    pub straight_run_min_fill: f64,
    /// The comparison of the propellers is read off the yaw balance as the
    /// profile writes it (yaw inertia, yaw damping, the propellers'
    /// thrust). It counts as excited only while the filter's yaw damping,
    /// mass and thrust coefficient errors are within this many of their
    /// prior standard deviations ([`Self::profile_sigma`]; the thrust
    /// coefficient's bound is never narrower than an unidentified
    /// profile's, [`Self::UNIDENTIFIED_PROFILE_SIGMA`]): further out the profile does
    /// not describe the vessel, and the comparison absorbs what it lacks (a
    /// vessel twice its profile's mass, healthy, read a relative loss of
    /// 0.27 +- 0.03 with the filter's mass error at its floor; a starboard
    /// loss of 0.39 that the filter answered by moving its thrust and surge
    /// damping errors to -0.8 read the healthy port propeller as a loss of
    /// 0.19 +- 0.05; docs/model.md section 10).
    pub plausible_profile_sigmas: f64,
    /// The same while the filter explains the data: its NIS per degree of
    /// freedom, averaged over the filter's memory, at most this.
    pub max_explained_nis_per_dof: f64,
    /// How much two propellers of one make differ when both are healthy
    /// (thrust coefficients, shaft-speed sensors, their distance from the
    /// centre line), as a standard deviation of their relative
    /// effectiveness: the published relative loss is never surer than this.
    pub propeller_mismatch_sigma: f64,
}

impl KineticConfig {
    /// The Otter with 5 Hz GNSS (0.3 m, 0.05 m/s), a heading sensor, if
    /// any, at 0.5 deg, and a rate gyro, if any, at 0.5 deg/s, in sheltered
    /// harbour water.
    ///
    /// Process noise: the kinematics are exact (tiny noise on position and
    /// heading); the velocities take the random forces of harbour water as
    /// white accelerations of density `q = M^-1 diag(2 F^2 T) M^-T` for gusts
    /// and chop of 3 N surge, 4 N sway, 0.5 N m yaw with 2 s correlation (the
    /// simulator's default disturbance, `twin_sim::DisturbanceSpec`); the
    /// current and the heading sensor's offset drift slowly.
    pub fn otter() -> Self {
        Self::otter_with(Self::UNMODELLED_FORCE_FACTOR)
    }

    /// The Otter whose profile is the vessel's own, its errors known to
    /// `profile_sigma` (relative standard deviations of surge damping, yaw
    /// damping, thrust coefficient and mass): the velocities' process
    /// noise, its forecasts' too, is the water's alone, and the losses'
    /// common part is known as well as the profile is. The seed's trials
    /// run it (their simulated vessel is the profile's Otter). A profile
    /// identified from a trial of a vessel is not known to be its own in
    /// what the identification does not fit:
    /// [`Self::with_identified_profile`] keeps its forecasts' allowance.
    pub fn identified(profile_sigma: [f64; 4]) -> Self {
        let mut config = Self::otter_with(1.0);
        config.set_profile_sigma(profile_sigma);
        config
    }

    /// This configuration with the velocities' process noise of the
    /// harbour water alone ([`Self::otter_with`] 1), for a search of what
    /// the model lacks: its misfit must show in the residuals.
    pub fn for_search(mut self) -> Self {
        self.unmodelled_force_factor = 1.0;
        self.set_velocity_noise();
        self
    }

    /// Sets [`Self::profile_sigma`] and the profile errors' prior with it.
    pub fn set_profile_sigma(&mut self, profile_sigma: [f64; 4]) {
        self.profile_sigma = profile_sigma;
        for (k, s) in profile_sigma.iter().enumerate() {
            self.filter.initial_fault_covariance
                [(fault::SURGE_DAMPING + k, fault::SURGE_DAMPING + k)] = s * s;
        }
    }

    /// [`Self::otter`] with the velocities' process noise
    /// `unmodelled_force_factor` times the harbour water's (1: the water
    /// alone, for a search of what the model lacks, `twin diagnose`, where
    /// the misfit must show in the residuals rather than in the states),
    /// its forecasts' too ([`Self::forecast_force_factor`]).
    pub fn otter_with(unmodelled_force_factor: f64) -> Self {
        let f = unmodelled_force_factor;
        let mut q = SMatrix::<f64, STATES, STATES>::from_diagonal(&SVector::<f64, STATES>::from([
            1e-6,
            1e-6,
            1e-7, // position and heading
            4.9e-3 * f,
            2.5e-3 * f,
            7.8e-4 * f, // surge, sway, yaw accelerations
            1e-6,
            1e-6,  // current
            1e-8,  // heading sensor offset
            1e-10, // rate sensor bias
        ]));
        // The sway-yaw mass coupling turns a sway force into a yaw acceleration too.
        q[(idx::V, idx::R)] = -7.7e-4 * f;
        q[(idx::R, idx::V)] = -7.7e-4 * f;
        let r = SVector::<f64, MEASUREMENTS>::from([
            0.3 * 0.3,
            0.3 * 0.3,
            0.05 * 0.05,
            0.03 * 0.03,
            0.0087 * 0.0087,
            0.0087 * 0.0087,
        ]);
        let profile_sigma = [Self::UNIDENTIFIED_PROFILE_SIGMA; 4];
        Self {
            params: VesselParams::default(),
            filter: AekfConfig {
                process_noise_density: q,
                measurement_noise: SMatrix::from_diagonal(&r),
                forgetting_time_constant_s: 60.0,
                // The losses can change at any time; the profile's errors
                // (and the mass) do not: they are remembered for an hour.
                fault_memory_factor: Faults::from([1.0, 1.0, 60.0, 60.0, 60.0, 60.0]),
                initial_fault_covariance: SMatrix::from_diagonal(&Faults::from([
                    0.1,
                    0.1,
                    profile_sigma[0] * profile_sigma[0],
                    profile_sigma[1] * profile_sigma[1],
                    profile_sigma[2] * profile_sigma[2],
                    profile_sigma[3] * profile_sigma[3],
                ])),
                anti_windup_ratio: 0.1,
                excitation_sigma: 0.03,
                noise_adaptation: None,
                gain_sensitivity: GainSensitivity::Omitted,
                gain_sensitivity_faults: [true; _],
            },
            initial_current_sigma_mps: 0.5,
            estimate_current: true,
            initial_heading_bias_sigma_rad: 10f64.to_radians(),
            initial_yaw_rate_bias_sigma_radps: 0.5f64.to_radians(),
            estimate_yaw_rate_bias: true,
            profile_sigma,
            unmodelled_force_factor: f,
            forecast_force_factor: f,
            max_propeller_age_s: 1.0,
            excitation_sigma: 0.1,
            relative_excitation_sigma: 0.07,
            relative_release_sigma: 0.10,
            min_heading_spread: 0.05,
            min_yaw_rate_spread: 0.8,
            min_turn_share: 0.2,
            straight_yaw_rate_radps: 0.02,
            straight_run_min_fill: 1.0 - (-1.0f64).exp(),
            plausible_profile_sigmas: 2.5,
            max_explained_nis_per_dof: 2.0,
            propeller_mismatch_sigma: 0.03,
        }
    }
}

impl KineticConfig {
    /// How many times the harbour water's random forces the velocities'
    /// process noise allows in an unidentified profile: the rest is the
    /// part of the vessel's motion its profile does not model (a vessel
    /// whose mass, damping and thrust are each 20-30 % off its profile, the
    /// trust matrix in `tests/src/trust.rs`), which the filter must take as
    /// noise rather than pin on the losses.
    pub const UNMODELLED_FORCE_FACTOR: f64 = 5.0;

    /// The relative standard deviation of each of an unidentified
    /// profile's errors (surge and yaw damping, thrust coefficient, mass):
    /// what a profile from drawings and rules of thumb promises.
    pub const UNIDENTIFIED_PROFILE_SIGMA: f64 = 0.25;

    /// [`Self::otter_with`] for the vessel `params` describes: its
    /// parameters, and the velocities' process noise of harbour water on a
    /// hull of its size ([`harbour_velocity_noise`]).
    pub fn for_vessel(params: VesselParams, unmodelled_force_factor: f64) -> Self {
        Self::otter_with(unmodelled_force_factor).with_vessel(params)
    }

    /// This configuration for the vessel `params` describes, its other
    /// tuning kept: the parameters, and the velocities' process noise of
    /// harbour water on that hull times [`Self::unmodelled_force_factor`].
    pub fn with_vessel(mut self, params: VesselParams) -> Self {
        self.params = params;
        self.set_velocity_noise();
        self
    }

    /// This configuration for a profile identified from a trial of the
    /// vessel, its errors known to `profile_sigma`: the velocities' process
    /// noise of the water alone, and the profile errors' prior
    /// ([`Self::identified`]). Its forecasts keep their
    /// [`Self::forecast_force_factor`].
    pub fn with_identified_profile(mut self, profile_sigma: [f64; 4]) -> Self {
        self.unmodelled_force_factor = 1.0;
        self.set_velocity_noise();
        self.set_profile_sigma(profile_sigma);
        self
    }

    /// The process noise density a forecast of this twin propagates with,
    /// from the filter's `filter_density` (its estimate's
    /// `process_noise_density`): the same, the velocities' block scaled
    /// from [`Self::unmodelled_force_factor`] to
    /// [`Self::forecast_force_factor`].
    pub fn forecast_process_noise_density(
        &self,
        filter_density: &SMatrix<f64, STATES, STATES>,
    ) -> SMatrix<f64, STATES, STATES> {
        let mut q = *filter_density;
        let ratio = self.forecast_force_factor / self.unmodelled_force_factor;
        if ratio.is_finite() && ratio > 0.0 {
            for i in idx::U..=idx::R {
                for j in idx::U..=idx::R {
                    q[(i, j)] *= ratio;
                }
            }
        }
        q
    }

    /// The velocities' process noise for [`Self::params`] and
    /// [`Self::unmodelled_force_factor`]: the numbers [`Self::otter_with`]
    /// writes for the Otter (the formula's, rounded), the formula of
    /// [`harbour_velocity_noise`] for any other vessel.
    fn set_velocity_noise(&mut self) {
        let q = if self.params == VesselParams::default() {
            let written = Self::otter_with(1.0).filter.process_noise_density;
            Matrix3::from_fn(|i, j| written[(idx::U + i, idx::U + j)])
        } else {
            harbour_velocity_noise(&self.params)
        } * self.unmodelled_force_factor;
        for i in 0..3 {
            for j in 0..3 {
                self.filter.process_noise_density[(idx::U + i, idx::U + j)] = q[(i, j)];
            }
        }
    }
}

/// The random forces of harbour water (gusts and chop) on the Otter, as
/// standard deviations in surge (N), sway (N) and yaw (N m): the
/// simulator's default disturbance, `twin_sim::DisturbanceSpec`.
const OTTER_HARBOUR_FORCE: [f64; 3] = [3.0, 4.0, 0.5];
/// Their correlation time, s.
const HARBOUR_FORCE_CORRELATION_S: f64 = 2.0;

/// The velocities' process noise density (surge, sway, yaw) of harbour
/// water on the vessel `params` describes: white accelerations
/// `q = M^-1 diag(2 F^2 T) M^-T` for random forces `F` of correlation time
/// `T`. The forces are the Otter's scaled with the hull: the surge and sway
/// forces with its wetted area (its mass to the power 2/3), the yaw moment
/// with that area times its length.
pub fn harbour_velocity_noise(params: &VesselParams) -> Matrix3<f64> {
    let otter = VesselParams::default();
    let area_ratio = (params.mass_kg / otter.mass_kg).powf(2.0 / 3.0);
    let length_ratio = params.length_m / otter.length_m;
    let force = [
        OTTER_HARBOUR_FORCE[0] * area_ratio,
        OTTER_HARBOUR_FORCE[1] * area_ratio,
        OTTER_HARBOUR_FORCE[2] * area_ratio * length_ratio,
    ];
    let spectral = Matrix3::from_diagonal(&Vector3::from(
        force.map(|f| 2.0 * f * f * HARBOUR_FORCE_CORRELATION_S),
    ));
    let inverse = params
        .mass_matrix
        .try_inverse()
        .unwrap_or_else(Matrix3::identity);
    inverse * spectral * inverse.transpose()
}

/// How a part of the model enters a filter run: left out, estimated, or
/// held at given values.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Term<const K: usize> {
    /// Held at zero.
    Off,
    /// Estimated by the filter.
    Free,
    /// Held at these values.
    Fixed([f64; K]),
}

/// Starts the states `slots` of a term: at the values held, for
/// `Term::Fixed`; returns their prior variance, `free_sigma` squared where
/// the filter estimates them, else [`HELD_VARIANCE`].
fn start_term<const K: usize>(
    term: Term<K>,
    slots: [usize; K],
    free_sigma: f64,
    x0: &mut State,
) -> f64 {
    match term {
        Term::Free => free_sigma.powi(2),
        Term::Off => HELD_VARIANCE,
        Term::Fixed(values) => {
            for (slot, value) in slots.into_iter().zip(values) {
                x0[slot] = value;
            }
            HELD_VARIANCE
        }
    }
}

/// What the kinetic base estimates and how it measures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KineticOptions {
    /// Effects on the measurement beyond the profile's (none for the live
    /// twin; an antenna offset here adds to the profile's antenna position).
    pub effects: SensorEffects,
    /// The water current `[north, east]`, m/s.
    pub current: Term<2>,
    /// The propeller losses `[port, starboard]`.
    pub losses: Term<2>,
    /// The heading sensor's offset, rad.
    pub heading_bias: Term<1>,
    /// The rate sensor's bias, rad/s.
    pub yaw_rate_bias: Term<1>,
    /// The relative errors of the profile's surge damping, yaw damping,
    /// thrust coefficient and mass.
    pub profile_errors: Term<4>,
}

impl KineticOptions {
    /// The live twin's: no sensor effects; the losses, the damping errors
    /// and the heading sensor's offset estimated; the current and the rate
    /// sensor's bias estimated or held at zero.
    pub fn live(estimate_current: bool, estimate_yaw_rate_bias: bool) -> Self {
        Self {
            effects: SensorEffects::default(),
            current: if estimate_current {
                Term::Free
            } else {
                Term::Off
            },
            losses: Term::Free,
            heading_bias: Term::Free,
            yaw_rate_bias: if estimate_yaw_rate_bias {
                Term::Free
            } else {
                Term::Off
            },
            profile_errors: Term::Free,
        }
    }
}

/// The kinetic base.
#[derive(Debug, Clone)]
pub struct KineticBase {
    filter: KineticFilter,
    options: KineticOptions,
    initial_current_sigma_mps: f64,
    initial_heading_bias_sigma_rad: f64,
    initial_yaw_rate_bias_sigma_radps: f64,
    excitation_sigma: f64,
    relative_excitation_sigma: f64,
    relative_release_sigma: f64,
    propeller_mismatch_sigma: f64,
    /// The losses' prior variance.
    prior_loss_variance: f64,
    /// The variance of the losses' common part that no data resolve, from
    /// the profile's prior (see [`KineticBase::losses`], which adds how far
    /// the estimate has moved the profile's errors).
    common_mode_variance: f64,
    gate: CourseGate,
}

/// A state that is held (no variance, no noise) is given this sliver of
/// variance so that the covariance stays positive definite.
const HELD_VARIANCE: f64 = 1e-12;

/// The losses as a controller reads them off an estimate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LossReading {
    /// Loss of each propeller `[port, starboard]`: the filter's estimate
    /// where it is excited, else the smallest losses the relative loss
    /// allows ([`KineticBase::losses`]).
    pub loss: [f64; 2],
    /// Its standard deviation, with every other fault (the other loss, the
    /// damping errors) unknown: the marginal of the filter's covariance.
    pub sigma: [f64; 2],
    /// Covariance of the two losses.
    pub covariance: [[f64; 2]; 2],
    /// Each propeller's loss relative to the other:
    /// `1 - (1 - loss_i) / (1 - loss_j)`, what the yaw balance measures
    /// even where the common part of the losses cannot be told from the
    /// hull's drag.
    pub relative_loss: [f64; 2],
    /// Its standard deviation (first order).
    pub relative_sigma: [f64; 2],
    /// Whether each loss on its own is excited: the data pin it down, with
    /// the other faults unknown, to the configured standard deviation.
    pub excited: [bool; 2],
    /// Whether the relative losses are excited: the narrower of their
    /// standard deviations (the weaker propeller's) is within the
    /// configured bar. The same for both sides.
    pub relative_excited: [bool; 2],
    /// Whether the relative losses are told weakly: not excited, but the
    /// narrower standard deviation within
    /// [`KineticConfig::relative_release_sigma`] and the yaw balance told.
    pub relative_weakly_told: [bool; 2],
}

impl KineticBase {
    /// The base of `config` with `options`, masking the course below
    /// `gate`'s speed. A current or heading offset that is not estimated has
    /// no process noise; faults that are not estimated have no covariance
    /// (the filter then holds them).
    pub fn new(
        config: &KineticConfig,
        gate: CourseGate,
        options: KineticOptions,
    ) -> Result<Self, AekfError> {
        let mut filter = config.filter;
        if options.current != Term::Free {
            for i in [idx::CURRENT_NORTH, idx::CURRENT_EAST] {
                filter.process_noise_density[(i, i)] = 0.0;
            }
        }
        if options.heading_bias != Term::Free {
            filter.process_noise_density[(idx::HEADING_BIAS, idx::HEADING_BIAS)] = 0.0;
        }
        if options.yaw_rate_bias != Term::Free {
            filter.process_noise_density[(idx::YAW_RATE_BIAS, idx::YAW_RATE_BIAS)] = 0.0;
        }
        let s0 = &mut filter.initial_fault_covariance;
        let mut hold = |i: usize| {
            s0.set_row(i, &SMatrix::<f64, 1, FAULTS>::zeros());
            s0.set_column(i, &SVector::<f64, FAULTS>::zeros());
        };
        if options.losses != Term::Free {
            hold(fault::PORT);
            hold(fault::STARBOARD);
        }
        if options.profile_errors != Term::Free {
            hold(fault::SURGE_DAMPING);
            hold(fault::YAW_DAMPING);
            hold(fault::THRUST);
            hold(fault::MASS);
        }
        // The profile's antenna position, and any lever arm a search adds to it.
        let effects = options.effects.with_antenna_from(config.params.antenna_m);
        let model = OtterTwin::new(config.params).with_effects(effects);
        Ok(Self {
            filter: Aekf::new(model, filter)?,
            options,
            initial_current_sigma_mps: config.initial_current_sigma_mps,
            initial_heading_bias_sigma_rad: config.initial_heading_bias_sigma_rad,
            initial_yaw_rate_bias_sigma_radps: config.initial_yaw_rate_bias_sigma_radps,
            excitation_sigma: config.excitation_sigma,
            relative_excitation_sigma: config.relative_excitation_sigma,
            relative_release_sigma: config.relative_release_sigma,
            propeller_mismatch_sigma: config.propeller_mismatch_sigma,
            prior_loss_variance: config.filter.initial_fault_covariance[(fault::PORT, fault::PORT)],
            // The thrust coefficient's and the surge damping's errors both
            // scale the thrust-to-resistance balance.
            common_mode_variance: config.profile_sigma[0].powi(2) + config.profile_sigma[2].powi(2),
            gate,
        })
    }

    /// The filter.
    pub fn filter(&self) -> &KineticFilter {
        &self.filter
    }

    /// The model.
    pub fn model(&self) -> &OtterTwin {
        &self.filter.model
    }

    /// What is estimated.
    pub fn options(&self) -> &KineticOptions {
        &self.options
    }

    /// `[north, east, sog, cog, heading, yaw rate]`, each where measured,
    /// the course only above the gate's speed.
    pub fn measurement(&self, fix: &LocalFix) -> Measurement<MEASUREMENTS> {
        self.gate.measurement(fix, fix.yaw_rate_radps)
    }

    /// Puts what was learnt of the surroundings (the current, the heading
    /// sensor's offset, the rate sensor's bias) into a prior, where the
    /// terms estimate them.
    fn restore_surroundings(
        &self,
        learnt: &Surroundings,
        x0: &mut State,
        p0: &mut SMatrix<f64, STATES, STATES>,
    ) {
        let slots = [
            (idx::CURRENT_NORTH, self.options.current == Term::Free),
            (idx::CURRENT_EAST, self.options.current == Term::Free),
            (idx::HEADING_BIAS, self.options.heading_bias == Term::Free),
        ];
        let values = [
            learnt.current_mps[0],
            learnt.current_mps[1],
            learnt.heading_bias_rad,
        ];
        for (a, (ia, free_a)) in slots.iter().enumerate() {
            if !free_a {
                continue;
            }
            x0[*ia] = values[a];
            for (b, (ib, free_b)) in slots.iter().enumerate() {
                if *free_b {
                    p0[(*ia, *ib)] = learnt.covariance[a][b];
                }
            }
        }
        if self.options.current == Term::Free {
            let c = learnt.covariance;
            p0[(idx::U, idx::U)] = 0.3f64.powi(2) + c[0][0].max(c[1][1]);
        }
        if let (Term::Free, Some(g)) = (self.options.yaw_rate_bias, learnt.yaw_rate_bias) {
            x0[idx::YAW_RATE_BIAS] = g.radps;
            p0[(idx::YAW_RATE_BIAS, idx::YAW_RATE_BIAS)] = g.variance;
        }
    }

    /// The first estimate from a fix: position as measured; heading from the
    /// heading sensor (less its offset, if the effects have one), else the
    /// course; surge speed from the speed over ground (less its scale); sway
    /// zero; yaw rate from the rate sensor (less its bias and scale), else
    /// zero; the current, the heading sensor's offset and the rate sensor's
    /// bias as their terms say, or as `restored` learnt them. The
    /// faults start from `restored` where given (estimate, covariance and
    /// anti-windup memory), else from none with the configured covariance,
    /// or at the values held.
    pub fn prior(&self, fix: &LocalFix, restored: Option<&Learnt<FAULTS>>) -> KineticState {
        let fx = &self.options.effects;
        let mut x0 = State::zeros();
        x0[idx::NORTH] = fix.position.north_m;
        x0[idx::EAST] = fix.position.east_m;
        x0[idx::PSI] = fix
            .heading_rad
            .map(|h| crate::geodesy::wrap_pi(h - fx.heading_offset_rad))
            .or(fix.cog_rad)
            .unwrap_or(0.0);
        x0[idx::U] = fix.sog_mps.unwrap_or(0.0) / fx.sog_scale;
        let current_variance = start_term(
            self.options.current,
            [idx::CURRENT_NORTH, idx::CURRENT_EAST],
            self.initial_current_sigma_mps,
            &mut x0,
        );
        let bias_variance = start_term(
            self.options.heading_bias,
            [idx::HEADING_BIAS],
            self.initial_heading_bias_sigma_rad,
            &mut x0,
        );
        let rate_bias_variance = start_term(
            self.options.yaw_rate_bias,
            [idx::YAW_RATE_BIAS],
            self.initial_yaw_rate_bias_sigma_radps,
            &mut x0,
        );
        let r = &self.filter.config.measurement_noise;
        // Not knowing the sensor's offset, the heading is as uncertain as
        // it (set below, once the offset's prior is known).
        let heading_variance = 0.5f64.powi(2);
        let yaw_rate_variance = if fix.yaw_rate_radps.is_some() {
            r[(meas::YAW_RATE, meas::YAW_RATE)]
        } else {
            0.1f64.powi(2)
        };
        // The surge speed through the water is the speed over ground less
        // the current along the track: it is as uncertain as the current.
        let mut p0 = SMatrix::<f64, STATES, STATES>::from_diagonal(&SVector::from([
            r[(meas::NORTH, meas::NORTH)],
            r[(meas::EAST, meas::EAST)],
            heading_variance,
            0.3f64.powi(2) + current_variance,
            0.3f64.powi(2),
            yaw_rate_variance,
            current_variance,
            current_variance,
            bias_variance,
            rate_bias_variance,
        ]));
        if let Some(learnt) = restored.and_then(|r| r.surroundings) {
            self.restore_surroundings(&learnt, &mut x0, &mut p0);
        }
        let bias_variance = p0[(idx::HEADING_BIAS, idx::HEADING_BIAS)];
        if fix.heading_rad.is_some() {
            // The heading is the sensor's reading less the offset.
            let bias = x0[idx::HEADING_BIAS];
            x0[idx::PSI] = crate::geodesy::wrap_pi(x0[idx::PSI] - bias);
            p0[(idx::PSI, idx::PSI)] = r[(meas::HEADING, meas::HEADING)] + bias_variance;
            p0[(idx::PSI, idx::HEADING_BIAS)] = -bias_variance;
            p0[(idx::HEADING_BIAS, idx::PSI)] = -bias_variance;
        }
        let rate_bias_variance = p0[(idx::YAW_RATE_BIAS, idx::YAW_RATE_BIAS)];
        if let Some(rate) = fix.yaw_rate_radps {
            // Likewise the yaw rate is the rate sensor's less its bias.
            x0[idx::R] = fx.yaw_rate_of_reading(rate - x0[idx::YAW_RATE_BIAS]);
            p0[(idx::R, idx::R)] = r[(meas::YAW_RATE, meas::YAW_RATE)] + rate_bias_variance;
            p0[(idx::R, idx::YAW_RATE_BIAS)] = -rate_bias_variance;
            p0[(idx::YAW_RATE_BIAS, idx::R)] = -rate_bias_variance;
        }
        let config = &self.filter.config;
        let mut theta0 = Faults::zeros();
        if let Term::Fixed(l) = self.options.losses {
            theta0[fault::PORT] = l[0];
            theta0[fault::STARBOARD] = l[1];
        }
        if let Term::Fixed(d) = self.options.profile_errors {
            theta0[fault::SURGE_DAMPING] = d[0];
            theta0[fault::YAW_DAMPING] = d[1];
            theta0[fault::THRUST] = d[2];
            theta0[fault::MASS] = d[3];
        }
        match restored {
            Some(r)
                if self.options.losses == Term::Free
                    && self.options.profile_errors == Term::Free =>
            {
                let mut state = AekfState::new(config, x0, p0, r.theta);
                state.s = r.covariance;
                state.held_information = r.held_information;
                state
            }
            _ => AekfState::new(config, x0, p0, theta0),
        }
    }

    /// One step to `fix`, `dt_s` after the estimate, driven by `input`. A
    /// current or heading offset that is off stays exactly zero. The
    /// course's noise is set for the fix's speed ([`Self::course_variance`]).
    pub fn step(
        &self,
        state: &mut KineticState,
        input: &ShaftSpeeds,
        fix: &LocalFix,
        dt_s: f64,
    ) -> Result<KineticReport, AekfError> {
        state.measurement_noise[(meas::COG, meas::COG)] = self.course_variance(fix);
        let report = self
            .filter
            .step(state, input, &self.measurement(fix), dt_s)?;
        if self.options.current == Term::Off {
            state.x[idx::CURRENT_NORTH] = 0.0;
            state.x[idx::CURRENT_EAST] = 0.0;
        }
        if self.options.heading_bias == Term::Off {
            state.x[idx::HEADING_BIAS] = 0.0;
        }
        if self.options.yaw_rate_bias == Term::Off {
            state.x[idx::YAW_RATE_BIAS] = 0.0;
        }
        Ok(report)
    }

    /// The variance of `fix`'s course, rad²: the configured one, or, where
    /// larger, the speed's over the speed squared. A receiver measures one
    /// velocity over ground, with about the same noise along and across
    /// the track; the speed is its length and the course its direction, so
    /// the course's noise is the velocity's divided by the speed, and grows
    /// as the vessel slows. At a fixed course noise, below about 1.5 m/s the
    /// filter took that noise for yaw, let the heading wander with a
    /// current across the track, and on a straight run drifted the losses
    /// and the current together (docs/model.md section 10).
    pub fn course_variance(&self, fix: &LocalFix) -> f64 {
        let r = &self.filter.config.measurement_noise;
        let configured = r[(meas::COG, meas::COG)];
        match fix.sog_mps {
            Some(sog) if self.gate.course_available(fix) && sog > 0.0 => {
                configured.max(r[(meas::SOG, meas::SOG)] / (sog * sog))
            }
            _ => configured,
        }
    }

    /// The losses of `state` as a controller reads them ([`LossReading`]).
    /// `common_part_told`: whether the data can separate the losses'
    /// common part from what else slows the vessel (false on a straight
    /// run with the current estimated): without it no loss is excited on
    /// its own. `yaw_balance_told`: whether the yaw rates seen separate a
    /// difference of the losses from a yaw damping error (false on a steady
    /// turn, [`KineticConfig::min_yaw_rate_spread`]): without it the
    /// comparison is not excited. `comparison_was_told`: whether the
    /// comparison was excited at the last fix
    /// ([`KineticConfig::relative_release_sigma`]).
    pub fn losses(
        &self,
        state: &KineticState,
        common_part_told: bool,
        yaw_balance_told: bool,
        comparison_was_told: bool,
    ) -> LossReading {
        let t = &state.theta;
        let s = &state.s;
        let (p, sb) = (fault::PORT, fault::STARBOARD);
        let loss = [t[p], t[sb]];
        let filter_covariance = [[s[(p, p)], s[(p, sb)]], [s[(sb, p)], s[(sb, sb)]]];
        // The part of the losses common to both propellers is known only as
        // well as the profile's thrust-to-resistance balance (docs/model.md
        // sections 8 and 10): what the filter learns of it comes from how quickly
        // the vessel answers its propellers, which waves, wakes and every
        // unmodelled motion blur. The published uncertainty is therefore
        // never narrower along the common part than the profile's: a
        // common scale error c of both effectivenesses moves each loss by
        // -(1 - loss_i) c. The relative losses are untouched (a common scale
        // cancels in them).
        //
        // The floor also holds how far the filter has moved the surge
        // damping and thrust errors from the profile: those moves run along
        // the direction no data resolve (a thrust error up, both losses up
        // alike), where the filter's own variance shrinks from the weak
        // coupling through the sway and yaw balance rather than from
        // evidence. On a vessel whose profile was identified from a trial,
        // a port loss of 0.25 took the thrust error to +0.23 and the healthy
        // starboard loss with it to 0.21, both with sigmas of 0.02 to 0.06
        // (docs/model.md section 10). A move of the errors by d widens the
        // common part by d: the loss is then as uncertain as the profile it
        // was measured against.
        let e = [1.0 - loss[0], 1.0 - loss[1]];
        let moved = t[fault::SURGE_DAMPING].powi(2) + t[fault::THRUST].powi(2);
        let floor = self.common_mode_variance + moved;
        // Where the common part is not told at all, it is as uncertain as
        // the losses' prior, whatever the estimate has drifted to.
        let untold = if common_part_told {
            0.0
        } else {
            self.prior_loss_variance
        };
        let covariance: [[f64; 2]; 2] = std::array::from_fn(|i| {
            std::array::from_fn(|j| filter_covariance[i][j] + floor * e[i] * e[j] + untold)
        });
        let sigma = [
            covariance[0][0].max(0.0).sqrt(),
            covariance[1][1].max(0.0).sqrt(),
        ];
        // Relative loss of i against j: 1 - e_i / e_j, e = 1 - loss; its
        // gradient in (loss_i, loss_j) is (1 / e_j, -e_i / e_j^2).
        let relative = |i: usize, j: usize| {
            let (ei, ej) = (1.0 - loss[i], (1.0 - loss[j]).max(1e-3));
            let rel = 1.0 - ei / ej;
            let g = [1.0 / ej, -ei / (ej * ej)];
            let c = &filter_covariance;
            let var = g[0] * g[0] * c[i][i] + 2.0 * g[0] * g[1] * c[i][j] + g[1] * g[1] * c[j][j];
            (rel, var.max(0.0).sqrt())
        };
        let (rp, sp) = relative(0, 1);
        let (rs, ss) = relative(1, 0);
        // Excitation is what the data tell; the published uncertainty adds
        // what no data of this vessel can: how unlike its propellers are.
        let published = |s: f64| s.hypot(self.propeller_mismatch_sigma);
        // The comparison is one quantity, told in two ways: the weaker
        // propeller's relative loss has the narrower uncertainty (it
        // divides by the stronger one's effectiveness), and once it is
        // within the bar the data tell both sides.
        let bar = if comparison_was_told {
            self.relative_release_sigma
        } else {
            self.relative_excitation_sigma
        };
        let pair_excited = yaw_balance_told && sp.min(ss) <= bar;
        let relative_excited = [pair_excited; 2];
        let relative_weakly_told =
            [!pair_excited && yaw_balance_told && sp.min(ss) <= self.relative_release_sigma; 2];
        let excited = sigma.map(|s| common_part_told && s <= self.excitation_sigma);
        // Where the data do not tell the losses themselves, the losses
        // published are the smallest the comparison of the propellers
        // allows (a loss is never negative): the weaker propeller's
        // relative loss, none on the other. A propeller that fails does so
        // alone far more often than both lose alike, and the uncertainty
        // (with the common part's floor) still covers the case where they
        // do. One rule whether or not the comparison is excited yet, so that
        // the published loss does not jump when its excitation comes or goes.
        let weaker = usize::from(rs > rp);
        let loss = if !excited[0] && !excited[1] {
            let mut smallest = [0.0; 2];
            smallest[weaker] = [rp, rs][weaker].max(0.0);
            smallest
        } else {
            loss
        };
        LossReading {
            loss,
            sigma,
            covariance,
            relative_loss: [rp, rs],
            relative_sigma: [published(sp), published(ss)],
            // The data pin a loss down when its standard deviation, with
            // everything else unknown, is within the bar: the prior alone
            // never is.
            excited,
            relative_excited,
            relative_weakly_told,
        }
    }
}

/// The shaft-speed samples around the last interval between fixes: the
/// kinetic base's input is the mean shaft speed over the interval.
///
/// The mean is of the samples' piecewise-linear interpolant over the
/// interval, the sample before it included: a logger that writes the
/// shaft speed at each fix's instant (before or after the fix), or faster,
/// gives the same mean, and the change of shaft speed within the interval
/// is not shifted by half an interval. Without samples in the interval the
/// last one holds while it is at most `max_age_s` old.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ShaftAccumulator {
    /// Time-weighted integral of each shaft speed since `start`, rad.
    integral: [f64; 2],
    /// Where the integral starts, s.
    start_s: Option<f64>,
    /// Samples since the last [`Self::take`].
    count: u32,
    last: Option<PropellerSpeeds>,
}

impl ShaftAccumulator {
    /// Adds a sample.
    pub fn push(&mut self, p: &PropellerSpeeds) {
        if let Some(prev) = self.last
            && p.time_s > prev.time_s
        {
            // Trapezoid from the later of the previous sample and the
            // interval's start.
            let from = self.start_s.map_or(prev.time_s, |s| s.max(prev.time_s));
            if p.time_s > from {
                let w = (from - prev.time_s) / (p.time_s - prev.time_s);
                let at_from = [
                    prev.port_radps + w * (p.port_radps - prev.port_radps),
                    prev.starboard_radps + w * (p.starboard_radps - prev.starboard_radps),
                ];
                let span = p.time_s - from;
                self.integral[0] += 0.5 * (at_from[0] + p.port_radps) * span;
                self.integral[1] += 0.5 * (at_from[1] + p.starboard_radps) * span;
                self.start_s.get_or_insert(from);
            }
        }
        self.count += 1;
        self.last = Some(*p);
    }

    /// Samples since the last [`Self::take`].
    pub fn count(&self) -> u32 {
        self.count
    }

    /// The mean shaft speeds over the interval ending at `time_s` and starts
    /// the next interval there; without a sample in the interval, the last
    /// sample if it is at most `max_age_s` older than `time_s`, else `None`.
    pub fn take(&mut self, time_s: f64, max_age_s: f64) -> Option<ShaftSpeeds> {
        let last = self.last?;
        let fresh = self.count > 0;
        let result = match self.start_s {
            Some(start) if fresh && time_s > start => {
                // The last sample holds to the end of the interval.
                let mut integral = self.integral;
                let end = time_s.max(last.time_s);
                integral[0] += last.port_radps * (end - last.time_s);
                integral[1] += last.starboard_radps * (end - last.time_s);
                let span = end - start;
                Some(ShaftSpeeds {
                    port_radps: integral[0] / span,
                    starboard_radps: integral[1] / span,
                })
            }
            _ if fresh || time_s - last.time_s <= max_age_s => Some(ShaftSpeeds {
                port_radps: last.port_radps,
                starboard_radps: last.starboard_radps,
            }),
            _ => None,
        };
        // The next interval starts at this fix.
        self.integral = [0.0; 2];
        self.start_s = Some(time_s.max(last.time_s));
        self.count = 0;
        result
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geodesy::NorthEast;

    /// The course's variance is the configured one at cruise speed, the
    /// speed's variance over the speed squared where that is larger (a
    /// slow vessel), and the configured one where the course is not used.
    #[test]
    fn the_course_is_as_noisy_as_the_velocity_over_the_speed() {
        let config = KineticConfig::otter();
        let gate = CourseGate { min_sog_mps: 0.3 };
        let base = KineticBase::new(&config, gate, KineticOptions::live(true, true)).unwrap();
        let r = config.filter.measurement_noise;
        let (course, speed) = (r[(meas::COG, meas::COG)], r[(meas::SOG, meas::SOG)]);
        let fix = |sog_mps: Option<f64>| LocalFix {
            time_s: 0.0,
            position: NorthEast {
                north_m: 0.0,
                east_m: 0.0,
            },
            position_measured: true,
            sog_mps,
            cog_rad: Some(0.3),
            heading_rad: None,
            yaw_rate_radps: None,
            stw_mps: None,
        };
        // 0.05 m/s over 3 m/s is 0.017 rad, within the configured 0.03.
        assert_eq!(base.course_variance(&fix(Some(3.0))), course);
        // At 0.8 m/s the velocity's noise gives 0.0625 rad.
        let slow = base.course_variance(&fix(Some(0.8)));
        assert!((slow - speed / 0.64).abs() < 1e-15, "{slow}");
        assert!(slow > 4.0 * course);
        // Below the gate's speed the course is not used.
        assert_eq!(base.course_variance(&fix(Some(0.1))), course);
        assert_eq!(base.course_variance(&fix(None)), course);
    }

    /// The Otter's velocity noise written in [`KineticConfig::otter_with`]
    /// is the formula of [`harbour_velocity_noise`] for its mass matrix,
    /// rounded to two digits.
    #[test]
    fn the_harbour_noise_formula_gives_the_otters_numbers() {
        let written = KineticConfig::otter_with(1.0).filter.process_noise_density;
        let computed = harbour_velocity_noise(&VesselParams::default());
        for (i, a) in [idx::U, idx::V, idx::R].into_iter().enumerate() {
            for (j, b) in [idx::U, idx::V, idx::R].into_iter().enumerate() {
                let (w, c) = (written[(a, b)], computed[(i, j)]);
                if i != j && (i == 0 || j == 0) {
                    assert_eq!(w, 0.0);
                    assert!(c.abs() < 1e-12, "({i}, {j}): {c}");
                } else {
                    assert!((w - c).abs() <= 0.02 * w.abs(), "({i}, {j}): {w} vs {c}");
                }
            }
        }
    }

    /// An identified profile's filter takes the water's random forces
    /// alone; its forecasts propagate the unidentified profile's allowance
    /// for what the profile does not model, and nothing else changes.
    #[test]
    fn an_identified_profiles_forecast_keeps_the_unmodelled_forces() {
        let unidentified = KineticConfig::otter();
        let identified = KineticConfig::otter().with_identified_profile([0.05; 4]);
        let (q_filter, q_before) = (
            identified.filter.process_noise_density,
            unidentified.filter.process_noise_density,
        );
        assert!(q_filter[(idx::U, idx::U)] < q_before[(idx::U, idx::U)] / 4.0);
        let q_forecast = identified.forecast_process_noise_density(&q_filter);
        for i in 0..STATES {
            for j in 0..STATES {
                let expected = q_before[(i, j)];
                assert!(
                    (q_forecast[(i, j)] - expected).abs() <= 1e-12 * expected.abs(),
                    "({i}, {j}): {} vs {expected}",
                    q_forecast[(i, j)]
                );
            }
        }
        // On an unidentified profile the forecast's noise is the filter's.
        assert_eq!(
            unidentified.forecast_process_noise_density(&q_before),
            q_before
        );
    }

    /// A vessel twice the Otter's mass matrix, alike in shape, feels forces
    /// 2^(2/3) times the Otter's (in yaw also times its length ratio) and
    /// so accelerations 2^(2/3) / 2 times as strong: variances times
    /// 2^(-2/3) (and 2^(4/3) 2^(-2) in yaw with a length of 4 m).
    #[test]
    fn a_heavier_hull_takes_less_noise_per_mass() {
        let otter = VesselParams::default();
        let mut big = otter;
        big.mass_kg *= 2.0;
        big.mass_matrix *= 2.0;
        big.length_m *= 2.0;
        let (q0, q1) = (harbour_velocity_noise(&otter), harbour_velocity_noise(&big));
        let surge = q1[(0, 0)] / q0[(0, 0)];
        assert!((surge - 2f64.powf(-2.0 / 3.0)).abs() < 1e-9, "{surge}");
        let config = KineticConfig::for_vessel(big, 1.0);
        assert_eq!(config.params, big);
        assert_eq!(
            config.filter.process_noise_density[(idx::U, idx::U)],
            q1[(0, 0)]
        );
        assert_eq!(
            config.filter.process_noise_density[(idx::R, idx::V)],
            q1[(2, 1)]
        );
    }

    /// The Otter's configurations are the ones written out, whichever way
    /// they are reached.
    #[test]
    fn the_otter_reached_through_a_profile_is_the_written_otter() {
        let otter = VesselParams::default();
        assert_eq!(
            KineticConfig::for_vessel(otter, 5.0),
            KineticConfig::otter()
        );
        // An identified profile's filter is the one of a profile known to
        // be the vessel's own; only its forecasts' allowance differs.
        let identified = KineticConfig::otter().with_identified_profile([0.01; 4]);
        let own = KineticConfig::identified([0.01; 4]);
        assert_eq!(identified.filter, own.filter);
        assert_eq!(
            identified.forecast_force_factor,
            KineticConfig::UNMODELLED_FORCE_FACTOR
        );
        assert_eq!(own.forecast_force_factor, 1.0);
        assert_eq!(
            KineticConfig {
                forecast_force_factor: 1.0,
                ..identified
            },
            own
        );
        assert_eq!(
            KineticConfig::otter().for_search().filter,
            KineticConfig::otter_with(1.0).filter
        );
    }
}
