//! Hidden-effect tests of `twin diagnose` on vessels that are not exactly
//! their profile: each draw hides one effect, as in `hidden_effects.rs`,
//! and two draws in three also change the simulated vessel itself: one of
//! its surge damping, yaw damping or mass (with its added mass) by a
//! factor of 1 ± U(0.2, 0.3); the third draw is the unperturbed control.
//!
//! Bars, fixed before the draws (the diagnose-truth issue's): the hidden
//! effect named with its size within 20 % and no other sensor, environment
//! or propeller cause (nothing on a clean log); a model-parameter finding
//! only for the parameter that was changed, in its direction, its size
//! (scale - 1) within 30 %; no model-parameter finding on a control draw.
//!
//! Every draw must meet the bars, on the changed vessels as on the control
//! draws. The verdicts and the share that meets the bars are printed, and
//! docs/accuracy.md shows them (`diagnose-perturbed`). The sizes of the
//! yaw damping and mass findings rely on their refit under the process
//! noise the data ask for (`twin_core::diagnose`, `noise_level`): without
//! it a yaw damping 23 % high beside a current is named 35 % high.

#[path = "common/hidden.rs"]
mod hidden;
#[path = "common/perturbed.rs"]
mod perturbed;
#[path = "common/twin_sim_draws.rs"]
mod twin_sim_draws;

use hidden::{Hidden, draw_gyro, named};
use perturbed::{Outcome, Perturbation, draw_perturbation, judge_on_vessel, report};
use twin_sim::VesselSpec;
use twin_sim_draws::{apply, base, diagnose_scenario, draw, on_two_threads};

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

fn perturb(spec: &mut VesselSpec, p: Perturbation) {
    match p.cause {
        "surge_damping" => spec.surge_damping_scale = p.scale,
        "yaw_damping" => spec.yaw_damping_scale = p.scale,
        _ => {
            spec.mass_scale = p.scale;
            spec.added_mass_scale = p.scale;
        }
    }
}

/// Simulates, diagnoses and judges one draw (the trial with a rate gyro
/// of 0.2 deg/s noise at 10 Hz where `gyro`).
fn run_draw(i: usize, h: Hidden, p: Option<Perturbation>, seed: u64, gyro: bool) -> Outcome {
    let mut sc = base();
    sc.seed = seed;
    sc.sensors.yaw_rate.enabled = gyro;
    apply(&mut sc, h);
    if let Some(p) = p {
        let mut spec = VesselSpec::default();
        perturb(&mut spec, p);
        sc.vessel = Some(spec);
    }
    let kind = if gyro { "gyro-draw" } else { "draw" };
    let r = diagnose_scenario(&sc, &format!("{kind}-{i}"));
    let verdict = judge_on_vessel(h, p, &r);
    (i, h, p, verdict, named(&r))
}

#[test]
fn hidden_effects_on_vessels_that_differ_from_their_profile() {
    let mut rng = StdRng::seed_from_u64(20261126);
    let draws: Vec<(usize, Hidden, Option<Perturbation>, u64)> = (0..24)
        .map(|i| {
            let h = draw(&mut rng);
            let p = (i % 3 != 0).then(|| draw_perturbation(&mut rng));
            (i, h, p, rng.random_range(0..1_000_000))
        })
        .collect();
    let results: Vec<Outcome> =
        on_two_threads(&draws, |(i, h, p, seed)| run_draw(*i, *h, *p, *seed, false));
    let misses = report("diagnose-perturbed", &results);
    assert!(
        misses.control.is_empty(),
        "wrong diagnoses of the profile's own vessel: {:?}",
        misses.control
    );
    assert!(
        misses.changed.is_empty(),
        "wrong diagnoses of a changed vessel: {:?}",
        misses.changed
    );
}

/// A rate gyro whose scale is off is named by its scale, one that is biased
/// by its bias, and a true one is not named, on vessels that differ from
/// their profile: twelve trials with a rate gyro, in turn one reading
/// 1 ± U(0.06, 0.12) times the yaw rate, a true one, and one biased by
/// ± U(0.2, 0.8) deg/s, two in three on a changed vessel. The bars are the
/// test's above.
/// Below an error of about 0.06 the 20 % bar is within the twin's own bias
/// on this simulator's vessel (a gyro reading true is fitted at 0.99:
/// docs/known-issues.md, "Diagnose").
#[test]
fn a_rate_gyros_scale_or_bias_is_named_and_a_true_gyro_is_not() {
    let mut rng = StdRng::seed_from_u64(20261128);
    let draws: Vec<(usize, Hidden, Option<Perturbation>, u64)> = (0..12)
        .map(|i| {
            let h = draw_gyro(&mut rng, i);
            let p = (i % 3 != 0).then(|| draw_perturbation(&mut rng));
            (i, h, p, rng.random_range(0..1_000_000))
        })
        .collect();
    let results: Vec<Outcome> =
        on_two_threads(&draws, |(i, h, p, seed)| run_draw(*i, *h, *p, *seed, true));
    let misses = report("diagnose-gyro", &results);
    assert!(
        misses.control.is_empty() && misses.changed.is_empty(),
        "wrong diagnoses with a rate gyro: {:?} on the profile's vessel, {:?} on a changed one",
        misses.control,
        misses.changed
    );
}
