//! Open-loop prediction from a calibrated estimate: the twin's forecast of
//! where the vessel will be, with the faults frozen at their estimates and
//! the uncertainty of every predicted point.
//!
//! The state and the fault estimate are propagated jointly. The filter's
//! estimate error has a part independent of the fault error (covariance `P`)
//! and a part driven by it through `Upsilon` (Zhang 2018), so the joint
//! covariance at the start is
//!
//! ```text
//! [[P + Upsilon S Upsilon^T, Upsilon S], [S Upsilon^T, S]]
//! ```
//!
//! and each step applies `[[F, Psi], [0, I]]` plus the process noise
//! `Q_c dt` on the state: the faults are frozen (no noise), but their
//! uncertainty keeps spreading into the state.

use nalgebra::{SMatrix, SVector};

use crate::aekf::AekfState;
use crate::linalg::{mul, mul_sparse_left, mul_t, sym_mul_t_sparse};
use crate::model::Model;

/// One predicted point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PredictedPoint<const N: usize> {
    /// Time of the point, seconds (same clock as the estimate's).
    pub time_s: f64,
    /// Predicted state.
    pub x: SVector<f64, N>,
    /// Covariance of the predicted state, including the fault uncertainty.
    pub covariance: SMatrix<f64, N, N>,
}

impl<const N: usize> PredictedPoint<N> {
    /// Standard deviation of state component `i`.
    pub fn sigma(&self, i: usize) -> f64 {
        self.covariance[(i, i)].max(0.0).sqrt()
    }
}

/// Predicts from `state` (taken at `start_time_s`) through the given inputs,
/// each applied for its `dt_s`, with process noise density `q_density`.
/// Each step uses the model's [`Model::forecast_transition`].
/// Returns one point per input, at the end of its interval. Stops early at
/// the first step that produces a non-finite state.
///
/// Like the filter's step, it runs a copy of its code compiled for AVX2
/// where the processor has it, with the same numbers bit for bit
/// ([`crate::simd`]).
pub fn predict<Mdl, const N: usize, const M: usize, const P: usize>(
    model: &Mdl,
    state: &AekfState<N, M, P>,
    q_density: &SMatrix<f64, N, N>,
    start_time_s: f64,
    inputs: impl IntoIterator<Item = (f64, Mdl::Input)>,
) -> Vec<PredictedPoint<N>>
where
    Mdl: Model<N, M, P>,
{
    #[cfg(target_arch = "x86_64")]
    if crate::simd::avx2_available() {
        // SAFETY: `predict_avx2` requires AVX2 and FMA, and the processor
        // running this code has both (checked on the line above).
        #[allow(unsafe_code)]
        return unsafe { predict_avx2(model, state, q_density, start_time_s, inputs) };
    }
    predict_baseline(model, state, q_density, start_time_s, inputs)
}

/// [`predict`] compiled for AVX2 (the same source, inlined here).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn predict_avx2<Mdl, const N: usize, const M: usize, const P: usize>(
    model: &Mdl,
    state: &AekfState<N, M, P>,
    q_density: &SMatrix<f64, N, N>,
    start_time_s: f64,
    inputs: impl IntoIterator<Item = (f64, Mdl::Input)>,
) -> Vec<PredictedPoint<N>>
where
    Mdl: Model<N, M, P>,
{
    predict_baseline(model, state, q_density, start_time_s, inputs)
}

/// [`predict`] in the baseline code, whatever the processor.
#[inline(always)]
fn predict_baseline<Mdl, const N: usize, const M: usize, const P: usize>(
    model: &Mdl,
    state: &AekfState<N, M, P>,
    q_density: &SMatrix<f64, N, N>,
    start_time_s: f64,
    inputs: impl IntoIterator<Item = (f64, Mdl::Input)>,
) -> Vec<PredictedPoint<N>>
where
    Mdl: Model<N, M, P>,
{
    let mut x = state.x;
    let theta = state.theta;
    let p_tt = state.s;
    let mut p_xt = state.upsilon * state.s;
    let mut p_xx = state.p + p_xt * state.upsilon.transpose();
    let mut time_s = start_time_s;
    let inputs = inputs.into_iter();
    let mut out = Vec::with_capacity(inputs.size_hint().0);
    for (dt_s, input) in inputs {
        if !(dt_s > 0.0 && dt_s.is_finite()) {
            break;
        }
        let tr = model.forecast_transition(&x, &input, &theta, dt_s);
        if tr.next.iter().any(|v| !v.is_finite()) {
            break;
        }
        let f = tr.jacobian;
        let f_pattern = &Mdl::TRANSITION_PATTERN;
        let psi = tr.fault_sensitivity;
        // The filter's own small products (linalg), skipping F's known zeros.
        let f_pxt = mul_sparse_left(&f, f_pattern, &p_xt);
        let psi_ptt = mul(&psi, &p_tt);
        let cross = mul_t(&f_pxt, &psi);
        p_xx = sym_mul_t_sparse(&mul_sparse_left(&f, f_pattern, &p_xx), &f, f_pattern)
            + cross
            + cross.transpose()
            + mul_t(&psi_ptt, &psi)
            + q_density * dt_s;
        p_xx = (p_xx + p_xx.transpose()) * 0.5;
        p_xt = f_pxt + psi_ptt;
        x = tr.next;
        time_s += dt_s;
        out.push(PredictedPoint {
            time_s,
            x,
            covariance: p_xx,
        });
    }
    out
}

/// The states alone of [`predict`] (no covariance, no derivatives): from
/// `state`'s estimate with its faults frozen, one `(time, state)` per input,
/// each applied for its `dt_s`. Stops early like [`predict`].
pub fn predict_states<Mdl, const N: usize, const M: usize, const P: usize>(
    model: &Mdl,
    state: &AekfState<N, M, P>,
    start_time_s: f64,
    inputs: impl IntoIterator<Item = (f64, Mdl::Input)>,
) -> Vec<(f64, SVector<f64, N>)>
where
    Mdl: Model<N, M, P>,
{
    let mut x = state.x;
    let mut time_s = start_time_s;
    let inputs = inputs.into_iter();
    let mut out = Vec::with_capacity(inputs.size_hint().0);
    for (dt_s, input) in inputs {
        if !(dt_s > 0.0 && dt_s.is_finite()) {
            break;
        }
        let next = model.propagate(&x, &input, &state.theta, dt_s);
        if next.iter().any(|v| !v.is_finite()) {
            break;
        }
        x = next;
        time_s += dt_s;
        out.push((time_s, x));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::otter_twin::{OtterTwin, STATES, ShaftSpeeds};
    use crate::twin::TwinConfig;

    /// The forecast's AVX2 copy and its baseline code give the same bits
    /// (exact Debug text of every point), on the extended twin in a turn
    /// with a propeller down and an uncertain estimate.
    #[test]
    fn both_copies_of_the_forecast_give_the_same_bits() {
        if !crate::simd::avx2_available() {
            eprintln!("no AVX2 here: both calls run the baseline code");
        }
        let kinetic = TwinConfig::default().kinetic;
        let model = OtterTwin::new(kinetic.params);
        let mut x0 = SVector::<f64, STATES>::zeros();
        x0[3] = 1.4;
        x0[5] = 0.1;
        let mut state = AekfState::new(
            &kinetic.filter,
            x0,
            SMatrix::identity() * 0.05,
            SVector::from([0.25, 0.0, 0.1, -0.1, 0.05, 0.02]),
        );
        state.upsilon[(3, 0)] = -0.3;
        let inputs = (0..60).map(|k| {
            let turn = if k < 30 { 0.6 } else { 1.0 };
            let u = ShaftSpeeds {
                port_radps: 90.0 * turn,
                starboard_radps: 90.0,
            };
            (1.0, u)
        });
        let dispatched = predict(
            &model,
            &state,
            &kinetic.filter.process_noise_density,
            10.0,
            inputs.clone(),
        );
        let baseline = predict_baseline(
            &model,
            &state,
            &kinetic.filter.process_noise_density,
            10.0,
            inputs,
        );
        assert_eq!(dispatched.len(), 60);
        assert_eq!(format!("{dispatched:?}"), format!("{baseline:?}"));
    }
}
