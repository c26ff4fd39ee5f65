//! The level of the base model's velocity process noise that a log asks
//! for, per axis, and the sizes of the vessel's dynamics and of a rate
//! sensor's scale refitted under it.
//!
//! The search of causes runs its filter with the harbour water's process
//! noise, fixed (`KineticConfig::for_search`, and the water base's random
//! walks): the bars of the selection were set with it. But a likelihood
//! maximised with a process noise that is not the data's does not peak at
//! the parameters' true values. The innovation covariance of a model whose
//! velocities decay faster (a more damped or a lighter hull) is smaller,
//! and so is that of a rate sensor read as measuring less of the yaw rate;
//! where the configured noise is larger than the water's, the
//! log-determinant term rewards that without the model predicting any
//! better: on the profile's own vessel in calm water the fit put the yaw
//! damping at 1.06 and the mass at 0.89 of the profile's, and a true rate
//! gyro's scale at 0.99. The maximum likelihood estimate of such a
//! parameter is consistent once the noise level is estimated with it
//! (Harvey 1989, *Forecasting, Structural Time Series Models and the
//! Kalman Filter*, section 3.4, for a common scale; here one level per
//! axis, surge, sway and yaw, because the water's forces and what the model
//! lacks differ per axis; the water base, which has no sway state, has the
//! surge and yaw axes only).
//!
//! So, once the causes are selected, the sizes of the yaw damping, mass
//! and yaw-rate scale findings are fitted again under the levels the
//! training likelihood prefers with every finding in the model
//! (`fit::refine_sizes_under_fitted_noise`). The selection, the judging on held-out
//! data and the surge damping are left as they are: with the fitted levels
//! in the search itself, causes that imitate a model error (a lever arm, a
//! latency) gained enough to be named on vessels that have neither, and the
//! surge damping shares a ridge with the losses' common part, along which
//! a refit moves both (docs/known-issues.md, "Diagnose").

use super::fit::{BaseModel, DiagnoseConfig, golden_section};
use crate::models::otter_twin::idx;
use crate::models::water_kinematic::idx as water_idx;

/// Each axis's level is searched from 1/16 to 4 times the configured
/// noise, as a power of two ...
const LOG2_LEVEL_RANGE: (f64, f64) = (-4.0, 2.0);
/// ... or, from a level found before, within this many powers of two of it.
const LOG2_LEVEL_STEP: f64 = 1.0;
/// The search's bracket is narrowed to this (a level to within 3 %).
const LOG2_LEVEL_TOLERANCE: f64 = 0.05;

/// The axes (0 surge, 1 sway, 2 yaw) whose velocity is a state of `base`.
pub(super) fn velocity_axes(base: BaseModel) -> &'static [usize] {
    match base {
        BaseModel::Kinetic => &[0, 1, 2],
        BaseModel::Water => &[0, 2],
    }
}

/// `config` with `base`'s velocity process noise density scaled by
/// `2^log2_levels` on the surge, sway and yaw axes: the kinetic base's
/// (the sway-yaw coupling by the geometric mean of its two), or the water
/// base's random walks of its speed through water and yaw rate (its sway
/// is the sideslip's, no state: that level is not used).
pub(super) fn with_velocity_noise_levels(
    config: &DiagnoseConfig,
    base: BaseModel,
    log2_levels: [f64; 3],
) -> DiagnoseConfig {
    let mut scaled = config.clone();
    let levels = log2_levels.map(f64::exp2);
    match base {
        BaseModel::Kinetic => {
            let q = &mut scaled.twin.kinetic.filter.process_noise_density;
            for i in 0..3 {
                for j in 0..3 {
                    q[(idx::U + i, idx::U + j)] *= (levels[i] * levels[j]).sqrt();
                }
            }
        }
        BaseModel::Water => {
            scaled.water_process_noise[water_idx::U] *= levels[0];
            scaled.water_process_noise[water_idx::R] *= levels[2];
        }
    }
    scaled
}

/// The levels (powers of two over `config`'s noise, surge, sway and yaw)
/// that minimise `training_nll`, the training part's negative
/// log-likelihood under a configuration: each of `base`'s axes on its own,
/// with the others at `start` (the axes' levels hardly interact: each is
/// read mostly off its own velocity's innovations), on up to `threads`
/// threads; an axis `base` has no state for stays at its start. With
/// `near_start`, each is searched within [`LOG2_LEVEL_STEP`] of its start.
pub(super) fn fitted_velocity_noise_levels(
    config: &DiagnoseConfig,
    base: BaseModel,
    start: [f64; 3],
    near_start: bool,
    training_nll: &(dyn Fn(&DiagnoseConfig) -> f64 + Sync),
    threads: usize,
) -> [f64; 3] {
    let fit_axis = |axis: usize| {
        let nll = |level: f64| {
            let mut trial = start;
            trial[axis] = level;
            training_nll(&with_velocity_noise_levels(config, base, trial))
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
    let axes = velocity_axes(base);
    let mut levels = start;
    if threads <= 1 {
        for &axis in axes {
            levels[axis] = fit_axis(axis);
        }
        return levels;
    }
    std::thread::scope(|scope| {
        let fit_axis = &fit_axis;
        let others: Vec<_> = axes[1..]
            .iter()
            .map(|&axis| (axis, scope.spawn(move || fit_axis(axis))))
            .collect();
        levels[axes[0]] = fit_axis(axes[0]);
        for (axis, handle) in others {
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
        let scaled = with_velocity_noise_levels(&config, BaseModel::Kinetic, [1.0, -1.0, 2.0]);
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
        assert_eq!(scaled.water_process_noise, config.water_process_noise);
        // The water base: its speed's and yaw rate's random walks.
        let scaled = with_velocity_noise_levels(&config, BaseModel::Water, [1.0, -1.0, 2.0]);
        let (w0, w) = (config.water_process_noise, scaled.water_process_noise);
        for i in 0..7 {
            let factor = match i {
                water_idx::U => 2.0,
                water_idx::R => 4.0,
                _ => 1.0,
            };
            assert_eq!(w[i], factor * w0[i], "state {i}");
        }
        assert_eq!(
            scaled.twin.kinetic.filter.process_noise_density,
            config.twin.kinetic.filter.process_noise_density
        );
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
            let got = fitted_velocity_noise_levels(
                &config,
                BaseModel::Kinetic,
                [0.0; 3],
                false,
                &nll,
                threads,
            );
            for a in 0..3 {
                assert!((got[a] - want[a]).abs() < 0.05, "axis {a}: {got:?}");
            }
        }
        // From a start near the minimum, the search stays near it.
        let got = fitted_velocity_noise_levels(
            &config,
            BaseModel::Kinetic,
            [-0.5, 0.5, 0.5],
            true,
            &nll,
            1,
        );
        for a in 0..3 {
            assert!((got[a] - want[a]).abs() < 0.05, "axis {a}: {got:?}");
        }
    }

    /// On the water base the surge and yaw levels are fitted and the sway
    /// level, which has no state there, stays at its start.
    #[test]
    fn the_water_base_fits_its_surge_and_yaw_levels() {
        let config = DiagnoseConfig::default();
        let w0 = config.water_process_noise;
        let want = [1.0, 0.0, -2.0];
        let nll = |c: &DiagnoseConfig| {
            let w = c.water_process_noise;
            let surge = (w[water_idx::U] / w0[water_idx::U]).log2();
            let yaw = (w[water_idx::R] / w0[water_idx::R]).log2();
            (surge - want[0]).powi(2) + (yaw - want[2]).powi(2)
        };
        for threads in [1, 2] {
            let got = fitted_velocity_noise_levels(
                &config,
                BaseModel::Water,
                [0.0, 0.7, 0.0],
                false,
                &nll,
                threads,
            );
            assert!((got[0] - want[0]).abs() < 0.05, "{got:?}");
            assert_eq!(got[1], 0.7, "no sway state: its start");
            assert!((got[2] - want[2]).abs() < 0.05, "{got:?}");
        }
    }
}
