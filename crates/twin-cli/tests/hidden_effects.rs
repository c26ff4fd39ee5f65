//! Hidden-effect tests of `twin diagnose`: the
//! simulator hides an effect chosen by a seeded random draw in a trial (a
//! current of random speed and direction, a heading-sensor offset, a SOG
//! scale, GNSS latency, a propeller loss, or nothing), writes the log as the
//! project's JSON lines, and `twin diagnose` reads the log (never the truth)
//! and must name the right cause with its size within 20 %, and nothing on
//! the clean logs.

#[path = "common/hidden.rs"]
mod hidden;
#[path = "common/twin_sim_draws.rs"]
mod twin_sim_draws;

use hidden::{Hidden, describe, judge, named};
use twin_sim_draws::{apply, base, diagnose_scenario, draw, on_two_threads};

use twin_cli::diagnose::DiagnoseReport;

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

#[test]
fn hidden_effects_are_named_with_their_size() {
    let mut rng = StdRng::seed_from_u64(20261121);
    let draws: Vec<(usize, Hidden, u64)> = (0..30)
        .map(|i| (i, draw(&mut rng), rng.random_range(0..1_000_000)))
        .collect();
    let results: Vec<(usize, Hidden, Result<(), String>, String)> =
        on_two_threads(&draws, |(i, h, seed)| {
            let mut sc = base();
            sc.seed = *seed;
            apply(&mut sc, *h);
            let r = diagnose_scenario(&sc, &format!("draw-{i}"));
            (*i, *h, judge(*h, &r), named(&r))
        });
    let mut failures = Vec::new();
    for (i, h, verdict, summary) in &results {
        println!(
            "draw {i:2}: {} -> {summary}{}",
            describe(*h),
            match verdict {
                Ok(()) => String::new(),
                Err(e) => format!("   <-- WRONG: {e}"),
            }
        );
        if verdict.is_err() {
            failures.push(*i);
        }
    }
    let kinds = |f: fn(&Hidden) -> bool| results.iter().filter(|r| f(&r.1)).count();
    println!(
        "{} draws: {} clean, {} current, {} heading offset, {} SOG scale, {} latency, {} loss; wrong: {failures:?}",
        results.len(),
        kinds(|h| matches!(h, Hidden::Nothing)),
        kinds(|h| matches!(h, Hidden::Current { .. })),
        kinds(|h| matches!(h, Hidden::HeadingOffset { .. })),
        kinds(|h| matches!(h, Hidden::SogScale { .. })),
        kinds(|h| matches!(h, Hidden::Latency { .. })),
        kinds(|h| matches!(h, Hidden::Loss { .. })),
    );
    assert!(failures.is_empty(), "wrong diagnoses: {failures:?}");
}

#[test]
fn a_current_and_a_propeller_loss_are_both_named() {
    let mut sc = base();
    sc.seed = 4242;
    apply(
        &mut sc,
        Hidden::Current {
            speed_mps: 0.25,
            toward_deg: 200.0,
        },
    );
    apply(
        &mut sc,
        Hidden::Loss {
            port: false,
            loss: 0.22,
        },
    );
    let r = diagnose_scenario(&sc, "combined");
    for f in &r.findings {
        println!(
            "{} {:?} gain {:.0}",
            f.cause, f.parameters, f.gain.heldout_nll_gain
        );
    }
    let mut causes: Vec<&str> = r.findings.iter().map(|f| f.cause.as_str()).collect();
    causes.sort();
    assert_eq!(causes, ["current", "thruster_loss"]);
    let cur = r.findings.iter().find(|f| f.cause == "current").unwrap();
    let loss = r
        .findings
        .iter()
        .find(|f| f.cause == "thruster_loss")
        .unwrap();
    assert!((cur.parameters["speed_mps"].as_f64().unwrap() - 0.25).abs() <= 0.05);
    assert_eq!(loss.parameters["side"], "starboard");
    assert!((loss.parameters["loss"].as_f64().unwrap() - 0.22).abs() <= 0.044);
}

/// Diagnoses the base trial (seed `seed`) with a loss of `truth` on `side`
/// from `onset_s`: `Err` with what was named unless that loss alone is
/// named, its size within 20 % and its onset within 30 s; else the report.
fn loss_found_with_its_onset(
    seed: u64,
    side: &str,
    truth: f64,
    onset_s: f64,
) -> Result<DiagnoseReport, String> {
    let mut sc = base();
    sc.seed = seed;
    let propeller = if side == "port" {
        &mut sc.propellers.port
    } else {
        &mut sc.propellers.starboard
    };
    propeller.loss = truth;
    propeller.onset_s = onset_s;
    let r = diagnose_scenario(&sc, &format!("loss-from-{onset_s}s"));
    let what = format!(
        "{side} {truth:.3} from {onset_s:.1} s (seed {seed}): {:?}",
        r.findings
    );
    let causes: Vec<&str> = r.findings.iter().map(|f| f.cause.as_str()).collect();
    let [f] = r.findings.as_slice() else {
        return Err(what);
    };
    let loss = f.parameters["loss"].as_f64().unwrap_or(f64::NAN);
    let onset = f.parameters["onset_s"].as_f64().unwrap_or(f64::NAN);
    let within = causes == ["thruster_loss"]
        && f.parameters["side"] == side
        && (loss - truth).abs() <= 0.2 * truth
        && (onset - onset_s).abs() <= 30.0;
    if within { Ok(r) } else { Err(what) }
}

/// A loss that starts mid-log is named with its onset: the time from
/// which the filter's loss estimate stays above half its final value.
#[test]
fn a_loss_that_starts_mid_log_is_found_with_its_onset() {
    loss_found_with_its_onset(777, "port", 0.3, 90.0).unwrap();
}

/// A loss from 120 s has a minute of the training part: the filter's
/// estimate at the split has moved about four fifths of the step. Fitted
/// as a step at its onset, it is named within the same bars.
#[test]
fn a_loss_a_minute_before_the_split_is_sized_as_a_step() {
    loss_found_with_its_onset(779, "port", 0.3, 120.0).unwrap();
}

/// A loss from 160 s has 20 s of the training part: the filter's estimate
/// at the split is a transient, a fraction of the step, which fixed there
/// would judge the held-out part with a fraction of the loss. Its track
/// rose late, so it is fitted as a step on those 20 s.
#[test]
fn a_loss_just_before_the_split_is_sized_as_a_step() {
    loss_found_with_its_onset(780, "starboard", 0.3, 160.0).unwrap();
}

/// A loss that starts in the held-out part (the last 40 % of the log,
/// from 180 s) has nothing to fit in the training part: it is named from
/// the losses the filter tracks through the held-out part, with its onset.
#[test]
fn a_loss_that_starts_in_the_held_out_part_is_found_with_its_onset() {
    let r = loss_found_with_its_onset(778, "starboard", 0.3, 200.0).unwrap();
    // The tracked loss lags the step for a minute; after that, the model
    // explains the held-out data.
    assert!(r.unexplained.is_none(), "{:?}", r.unexplained);
}

/// Losses of 15-40 % from onsets drawn across the log, three in each of
/// four bands: early in the training part (40-110 s), late in it
/// (110-180 s: the filter's estimate at the split at 180 s has not caught
/// up), early in the held-out part (180-240 s) and late in it (240-285 s),
/// on either side: each alone named, within the same bars.
#[test]
fn losses_from_onsets_across_the_log_are_found_with_their_onsets() {
    let mut rng = StdRng::seed_from_u64(20261128);
    let bands_s = [
        (40.0, 110.0),
        (110.0, 180.0),
        (180.0, 240.0),
        (240.0, 285.0),
    ];
    let draws: Vec<(u64, &str, f64, f64)> = bands_s
        .iter()
        .flat_map(|band| [*band; 3])
        .map(|(from_s, to_s)| {
            (
                rng.random_range(1..1_000_000),
                if rng.random_bool(0.5) {
                    "port"
                } else {
                    "starboard"
                },
                rng.random_range(0.15..0.4),
                rng.random_range(from_s..to_s),
            )
        })
        .collect();
    let failures: Vec<String> = on_two_threads(&draws, |(seed, side, truth, onset_s)| {
        loss_found_with_its_onset(*seed, side, *truth, *onset_s).err()
    })
    .into_iter()
    .flatten()
    .collect();
    assert!(failures.is_empty(), "missed: {failures:#?}");
}
