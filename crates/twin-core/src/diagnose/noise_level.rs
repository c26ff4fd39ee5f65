//! The level of the kinetic base's velocity process noise that a log asks
//! for, per axis, and the sizes of the vessel's dynamics refitted under it.
//!
//! The search of causes runs its filter with the harbour water's process
//! noise, fixed (`KineticConfig::for_search`): the bars of the selection
//! were set with it. But a likelihood maximised with a process noise that
//! is not the data's does not peak at the parameters' true values. The
//! innovation covariance of a model whose velocities decay faster (a more
//! damped or a lighter hull) is smaller, and where the configured noise is
//! larger than the water's, the log-determinant term rewards that without
//! the model predicting any better: on the profile's own vessel in calm
//! water the fit put the yaw damping at 1.06 and the mass at 0.89 of the
//! profile's. The maximum likelihood estimate of a dynamics parameter is
//! consistent once the noise level is estimated with it (Harvey 1989,
//! *Forecasting, Structural Time Series Models and the Kalman Filter*,
//! section 3.4, for a common scale; here one level per axis, surge, sway
//! and yaw, because the water's forces and what the model lacks differ
//! per axis).
//!
//! So, once the causes are selected, the sizes of the yaw damping and mass
//! findings are fitted again under the levels the training likelihood
//! prefers with every finding in the model (`fit::refine_dynamics_sizes`).
//! The selection, the judging on held-out data and the surge damping are
//! left as they are: with the fitted levels in the search itself, causes
//! that imitate a model error (a lever arm, a latency) gained enough to be
//! named on vessels that have neither, and the surge damping shares a ridge
//! with the losses' common part, along which a refit moves both
//! (docs/known-issues.md, "Diagnose").

use super::fit::{DiagnoseConfig, golden_section};
use crate::models::otter_twin::idx;

/// Each axis's level is searched from 1/16 to 4 times the configured
/// noise, as a power of two ...
const LOG2_LEVEL_RANGE: (f64, f64) = (-4.0, 2.0);
/// ... or, from a level found before, within this many powers of two of it.
const LOG2_LEVEL_STEP: f64 = 1.0;
/// The search's bracket is narrowed to this (a level to within 3 %).
const LOG2_LEVEL_TOLERANCE: f64 = 0.05;

/// `config` with the kinetic base's velocity process noise density
/// scaled by `2^log2_levels` on the surge, sway and yaw axes (the
/// sway-yaw coupling by the geometric mean of its two).
pub(super) fn with_velocity_noise_levels(
    config: &DiagnoseConfig,
    log2_levels: [f64; 3],
) -> DiagnoseConfig {
    let mut scaled = config.clone();
    let q = &mut scaled.twin.kinetic.filter.process_noise_density;
    let levels = log2_levels.map(f64::exp2);
    for i in 0..3 {
        for j in 0..3 {
            q[(idx::U + i, idx::U + j)] *= (levels[i] * levels[j]).sqrt();
        }
    }
    scaled
}

/// The levels (powers of two over `config`'s noise, surge, sway and yaw)
/// that minimise `training_nll`, the training part's negative
/// log-likelihood under a configuration: each axis on its own, with the
/// others at `start` (the axes' levels hardly interact: each is read mostly
/// off its own velocity's innovations), on up to `threads` threads. With
/// `near_start`, each is searched within [`LOG2_LEVEL_STEP`] of its start.
pub(super) fn fitted_velocity_noise_levels(
    config: &DiagnoseConfig,
    start: [f64; 3],
    near_start: bool,
    training_nll: &(dyn Fn(&DiagnoseConfig) -> f64 + Sync),
    threads: usize,
) -> [f64; 3] {
    let fit_axis = |axis: usize| {
        let nll = |level: f64| {
            let mut trial = start;
            trial[axis] = level;
            training_nll(&with_velocity_noise_levels(config, trial))
        };
        let (lo, hi) = LOG2_LEVEL_RANGE;
        let (lo, hi) = if near_start {
            (
                (start[axis] - LOG2_LEVEL_STEP).max(lo),
                (start[axis] + LOG2_LEVEL_STEP).min(hi),
            )
        } else {
            (lo, hi)
        };
        // Each step leaves the golden ratio (0.618) of the bracket.
        let steps = ((LOG2_LEVEL_TOLERANCE / (hi - lo)).ln() / 0.618f64.ln()).ceil();
        golden_section(&nll, lo, hi, steps.max(1.0) as usize)
    };
    if threads <= 1 {
        return [0, 1, 2].map(fit_axis);
    }
    std::thread::scope(|scope| {
        let fit_axis = &fit_axis;
        let others: Vec<_> = (1..3)
            .map(|axis| scope.spawn(move || fit_axis(axis)))
            .collect();
        let surge = fit_axis(0);
        let mut levels = [surge, 0.0, 0.0];
        for (axis, handle) in (1..3).zip(others) {
            levels[axis] = handle.join().expect("a level's fit does not panic");
        }
        levels
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_levels_scale_only_the_velocities_noise() {
        let config = DiagnoseConfig::default();
        let scaled = with_velocity_noise_levels(&config, [1.0, -1.0, 2.0]);
        let (q0, q) = (
            config.twin.kinetic.filter.process_noise_density,
            scaled.twin.kinetic.filter.process_noise_density,
        );
        assert_eq!(q[(idx::U, idx::U)], 2.0 * q0[(idx::U, idx::U)]);
        assert_eq!(q[(idx::V, idx::V)], 0.5 * q0[(idx::V, idx::V)]);
        assert_eq!(q[(idx::R, idx::R)], 4.0 * q0[(idx::R, idx::R)]);
        // The coupling by the geometric mean keeps the block positive
        // definite: sqrt(0.5 * 4) = sqrt 2.
        let coupling = q[(idx::V, idx::R)] / q0[(idx::V, idx::R)];
        assert!((coupling - 2f64.sqrt()).abs() < 1e-12);
        assert_eq!(q[(idx::PSI, idx::PSI)], q0[(idx::PSI, idx::PSI)]);
    }

    #[test]
    fn each_axis_goes_to_the_level_the_likelihood_prefers() {
        // A likelihood with its minimum at levels (1/2, 2, 1) over the
        // configured noise, read off the scaled diagonal.
        let config = DiagnoseConfig::default();
        let q0 = config.twin.kinetic.filter.process_noise_density;
        let want = [-1.0, 1.0, 0.0];
        let nll = |c: &DiagnoseConfig| {
            let q = c.twin.kinetic.filter.process_noise_density;
            (0..3)
                .map(|a| {
                    let level = (q[(idx::U + a, idx::U + a)] / q0[(idx::U + a, idx::U + a)]).log2();
                    (level - want[a]).powi(2)
                })
                .sum::<f64>()
        };
        for threads in [1, 2] {
            let got = fitted_velocity_noise_levels(&config, [0.0; 3], false, &nll, threads);
            for a in 0..3 {
                assert!((got[a] - want[a]).abs() < 0.05, "axis {a}: {got:?}");
            }
        }
        // From a start near the minimum, the search stays near it.
        let got = fitted_velocity_noise_levels(&config, [-0.5, 0.5, 0.5], true, &nll, 1);
        for a in 0..3 {
            assert!((got[a] - want[a]).abs() < 0.05, "axis {a}: {got:?}");
        }
    }
}
