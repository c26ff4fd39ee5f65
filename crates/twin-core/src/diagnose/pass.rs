//! One pass of a base model's filter over a prepared log: the training
//! part's likelihood (what the fits maximise), the held-out part's
//! likelihood, innovations and k-step-ahead forecast errors (what the
//! findings are judged on), and the state estimates at the split.
//!
//! The bases are those of the live twin ([`crate::estimator`]); this module
//! only adds what a diagnosis reads off them ([`PassBase`]).

use nalgebra::{SMatrix, SVector};

use super::fit::{DiagnoseConfig, Hypothesis};
use super::prepare::{Prepared, Step};
use super::residuals::{COMPONENT_COUNT, InnovationRecord};
use crate::aekf::{AekfError, AekfState, StepReport};
use crate::estimator::{
    CourseGate, KineticBase, KineticConfig, KineticOptions, KineticState, LocalFix, Term,
    WaterBase, WaterOptions,
};
use crate::linalg::cholesky;
use crate::model::Model;
use crate::models::otter_twin::{
    FAULTS, MEASUREMENTS, OtterTwin, STATES, ShaftSpeeds, fault, idx as kidx,
};
use crate::models::water_kinematic::{
    MEASUREMENTS as WATER_MEASUREMENTS, WaterKinematic, idx as widx,
};
use crate::predict::predict_states;

/// State-type estimates at the end of the training part.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct AtSplit {
    pub current: [f64; 2],
    pub current_cov: [[f64; 2]; 2],
    pub loss: [f64; 2],
    pub loss_sigma: [f64; 2],
    /// Per propeller, seconds from the log's first fix to the step from
    /// which its estimated loss stays at or above half its value at the
    /// split (NaN where there is no loss, or no propeller data).
    pub loss_onset_s: [f64; 2],
}

/// What a pass measured.
#[derive(Debug, Clone, Default)]
pub(super) struct PassOut {
    pub nll_train: f64,
    pub nll_test: f64,
    pub steps_test: usize,
    pub at_split: AtSplit,
    pub records: Vec<InnovationRecord>,
    /// Per horizon: `(horizon s, sum of squared position errors m^2, count)`.
    pub forecast: Vec<(f64, f64, usize)>,
    pub failed: bool,
}

impl PassOut {
    fn failed() -> Self {
        Self {
            failed: true,
            ..Self::default()
        }
    }

    /// Position prediction RMSE per horizon: `(horizon s, m)`.
    pub fn rmse(&self) -> Vec<(f64, f64)> {
        self.forecast
            .iter()
            .map(|(h, sq, n)| {
                (
                    *h,
                    if *n > 0 {
                        (sq / *n as f64).sqrt()
                    } else {
                        f64::NAN
                    },
                )
            })
            .collect()
    }
}

/// How far a pass goes and what it keeps.
#[derive(Clone, Copy)]
pub(super) struct PassOptions<'a> {
    /// First held-out step.
    pub split: usize,
    /// Stop after the training part (fitting runs).
    pub train_only: bool,
    /// Keep the held-out innovations.
    pub record: bool,
    pub config: &'a DiagnoseConfig,
}

/// The input type of a model.
type InputOf<Mdl, const N: usize, const M: usize, const P: usize> = <Mdl as Model<N, M, P>>::Input;

/// What a diagnosis needs of a base beyond the live twin's use of it.
trait PassBase<const N: usize, const M: usize, const P: usize> {
    type Model: Model<N, M, P>;
    /// Where each measurement component goes in an [`InnovationRecord`].
    const SLOTS: [usize; M];

    fn model(&self) -> &Self::Model;
    fn prior(&self, fix: &LocalFix) -> AekfState<N, M, P>;
    fn available(&self, fix: &LocalFix) -> [bool; M];
    fn step(
        &self,
        state: &mut AekfState<N, M, P>,
        input: &InputOf<Self::Model, N, M, P>,
        fix: &LocalFix,
        dt_s: f64,
    ) -> Result<StepReport<M, P>, AekfError>;
    /// The input of every step, in step order.
    fn inputs(&self, steps: &[Step]) -> Vec<InputOf<Self::Model, N, M, P>>;
    /// `[sin heading, cos heading, speed, yaw rate]` of a state.
    fn signatures(&self, x: &SVector<f64, N>) -> [f64; 4];
    fn at_split(&self, state: &AekfState<N, M, P>) -> AtSplit;
    /// What the hypothesis changes in the held states from `elapsed_s`
    /// (seconds from the log's first fix), before that step.
    fn at_time(&self, _state: &mut AekfState<N, M, P>, _elapsed_s: f64) {}
    /// The propellers' estimated losses, where the base has them.
    fn losses(&self, _state: &AekfState<N, M, P>) -> Option<[f64; 2]> {
        None
    }
}

/// Per propeller, the time from which the loss track stays at or above half
/// its last value (NaN for a last value below `min_loss`).
fn loss_onsets(track: &[(f64, [f64; 2])], min_loss: f64) -> [f64; 2] {
    let mut onset = [f64::NAN; 2];
    let Some((_, last)) = track.last() else {
        return onset;
    };
    for side in 0..2 {
        if last[side].is_nan() || last[side] < min_loss {
            continue;
        }
        let half = 0.5 * last[side];
        onset[side] = track
            .iter()
            .rposition(|(_, l)| l[side] < half)
            .map_or(track[0].0, |i| track[(i + 1).min(track.len() - 1)].0);
    }
    onset
}

struct Kinetic {
    base: KineticBase,
    /// Losses `[port, starboard]` held from this many seconds after the
    /// log's first fix (none before), where the hypothesis has a step.
    loss_step: Option<(f64, [f64; 2])>,
}

impl PassBase<STATES, MEASUREMENTS, FAULTS> for Kinetic {
    type Model = OtterTwin;
    const SLOTS: [usize; MEASUREMENTS] = [0, 1, 2, 3, 4, 6];

    fn model(&self) -> &OtterTwin {
        self.base.model()
    }

    fn prior(&self, fix: &LocalFix) -> KineticState {
        self.base.prior(fix, None)
    }

    fn available(&self, fix: &LocalFix) -> [bool; MEASUREMENTS] {
        self.base.measurement(fix).available
    }

    fn step(
        &self,
        state: &mut KineticState,
        input: &ShaftSpeeds,
        fix: &LocalFix,
        dt_s: f64,
    ) -> Result<StepReport<MEASUREMENTS, FAULTS>, AekfError> {
        self.base.step(state, input, fix, dt_s)
    }

    /// The mean shaft speeds over each step's interval; an interval without
    /// samples holds the last.
    fn inputs(&self, steps: &[Step]) -> Vec<ShaftSpeeds> {
        let mut last = ShaftSpeeds::default();
        steps
            .iter()
            .map(|s| {
                if let Some([p, sb]) = s.shafts_radps {
                    last = ShaftSpeeds {
                        port_radps: p,
                        starboard_radps: sb,
                    };
                }
                last
            })
            .collect()
    }

    fn signatures(&self, x: &SVector<f64, STATES>) -> [f64; 4] {
        let (s, c) = x[kidx::PSI].sin_cos();
        [s, c, x[kidx::U].hypot(x[kidx::V]), x[kidx::R]]
    }

    fn at_split(&self, st: &KineticState) -> AtSplit {
        let sig = st.fault_sigma();
        let cov = st.p + st.upsilon * st.s * st.upsilon.transpose();
        let (a, b) = (kidx::CURRENT_NORTH, kidx::CURRENT_EAST);
        AtSplit {
            current: [st.x[a], st.x[b]],
            current_cov: [[cov[(a, a)], cov[(a, b)]], [cov[(b, a)], cov[(b, b)]]],
            loss: [st.theta[0], st.theta[1]],
            loss_sigma: [sig[0], sig[1]],
            loss_onset_s: [f64::NAN; 2],
        }
    }

    fn losses(&self, st: &KineticState) -> Option<[f64; 2]> {
        Some([st.theta[0], st.theta[1]])
    }

    fn at_time(&self, state: &mut KineticState, elapsed_s: f64) {
        if let Some((from_s, loss)) = self.loss_step
            && elapsed_s >= from_s
        {
            state.theta[fault::PORT] = loss[0];
            state.theta[fault::STARBOARD] = loss[1];
        }
    }
}

struct Water(WaterBase);

impl PassBase<7, WATER_MEASUREMENTS, 0> for Water {
    type Model = WaterKinematic;
    const SLOTS: [usize; WATER_MEASUREMENTS] = [0, 1, 2, 3, 4, 5, 6];

    fn model(&self) -> &WaterKinematic {
        &self.0.filter().model
    }

    fn prior(&self, fix: &LocalFix) -> AekfState<7, WATER_MEASUREMENTS, 0> {
        self.0.prior(fix)
    }

    fn available(&self, fix: &LocalFix) -> [bool; WATER_MEASUREMENTS] {
        self.0.measurement(fix).available
    }

    fn step(
        &self,
        state: &mut AekfState<7, WATER_MEASUREMENTS, 0>,
        _input: &(),
        fix: &LocalFix,
        dt_s: f64,
    ) -> Result<StepReport<WATER_MEASUREMENTS, 0>, AekfError> {
        self.0.step(state, fix, dt_s)
    }

    fn inputs(&self, steps: &[Step]) -> Vec<()> {
        vec![(); steps.len()]
    }

    fn signatures(&self, x: &SVector<f64, 7>) -> [f64; 4] {
        let (s, c) = x[widx::PSI].sin_cos();
        [s, c, x[widx::U], x[widx::R]]
    }

    fn at_split(&self, st: &AekfState<7, WATER_MEASUREMENTS, 0>) -> AtSplit {
        let (a, b) = (widx::CURRENT_NORTH, widx::CURRENT_EAST);
        AtSplit {
            current: [st.x[a], st.x[b]],
            current_cov: [[st.p[(a, a)], st.p[(a, b)]], [st.p[(b, a)], st.p[(b, b)]]],
            loss_onset_s: [f64::NAN; 2],
            ..AtSplit::default()
        }
    }
}

/// Runs the kinetic base with the hypothesis `hyp` over the log.
pub(super) fn kinetic_pass(prep: &Prepared, hyp: &Hypothesis, opts: PassOptions<'_>) -> PassOut {
    let config = &opts.config.twin;
    // A step: the losses held at none until `loss_from_s`, then at theirs.
    let loss_step = match hyp.loss {
        Term::Fixed(loss) if hyp.loss_from_s > 0.0 => Some((hyp.loss_from_s, loss)),
        _ => None,
    };
    let options = KineticOptions {
        effects: hyp.effects,
        current: hyp.current,
        losses: if loss_step.is_some() {
            Term::Fixed([0.0; 2])
        } else {
            hyp.loss
        },
        heading_bias: hyp.heading_bias,
        yaw_rate_bias: hyp.yaw_rate_bias,
        profile_errors: Term::Off,
    };
    // Scales of 1 leave every parameter as it is, bit for bit.
    let kinetic = KineticConfig {
        params: config.kinetic.params.scaled(hyp.profile_scales),
        ..config.kinetic
    };
    match KineticBase::new(&kinetic, gate(opts.config), options) {
        Ok(base) => drive(&Kinetic { base, loss_step }, prep, opts),
        Err(_) => PassOut::failed(),
    }
}

/// Runs the water base with the hypothesis `hyp` over the log.
pub(super) fn water_pass(prep: &Prepared, hyp: &Hypothesis, opts: PassOptions<'_>) -> PassOut {
    let c = opts.config;
    let options = WaterOptions {
        // The profile's antenna position, and any lever arm a search adds
        // to it, as on the kinetic base.
        effects: hyp
            .effects
            .with_antenna_from(c.twin.kinetic.params.antenna_m),
        stw_scale: hyp.stw_scale,
        sideslip_m: hyp.sideslip_m,
        sideslip_per_speed_s: hyp.speed_sideslip_m / prep.under_way_speed_mps,
        current: hyp.current,
        process_noise: c.water_process_noise,
        measurement_sigma: c.water_measurement_sigma,
    };
    match WaterBase::new(&options, gate(c)) {
        Ok(base) => drive(&Water(base), prep, opts),
        Err(_) => PassOut::failed(),
    }
}

/// The course gate of the twin the diagnosis is configured with.
fn gate(config: &DiagnoseConfig) -> CourseGate {
    CourseGate {
        min_sog_mps: config.twin.gating.min_sog_for_course_mps,
    }
}

/// `log det` of the innovation covariance over the available components.
fn log_det_available<const M: usize>(sigma: &SMatrix<f64, M, M>, available: &[bool; M]) -> f64 {
    let Some(l) = cholesky(sigma) else {
        return f64::INFINITY;
    };
    let mut s = 0.0;
    for i in 0..M {
        if available[i] {
            s += 2.0 * l[(i, i)].ln();
        }
    }
    // Masked rows are decoupled (zero rows of H, zero off-diagonals of R):
    // their diagonal factor is sqrt(R_ii) and does not belong to the
    // likelihood; it was skipped above.
    s
}

/// Drives `base` over the steps, scoring the one-step-ahead predictions.
fn drive<B, const N: usize, const M: usize, const P: usize>(
    base: &B,
    prep: &Prepared,
    opts: PassOptions<'_>,
) -> PassOut
where
    B: PassBase<N, M, P>,
{
    // Forecasts are scored on measured positions: none without them.
    let horizons_s: &[f64] = if prep.has_position {
        &opts.config.horizons_s
    } else {
        &[]
    };
    let mut out = PassOut {
        forecast: horizons_s.iter().map(|h| (*h, 0.0, 0)).collect(),
        ..PassOut::default()
    };
    let steps = &prep.steps;
    let inputs = base.inputs(steps);
    let mut state = base.prior(&steps[0].fix);
    let ln2pi = (2.0 * std::f64::consts::PI).ln();
    let mut next_forecast_s = f64::NEG_INFINITY;
    let mut last_speed = None::<(f64, f64)>;
    let t0 = steps[0].fix.time_s;
    let mut loss_track: Vec<(f64, [f64; 2])> = Vec::new();
    let min_loss = opts.config.acceptance.min_loss;
    for k in 1..steps.len() {
        if k == opts.split {
            out.at_split = base.at_split(&state);
            out.at_split.loss_onset_s = loss_onsets(&loss_track, min_loss);
            if opts.train_only {
                break;
            }
        }
        let step = &steps[k].fix;
        base.at_time(&mut state, step.time_s - t0);
        let dt = step.time_s - steps[k - 1].fix.time_s;
        let Ok(report) = base.step(&mut state, &inputs[k], step, dt) else {
            return PassOut::failed();
        };
        let avail = base.available(step);
        let dof = avail.iter().filter(|a| **a).count() as f64;
        let nll = 0.5
            * (report.nis + log_det_available(&report.innovation_covariance, &avail) + dof * ln2pi);
        if k < opts.split {
            out.nll_train += nll;
            if let Some(l) = base.losses(&state) {
                loss_track.push((step.time_s - t0, l));
            }
            continue;
        }
        out.nll_test += nll;
        out.steps_test += 1;
        if opts.record {
            let sig = base.signatures(&state.x);
            let accel = last_speed
                .map(|(t, v)| (sig[2] - v) / (step.time_s - t))
                .unwrap_or(0.0);
            last_speed = Some((step.time_s, sig[2]));
            let mut rec = InnovationRecord {
                time_s: step.time_s,
                innovation: [0.0; COMPONENT_COUNT],
                sigma: [0.0; COMPONENT_COUNT],
                available: [false; COMPONENT_COUNT],
                nis: report.nis,
                dof: report.dof,
                signatures: [sig[0], sig[1], sig[2], sig[3], accel, step.time_s - t0],
            };
            for i in 0..M {
                let slot = B::SLOTS[i];
                rec.innovation[slot] = report.innovation[i];
                rec.sigma[slot] = report.innovation_covariance[(i, i)].max(0.0).sqrt();
                rec.available[slot] = avail[i];
            }
            out.records.push(rec);
        }
        if step.time_s >= next_forecast_s && !out.forecast.is_empty() {
            next_forecast_s = step.time_s + opts.config.forecast_every_s;
            score_forecasts(base, prep, &inputs, k, &state, &mut out.forecast);
        }
    }
    if opts.split >= steps.len() {
        out.at_split = base.at_split(&state);
        out.at_split.loss_onset_s = loss_onsets(&loss_track, min_loss);
    }
    out
}

/// Forecasts from step `k`'s estimate through the recorded inputs and adds
/// the squared position errors at each horizon to `forecast`.
fn score_forecasts<B, const N: usize, const M: usize, const P: usize>(
    base: &B,
    prep: &Prepared,
    inputs: &[InputOf<B::Model, N, M, P>],
    k: usize,
    state: &AekfState<N, M, P>,
    forecast: &mut [(f64, f64, usize)],
) where
    B: PassBase<N, M, P>,
{
    let steps = &prep.steps;
    let now_s = steps[k].fix.time_s;
    let longest = forecast.iter().map(|f| f.0).fold(0.0, f64::max);
    let ahead: Vec<usize> = (k + 1..steps.len())
        .take_while(|j| steps[*j].fix.time_s <= now_s + longest + 1.0)
        .collect();
    let model_inputs = ahead
        .iter()
        .map(|j| (steps[*j].fix.time_s - steps[*j - 1].fix.time_s, inputs[*j]));
    // States alone: the forecast's covariance is not used here.
    let points = predict_states(base.model(), state, now_s, model_inputs);
    for (h, sq, n) in forecast.iter_mut() {
        let target = now_s + *h;
        if let Some((p, j)) = points
            .iter()
            .zip(&ahead)
            .find(|(_, j)| steps[**j].fix.time_s >= target - 1e-9)
            && steps[*j].fix.time_s - target < 1.0
        {
            let pred = base.model().observe(&p.1).predicted;
            let m = steps[*j].fix.position;
            *sq += (pred[0] - m.north_m).powi(2) + (pred[1] - m.east_m).powi(2);
            *n += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_loss_onset_is_where_the_track_last_rose_through_half_its_value() {
        let track: Vec<(f64, [f64; 2])> = (0..100)
            .map(|i| {
                let t = f64::from(i);
                // Port: none until 40 s, then 0.3 after a ramp of 10 s.
                let port = (0.03 * (t - 40.0)).clamp(0.0, 0.3);
                (t, [port, 0.01])
            })
            .collect();
        let onset = loss_onsets(&track, 0.03);
        // Half of 0.3 is reached at 45 s.
        assert_eq!(onset[0], 45.0);
        assert!(onset[1].is_nan(), "no loss on starboard: {}", onset[1]);
        // A loss there from the start has its onset at the first step.
        let from_start: Vec<(f64, [f64; 2])> =
            (0..10).map(|i| (f64::from(i), [0.2, 0.0])).collect();
        assert_eq!(loss_onsets(&from_start, 0.03)[0], 0.0);
        assert!(loss_onsets(&[], 0.03)[0].is_nan());
    }
}
