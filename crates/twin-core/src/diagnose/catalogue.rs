//! The catalogue of causes, as data: one declaration per cause says its
//! name, what it needs of the log, how it is searched (as states the filter
//! estimates, one scalar on its physical bounds, or the antenna's two
//! offsets), how its parameters are reported and the size a user would act
//! on. The fitting ([`super::fit`]) reads these declarations and has no
//! per-cause code; a new cause is a new [`Cause`] variant, whose missing
//! declaration [`Cause::spec`] refuses to compile.

use super::fit::{Acceptance, BaseModel, Hypothesis};
use super::pass::AtSplit;
use crate::estimator::Term;
use crate::geodesy::rad_to_compass_deg;
use crate::vessel::VesselParams;

/// A candidate cause of what the nominal model gets wrong.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Cause {
    /// A water current (two states: north and east).
    Current,
    /// A loss of thrust per propeller (where propeller speeds are logged).
    ThrusterLoss,
    /// The heading sensor reads off by a constant.
    HeadingOffset,
    /// The reported speed over ground is scaled.
    SogScale,
    /// GNSS data are older than their time stamps.
    GnssLatency,
    /// The GNSS antenna is away from the reference point.
    LeverArm,
    /// The speed-through-water log reads scaled (kinematic base only).
    StwScale,
    /// The hull slides sideways in turns, in proportion to the turn rate
    /// (kinematic base only; the Otter's twin models its sway).
    Sideslip,
    /// The hull slides sideways in turns in proportion to the turn rate
    /// and its speed through water: a drift angle per turn rate, as a hull
    /// whose damping does not grow with speed drifts (kinematic base only).
    SideslipWithSpeed,
    /// The hull's resistance in surge differs from the profile's (fouling,
    /// a load, a different hull): the surge damping rescaled.
    SurgeDamping,
    /// The hull's resistance to turning differs from the profile's.
    YawDamping,
    /// The vessel is heavier or lighter than the profile (a payload,
    /// ballast): mass, inertia and added mass rescaled together.
    Mass,
    /// The rate sensor reads the yaw rate scaled (a gyro's scale factor, a
    /// rate of turn its sensor damps).
    YawRateScale,
    /// The rate sensor reads a yaw rate when there is none (a gyro's bias).
    YawRateBias,
}

impl Cause {
    /// Every cause, in the order they are tried.
    pub const ALL: [Cause; 14] = [
        Cause::Current,
        Cause::ThrusterLoss,
        Cause::HeadingOffset,
        Cause::SogScale,
        Cause::GnssLatency,
        Cause::LeverArm,
        Cause::StwScale,
        Cause::Sideslip,
        Cause::SideslipWithSpeed,
        Cause::SurgeDamping,
        Cause::YawDamping,
        Cause::Mass,
        Cause::YawRateScale,
        Cause::YawRateBias,
    ];

    /// The cause's declaration in the catalogue.
    pub(super) fn spec(self) -> &'static CauseSpec {
        match self {
            Cause::Current => &CURRENT,
            Cause::ThrusterLoss => &THRUSTER_LOSS,
            Cause::HeadingOffset => &HEADING_OFFSET,
            Cause::SogScale => &SOG_SCALE,
            Cause::GnssLatency => &GNSS_LATENCY,
            Cause::LeverArm => &LEVER_ARM,
            Cause::StwScale => &STW_SCALE,
            Cause::Sideslip => &SIDESLIP,
            Cause::SideslipWithSpeed => &SIDESLIP_WITH_SPEED,
            Cause::SurgeDamping => &SURGE_DAMPING,
            Cause::YawDamping => &YAW_DAMPING,
            Cause::Mass => &MASS,
            Cause::YawRateScale => &YAW_RATE_SCALE,
            Cause::YawRateBias => &YAW_RATE_BIAS,
        }
    }

    /// The name used in reports and in `twin diagnose --json`.
    pub fn name(self) -> &'static str {
        self.spec().name
    }

    /// How many parameters it fits: of two causes that explain the data
    /// equally well, the one with fewer is named.
    pub(super) fn parameter_count(self) -> usize {
        match self.spec().search {
            Search::Scalar(_) => 1,
            Search::States(_) | Search::Plane(_) => 2,
        }
    }

    /// Whether it and `other` are shapes of one effect, never named
    /// together ([`CauseSpec::excludes`], either way).
    pub(super) fn excludes(self, other: Cause) -> bool {
        self.spec().excludes.contains(&other) || other.spec().excludes.contains(&self)
    }

    /// Whether the cause can be tried on a log of this kind.
    pub(super) fn applies(self, log: &LogKind) -> bool {
        (self.spec().applies)(log)
    }
}

/// What a log measured, and the base model it is diagnosed on: what a
/// cause's applicability is judged on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct LogKind {
    pub base: BaseModel,
    /// Whether the log has positions (else only its velocities are seen).
    pub has_position: bool,
    pub has_heading: bool,
    pub has_stw: bool,
    /// Whether the log has a rate sensor's yaw rate.
    pub has_yaw_rate: bool,
}

/// A cause's declaration.
pub(super) struct CauseSpec {
    /// The name in reports and in `twin diagnose --json`.
    pub name: &'static str,
    /// Whether it can be tried on a log.
    pub applies: fn(&LogKind) -> bool,
    /// A cause of the vessel's dynamics: the forecasts run on them, so it
    /// must make the held-out forecasts better over the horizons taken
    /// together (a steady force it would only absorb, a wind or a turning
    /// current, makes them worse).
    pub must_improve_forecast: bool,
    /// A sensor reading wrong (its offset, scale, clock or mounting), not
    /// the vessel or the water moving otherwise than the model says: of
    /// two causes that explain the data as well with as many parameters,
    /// the one that is not is named. A hull drifts in every turn and water
    /// moves; a sensor is wrong only when it is.
    pub sensor_error: bool,
    /// Causes never named beside it: other shapes of the same effect (a
    /// second shape beside the first fits what lies between them, a
    /// correction no hull has, not a second effect).
    pub excludes: &'static [Cause],
    /// How it is searched, and how its parameters are reported.
    pub search: Search,
}

/// How a cause is searched.
pub(super) enum Search {
    /// Estimated by the base model's filter as states, freed in the
    /// hypothesis and read at the end of the training part.
    States(StateSearch),
    /// One parameter: the training likelihood's maximum within its physical
    /// bounds.
    Scalar(ScalarSearch),
    /// The GNSS antenna's two offsets, by coordinate descent (they act on
    /// different axes of the fix and are nearly independent).
    Plane(PlaneSearch),
}

/// The reported parameters of a state cause, the size compared with the
/// bars, its z, and the practical size.
pub(super) struct StateReport {
    pub parameters: Vec<(&'static str, f64, f64)>,
    pub side: Option<&'static str>,
    pub size: f64,
    pub z: f64,
    pub practical: f64,
}

/// A state cause.
pub(super) struct StateSearch {
    /// Frees the cause's states in a hypothesis.
    pub free: fn(&mut Hypothesis),
    /// Takes them out of it.
    pub off: fn(&mut Hypothesis),
    /// Its report from the estimates at the split.
    pub report: fn(&AtSplit, &Acceptance) -> StateReport,
    /// What estimates outside the cause's physical bounds are evidence of
    /// (`None` when they are within them).
    pub beyond: fn(&AtSplit) -> Option<&'static str>,
    /// A part of the states that another cause moves the vessel alike
    /// with (`None` when there is none).
    pub shared: Option<SharedPart>,
    /// States that can start late in the log (`None`: states there from
    /// the start).
    pub late_rise: Option<LateRise>,
}

/// States that can start late in the log. Started more than
/// [`LATE_START_S`] into it, their estimates at the split lag the start
/// (the filter forgets slowly), and fixed there they would judge the
/// held-out part with a fraction of the cause: the loss is fitted as a
/// step at its onset on the training part instead. Nothing at the split,
/// they may start in the held-out part: they are then left tracked by the
/// filter through it, whose one-step-ahead predictions stay causal, so
/// that the held-out likelihood still judges them.
pub(super) struct LateRise {
    /// Whether the estimates at the split started after [`LATE_START_S`].
    pub starts_late: fn(&AtSplit) -> bool,
    /// Leaves them tracked through the held-out part in a hypothesis.
    pub track: fn(&mut Hypothesis),
}

/// A loss whose track rose later than this after the log's first fix is a
/// step at its onset; an earlier one is there from the start, s.
pub(super) const LATE_START_S: f64 = 30.0;

/// The side of the larger loss (0 port, 1 starboard): the side a loss
/// finding names.
pub(super) fn larger_loss_side(s: &AtSplit) -> usize {
    if s.loss[0] >= s.loss[1] { 0 } else { 1 }
}

/// Whether the larger loss's track rose after [`LATE_START_S`].
fn loss_starts_late(s: &AtSplit) -> bool {
    s.loss_onset_s[larger_loss_side(s)] >= LATE_START_S
}

/// The part of a state cause's estimates that another cause imitates
/// exactly on steady motion: both propellers losing alike is the hull's
/// resistance being off. Where that cause, fitted on top, takes the part
/// away without the held-out data getting worse, the part is named as
/// that cause (the issue's "a hull 30 % draggier is a finding, not a pair
/// of propeller losses").
pub(super) struct SharedPart {
    /// The cause that moves the vessel alike.
    pub cause: Cause,
    /// The shared part's size from the estimates (0 when there is none).
    pub size: fn(&AtSplit) -> f64,
    /// What the finding's evidence says of the part taken.
    pub what: &'static str,
}

/// The part both losses share: the smaller loss. Taken from both, it
/// leaves one propeller at none and the other with the difference, the
/// only split with no negative loss (a propeller giving more thrust than
/// its profile says): `[0.23, 0.51]` shares 0.23, `[-0.31, 0.19]` shares
/// -0.31 (a less draggy hull) and leaves a loss of 0.50.
fn shared_loss(s: &AtSplit) -> f64 {
    s.loss[0].min(s.loss[1])
}

/// A one-parameter cause.
pub(super) struct ScalarSearch {
    /// The parameter's name in reports.
    pub parameter: &'static str,
    /// The physical bounds, in the hypothesis' unit; the search runs
    /// within them.
    pub bounds: (f64, f64),
    /// Grid steps before the parabolic refinement (`fit::minimise_1d`).
    pub grid: usize,
    /// The value of "no effect".
    pub neutral: f64,
    /// Sets the parameter in a hypothesis.
    pub set: fn(&mut Hypothesis, f64),
    /// The reported value (and standard deviation) from the hypothesis'.
    pub shown: fn(f64) -> f64,
    /// The smallest size worth reporting, in the hypothesis' unit.
    pub practical: fn(&Acceptance) -> f64,
    /// What a fit that wants to go below the lower bound is evidence of
    /// (`None`: the bound is a search range only).
    pub below_means: Option<&'static str>,
}

/// The antenna's two offsets.
pub(super) struct PlaneSearch {
    /// The parameters' names in reports.
    pub parameters: [&'static str; 2],
    /// Each offset's range `(lowest, highest)`, forward then starboard, m,
    /// from the vessel's profile: the antenna stays on the hull.
    pub bounds_m: fn(&VesselParams) -> [(f64, f64); 2],
    /// Grid points per offset.
    pub grid: usize,
    /// The smallest offset worth reporting, m.
    pub practical: fn(&Acceptance) -> f64,
}

fn always(_: &LogKind) -> bool {
    true
}

fn identity(v: f64) -> f64 {
    v
}

fn free_current(h: &mut Hypothesis) {
    h.current = Term::Free;
}

fn free_losses(h: &mut Hypothesis) {
    h.loss = Term::Free;
}

/// The current's speed and direction, with variances by first-order
/// propagation from its north and east components.
fn current_report(s: &AtSplit, acc: &Acceptance) -> StateReport {
    let [n, e] = s.current;
    let speed = n.hypot(e);
    let c = s.current_cov;
    let (un, ue) = if speed > 1e-9 {
        (n / speed, e / speed)
    } else {
        (1.0, 0.0)
    };
    let var_speed = un * un * c[0][0] + 2.0 * un * ue * c[0][1] + ue * ue * c[1][1];
    let var_dir = if speed > 1e-9 {
        (ue * ue * c[0][0] - 2.0 * un * ue * c[0][1] + un * un * c[1][1]) / (speed * speed)
    } else {
        f64::INFINITY
    };
    let sd = var_speed.max(0.0).sqrt();
    StateReport {
        parameters: vec![
            ("speed_mps", speed, sd),
            (
                "toward_deg",
                rad_to_compass_deg(e.atan2(n)),
                var_dir.max(0.0).sqrt().to_degrees(),
            ),
            ("north_mps", n, c[0][0].max(0.0).sqrt()),
            ("east_mps", e, c[1][1].max(0.0).sqrt()),
        ],
        side: None,
        size: speed,
        z: speed / sd.max(1e-12),
        practical: acc.min_current_mps,
    }
}

/// The losses, the larger one naming the side.
fn loss_report(s: &AtSplit, acc: &Acceptance) -> StateReport {
    let side = larger_loss_side(s);
    let mut parameters = vec![
        ("loss", s.loss[side], s.loss_sigma[side]),
        ("loss_port", s.loss[0], s.loss_sigma[0]),
        ("loss_starboard", s.loss[1], s.loss_sigma[1]),
    ];
    if s.loss_onset_s[side].is_finite() {
        // Read off the filter's track: no standard deviation of its own.
        parameters.push(("onset_s", s.loss_onset_s[side], f64::NAN));
    }
    StateReport {
        parameters,
        side: Some(if side == 0 { "port" } else { "starboard" }),
        size: s.loss[side],
        z: s.loss[side] / s.loss_sigma[side].max(1e-12),
        practical: acc.min_loss,
    }
}

/// Why a latency fit that wants to go below zero is not a latency.
pub(super) const NEGATIVE_LATENCY: &str = "it wants a negative latency, which no receiver has: the fixes lead the model, \
     a difference in the vessel's dynamics (a time constant, damping, mass), not a clock";

/// The fastest current the catalogue names, m/s: tidal races reach a few
/// m/s; the waters a small USV works in, less.
pub(super) const MAX_CURRENT_MPS: f64 = 3.0;

/// Why a current beyond [`MAX_CURRENT_MPS`] is not a current.
pub(super) const TOO_FAST_CURRENT: &str = "it wants a current faster than 3 m/s, beyond the waters a small vessel works in:      the current state is absorbing a difference in the vessel's dynamics";

/// A loss below this (more thrust than the profile gives) is not a loss.
pub(super) const MIN_LOSS: f64 = -0.1;

/// Why a negative loss is not a loss.
pub(super) const NEGATIVE_LOSS: &str = "it wants a propeller giving more thrust than the profile says (a negative loss):      the profile's thrust, damping or mass, not a fault";

/// Why the same loss on both propellers is not a propeller fault.
pub(super) const EQUAL_LOSSES: &str = "it wants the same loss on both propellers: the same motion as the profile's thrust, \
     or its hull resistance, being off for both; a profile error, not a fault of one propeller";

/// Whether the losses are both clearly there and equal within `tolerance`:
/// `T = (1 - loss) k n|n|` on both sides is exactly a thrust coefficient
/// scaled by `1 - loss`, which the vessel's motion cannot tell from the
/// profile.
fn equal_losses(loss: [f64; 2], tolerance: f64) -> bool {
    loss[0].min(loss[1]) > 2.0 * tolerance && (loss[0] - loss[1]).abs() < tolerance
}

/// Why an antenna beyond the hull is not a lever arm.
pub(super) const OUTSIDE_HULL: &str =
    "it wants an antenna outside the hull: the lever arm is absorbing something else";

static CURRENT: CauseSpec = CauseSpec {
    name: "current",
    must_improve_forecast: false,
    sensor_error: false,
    excludes: &[],
    applies: always,
    search: Search::States(StateSearch {
        free: free_current,
        off: |h| h.current = Term::Off,
        report: current_report,
        beyond: |s| {
            (s.current[0].hypot(s.current[1]) > MAX_CURRENT_MPS).then_some(TOO_FAST_CURRENT)
        },
        shared: None,
        late_rise: None,
    }),
};

static THRUSTER_LOSS: CauseSpec = CauseSpec {
    name: "thruster_loss",
    must_improve_forecast: false,
    sensor_error: false,
    excludes: &[],
    applies: |log| log.base == BaseModel::Kinetic,
    search: Search::States(StateSearch {
        free: free_losses,
        off: |h| {
            h.loss = Term::Off;
            h.loss_from_s = 0.0;
            h.loss_tracked = false;
        },
        report: loss_report,
        beyond: |s| {
            if s.loss[0].min(s.loss[1]) < MIN_LOSS {
                Some(NEGATIVE_LOSS)
            } else if equal_losses(s.loss, 0.03) {
                Some(EQUAL_LOSSES)
            } else {
                None
            }
        },
        shared: Some(SharedPart {
            cause: Cause::SurgeDamping,
            size: shared_loss,
            what: "the loss both propellers shared",
        }),
        late_rise: Some(LateRise {
            starts_late: loss_starts_late,
            track: |h| h.loss_tracked = true,
        }),
    }),
};

static HEADING_OFFSET: CauseSpec = CauseSpec {
    name: "heading_offset",
    must_improve_forecast: false,
    sensor_error: true,
    excludes: &[],
    applies: |log| log.has_heading,
    search: Search::Scalar(ScalarSearch {
        parameter: "offset_deg",
        bounds: (-15f64.to_radians(), 15f64.to_radians()),
        grid: 6,
        neutral: 0.0,
        set: |h, v| h.effects.heading_offset_rad = v,
        shown: f64::to_degrees,
        practical: |acc| acc.min_heading_offset_rad,
        below_means: None,
    }),
};

static SOG_SCALE: CauseSpec = CauseSpec {
    name: "sog_scale",
    must_improve_forecast: false,
    sensor_error: true,
    excludes: &[],
    applies: always,
    search: Search::Scalar(ScalarSearch {
        parameter: "scale",
        bounds: (0.85, 1.15),
        grid: 6,
        neutral: 1.0,
        set: |h, v| h.effects.sog_scale = v,
        shown: identity,
        practical: |acc| acc.min_sog_scale_error,
        below_means: None,
    }),
};

static GNSS_LATENCY: CauseSpec = CauseSpec {
    name: "gnss_latency",
    must_improve_forecast: false,
    sensor_error: true,
    excludes: &[],
    // Seen in the fixes' positions against the vessel's motion.
    applies: |log| log.has_position,
    // A fix is stamped at or after the instant it describes, never before:
    // a latency is physically in [0, 2] s.
    search: Search::Scalar(ScalarSearch {
        parameter: "latency_s",
        bounds: (0.0, 2.0),
        grid: 6,
        neutral: 0.0,
        set: |h, v| h.effects.gnss_latency_s = v,
        shown: identity,
        practical: |acc| acc.min_latency_s,
        below_means: Some(NEGATIVE_LATENCY),
    }),
};

static LEVER_ARM: CauseSpec = CauseSpec {
    name: "lever_arm",
    must_improve_forecast: false,
    sensor_error: true,
    excludes: &[],
    // The water base needs a heading to turn a body offset into the fix's.
    // Seen in the fixes' positions as the hull turns.
    applies: |log| log.has_position && (log.base == BaseModel::Kinetic || log.has_heading),
    search: Search::Plane(PlaneSearch {
        parameters: ["x_m", "y_m"],
        // The offset is found against the profile's antenna, and the
        // antenna it gives is on the hull: a fit that runs to the hull's
        // edge wants the antenna off it (OUTSIDE_HULL).
        bounds_m: on_the_hull,
        grid: 8,
        practical: |acc| acc.min_lever_arm_m,
    }),
};

/// The lever arm's range: the offsets from the profile's antenna that keep
/// the antenna within the hull's length and beam about the reference point
/// (the bounds a profile's antenna is validated against).
fn on_the_hull(p: &VesselParams) -> [(f64, f64); 2] {
    let half = [0.5 * p.length_m, 0.5 * p.beam_m];
    [0, 1].map(|i| (-half[i] - p.antenna_m[i], half[i] - p.antenna_m[i]))
}

static STW_SCALE: CauseSpec = CauseSpec {
    name: "stw_scale",
    must_improve_forecast: false,
    sensor_error: true,
    excludes: &[],
    applies: |log| log.base == BaseModel::Water && log.has_stw,
    search: Search::Scalar(ScalarSearch {
        parameter: "scale",
        bounds: (0.7, 1.3),
        grid: 6,
        neutral: 1.0,
        set: |h, v| h.stw_scale = v,
        shown: identity,
        practical: |acc| acc.min_stw_scale_error,
        below_means: None,
    }),
};

/// The hull's drift in its turns as a sway per yaw rate, `v = k r`, at
/// any speed.
static SIDESLIP: CauseSpec = drift(
    "sideslip",
    |h, v| h.sideslip_m = v,
    &[Cause::SideslipWithSpeed],
);

/// The sideslip whose sway grows with the speed through water (`v = k_u u
/// r`), reported and bounded as the sway per yaw rate at the log's speed
/// under way, so that its size reads as the [`SIDESLIP`]'s does. The two
/// shapes agree at one speed; a log whose speed changes tells them apart
/// (the independent simulator's Otter drifts as this one, the Furuno
/// motor boats as the other).
static SIDESLIP_WITH_SPEED: CauseSpec = drift(
    "sideslip_with_speed",
    |h, v| h.speed_sideslip_m = v,
    &[Cause::Sideslip],
);

/// A shape of the hull's drift in its turns (kinematic base, with a
/// heading): its sway per yaw rate, m/s per rad/s, set in the hypothesis
/// by `set`; never named beside the `other_shape`.
const fn drift(
    name: &'static str,
    set: fn(&mut Hypothesis, f64),
    other_shape: &'static [Cause],
) -> CauseSpec {
    CauseSpec {
        name,
        must_improve_forecast: false,
        sensor_error: false,
        excludes: other_shape,
        applies: |log| log.base == BaseModel::Water && log.has_heading,
        search: Search::Scalar(ScalarSearch {
            parameter: "lateral_mps_per_radps",
            bounds: (-20.0, 20.0),
            grid: 8,
            neutral: 0.0,
            set,
            shown: identity,
            practical: |acc| acc.min_sideslip_m,
            below_means: None,
        }),
    }
}

/// A model-parameter cause: one of the profile's parameters in
/// [`Hypothesis::profile_scales`] rescaled, on the kinetic base. Searched
/// from 0.4 to 2.5 times the profile's: beyond, the profile is not of this
/// vessel at all (`twin identify` is the tool).
///
/// The thrust coefficients are not a cause: positions and shaft speeds say
/// how the vessel accelerates and turns for a shaft speed, never how many
/// newtons that takes, so a thrust scale is the same motion as the mass and
/// the damping scaled the other way together (and, on one side, as a
/// propeller loss). The profile's thrust is the baseline, as in
/// `twin identify`.
const fn profile_scale(name: &'static str, set: fn(&mut Hypothesis, f64)) -> CauseSpec {
    CauseSpec {
        name,
        applies: kinetic_with_positions,
        must_improve_forecast: true,
        sensor_error: false,
        excludes: &[],
        search: Search::Scalar(ScalarSearch {
            parameter: "scale",
            bounds: (0.4, 2.5),
            grid: 8,
            neutral: 1.0,
            set,
            shown: identity,
            practical: |acc| acc.min_profile_scale_error,
            below_means: None,
        }),
    }
}

/// A cause of the vessel's dynamics is judged on the held-out position
/// forecast: it needs the kinetic base and positions.
fn kinetic_with_positions(log: &LogKind) -> bool {
    log.base == BaseModel::Kinetic && log.has_position
}

/// A rate sensor's error is told against how the heading (or, without a
/// heading sensor, the course over ground) turns.
fn rate_sensor_told(log: &LogKind) -> bool {
    log.has_yaw_rate && (log.has_heading || log.has_position)
}

static YAW_RATE_SCALE: CauseSpec = CauseSpec {
    name: "yaw_rate_scale",
    must_improve_forecast: false,
    sensor_error: true,
    excludes: &[],
    applies: rate_sensor_told,
    // A rate gyro's scale factor is within a few per cent of one, a rate of
    // turn damped by its sensor reads low in a turn: beyond 20 % the rate is
    // not of this vessel's yaw.
    search: Search::Scalar(ScalarSearch {
        parameter: "scale",
        bounds: (0.8, 1.2),
        grid: 6,
        neutral: 1.0,
        set: |h, v| h.effects.yaw_rate_scale = v,
        shown: identity,
        practical: |acc| acc.min_yaw_rate_scale_error,
        below_means: None,
    }),
};

static YAW_RATE_BIAS: CauseSpec = CauseSpec {
    name: "yaw_rate_bias",
    must_improve_forecast: false,
    sensor_error: true,
    excludes: &[],
    applies: rate_sensor_told,
    // An uncalibrated MEMS gyro's bias is within a degree or two a second,
    // a rate of turn's zero within a fraction of that: beyond 3 deg/s the
    // rate is not of this vessel's yaw.
    search: Search::Scalar(ScalarSearch {
        parameter: "bias_deg_s",
        bounds: (-3f64.to_radians(), 3f64.to_radians()),
        grid: 6,
        neutral: 0.0,
        set: |h, v| h.effects.yaw_rate_bias_radps = v,
        shown: f64::to_degrees,
        practical: |acc| acc.min_yaw_rate_bias_radps,
        below_means: None,
    }),
};

static SURGE_DAMPING: CauseSpec = profile_scale("surge_damping", |h, v| h.profile_scales[0] = v);
static YAW_DAMPING: CauseSpec = profile_scale("yaw_damping", |h, v| h.profile_scales[1] = v);
static MASS: CauseSpec = profile_scale("mass", |h, v| h.profile_scales[3] = v);

#[cfg(test)]
mod tests {
    use super::*;

    fn kinds() -> Vec<LogKind> {
        let mut v = Vec::new();
        for base in [BaseModel::Kinetic, BaseModel::Water] {
            for has_position in [false, true] {
                for has_heading in [false, true] {
                    for has_stw in [false, true] {
                        for has_yaw_rate in [false, true] {
                            v.push(LogKind {
                                base,
                                has_position,
                                has_heading,
                                has_stw,
                                has_yaw_rate,
                            });
                        }
                    }
                }
            }
        }
        v
    }

    #[test]
    fn every_cause_is_declared_once_with_a_unique_name() {
        let names: Vec<&str> = Cause::ALL.iter().map(|c| c.name()).collect();
        for (i, n) in names.iter().enumerate() {
            assert!(!n.is_empty());
            assert!(
                !names[..i].contains(n),
                "{n} is declared twice in the catalogue"
            );
        }
        for (i, a) in Cause::ALL.iter().enumerate() {
            for b in &Cause::ALL[..i] {
                assert!(
                    !std::ptr::eq(a.spec(), b.spec()),
                    "{a:?} and {b:?} share a declaration"
                );
            }
        }
    }

    #[test]
    fn every_scalar_search_has_its_neutral_value_inside_its_bounds() {
        for c in Cause::ALL {
            if let Search::Scalar(s) = &c.spec().search {
                let (lo, hi) = s.bounds;
                assert!(lo < hi, "{c:?}");
                assert!(
                    (lo..=hi).contains(&s.neutral),
                    "{c:?}: {} outside [{lo}, {hi}]",
                    s.neutral
                );
                assert!(s.grid >= 2, "{c:?}");
            }
        }
    }

    #[test]
    fn a_latency_is_searched_on_its_physical_bounds_only() {
        let Search::Scalar(s) = &Cause::GnssLatency.spec().search else {
            panic!("the latency is one scalar");
        };
        assert_eq!(s.bounds, (0.0, 2.0));
        assert_eq!(s.below_means, Some(NEGATIVE_LATENCY));
        let mut h = Hypothesis::nominal();
        (s.set)(&mut h, 0.3);
        assert_eq!(h.effects.gnss_latency_s, 0.3);
    }

    #[test]
    fn a_yaw_rate_scale_is_searched_near_one_and_scales_the_rate_sensor() {
        let Search::Scalar(s) = &Cause::YawRateScale.spec().search else {
            panic!("the yaw rate's scale is one scalar");
        };
        assert_eq!((s.bounds, s.neutral), ((0.8, 1.2), 1.0));
        let mut h = Hypothesis::nominal();
        (s.set)(&mut h, 0.96);
        assert_eq!(h.effects.yaw_rate_scale, 0.96);
        assert_eq!(
            Cause::YawRateScale.name(),
            "yaw_rate_scale",
            "the name the contract lists"
        );
    }

    #[test]
    fn a_yaw_rate_bias_is_searched_both_ways_and_biases_the_rate_sensor() {
        let Search::Scalar(s) = &Cause::YawRateBias.spec().search else {
            panic!("the yaw rate's bias is one scalar");
        };
        let (lo, hi) = s.bounds;
        assert_eq!((lo, s.neutral), (-hi, 0.0), "either sign, centred on none");
        assert!((hi.to_degrees() - 3.0).abs() < 1e-12);
        let mut h = Hypothesis::nominal();
        (s.set)(&mut h, 0.005);
        assert_eq!(h.effects.yaw_rate_bias_radps, 0.005);
        assert!(((s.shown)(0.005) - 0.005f64.to_degrees()).abs() < 1e-15);
        assert_eq!(Cause::YawRateBias.name(), "yaw_rate_bias");
        assert!(Cause::YawRateBias.spec().sensor_error);
    }

    #[test]
    fn applicability_follows_what_the_log_measured() {
        for kind in kinds() {
            let applies = |c: Cause| c.applies(&kind);
            assert!(applies(Cause::Current) && applies(Cause::SogScale));
            // The fixes' timing and the antenna's offset show in positions.
            assert_eq!(applies(Cause::GnssLatency), kind.has_position);
            assert_eq!(
                applies(Cause::ThrusterLoss),
                kind.base == BaseModel::Kinetic
            );
            assert_eq!(applies(Cause::HeadingOffset), kind.has_heading);
            assert_eq!(
                applies(Cause::StwScale),
                kind.base == BaseModel::Water && kind.has_stw
            );
            for c in [Cause::Sideslip, Cause::SideslipWithSpeed] {
                assert_eq!(
                    applies(c),
                    kind.base == BaseModel::Water && kind.has_heading,
                    "{c:?}"
                );
            }
            assert_eq!(
                applies(Cause::LeverArm),
                kind.has_position && (kind.base == BaseModel::Kinetic || kind.has_heading)
            );
            for c in [Cause::YawRateScale, Cause::YawRateBias] {
                assert_eq!(
                    applies(c),
                    kind.has_yaw_rate && (kind.has_heading || kind.has_position),
                    "{c:?}"
                );
            }
            // Judged on the held-out position forecast.
            for c in [Cause::SurgeDamping, Cause::YawDamping, Cause::Mass] {
                assert_eq!(
                    applies(c),
                    kind.base == BaseModel::Kinetic && kind.has_position,
                    "{c:?}"
                );
            }
        }
    }

    /// The two shapes of the hull's drift exclude each other, both ways,
    /// each sets its own part of the hypothesis, and no other pair of
    /// causes excludes each other.
    #[test]
    fn the_two_shapes_of_a_drift_exclude_each_other_and_nothing_else_does() {
        let (a, b) = (Cause::Sideslip, Cause::SideslipWithSpeed);
        assert!(a.excludes(b) && b.excludes(a));
        for c in Cause::ALL {
            for d in Cause::ALL {
                let pair = (c == a && d == b) || (c == b && d == a);
                assert_eq!(c.excludes(d), pair, "{c:?} and {d:?}");
            }
        }
        let set = |c: Cause| {
            let Search::Scalar(s) = &c.spec().search else {
                panic!("{c:?} is one scalar");
            };
            let mut h = Hypothesis::nominal();
            (s.set)(&mut h, -0.7);
            (h.sideslip_m, h.speed_sideslip_m)
        };
        assert_eq!(set(a), (-0.7, 0.0));
        assert_eq!(set(b), (0.0, -0.7));
    }

    /// Each model-parameter cause rescales its own parameter of the
    /// profile and no other.
    #[test]
    fn each_model_parameter_cause_sets_its_own_scale() {
        let causes = [Cause::SurgeDamping, Cause::YawDamping, Cause::Mass];
        for (c, i) in causes.into_iter().zip([0, 1, 3]) {
            let Search::Scalar(s) = &c.spec().search else {
                panic!("{c:?} is one scalar");
            };
            let mut h = Hypothesis::nominal();
            (s.set)(&mut h, 1.3);
            let mut want = [1.0; 4];
            want[i] = 1.3;
            assert_eq!(h.profile_scales, want, "{c:?}");
        }
    }

    /// A state estimate outside its cause's physical bounds is refused with
    /// what it is evidence of.
    #[test]
    fn state_estimates_beyond_their_bounds_are_refused() {
        let beyond = |c: Cause, s: &AtSplit| match &c.spec().search {
            Search::States(st) => (st.beyond)(s),
            _ => panic!("{c:?} is a state cause"),
        };
        let mut s = AtSplit::default();
        assert_eq!(beyond(Cause::Current, &s), None);
        assert_eq!(beyond(Cause::ThrusterLoss, &s), None);
        s.current = [2.5, 2.0];
        assert_eq!(beyond(Cause::Current, &s), Some(TOO_FAST_CURRENT));
        s.loss = [0.9, -0.05];
        assert_eq!(beyond(Cause::ThrusterLoss, &s), None);
        s.loss = [0.2, -0.2];
        assert_eq!(beyond(Cause::ThrusterLoss, &s), Some(NEGATIVE_LOSS));
        s.loss = [0.22, 0.21];
        assert_eq!(beyond(Cause::ThrusterLoss, &s), Some(EQUAL_LOSSES));
        s.loss = [0.22, 0.0];
        assert_eq!(beyond(Cause::ThrusterLoss, &s), None);
        s.loss = [0.03, 0.02];
        assert_eq!(
            beyond(Cause::ThrusterLoss, &s),
            None,
            "too small to be a loss"
        );
    }

    /// The losses' shared part is the smaller loss, declared as the hull's
    /// surge damping: taken from both, it leaves no negative loss.
    #[test]
    fn the_losses_share_the_smaller_one_with_the_hull() {
        let Search::States(st) = &Cause::ThrusterLoss.spec().search else {
            panic!("the losses are states");
        };
        let shared = st.shared.as_ref().expect("the losses have a shared part");
        assert_eq!(shared.cause, Cause::SurgeDamping);
        let part = |loss: [f64; 2]| {
            (shared.size)(&AtSplit {
                loss,
                ..AtSplit::default()
            })
        };
        assert_eq!(part([0.23, 0.51]), 0.23);
        assert_eq!(part([0.19, -0.31]), -0.31);
        assert_eq!(part([0.0, 0.4]), 0.0);
        let Search::States(current) = &Cause::Current.spec().search else {
            panic!("the current is states");
        };
        assert!(current.shared.is_none());
    }

    #[test]
    fn the_antenna_is_searched_on_the_hull() {
        let Search::Plane(p) = &Cause::LeverArm.spec().search else {
            panic!("the lever arm is a plane");
        };
        let mut otter = VesselParams::default();
        assert_eq!((p.bounds_m)(&otter), [(-1.0, 1.0), (-0.54, 0.54)]);
        // Found against the profile's antenna: the offsets that keep the
        // antenna within the 2 m x 1.08 m hull.
        otter.antenna_m = [0.25, -0.5];
        let [(x_lo, x_hi), (y_lo, y_hi)] = (p.bounds_m)(&otter);
        assert_eq!((x_lo, x_hi), (-1.25, 0.75));
        assert!((y_lo - -0.04).abs() < 1e-12 && (y_hi - 1.04).abs() < 1e-12);
    }

    #[test]
    fn the_larger_loss_names_the_side_and_a_current_its_direction() {
        let acc = Acceptance::default();
        let s = AtSplit {
            loss: [0.05, 0.3],
            loss_sigma: [0.01, 0.02],
            ..AtSplit::default()
        };
        let r = loss_report(&s, &acc);
        assert_eq!(r.side, Some("starboard"));
        assert_eq!((r.size, r.z), (0.3, 15.0));
        let s = AtSplit {
            current: [0.0, 0.2],
            current_cov: [[1e-4, 0.0], [0.0, 1e-4]],
            ..AtSplit::default()
        };
        let r = current_report(&s, &acc);
        assert!((r.size - 0.2).abs() < 1e-12);
        assert!((r.parameters[1].1 - 90.0).abs() < 1e-9, "toward east");
        assert!((r.z - 20.0).abs() < 1e-9);
    }
}
