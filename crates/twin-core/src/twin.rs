//! The vessel twin: one vessel's estimators, fed measurement by measurement.
//!
//! This is what the daemon runs per vessel and what `twin analyze` runs over a
//! log, so both give the same numbers for the same data. It owns
//! - the local frame (origin at the first accepted fix);
//! - the validation of every measurement, with a typed [`Rejection`] that
//!   leaves the estimate exactly as it was;
//! - the seed's method: inputs derived from GNSS, the kinematic model in the
//!   adaptive EKF, and the seed's step 4 to per-thruster "faults" (kept for
//!   comparison: docs/model.md section 5 explains why it cannot see a thrust loss);
//! - the extended twin: the Otter's kinetic model driven by the measured
//!   propeller speeds, estimating each propeller's loss and the water current,
//!   active while propeller data arrive;
//! - the fault decision and the forecasts.
//!
//! Timing rules (documented for the daemon):
//! - a fix must be newer than the last accepted fix: an equal time is a
//!   [`Rejection::Duplicate`], an older one [`Rejection::TimeWentBackwards`],
//!   except one older by more than [`GatingConfig::reinitialise_after_gap_s`]:
//!   that is a new track (a restarted source, a replay starting over) and
//!   restarts the state estimate, keeping the calibration;
//! - the filter steps on message time; a gap longer than
//!   [`GatingConfig::reinitialise_after_gap_s`] restarts the state estimate
//!   from the next fix (the calibration, i.e. the fault estimate, is kept);
//! - propeller samples are averaged over each GNSS interval; if none arrived
//!   within [`KineticConfig::max_propeller_age_s`] the extended twin holds
//!   and restarts its state when they return.

use nalgebra::{SMatrix, SVector, Vector2};

use crate::aekf::{AekfError, AekfState, StepReport};
use crate::decision::{
    DecisionConfig, FaultDecider, LossEvidence, StatusChange, ThrusterDecision, ThrusterStatus,
};
use crate::estimator::seed::step_four;
use crate::estimator::{
    CourseGate, KineticBase, KineticOptions, KineticReport, KineticState, Learnt, LocalFix,
    RateSensorBias, SeedBase, SeedInputs, ShaftAccumulator, Surroundings, Term,
};
pub use crate::estimator::{KineticConfig, SeedConfig};
use crate::geodesy::{LatLon, LocalFrame, NorthEast, wrap_two_pi};
use crate::inputs::InputConfigError;
use crate::model::Model;
use crate::models::kinematic::KinematicInput;
use crate::models::otter_twin::{FAULTS, MEASUREMENTS, STATES, ShaftSpeeds, fault, idx, meas};
use crate::predict::{PredictedPoint, predict};
use crate::sample::{GnssFix, PropellerSpeeds, Side};
use crate::vessel::VesselParams;

/// Why a measurement was not used. The estimate is unchanged after any.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum Rejection {
    /// A number is NaN or infinite.
    #[error("non-finite {field}")]
    NonFinite {
        /// Which field.
        field: &'static str,
    },
    /// A value is outside its physical range.
    #[error("{field} = {value} is out of range")]
    OutOfRange {
        /// Which field.
        field: &'static str,
        /// The value received.
        value: f64,
    },
    /// The same time as the last accepted measurement of its kind.
    #[error("duplicate time stamp {time_s}")]
    Duplicate {
        /// The repeated time, s.
        time_s: f64,
    },
    /// Older than the last accepted measurement of its kind.
    #[error("time went backwards by {by_s} s")]
    TimeWentBackwards {
        /// How much older, s.
        by_s: f64,
    },
    /// A time far from the vessel's timeline (beyond the longest gap ahead,
    /// or farther back than a fix out of order), not yet confirmed by fixes
    /// that agree with it.
    #[error("time jumped {by_s} s")]
    TimeJump {
        /// How far from the last accepted fix, s (negative: back).
        by_s: f64,
    },
    /// A position jump faster than any vessel of this kind moves.
    #[error("position jumped {distance_m:.0} m in {dt_s:.2} s")]
    Jump {
        /// Distance from the expected position, m.
        distance_m: f64,
        /// Time since the last accepted fix, s.
        dt_s: f64,
    },
    /// The filter refused the step (non-positive-definite matrix and the like).
    #[error("estimator refused the step: {0}")]
    Estimator(AekfError),
}

impl Rejection {
    /// A short, stable name for counting rejections by reason.
    pub fn reason(&self) -> &'static str {
        match self {
            Rejection::NonFinite { .. } => "non_finite",
            Rejection::OutOfRange { .. } => "out_of_range",
            Rejection::Duplicate { .. } => "duplicate",
            Rejection::TimeWentBackwards { .. } => "time_backwards",
            Rejection::TimeJump { .. } => "time_jump",
            Rejection::Jump { .. } => "position_jump",
            Rejection::Estimator(_) => "estimator",
        }
    }
}

/// Validation limits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GatingConfig {
    /// Fastest credible speed over ground, m/s; a fix implying more is a jump.
    pub max_speed_mps: f64,
    /// Slack on the jump test for position noise, m.
    pub jump_slack_m: f64,
    /// After this many consecutive jump rejections that agree with each
    /// other, the vessel really is there: restart from them.
    pub jumps_before_restart: u32,
    /// A gap in fixes longer than this starts a new track (the state
    /// estimate restarts; what the twin learnt about the vessel is kept);
    /// a fix older than the last accepted one by more than this is far
    /// from the timeline, s.
    pub reinitialise_after_gap_s: f64,
    /// A fix later than the last accepted one by more than this is far
    /// from the vessel's timeline: refused until fixes that agree with it
    /// confirm a new track, s.
    pub max_gap_s: f64,
    /// Below this speed over ground the course is meaningless and masked, m/s.
    pub min_sog_for_course_mps: f64,
    /// Fastest credible yaw rate, rad/s; a fix reporting more is refused.
    pub max_yaw_rate_radps: f64,
}

impl Default for GatingConfig {
    fn default() -> Self {
        Self {
            max_speed_mps: 20.0,
            jump_slack_m: 25.0,
            jumps_before_restart: 5,
            reinitialise_after_gap_s: 30.0,
            max_gap_s: 3600.0,
            min_sog_for_course_mps: 0.3,
            max_yaw_rate_radps: 5.0,
        }
    }
}

/// Everything the twin of one vessel is configured with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TwinConfig {
    /// Validation limits.
    pub gating: GatingConfig,
    /// The seed's method.
    pub seed: SeedConfig,
    /// The extended twin.
    pub kinetic: KineticConfig,
    /// Fault decision thresholds.
    pub decision: DecisionConfig,
}

impl Default for TwinConfig {
    fn default() -> Self {
        Self {
            gating: GatingConfig::default(),
            seed: SeedConfig::seed(),
            kinetic: KineticConfig::otter(),
            decision: DecisionConfig::default(),
        }
    }
}

impl TwinConfig {
    /// The twin of a vessel whose profile is its own, known to
    /// `profile_sigma` (the relative standard deviations of its surge
    /// damping, yaw damping, thrust coefficient and mass):
    /// [`KineticConfig::identified`]. With it the losses themselves, not
    /// only how the propellers compare, can be told. The default assumes
    /// an unidentified profile; a profile identified from a trial is
    /// [`Self::with_identified_profile`].
    pub fn identified(profile_sigma: [f64; 4]) -> Self {
        Self {
            kinetic: KineticConfig::identified(profile_sigma),
            ..Self::default()
        }
    }

    /// This twin's tuning for the vessel `params` describes
    /// ([`KineticConfig::with_vessel`]).
    pub fn with_vessel(mut self, params: VesselParams) -> Self {
        self.kinetic = self.kinetic.with_vessel(params);
        self
    }

    /// This twin for the vessel `params` describes, its profile's errors
    /// known to `profile_sigma` (`None`: an unidentified profile, as the
    /// default): [`KineticConfig::for_vessel`] with the velocities'
    /// process noise of [`Self::default`] or [`Self::identified`].
    pub fn for_vessel(params: VesselParams, profile_sigma: Option<[f64; 4]>) -> Self {
        let twin = Self::default().with_vessel(params);
        match profile_sigma {
            Some(sigma) => twin.with_identified_profile(sigma),
            None => twin,
        }
    }

    /// This twin's tuning for a profile identified to `profile_sigma`
    /// ([`KineticConfig::with_identified_profile`]).
    pub fn with_identified_profile(mut self, profile_sigma: [f64; 4]) -> Self {
        self.kinetic = self.kinetic.with_identified_profile(profile_sigma);
        self
    }
}

/// Which estimator a fault estimate comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FaultSource {
    /// The extended twin: per-propeller losses from propeller speeds.
    Kinetic,
    /// The seed's method: per-thruster values from its input faults (step 4).
    /// Not a measurement of thrust loss (docs/model.md section 5).
    SeedMethod,
}

/// The fault estimate of one thruster.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThrusterEstimate {
    /// Estimated loss of effectiveness (raw: may leave [0, 1] slightly).
    pub loss: f64,
    /// Its standard deviation, with everything else the twin estimates
    /// unknown (the other loss, the hull's damping): where the losses'
    /// common part cannot be told from the hull's drag, this is as wide as
    /// that ignorance.
    pub sigma: f64,
    /// Whether the recent data can tell the loss on its own.
    pub excited: bool,
    /// The loss relative to the other propeller, `1 - (1 - loss) / (1 -
    /// other's loss)`: what the yaw balance measures even where the losses'
    /// common part is unknown.
    pub relative_loss: f64,
    /// Its standard deviation.
    pub relative_sigma: f64,
    /// Whether the recent data can tell the relative loss.
    pub relative_excited: bool,
    /// Whether they tell it only weakly (a fault from it must last longer,
    /// `twin_core::decision`).
    pub relative_weakly_told: bool,
    /// The decision about it.
    pub decision: ThrusterDecision,
}

/// The fault picture at one time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FaultReport {
    /// Time, s.
    pub time_s: f64,
    /// Which estimator.
    pub source: FaultSource,
    /// Port and starboard.
    pub thrusters: [ThrusterEstimate; 2],
    /// The worst status.
    pub status: ThrusterStatus,
    /// The seed method's input faults `[theta_a, theta_r]`.
    pub seed_input_faults: Vector2<f64>,
    /// Covariance of the two loss estimates (`[[port, cross], [cross,
    /// starboard]]`), NaN for the seed's method. On a straight run the two
    /// losses are strongly correlated: their ratio is known far better than
    /// either.
    pub loss_covariance: [[f64; 2]; 2],
    /// The extended twin's estimates of the relative errors of the
    /// profile's surge damping, yaw damping, thrust coefficient and mass,
    /// `[(value, sigma); 4]` (a hull 30 % draggier than its profile: surge
    /// 0.3); `None` for the seed's method.
    pub profile_errors: Option<[(f64, f64); 4]>,
    /// Where the comparison of the propellers is withheld because the
    /// profile does not describe the vessel, what shows it
    /// ([`VesselTwin::profile_mismatch`]); `None` otherwise.
    pub profile_mismatch: Option<ProfileMismatch>,
}

impl FaultReport {
    /// The ratio of the port to the starboard propeller's effectiveness,
    /// `(1 - loss_port) / (1 - loss_stb)`, and its standard deviation: what
    /// the yaw balance tells even on a straight run, and what the decisions
    /// judge when the losses' common part is unknown. From the port
    /// propeller's relative loss where the extended twin has one, else from
    /// the losses and their covariance (first order).
    pub fn effectiveness_ratio(&self) -> (f64, f64) {
        let port = &self.thrusters[0];
        if port.relative_loss.is_finite() && port.relative_sigma.is_finite() {
            return (1.0 - port.relative_loss, port.relative_sigma);
        }
        let (lp, ls) = (self.thrusters[0].loss, self.thrusters[1].loss);
        let ratio = (1.0 - lp) / (1.0 - ls);
        let grad = [-1.0 / (1.0 - ls), (1.0 - lp) / (1.0 - ls).powi(2)];
        let c = self.loss_covariance;
        let var = grad[0] * grad[0] * c[0][0]
            + 2.0 * grad[0] * grad[1] * c[0][1]
            + grad[1] * grad[1] * c[1][1];
        (ratio, var.max(0.0).sqrt())
    }
}

/// The state estimate at one time, in the frames users read.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StateReport {
    /// Time, s.
    pub time_s: f64,
    /// Position.
    pub position: LatLon,
    /// Position in the local frame.
    pub local: NorthEast,
    /// Standard deviations of north and east, m.
    pub position_sigma_m: [f64; 2],
    /// Speed over ground, m/s, and its standard deviation.
    pub sog_mps: f64,
    /// Standard deviation of the speed over ground, m/s.
    pub sog_sigma_mps: f64,
    /// Course over ground, rad in [0, 2 pi).
    pub cog_rad: f64,
    /// Standard deviation of the course, rad.
    pub cog_sigma_rad: f64,
    /// Heading, rad, where the estimator has it (the extended twin).
    pub heading_rad: Option<f64>,
    /// Water current `[north, east]`, m/s, where estimated.
    pub current_mps: Option<[f64; 2]>,
    /// Normalised innovation squared of the last step and its degrees of freedom.
    pub nis: f64,
    /// Degrees of freedom of `nis`.
    pub nis_dof: usize,
    /// Which estimator this is.
    pub source: FaultSource,
}

/// What one accepted fix produced.
#[derive(Debug, Clone, PartialEq)]
pub struct StepOutput {
    /// The state estimate after the fix.
    pub state: StateReport,
    /// The fault picture after the fix.
    pub faults: FaultReport,
    /// Status changes declared by this fix (alarms).
    pub changes: Vec<StatusChange>,
    /// The innovation of the reporting estimator (for residual analysis),
    /// `[north, east, sog, cog, heading, yaw rate]` (heading and yaw rate 0
    /// for the seed model), with which were available.
    pub innovation: [f64; MEASUREMENTS],
    /// Which innovation components were measured.
    pub innovation_available: [bool; MEASUREMENTS],
}

/// One predicted point in user frames.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForecastPoint {
    /// Time, s.
    pub time_s: f64,
    /// Position.
    pub position: LatLon,
    /// Local position.
    pub local: NorthEast,
    /// Standard deviations of north and east, m.
    pub position_sigma_m: [f64; 2],
    /// Speed over ground, m/s.
    pub sog_mps: f64,
    /// Course over ground, rad.
    pub cog_rad: f64,
}

/// A calibration to save and restore: what the twin has learnt about the
/// vessel, independent of where it is.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    /// Which estimator learnt it.
    pub source: FaultSource,
    /// Fault estimate: the extended twin's `[port loss, starboard loss,
    /// surge damping error, yaw damping error, thrust error, mass error]`
    /// (`models::otter_twin::fault`), or the seed method's input faults
    /// `[theta_a, theta_r]`.
    pub theta: Vec<f64>,
    /// Fault covariance, row-major (`theta.len()` squared entries).
    pub theta_covariance: Vec<f64>,
    /// Held information per fault (the anti-windup memory).
    pub held_information: Vec<f64>,
    /// What the extended twin learnt of the water current and of its
    /// heading sensor's offset.
    pub surroundings: Option<Surroundings>,
    /// The decision per thruster.
    pub decisions: [ThrusterDecision; 2],
    /// Time of the last fix it was learnt from, s.
    pub time_s: f64,
}

impl Calibration {
    /// The faults of an estimator with `P` of them, if this calibration has
    /// that many.
    fn learnt<const P: usize>(&self) -> Option<Learnt<P>> {
        if self.theta.len() != P
            || self.theta_covariance.len() != P * P
            || self.held_information.len() != P
        {
            return None;
        }
        Some(Learnt {
            theta: SVector::from_column_slice(&self.theta),
            covariance: SMatrix::from_row_slice(&self.theta_covariance),
            held_information: SVector::from_column_slice(&self.held_information),
            surroundings: self.surroundings,
        })
    }

    /// This calibration after `elapsed_s` without data: what was learnt is
    /// kept, its uncertainty widened for what may have changed meanwhile
    /// (the faults by their prior `fault_prior` spread over an hour, the
    /// current by 0.5 m/s over ten minutes, the heading sensor's offset by
    /// its prior over a day, the rate sensor's bias, which changes each time
    /// a gyro is switched on, by its prior over an hour; each at most by its
    /// prior).
    fn aged(
        mut self,
        elapsed_s: f64,
        fault_prior: &[f64],
        current_prior: f64,
        bias_prior: f64,
        rate_bias_prior: f64,
    ) -> Self {
        let share = |over_s: f64| (elapsed_s.max(0.0) / over_s).min(1.0);
        let p = self.theta.len();
        for i in 0..p {
            self.theta_covariance[i * p + i] +=
                fault_prior.get(i).copied().unwrap_or(0.0) * share(3600.0);
        }
        if let Some(s) = &mut self.surroundings {
            s.covariance[0][0] += current_prior * share(600.0);
            s.covariance[1][1] += current_prior * share(600.0);
            s.covariance[2][2] += bias_prior * share(86_400.0);
            if let Some(g) = &mut s.yaw_rate_bias {
                g.variance += rate_bias_prior * share(3600.0);
            }
        }
        self
    }
}

/// The seed's method as the twin runs it: its base, its inputs, and the
/// running estimate.
#[derive(Debug, Clone)]
struct SeedEstimator {
    base: SeedBase,
    inputs: SeedInputs,
    state: Option<AekfState<4, 4, 2>>,
    last_report: Option<StepReport<4, 2>>,
    last_available: [bool; 4],
    thruster_loss: [Option<f64>; 2],
}

/// What shows that a vessel's profile does not describe it: the extended
/// twin's yaw damping, mass and thrust coefficient errors with the most
/// each may be
/// ([`KineticConfig::plausible_profile_sigmas`] of its prior), and the NIS
/// per degree of freedom over the filter's memory with its bound
/// ([`KineticConfig::max_explained_nis_per_dof`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProfileMismatch {
    /// The relative error of the profile's yaw damping the filter reached.
    pub yaw_damping_error: f64,
    /// The largest it may be.
    pub yaw_damping_bound: f64,
    /// The relative error of the profile's mass the filter reached.
    pub mass_error: f64,
    /// The largest it may be.
    pub mass_bound: f64,
    /// The relative error of the profile's thrust coefficient the filter
    /// reached.
    pub thrust_error: f64,
    /// The largest it may be.
    pub thrust_bound: f64,
    /// The NIS per degree of freedom over the filter's memory.
    pub nis_per_dof: f64,
    /// The largest it may be.
    pub max_nis_per_dof: f64,
}

/// The extended twin as the twin runs it: its base and the running
/// estimate.
#[derive(Debug, Clone)]
struct KineticEstimator {
    base: KineticBase,
    state: Option<KineticState>,
    last_report: Option<KineticReport>,
    last_available: [bool; MEASUREMENTS],
    last_input: Option<ShaftSpeeds>,
    /// Exponentially weighted mean of the unit heading vector over the
    /// filter's memory (see [`KineticConfig::min_heading_spread`]).
    heading_mean: [f64; 2],
    /// The yaw rates over the filter's memory
    /// ([`KineticConfig::min_yaw_rate_spread`]).
    yaw_rate_moments: YawRateMoments,
    /// Exponentially weighted means over the filter's memory of the NIS and
    /// of its degrees of freedom (see
    /// [`KineticConfig::max_explained_nis_per_dof`]).
    nis_moments: [f64; 2],
    /// Whether the comparison of the propellers was excited at the last
    /// fix ([`KineticConfig::relative_release_sigma`]).
    comparison_told: bool,
}

impl KineticEstimator {
    /// The NIS per degree of freedom over the filter's memory (0 before
    /// the first update).
    fn nis_per_dof(&self) -> f64 {
        let [nis, dof] = self.nis_moments;
        if dof > 0.0 { nis / dof } else { 0.0 }
    }

    /// Where the profile no longer describes the vessel well enough for the
    /// yaw balance to compare the propellers, what shows it: a yaw damping,
    /// mass or thrust coefficient error beyond
    /// [`KineticConfig::plausible_profile_sigmas`] of its prior, or data
    /// unexplained
    /// ([`KineticConfig::max_explained_nis_per_dof`]); `None` where it does.
    fn profile_mismatch(
        &self,
        state: &KineticState,
        config: &KineticConfig,
    ) -> Option<ProfileMismatch> {
        let k = config.plausible_profile_sigmas;
        // `profile_sigma` is in the faults' order from the surge damping on.
        let bound = |i: usize| k * config.profile_sigma[i - fault::SURGE_DAMPING];
        let m = ProfileMismatch {
            yaw_damping_error: state.theta[fault::YAW_DAMPING],
            yaw_damping_bound: bound(fault::YAW_DAMPING),
            mass_error: state.theta[fault::MASS],
            mass_bound: bound(fault::MASS),
            thrust_error: state.theta[fault::THRUST],
            // An identification holds the thrust coefficient (the force
            // scale it identifies the rest against), so the small standard
            // deviation it gives it is no measure of how far the filter may
            // move it: a loss's common part moves it too (a port loss of
            // 0.25 took it to +0.23 on an identified profile). Beyond an
            // unidentified profile's bound, more than one propeller's loss
            // can account for, the profile no longer describes the vessel.
            thrust_bound: bound(fault::THRUST).max(k * KineticConfig::UNIDENTIFIED_PROFILE_SIGMA),
            nis_per_dof: self.nis_per_dof(),
            max_nis_per_dof: config.max_explained_nis_per_dof,
        };
        let describes = m.yaw_damping_error.abs() <= m.yaw_damping_bound
            && m.mass_error.abs() <= m.mass_bound
            && m.thrust_error.abs() <= m.thrust_bound
            && m.nis_per_dof <= m.max_nis_per_dof;
        (!describes).then_some(m)
    }

    /// Moves the running means of the heading and the yaw rate towards the
    /// estimate, and those of the NIS towards the last step's, after a step
    /// of `dt_s`; or starts them at the estimate (the NIS's empty).
    fn track_motion(&mut self, dt_s: Option<f64>) {
        let Some(state) = &self.state else { return };
        let (sin_h, cos_h) = state.x[idx::PSI].sin_cos();
        let w = dt_s.map_or(1.0, |dt| 1.0 - self.base.filter().lambda(dt));
        let m = &mut self.heading_mean;
        m[0] += w * (cos_h - m[0]);
        m[1] += w * (sin_h - m[1]);
        match dt_s {
            Some(_) => self.yaw_rate_moments.add(state.x[idx::R], w),
            None => self.yaw_rate_moments = YawRateMoments::default(),
        }
        match (dt_s, &self.last_report) {
            (Some(_), Some(report)) if report.nis.is_finite() => {
                let m = &mut self.nis_moments;
                m[0] += w * (report.nis - m[0]);
                m[1] += w * (report.dof as f64 - m[1]);
            }
            (None, _) => self.nis_moments = [0.0; 2],
            _ => {}
        }
        if dt_s.is_none() {
            self.comparison_told = false;
        }
    }

    /// Whether the yaw rates over the filter's memory separate a difference
    /// of the losses from a yaw damping error
    /// ([`KineticConfig::min_yaw_rate_spread`]).
    fn yaw_balance_told(&self, config: &KineticConfig) -> bool {
        self.yaw_rate_moments.tell_yaw_balance(config)
    }

    /// How much the heading has varied over the filter's memory:
    /// `1 - |mean unit heading vector|` (0 on a straight line, 1 - 2/pi for
    /// a half circle).
    fn heading_spread(&self) -> f64 {
        1.0 - self.heading_mean[0].hypot(self.heading_mean[1])
    }
}

/// Exponentially weighted sums over the filter's memory of the yaw rate,
/// of its square where it turns to starboard and to port (their sum is
/// the square's), and of the weights, since the estimate started
/// ([`KineticConfig::min_yaw_rate_spread`]). The means are the sums over
/// the weights, so the start's guess counts as one sample, not as a
/// memory's worth; the weight itself is how much of a memory the data
/// fill (`1 - e^(-t / T)` after `t` of a memory `T`).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct YawRateMoments {
    sum: f64,
    sum_square_starboard: f64,
    sum_square_port: f64,
    weight: f64,
}

impl YawRateMoments {
    /// Moves the sums towards the yaw rate `r_radps` with weight `w`
    /// (`1 - lambda` of the step).
    fn add(&mut self, r_radps: f64, w: f64) {
        let square = r_radps * r_radps;
        let (starboard, port) = if r_radps > 0.0 {
            (square, 0.0)
        } else {
            (0.0, square)
        };
        for (sum, sample) in [
            (&mut self.sum, r_radps),
            (&mut self.sum_square_starboard, starboard),
            (&mut self.sum_square_port, port),
            (&mut self.weight, 1.0),
        ] {
            *sum += w * (sample - *sum);
        }
    }

    /// Whether these yaw rates separate a difference of the losses from a
    /// yaw damping error: a straight run that fills
    /// [`KineticConfig::straight_run_min_fill`] of the memory, or rates
    /// spread ([`KineticConfig::min_yaw_rate_spread`]) with each way of
    /// turning holding [`KineticConfig::min_turn_share`] of their mean
    /// square.
    fn tell_yaw_balance(&self, config: &KineticConfig) -> bool {
        let Some((rms, std)) = self.rms_and_std() else {
            return false;
        };
        if rms <= config.straight_yaw_rate_radps {
            // A straight run: the heading's small corrections are no turns
            // either way.
            return self.weight >= config.straight_run_min_fill;
        }
        let each_way = self.sum_square_starboard.min(self.sum_square_port)
            >= config.min_turn_share * self.sum_square();
        std >= config.min_yaw_rate_spread * rms && each_way
    }

    /// The weighted sum of the squares, both ways of turning.
    fn sum_square(&self) -> f64 {
        self.sum_square_starboard + self.sum_square_port
    }

    /// The yaw rate's root mean square and standard deviation, rad/s;
    /// `None` before the first rate.
    fn rms_and_std(&self) -> Option<(f64, f64)> {
        if self.weight <= 0.0 {
            return None;
        }
        let mean = self.sum / self.weight;
        let mean_square = (self.sum_square() / self.weight).max(0.0);
        Some((
            mean_square.sqrt(),
            (mean_square - mean * mean).max(0.0).sqrt(),
        ))
    }
}

/// What [`VesselTwin::on_gnss`] can have changed when a step fails: the
/// frame, the seed's estimator (stepped before the extended filter), the
/// extended filter's state where a restart cleared it (its filter leaves it
/// unchanged when a step fails), and the propeller samples. The decision is
/// updated only after every fallible point.
struct StepUndo {
    frame: Option<LocalFrame>,
    restored: Option<Option<Calibration>>,
    seed: SeedEstimator,
    kinetic_state: Option<Option<KineticState>>,
    propellers: ShaftAccumulator,
    last_propeller_time_s: Option<f64>,
}

impl StepUndo {
    fn of(twin: &VesselTwin, restart: bool) -> Self {
        Self {
            frame: twin.frame,
            restored: restart.then(|| twin.restored.clone()),
            seed: twin.seed.clone(),
            kinetic_state: restart.then_some(twin.kinetic.state),
            propellers: twin.propellers,
            last_propeller_time_s: twin.last_propeller_time_s,
        }
    }

    fn restore(self, twin: &mut VesselTwin) {
        twin.frame = self.frame;
        if let Some(restored) = self.restored {
            twin.restored = restored;
        }
        twin.seed = self.seed;
        if let Some(state) = self.kinetic_state {
            twin.kinetic.state = state;
        }
        twin.propellers = self.propellers;
        twin.last_propeller_time_s = self.last_propeller_time_s;
    }
}

/// The twin of one vessel.
#[derive(Debug, Clone)]
pub struct VesselTwin {
    config: TwinConfig,
    frame: Option<LocalFrame>,
    last_fix: Option<(f64, NorthEast)>,
    jump_run: Vec<(f64, NorthEast)>,
    seed: SeedEstimator,
    kinetic: KineticEstimator,
    propellers: ShaftAccumulator,
    last_propeller_time_s: Option<f64>,
    decider: FaultDecider,
    restored: Option<Calibration>,
}

/// Why a twin cannot be configured.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum TwinConfigError {
    /// A filter's tuning is unusable.
    #[error("filter: {0}")]
    Filter(#[from] AekfError),
    /// The input derivation is unusable.
    #[error("input derivation: {0}")]
    Inputs(#[from] InputConfigError),
}

impl VesselTwin {
    /// A twin with `config` that has seen nothing yet.
    pub fn new(config: TwinConfig) -> Result<Self, TwinConfigError> {
        let gate = CourseGate {
            min_sog_mps: config.gating.min_sog_for_course_mps,
        };
        Ok(Self {
            seed: SeedEstimator {
                base: SeedBase::new(&config.seed, gate)?,
                inputs: SeedInputs::new(&config.seed)?,
                state: None,
                last_report: None,
                last_available: [false; 4],
                thruster_loss: [None, None],
            },
            kinetic: KineticEstimator {
                base: KineticBase::new(
                    &config.kinetic,
                    gate,
                    KineticOptions::live(
                        config.kinetic.estimate_current,
                        config.kinetic.estimate_yaw_rate_bias,
                    ),
                )?,
                state: None,
                last_report: None,
                last_available: [false; MEASUREMENTS],
                heading_mean: [0.0; 2],
                yaw_rate_moments: YawRateMoments::default(),
                nis_moments: [0.0; 2],
                comparison_told: false,
                last_input: None,
            },
            config,
            frame: None,
            last_fix: None,
            jump_run: Vec::new(),
            propellers: ShaftAccumulator::default(),
            last_propeller_time_s: None,
            decider: FaultDecider::new(config.decision),
            restored: None,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &TwinConfig {
        &self.config
    }

    /// The local frame, once the first fix fixed its origin.
    pub fn frame(&self) -> Option<&LocalFrame> {
        self.frame.as_ref()
    }

    /// Whether the extended twin (propeller data) is running.
    pub fn kinetic_active(&self) -> bool {
        self.kinetic.state.is_some()
    }

    /// Takes a propeller-speed sample.
    pub fn on_propellers(&mut self, p: &PropellerSpeeds) -> Result<(), Rejection> {
        for (field, v) in [
            ("time", p.time_s),
            ("port", p.port_radps),
            ("starboard", p.starboard_radps),
        ] {
            if !v.is_finite() {
                return Err(Rejection::NonFinite { field });
            }
        }
        for (field, v) in [("port", p.port_radps), ("starboard", p.starboard_radps)] {
            // 3x the Otter's shaft limit: anything beyond is not a shaft speed.
            if v.abs() > 3.0 * self.config.kinetic.params.max_shaft_speed_radps {
                return Err(Rejection::OutOfRange { field, value: v });
            }
        }
        if let Some(last) = self.last_propeller_time_s {
            if p.time_s == last {
                return Err(Rejection::Duplicate { time_s: p.time_s });
            }
            let gap = self.config.gating.reinitialise_after_gap_s;
            if p.time_s < last && p.time_s >= last - gap {
                return Err(Rejection::TimeWentBackwards {
                    by_s: last - p.time_s,
                });
            }
            if p.time_s < last - gap {
                // A new track back in time (see `on_gnss`).
                self.propellers = ShaftAccumulator::default();
            }
        }
        self.last_propeller_time_s = Some(p.time_s);
        self.propellers.push(p);
        Ok(())
    }

    fn validate_fix(&self, fix: &GnssFix) -> Result<(), Rejection> {
        let finite = [
            ("time", Some(fix.time_s)),
            ("lat_deg", Some(fix.position.lat_deg)),
            ("lon_deg", Some(fix.position.lon_deg)),
            ("sog_mps", fix.sog_mps),
            ("cog_rad", fix.cog_rad),
            ("heading_rad", fix.heading_rad),
            ("yaw_rate_radps", fix.yaw_rate_radps),
            ("hdop", fix.hdop),
        ];
        for (field, v) in finite {
            if let Some(v) = v
                && !v.is_finite()
            {
                return Err(Rejection::NonFinite { field });
            }
        }
        if fix.position.lat_deg.abs() > 90.0 {
            return Err(Rejection::OutOfRange {
                field: "lat_deg",
                value: fix.position.lat_deg,
            });
        }
        if fix.position.lon_deg.abs() > 180.0 {
            return Err(Rejection::OutOfRange {
                field: "lon_deg",
                value: fix.position.lon_deg,
            });
        }
        if fix.position.lat_deg.abs() > 89.0 {
            return Err(Rejection::OutOfRange {
                field: "lat_deg (polar)",
                value: fix.position.lat_deg,
            });
        }
        if let Some(s) = fix.sog_mps
            && !(0.0..=self.config.gating.max_speed_mps * 2.0).contains(&s)
        {
            return Err(Rejection::OutOfRange {
                field: "sog_mps",
                value: s,
            });
        }
        // An angle beyond a turn either way is not a course or heading in
        // radians (most likely degrees).
        let tau = std::f64::consts::TAU;
        for (field, angle) in [("cog_rad", fix.cog_rad), ("heading_rad", fix.heading_rad)] {
            if let Some(a) = angle
                && !(-tau..=2.0 * tau).contains(&a)
            {
                return Err(Rejection::OutOfRange { field, value: a });
            }
        }
        if let Some(r) = fix.yaw_rate_radps
            && r.abs() > self.config.gating.max_yaw_rate_radps
        {
            return Err(Rejection::OutOfRange {
                field: "yaw_rate_radps",
                value: r,
            });
        }
        if let Some(h) = fix.hdop
            && h <= 0.0
        {
            return Err(Rejection::OutOfRange {
                field: "hdop",
                value: h,
            });
        }
        if let Some((t, _)) = self.last_fix {
            if fix.time_s == t {
                return Err(Rejection::Duplicate { time_s: t });
            }
            // A little back is an out-of-order fix. Far back may be a new
            // track (a restarted source, a looping replay), once confirmed
            // (`on_gnss`).
            if fix.time_s < t && fix.time_s >= t - self.config.gating.reinitialise_after_gap_s {
                return Err(Rejection::TimeWentBackwards {
                    by_s: t - fix.time_s,
                });
            }
        }
        Ok(())
    }

    /// Takes a GNSS fix: validates it, steps the estimators, updates the
    /// decision. On `Err` nothing changed.
    pub fn on_gnss(&mut self, fix: &GnssFix) -> Result<StepOutput, Rejection> {
        self.validate_fix(fix)?;
        let frame = match self.frame {
            Some(f) => f,
            None => LocalFrame::new(fix.position).map_err(|_| Rejection::OutOfRange {
                field: "lat_deg",
                value: fix.position.lat_deg,
            })?,
        };
        let ne = frame.to_local(fix.position);
        let g = self.config.gating;

        // Time and position against the last accepted fix.
        let mut restart = false;
        if let Some((t, last)) = self.last_fix {
            let dt = fix.time_s - t;
            let distance = (ne.north_m - last.north_m).hypot(ne.east_m - last.east_m);
            let far_in_time = dt > g.max_gap_s || dt < -g.reinitialise_after_gap_s;
            if far_in_time || distance > g.max_speed_mps * dt.max(0.0) + g.jump_slack_m {
                // A fix far from the vessel's timeline (a wild time stamp, a
                // source restarted in the past) or a position jump is
                // obeyed only once fixes that agree with each other confirm
                // it: one wild fix changes nothing.
                if !self.confirms_new_track(fix.time_s, ne) {
                    self.note_jump(fix.time_s, ne);
                    return Err(if far_in_time {
                        Rejection::TimeJump { by_s: dt }
                    } else {
                        Rejection::Jump {
                            distance_m: distance,
                            dt_s: dt,
                        }
                    });
                }
                restart = true;
            } else if dt > g.reinitialise_after_gap_s {
                // A real gap: a new track.
                restart = true;
            }
        }

        // A refused step leaves everything as it was: what the step can
        // change before its last fallible point is kept and put back on
        // `Err` (a copy of the whole twin, configuration included, cost more
        // than the rest of the twin's own work per fix).
        let undo = StepUndo::of(self, restart);
        self.frame = Some(frame);
        if restart {
            // A new track keeps what the twin learnt about the vessel.
            self.restored = self.carried_over(fix.time_s);
            self.seed.state = None;
            self.kinetic.state = None;
            if self.last_fix.is_some_and(|(t, _)| fix.time_s < t) {
                // A new track back in time: propeller samples start over too.
                self.last_propeller_time_s = None;
                self.propellers = ShaftAccumulator::default();
            }
        }
        let changes = match self.step_estimators(fix, ne, restart) {
            Ok(changes) => changes,
            Err(r) => {
                undo.restore(self);
                return Err(r);
            }
        };
        self.jump_run.clear();
        self.last_fix = Some((fix.time_s, ne));
        Ok(self.output(fix.time_s, changes))
    }

    /// Whether `time_s`, `ne` is the last of a run of refused fixes that
    /// agree with each other (each after the one before by at most the gap
    /// that starts a new track, and no farther from it than a vessel
    /// moves) long enough to start a new track.
    fn confirms_new_track(&mut self, time_s: f64, ne: NorthEast) -> bool {
        let g = self.config.gating;
        let consistent = self.jump_run.last().is_none_or(|(tj, pj)| {
            let dt = time_s - tj;
            let d = (ne.north_m - pj.north_m).hypot(ne.east_m - pj.east_m);
            dt > 0.0
                && dt <= g.reinitialise_after_gap_s
                && d <= g.max_speed_mps * dt + g.jump_slack_m
        });
        if !consistent {
            self.jump_run.clear();
        }
        (self.jump_run.len() as u32) + 1 >= g.jumps_before_restart
    }

    /// Records a refused jump so that a run of consistent ones can restart
    /// the estimate. Bookkeeping only: the estimate is untouched.
    fn note_jump(&mut self, time_s: f64, ne: NorthEast) {
        self.jump_run.push((time_s, ne));
        if self.jump_run.len() > 16 {
            self.jump_run.remove(0);
        }
    }

    /// Steps both estimators to `fix` (at `ne` in the local frame) and
    /// updates the decision; `restarted` when the state estimate starts over.
    fn step_estimators(
        &mut self,
        fix: &GnssFix,
        ne: NorthEast,
        restarted: bool,
    ) -> Result<Vec<StatusChange>, Rejection> {
        let dt = self.last_fix.map(|(t, _)| fix.time_s - t);
        let local = LocalFix::at(fix, ne);
        self.step_seed(&local, dt, restarted)?;
        let input = self
            .propellers
            .take(fix.time_s, self.config.kinetic.max_propeller_age_s);
        self.step_kinetic(&local, input, dt)?;

        // The decision, from the extended twin where it runs.
        let faults = self.fault_report(fix.time_s);
        Ok(match faults.source {
            FaultSource::Kinetic => {
                let evidence = faults.thrusters.map(|t| LossEvidence {
                    loss: t.loss,
                    sigma: t.sigma,
                    excited: t.excited,
                    relative_loss: t.relative_loss,
                    relative_sigma: t.relative_sigma,
                    relative_excited: t.relative_excited,
                    relative_weakly_told: t.relative_weakly_told,
                    profile_describes: faults.profile_mismatch.is_none(),
                });
                self.kinetic.comparison_told = faults.thrusters[0].relative_excited;
                self.decider.update(fix.time_s, evidence)
            }
            FaultSource::SeedMethod => Vec::new(),
        })
    }

    /// The seed's method: its inputs from the track, its step (or its first
    /// estimate), and step 4.
    fn step_seed(
        &mut self,
        fix: &LocalFix,
        dt: Option<f64>,
        restarted: bool,
    ) -> Result<(), Rejection> {
        let restored = self.restored_learnt::<2>(FaultSource::SeedMethod);
        let seed = &mut self.seed;
        let derived = seed
            .inputs
            .push(fix, restarted)
            .map_err(|_| Rejection::Estimator(AekfError::InvalidConfig("inputs")))?;
        match (&mut seed.state, dt) {
            (Some(state), Some(dt)) => {
                let input = derived.unwrap_or(seed.inputs.last());
                let report = seed
                    .base
                    .step(state, &input, fix, dt)
                    .map_err(Rejection::Estimator)?;
                seed.last_report = Some(report);
                seed.last_available = seed.base.measurement(fix).available;
                let yaw_accel = seed.inputs.record(fix.time_s, input);
                seed.thruster_loss = step_four(
                    &self.config.kinetic.params,
                    &self.config.seed,
                    state,
                    &input,
                    yaw_accel,
                );
            }
            _ => {
                seed.state = Some(seed.base.prior(fix, restored.as_ref()));
            }
        }
        Ok(())
    }

    /// The extended twin, while propeller data arrive: its step with the
    /// mean shaft speeds since the last fix (or its first estimate); without
    /// propeller data it stops.
    fn step_kinetic(
        &mut self,
        fix: &LocalFix,
        input: Option<ShaftSpeeds>,
        dt: Option<f64>,
    ) -> Result<(), Rejection> {
        let Some(u) = input else {
            self.kinetic.state = None;
            return Ok(());
        };
        let restored = self.restored_learnt::<FAULTS>(FaultSource::Kinetic);
        let kinetic = &mut self.kinetic;
        match (&mut kinetic.state, dt) {
            (Some(state), Some(dt)) => {
                let report = kinetic
                    .base
                    .step(state, &u, fix, dt)
                    .map_err(Rejection::Estimator)?;
                kinetic.last_report = Some(report);
                kinetic.last_available = kinetic.base.measurement(fix).available;
                kinetic.track_motion(Some(dt));
            }
            _ => {
                kinetic.state = Some(kinetic.base.prior(fix, restored.as_ref()));
                kinetic.track_motion(None);
            }
        }
        kinetic.last_input = Some(u);
        Ok(())
    }

    /// What a restored calibration learnt by `source` gives an estimator
    /// with `P` faults.
    fn restored_learnt<const P: usize>(&self, source: FaultSource) -> Option<Learnt<P>> {
        self.restored
            .as_ref()
            .filter(|c| c.source == source)
            .and_then(Calibration::learnt)
    }

    /// Restores a saved calibration: the next estimator started takes its
    /// faults (estimate, covariance, anti-windup memory) and, for the
    /// extended twin, the current and the heading sensor's offset from it,
    /// and the decisions hold. A calibration with a different number of
    /// faults (from another version of the twin) restores only the
    /// decisions.
    pub fn restore(&mut self, calibration: Calibration) {
        for side in Side::BOTH {
            self.decider
                .restore(side, calibration.decisions[side.index()]);
        }
        match calibration.source {
            FaultSource::Kinetic => {
                if let (Some(st), Some(l)) =
                    (&mut self.kinetic.state, calibration.learnt::<FAULTS>())
                {
                    st.theta = l.theta;
                    st.s = l.covariance;
                    st.held_information = l.held_information;
                }
            }
            FaultSource::SeedMethod => {
                if let (Some(st), Some(l)) = (&mut self.seed.state, calibration.learnt::<2>()) {
                    st.theta = l.theta;
                    st.s = l.covariance;
                    st.held_information = l.held_information;
                }
            }
        }
        self.restored = Some(calibration);
    }

    /// What the twin has learnt, to save.
    pub fn calibration(&self) -> Option<Calibration> {
        let time_s = self.last_fix.map(|(t, _)| t)?;
        let flat = |m: &[f64]| m.to_vec();
        let (source, theta, covariance, held, surroundings) = if let Some(k) = &self.kinetic.state {
            let (cn, ce, b) = (idx::CURRENT_NORTH, idx::CURRENT_EAST, idx::HEADING_BIAS);
            let slots = [cn, ce, b];
            let g = idx::YAW_RATE_BIAS;
            let surroundings = Surroundings {
                current_mps: [k.x[cn], k.x[ce]],
                heading_bias_rad: k.x[b],
                covariance: std::array::from_fn(|i| {
                    std::array::from_fn(|j| k.p[(slots[i], slots[j])])
                }),
                yaw_rate_bias: (self.kinetic.base.options().yaw_rate_bias == Term::Free).then(
                    || RateSensorBias {
                        radps: k.x[g],
                        variance: k.p[(g, g)],
                    },
                ),
            };
            (
                FaultSource::Kinetic,
                flat(k.theta.as_slice()),
                flat(k.s.transpose().as_slice()),
                flat(k.held_information.as_slice()),
                Some(surroundings),
            )
        } else if let Some(r) = &self.restored {
            return Some(r.clone());
        } else {
            let st = self.seed.state.as_ref()?;
            (
                FaultSource::SeedMethod,
                flat(st.theta.as_slice()),
                flat(st.s.transpose().as_slice()),
                flat(st.held_information.as_slice()),
                None,
            )
        };
        Some(Calibration {
            source,
            theta,
            theta_covariance: covariance,
            held_information: held,
            surroundings,
            decisions: [
                self.decider.decision(Side::Port),
                self.decider.decision(Side::Starboard),
            ],
            time_s,
        })
    }

    /// What the twin carries into a new track starting at `time_s`: what it
    /// has learnt (or had restored), its uncertainty widened for the time
    /// that passed.
    fn carried_over(&self, time_s: f64) -> Option<Calibration> {
        let c = self.calibration()?;
        let elapsed_s = (time_s - c.time_s).abs();
        let k = &self.config.kinetic;
        let fault_prior: Vec<f64> = match c.source {
            FaultSource::Kinetic => k
                .filter
                .initial_fault_covariance
                .diagonal()
                .iter()
                .copied()
                .collect(),
            FaultSource::SeedMethod => self
                .config
                .seed
                .filter
                .initial_fault_covariance
                .diagonal()
                .iter()
                .copied()
                .collect(),
        };
        Some(c.aged(
            elapsed_s,
            &fault_prior,
            k.initial_current_sigma_mps.powi(2),
            k.initial_heading_bias_sigma_rad.powi(2),
            k.initial_yaw_rate_bias_sigma_radps.powi(2),
        ))
    }

    /// The current fault picture at `time_s`.
    pub fn fault_report(&self, time_s: f64) -> FaultReport {
        let seed_theta = self
            .seed
            .state
            .map(|s| s.theta)
            .unwrap_or_else(SVector::zeros);
        let mismatch = self.profile_mismatch();
        let (source, thrusters, loss_covariance, profile_errors) = match &self.kinetic.state {
            Some(k) => {
                // With the current estimated, a loss both propellers share
                // and a current along the track slow the vessel alike until
                // it turns ([`KineticConfig::min_heading_spread`]).
                let common_part_told = !self.config.kinetic.estimate_current
                    || self.kinetic.heading_spread() >= self.config.kinetic.min_heading_spread;
                // On a steady turn a yaw damping error and a difference of
                // the losses are one ([`KineticConfig::min_yaw_rate_spread`]).
                // Nor where the profile no longer describes the vessel
                // ([`KineticConfig::plausible_profile_sigmas`]).
                let yaw_balance_told =
                    self.kinetic.yaw_balance_told(&self.config.kinetic) && mismatch.is_none();
                let r = self.kinetic.base.losses(
                    k,
                    common_part_told,
                    yaw_balance_told,
                    self.kinetic.comparison_told,
                );
                let damping_of = |i: usize| (k.theta[i], k.s[(i, i)].max(0.0).sqrt());
                (
                    FaultSource::Kinetic,
                    std::array::from_fn(|i| ThrusterEstimate {
                        loss: r.loss[i],
                        sigma: r.sigma[i],
                        excited: r.excited[i],
                        relative_loss: r.relative_loss[i],
                        relative_sigma: r.relative_sigma[i],
                        relative_excited: r.relative_excited[i],
                        relative_weakly_told: r.relative_weakly_told[i],
                        decision: self.decider.decision(Side::BOTH[i]),
                    }),
                    r.covariance,
                    Some([
                        damping_of(fault::SURGE_DAMPING),
                        damping_of(fault::YAW_DAMPING),
                        damping_of(fault::THRUST),
                        damping_of(fault::MASS),
                    ]),
                )
            }
            None => (
                FaultSource::SeedMethod,
                std::array::from_fn(|i| ThrusterEstimate {
                    loss: self.seed.thruster_loss[i].unwrap_or(f64::NAN),
                    sigma: f64::NAN,
                    excited: self.seed.thruster_loss[i].is_some(),
                    relative_loss: f64::NAN,
                    relative_sigma: f64::NAN,
                    relative_excited: false,
                    relative_weakly_told: false,
                    decision: ThrusterDecision {
                        status: ThrusterStatus::NotExcited,
                        onset_time_s: None,
                    },
                }),
                [[f64::NAN; 2]; 2],
                None,
            ),
        };
        FaultReport {
            time_s,
            source,
            status: match source {
                FaultSource::Kinetic => self.decider.overall(),
                FaultSource::SeedMethod => ThrusterStatus::NotExcited,
            },
            thrusters,
            seed_input_faults: seed_theta,
            loss_covariance,
            profile_errors,
            profile_mismatch: mismatch,
        }
    }

    /// The seed method's per-thruster values at the last fix (step 4).
    pub fn seed_thruster_loss(&self) -> [Option<f64>; 2] {
        self.seed.thruster_loss
    }

    /// The seed method's filter state, if running.
    pub fn seed_state(&self) -> Option<&AekfState<4, 4, 2>> {
        self.seed.state.as_ref()
    }

    /// Where the extended twin withholds the comparison of the propellers
    /// because its profile does not describe the vessel, what shows it
    /// ([`KineticConfig::plausible_profile_sigmas`]); `None` where the
    /// profile describes it, or the extended twin is not running.
    pub fn profile_mismatch(&self) -> Option<ProfileMismatch> {
        let state = self.kinetic.state.as_ref()?;
        self.kinetic.profile_mismatch(state, &self.config.kinetic)
    }

    /// The extended twin's filter state, if running.
    pub fn kinetic_state(&self) -> Option<&KineticState> {
        self.kinetic.state.as_ref()
    }

    /// The state estimate at the last fix, from the extended twin where it
    /// runs, else from the seed's model.
    pub fn state_report(&self) -> Option<StateReport> {
        let frame = self.frame?;
        let (time_s, _) = self.last_fix?;
        if let Some(k) = &self.kinetic.state {
            let obs = self.kinetic.base.model().observe(&k.x);
            let cov = obs.jacobian * k.p * obs.jacobian.transpose();
            let local = NorthEast {
                north_m: k.x[idx::NORTH],
                east_m: k.x[idx::EAST],
            };
            let (nis, dof) = self
                .kinetic
                .last_report
                .map(|r| (r.nis, r.dof))
                .unwrap_or((0.0, 0));
            return Some(StateReport {
                time_s,
                position: frame.to_geodetic(local),
                local,
                position_sigma_m: [k.p[(0, 0)].sqrt(), k.p[(1, 1)].sqrt()],
                sog_mps: obs.predicted[meas::SOG],
                sog_sigma_mps: cov[(meas::SOG, meas::SOG)].max(0.0).sqrt(),
                cog_rad: wrap_two_pi(obs.predicted[meas::COG]),
                cog_sigma_rad: cov[(meas::COG, meas::COG)].max(0.0).sqrt(),
                heading_rad: Some(wrap_two_pi(k.x[idx::PSI])),
                current_mps: self
                    .config
                    .kinetic
                    .estimate_current
                    .then(|| [k.x[idx::CURRENT_NORTH], k.x[idx::CURRENT_EAST]]),
                nis,
                nis_dof: dof,
                source: FaultSource::Kinetic,
            });
        }
        let s = self.seed.state.as_ref()?;
        let local = NorthEast {
            north_m: s.x[0],
            east_m: s.x[1],
        };
        let (nis, dof) = self
            .seed
            .last_report
            .map(|r| (r.nis, r.dof))
            .unwrap_or((0.0, 0));
        Some(StateReport {
            time_s,
            position: frame.to_geodetic(local),
            local,
            position_sigma_m: [s.p[(0, 0)].sqrt(), s.p[(1, 1)].sqrt()],
            sog_mps: s.x[2],
            sog_sigma_mps: s.p[(2, 2)].sqrt(),
            cog_rad: wrap_two_pi(s.x[3]),
            cog_sigma_rad: s.p[(3, 3)].sqrt(),
            heading_rad: None,
            current_mps: None,
            nis,
            nis_dof: dof,
            source: FaultSource::SeedMethod,
        })
    }

    fn output(&self, time_s: f64, changes: Vec<StatusChange>) -> StepOutput {
        let state = self.state_report().expect("a fix was just accepted");
        let faults = self.fault_report(time_s);
        let (innovation, innovation_available) =
            match (&self.kinetic.state, self.kinetic.last_report) {
                (Some(_), Some(r)) => (
                    std::array::from_fn(|i| r.innovation[i]),
                    self.kinetic.last_available,
                ),
                _ => match self.seed.last_report {
                    Some(r) => {
                        let a = self.seed.last_available;
                        (
                            [
                                r.innovation[0],
                                r.innovation[1],
                                r.innovation[2],
                                r.innovation[3],
                                0.0,
                                0.0,
                            ],
                            [a[0], a[1], a[2], a[3], false, false],
                        )
                    }
                    None => ([0.0; MEASUREMENTS], [false; MEASUREMENTS]),
                },
            };
        StepOutput {
            state,
            faults,
            changes,
            innovation,
            innovation_available,
        }
    }

    /// Forecast from the last fix for `horizon_s` in steps of `step_s`, with
    /// the inputs held at their last values (the seed's derived inputs, or the
    /// extended twin's propeller speeds).
    pub fn forecast(&self, horizon_s: f64, step_s: f64) -> Vec<ForecastPoint> {
        let steps = if step_s > 0.0 && horizon_s > 0.0 {
            (horizon_s / step_s).round().clamp(0.0, 10_000.0) as usize
        } else {
            0
        };
        match (&self.kinetic.state, self.kinetic.last_input) {
            (Some(_), Some(u)) => self.forecast_kinetic(std::iter::repeat_n((step_s, u), steps)),
            _ => {
                let u = self.seed.inputs.last();
                self.forecast_seed(std::iter::repeat_n((step_s, u), steps))
            }
        }
    }

    /// Forecast of the extended twin through given propeller speeds.
    pub fn forecast_kinetic(
        &self,
        inputs: impl IntoIterator<Item = (f64, ShaftSpeeds)>,
    ) -> Vec<ForecastPoint> {
        let (Some(frame), Some((t0, _)), Some(k)) =
            (self.frame, self.last_fix, &self.kinetic.state)
        else {
            return Vec::new();
        };
        let model = self.kinetic.base.model();
        let q = self
            .config
            .kinetic
            .forecast_process_noise_density(&k.process_noise_density);
        let points = predict(model, k, &q, t0, inputs);
        points
            .iter()
            .map(|p: &PredictedPoint<STATES>| {
                let obs = model.observe(&p.x);
                let local = NorthEast {
                    north_m: p.x[idx::NORTH],
                    east_m: p.x[idx::EAST],
                };
                ForecastPoint {
                    time_s: p.time_s,
                    position: frame.to_geodetic(local),
                    local,
                    position_sigma_m: [p.sigma(idx::NORTH), p.sigma(idx::EAST)],
                    sog_mps: obs.predicted[meas::SOG],
                    cog_rad: wrap_two_pi(obs.predicted[meas::COG]),
                }
            })
            .collect()
    }

    /// Forecast of the seed's model through given inputs.
    pub fn forecast_seed(
        &self,
        inputs: impl IntoIterator<Item = (f64, KinematicInput)>,
    ) -> Vec<ForecastPoint> {
        let (Some(frame), Some((t0, _)), Some(s)) = (self.frame, self.last_fix, &self.seed.state)
        else {
            return Vec::new();
        };
        predict(
            &self.seed.base.filter().model,
            s,
            &s.process_noise_density,
            t0,
            inputs,
        )
        .iter()
        .map(|p| {
            let local = NorthEast {
                north_m: p.x[0],
                east_m: p.x[1],
            };
            ForecastPoint {
                time_s: p.time_s,
                position: frame.to_geodetic(local),
                local,
                position_sigma_m: [p.sigma(0), p.sigma(1)],
                sog_mps: p.x[2],
                cog_rad: wrap_two_pi(p.x[3]),
            }
        })
        .collect()
    }

    /// The seed method's last derived input.
    pub fn seed_last_input(&self) -> KinematicInput {
        self.seed.inputs.last()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geodesy::LatLon;

    /// The yaw-rate moments after `legs` of `(seconds, yaw rate rad/s)` at
    /// 5 Hz with the default memory; a straight leg's rate alternates by
    /// `+-0.01` rad/s, the heading's small corrections.
    fn moments_after(legs: &[(f64, f64)]) -> YawRateMoments {
        let dt_s: f64 = 0.2;
        let memory_s: f64 = KineticConfig::otter().filter.forgetting_time_constant_s;
        let w = 1.0 - (-dt_s / memory_s).exp();
        let mut m = YawRateMoments::default();
        let mut k = 0usize;
        for &(seconds, rate) in legs {
            for _ in 0..(seconds / dt_s).round() as usize {
                let wobble = if k.is_multiple_of(2) { 0.01 } else { -0.01 };
                m.add(if rate == 0.0 { wobble } else { rate }, w);
                k += 1;
            }
        }
        m
    }

    /// Whether `legs` tell the yaw balance.
    fn told_after(legs: &[(f64, f64)]) -> bool {
        moments_after(legs).tell_yaw_balance(&KineticConfig::otter())
    }

    /// `std(r) / rms(r)` of the moments: what the spread alone asks.
    fn spread(m: &YawRateMoments) -> f64 {
        let (rms, std) = m.rms_and_std().expect("rates were added");
        std / rms
    }

    #[test]
    fn a_straight_leg_and_the_start_of_one_turn_do_not_tell_the_yaw_balance() {
        let config = KineticConfig::otter();
        // The lawn-mower's first leg (27 s at 1.5 m/s) and 8 s into its
        // first turn (a 12 m radius, 0.125 rad/s): spread enough by
        // `std >= 0.8 rms`, but the vessel has turned one way only.
        let m = moments_after(&[(27.0, 0.0), (8.0, 0.125)]);
        assert!(spread(&m) >= config.min_yaw_rate_spread, "{}", spread(&m));
        assert!(!m.tell_yaw_balance(&config));
        // The rest of the turn, the second leg, and the first seconds of a
        // turn the other way: told.
        assert!(!told_after(&[
            (27.0, 0.0),
            (25.0, 0.125),
            (27.0, 0.0),
            (2.0, -0.125)
        ]));
        assert!(told_after(&[
            (27.0, 0.0),
            (25.0, 0.125),
            (27.0, 0.0),
            (10.0, -0.125)
        ]));
        // A steady turn never.
        assert!(!told_after(&[(20.0, 0.0), (300.0, 0.075)]));
    }

    #[test]
    fn a_straight_run_tells_the_yaw_balance_once_it_fills_a_memory() {
        let memory_s: f64 = KineticConfig::otter().filter.forgetting_time_constant_s;
        // The heading's small corrections either way are no turns.
        assert!(!told_after(&[(0.9 * memory_s, 0.0)]));
        assert!(told_after(&[(1.1 * memory_s, 0.0)]));
    }

    fn fix(time_s: f64, north_m: f64) -> GnssFix {
        let frame = LocalFrame::new(LatLon {
            lat_deg: 60.0,
            lon_deg: 20.0,
        })
        .unwrap();
        GnssFix {
            time_s,
            position: frame.to_geodetic(NorthEast {
                north_m,
                east_m: 0.0,
            }),
            sog_mps: Some(1.5),
            cog_rad: Some(0.0),
            heading_rad: None,
            yaw_rate_radps: None,
            hdop: None,
        }
    }

    #[test]
    fn time_rules_reject_small_steps_back_and_restart_on_a_new_track() {
        let mut twin = VesselTwin::new(TwinConfig::default()).unwrap();
        for k in 0..50 {
            twin.on_gnss(&fix(1000.0 + 0.2 * k as f64, 0.3 * k as f64))
                .unwrap();
        }
        let last = 1000.0 + 0.2 * 49.0;
        assert!(matches!(
            twin.on_gnss(&fix(last, 14.7)),
            Err(Rejection::Duplicate { .. })
        ));
        assert!(matches!(
            twin.on_gnss(&fix(last - 1.0, 14.0)),
            Err(Rejection::TimeWentBackwards { .. })
        ));
        // A looping replay starting over, 90 s back in time: a new track,
        // once five fixes that agree with each other confirm it.
        for k in 0..4 {
            assert!(matches!(
                twin.on_gnss(&fix(910.0 + 0.2 * k as f64, 0.3 * k as f64)),
                Err(Rejection::TimeJump { .. })
            ));
        }
        let out = twin
            .on_gnss(&fix(910.8, 1.2))
            .expect("a confirmed new track restarts");
        assert_eq!(out.state.time_s, 910.8);
        twin.on_gnss(&fix(911.0, 1.5)).unwrap();
        // A jump of a kilometre in 0.2 s is refused.
        assert!(matches!(
            twin.on_gnss(&fix(911.2, 1000.0)),
            Err(Rejection::Jump { .. })
        ));
    }

    /// One fix dated far ahead (or an hour back) is refused and changes
    /// nothing; a real gap starts a new track that keeps what was learnt.
    #[test]
    fn a_wild_time_stamp_changes_nothing_and_a_gap_keeps_what_was_learnt() {
        let mut twin = twin_with_both_estimators(300, false);
        let before = format!("{twin:?}");
        let learnt = twin.calibration().expect("a calibration");
        let last = 1000.0 + 0.2 * 299.0;
        for wild in [last + 73.0 * 365.25 * 86_400.0, last - 3600.0] {
            assert!(matches!(
                twin.on_gnss(&fix(wild, 0.3 * 300.0)),
                Err(Rejection::TimeJump { .. })
            ));
        }
        // Bookkeeping of the refused fixes aside, nothing changed.
        twin.jump_run.clear();
        assert_eq!(format!("{twin:?}"), before);
        // A two-minute gap: a new track, the faults carried over with
        // their estimate and anti-windup memory, their uncertainty wider.
        let after_gap = last + 120.0;
        twin.on_propellers(&PropellerSpeeds {
            time_s: after_gap - 0.1,
            port_radps: 70.0,
            starboard_radps: 70.0,
        })
        .unwrap();
        twin.on_gnss(&fix(after_gap, 0.3 * 300.0 + 180.0)).unwrap();
        let carried = twin.calibration().expect("a calibration");
        assert_eq!(carried.theta, learnt.theta);
        assert_eq!(carried.held_information, learnt.held_information);
        let p = carried.theta.len();
        for i in 0..p {
            assert!(
                carried.theta_covariance[i * p + i] > learnt.theta_covariance[i * p + i],
                "fault {i}"
            );
        }
    }

    /// The rate sensor's bias the extended twin learnt is in its
    /// calibration, and a twin restored from it starts from it: the bias
    /// and its variance, not the prior's 0.5 deg/s; a gap keeps it, its
    /// variance widened; a twin that holds the bias at zero saves none.
    #[test]
    fn the_rate_sensors_learnt_bias_is_kept_and_restored() {
        let bias_radps = 0.3f64.to_radians();
        let propellers = |t: f64| PropellerSpeeds {
            time_s: t - 0.1,
            port_radps: 70.0,
            starboard_radps: 70.0,
        };
        let biased = |t: f64, north_m: f64| GnssFix {
            yaw_rate_radps: Some(bias_radps),
            ..fix(t, north_m)
        };
        let run = |config: TwinConfig| {
            let mut twin = VesselTwin::new(config).unwrap();
            for k in 0..600 {
                let t = 1000.0 + 0.2 * k as f64;
                twin.on_propellers(&propellers(t)).unwrap();
                twin.on_gnss(&biased(t, 0.3 * k as f64)).unwrap();
            }
            twin
        };
        let config = TwinConfig::default();
        let prior = config.kinetic.initial_yaw_rate_bias_sigma_radps.powi(2);
        let twin = run(config);
        let learnt = twin.calibration().unwrap();
        let g = learnt.surroundings.unwrap().yaw_rate_bias.unwrap();
        assert!((g.radps - bias_radps).abs() < 0.05f64.to_radians(), "{g:?}");
        assert!(g.variance < 0.01 * prior, "{g:?}");

        let mut restored = VesselTwin::new(config).unwrap();
        restored.restore(learnt.clone());
        restored.on_propellers(&propellers(2000.0)).unwrap();
        restored.on_gnss(&biased(2000.0, 0.0)).unwrap();
        let k = restored.kinetic.state.as_ref().unwrap();
        assert_eq!(k.x[idx::YAW_RATE_BIAS], g.radps);
        assert_eq!(k.p[(idx::YAW_RATE_BIAS, idx::YAW_RATE_BIAS)], g.variance);
        // The yaw rate starts as the reading less the learnt bias.
        assert!(k.x[idx::R].abs() < 0.05f64.to_radians(), "{}", k.x[idx::R]);

        // Half an hour later: the bias kept, its variance half the prior's wider.
        let aged = twin.carried_over(learnt.time_s + 1800.0).unwrap();
        let a = aged.surroundings.unwrap().yaw_rate_bias.unwrap();
        assert_eq!(a.radps, g.radps);
        assert!((a.variance - g.variance - 0.5 * prior).abs() < 1e-12 * prior);

        let mut held = config;
        held.kinetic.estimate_yaw_rate_bias = false;
        let twin = run(held);
        assert_eq!(
            twin.calibration()
                .unwrap()
                .surroundings
                .unwrap()
                .yaw_rate_bias,
            None
        );
    }

    /// Both estimators running after `fixes` fixes, with propeller speeds
    /// waiting for the next; with `poisoned`, the extended filter's
    /// covariance holds a NaN, so that its next step fails after the seed's
    /// has succeeded.
    fn twin_with_both_estimators(fixes: usize, poisoned: bool) -> VesselTwin {
        let mut twin = VesselTwin::new(TwinConfig::default()).unwrap();
        let propellers = |t: f64| PropellerSpeeds {
            time_s: t - 0.1,
            port_radps: 70.0,
            starboard_radps: 70.0,
        };
        for k in 0..fixes {
            let t = 1000.0 + 0.2 * k as f64;
            twin.on_propellers(&propellers(t)).unwrap();
            twin.on_gnss(&fix(t, 0.3 * k as f64)).unwrap();
        }
        if poisoned {
            let state = twin.kinetic.state.as_mut().expect("the extended twin runs");
            state.p[(0, 0)] = f64::NAN;
        }
        twin.on_propellers(&propellers(1000.0 + 0.2 * fixes as f64))
            .unwrap();
        twin
    }

    #[test]
    fn a_fix_the_extended_filter_refuses_changes_nothing() {
        let fixes = 40;
        let next = fix(1000.0 + 0.2 * fixes as f64, 0.3 * fixes as f64);
        let mut twin = twin_with_both_estimators(fixes, true);
        let before = format!("{twin:?}");
        let refused = twin.on_gnss(&next);
        assert!(
            matches!(refused, Err(Rejection::Estimator(_))),
            "{refused:?}"
        );
        // Everything, the seed's estimator (already stepped when the
        // extended filter failed) and the propeller samples included.
        assert_eq!(format!("{twin:?}"), before);

        // The same fix without the poison is accepted and changes the seed's
        // estimate and the propeller samples: the comparison above could see
        // those changes.
        let mut healthy = twin_with_both_estimators(fixes, false);
        let seed_before = healthy.seed.state.unwrap().x;
        let samples_before = healthy.propellers.count();
        healthy.on_gnss(&next).expect("a working filter accepts it");
        assert_ne!(healthy.seed.state.unwrap().x, seed_before);
        assert_ne!(healthy.propellers.count(), samples_before);
    }

    /// The extended twin of [`twin_with_both_estimators`] with its profile's
    /// yaw damping and mass errors at zero and its thrust coefficient's at
    /// `thrust_error`.
    fn with_thrust_error(twin: &mut VesselTwin, thrust_error: f64) {
        let state = twin.kinetic.state.as_mut().expect("the extended twin runs");
        state.theta[fault::THRUST] = thrust_error;
        state.theta[fault::YAW_DAMPING] = 0.0;
        state.theta[fault::MASS] = 0.0;
    }

    #[test]
    fn a_thrust_error_past_its_bound_withholds_the_comparison() {
        let mut twin = twin_with_both_estimators(40, false);
        let bound = twin.config.kinetic.plausible_profile_sigmas
            * KineticConfig::UNIDENTIFIED_PROFILE_SIGMA;
        with_thrust_error(&mut twin, 0.9 * bound);
        assert_eq!(twin.profile_mismatch(), None);
        // A filter that answers a loss by moving its thrust coefficient
        // far reads the yaw balance off a profile it no longer believes.
        with_thrust_error(&mut twin, -1.1 * bound);
        let m = twin
            .profile_mismatch()
            .expect("the thrust error is past its bound");
        assert_eq!((m.thrust_error, m.thrust_bound), (-1.1 * bound, bound));
        let report = twin.fault_report(1010.0);
        assert!(report.thrusters.iter().all(|t| !t.relative_excited));
        assert_eq!(report.profile_mismatch, Some(m));
    }

    #[test]
    fn an_identified_profile_keeps_the_thrust_bound_of_an_unidentified_one() {
        // An identification holds the thrust coefficient and gives it a
        // small standard deviation; the bound stays an unidentified
        // profile's, while the yaw damping's narrows with its own.
        let config = TwinConfig::identified([0.05; 4]);
        let k = config.kinetic.plausible_profile_sigmas;
        let mut twin = VesselTwin::new(config).unwrap();
        let source = twin_with_both_estimators(40, false);
        twin.kinetic.state = source.kinetic.state;
        twin.kinetic.nis_moments = source.kinetic.nis_moments;
        with_thrust_error(&mut twin, 0.3);
        assert_eq!(twin.profile_mismatch(), None);
        with_thrust_error(&mut twin, 0.7);
        let m = twin
            .profile_mismatch()
            .expect("the thrust error is past its bound");
        assert_eq!(
            m.thrust_bound,
            k * KineticConfig::UNIDENTIFIED_PROFILE_SIGMA
        );
        assert!((m.yaw_damping_bound - k * 0.05).abs() < 1e-12);
    }
}
