//! The catalogue of causes, their fitting on the training part, their
//! judgement on the held-out part, and the greedy selection (see the module
//! doc of [`crate::diagnose`]).

use super::pass::{AtSplit, PassOptions, PassOut, kinetic_pass, water_pass};
use super::prepare::Prepared;
use super::residuals::{InnovationRecord, ResidualSummary, summarise};
use crate::estimator::Term;
use crate::geodesy::rad_to_compass_deg;
use crate::models::effects::SensorEffects;
use crate::twin::TwinConfig;

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
}

impl Cause {
    /// Every cause, in the order they are tried.
    pub const ALL: [Cause; 8] = [
        Cause::Current,
        Cause::ThrusterLoss,
        Cause::HeadingOffset,
        Cause::SogScale,
        Cause::GnssLatency,
        Cause::LeverArm,
        Cause::StwScale,
        Cause::Sideslip,
    ];

    /// The name used in reports and in `twin diagnose --json`.
    pub fn name(self) -> &'static str {
        match self {
            Cause::Current => "current",
            Cause::ThrusterLoss => "thruster_loss",
            Cause::HeadingOffset => "heading_offset",
            Cause::SogScale => "sog_scale",
            Cause::GnssLatency => "gnss_latency",
            Cause::LeverArm => "lever_arm",
            Cause::StwScale => "stw_scale",
            Cause::Sideslip => "sideslip",
        }
    }
}

/// The bars a cause must clear to be reported, fixed in advance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Acceptance {
    /// Held-out log-likelihood gain (natural log) at least this.
    pub min_gain_nll: f64,
    /// Fitted size at least this many standard deviations from none.
    pub min_z: f64,
    /// Smallest current worth reporting, m/s.
    pub min_current_mps: f64,
    /// Smallest propeller loss worth reporting.
    pub min_loss: f64,
    /// Smallest heading offset worth reporting, rad.
    pub min_heading_offset_rad: f64,
    /// Smallest SOG scale error worth reporting (|scale - 1|).
    pub min_sog_scale_error: f64,
    /// Smallest latency worth reporting, s.
    pub min_latency_s: f64,
    /// Smallest lever arm worth reporting, m.
    pub min_lever_arm_m: f64,
    /// Smallest STW scale error worth reporting (|scale - 1|).
    pub min_stw_scale_error: f64,
    /// Smallest sideslip worth reporting, m/s per rad/s.
    pub min_sideslip_m: f64,
}

impl Default for Acceptance {
    /// A likelihood ratio of e^10 on held-out data, 3 sigma, and sizes at
    /// which a user would act: 5 cm/s of current, 3 % of thrust, 1 deg of
    /// heading, 1 % of speed, 0.1 s of latency, 30 cm of antenna offset, 2 %
    /// of a log's speed (paddle wheels are rarely better calibrated), and a
    /// sideslip of 0.5 m/s per rad/s (a degree of drift in an ordinary turn).
    fn default() -> Self {
        Self {
            min_gain_nll: 10.0,
            min_z: 3.0,
            min_current_mps: 0.05,
            min_loss: 0.03,
            min_heading_offset_rad: 1f64.to_radians(),
            min_sog_scale_error: 0.01,
            min_latency_s: 0.1,
            min_lever_arm_m: 0.3,
            min_stw_scale_error: 0.02,
            min_sideslip_m: 0.5,
        }
    }
}

/// Tuning of a diagnosis.
#[derive(Debug, Clone, PartialEq)]
pub struct DiagnoseConfig {
    /// Fraction of the log (by steps, at its end) held out for judging.
    pub holdout_fraction: f64,
    /// Prediction horizons for the k-step-ahead errors, s.
    pub horizons_s: Vec<f64>,
    /// A forecast is started this often in the held-out part, s.
    pub forecast_every_s: f64,
    /// The bars.
    pub acceptance: Acceptance,
    /// The most findings reported.
    pub max_findings: usize,
    /// Threads the candidates of a round are fitted on (each fit is
    /// independent; 1 fits them one after the other).
    pub threads: usize,
    /// The twin whose kinetic model is the base with propeller data.
    pub twin: TwinConfig,
    /// Process noise density of the kinematic base (no propeller data).
    pub water_process_noise: [f64; 7],
    /// Measurement noise standard deviations of the kinematic base:
    /// `[position m, SOG m/s, COG rad, heading rad, STW m/s]`.
    pub water_measurement_sigma: [f64; 5],
}

impl Default for DiagnoseConfig {
    fn default() -> Self {
        Self {
            holdout_fraction: 0.4,
            horizons_s: vec![5.0, 15.0, 30.0],
            forecast_every_s: 10.0,
            acceptance: Acceptance::default(),
            max_findings: 4,
            threads: 1,
            // The harbour water's random forces alone: what the model lacks
            // must show in the residuals, not be absorbed by the velocities.
            twin: TwinConfig {
                kinetic: crate::estimator::KineticConfig::otter().for_search(),
                ..TwinConfig::default()
            },
            // Any vessel: position and heading follow the velocity; speed and
            // yaw rate wander (0.1 m/s^2 and 0.01 rad/s^2 over a second); the
            // current drifts slowly.
            water_process_noise: [1e-4, 1e-4, 1e-6, 1e-2, 1e-4, 1e-6, 1e-6],
            water_measurement_sigma: [0.5, 0.1, 0.05, 1f64.to_radians(), 0.1],
        }
    }
}

/// What a finding gains on the held-out data.
#[derive(Debug, Clone, PartialEq)]
pub struct Gain {
    /// Held-out log-likelihood gain over the model without this finding.
    pub heldout_nll_gain: f64,
    /// Held-out steps.
    pub heldout_steps: usize,
    /// Mean NIS per degree of freedom on held-out data, before.
    pub nis_per_dof_before: f64,
    /// ... and after.
    pub nis_per_dof_after: f64,
    /// Position prediction RMSE on held-out data per horizon, before: `(horizon s, m)`.
    pub prediction_rmse_before_m: Vec<(f64, f64)>,
    /// ... and after.
    pub prediction_rmse_after_m: Vec<(f64, f64)>,
}

/// A named cause with its fitted parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct Finding {
    /// The cause.
    pub cause: Cause,
    /// Numeric parameters: name, value, standard deviation.
    pub parameters: Vec<(&'static str, f64, f64)>,
    /// A text parameter (the side of a thruster loss).
    pub side: Option<&'static str>,
    /// What in the nominal residuals points at it.
    pub evidence: Vec<String>,
    /// What the model gains with it, on held-out data.
    pub gain: Gain,
}

/// A cause tried and not reported, with why.
#[derive(Debug, Clone, PartialEq)]
pub struct Rejected {
    /// The cause.
    pub cause: Cause,
    /// Its fitted parameters.
    pub parameters: Vec<(&'static str, f64, f64)>,
    /// Its held-out gain.
    pub heldout_nll_gain: f64,
    /// Which bar it missed.
    pub reason: String,
}

/// Which model the diagnosis is built on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BaseModel {
    /// The Otter's kinetic twin, driven by the logged propeller speeds.
    Kinetic,
    /// The kinematic model of a vessel through water (no propeller data).
    Water,
}

/// The outcome of a diagnosis.
#[derive(Debug, Clone, PartialEq)]
pub struct Diagnosis {
    /// The base model.
    pub base: BaseModel,
    /// Steps used.
    pub steps: usize,
    /// Steps in the training part.
    pub training_steps: usize,
    /// The nominal model's residuals over the held-out part.
    pub nominal: ResidualSummary,
    /// The residuals with every finding, over the held-out part.
    pub extended: ResidualSummary,
    /// The findings, in the order they were accepted.
    pub findings: Vec<Finding>,
    /// The causes tried in the last round and not reported.
    pub rejected: Vec<Rejected>,
    /// The nominal model's innovations over the held-out part (for plots).
    pub nominal_records: Vec<InnovationRecord>,
    /// The extended model's innovations over the held-out part.
    pub extended_records: Vec<InnovationRecord>,
}

// ----------------------------------------------------------------------------
// Hypotheses and one pass of a filter over the log.

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Hypothesis {
    pub current: Term<2>,
    pub loss: Term<2>,
    pub effects: SensorEffects,
    pub stw_scale: f64,
    pub sideslip_m: f64,
}

impl Hypothesis {
    pub(super) fn nominal() -> Self {
        Self {
            current: Term::Off,
            loss: Term::Off,
            effects: SensorEffects::default(),
            stw_scale: 1.0,
            sideslip_m: 0.0,
        }
    }
}

// ----------------------------------------------------------------------------
// Fitting.

struct Ctx<'a> {
    prep: &'a Prepared,
    base: BaseModel,
    config: &'a DiagnoseConfig,
    split: usize,
}

impl Ctx<'_> {
    fn pass(&self, hyp: &Hypothesis, train_only: bool, record: bool) -> PassOut {
        let opts = PassOptions {
            split: self.split,
            train_only,
            record,
            config: self.config,
        };
        match self.base {
            BaseModel::Kinetic => kinetic_pass(self.prep, hyp, opts),
            BaseModel::Water => water_pass(self.prep, hyp, opts),
        }
    }

    fn train_nll(&self, hyp: &Hypothesis) -> f64 {
        let out = self.pass(hyp, true, false);
        if out.failed || !out.nll_train.is_finite() {
            f64::INFINITY
        } else {
            out.nll_train
        }
    }
}

/// Minimises `f` on `[lo, hi]`: a grid, then golden-section search around
/// the best grid point. Returns the minimiser and the curvature-based
/// standard deviation `1 / sqrt(f'')` (the likelihood's Fisher information).
pub(super) fn minimise_1d(f: &dyn Fn(f64) -> f64, lo: f64, hi: f64, grid: usize) -> (f64, f64) {
    let step = (hi - lo) / grid as f64;
    let mut best = (lo, f(lo));
    for i in 1..=grid {
        let x = lo + step * i as f64;
        let v = f(x);
        if v < best.1 {
            best = (x, v);
        }
    }
    let (mut a, mut b) = ((best.0 - step).max(lo), (best.0 + step).min(hi));
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..7 {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - g * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + g * (b - a);
            fd = f(d);
        }
    }
    let x = 0.5 * (a + b);
    let h = step / 4.0;
    let curvature = (f(x + h) - 2.0 * f(x) + f(x - h)) / (h * h);
    let sigma = if curvature > 0.0 {
        1.0 / curvature.sqrt()
    } else {
        f64::INFINITY
    };
    (x, sigma)
}

/// A candidate fitted on the training part, as a fixed hypothesis.
struct Fitted {
    cause: Cause,
    hypothesis: Hypothesis,
    parameters: Vec<(&'static str, f64, f64)>,
    side: Option<&'static str>,
    /// The size compared with the practical bar, and its z.
    size: f64,
    z: f64,
    practical: f64,
    /// The fit ran to the edge of its search range: the value is not
    /// determined (another cause, or several, is being imitated).
    at_edge: bool,
    /// The fit ran to a physical bound of its cause (a latency of zero,
    /// wanting a negative one): what it says instead, for the rejection.
    beyond_physics: Option<&'static str>,
    /// The state estimates of the fitting pass (for refreshing the
    /// parameters of state causes accepted earlier and re-estimated jointly).
    states: Option<AtSplit>,
}

type StateParameters = (
    Vec<(&'static str, f64, f64)>,
    Option<&'static str>,
    f64,
    f64,
    f64,
);

/// The reported parameters of a state cause from the estimates at the split.
fn state_parameters(cause: Cause, s: &AtSplit, acc: &Acceptance) -> StateParameters {
    if cause == Cause::Current {
        let [n, e] = s.current;
        let speed = n.hypot(e);
        // Speed and direction variances by first-order propagation.
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
        (
            vec![
                ("speed_mps", speed, sd),
                (
                    "toward_deg",
                    rad_to_compass_deg(e.atan2(n)),
                    var_dir.max(0.0).sqrt().to_degrees(),
                ),
                ("north_mps", n, c[0][0].max(0.0).sqrt()),
                ("east_mps", e, c[1][1].max(0.0).sqrt()),
            ],
            None,
            speed,
            speed / sd.max(1e-12),
            acc.min_current_mps,
        )
    } else {
        // The larger loss names the side.
        let side = if s.loss[0] >= s.loss[1] { 0 } else { 1 };
        (
            vec![
                ("loss", s.loss[side], s.loss_sigma[side]),
                ("loss_port", s.loss[0], s.loss_sigma[0]),
                ("loss_starboard", s.loss[1], s.loss_sigma[1]),
            ],
            Some(if side == 0 { "port" } else { "starboard" }),
            s.loss[side],
            s.loss[side] / s.loss_sigma[side].max(1e-12),
            acc.min_loss,
        )
    }
}

/// Why a latency fit that wants to go below zero is not a latency.
const NEGATIVE_LATENCY: &str = "it wants a negative latency, which no receiver has: the fixes lead the model, \
     a difference in the vessel's dynamics (a time constant, damping, mass), not a clock";

/// Whether a latency fit at its physical floor (zero) would fit the
/// training data better still below it (by `margin_nll`, at 0.1 s below):
/// the data want a negative latency.
fn wants_below(
    cause: Cause,
    v: f64,
    lo: f64,
    hi: f64,
    nll: &dyn Fn(f64) -> f64,
    margin_nll: f64,
) -> bool {
    cause == Cause::GnssLatency
        && near_edge(v, lo, hi)
        && v < 0.5 * (lo + hi)
        && nll(lo - 0.1) < nll(lo) - margin_nll
}

/// True when `v` is within 2 % of the width of `[lo, hi]` from an end.
fn near_edge(v: f64, lo: f64, hi: f64) -> bool {
    let margin = 0.02 * (hi - lo);
    v <= lo + margin || v >= hi - margin
}

#[allow(clippy::too_many_lines)] // One arm per cause of the catalogue.
fn fit(ctx: &Ctx<'_>, accepted: &Hypothesis, cause: Cause) -> Option<Fitted> {
    let acc = &ctx.config.acceptance;
    let mut hyp = *accepted;
    // Already-accepted states are re-estimated jointly with the candidate.
    let free_states = |mut h: Hypothesis| {
        if matches!(h.current, Term::Fixed(_)) {
            h.current = Term::Free;
        }
        if matches!(h.loss, Term::Fixed(_)) {
            h.loss = Term::Free;
        }
        h
    };
    let fix_states = |h: &mut Hypothesis, s: &AtSplit| {
        if h.current == Term::Free {
            h.current = Term::Fixed(s.current);
        }
        if h.loss == Term::Free {
            h.loss = Term::Fixed(s.loss);
        }
    };
    match cause {
        Cause::Current | Cause::ThrusterLoss => {
            let mut train = free_states(hyp);
            if cause == Cause::Current {
                train.current = Term::Free;
            } else {
                train.loss = Term::Free;
            }
            let out = ctx.pass(&train, true, false);
            if out.failed {
                return None;
            }
            let s = out.at_split;
            fix_states(&mut train, &s);
            hyp = train;
            let (parameters, side, size, z, practical) = state_parameters(cause, &s, acc);
            Some(Fitted {
                cause,
                hypothesis: hyp,
                parameters,
                side,
                size,
                z,
                practical,
                at_edge: false,
                beyond_physics: None,
                states: Some(s),
            })
        }
        Cause::HeadingOffset
        | Cause::SogScale
        | Cause::GnssLatency
        | Cause::StwScale
        | Cause::Sideslip => {
            let water_only = matches!(cause, Cause::StwScale | Cause::Sideslip);
            if (cause == Cause::HeadingOffset && !ctx.prep.has_heading)
                || (water_only && ctx.base != BaseModel::Water)
                || (cause == Cause::StwScale && !ctx.prep.has_stw)
                || (cause == Cause::Sideslip && !ctx.prep.has_heading)
            {
                return None;
            }
            // States free while the effect is scanned, as they will be.
            let train = free_states(hyp);
            let with = |v: f64| {
                let mut h = train;
                match cause {
                    Cause::HeadingOffset => h.effects.heading_offset_rad = v,
                    Cause::SogScale => h.effects.sog_scale = v,
                    Cause::StwScale => h.stw_scale = v,
                    Cause::Sideslip => h.sideslip_m = v,
                    _ => h.effects.gnss_latency_s = v,
                }
                h
            };
            let f = |v: f64| ctx.train_nll(&with(v));
            let (lo, hi, grid, neutral) = match cause {
                Cause::HeadingOffset => (-15f64.to_radians(), 15f64.to_radians(), 6, 0.0),
                Cause::SogScale => (0.85, 1.15, 6, 1.0),
                Cause::StwScale => (0.7, 1.3, 6, 1.0),
                Cause::Sideslip => (-20.0, 20.0, 8, 0.0),
                // A fix is stamped at or after the instant it describes, never
                // before: a latency is physically in [0, 2] s.
                _ => (0.0, 2.0, 6, 0.0),
            };
            let (v, sd) = minimise_1d(&f, lo, hi, grid);
            let mut h = with(v);
            let out = ctx.pass(&h, true, false);
            fix_states(&mut h, &out.at_split);
            let (name, shown, shown_sd, practical) = match cause {
                Cause::HeadingOffset => (
                    "offset_deg",
                    v.to_degrees(),
                    sd.to_degrees(),
                    acc.min_heading_offset_rad,
                ),
                Cause::SogScale => ("scale", v, sd, acc.min_sog_scale_error),
                Cause::StwScale => ("scale", v, sd, acc.min_stw_scale_error),
                Cause::Sideslip => ("lateral_mps_per_radps", v, sd, acc.min_sideslip_m),
                _ => ("latency_s", v, sd, acc.min_latency_s),
            };
            Some(Fitted {
                cause,
                hypothesis: h,
                parameters: vec![(name, shown, shown_sd)],
                side: None,
                size: (v - neutral).abs(),
                z: (v - neutral).abs() / sd.max(1e-12),
                practical,
                at_edge: near_edge(v, lo, hi),
                beyond_physics: wants_below(cause, v, lo, hi, &f, acc.min_gain_nll)
                    .then_some(NEGATIVE_LATENCY),
                states: Some(out.at_split),
            })
        }
        Cause::LeverArm => {
            if ctx.base == BaseModel::Water && !ctx.prep.has_heading {
                return None;
            }
            let train = free_states(hyp);
            let with = |x: f64, y: f64| {
                let mut h = train;
                h.effects.antenna_m = [x, y];
                h
            };
            // Coordinate descent: the two offsets act on different axes of
            // the fix and are nearly independent.
            let y0 = train.effects.antenna_m[1];
            let (x, sx) = minimise_1d(&|v| ctx.train_nll(&with(v, y0)), -10.0, 10.0, 8);
            let (y, sy) = minimise_1d(&|v| ctx.train_nll(&with(x, v)), -10.0, 10.0, 8);
            let mut h = with(x, y);
            let out = ctx.pass(&h, true, false);
            fix_states(&mut h, &out.at_split);
            let size = x.hypot(y);
            let sd = if size > 1e-9 {
                ((x * sx).powi(2) + (y * sy).powi(2)).sqrt() / size
            } else {
                sx.max(sy)
            };
            Some(Fitted {
                cause,
                hypothesis: h,
                parameters: vec![("x_m", x, sx), ("y_m", y, sy)],
                side: None,
                size,
                z: size / sd.max(1e-12),
                practical: acc.min_lever_arm_m,
                at_edge: near_edge(x, -10.0, 10.0) || near_edge(y, -10.0, 10.0),
                beyond_physics: None,
                states: Some(out.at_split),
            })
        }
    }
}

fn evidence(before: &ResidualSummary, after: &ResidualSummary) -> Vec<String> {
    use super::residuals::{COMPONENT_COUNT, COMPONENTS};
    let mut lines: Vec<(f64, String)> = Vec::new();
    for c in 0..COMPONENT_COUNT {
        if !before.measured[c] {
            continue;
        }
        let drop = before.bias_z[c].abs() - after.bias_z[c].abs();
        if before.bias_z[c].abs() > 3.0 && drop > 0.0 {
            lines.push((
                drop,
                format!(
                    "{} innovation mean {:.4} ({:.1} standard errors) -> {:.4} ({:.1})",
                    COMPONENTS[c], before.mean[c], before.bias_z[c], after.mean[c], after.bias_z[c]
                ),
            ));
        }
        let rms_drop = 1.0 - after.rms[c] / before.rms[c];
        if rms_drop > 0.1 {
            lines.push((
                10.0 * rms_drop,
                format!(
                    "{} innovation RMS {:.4} -> {:.4}",
                    COMPONENTS[c], before.rms[c], after.rms[c]
                ),
            ));
        }
    }
    for s in &before.signatures {
        if s.correlation.abs() < 0.3 {
            continue;
        }
        let after_corr = after
            .signatures
            .iter()
            .find(|a| a.component == s.component && a.signature == s.signature)
            .map(|a| a.correlation)
            .unwrap_or(0.0);
        if s.correlation.abs() - after_corr.abs() > 0.2 {
            lines.push((
                5.0 * (s.correlation.abs() - after_corr.abs()),
                format!(
                    "{} innovation follows {} (correlation {:.2} -> {:.2})",
                    s.component, s.signature, s.correlation, after_corr
                ),
            ));
        }
    }
    lines.sort_by(|a, b| b.0.total_cmp(&a.0));
    lines.into_iter().take(4).map(|(_, l)| l).collect()
}

/// Diagnoses a prepared log.
#[allow(clippy::too_many_lines)] // The greedy search's steps, read top to bottom.
pub fn diagnose(prep: &Prepared, config: &DiagnoseConfig) -> Diagnosis {
    let base = if prep.has_propellers {
        BaseModel::Kinetic
    } else {
        BaseModel::Water
    };
    let n = prep.steps.len();
    let split = ((n as f64) * (1.0 - config.holdout_fraction))
        .round()
        .clamp(2.0, (n - 1) as f64) as usize;
    let ctx = Ctx {
        prep,
        base,
        config,
        split,
    };
    let mut accepted = Hypothesis::nominal();
    let nominal_out = ctx.pass(&accepted, false, true);
    let nominal = summarise(&nominal_out.records);
    let nominal_records = nominal_out.records.clone();
    let mut current_out = nominal_out;
    let mut findings = Vec::new();
    let mut rejected = Vec::new();
    let mut remaining: Vec<Cause> = Cause::ALL
        .iter()
        .copied()
        .filter(|c| *c != Cause::ThrusterLoss || base == BaseModel::Kinetic)
        .collect();
    while findings.len() < config.max_findings && !remaining.is_empty() {
        // Each candidate's fit and held-out run is independent of the others.
        let try_one = |cause: Cause| -> Option<(Fitted, PassOut)> {
            let f = fit(&ctx, &accepted, cause)?;
            let out = ctx.pass(&f.hypothesis, false, true);
            (!out.failed).then_some((f, out))
        };
        let threads = config.threads.clamp(1, remaining.len().max(1));
        let mut scored: Vec<(Fitted, PassOut)> = if threads == 1 {
            remaining.iter().filter_map(|c| try_one(*c)).collect()
        } else {
            let next = std::sync::atomic::AtomicUsize::new(0);
            let results = std::sync::Mutex::new(Vec::new());
            std::thread::scope(|s| {
                for _ in 0..threads {
                    s.spawn(|| {
                        loop {
                            let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                            let Some(cause) = remaining.get(i) else { break };
                            if let Some(r) = try_one(*cause)
                                && let Ok(mut v) = results.lock()
                            {
                                v.push((i, r));
                            }
                        }
                    });
                }
            });
            let mut v = results.into_inner().unwrap_or_default();
            // The order of the candidates, whatever the threads did.
            v.sort_by_key(|(i, _)| *i);
            v.into_iter().map(|(_, r)| r).collect()
        };
        scored.sort_by(|a, b| {
            (current_out.nll_test - b.1.nll_test).total_cmp(&(current_out.nll_test - a.1.nll_test))
        });
        rejected.clear();
        let mut took = None;
        for (f, out) in scored {
            let gain = current_out.nll_test - out.nll_test;
            let reason = if let Some(why) = f.beyond_physics {
                Some(why.to_string())
            } else if gain < config.acceptance.min_gain_nll {
                Some(format!(
                    "held-out log-likelihood gain {gain:.1} < {}",
                    config.acceptance.min_gain_nll
                ))
            } else if f.z < config.acceptance.min_z {
                Some(format!(
                    "size {:.3} is only {:.1} standard deviations",
                    f.size, f.z
                ))
            } else if f.size < f.practical {
                Some(format!(
                    "size {:.3} is below the practical {:.3}",
                    f.size, f.practical
                ))
            } else if f.at_edge {
                Some("the fit ran to the edge of its search range: not determined (it imitates another cause)".to_string())
            } else {
                None
            };
            match (reason, took.is_none()) {
                (None, true) => took = Some((f, out, gain)),
                (reason, _) => rejected.push(Rejected {
                    cause: f.cause,
                    parameters: f.parameters.clone(),
                    heldout_nll_gain: gain,
                    reason: reason
                        .unwrap_or_else(|| "a larger gain was taken this round".to_string()),
                }),
            }
        }
        let Some((f, out, gain)) = took else {
            break;
        };
        // A cause that made the held-out fit clearly worse this round is not
        // tried again (it imitates nothing the data show).
        let hopeless: Vec<Cause> = rejected
            .iter()
            .filter(|r| r.heldout_nll_gain < -config.acceptance.min_gain_nll)
            .map(|r| r.cause)
            .collect();
        remaining.retain(|c| !hopeless.contains(c));
        let before = summarise(&current_out.records);
        let after = summarise(&out.records);
        findings.push(Finding {
            cause: f.cause,
            parameters: f.parameters,
            side: f.side,
            evidence: evidence(&before, &after),
            gain: Gain {
                heldout_nll_gain: gain,
                heldout_steps: out.steps_test,
                nis_per_dof_before: before.nis_per_dof,
                nis_per_dof_after: after.nis_per_dof,
                prediction_rmse_before_m: current_out.rmse(),
                prediction_rmse_after_m: out.rmse(),
            },
        });
        // State causes accepted earlier were re-estimated jointly with this
        // one: report their joint values.
        if let Some(states) = f.states {
            let n = findings.len() - 1;
            for earlier in findings[..n].iter_mut() {
                if matches!(earlier.cause, Cause::Current | Cause::ThrusterLoss) {
                    let (parameters, side, ..) =
                        state_parameters(earlier.cause, &states, &config.acceptance);
                    earlier.parameters = parameters;
                    earlier.side = side;
                }
            }
        }
        remaining.retain(|c| *c != f.cause);
        accepted = f.hypothesis;
        current_out = out;
    }
    let extended = summarise(&current_out.records);
    Diagnosis {
        base,
        steps: n,
        training_steps: split,
        nominal,
        extended,
        findings,
        rejected,
        nominal_records,
        extended_records: current_out.records,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A latency is searched in [0, 2] s only; a fit stopped at zero is
    /// said to want a negative latency only when the data fit better below
    /// zero, and never for another cause.
    #[test]
    fn a_latency_fit_at_zero_wants_below_only_when_the_data_do() {
        let (lo, hi) = (0.0, 2.0);
        let wants_negative = |v: f64| 1000.0 * (v + 0.15).powi(2);
        let at_zero = |v: f64| 1000.0 * v.powi(2);
        let (v, _) = minimise_1d(&wants_negative, lo, hi, 6);
        assert!(v < 0.05, "the search stops at the floor: {v}");
        assert!(wants_below(
            Cause::GnssLatency,
            v,
            lo,
            hi,
            &wants_negative,
            2.0
        ));
        let (v, _) = minimise_1d(&at_zero, lo, hi, 6);
        assert!(!wants_below(Cause::GnssLatency, v, lo, hi, &at_zero, 2.0));
        assert!(!wants_below(
            Cause::SogScale,
            v,
            lo,
            hi,
            &wants_negative,
            2.0
        ));
        let inside = |v: f64| 1000.0 * (v - 0.4).powi(2);
        let (v, _) = minimise_1d(&inside, lo, hi, 6);
        assert!((v - 0.4).abs() < 0.02, "{v}");
        assert!(!wants_below(Cause::GnssLatency, v, lo, hi, &inside, 2.0));
    }
}
