//! The fitting of the catalogue's causes ([`super::catalogue`]) on the
//! training part, their judgement on the held-out part, and the greedy
//! selection (see the module doc of [`crate::diagnose`]). Each search kind
//! of the catalogue has one fitting function; the one thing written for a
//! cause is the step of a loss that starts late (the catalogue's
//! `LateRise`: `late_step`, `find_loss_after_training`, `size_tracked_loss`).

use super::catalogue::{
    Cause, LATE_START_S, LogKind, OUTSIDE_HULL, PlaneSearch, ScalarSearch, Search, SharedPart,
    StateSearch, larger_loss_side,
};
use super::noise_level;
use super::pass::{AtSplit, PassOptions, PassOut, kinetic_pass, water_pass};
use super::prepare::Prepared;
use super::residuals::{InnovationRecord, ResidualSummary, summarise};
use std::sync::Mutex;

use crate::estimator::Term;
use crate::models::effects::SensorEffects;
use crate::twin::TwinConfig;

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
    /// Smallest error of a profile's parameter worth reporting (|scale - 1|).
    pub min_profile_scale_error: f64,
    /// Smallest scale error of the rate sensor's yaw rate worth reporting
    /// (|scale - 1|).
    pub min_yaw_rate_scale_error: f64,
    /// Smallest bias of the rate sensor worth reporting, rad/s.
    pub min_yaw_rate_bias_radps: f64,
    /// Held-out NIS per degree of freedom above which, after the findings,
    /// the data are called unexplained.
    pub max_explained_nis_per_dof: f64,
    /// A held-out innovation mean further than this many standard errors
    /// from zero, after the findings, is called unexplained too.
    pub max_explained_bias_z: f64,
}

impl Default for Acceptance {
    /// A likelihood ratio of e^10 on held-out data, 3 sigma, and sizes at
    /// which a user would act: 5 cm/s of current, 3 % of thrust, 1 deg of
    /// heading, 1 % of speed, 0.1 s of latency, 30 cm of antenna offset, 2 %
    /// of a log's speed (paddle wheels are rarely better calibrated), a
    /// sideslip of 0.15 m/s per rad/s (it bends the course as a GNSS
    /// latency of 0.1 s does at 1.5 m/s: a drift too small to report must
    /// not leave the latency it imitates to be named in its place; half a
    /// degree of drift at 1.5 m/s in a turn of 0.1 rad/s),
    /// 10 % of a profile's parameter, 2 % of a rate sensor's yaw rate and
    /// 0.1 deg/s of its bias (a degree of heading every ten seconds). The
    /// data are unexplained when the innovations after the findings are
    /// twice as large as the filter expects (NIS per degree of freedom
    /// above 2) or a component's mean is more than 10 standard errors from
    /// zero (the standard errors assume white innovations; a filter under
    /// mismatch has correlated ones, so 3 would flag every imperfect
    /// model).
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
            min_sideslip_m: 0.15,
            min_profile_scale_error: 0.1,
            min_yaw_rate_scale_error: 0.02,
            min_yaw_rate_bias_radps: 0.1f64.to_radians(),
            max_explained_nis_per_dof: 2.0,
            max_explained_bias_z: 10.0,
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
    /// `[position m, SOG m/s, COG rad, heading rad, STW m/s, yaw rate
    /// rad/s]` (the yaw rate's as the extended twin's rate gyro).
    pub water_measurement_sigma: [f64; 6],
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
            water_measurement_sigma: [0.5, 0.1, 0.05, 1f64.to_radians(), 0.1, 0.0087],
        }
    }
}

/// What a finding gains on the held-out data.
#[derive(Debug, Clone, PartialEq)]
pub struct Gain {
    /// Held-out log-likelihood gain over the model with every other
    /// finding and without this one.
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

/// The held-out residuals the findings do not explain: the model is still
/// wrong in a way the catalogue has no cause for.
#[derive(Debug, Clone, PartialEq)]
pub struct Unexplained {
    /// Held-out NIS per degree of freedom with every finding.
    pub nis_per_dof: f64,
    /// The components whose held-out innovation mean is beyond the bar,
    /// with its distance from zero in standard errors.
    pub biased: Vec<(&'static str, f64)>,
}

/// The verdict on the extended model's held-out residuals.
fn unexplained(extended: &ResidualSummary, acc: &Acceptance) -> Option<Unexplained> {
    use super::residuals::COMPONENTS;
    let biased: Vec<(&'static str, f64)> = COMPONENTS
        .iter()
        .zip(extended.bias_z.iter().zip(&extended.measured))
        .filter(|(_, (z, measured))| **measured && z.abs() > acc.max_explained_bias_z)
        .map(|(name, (z, _))| (*name, *z))
        .collect();
    (extended.nis_per_dof > acc.max_explained_nis_per_dof || !biased.is_empty()).then_some(
        Unexplained {
            nis_per_dof: extended.nis_per_dof,
            biased,
        },
    )
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
    /// The causes tried in the last round and not reported, and the
    /// findings dropped when judged again with all the others.
    pub rejected: Vec<Rejected>,
    /// What the findings leave unexplained, when the extended model's
    /// held-out residuals are still well outside what the filter expects
    /// (after a tracked loss has settled: `settled_records`).
    pub unexplained: Option<Unexplained>,
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
    /// The heading sensor's offset as a state of the kinetic base: held
    /// at zero while causes are searched (a heading offset is a cause of
    /// its own), estimated by `identify`, as the live twin does.
    pub heading_bias: Term<1>,
    /// The rate sensor's bias as a state of the kinetic base: held at zero
    /// while causes are searched (the rate sensor's scale is a cause of its
    /// own, its bias is not in the catalogue), estimated by `identify`, as
    /// the live twin does.
    pub yaw_rate_bias: Term<1>,
    pub effects: SensorEffects,
    pub stw_scale: f64,
    pub sideslip_m: f64,
    /// The sideslip that grows with the speed through water, as the sway
    /// per yaw rate at the log's speed under way
    /// ([`super::prepare::Prepared::under_way_speed_mps`]), m/s per rad/s.
    pub speed_sideslip_m: f64,
    /// The profile's `[surge damping, yaw damping, thrust coefficients,
    /// mass]` over the profile's own (kinetic base only).
    pub profile_scales: [f64; 4],
    /// Seconds from the log's first fix from which `Fixed` losses apply
    /// (none before: a step at a loss's onset); 0 for the whole log.
    pub loss_from_s: f64,
    /// `Free` losses tracked by the filter through the held-out part too,
    /// not fixed at the split ([`super::catalogue::LateRise`]).
    pub loss_tracked: bool,
}

impl Hypothesis {
    pub(super) fn nominal() -> Self {
        Self {
            current: Term::Off,
            loss: Term::Off,
            heading_bias: Term::Off,
            yaw_rate_bias: Term::Off,
            effects: SensorEffects::default(),
            stw_scale: 1.0,
            sideslip_m: 0.0,
            speed_sideslip_m: 0.0,
            profile_scales: [1.0; 4],
            loss_from_s: 0.0,
            loss_tracked: false,
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
    /// The passes already run with this log, configuration and split.
    /// `None` in a context whose configuration differs from the one the
    /// memo's passes were run with.
    memo: Option<&'a PassMemo>,
}

/// The passes already run in one diagnosis, by hypothesis. The selection
/// asks for many of them again (a joint refit scores the candidates on the
/// model a greedy round scored them on; a judgement runs the model without
/// a finding as an earlier judgement did), and a pass is a pure function
/// of the log, the configuration, the split and the hypothesis: a pass
/// taken from here is the one that would have been run.
#[derive(Default)]
struct PassMemo {
    /// Training-only passes, without records.
    train: Mutex<Vec<(Hypothesis, PassOut)>>,
    /// Whole passes, with the held-out records.
    whole: Mutex<Vec<(Hypothesis, PassOut)>>,
}

impl PassMemo {
    fn table(&self, train_only: bool) -> &Mutex<Vec<(Hypothesis, PassOut)>> {
        if train_only { &self.train } else { &self.whole }
    }

    fn get(&self, hyp: &Hypothesis, train_only: bool) -> Option<PassOut> {
        let table = self.table(train_only).lock().ok()?;
        table
            .iter()
            .find(|(h, _)| h == hyp)
            .map(|(_, out)| out.clone())
    }

    fn put(&self, hyp: &Hypothesis, train_only: bool, out: &PassOut) {
        if let Ok(mut table) = self.table(train_only).lock() {
            table.push((*hyp, out.clone()));
        }
    }
}

impl<'a> Ctx<'a> {
    /// The same log and split under another configuration, without the
    /// memo (its passes were run with this one's).
    fn with_config<'b>(&self, config: &'b DiagnoseConfig) -> Ctx<'b>
    where
        'a: 'b,
    {
        Ctx {
            config,
            memo: None,
            ..*self
        }
    }

    /// The same log and configuration with the whole log as the training
    /// part (the states at its end, the tracks over all of it), without the
    /// memo (its passes were split elsewhere).
    fn over_whole_log(&self) -> Self {
        Ctx {
            split: self.prep.steps.len(),
            memo: None,
            ..*self
        }
    }

    /// The split's time from the log's first fix, s (a split inside the
    /// log).
    fn split_s(&self) -> f64 {
        self.prep.steps[self.split].fix.time_s - self.prep.steps[0].fix.time_s
    }

    /// One pass over the log with `hyp`: the training part only, without
    /// records, or the whole log with the held-out part's records.
    fn pass(&self, hyp: &Hypothesis, train_only: bool) -> PassOut {
        if let Some(out) = self.memo.and_then(|m| m.get(hyp, train_only)) {
            return out;
        }
        let opts = PassOptions {
            split: self.split,
            train_only,
            record: !train_only,
            config: self.config,
        };
        let out = match self.base {
            BaseModel::Kinetic => kinetic_pass(self.prep, hyp, opts),
            BaseModel::Water => water_pass(self.prep, hyp, opts),
        };
        if let Some(memo) = self.memo {
            memo.put(hyp, train_only, &out);
        }
        out
    }

    fn train_nll(&self, hyp: &Hypothesis) -> f64 {
        let out = self.pass(hyp, true);
        if out.failed || !out.nll_train.is_finite() {
            f64::INFINITY
        } else {
            out.nll_train
        }
    }
}

/// Minimises a smooth `f` on `[lo, hi]` (a likelihood in a cause's size):
/// a grid of `grid` steps, then two parabolic steps from the best grid
/// point. Returns the minimiser and the curvature-based standard deviation
/// `1 / sqrt(f'')` (the likelihood's Fisher information).
///
/// The first step is Newton's on a three-point stencil a quarter of a grid
/// step wide around the best grid point, whose curvature gives the
/// standard deviation; the second puts a parabola through the three
/// lowest of the values then known. The minimiser is the lowest point
/// evaluated. A likelihood is close to a parabola within a grid step of
/// its minimum, so this puts the minimiser as close as the seven steps of
/// a golden-section search would, in four evaluations beyond the grid
/// against twelve; where it is not (the likelihood in a hull's mass is
/// steeper on the light side), the second step corrects the first, and
/// the result is never worse than the best grid point. A best grid point
/// at the range's edge, a neighbour without a finite value, or a
/// likelihood whose curvature read a quarter of a grid step wide differs
/// from the one read a grid step wide by more than [`CURVATURE_AGREEMENT`]
/// (not smooth at the grid's scale) is refined by golden section instead,
/// as [`minimise_1d_golden`] does.
pub(super) fn minimise_1d(f: &dyn Fn(f64) -> f64, lo: f64, hi: f64, grid: usize) -> (f64, f64) {
    let step = (hi - lo) / grid as f64;
    let h = step / 4.0;
    let at = |i: usize| lo + step * i as f64;
    let values = on_grid(f, lo, step, grid);
    let b = best_index(&values);
    if b == 0 || b == grid || !(values[b - 1].is_finite() && values[b + 1].is_finite()) {
        return golden_from_grid(f, lo, hi, (at(b), values[b]), step);
    }
    let (x0, bracket) = (at(b), (at(b - 1), at(b + 1)));
    let stencil = [(x0 - h, f(x0 - h)), (x0, values[b]), (x0 + h, f(x0 + h))];
    let wide = [
        (bracket.0, values[b - 1]),
        (x0, values[b]),
        (bracket.1, values[b + 1]),
    ];
    let narrow_over_wide = parabola_curvature(&stencil) / parabola_curvature(&wide);
    if !(CURVATURE_AGREEMENT.contains(&narrow_over_wide)) {
        return golden_from_grid(f, lo, hi, (x0, values[b]), step);
    }
    let mut known = wide.to_vec();
    known.extend([stencil[0], stencil[2]]);
    for _ in 0..2 {
        if let Some(x) =
            parabola_vertex(&lowest_three(&known)).map(|x| x.clamp(bracket.0, bracket.1))
            && known.iter().all(|(k, _)| *k != x)
        {
            known.push((x, f(x)));
        }
    }
    let lowest = known
        .iter()
        .copied()
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .expect("the bracket and the stencil are known");
    (lowest.0, sd_of_curvature(parabola_curvature(&stencil)))
}

/// How far the curvature read a quarter of a grid step wide may differ
/// from the one read a grid step wide, as a ratio, for the likelihood to be
/// taken as smooth at the grid's scale. Where the ratio is outside it (the
/// filter's likelihood on a real log can jump by hundreds between values
/// of a parameter 0.02 apart), parabolic steps would follow the jumps, and
/// [`minimise_1d`] searches by golden section instead.
const CURVATURE_AGREEMENT: std::ops::RangeInclusive<f64> = 0.5..=2.0;

/// The three points of `known` with the lowest values, in order of `x`.
fn lowest_three(known: &[(f64, f64)]) -> [(f64, f64); 3] {
    let mut points = known.to_vec();
    points.sort_by(|a, b| a.1.total_cmp(&b.1));
    let mut three = [points[0], points[1], points[2]];
    three.sort_by(|a, b| a.0.total_cmp(&b.0));
    three
}

/// The vertex of the parabola through three points in order of `x`, where
/// it opens upwards; none otherwise.
fn parabola_vertex(p: &[(f64, f64); 3]) -> Option<f64> {
    let curvature = parabola_curvature(p);
    if curvature.is_nan() || curvature <= 0.0 {
        return None;
    }
    let [(x0, f0), (x1, f1), (x2, f2)] = *p;
    let (d0, d2) = ((x1 - x0) * (f1 - f2), (x1 - x2) * (f1 - f0));
    let vertex = x1 - ((x1 - x0) * d0 - (x1 - x2) * d2) / (2.0 * (d0 - d2));
    vertex.is_finite().then_some(vertex)
}

/// The second derivative of the parabola through three points in order of
/// `x` (twice their second divided difference).
fn parabola_curvature(p: &[(f64, f64); 3]) -> f64 {
    let [(x0, f0), (x1, f1), (x2, f2)] = *p;
    let slope_left = (f1 - f0) / (x1 - x0);
    let slope_right = (f2 - f1) / (x2 - x1);
    2.0 * (slope_right - slope_left) / (x2 - x0)
}

/// Minimises `f` on `[lo, hi]` as [`minimise_1d`] does, for an `f` that is
/// not smooth (the likelihood in a step's onset moves only as the onset
/// crosses a sample): a grid, then golden-section search around the best
/// grid point.
pub(super) fn minimise_1d_golden(
    f: &dyn Fn(f64) -> f64,
    lo: f64,
    hi: f64,
    grid: usize,
) -> (f64, f64) {
    let step = (hi - lo) / grid as f64;
    let values = on_grid(f, lo, step, grid);
    let b = best_index(&values);
    golden_from_grid(f, lo, hi, (lo + step * b as f64, values[b]), step)
}

/// `f` at the `grid + 1` points from `lo`, `step` apart.
fn on_grid(f: &dyn Fn(f64) -> f64, lo: f64, step: f64, grid: usize) -> Vec<f64> {
    (0..=grid).map(|i| f(lo + step * i as f64)).collect()
}

/// The index of the first least of `values` (0 where none is finite).
fn best_index(values: &[f64]) -> usize {
    let mut best = 0;
    for (i, v) in values.iter().enumerate() {
        if *v < values[best] {
            best = i;
        }
    }
    best
}

/// Golden-section search within a grid step of the best grid point
/// `best` (its place and value; seven steps), and the standard deviation
/// of the curvature there. The result is never worse than `best`: where
/// the likelihood is not unimodal within the bracket (it can jump by
/// hundreds between values 0.01 apart on a real log), the search's point
/// can be, and the best grid point stands.
fn golden_from_grid(
    f: &dyn Fn(f64) -> f64,
    lo: f64,
    hi: f64,
    best: (f64, f64),
    step: f64,
) -> (f64, f64) {
    let (best_x, best_f) = best;
    let searched = golden_section(f, (best_x - step).max(lo), (best_x + step).min(hi), 7);
    let at_searched = f(searched);
    let (x, fx) = if at_searched <= best_f {
        (searched, at_searched)
    } else {
        best
    };
    let h = step / 4.0;
    let curvature = (f(x + h) - 2.0 * fx + f(x - h)) / (h * h);
    (x, sd_of_curvature(curvature))
}

/// `1 / sqrt(f'')`: the standard deviation a negative log-likelihood's
/// curvature gives; infinite where it has none.
fn sd_of_curvature(curvature: f64) -> f64 {
    if curvature > 0.0 {
        1.0 / curvature.sqrt()
    } else {
        f64::INFINITY
    }
}

/// The middle of the bracket left of `[lo, hi]` after `steps` steps of a
/// golden-section search for the minimum of `f` (unimodal there): each
/// step one evaluation, the bracket shrinking by the golden ratio.
pub(super) fn golden_section(f: &dyn Fn(f64) -> f64, lo: f64, hi: f64, steps: usize) -> f64 {
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut a, mut b) = (lo, hi);
    let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..steps {
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
    0.5 * (a + b)
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
    /// The cause fitted with it for the part of its states that the other
    /// imitates ([`SharedPart`]): the two are one candidate.
    companion: Option<Box<Fitted>>,
    /// How a scalar cause's value was found, for [`settle`].
    scalar_fit: Option<ScalarFit>,
}

/// A scalar cause's fit on the training part: the hypothesis it was
/// searched on, the value and its standard deviation (in the hypothesis'
/// unit).
#[derive(Clone, Copy)]
struct ScalarFit {
    train: Hypothesis,
    value: f64,
    sd: f64,
}

/// What the training likelihood's slope says of a candidate's fit
/// ([`settle`]).
enum Settled {
    /// At a minimum (or not a scalar fit: nothing to say).
    AtMinimum,
    /// Moved to the minimum the slope pointed to, with its held-out pass.
    Moved(Box<(Fitted, PassOut)>),
    /// No minimum the standard deviation describes: why.
    NotSmooth(String),
}

/// Whether a scalar fit sits at a minimum of the training likelihood. Read
/// over a thousandth of the fit's standard deviation, the slope times the
/// standard deviation is how many standard deviations away the parabola
/// the standard deviation stands for puts the minimum: a smooth
/// likelihood's fit puts it within a fraction of one. Where it is further
/// than three, Newton steps (the curvature read one standard deviation
/// wide) follow the slope, at most [`NEWTON_STEPS`] and within the cause's
/// bounds: a search that stopped short of a smooth minimum is moved there
/// (a mass scale fitted at 0.80 +- 0.03 whose minimum the slope put three
/// of those lower, on a vessel whose mass is 0.77 of the profile's). Where
/// they reach none, neither the value nor its standard deviation says
/// anything of the data: a likelihood whose filter's path hangs on the
/// smallest difference (a vessel at a standstill without a heading
/// sensor, its heading left to the linearisation) has slopes of thousands
/// of standard deviations between its jumps.
fn settle(ctx: &Ctx<'_>, f: &Fitted) -> Settled {
    let Some(fit) = f.scalar_fit else {
        return Settled::AtMinimum;
    };
    let Search::Scalar(search) = &f.cause.spec().search else {
        return Settled::AtMinimum;
    };
    if !(fit.sd.is_finite() && fit.sd > 0.0) {
        return Settled::AtMinimum;
    }
    let nll = |v: f64| ctx.train_nll(&with_scalar(fit.train, search, v));
    let (lo, hi) = search.bounds;
    let (mut v, mut sd) = (fit.value, fit.sd);
    let mut first_away_sd = None;
    for step in 0..=NEWTON_STEPS {
        let delta = SLOPE_READ_OVER_SD * sd;
        let slope = (nll(v + delta) - nll(v - delta)) / (2.0 * delta);
        let away_sd = (slope * sd).abs();
        first_away_sd.get_or_insert(away_sd);
        if away_sd <= MAX_MINIMUM_AWAY_SD {
            if step == 0 {
                return Settled::AtMinimum;
            }
            let moved = scalar_fitted(ctx, fit.train, f.cause, search, v, sd);
            let out = ctx.pass(&moved.hypothesis, false);
            if out.failed {
                break;
            }
            return Settled::Moved(Box::new((moved, out)));
        }
        if step == NEWTON_STEPS {
            break;
        }
        let curvature = (nll(v + sd) - 2.0 * nll(v) + nll(v - sd)) / (sd * sd);
        let next = v - slope / curvature;
        if !(curvature > 0.0 && next > lo && next < hi) {
            break;
        }
        (v, sd) = (next, 1.0 / curvature.sqrt());
    }
    let first = first_away_sd.unwrap_or(f64::NAN);
    Settled::NotSmooth(format!(
        "the training likelihood's slope at its fit puts the minimum {first:.0} of its standard deviations away, and following the slope finds none: the likelihood is not smooth there, so neither its size nor its standard deviation is determined"
    ))
}

/// The width over which [`settle`] reads the slope, in standard deviations
/// of the fit.
const SLOPE_READ_OVER_SD: f64 = 1e-3;

/// How far from a scalar fit's value, in its standard deviations, the
/// slope may put the minimum ([`settle`]).
const MAX_MINIMUM_AWAY_SD: f64 = 3.0;

/// The Newton steps [`settle`] takes towards a minimum the slope points to.
const NEWTON_STEPS: usize = 3;

impl Fitted {
    /// Whether, once this is named, `cause` is no longer a candidate: it is
    /// this cause or its companion, or another shape of the same effect
    /// ([`Cause::excludes`]).
    fn takes_the_place_of(&self, cause: Cause) -> bool {
        cause == self.cause
            || self.cause.excludes(cause)
            || self.companion.as_ref().is_some_and(|k| k.cause == cause)
    }

    /// Why its size does not clear the bars (at the edge of its search, too
    /// few standard deviations, below the practical size), if it does not.
    fn size_bar_missed(&self, acc: &Acceptance) -> Option<String> {
        (self.at_edge || self.z < acc.min_z || self.size < self.practical).then(|| {
            format!(
                "its size {:.3} ({:.1} standard deviations) is not determined",
                self.size, self.z
            )
        })
    }

    /// How many parameters the candidate fits, with its companion's.
    fn parameter_count(&self) -> usize {
        self.cause.parameter_count() + self.companion.as_ref().map_or(0, |c| c.parameter_count())
    }
}

impl Hypothesis {
    /// Already-accepted states, freed to be re-estimated jointly with a
    /// candidate.
    fn with_states_free(mut self) -> Self {
        if matches!(self.current, Term::Fixed(_)) {
            self.current = Term::Free;
        }
        // A step stays as fitted: freed, its track would lag it again.
        if matches!(self.loss, Term::Fixed(_)) && self.loss_from_s == 0.0 {
            self.loss = Term::Free;
        }
        self
    }

    /// Free states held at their estimates at the split.
    fn fix_states(&mut self, s: &AtSplit) {
        if self.current == Term::Free {
            self.current = Term::Fixed(s.current);
        }
        if self.loss == Term::Free && !self.loss_tracked {
            self.loss = Term::Fixed(s.loss);
        }
    }
}

/// Whether a fit stopped at its lower physical bound would fit the training
/// data better still below it (by `margin_nll`, a twentieth of the bounds'
/// width below): the data want an impossible value.
fn wants_below(v: f64, lo: f64, hi: f64, nll: &dyn Fn(f64) -> f64, margin_nll: f64) -> bool {
    near_edge(v, lo, hi) && v < 0.5 * (lo + hi) && nll(lo - 0.05 * (hi - lo)) < nll(lo) - margin_nll
}

/// True when `v` is within 2 % of the width of `[lo, hi]` from an end.
fn near_edge(v: f64, lo: f64, hi: f64) -> bool {
    let margin = 0.02 * (hi - lo);
    v <= lo + margin || v >= hi - margin
}

/// True when the offset `v`, searched in `[lo, hi]` (which holds 0, the
/// neutral offset, anywhere: the antenna's range about the profile's own
/// antenna), moved from 0 to within 2 % of the range's width of the end it
/// moved towards. A profile's antenna that is itself at the hull's edge
/// does not make an offset of about 0 an edge.
fn moved_to_edge(v: f64, lo: f64, hi: f64) -> bool {
    let margin = 0.02 * (hi - lo);
    (v <= lo + margin && v < -margin) || (v >= hi - margin && v > margin)
}

/// Fits `cause` on the training part on top of the `accepted` hypothesis,
/// as its declaration in the catalogue says.
fn fit(ctx: &Ctx<'_>, accepted: &Hypothesis, cause: Cause) -> Option<Fitted> {
    // States accepted earlier are free while the candidate is fitted, as
    // they will be.
    let train = accepted.with_states_free();
    match &cause.spec().search {
        Search::States(s) => fit_states(ctx, train, cause, s),
        Search::Scalar(s) => Some(fit_scalar(ctx, train, cause, s)),
        Search::Plane(s) => Some(fit_plane(ctx, train, cause, s)),
    }
}

/// A state cause fitted together with the cause that imitates its shared
/// part ([`SharedPart`]), where the state cause's own fit has such a part
/// of a practical size and the model does not yet hold that cause: the
/// companion fitted on top with the states free (a one-sided loss on a
/// less draggy hull wants a negative loss on the other side alone, and is
/// a loss on its side with the hull beside it). `None` where there is no
/// such part, or the companion leaves it.
fn fit_with_shared(ctx: &Ctx<'_>, accepted: &Hypothesis, alone: &Fitted) -> Option<Fitted> {
    let Search::States(search) = &alone.cause.spec().search else {
        return None;
    };
    let shared = search.shared.as_ref()?;
    let states = alone.states?;
    // A loss that starts late (a step, or tracked through the held-out
    // part) shares nothing with the hull, which was there from the start.
    if alone.hypothesis.loss_tracked || alone.hypothesis.loss_from_s > 0.0 {
        return None;
    }
    let practical = (search.report)(&states, &ctx.config.acceptance).practical;
    if (shared.size)(&states).abs() < practical || without(accepted, shared.cause) != *accepted {
        return None;
    }
    let placed = place_companion(ctx, accepted, search, shared, practical, None)?;
    let joint = placed.states;
    let hypothesis = placed.hypothesis;
    Some(Fitted {
        companion: Some(Box::new(placed.fitted(ctx, shared))),
        ..state_fitted(ctx, alone.cause, search, hypothesis, joint)
    })
}

/// A shared part's companion placed by [`place_companion`].
struct Placed {
    /// Its value and standard deviation, in the hypothesis' unit.
    value: f64,
    sd: f64,
    /// Whether it is at its training maximum (else moved along the ridge).
    at_maximum: bool,
    /// The hypothesis with the companion there and the states fixed.
    hypothesis: Hypothesis,
    /// The states there.
    states: AtSplit,
}

impl Placed {
    /// The companion as a candidate of its own (for its size bars and its
    /// finding).
    fn fitted(&self, ctx: &Ctx<'_>, shared: &SharedPart) -> Fitted {
        let Search::Scalar(scalar) = &shared.cause.spec().search else {
            unreachable!("a companion is a scalar cause (place_companion)");
        };
        let (lo, hi) = scalar.bounds;
        let size = (self.value - scalar.neutral).abs();
        Fitted {
            cause: shared.cause,
            hypothesis: self.hypothesis,
            parameters: vec![(
                scalar.parameter,
                (scalar.shown)(self.value),
                (scalar.shown)(self.sd),
            )],
            side: None,
            size,
            z: size / self.sd.max(1e-12),
            practical: (scalar.practical)(&ctx.config.acceptance),
            at_edge: near_edge(self.value, lo, hi),
            beyond_physics: None,
            states: None,
            companion: None,
            scalar_fit: None,
        }
    }
}

/// The companion of a state cause's shared part, fitted on `accepted` with
/// the states free: from `from` (its value and standard deviation where
/// it is named already), else from its training maximum; kept there where
/// that leaves the part below `practical`, else moved along the ridge to
/// the point that shares none ([`Ridge::where_none_is_shared`]). `None`
/// where the companion is not a scalar cause or the ridge has no such
/// point the data accept.
fn place_companion(
    ctx: &Ctx<'_>,
    accepted: &Hypothesis,
    search: &StateSearch,
    shared: &'static SharedPart,
    practical: f64,
    from: Option<(f64, f64)>,
) -> Option<Placed> {
    let Search::Scalar(scalar) = &shared.cause.spec().search else {
        return None;
    };
    let mut train = accepted.with_states_free();
    (search.free)(&mut train);
    let (v_ml, sd) = match from {
        Some(named) => named,
        None => {
            let ml = fit_scalar(ctx, train, shared.cause, scalar);
            (ml.parameters[0].1, ml.parameters[0].2)
        }
    };
    let (v_ml, sd) = (scalar_value(scalar, v_ml), scalar_value(scalar, sd));
    let ridge = Ridge {
        ctx,
        train,
        scalar,
        shared,
    };
    let (value, hypothesis, states) = ridge.at_or_off(v_ml, sd, practical)?;
    Some(Placed {
        value,
        sd,
        at_maximum: value == v_ml,
        hypothesis,
        states,
    })
}

/// A state cause's candidate: its hypothesis (the states fixed at
/// `states`) and its report from them.
fn state_fitted(
    ctx: &Ctx<'_>,
    cause: Cause,
    search: &StateSearch,
    hypothesis: Hypothesis,
    states: AtSplit,
) -> Fitted {
    let r = (search.report)(&states, &ctx.config.acceptance);
    Fitted {
        cause,
        hypothesis,
        parameters: r.parameters,
        side: r.side,
        size: r.size,
        z: r.z,
        practical: r.practical,
        at_edge: false,
        beyond_physics: (search.beyond)(&states),
        states: Some(states),
        companion: None,
        scalar_fit: None,
    }
}

/// A scalar cause's value in the hypothesis' unit from its shown one (the
/// model-parameter scales are shown as they are).
fn scalar_value(scalar: &ScalarSearch, shown: f64) -> f64 {
    debug_assert_eq!((scalar.shown)(1.0), 1.0, "a scale is shown as it is");
    shown
}

/// The ridge between a state cause's shared part and the cause that
/// imitates it: the training hypothesis (the states free) and the
/// companion's search.
struct Ridge<'c, 'a> {
    ctx: &'c Ctx<'a>,
    train: Hypothesis,
    scalar: &'static ScalarSearch,
    shared: &'static SharedPart,
}

impl Ridge<'_, '_> {
    /// The training pass with the companion at `v`.
    fn at(&self, v: f64) -> Option<(Hypothesis, PassOut)> {
        let h = with_scalar(self.train, self.scalar, v);
        let out = self.ctx.pass(&h, true);
        (!out.failed).then_some((h, out))
    }

    /// The companion at its maximum `v_ml` where that leaves the shared
    /// part below `practical`, else the point on the ridge that shares none
    /// ([`Self::where_none_is_shared`]): its value, the hypothesis with the
    /// states fixed there, and the states.
    fn at_or_off(&self, v_ml: f64, sd: f64, practical: f64) -> Option<(f64, Hypothesis, AtSplit)> {
        let (mut h, out) = self.at(v_ml)?;
        if (self.shared.size)(&out.at_split).abs() < practical {
            h.fix_states(&out.at_split);
            return Some((v_ml, h, out.at_split));
        }
        self.where_none_is_shared(v_ml, sd, &out)
    }

    /// Where the training likelihood along the companion's parameter is
    /// nearly flat (the shared part and the companion trading off), the
    /// point on it at which the states share nothing: bracketed from the
    /// maximum `v_ml` (standard deviation `sd`, pass `at_ml`) outwards,
    /// then bisected on the shared part's sign. Taken only where the
    /// training likelihood there is within `min_gain_nll` of the
    /// maximum's: the simpler split of the same motion, never one the data
    /// argue against.
    fn where_none_is_shared(
        &self,
        v_ml: f64,
        sd: f64,
        at_ml: &PassOut,
    ) -> Option<(f64, Hypothesis, AtSplit)> {
        let part = |out: &PassOut| (self.shared.size)(&out.at_split);
        let sign_ml = part(at_ml).signum();
        let (lo, hi) = self.scalar.bounds;
        let mut step = (4.0 * sd).max(0.02 * (hi - lo));
        let mut other = None;
        for _ in 0..4 {
            other = [v_ml + step, v_ml - step]
                .into_iter()
                .filter(|v| (lo..=hi).contains(v))
                .find(|v| {
                    self.at(*v)
                        .is_some_and(|(_, o)| part(&o).signum() != sign_ml)
                });
            if other.is_some() {
                break;
            }
            step *= 2.0;
        }
        let (mut a, mut b) = (v_ml, other?);
        for _ in 0..10 {
            let m = 0.5 * (a + b);
            if part(&self.at(m)?.1).signum() == sign_ml {
                a = m;
            } else {
                b = m;
            }
        }
        let v = 0.5 * (a + b);
        let (mut h, out) = self.at(v)?;
        if out.nll_train > at_ml.nll_train + self.ctx.config.acceptance.min_gain_nll {
            return None;
        }
        h.fix_states(&out.at_split);
        Some((v, h, out.at_split))
    }
}

fn fit_states(
    ctx: &Ctx<'_>,
    mut train: Hypothesis,
    cause: Cause,
    search: &StateSearch,
) -> Option<Fitted> {
    (search.free)(&mut train);
    let out = ctx.pass(&train, true);
    if out.failed {
        return None;
    }
    let s = out.at_split;
    if let Some(late) = &search.late_rise
        && (late.starts_late)(&s)
    {
        return Some(late_step(ctx, train, cause, search, s));
    }
    train.fix_states(&s);
    Some(state_fitted(ctx, cause, search, train, s))
}

fn fit_scalar(ctx: &Ctx<'_>, train: Hypothesis, cause: Cause, search: &ScalarSearch) -> Fitted {
    let f = |v: f64| ctx.train_nll(&with_scalar(train, search, v));
    let (lo, hi) = search.bounds;
    let (v, sd) = minimise_1d(&f, lo, hi, search.grid);
    scalar_fitted(ctx, train, cause, search, v, sd)
}

/// `train` with the scalar cause of `search` at `v`.
fn with_scalar(train: Hypothesis, search: &ScalarSearch, v: f64) -> Hypothesis {
    let mut h = train;
    (search.set)(&mut h, v);
    h
}

/// A scalar cause fitted on `train` at `v` with standard deviation `sd`, as
/// a candidate: the states of its training pass fixed, and its bars.
fn scalar_fitted(
    ctx: &Ctx<'_>,
    train: Hypothesis,
    cause: Cause,
    search: &ScalarSearch,
    v: f64,
    sd: f64,
) -> Fitted {
    let f = |v: f64| ctx.train_nll(&with_scalar(train, search, v));
    let (lo, hi) = search.bounds;
    let mut h = with_scalar(train, search, v);
    let out = ctx.pass(&h, true);
    h.fix_states(&out.at_split);
    let beyond_physics = search
        .below_means
        .filter(|_| wants_below(v, lo, hi, &f, ctx.config.acceptance.min_gain_nll));
    Fitted {
        cause,
        hypothesis: h,
        parameters: vec![(search.parameter, (search.shown)(v), (search.shown)(sd))],
        side: None,
        size: (v - search.neutral).abs(),
        z: (v - search.neutral).abs() / sd.max(1e-12),
        practical: (search.practical)(&ctx.config.acceptance),
        at_edge: near_edge(v, lo, hi),
        beyond_physics,
        states: Some(out.at_split),
        companion: None,
        scalar_fit: Some(ScalarFit {
            train,
            value: v,
            sd,
        }),
    }
}

fn fit_plane(ctx: &Ctx<'_>, train: Hypothesis, cause: Cause, search: &PlaneSearch) -> Fitted {
    let with = |x: f64, y: f64| {
        let mut h = train;
        h.effects.antenna_m = [x, y];
        h
    };
    let [(x_lo, x_hi), (y_lo, y_hi)] = (search.bounds_m)(&ctx.config.twin.kinetic.params);
    let y0 = train.effects.antenna_m[1].max(y_lo).min(y_hi);
    let (x, sx) = minimise_1d(&|v| ctx.train_nll(&with(v, y0)), x_lo, x_hi, search.grid);
    let (y, sy) = minimise_1d(&|v| ctx.train_nll(&with(x, v)), y_lo, y_hi, search.grid);
    let mut h = with(x, y);
    let out = ctx.pass(&h, true);
    h.fix_states(&out.at_split);
    let size = x.hypot(y);
    let on_edge = moved_to_edge(x, x_lo, x_hi) || moved_to_edge(y, y_lo, y_hi);
    let sd = if size > 1e-9 {
        ((x * sx).powi(2) + (y * sy).powi(2)).sqrt() / size
    } else {
        sx.max(sy)
    };
    Fitted {
        cause,
        hypothesis: h,
        parameters: vec![(search.parameters[0], x, sx), (search.parameters[1], y, sy)],
        side: None,
        size,
        z: size / sd.max(1e-12),
        practical: (search.practical)(&ctx.config.acceptance),
        at_edge: on_edge,
        beyond_physics: on_edge.then_some(OUTSIDE_HULL),
        states: Some(out.at_split),
        companion: None,
        scalar_fit: None,
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

/// Each remaining candidate fitted and run over the held-out part, in the
/// candidates' order (whatever the threads did).
fn score_round(
    ctx: &Ctx<'_>,
    accepted: &Hypothesis,
    remaining: &[Cause],
) -> Vec<(Fitted, PassOut)> {
    let try_one = |cause: Cause| -> Vec<(Fitted, PassOut)> {
        let Some(f) = fit(ctx, accepted, cause) else {
            return Vec::new();
        };
        let joint = fit_with_shared(ctx, accepted, &f);
        [Some(f), joint]
            .into_iter()
            .flatten()
            .filter_map(|f| {
                let out = ctx.pass(&f.hypothesis, false);
                (!out.failed).then_some((f, out))
            })
            .collect()
    };
    let threads = ctx.config.threads.clamp(1, remaining.len().max(1));
    if threads == 1 {
        return remaining.iter().flat_map(|c| try_one(*c)).collect();
    }
    let next = std::sync::atomic::AtomicUsize::new(0);
    let results = std::sync::Mutex::new(Vec::new());
    std::thread::scope(|s| {
        for _ in 0..threads {
            s.spawn(|| {
                loop {
                    let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    let Some(cause) = remaining.get(i) else { break };
                    let r = try_one(*cause);
                    if let Ok(mut v) = results.lock() {
                        v.extend(r.into_iter().map(|r| (i, r)));
                    }
                }
            });
        }
    });
    let mut v = results.into_inner().unwrap_or_default();
    // Stable: a cause's own fit stays before its joint one.
    v.sort_by_key(|(i, _)| *i);
    v.into_iter().map(|(_, r)| r).collect()
}

/// Which bar a fitted candidate with held-out gain `gain_nll` misses, if
/// any, in the order they are checked.
fn missed_bar(
    f: &Fitted,
    gain_nll: f64,
    forecast_m: Forecasts,
    acc: &Acceptance,
) -> Option<String> {
    let companion_misses = f.companion.as_ref().and_then(|c| {
        let missed = c
            .beyond_physics
            .map(str::to_string)
            .or_else(|| c.size_bar_missed(acc));
        missed.map(|m| format!("{} {m}", c.cause.name()))
    });
    let judged_on_forecast = f.cause.spec().must_improve_forecast
        || f.companion
            .as_ref()
            .is_some_and(|c| c.cause.spec().must_improve_forecast);
    if let Some(why) = f.beyond_physics {
        Some(why.to_string())
    } else if let Some(why) = companion_misses {
        Some(why)
    } else if let Some(worse) = forecast_m.worse()
        && judged_on_forecast
    {
        Some(format!(
            "{worse}, which a change of the vessel's dynamics would improve: it absorbs a force the catalogue has no cause for"
        ))
    } else if gain_nll < acc.min_gain_nll {
        Some(format!(
            "held-out log-likelihood gain {gain_nll:.1} < {}",
            acc.min_gain_nll
        ))
    } else if f.z < acc.min_z {
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
        Some(
            "the fit ran to the edge of its search range: not determined (it imitates another cause)"
                .to_string(),
        )
    } else {
        None
    }
}

/// The held-out position forecast errors per horizon, without and with a
/// candidate: `(horizon s, m)` each.
#[derive(Clone, Copy)]
struct Forecasts<'a> {
    before_m: &'a [(f64, f64)],
    after_m: &'a [(f64, f64)],
}

impl Forecasts<'_> {
    /// The geometric mean over the horizons of the errors' ratio, with
    /// over without (below 1: the candidate forecasts better); `None`
    /// where no forecast was scored or one is not finite (a held-out part
    /// too short for the horizon): the forecast then judges nothing.
    fn mean_ratio(&self) -> Option<f64> {
        let ratios: Vec<f64> = self
            .before_m
            .iter()
            .zip(self.after_m)
            .map(|((_, before), (_, after))| after / before)
            .collect();
        let log_mean = ratios.iter().map(|r| r.ln()).sum::<f64>() / ratios.len() as f64;
        (!ratios.is_empty() && log_mean.is_finite()).then(|| log_mean.exp())
    }

    /// Whether the candidate forecasts worse over the horizons taken
    /// together, and how: one horizon alone is not the judge (at 30 s a
    /// forecast's error is mostly its heading's, and a truer hull that
    /// halves the 5 s error can lose a few metres there).
    fn worse(&self) -> Option<String> {
        let ratio = self.mean_ratio()?;
        (ratio >= 1.0).then(|| {
            let horizons: Vec<String> = self
                .before_m
                .iter()
                .zip(self.after_m)
                .map(|((h, before), (_, after))| format!("{h:.0} s {before:.1} m -> {after:.1} m"))
                .collect();
            format!(
                "it makes the held-out forecasts worse ({}; errors x{ratio:.2} on the geometric mean)",
                horizons.join(", ")
            )
        })
    }
}

/// A round's outcome: the candidate taken, if any, and the others with why.
struct Round {
    took: Option<(Fitted, PassOut, f64)>,
    rejected: Vec<Rejected>,
}

/// A greedy round: the `remaining` causes fitted on top of `accepted`,
/// and the one taken ([`choose`]) against the model so far (`current`).
fn next_round(
    ctx: &Ctx<'_>,
    accepted: &Hypothesis,
    remaining: &[Cause],
    current: &PassOut,
) -> Round {
    choose(
        score_round(ctx, accepted, remaining),
        current,
        &ctx.config.acceptance,
        &|f| settle(ctx, f),
    )
}

/// Takes, of the scored candidates that clear every bar, the one with the
/// largest held-out gain, unless another explains the data as well (a gain
/// within `min_gain_nll` of it) with fewer parameters, or with as many and
/// no claim that a sensor is wrong (`CauseSpec::sensor_error`): the simpler
/// explanation is named. A candidate about to be taken is first settled
/// (`settle`: the training likelihood's slope at its fit, which costs
/// passes, so only of the one about to be taken, once): where its fit is
/// not at a minimum, it is moved to the one the slope points to and judged
/// again, or, where there is none, that is the bar it misses; and the
/// choice is made again. The others are rejected with the bar they missed.
fn choose(
    mut scored: Vec<(Fitted, PassOut)>,
    current: &PassOut,
    acc: &Acceptance,
    settle: &dyn Fn(&Fitted) -> Settled,
) -> Round {
    let current_nll_test = current.nll_test;
    let before_m = current.rmse();
    scored.sort_by(|a, b| {
        (current_nll_test - b.1.nll_test).total_cmp(&(current_nll_test - a.1.nll_test))
    });
    let judge = |f: &Fitted, out: &PassOut| {
        let gain = current_nll_test - out.nll_test;
        let after_m = out.rmse();
        let forecast_m = Forecasts {
            before_m: &before_m,
            after_m: &after_m,
        };
        (gain, missed_bar(f, gain, forecast_m, acc))
    };
    let mut judged: Vec<(f64, Option<String>)> =
        scored.iter().map(|(f, out)| judge(f, out)).collect();
    let mut settled = vec![false; scored.len()];
    let taken = loop {
        let clearing: Vec<usize> = (0..scored.len())
            .filter(|i| judged[*i].1.is_none())
            .collect();
        // The largest gain (the first of equal ones).
        let Some(best) = clearing
            .iter()
            .copied()
            .max_by(|a, b| judged[*a].0.total_cmp(&judged[*b].0).then(b.cmp(a)))
        else {
            break None;
        };
        let pick = clearing
            .iter()
            .copied()
            .filter(|i| judged[*i].0 >= judged[best].0 - acc.min_gain_nll)
            .min_by_key(|i| {
                let f = &scored[*i].0;
                (f.parameter_count(), f.cause.spec().sensor_error, *i)
            })
            .unwrap_or(best);
        if std::mem::replace(&mut settled[pick], true) {
            break Some(pick);
        }
        match settle(&scored[pick].0) {
            Settled::AtMinimum => break Some(pick),
            Settled::NotSmooth(why) => judged[pick].1 = Some(why),
            Settled::Moved(moved) => {
                let (f, out) = *moved;
                judged[pick] = judge(&f, &out);
                scored[pick] = (f, out);
            }
        }
    };
    let taken_by = taken.map(|i| {
        let f = &scored[i].0;
        (f.cause.name(), judged[i].0, f.parameter_count())
    });
    let mut round = Round {
        took: None,
        rejected: Vec::new(),
    };
    for (i, ((f, out), (gain, reason))) in scored.into_iter().zip(judged).enumerate() {
        if Some(i) == taken {
            round.took = Some((f, out, gain));
            continue;
        }
        let joint = f
            .companion
            .as_ref()
            .map(|c| format!("with {} for the part both share: ", c.cause.name()));
        let reason = reason.unwrap_or_else(|| match taken_by {
            Some((name, taken_gain, taken_count)) if gain > taken_gain => format!(
                "{name} explains the data as well (a held-out gain within {}) {}",
                acc.min_gain_nll,
                if taken_count < f.parameter_count() {
                    "with fewer parameters"
                } else {
                    "without a sensor being wrong"
                }
            ),
            _ => "a larger gain was taken this round".to_string(),
        });
        round.rejected.push(Rejected {
            cause: f.cause,
            parameters: f.parameters.clone(),
            heldout_nll_gain: gain,
            reason: joint.map_or(reason.clone(), |j| j + &reason),
        });
    }
    round
}

/// The finding of a taken candidate, judged against the model before it.
fn finding(f: &Fitted, out: &PassOut, gain: f64, before_out: &PassOut) -> Finding {
    let before = summarise(&before_out.records);
    let after = summarise(&out.records);
    Finding {
        cause: f.cause,
        parameters: f.parameters.clone(),
        side: f.side,
        evidence: evidence(&before, &after),
        gain: gain_of(gain, before_out, &before, out, &after),
    }
}

/// The findings of a taken candidate: its own, and its companion's where
/// it has one.
fn findings_of(
    f: &Fitted,
    out: &PassOut,
    gain: f64,
    before_out: &PassOut,
) -> (Finding, Option<Finding>) {
    let companion = f.companion.as_ref().map(|c| {
        let mut found = finding(c, out, gain, before_out);
        found.evidence.insert(
            0,
            format!(
                "fitted with the {} for the part both propellers would otherwise share",
                f.cause.name()
            ),
        );
        found
    });
    (finding(f, out, gain, before_out), companion)
}

/// The gain of going from `before_out` (residuals `before`) to `out`
/// (residuals `after`), `gain` in held-out log-likelihood.
fn gain_of(
    gain: f64,
    before_out: &PassOut,
    before: &ResidualSummary,
    out: &PassOut,
    after: &ResidualSummary,
) -> Gain {
    Gain {
        heldout_nll_gain: gain,
        heldout_steps: out.steps_test,
        nis_per_dof_before: before.nis_per_dof,
        nis_per_dof_after: after.nis_per_dof,
        prediction_rmse_before_m: before_out.rmse(),
        prediction_rmse_after_m: out.rmse(),
    }
}

/// Each finding's gain judged against the final model without it (the
/// other findings in): what the report says each buys.
fn judge_each_against_the_rest(ctx: &Ctx<'_>, model: &Accepted, findings: &mut [Finding]) {
    let after = summarise(&model.out.records);
    for f in findings {
        let out = ctx.pass(&without(&model.hypothesis, f.cause), false);
        if !out.failed {
            let before = summarise(&out.records);
            let gain = out.nll_test - model.out.nll_test;
            f.gain = gain_of(gain, &out, &before, &model.out, &after);
        }
    }
}

/// State causes accepted earlier were re-estimated jointly with the last
/// one: their reports take the joint values.
fn refresh_state_findings(earlier: &mut [Finding], states: &AtSplit, acc: &Acceptance) {
    for f in earlier {
        if let Search::States(s) = &f.cause.spec().search {
            let r = (s.report)(states, acc);
            f.parameters = r.parameters;
            f.side = r.side;
        }
    }
}

/// `h` without `cause`: its states off, its parameter at "no effect".
fn without(h: &Hypothesis, cause: Cause) -> Hypothesis {
    let mut h = *h;
    match &cause.spec().search {
        Search::States(s) => (s.off)(&mut h),
        Search::Scalar(s) => (s.set)(&mut h, s.neutral),
        Search::Plane(_) => h.effects.antenna_m = [0.0, 0.0],
    }
    h
}

/// The accepted model and its held-out pass.
struct Accepted {
    hypothesis: Hypothesis,
    out: PassOut,
}

/// A state cause accepted early is re-estimated with each later one; where
/// its final estimates (`states`) leave its physical bounds (two equal
/// losses once a sensor effect is taken out, say), it is dropped with the
/// reason.
fn drop_beyond_physics(
    ctx: &Ctx<'_>,
    model: &mut Accepted,
    findings: &mut Vec<Finding>,
    rejected: &mut Vec<Rejected>,
    states: &AtSplit,
) {
    let beyond = |c: Cause| match &c.spec().search {
        Search::States(s) => (s.beyond)(states),
        Search::Scalar(_) | Search::Plane(_) => None,
    };
    while let Some(i) = findings.iter().position(|f| beyond(f.cause).is_some()) {
        let without_it = without(&model.hypothesis, findings[i].cause);
        let out = ctx.pass(&without_it, false);
        if out.failed {
            return;
        }
        let f = findings.remove(i);
        rejected.push(Rejected {
            cause: f.cause,
            parameters: f.parameters,
            heldout_nll_gain: out.nll_test - model.out.nll_test,
            reason: beyond(f.cause).unwrap_or_default().to_string(),
        });
        model.hypothesis = without_it;
        model.out = out;
    }
}

/// After the greedy pass, each finding is judged again against the model
/// with all the others: the one that gains least, if below the bar, is
/// dropped (a later finding explains what it did), and the rest judged
/// again.
fn drop_redundant(
    ctx: &Ctx<'_>,
    model: &mut Accepted,
    findings: &mut Vec<Finding>,
    rejected: &mut Vec<Rejected>,
) {
    let acc = &ctx.config.acceptance;
    while findings.len() > 1 {
        let mut weakest: Option<(usize, f64, PassOut)> = None;
        for (i, f) in findings.iter().enumerate() {
            let out = ctx.pass(&without(&model.hypothesis, f.cause), false);
            let gain = out.nll_test - model.out.nll_test;
            if !out.failed && gain < acc.min_gain_nll && weakest.as_ref().is_none_or(|w| gain < w.1)
            {
                weakest = Some((i, gain, out));
            }
        }
        let Some((i, gain, out)) = weakest else {
            break;
        };
        let f = findings.remove(i);
        rejected.push(Rejected {
            cause: f.cause,
            parameters: f.parameters,
            heldout_nll_gain: gain,
            reason: format!(
                "with the other findings it gains {gain:.1} on held-out data (< {}): they explain what it did",
                acc.min_gain_nll
            ),
        });
        model.hypothesis = without(&model.hypothesis, f.cause);
        model.out = out;
    }
}

/// After the greedy pass, each finding is fitted again on the model with
/// all the others (one cause at a time, the others held: a joint refit by
/// coordinate descent), and each of the `candidates` not named is fitted
/// in its place.
/// Where another explains the held-out data better by `min_gain_nll`, or
/// as well with fewer parameters, without making the held-out forecast
/// worse, it takes the finding's place: the greedy order names first what
/// imitates several effects at once (a fore-aft lever arm for a latency on
/// a draggier hull), and only the others being in the model tell the two
/// apart. A finding whose refit no longer clears its bars is dropped with
/// the bar it missed. Returns whether the findings changed.
fn refit_jointly(
    ctx: &Ctx<'_>,
    candidates: &[Cause],
    model: &mut Accepted,
    findings: &mut Vec<Finding>,
    rejected: &mut Vec<Rejected>,
) -> bool {
    let acc = &ctx.config.acceptance;
    let mut changed = false;
    let mut i = 0;
    while i < findings.len() {
        let old = findings[i].cause;
        let base = without(&model.hypothesis, old);
        let base_out = ctx.pass(&base, false);
        if base_out.failed {
            i += 1;
            continue;
        }
        let mut tried: Vec<Cause> = candidates
            .iter()
            .copied()
            .filter(|c| {
                findings
                    .iter()
                    .enumerate()
                    .all(|(j, f)| f.cause != *c && (j == i || !c.excludes(f.cause)))
            })
            .collect();
        tried.push(old);
        let (own, others): (Vec<_>, Vec<_>) = score_round(ctx, &base, &tried)
            .into_iter()
            .partition(|(f, _)| f.cause == old);
        let smooth = |f: &Fitted| settle(ctx, f);
        let replacement = choose(others, &base_out, acc, &smooth)
            .took
            .filter(|(f, out, _)| replaces(f, out, old, &model.out, acc));
        let own = choose(own, &base_out, acc, &smooth);
        let (f, out, gain) = match (replacement, own.took) {
            (Some(r), _) => {
                rejected.push(Rejected {
                    cause: old,
                    parameters: findings[i].parameters.clone(),
                    heldout_nll_gain: base_out.nll_test - model.out.nll_test,
                    reason: format!(
                        "with the other findings, {} explains what it did (held-out log-likelihood {:+.1} over it{})",
                        r.0.cause.name(),
                        model.out.nll_test - r.1.nll_test,
                        if r.0.cause.parameter_count() < old.parameter_count() {
                            ", with fewer parameters"
                        } else {
                            ""
                        }
                    ),
                });
                changed = true;
                r
            }
            (None, Some(refit)) => refit,
            (None, None) => {
                let f = findings.remove(i);
                let missed = own.rejected.into_iter().next();
                rejected.push(Rejected {
                    cause: f.cause,
                    parameters: missed
                        .as_ref()
                        .map_or(f.parameters, |m| m.parameters.clone()),
                    heldout_nll_gain: base_out.nll_test - model.out.nll_test,
                    reason: format!(
                        "refitted with the other findings, {}",
                        missed.map_or_else(|| "it failed".to_string(), |m| m.reason)
                    ),
                });
                model.hypothesis = base;
                model.out = base_out;
                changed = true;
                continue;
            }
        };
        let (own, companion) = findings_of(&f, &out, gain, &base_out);
        findings[i] = own;
        if let Some(states) = &f.states {
            for (j, other) in findings.iter_mut().enumerate() {
                if j != i {
                    refresh_state_findings(std::slice::from_mut(other), states, acc);
                }
            }
        }
        if let Some(companion) = companion
            && findings.iter().all(|g| g.cause != companion.cause)
        {
            findings.push(companion);
            changed = true;
        }
        model.hypothesis = f.hypothesis;
        model.out = out;
        i += 1;
    }
    changed
}

/// At most this many sweeps of [`refit_jointly`]: each one after the first
/// follows a change of the findings in the sweep before, and refits the
/// findings' sizes only.
const MAX_REFIT_SWEEPS: usize = 3;

/// How much worse (on the geometric mean over the horizons) the forecasts
/// of one explanation of the data may be than another's and still count
/// as holding: two explanations of the same motion forecast alike up to
/// noise, and a few tenths of a percent must not decide between them.
const FORECAST_TOLERANCE: f64 = 1.05;

/// Whether the held-out forecasts of `out` hold against those of
/// `model_out` (within [`FORECAST_TOLERANCE`]).
fn forecast_holds(model_out: &PassOut, out: &PassOut) -> bool {
    Forecasts {
        before_m: &model_out.rmse(),
        after_m: &out.rmse(),
    }
    .mean_ratio()
    .is_none_or(|ratio| ratio <= FORECAST_TOLERANCE)
}

/// Whether candidate `f` (held-out pass `out`), fitted without the finding
/// of cause `old`, should take its place in the model whose held-out pass
/// is `model_out`: it explains the held-out data better by `min_gain_nll`,
/// or as well with fewer parameters, and it does not make the held-out
/// forecast worse (one cause standing in for two, a propeller loss for a
/// heading offset on a draggier hull, fits the innovations and loses the
/// track).
fn replaces(f: &Fitted, out: &PassOut, old: Cause, model_out: &PassOut, acc: &Acceptance) -> bool {
    let better = out.nll_test < model_out.nll_test - acc.min_gain_nll;
    let as_well_simpler = out.nll_test < model_out.nll_test + acc.min_gain_nll
        && f.cause.parameter_count() < old.parameter_count();
    let forecast_holds = forecast_holds(model_out, out);
    (better || as_well_simpler) && forecast_holds
}

/// A state finding's shared part ([`SharedPart`], declared in the
/// catalogue) named as the cause that moves the vessel alike. Where that
/// cause is not yet named, it is fitted on top of the model with the
/// finding's states free, and taken where it clears its own size bars and
/// neither the held-out likelihood nor the forecast gets worse (the
/// likelihood-gain bar is not asked of it: both explain the same steady
/// motion, the held-out data cannot prefer one by much, and what tells
/// them apart, the hull's time constant, is read by the fit on the
/// training part). Where it is named already, or its fit still leaves a
/// shared part, it moves along the ridge to the point that shares none
/// ([`Ridge::where_none_is_shared`]), if the held-out likelihood there is within
/// `min_gain_nll` and the forecast holds.
fn name_shared_parts(ctx: &Ctx<'_>, model: &mut Accepted, findings: &mut Vec<Finding>) {
    let acc = &ctx.config.acceptance;
    for i in 0..findings.len() {
        let Search::States(search) = &findings[i].cause.spec().search else {
            continue;
        };
        let Some(shared) = &search.shared else {
            continue;
        };
        let states = model.out.at_split;
        let before = (shared.size)(&states);
        let practical = (search.report)(&states, acc).practical;
        let named = findings.iter().position(|f| f.cause == shared.cause);
        if before.abs() < practical
            || (named.is_none() && findings.len() >= ctx.config.max_findings)
        {
            continue;
        }
        let from = named.map(|j| (findings[j].parameters[0].1, findings[j].parameters[0].2));
        let Some(placed) = place_companion(ctx, &model.hypothesis, search, shared, practical, from)
        else {
            continue;
        };
        let out = ctx.pass(&placed.hypothesis, false);
        let allowed_nll = if named.is_some() {
            acc.min_gain_nll
        } else {
            0.0
        };
        let companion = placed.fitted(ctx, shared);
        if out.failed
            || out.nll_test > model.out.nll_test + allowed_nll
            || !forecast_holds(&model.out, &out)
            || companion.size_bar_missed(acc).is_some()
        {
            continue;
        }
        let line = shared_part_line(shared, before, &placed.states, placed.at_maximum, acc);
        match named {
            Some(j) => {
                findings[j].parameters = companion.parameters;
                findings[j].evidence.insert(0, line);
            }
            None => {
                let mut found = finding(
                    &companion,
                    &out,
                    model.out.nll_test - out.nll_test,
                    &model.out,
                );
                found.evidence = vec![line];
                findings.push(found);
            }
        }
        refresh_state_findings(findings, &placed.states, acc);
        model.hypothesis = placed.hypothesis;
        model.out = out;
    }
}

/// The evidence line of a shared part taken from `before` to what is left
/// in `after_states`, at the companion's maximum or moved along the ridge.
fn shared_part_line(
    shared: &SharedPart,
    before: f64,
    after_states: &AtSplit,
    at_maximum: bool,
    acc: &Acceptance,
) -> String {
    let after = (shared.size)(after_states);
    let after = if after.abs() < 5e-4 { 0.0 } else { after };
    if at_maximum {
        format!(
            "takes {} ({before:.3} -> {after:.3}): the same steady motion, told apart by the hull's time constant",
            shared.what
        )
    } else {
        format!(
            "takes {} ({before:.3} -> {after:.3}): the same steady motion, which the data do not tell apart \
             (training log-likelihood within {} of the best split); the split that leaves a loss on one propeller is named",
            shared.what, acc.min_gain_nll
        )
    }
}

/// The causes whose sizes are fitted again under the process noise the
/// data ask for: the dynamics that set how fast the velocities decay, and
/// the rate sensor's scale, whose innovation covariance shrinks with it.
/// Not the surge damping: it shares a ridge with the losses' common part,
/// and a refit moves both along it.
const REFINED_SIZES: [Cause; 3] = [Cause::YawDamping, Cause::Mass, Cause::YawRateScale];
/// A refined size is searched within this factor of its selected size,
/// either way.
const REFINE_SPAN: f64 = 1.3;
/// At most this many rounds of the refinement ...
const REFINE_ROUNDS: usize = 3;
/// ... which stops once no size moved by more than this in a round.
const REFINE_SETTLED: f64 = 0.005;

/// A finding refitted by [`refine_sizes_under_fitted_noise`]: its cause's search,
/// the size it was selected with, and its refitted size and standard
/// deviation.
struct Refitted {
    cause: Cause,
    search: &'static ScalarSearch,
    selected: f64,
    size: f64,
    sd: f64,
}

/// Fits the sizes of the yaw damping, mass and yaw-rate scale findings
/// again under the velocity process noise whose level, per axis, the
/// training likelihood prefers with every finding in the model
/// ([`super::noise_level`]); the model takes the refined sizes, and a
/// finding whose refined size falls below its practical bar is dropped with
/// the reason. The fixed search noise biases those sizes: a
/// faster-contracting model, or a rate sensor read as measuring less of the
/// yaw rate, shrinks the innovation covariances, which the likelihood
/// rewards where the noise is larger than the data's.
fn refine_sizes_under_fitted_noise(
    ctx: &Ctx<'_>,
    model: &mut Accepted,
    findings: &mut Vec<Finding>,
    rejected: &mut Vec<Rejected>,
) {
    let mut refitted: Vec<Refitted> = findings
        .iter()
        .filter(|f| REFINED_SIZES.contains(&f.cause))
        .filter_map(|f| {
            let Search::Scalar(search) = &f.cause.spec().search else {
                return None;
            };
            let (_, selected, _) = f.parameters.iter().find(|p| p.0 == search.parameter)?;
            let selected = scalar_value(search, *selected);
            Some(Refitted {
                cause: f.cause,
                search,
                selected,
                size: selected,
                sd: f64::NAN,
            })
        })
        .collect();
    if refitted.is_empty() {
        return;
    }
    let training_nll =
        |config: &DiagnoseConfig, hyp: &Hypothesis| ctx.with_config(config).train_nll(hyp);
    // Coordinate ascent on the joint likelihood: the levels with the
    // sizes held, then the sizes with the levels held, until the sizes
    // settle.
    let mut hyp = model.hypothesis;
    let mut levels = [0.0; 3];
    for round in 0..REFINE_ROUNDS {
        let at_sizes = hyp;
        levels = noise_level::fitted_velocity_noise_levels(
            ctx.config,
            ctx.base,
            levels,
            round > 0,
            &|c| training_nll(c, &at_sizes),
            ctx.config.threads,
        );
        let at_levels = noise_level::with_velocity_noise_levels(ctx.config, ctx.base, levels);
        let mut moved: f64 = 0.0;
        for r in &mut refitted {
            let nll = |v: f64| training_nll(&at_levels, &with_scalar(hyp, r.search, v));
            let (lo, hi) = r.search.bounds;
            let (size, sd) = minimise_1d(
                &nll,
                (r.selected / REFINE_SPAN).max(lo),
                (r.selected * REFINE_SPAN).min(hi),
                r.search.grid,
            );
            (r.search.set)(&mut hyp, size);
            moved = moved.max((size - r.size).abs());
            (r.size, r.sd) = (size, sd);
        }
        if moved < REFINE_SETTLED {
            break;
        }
    }
    let out = ctx.pass(&hyp, false);
    if out.failed {
        return;
    }
    model.hypothesis = hyp;
    model.out = out;
    take_refined_sizes(
        refitted,
        &ctx.config.acceptance,
        &mut model.hypothesis,
        findings,
        rejected,
    );
    if model.hypothesis != hyp {
        let out = ctx.pass(&model.hypothesis, false);
        if !out.failed {
            model.out = out;
        }
    }
}

/// The refined sizes put in their findings (value and standard deviation);
/// a finding whose refined size is within its cause's practical size
/// (`acc`) of 1 is dropped from the findings and from `hypothesis`, with
/// the reason.
fn take_refined_sizes(
    refitted: Vec<Refitted>,
    acc: &Acceptance,
    hypothesis: &mut Hypothesis,
    findings: &mut Vec<Finding>,
    rejected: &mut Vec<Rejected>,
) {
    for r in refitted {
        let practical = (r.search.practical)(acc);
        let Some(k) = findings.iter().position(|f| f.cause == r.cause) else {
            continue;
        };
        for p in &mut findings[k].parameters {
            if p.0 == r.search.parameter {
                (p.1, p.2) = (r.size, r.sd);
            }
        }
        if (r.size - 1.0).abs() < practical {
            let f = findings.remove(k);
            *hypothesis = without(hypothesis, r.cause);
            rejected.push(Rejected {
                cause: r.cause,
                parameters: f.parameters,
                heldout_nll_gain: f.gain.heldout_nll_gain,
                reason: format!(
                    "fitted under the process noise the data ask for, its scale {:.3} is within {practical} of 1",
                    r.size
                ),
            });
        }
    }
}

/// The named side's loss fitted as a step (none before its onset, its size
/// after, the other side's loss held) by the training likelihood of `ctx`:
/// the size within its range with the onset at `onset_s`, then the onset
/// within its range, then the size again. Returns the size, its standard
/// deviation, the onset, and the hypothesis with the step.
fn fit_loss_step(
    ctx: &Ctx<'_>,
    base: &Hypothesis,
    losses: [f64; 2],
    side: usize,
    onset_s: f64,
    (size_range, onset_range_s): ((f64, f64), (f64, f64)),
) -> (f64, f64, f64, Hypothesis) {
    let with = |v: f64, from_s: f64| {
        let mut h = *base;
        let mut l = losses;
        l[side] = v;
        h.loss = Term::Fixed(l);
        h.loss_from_s = from_s;
        h
    };
    let size_at = |from_s: f64| {
        minimise_1d(
            &|v| ctx.train_nll(&with(v, from_s)),
            size_range.0,
            size_range.1,
            6,
        )
    };
    let (size, _) = size_at(onset_s);
    let (onset_s, _) = minimise_1d_golden(
        &|t| ctx.train_nll(&with(size, t)),
        onset_range_s.0,
        onset_range_s.1,
        10,
    );
    let (size, sd) = size_at(onset_s);
    (size, sd, onset_s, with(size, onset_s))
}

/// A loss whose track rose after [`LATE_START_S`]: its estimates at the
/// split lag the start, so it is fitted as a step at its onset on the
/// training part ([`fit_loss_step`], [`step_ranges`]).
fn late_step(
    ctx: &Ctx<'_>,
    train: Hypothesis,
    cause: Cause,
    search: &StateSearch,
    mut states: AtSplit,
) -> Fitted {
    let side = larger_loss_side(&states);
    let onset_s = states.loss_onset_s[side];
    let split_s = ctx.split_s();
    let mut base = train;
    (search.off)(&mut base);
    let ranges = step_ranges(states.loss[side], onset_s, split_s - 1.0);
    let (size, sd, onset_s, stepped) =
        fit_loss_step(ctx, &base, states.loss, side, onset_s, ranges);
    states.loss[side] = size;
    states.loss_sigma[side] = sd;
    states.loss_onset_s[side] = onset_s;
    state_fitted(ctx, cause, search, stepped, states)
}

/// The ranges [`fit_loss_step`] searches for a loss the filter tracked to
/// `tracked` with its track's onset at `onset_s`: the size from 0.7 times
/// the tracked one (its estimate lags a step by its memory) to 0.95, the
/// onset from 40 s before the track's (which the same lag delays) to 10 s
/// after it, and not after `latest_s`.
fn step_ranges(tracked: f64, onset_s: f64, latest_s: f64) -> ((f64, f64), (f64, f64)) {
    (
        ((0.7 * tracked).max(0.0), 0.95),
        (
            (onset_s - 40.0).max(LATE_START_S / 2.0),
            (onset_s + 10.0).min(latest_s),
        ),
    )
}

/// Puts a step's fitted size and onset in a loss finding's parameters.
fn set_step(f: &mut Finding, side: usize, size: f64, sd: f64, onset_s: f64) {
    let side_name = if side == 0 {
        "loss_port"
    } else {
        "loss_starboard"
    };
    for p in &mut f.parameters {
        if p.0 == "loss" || p.0 == side_name {
            (p.1, p.2) = (size, sd);
        } else if p.0 == "onset_s" {
            p.1 = onset_s;
        }
    }
}

/// A propeller loss that starts in the held-out part. The training part has
/// none to fit, so no greedy round can name it; where the model names no
/// loss, the losses are tracked by the filter through the held-out part
/// too. Its one-step-ahead predictions stay causal, so the held-out
/// likelihood judges the tracked losses as it judges a fitted cause, with
/// the same bars. Named only where the tracked loss is nothing at the
/// split (below its practical size, or within its bar of standard
/// deviations) and clears the bars at the log's end, where its size is
/// the filter's estimate (lagging a step by the filter's memory) and its
/// onset is read off the track over the whole log, until
/// [`size_tracked_loss`] fits it as a step. Returns the named loss's onset
/// (for [`settled_records`]), where one is named and has one.
fn find_loss_after_training(
    ctx: &Ctx<'_>,
    model: &mut Accepted,
    findings: &mut Vec<Finding>,
) -> Option<f64> {
    let cause = Cause::ThrusterLoss;
    let Search::States(search) = &cause.spec().search else {
        return None;
    };
    if ctx.base != BaseModel::Kinetic || model.hypothesis.loss != Term::Off {
        return None;
    }
    let acc = &ctx.config.acceptance;
    let mut tracked = model.hypothesis;
    (search.free)(&mut tracked);
    if let Some(late) = &search.late_rise {
        (late.track)(&mut tracked);
    }
    let out = ctx.pass(&tracked, false);
    let at_split = out.at_split;
    let none_at_split = (0..2).all(|side| {
        at_split.loss[side] < acc.min_loss
            || at_split.loss[side] < acc.min_z * at_split.loss_sigma[side]
    });
    if out.failed || !none_at_split {
        return None;
    }
    // The states at the log's end, the onsets from the whole track.
    let whole_log = ctx.over_whole_log();
    let at_end = whole_log.pass(&tracked, true);
    if at_end.failed {
        return None;
    }
    let fitted = state_fitted(ctx, cause, search, tracked, at_end.at_split);
    let gain = model.out.nll_test - out.nll_test;
    let forecasts = Forecasts {
        before_m: &model.out.rmse(),
        after_m: &out.rmse(),
    };
    if missed_bar(&fitted, gain, forecasts, acc).is_some() {
        return None;
    }
    let mut found = finding(&fitted, &out, gain, &model.out);
    let onset_s = size_tracked_loss(ctx, search, &tracked, &at_end.at_split, &mut found);
    findings.push(found);
    model.hypothesis = tracked;
    model.out = out;
    onset_s
}

/// The report of a loss that starts in the held-out part, `found`, which
/// the model `tracked` tracks through it: from the whole log, its states at
/// the log's end (`at_end`), and where it is a step, its size and onset
/// fitted as one over the whole log ([`fit_loss_step`]); a report only,
/// its gain stays the tracked losses' own, judged on the held-out part.
/// Returns its onset, where it has one.
fn size_tracked_loss(
    ctx: &Ctx<'_>,
    search: &StateSearch,
    tracked: &Hypothesis,
    at_end: &AtSplit,
    found: &mut Finding,
) -> Option<f64> {
    let mut how = "its size the estimate at the log's end".to_string();
    // The larger loss names the side (as the report does): a step where
    // its track rose late.
    let side = larger_loss_side(at_end);
    let mut onset_s = Some(at_end.loss_onset_s[side]).filter(|t| t.is_finite());
    if let Some(track_onset_s) = onset_s.filter(|t| *t >= LATE_START_S) {
        let mut before = *tracked;
        (search.off)(&mut before);
        let end_s =
            ctx.prep.steps[ctx.prep.steps.len() - 1].fix.time_s - ctx.prep.steps[0].fix.time_s;
        let ranges = step_ranges(at_end.loss[side], track_onset_s, end_s - 1.0);
        let (size, sd, step_onset_s, _) = fit_loss_step(
            &ctx.over_whole_log(),
            &before,
            at_end.loss,
            side,
            track_onset_s,
            ranges,
        );
        set_step(found, side, size, sd, step_onset_s);
        onset_s = Some(step_onset_s);
        how = "its size and onset fitted as a step over the whole log".to_string();
    }
    found.evidence.insert(
        0,
        format!(
            "it starts late (the training part ends at {:.0} s): judged as the losses the filter tracks through the held-out part, {how}",
            ctx.split_s()
        ),
    );
    onset_s
}

/// The evidence lines the final model adds to its findings: a loss's
/// step, a drift's look-alike latency.
fn annotate(prep: &Prepared, model: &Accepted, findings: &mut [Finding]) {
    note_training_step(model, findings);
    note_latency_alike(prep, findings);
}

/// Says so where a named loss is a step fitted on the training part.
fn note_training_step(model: &Accepted, findings: &mut [Finding]) {
    if model.hypothesis.loss_tracked || model.hypothesis.loss_from_s <= 0.0 {
        return;
    }
    if let Some(f) = findings.iter_mut().find(|f| f.cause == Cause::ThrusterLoss) {
        f.evidence.insert(
            0,
            "it starts late: a step, its size and onset fitted as one on the training part"
                .to_string(),
        );
    }
}

/// Says, on a sideslip that drifts outward, which GNSS latency would bend
/// the course in the turns as much: at a steady speed `u` the course of a
/// hull drifting `v = k r` leaves its heading by `k r / u`, and a fix
/// `L` old lags it by `L r`, so the two are one where `L = -k / u`
/// (docs/model.md section 8). Positions, heading and a yaw rate tell them
/// apart where the speed changes (the [`Cause::Sideslip`]'s angle falls
/// with speed, a latency's does not) and hardly at all for the
/// [`Cause::SideslipWithSpeed`], whose angle does not either; propeller
/// speeds, whose model has the hull's sway, do.
fn note_latency_alike(prep: &Prepared, findings: &mut [Finding]) {
    for f in findings.iter_mut() {
        if !matches!(f.cause, Cause::Sideslip | Cause::SideslipWithSpeed) {
            continue;
        }
        let Some(&(_, lateral, _)) = f.parameters.first() else {
            continue;
        };
        let latency_s = -lateral / prep.under_way_speed_mps;
        let told_apart = if f.cause == Cause::Sideslip {
            "only where the speed changes"
        } else {
            "hardly at all (this drift's angle, as a latency's, does not change with the speed)"
        };
        if latency_s > 0.0 {
            f.evidence.push(format!(
                "at the log's speed under way ({:.2} m/s) a GNSS latency of {latency_s:.2} s bends the course as this drift does: without propeller data the two are told apart {told_apart}",
                prep.under_way_speed_mps
            ));
        }
    }
}

/// Fewest held-out records a verdict is judged on when a tracked loss's
/// settling is left out (30 s at 5 Hz); with fewer, all are.
const MIN_SETTLED_RECORDS: usize = 150;

/// The held-out records the verdict on the extended model is judged on:
/// all of them, except where the model tracks a loss that starts late
/// through the held-out part. Its estimate lags the step by the filter's
/// memory for losses, which biases the innovations that follow the onset;
/// that is the tracking's lag, not something the catalogue lacks, so the
/// verdict is judged from one memory after the onset on (where that
/// leaves enough records).
fn settled_records<'r>(
    ctx: &Ctx<'_>,
    tracked_onset_s: Option<f64>,
    records: &'r [InnovationRecord],
) -> &'r [InnovationRecord] {
    let Some(onset_s) = tracked_onset_s else {
        return records;
    };
    let filter = &ctx.config.twin.kinetic.filter;
    let memory_s = filter.forgetting_time_constant_s
        * filter.fault_memory_factor[crate::models::otter_twin::fault::PORT];
    let settled_s = ctx.prep.steps[0].fix.time_s + onset_s + memory_s;
    let from = records.partition_point(|r| r.time_s < settled_s);
    if records.len() - from >= MIN_SETTLED_RECORDS {
        &records[from..]
    } else {
        records
    }
}

/// Diagnoses a prepared log.
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
    let memo = PassMemo::default();
    let ctx = Ctx {
        prep,
        base,
        config,
        split,
        memo: Some(&memo),
    };
    let log = LogKind {
        base,
        has_position: prep.has_position,
        has_heading: prep.has_heading,
        has_stw: prep.has_stw,
        has_yaw_rate: prep.has_yaw_rate,
    };
    let acc = &config.acceptance;
    let mut accepted = Hypothesis::nominal();
    let nominal_out = ctx.pass(&accepted, false);
    let nominal = summarise(&nominal_out.records);
    let nominal_records = nominal_out.records.clone();
    let mut current_out = nominal_out;
    let mut findings: Vec<Finding> = Vec::new();
    let mut rejected = Vec::new();
    let mut remaining: Vec<Cause> = Cause::ALL.into_iter().filter(|c| c.applies(&log)).collect();
    let mut last_states: Option<AtSplit> = None;
    while findings.len() < config.max_findings && !remaining.is_empty() {
        let round = next_round(&ctx, &accepted, &remaining, &current_out);
        rejected = round.rejected;
        let Some((f, out, gain)) = round.took else {
            break;
        };
        // A cause that made the held-out fit clearly worse this round is not
        // tried again (it imitates nothing the data show).
        remaining.retain(|c| {
            !rejected
                .iter()
                .any(|r| r.cause == *c && r.heldout_nll_gain < -acc.min_gain_nll)
        });
        let earlier = findings.len();
        let (own, companion) = findings_of(&f, &out, gain, &current_out);
        // The companion first: the part it takes is the cause's baseline.
        findings.extend(companion);
        findings.push(own);
        if let Some(states) = &f.states {
            refresh_state_findings(&mut findings[..earlier], states, acc);
            last_states = Some(*states);
        }
        remaining.retain(|c| !f.takes_the_place_of(*c));
        accepted = f.hypothesis;
        current_out = out;
    }
    let mut model = Accepted {
        hypothesis: accepted,
        out: current_out,
    };
    if let Some(states) = &last_states {
        drop_beyond_physics(&ctx, &mut model, &mut findings, &mut rejected, states);
    }
    drop_redundant(&ctx, &mut model, &mut findings, &mut rejected);
    // Every applicable cause is a candidate in a finding's place, also one
    // that made the held-out fit worse in a greedy round: on top of other
    // findings it can be what the data show (the mass, once a current is
    // in, for a yaw damping that stood in for it).
    let applicable: Vec<Cause> = Cause::ALL.into_iter().filter(|c| c.applies(&log)).collect();
    // A finding dropped or replaced in a sweep changes what the ones
    // refitted before it in that sweep were fitted beside (a surge damping
    // refitted beside a loss on both propellers that is then dropped as a
    // profile error): another sweep refits their sizes, until the findings
    // settle. Only the first tries every cause in a finding's place: the
    // later ones refit the findings themselves, at a fraction of its cost.
    let mut candidates: &[Cause] = &applicable;
    for _ in 0..MAX_REFIT_SWEEPS {
        if !refit_jointly(&ctx, candidates, &mut model, &mut findings, &mut rejected) {
            break;
        }
        drop_redundant(&ctx, &mut model, &mut findings, &mut rejected);
        candidates = &[];
    }
    refine_sizes_under_fitted_noise(&ctx, &mut model, &mut findings, &mut rejected);
    name_shared_parts(&ctx, &mut model, &mut findings);
    let tracked_onset_s = find_loss_after_training(&ctx, &mut model, &mut findings);
    annotate(prep, &model, &mut findings);
    judge_each_against_the_rest(&ctx, &model, &mut findings);
    // A cause rejected in one round, or tried alone and with a companion,
    // can be named in the end (in a finding's place, or as a companion):
    // the finding stands.
    rejected.retain(|r| findings.iter().all(|f| f.cause != r.cause));
    let current_out = model.out;
    let extended = summarise(&current_out.records);
    let settled = settled_records(&ctx, tracked_onset_s, &current_out.records);
    let unexplained = if settled.len() == current_out.records.len() {
        unexplained(&extended, acc)
    } else {
        unexplained(&summarise(settled), acc)
    };
    Diagnosis {
        unexplained,
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
    use crate::diagnose::prepare::{DiagEvent, prepare};
    use crate::geodesy::LatLon;
    use crate::sample::{GnssFix, PropellerSpeeds};

    /// A minute of a vessel circling at 1.5 m/s (fixes with course, speed
    /// and heading at 5 Hz, shaft speeds at 10 Hz, the port one faster).
    fn circling_log() -> Vec<DiagEvent> {
        let (radius_m, speed_mps) = (30.0, 1.5);
        let m_per_deg = 111_320.0;
        let mut events = Vec::new();
        for k in 0..600 {
            let time_s = 1.0e9 + 0.1 * k as f64;
            events.push(DiagEvent::Propellers(PropellerSpeeds {
                time_s,
                port_radps: 100.0,
                starboard_radps: 80.0,
            }));
            if k % 2 == 0 {
                let angle = speed_mps * 0.1 * k as f64 / radius_m;
                let (north_m, east_m) = (radius_m * angle.sin(), radius_m * (1.0 - angle.cos()));
                events.push(DiagEvent::Fix(GnssFix {
                    time_s,
                    position: LatLon {
                        lat_deg: 60.0 + north_m / m_per_deg,
                        lon_deg: 10.0 + east_m / (m_per_deg * 0.5),
                    },
                    sog_mps: Some(speed_mps),
                    cog_rad: Some(angle),
                    heading_rad: Some(angle),
                    yaw_rate_radps: None,
                    hdop: None,
                }));
            }
        }
        events
    }

    /// A refined size replaces the selected one in its finding; one that
    /// falls within the practical bar of 1 drops its finding, which leaves
    /// the model's hypothesis and is rejected with its refined size.
    #[test]
    fn a_refined_size_within_the_bar_drops_its_finding() {
        let finding = |cause: Cause, scale: f64| Finding {
            cause,
            parameters: vec![("scale", scale, 0.01)],
            side: None,
            evidence: Vec::new(),
            gain: Gain {
                heldout_nll_gain: 40.0,
                heldout_steps: 600,
                nis_per_dof_before: 1.2,
                nis_per_dof_after: 1.0,
                prediction_rmse_before_m: Vec::new(),
                prediction_rmse_after_m: Vec::new(),
            },
        };
        let refitted = |cause: Cause, selected: f64, size: f64| {
            let Search::Scalar(search) = &cause.spec().search else {
                panic!("a scalar cause");
            };
            assert_eq!(search.parameter, "scale");
            Refitted {
                cause,
                search,
                selected,
                size,
                sd: 0.02,
            }
        };
        let mut hypothesis = Hypothesis::nominal();
        hypothesis.profile_scales = [1.0, 1.28, 1.0, 1.12];
        hypothesis.effects.yaw_rate_scale = 0.96;
        let mut findings = vec![
            finding(Cause::YawDamping, 1.25),
            finding(Cause::Mass, 1.12),
            finding(Cause::YawRateScale, 0.95),
        ];
        let mut rejected = Vec::new();
        // Each against its own practical size: 0.1 of a profile's
        // parameter, 0.02 of a rate sensor's scale.
        take_refined_sizes(
            vec![
                refitted(Cause::YawDamping, 1.25, 1.28),
                refitted(Cause::Mass, 1.12, 1.06),
                refitted(Cause::YawRateScale, 0.95, 0.96),
            ],
            &Acceptance::default(),
            &mut hypothesis,
            &mut findings,
            &mut rejected,
        );
        assert_eq!(findings.len(), 2);
        assert_eq!(findings[0].cause, Cause::YawDamping);
        assert_eq!(findings[0].parameters, vec![("scale", 1.28, 0.02)]);
        assert_eq!(findings[1].cause, Cause::YawRateScale);
        assert_eq!(findings[1].parameters, vec![("scale", 0.96, 0.02)]);
        assert_eq!(hypothesis.effects.yaw_rate_scale, 0.96);
        assert_eq!(hypothesis.profile_scales, [1.0, 1.28, 1.0, 1.0]);
        assert_eq!(rejected.len(), 1);
        assert_eq!(rejected[0].cause, Cause::Mass);
        assert_eq!(rejected[0].parameters, vec![("scale", 1.06, 0.02)]);
        assert!(rejected[0].reason.contains("1.060 is within 0.1 of 1"));
    }

    /// A pass the memo serves is the pass that would have been run, in
    /// both kinds; a hypothesis that differs in one field is not served
    /// another's pass.
    #[test]
    fn the_pass_memo_serves_only_the_same_pass() {
        let prep = prepare(&circling_log()).expect("the log prepares");
        let config = DiagnoseConfig::default();
        let memo = PassMemo::default();
        let memoised = Ctx {
            prep: &prep,
            base: BaseModel::Kinetic,
            config: &config,
            split: prep.steps.len() * 6 / 10,
            memo: Some(&memo),
        };
        let run = Ctx {
            memo: None,
            ..memoised
        };
        let nominal = Hypothesis::nominal();
        let mut slower_turning = nominal;
        slower_turning.profile_scales[1] = 1.3;
        let mut late = nominal;
        late.effects.gnss_latency_s = 0.3;
        for train_only in [true, false] {
            for hyp in [nominal, slower_turning, late, nominal, late] {
                let served = memoised.pass(&hyp, train_only);
                let fresh = run.pass(&hyp, train_only);
                assert!(!fresh.failed);
                assert_eq!(format!("{served:?}"), format!("{fresh:?}"));
            }
            let kept = memo.table(train_only).lock().map_or(0, |t| t.len());
            assert_eq!(kept, 3, "each hypothesis run once");
        }
        let nll = |h: &Hypothesis| run.pass(h, true).nll_train;
        assert!(nll(&slower_turning) != nll(&nominal) && nll(&late) != nll(&nominal));
    }

    /// A latency is searched in [0, 2] s only; a fit stopped at zero is
    /// said to want a negative latency only when the data fit better below
    /// zero.
    #[test]
    fn a_fit_at_its_lower_bound_wants_below_only_when_the_data_do() {
        let (lo, hi) = (0.0, 2.0);
        let wants_negative = |v: f64| 1000.0 * (v + 0.15).powi(2);
        let at_zero = |v: f64| 1000.0 * v.powi(2);
        let (v, _) = minimise_1d(&wants_negative, lo, hi, 6);
        assert!(v < 0.05, "the search stops at the floor: {v}");
        assert!(wants_below(v, lo, hi, &wants_negative, 2.0));
        let (v, _) = minimise_1d(&at_zero, lo, hi, 6);
        assert!(!wants_below(v, lo, hi, &at_zero, 2.0));
        let inside = |v: f64| 1000.0 * (v - 0.4).powi(2);
        let (v, _) = minimise_1d(&inside, lo, hi, 6);
        assert!((v - 0.4).abs() < 0.02, "{v}");
        assert!(!wants_below(v, lo, hi, &inside, 2.0));
    }

    /// The minimiser finds an interior minimum of a parabola, and its
    /// standard deviation is the curvature's: `f = (x - m)^2 / (2 s^2)`
    /// gives `s`.
    #[test]
    fn the_minimiser_finds_the_minimum_and_its_curvature() {
        let (m, s) = (0.37, 0.05);
        let f = |x: f64| (x - m).powi(2) / (2.0 * s * s);
        let (x, sd) = minimise_1d(&f, -1.0, 1.0, 8);
        // A parabola's vertex, exactly, and its curvature.
        assert!((x - m).abs() < 1e-9, "{x}");
        assert!((sd - s).abs() < 1e-6 * s.max(1.0), "{sd}");
        // At the edge of the range, it stops there.
        let (x, _) = minimise_1d(&f, 0.5, 1.0, 6);
        assert!(near_edge(x, 0.5, 1.0), "{x}");
        // A flat function has no curvature: an infinite deviation.
        let (_, sd) = minimise_1d(&|_| 1.0, 0.0, 1.0, 4);
        assert!(sd.is_infinite());
    }

    /// On a likelihood steeper on one side of its minimum (as a hull's
    /// mass gives: `K (x/m - 1 - ln(x/m))`), the minimiser is found within
    /// the precision seven golden-section steps give (half their last
    /// bracket), wherever the minimum falls between the grid's points, in
    /// four evaluations beyond the grid.
    #[test]
    fn the_minimiser_finds_an_asymmetric_minimum_in_four_evaluations() {
        let (lo, hi, grid) = (0.4, 2.5, 8);
        let step = (hi - lo) / grid as f64;
        let golden_precision = 0.5 * 2.0 * step * 0.618f64.powi(7);
        for m in [0.55, 0.6625, 0.70, 0.73, 0.79, 1.37, 2.1] {
            let calls = std::cell::Cell::new(0);
            let f = |x: f64| {
                calls.set(calls.get() + 1);
                2000.0 * (x / m - 1.0 - (x / m).ln())
            };
            let (x, sd) = minimise_1d(&f, lo, hi, grid);
            assert!((x - m).abs() < golden_precision, "minimum {m}: {x}");
            assert!(
                calls.get() <= grid + 1 + 4,
                "minimum {m}: {} calls",
                calls.get()
            );
            // The curvature at the minimum is 2000 / m^2: a deviation of
            // m / 44.7, read within a grid step of it.
            let want = m / 2000f64.sqrt();
            assert!(
                (sd / want - 1.0).abs() < 0.5,
                "minimum {m}: sd {sd} for {want}"
            );
        }
    }

    /// A likelihood that jumps between close values of its parameter (as
    /// the filter's can on a real log) is not followed by parabolic steps:
    /// it is searched by golden section, as [`minimise_1d_golden`] does.
    #[test]
    fn a_likelihood_that_is_not_smooth_is_searched_by_golden_section() {
        let jagged = |x: f64| 1000.0 * (x - 0.7).powi(2) + 30.0 * (x * 97.0).sin();
        let (lo, hi, grid) = (0.0, 2.0, 6);
        let searched = minimise_1d(&jagged, lo, hi, grid);
        assert_eq!(searched, minimise_1d_golden(&jagged, lo, hi, grid));
        // A smooth one of the same shape takes the parabolic steps: not
        // the golden section's answer, and a better one.
        let smooth = |x: f64| 1000.0 * (x - 0.7).powi(2);
        let (x, _) = minimise_1d(&smooth, lo, hi, grid);
        let (x_golden, _) = minimise_1d_golden(&smooth, lo, hi, grid);
        assert!((x - 0.7).abs() < (x_golden - 0.7).abs(), "{x} {x_golden}");
    }

    /// A lever arm's range is the hull about the profile's antenna, so 0
    /// can lie near one end; the fit is at an edge only where it moved there.
    #[test]
    fn an_offset_is_at_the_edge_only_where_it_moved_to_it() {
        // A profile's antenna 0.53 m to starboard on a 1.08 m beam: the
        // offsets that keep it on the hull are (-1.07, 0.01).
        let (lo, hi) = (-1.07, 0.01);
        assert!(!moved_to_edge(0.0, lo, hi), "no offset is no edge");
        assert!(!moved_to_edge(0.005, lo, hi));
        assert!(!moved_to_edge(-0.5, lo, hi));
        assert!(moved_to_edge(-1.06, lo, hi), "to port's edge");
        // On a range symmetric about 0, the ends are the edges.
        assert!(moved_to_edge(0.99, -1.0, 1.0) && moved_to_edge(-0.99, -1.0, 1.0));
        assert!(!moved_to_edge(0.9, -1.0, 1.0));
    }

    /// Where the likelihood jumps within the golden section's bracket (as
    /// the latency's does on a log with standstills), the search's point
    /// can be worse than the best grid point; the grid point then stands.
    #[test]
    fn a_search_never_ends_worse_than_its_best_grid_point() {
        // Lowest at the range's edge, every other point worse, with jumps of
        // hundreds between values 0.005 apart.
        let jagged = |x: f64| {
            if x == 0.0 {
                0.0
            } else {
                20.0 * x.abs() + 400.0 * (x * 700.0).sin().powi(2)
            }
        };
        assert_eq!(minimise_1d(&jagged, 0.0, 2.0, 6).0, 0.0);
        assert_eq!(minimise_1d_golden(&jagged, 0.0, 2.0, 6).0, 0.0);
    }

    fn fitted(cause: Cause, size: f64, z: f64) -> Fitted {
        Fitted {
            cause,
            hypothesis: Hypothesis::nominal(),
            parameters: Vec::new(),
            side: None,
            size,
            z,
            practical: 0.1,
            at_edge: false,
            beyond_physics: None,
            states: None,
            companion: None,
            scalar_fit: None,
        }
    }

    fn at(nll_test: f64) -> PassOut {
        PassOut {
            nll_test,
            ..PassOut::default()
        }
    }

    fn scored(f: Fitted, nll_test: f64) -> (Fitted, PassOut) {
        (
            f,
            PassOut {
                nll_test,
                ..PassOut::default()
            },
        )
    }

    /// The candidate with the largest held-out gain that clears every bar
    /// is taken; a larger gain that misses a bar is rejected with the bar.
    #[test]
    fn a_round_takes_the_largest_gain_that_clears_every_bar() {
        let acc = Acceptance::default();
        let mut too_small = fitted(Cause::SogScale, 0.05, 10.0);
        too_small.practical = 0.2;
        let mut impossible = fitted(Cause::GnssLatency, 0.0, 10.0);
        impossible.beyond_physics = Some("no");
        let round = choose(
            vec![
                scored(fitted(Cause::Current, 0.3, 2.0), 900.0),
                scored(too_small, 850.0),
                scored(impossible, 800.0),
                scored(fitted(Cause::HeadingOffset, 0.2, 8.0), 950.0),
                scored(fitted(Cause::LeverArm, 0.5, 8.0), 960.0),
                scored(fitted(Cause::ThrusterLoss, 0.5, 8.0), 995.0),
            ],
            &at(1000.0),
            &acc,
            &|_| Settled::AtMinimum,
        );
        let (f, _, gain) = round.took.expect("one clears the bars");
        assert_eq!(f.cause, Cause::HeadingOffset);
        assert_eq!(gain, 50.0);
        let reasons: Vec<(Cause, &str)> = round
            .rejected
            .iter()
            .map(|r| (r.cause, r.reason.as_str()))
            .collect();
        assert_eq!(reasons.len(), 5);
        assert_eq!(reasons[0].0, Cause::GnssLatency);
        assert_eq!(reasons[0].1, "no");
        assert!(
            reasons[1]
                .1
                .starts_with("size 0.050 is below the practical")
        );
        assert!(reasons[2].1.contains("standard deviations"));
        assert_eq!(reasons[3].1, "a larger gain was taken this round");
        assert!(reasons[4].1.starts_with("held-out log-likelihood gain 5.0"));
    }

    /// A candidate about to be taken whose fit is at no minimum of a
    /// smooth likelihood is rejected with that reason, and the next that
    /// clears every bar is taken; only candidates about to be taken are
    /// settled.
    #[test]
    fn a_fit_at_no_minimum_is_not_taken_and_the_next_is() {
        let acc = Acceptance::default();
        let asked = std::cell::RefCell::new(Vec::new());
        let rough = |f: &Fitted| {
            asked.borrow_mut().push(f.cause);
            if f.cause == Cause::GnssLatency {
                Settled::NotSmooth("not smooth".to_string())
            } else {
                Settled::AtMinimum
            }
        };
        let round = choose(
            vec![
                scored(fitted(Cause::Current, 0.3, 8.0), 900.0),
                scored(fitted(Cause::GnssLatency, 0.3, 8.0), 880.0),
                scored(fitted(Cause::SogScale, 0.3, 1.0), 860.0),
            ],
            &at(1000.0),
            &acc,
            &rough,
        );
        let (f, _, gain) = round.took.expect("the current clears every bar");
        assert_eq!((f.cause, gain), (Cause::Current, 100.0));
        assert_eq!(*asked.borrow(), [Cause::GnssLatency, Cause::Current]);
        let latency = round
            .rejected
            .iter()
            .find(|r| r.cause == Cause::GnssLatency)
            .expect("rejected");
        assert_eq!(latency.reason, "not smooth");
        assert_eq!(latency.heldout_nll_gain, 120.0);
    }

    /// A candidate about to be taken whose fit stopped short of its
    /// minimum is moved there and judged again, once: moved to a smaller
    /// held-out gain, it gives way to a larger one; moved to where it
    /// misses a bar, it is rejected with that bar.
    #[test]
    fn a_fit_short_of_its_minimum_is_moved_there_and_judged_again() {
        let acc = Acceptance::default();
        let asked = std::cell::RefCell::new(Vec::new());
        let moving = |f: &Fitted| {
            asked.borrow_mut().push(f.cause);
            match f.cause {
                Cause::GnssLatency => Settled::Moved(Box::new(scored(
                    fitted(Cause::GnssLatency, 0.4, 8.0),
                    940.0,
                ))),
                Cause::Mass => {
                    Settled::Moved(Box::new(scored(fitted(Cause::Mass, 0.4, 1.0), 800.0)))
                }
                _ => Settled::AtMinimum,
            }
        };
        let round = choose(
            vec![
                scored(fitted(Cause::Current, 0.3, 8.0), 900.0),
                scored(fitted(Cause::GnssLatency, 0.3, 8.0), 880.0),
            ],
            &at(1000.0),
            &acc,
            &moving,
        );
        let (f, _, gain) = round.took.expect("the current clears every bar");
        assert_eq!((f.cause, gain), (Cause::Current, 100.0));
        assert_eq!(*asked.borrow(), [Cause::GnssLatency, Cause::Current]);
        let latency = &round.rejected[0];
        assert_eq!(latency.cause, Cause::GnssLatency);
        assert_eq!(latency.heldout_nll_gain, 60.0);
        assert_eq!(
            latency.parameters,
            fitted(Cause::GnssLatency, 0.4, 8.0).parameters
        );
        asked.borrow_mut().clear();
        let round = choose(
            vec![scored(fitted(Cause::Mass, 0.3, 8.0), 900.0)],
            &at(1000.0),
            &acc,
            &moving,
        );
        assert!(round.took.is_none());
        assert_eq!(*asked.borrow(), [Cause::Mass]);
        assert!(
            round.rejected[0].reason.contains("standard deviations"),
            "{}",
            round.rejected[0].reason
        );
    }

    /// Of two causes that explain the data as well (held-out gains within
    /// the bar of each other), the one with fewer parameters is named; a
    /// clearly larger gain still wins.
    #[test]
    fn the_simpler_of_two_equal_explanations_is_named() {
        let acc = Acceptance::default();
        let round = choose(
            vec![
                scored(fitted(Cause::ThrusterLoss, 0.3, 8.0), 900.0),
                scored(fitted(Cause::SurgeDamping, 0.3, 8.0), 905.0),
            ],
            &at(1000.0),
            &acc,
            &|_| Settled::AtMinimum,
        );
        assert_eq!(round.took.expect("taken").0.cause, Cause::SurgeDamping);
        assert!(
            round.rejected[0]
                .reason
                .starts_with("surge_damping explains the data as well"),
            "{}",
            round.rejected[0].reason
        );
        let round = choose(
            vec![
                scored(fitted(Cause::ThrusterLoss, 0.3, 8.0), 900.0),
                scored(fitted(Cause::SurgeDamping, 0.3, 8.0), 920.0),
            ],
            &at(1000.0),
            &acc,
            &|_| Settled::AtMinimum,
        );
        assert_eq!(round.took.expect("taken").0.cause, Cause::ThrusterLoss);
        assert_eq!(
            round.rejected[0].reason,
            "a larger gain was taken this round"
        );
    }

    /// A cause of the vessel's dynamics that makes the forecasts worse
    /// over the horizons taken together is refused, however much one-step
    /// likelihood it buys; one that halves the short horizon's error and
    /// loses a little at the longest is not; a sensor cause is not judged
    /// on the forecast.
    #[test]
    fn a_dynamics_cause_must_improve_the_forecasts_taken_together() {
        let acc = Acceptance::default();
        // Root-mean-square errors 5 m at 5 s and 10 m at 30 s (4 forecasts).
        let current = PassOut {
            nll_test: 1000.0,
            forecast: vec![(5.0, 100.0, 4), (30.0, 400.0, 4)],
            ..PassOut::default()
        };
        let with_forecast = |f: Fitted, rms_5_m: f64, rms_30_m: f64| {
            (
                f,
                PassOut {
                    nll_test: 900.0,
                    forecast: vec![
                        (5.0, 4.0 * rms_5_m * rms_5_m, 4),
                        (30.0, 4.0 * rms_30_m * rms_30_m, 4),
                    ],
                    ..PassOut::default()
                },
            )
        };
        let round = choose(
            vec![
                with_forecast(fitted(Cause::Mass, 0.5, 8.0), 4.0, 15.0),
                with_forecast(fitted(Cause::HeadingOffset, 0.2, 8.0), 4.0, 15.0),
            ],
            &current,
            &acc,
            &|_| Settled::AtMinimum,
        );
        assert_eq!(round.took.expect("taken").0.cause, Cause::HeadingOffset);
        assert!(
            round.rejected[0].reason.starts_with(
                "it makes the held-out forecasts worse (5 s 5.0 m -> 4.0 m, 30 s 10.0 m -> 15.0 m; errors x1.10"
            ),
            "{}",
            round.rejected[0].reason
        );
        let round = choose(
            vec![with_forecast(fitted(Cause::Mass, 0.5, 8.0), 2.5, 12.0)],
            &current,
            &acc,
            &|_| Settled::AtMinimum,
        );
        assert_eq!(round.took.expect("taken").0.cause, Cause::Mass);
    }
}
