//! Hidden-effect tests of `twin diagnose` on logs from a simulator other than
//! the project's own (docs/accuracy.md, "Hidden effects"): `tests/othersim/otter6dof.py`,
//! an independent 6-DOF Otter written in Python from Fossen's published
//! model (its module doc says what it is and how it differs from `twin-sim`).
//!
//! A seeded random draw in this test, which the diagnosis never sees,
//! chooses one effect per trial and its size from ranges fixed in advance:
//!
//! | effect | range |
//! |---|---|
//! | nothing | |
//! | water current | 0.1-0.4 m/s, toward any direction (0-360 deg) |
//! | heading-sensor offset | 3-10 deg, either sign |
//! | SOG scale | 0.90-0.95 or 1.05-1.10 |
//! | GNSS latency | 0.3-1.0 s |
//! | propeller loss | 0.15-0.40, port or starboard |
//!
//! 36 draws: each block of six holds every kind once, in a random order.
//! The simulator writes the log as the project's JSON lines (and a truth
//! file the test does not read either: the truth is the draw itself),
//! `twin_cli::diagnose::diagnose_path` diagnoses it, and the verdict uses
//! the criteria of `hidden_effects.rs`: exactly the right cause named, its
//! size within 20 % (a current as a vector within 20 % of its speed), and
//! nothing named on the clean logs.
//! A second test hides a current and a propeller loss together and requires
//! both. Others run the draws on changed vessels, with a rate gyro whose
//! scale or bias is off, and without the propeller lines (the hull's own
//! drift named, not a GNSS latency).
//!
//! Needs `python3` on the PATH with NumPy; without them the tests fail with
//! the command that installs them (`python3 -m pip install -r
//! requirements.txt`, part of the README's test command).

#[path = "common/hidden.rs"]
mod hidden;
#[path = "common/perturbed.rs"]
mod perturbed;

use hidden::{Hidden, describe, draw_gyro, judge, named};
use perturbed::{
    Outcome as ChangedOutcome, Perturbation, draw_perturbation, judge_on_vessel, report,
};

use std::path::{Path, PathBuf};
use std::process::Command;

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use twin_cli::diagnose::{DiagnoseReport, diagnose_path};
use twin_core::diagnose::DiagnoseConfig;
use twin_wire::SourceChoice;
use twin_wire::profile::VesselProfile;

/// The independent simulator.
const SIMULATOR: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../tests/othersim/otter6dof.py"
);

/// Draws in the main test.
const DRAWS: usize = 36;

/// The six kinds of effect, in the order `draw` numbers them.
const KINDS: usize = 6;

/// One effect of `kind` (0..6) with a random size.
fn draw(rng: &mut StdRng, kind: usize) -> Hidden {
    let sign = |rng: &mut StdRng| if rng.random_bool(0.5) { 1.0 } else { -1.0 };
    match kind {
        0 => Hidden::Nothing,
        1 => Hidden::Current {
            speed_mps: rng.random_range(0.1..0.4),
            toward_deg: rng.random_range(0.0..360.0),
        },
        2 => Hidden::HeadingOffset {
            offset_deg: sign(rng) * rng.random_range(3.0..10.0),
        },
        3 => Hidden::SogScale {
            scale: 1.0 + sign(rng) * rng.random_range(0.05..0.10),
        },
        4 => Hidden::Latency {
            latency_s: rng.random_range(0.3..1.0),
        },
        _ => Hidden::Loss {
            port: rng.random_bool(0.5),
            loss: rng.random_range(0.15..0.40),
        },
    }
}

/// `DRAWS` effects: each block of six holds every kind once, in a random
/// order, so that every kind is tried equally often.
fn draws(rng: &mut StdRng) -> Vec<(usize, Hidden, u64)> {
    let mut kinds = Vec::with_capacity(DRAWS);
    while kinds.len() < DRAWS {
        let mut block: Vec<usize> = (0..KINDS).collect();
        // Fisher-Yates.
        for i in (1..KINDS).rev() {
            block.swap(i, rng.random_range(0..=i));
        }
        kinds.extend(block);
    }
    kinds
        .into_iter()
        .take(DRAWS)
        .enumerate()
        .map(|(i, kind)| (i, draw(rng, kind), rng.random_range(0..1_000_000)))
        .collect()
}

/// The simulator's arguments for one hidden effect.
fn simulator_args(h: Hidden) -> Vec<String> {
    match h {
        Hidden::Nothing => vec!["--effect".into(), "none".into()],
        Hidden::YawRateScale { scale } => vec![
            "--effect".into(),
            "none".into(),
            "--gyro".into(),
            format!("--gyro-scale={scale}"),
        ],
        Hidden::YawRateBias { bias_deg_s } => vec![
            "--effect".into(),
            "none".into(),
            "--gyro".into(),
            format!("--gyro-bias-deg-s={bias_deg_s}"),
        ],
        Hidden::Current {
            speed_mps,
            toward_deg,
        } => vec![
            "--effect".into(),
            "current".into(),
            "--current-speed-mps".into(),
            format!("{speed_mps}"),
            "--current-toward-deg".into(),
            format!("{toward_deg}"),
        ],
        Hidden::HeadingOffset { offset_deg } => vec![
            "--effect".into(),
            "heading_offset".into(),
            format!("--heading-offset-deg={offset_deg}"),
        ],
        Hidden::SogScale { scale } => vec![
            "--effect".into(),
            "sog_scale".into(),
            "--sog-scale".into(),
            format!("{scale}"),
        ],
        Hidden::Latency { latency_s } => vec![
            "--effect".into(),
            "latency".into(),
            "--latency-s".into(),
            format!("{latency_s}"),
        ],
        Hidden::Loss { port, loss } => vec![
            "--effect".into(),
            "loss".into(),
            "--loss-side".into(),
            if port { "port" } else { "starboard" }.into(),
            "--loss".into(),
            format!("{loss}"),
        ],
    }
}

/// Fails the test, with the command that installs them, unless `python3`
/// runs and imports NumPy: a test that needs a peer never passes without it.
fn require_numpy() {
    let install = "install it with: python3 -m pip install -r requirements.txt";
    match Command::new("python3")
        .args(["-c", "import numpy"])
        .output()
    {
        Err(e) => panic!("python3 cannot be run ({e}): install Python 3, then {install}"),
        Ok(out) => assert!(
            out.status.success(),
            "python3 has no NumPy ({}); {install}",
            String::from_utf8_lossy(&out.stderr)
                .lines()
                .last()
                .unwrap_or("")
                .trim()
        ),
    }
}

/// A fresh directory for this test's logs.
fn work_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("twin-othersim-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Runs the simulator with `effects` and `seed`; returns the log's path.
fn simulate(effects: &[Hidden], seed: u64, dir: &Path, name: &str) -> PathBuf {
    simulate_vessel(effects, None, &[], seed, dir, name)
}

/// The simulator's arguments for a change of the vessel.
fn vessel_args(p: Perturbation) -> Vec<String> {
    let scale = format!("{}", p.scale);
    match p.cause {
        "surge_damping" => vec!["--surge-damping-scale".into(), scale],
        "yaw_damping" => vec!["--yaw-damping-scale".into(), scale],
        _ => vec![
            "--mass-scale".into(),
            scale.clone(),
            "--added-mass-scale".into(),
            scale,
        ],
    }
}

/// [`simulate`] on a vessel changed by `vessel`, where given, with the
/// simulator's further arguments `extra`.
fn simulate_vessel(
    effects: &[Hidden],
    vessel: Option<Perturbation>,
    extra: &[&str],
    seed: u64,
    dir: &Path,
    name: &str,
) -> PathBuf {
    let log = dir.join(format!("{name}.jsonl"));
    let truth = dir.join(format!("{name}.truth.json"));
    let mut cmd = Command::new("python3");
    cmd.arg(SIMULATOR).arg("--seed").arg(seed.to_string());
    for h in effects {
        cmd.args(simulator_args(*h));
    }
    if let Some(p) = vessel {
        cmd.args(vessel_args(p));
    }
    cmd.args(extra);
    cmd.arg("--out").arg(&log).arg("--truth").arg(&truth);
    let out = cmd.output().expect("python3 runs");
    assert!(
        out.status.success(),
        "{SIMULATOR} failed on {name}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    log
}

fn diagnose_log(log: &Path) -> DiagnoseReport {
    diagnose_path(
        log,
        SourceChoice::Best,
        &DiagnoseConfig::default(),
        &VesselProfile::otter(),
    )
    .unwrap()
}

/// `f` over `items` on two threads (the machine has two cores), the
/// items dealt alternately so that both get a mix; the results in the
/// items' order.
fn alternating<T: Sync, R: Send>(items: &[T], f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    let mut results: Vec<(usize, R)> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..2)
            .map(|t| {
                let f = &f;
                s.spawn(move || {
                    items
                        .iter()
                        .enumerate()
                        .filter(|(k, _)| k % 2 == t)
                        .map(|(k, item)| (k, f(item)))
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap())
            .collect()
    });
    results.sort_by_key(|(k, _)| *k);
    results.into_iter().map(|(_, r)| r).collect()
}

/// One draw's outcome.
struct Outcome {
    draw: usize,
    hidden: Hidden,
    /// The simulator's seed.
    seed: u64,
    verdict: Result<(), String>,
    /// What the diagnosis named, as text.
    named: String,
}

#[test]
fn hidden_effects_are_named_on_logs_of_an_independent_simulator() {
    require_numpy();
    let dir = work_dir("draws");
    let mut rng = StdRng::seed_from_u64(20250314);
    let draws = draws(&mut rng);
    let results: Vec<Outcome> = alternating(&draws, |(i, h, seed)| {
        let log = simulate(&[*h], *seed, &dir, &format!("draw-{i:02}"));
        let r = diagnose_log(&log);
        Outcome {
            draw: *i,
            hidden: *h,
            seed: *seed,
            verdict: judge(*h, &r),
            named: named(&r),
        }
    });
    let mut failures = Vec::new();
    println!("| draw | seed | hidden | named by twin diagnose | verdict |");
    println!("|---|---|---|---|---|");
    for o in &results {
        println!(
            "| {:2} | {} | {} | {} | {} |",
            o.draw,
            o.seed,
            describe(o.hidden),
            o.named,
            match &o.verdict {
                Ok(()) => "right".to_string(),
                Err(e) => format!("WRONG: {e}"),
            }
        );
        if o.verdict.is_err() {
            failures.push(o.draw);
        }
    }
    let kinds = |f: fn(&Hidden) -> bool| results.iter().filter(|o| f(&o.hidden)).count();
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
    if failures.is_empty() {
        let _ = std::fs::remove_dir_all(&dir);
    } else {
        println!("logs kept in {}", dir.display());
    }
    assert!(failures.is_empty(), "wrong diagnoses: {failures:?}");
}

#[test]
fn a_current_and_a_propeller_loss_are_both_named_on_the_other_simulator() {
    require_numpy();
    let dir = work_dir("combined");
    let log = simulate(
        &[
            Hidden::Current {
                speed_mps: 0.25,
                toward_deg: 200.0,
            },
            Hidden::Loss {
                port: false,
                loss: 0.22,
            },
        ],
        4242,
        &dir,
        "combined",
    );
    let r = diagnose_log(&log);
    println!("{}", named(&r));
    let mut causes: Vec<&str> = r.findings.iter().map(|f| f.cause.as_str()).collect();
    causes.sort();
    assert_eq!(causes, ["current", "thruster_loss"]);
    let cur = r.findings.iter().find(|f| f.cause == "current").unwrap();
    let loss = r
        .findings
        .iter()
        .find(|f| f.cause == "thruster_loss")
        .unwrap();
    // The current as a vector within 20 % of its speed; the loss within 20 %.
    let (s, d) = (
        cur.parameters["speed_mps"].as_f64().unwrap(),
        cur.parameters["toward_deg"].as_f64().unwrap().to_radians(),
    );
    let t = 200f64.to_radians();
    assert!((s * d.cos() - 0.25 * t.cos()).hypot(s * d.sin() - 0.25 * t.sin()) <= 0.05);
    assert_eq!(loss.parameters["side"], "starboard");
    assert!((loss.parameters["loss"].as_f64().unwrap() - 0.22).abs() <= 0.044);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The hidden effects again, on the independent simulator's vessel changed
/// as in `hidden_effects_perturbed.rs` (`common/perturbed.rs`): two draws
/// in three change its surge damping, its yaw damping, or its mass with
/// its added mass by 1 ± U(0.2, 0.3); the third is the unchanged control.
/// 12 draws, each block of six holding every kind of effect once. The bars
/// are that test's, fixed before the draws; the control draws must meet
/// them, and the verdicts on the changed vessels are printed
/// (docs/accuracy.md, `diagnose-perturbed-othersim`).
#[test]
fn hidden_effects_on_changed_vessels_of_the_independent_simulator() {
    require_numpy();
    let dir = work_dir("perturbed");
    let mut rng = StdRng::seed_from_u64(20261127);
    let draws: Vec<(usize, Hidden, Option<Perturbation>, u64)> = draws(&mut rng)
        .into_iter()
        .take(12)
        .map(|(i, h, seed)| {
            (
                i,
                h,
                (i % 3 != 0).then(|| draw_perturbation(&mut rng)),
                seed,
            )
        })
        .collect();
    let results: Vec<ChangedOutcome> = alternating(&draws, |(i, h, p, seed)| {
        let log = simulate_vessel(&[*h], *p, &[], *seed, &dir, &format!("changed-{i:02}"));
        let r = diagnose_log(&log);
        let verdict = judge_on_vessel(*h, *p, &r);
        (*i, *h, *p, verdict, named(&r))
    });
    let misses = report("diagnose-perturbed-othersim", &results);
    let control_failures = misses.control;
    // One changed-vessel draw is known to miss the bars: a GNSS latency of
    // 0.5 s beside a yaw damping 28 % low, found as a latency of 0.29 s
    // (docs/known-issues.md, "Diagnose": the twin's model of that vessel).
    // Any other miss fails.
    const KNOWN_MISSES: [usize; 1] = [5];
    println!(
        "changed-vessel draws that miss the bars: {:?} (known: {KNOWN_MISSES:?})",
        misses.changed
    );
    let new_misses: Vec<usize> = misses
        .changed
        .iter()
        .copied()
        .filter(|i| !KNOWN_MISSES.contains(i))
        .collect();
    if control_failures.is_empty() && new_misses.is_empty() {
        let _ = std::fs::remove_dir_all(&dir);
    } else {
        println!("logs kept in {}", dir.display());
    }
    assert!(
        control_failures.is_empty(),
        "wrong diagnoses of the unchanged vessel: {control_failures:?}"
    );
    assert!(
        new_misses.is_empty(),
        "changed-vessel draws that miss the bars beyond the known one: {new_misses:?}"
    );
}

/// A rate gyro's scale error or bias on the independent simulator: nine
/// trials with a rate gyro (0.2 deg/s of noise in each fix's line), in turn
/// one reading 1 ± U(0.06, 0.12) times the yaw rate, a true one, and one
/// biased by ± U(0.2, 0.8) deg/s, two in three on a changed vessel. The
/// bars are the other tests': the scale or the bias named alone with its
/// size within 20 %, nothing on a true gyro, a model-parameter finding only
/// for the parameter changed.
#[test]
fn a_rate_gyros_scale_or_bias_is_named_on_the_other_simulator() {
    require_numpy();
    let dir = work_dir("gyro");
    let mut rng = StdRng::seed_from_u64(20261128);
    let draws: Vec<(usize, Hidden, Option<Perturbation>, u64)> = (0..9)
        .map(|i| {
            let h = draw_gyro(&mut rng, i);
            let p = (i % 3 != 0).then(|| draw_perturbation(&mut rng));
            (i, h, p, rng.random_range(0..1_000_000))
        })
        .collect();
    let results: Vec<ChangedOutcome> = alternating(&draws, |(i, h, p, seed)| {
        let log = simulate_vessel(&[*h], *p, &["--gyro"], *seed, &dir, &format!("gyro-{i:02}"));
        let r = diagnose_log(&log);
        let verdict = judge_on_vessel(*h, *p, &r);
        (*i, *h, *p, verdict, named(&r))
    });
    let misses = report("diagnose-gyro-othersim", &results);
    if misses.control.is_empty() && misses.changed.is_empty() {
        let _ = std::fs::remove_dir_all(&dir);
    } else {
        println!("logs kept in {}", dir.display());
    }
    assert!(
        misses.control.is_empty() && misses.changed.is_empty(),
        "wrong diagnoses with a rate gyro: {:?} on the profile's vessel, {:?} on a changed one",
        misses.control,
        misses.changed
    );
}

/// The log at `log` without its propeller lines, as most boats log: what
/// the kinematic water base diagnoses.
fn without_propellers(log: &Path) -> PathBuf {
    let text = std::fs::read_to_string(log).unwrap();
    let kept: String = text
        .lines()
        .filter(|l| !l.contains("\"type\":\"actuators\""))
        .flat_map(|l| [l, "\n"])
        .collect();
    let out = log.with_extension("no-propellers.jsonl");
    std::fs::write(&out, kept).unwrap();
    out
}

/// The simulated hull's own drift in its turns, from the simulator's truth
/// file (its states once a second): the least-squares slope of the sway
/// speed through the water over the yaw rate (`sideslip`), or over the yaw
/// rate times the surge speed, times the mean speed over ground where the
/// vessel is under way (`sideslip_with_speed`, reported at that speed), m/s
/// per rad/s; and that mean speed, m/s.
fn true_drift(truth: &Path, cause: &str) -> (f64, f64) {
    let text = std::fs::read_to_string(truth).unwrap();
    let t: serde_json::Value = serde_json::from_str(&text).unwrap();
    let track = t["track_1hz"].as_array().expect("a track");
    let get = |p: &serde_json::Value, k: &str| p[k].as_f64().expect("a number");
    let (mut vx, mut xx, mut speed, mut under_way) = (0.0, 0.0, 0.0, 0.0);
    for p in track {
        let r = get(p, "r_degps").to_radians();
        let x = if cause == "sideslip" {
            r
        } else {
            r * get(p, "u_water_mps")
        };
        vx += get(p, "v_water_mps") * x;
        xx += x * x;
        if get(p, "sog_mps") >= twin_core::diagnose::UNDER_WAY_MPS {
            speed += get(p, "sog_mps");
            under_way += 1.0;
        }
    }
    let (slope, speed_mps) = (vx / xx, speed / under_way);
    if cause == "sideslip" {
        (slope, speed_mps)
    } else {
        (slope * speed_mps, speed_mps)
    }
}

/// The verdict on a diagnosis of a log without propeller data of the
/// independent simulator, whose receiver is `latency_s` late (0: on time):
/// one finding, the hull's drift (`truth` its truth file), of either shape,
/// within 20 % of the hull's own in that shape; with a latency, either the
/// latency within 20 %, or a drift that bends the course as the hull's and
/// the receiver's together do (at the speed under way, a latency `L` and a
/// drift `k` bend it alike where `L = -k / u`), within 20 %.
fn judge_drift(r: &DiagnoseReport, truth: &Path, latency_s: f64) -> Result<(), String> {
    let [f] = r.findings.as_slice() else {
        return Err("not one finding".into());
    };
    let within = |found: f64, truth: f64| (found - truth).abs() <= 0.2 * truth.abs();
    if f.cause == "gnss_latency" && latency_s > 0.0 {
        let found = f.parameters["latency_s"].as_f64().unwrap();
        return if within(found, latency_s) {
            Ok(())
        } else {
            Err(format!("a latency of {found:.3} s for {latency_s:.3} s"))
        };
    }
    if r.base_model != "water" || !hidden::is_sideslip(&f.cause) {
        return Err("not the hull's drift".into());
    }
    let k = f.parameters["lateral_mps_per_radps"].as_f64().unwrap();
    let (hull, speed_mps) = true_drift(truth, &f.cause);
    let alike = hull - latency_s * speed_mps;
    if within(k, alike) {
        Ok(())
    } else {
        Err(format!(
            "{k:.3} for the hull's {hull:.3} and the receiver's {:.3} m/s per rad/s",
            -latency_s * speed_mps
        ))
    }
}

/// Logs of the independent simulator without their propeller lines: its
/// Otter drifts outward in its turns (its sway speed close to -0.4 s times
/// the surge speed times the yaw rate), which bends the course over ground
/// as a GNSS latency of about 0.4 s does, and the kinematic water base has
/// no sway of its own. Six trials with no hidden effect and two with a GNSS
/// latency of 0.3-0.6 s, two in three on a changed vessel, every other one
/// with a rate gyro. Bars, fixed before the draws: [`judge_drift`]; a clean
/// log names no latency.
#[test]
fn the_hulls_drift_is_named_not_a_latency_on_the_other_simulators_logs_without_propellers() {
    require_numpy();
    let dir = work_dir("no-propellers");
    let mut rng = StdRng::seed_from_u64(20261202);
    let draws: Vec<(usize, Option<Perturbation>, bool, f64, u64)> = (0..8)
        .map(|i| {
            let p = (i % 3 != 0).then(|| draw_perturbation(&mut rng));
            let latency_s = if i < 6 {
                0.0
            } else {
                rng.random_range(0.3..0.6)
            };
            (i, p, i % 2 == 0, latency_s, rng.random_range(0..1_000_000))
        })
        .collect();
    let results: Vec<(usize, Result<(), String>, String)> =
        alternating(&draws, |(i, p, gyro, latency_s, seed)| {
            let extra: &[&str] = if *gyro { &["--gyro"] } else { &[] };
            let name = format!("no-propellers-{i:02}");
            let hidden: Vec<Hidden> = (*latency_s > 0.0)
                .then_some(Hidden::Latency {
                    latency_s: *latency_s,
                })
                .into_iter()
                .collect();
            let log = simulate_vessel(&hidden, *p, extra, *seed, &dir, &name);
            let r = diagnose_log(&without_propellers(&log));
            let truth = dir.join(format!("{name}.truth.json"));
            let verdict = judge_drift(&r, &truth, *latency_s);
            let vessel = p.map_or("the Otter".into(), |p| {
                format!("{} x {:.2}", p.cause, p.scale)
            });
            let what = format!(
                "{vessel}, {}, {}: {}",
                if *gyro { "a rate gyro" } else { "no gyro" },
                hidden
                    .first()
                    .map_or("nothing hidden".into(), |h| describe(*h)),
                named(&r)
            );
            (*i, verdict, what)
        });
    let mut wrong = Vec::new();
    for (i, verdict, what) in &results {
        println!(
            "draw {i}: {what}{}",
            verdict
                .as_ref()
                .err()
                .map_or(String::new(), |e| format!("   <-- WRONG: {e}"))
        );
        if verdict.is_err() {
            wrong.push(*i);
        }
    }
    if wrong.is_empty() {
        let _ = std::fs::remove_dir_all(&dir);
    } else {
        println!("logs kept in {}", dir.display());
    }
    assert!(wrong.is_empty(), "wrong diagnoses: {wrong:?}");
}
