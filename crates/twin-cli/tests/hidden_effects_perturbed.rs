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
//! The control draws must meet the bars. The draws on a changed vessel do
//! not all meet them yet (docs/known-issues.md, "Diagnose"): their
//! verdicts and the share that meets the bars are printed, and
//! docs/accuracy.md shows them (`diagnose-perturbed`).

#[path = "common/hidden.rs"]
mod hidden;
#[path = "common/twin_sim_draws.rs"]
mod twin_sim_draws;

use hidden::{Hidden, describe, judge, named};
use twin_cli::diagnose::DiagnoseReport;
use twin_sim::VesselSpec;
use twin_sim_draws::{apply, base, diagnose_scenario, draw, on_two_threads};

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

/// The causes that are the vessel's own parameters.
const MODEL_CAUSES: [&str; 3] = ["surge_damping", "yaw_damping", "mass"];

/// The vessel's change in a draw: which model cause it is, and its factor.
#[derive(Debug, Clone, Copy)]
struct Perturbation {
    cause: &'static str,
    scale: f64,
}

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

/// Judges the model-parameter findings against the perturbation; `Ok`
/// says whether the perturbation was named.
fn judge_model(p: Option<Perturbation>, r: &DiagnoseReport) -> Result<bool, String> {
    let mut named = false;
    for f in r
        .findings
        .iter()
        .filter(|f| MODEL_CAUSES.contains(&f.cause.as_str()))
    {
        let scale = f.parameters["scale"].as_f64().unwrap_or(f64::NAN);
        let Some(p) = p.filter(|p| p.cause == f.cause) else {
            return Err(format!("{} {scale:.3} named, not planted", f.cause));
        };
        let (got, want) = (scale - 1.0, p.scale - 1.0);
        if got.signum() != want.signum() || (got - want).abs() > 0.3 * want.abs() {
            return Err(format!("{} {scale:.3}, planted {:.3}", f.cause, p.scale));
        }
        named = true;
    }
    Ok(named)
}

/// A draw's index, effect, change, verdict and what was named.
type Outcome = (
    usize,
    Hidden,
    Option<Perturbation>,
    Result<bool, String>,
    String,
);

/// Simulates, diagnoses and judges one draw.
fn run_draw(i: usize, h: Hidden, p: Option<Perturbation>, seed: u64) -> Outcome {
    let mut sc = base();
    sc.seed = seed;
    apply(&mut sc, h);
    if let Some(p) = p {
        let mut spec = VesselSpec::default();
        perturb(&mut spec, p);
        sc.vessel = Some(spec);
    }
    let r = diagnose_scenario(&sc, &format!("draw-{i}"));
    let mut others = r.clone();
    others
        .findings
        .retain(|f| !MODEL_CAUSES.contains(&f.cause.as_str()));
    let verdict = judge(h, &others).and_then(|()| judge_model(p, &r));
    (i, h, p, verdict, named(&r))
}

#[test]
fn hidden_effects_on_vessels_that_differ_from_their_profile() {
    let mut rng = StdRng::seed_from_u64(20261126);
    let draws: Vec<(usize, Hidden, Option<Perturbation>, u64)> = (0..24)
        .map(|i| {
            let h = draw(&mut rng);
            let p = (i % 3 != 0).then(|| {
                let cause = MODEL_CAUSES[rng.random_range(0..3)];
                let size = rng.random_range(0.2..0.3);
                let scale = if rng.random_bool(0.5) {
                    1.0 + size
                } else {
                    1.0 - size
                };
                Perturbation { cause, scale }
            });
            (i, h, p, rng.random_range(0..1_000_000))
        })
        .collect();
    type Outcome = (
        usize,
        Hidden,
        Option<Perturbation>,
        Result<bool, String>,
        String,
    );
    let results: Vec<Outcome> =
        on_two_threads(&draws, |(i, h, p, seed)| run_draw(*i, *h, *p, *seed));
    let mut control_failures = Vec::new();
    let (mut named, mut perturbed_right) = (0, 0);
    for (i, h, p, verdict, summary) in &results {
        println!(
            "draw {i:2}: {} on {} -> {summary}{}",
            describe(*h),
            p.map_or("the profile's vessel".to_string(), |p| format!(
                "{} x {:.2}",
                p.cause, p.scale
            )),
            match verdict {
                Ok(_) => String::new(),
                Err(e) => format!("   <-- misses the bars: {e}"),
            }
        );
        match (verdict, p) {
            (Ok(n), Some(_)) => {
                perturbed_right += 1;
                named += usize::from(*n);
            }
            (Ok(_), None) => {}
            (Err(_), Some(_)) => {}
            (Err(_), None) => control_failures.push(*i),
        }
    }
    let perturbed = results.iter().filter(|r| r.2.is_some()).count();
    println!(
        "diagnose-perturbed: control draws {} of {} meet the bars; draws on a changed vessel {perturbed_right} of {perturbed} meet the bars, the change named in {named}",
        results.len() - perturbed - control_failures.len(),
        results.len() - perturbed,
    );
    assert!(
        control_failures.is_empty(),
        "wrong diagnoses of the profile's own vessel: {control_failures:?}"
    );
}
