//! Hidden-effect tests of `twin diagnose`: the
//! simulator hides an effect chosen by a seeded random draw in a trial (a
//! current of random speed and direction, a heading-sensor offset, a SOG
//! scale, GNSS latency, a propeller loss, or nothing), writes the log as the
//! project's JSON lines, and `twin diagnose` reads the log (never the truth)
//! and must name the right cause with its size within 20 %, and nothing on
//! the clean logs.

#[path = "common/hidden.rs"]
mod hidden;

use hidden::{Hidden, judge};

use std::io::Cursor;
use std::path::Path;

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use twin_cli::diagnose::{DiagnoseReport, diagnose_loaded, load};
use twin_cli::simulate::{OutputFormat, simulate_to_bytes};
use twin_core::diagnose::DiagnoseConfig;
use twin_sim::{CurrentSpec, Scenario};
use twin_wire::SourceChoice;
use twin_wire::profile::VesselProfile;

fn base() -> Scenario {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../config/scenarios/diagnose_base.toml"
    );
    Scenario::from_toml_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn draw(rng: &mut StdRng) -> Hidden {
    let sign = |rng: &mut StdRng| if rng.random_bool(0.5) { 1.0 } else { -1.0 };
    match rng.random_range(0..6) {
        0 => Hidden::Nothing,
        1 => Hidden::Current {
            speed_mps: rng.random_range(0.1..0.5),
            toward_deg: rng.random_range(0.0..360.0),
        },
        2 => Hidden::HeadingOffset {
            offset_deg: sign(rng) * rng.random_range(2.0..10.0),
        },
        3 => Hidden::SogScale {
            scale: 1.0 + sign(rng) * rng.random_range(0.02..0.08),
        },
        4 => Hidden::Latency {
            latency_s: rng.random_range(0.2..1.0),
        },
        _ => Hidden::Loss {
            port: rng.random_bool(0.5),
            loss: rng.random_range(0.1..0.4),
        },
    }
}

fn apply(sc: &mut Scenario, h: Hidden) {
    match h {
        Hidden::Nothing => {}
        Hidden::Current {
            speed_mps,
            toward_deg,
        } => {
            sc.current = Some(CurrentSpec {
                speed_mps,
                toward_deg,
                rotation_deg_s: 0.0,
                speed_amplitude_mps: 0.0,
                speed_period_s: 600.0,
            })
        }
        Hidden::HeadingOffset { offset_deg } => sc.sensors.heading.offset_deg = offset_deg,
        Hidden::SogScale { scale } => sc.sensors.gnss.sog_scale = scale,
        // The simulator stamps a fix with its true time minus `latency_s`:
        // data older than their stamps is a negative value there.
        Hidden::Latency { latency_s } => sc.sensors.gnss.latency_s = -latency_s,
        Hidden::Loss { port: true, loss } => sc.propellers.port.loss = loss,
        Hidden::Loss { port: false, loss } => sc.propellers.starboard.loss = loss,
    }
}

fn diagnose_scenario(sc: &Scenario, name: &str) -> DiagnoseReport {
    let (bytes, _) = simulate_to_bytes(sc, OutputFormat::JsonLines).unwrap();
    let log = load(Cursor::new(bytes), Path::new(name), SourceChoice::Best).unwrap();
    diagnose_loaded(
        name,
        &log,
        &DiagnoseConfig::default(),
        &VesselProfile::otter(),
    )
    .unwrap()
}

#[test]
fn hidden_effects_are_named_with_their_size() {
    let mut rng = StdRng::seed_from_u64(20261121);
    let draws: Vec<(usize, Hidden, u64)> = (0..30)
        .map(|i| (i, draw(&mut rng), rng.random_range(0..1_000_000)))
        .collect();
    // Two threads: the machine has two cores.
    let results: Vec<(usize, Hidden, Result<(), String>, String)> = std::thread::scope(|s| {
        let handles: Vec<_> = draws
            .chunks(draws.len().div_ceil(2))
            .map(|chunk| {
                s.spawn(move || {
                    chunk
                        .iter()
                        .map(|(i, h, seed)| {
                            let mut sc = base();
                            sc.seed = *seed;
                            apply(&mut sc, *h);
                            let r = diagnose_scenario(&sc, &format!("draw-{i}"));
                            let summary: Vec<String> = r
                                .findings
                                .iter()
                                .map(|f| {
                                    format!(
                                        "{} {:?} (gain {:.0})",
                                        f.cause, f.parameters, f.gain.heldout_nll_gain
                                    )
                                })
                                .collect();
                            (*i, *h, judge(*h, &r), summary.join("; "))
                        })
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap())
            .collect()
    });
    let mut failures = Vec::new();
    for (i, h, verdict, summary) in &results {
        println!(
            "draw {i:2}: {h:?} -> {}{}",
            if summary.is_empty() {
                "no finding"
            } else {
                summary
            },
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
