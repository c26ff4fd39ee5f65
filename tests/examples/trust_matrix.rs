//! The trust matrix as a command: runs draws on both simulators and prints
//! the tables of `twin_tests::trust` (the CI test, `tests/trust_matrix.rs`,
//! runs the default matrix with the same bars; other seeds and sizes are
//! this command's).
//!
//! ```text
//! cargo run --release -p twin-tests --example trust_matrix -- [--own N] [--other N] [--seed S] [--seeds A-B] [--threads T] [--failures] [--trace I [--every S]] [--onsets] [--list] [--known-antenna] [--identified] [--diagnosed] [--gyro all|none] [--gyro-bias-deg-s B] [--hold-gyro-bias] [--calm] [--sensor-noise-scale S] [--gain-sensitivity covariance|exact]
//! ```
//!
//! `--trace I` prints what the twin published over draw `I`, every 10 s
//! (every `S` s with `--every S`), and beside it the filter's profile
//! errors, water current, heading sensor offset and its own losses (before
//! the publication widens their common part);
//! `--onsets` follows each loss of 15 % or more that starts mid-trial
//! through the 30 s after its onset (of the seed, or of each seed with
//! `--seeds`) and prints when it was declared and what stood in the way:
//! the profile's plausibility guard, and the relative loss, its standard
//! deviation and whether it was told, 30 s after the onset;
//! `--list` lists the draws; `--seeds A-B` runs the matrix of each seed
//! from `A` to `B` and prints one row of counts per seed, with the total;
//! `--known-antenna` gives the twin each draw's true antenna position, as
//! a profile that states it does (the twin does not estimate it);
//! `--identified` sails each draw on the profile `twin identify` gives
//! from a healthy trial of the draw's vessel first
//! (`twin_tests::trust::with_identified_profile`); `--diagnosed` on the
//! profile `twin diagnose --out` writes from the same healthy trial (the
//! antenna and the hull's scales the diagnosis finds;
//! `twin_tests::trust::diagnosed_profile`; with `--trace` it prints what
//! was carried);
//! `--gyro all` gives every draw a rate gyro and `--gyro none` none, the
//! draws otherwise the same (vessel, effects, noise): run both to see what
//! a measured yaw rate buys. `--gyro-bias-deg-s B` gives each draw's gyro a
//! bias of B deg/s, its sign alternating from draw to draw (the matrix's
//! own gyros have none); `--hold-gyro-bias` has the twin read every rate
//! sensor as exact (`KineticConfig::estimate_yaw_rate_bias` off) instead
//! of estimating its bias. `--calm` sails every draw in water without
//! random forces (on both simulators), the draws otherwise the same: what
//! an estimate keeps there is the vessel's difference from its profile,
//! and what it loses is the disturbance of the moment.
//! `--sensor-noise-scale S` multiplies the project's simulator's sensor
//! noise by S (the independent simulator keeps its own): with `--calm` on
//! a draw of the Otter itself, what an estimate keeps at the sensors'
//! noise and loses as it goes is the estimator's own bias.
//! `--gain-sensitivity covariance` runs the extended twin's filter with
//! the Kalman gain's part in the faults' sensitivity through the
//! propagated covariance, `--gain-sensitivity exact` with all of it
//! (`twin_core::aekf::GainSensitivity`), `--gain-sensitivity
//! covariance-profile` through the covariance on the profile's errors
//! alone (`AekfConfig::gain_sensitivity_faults`).

use twin_core::aekf::GainSensitivity;
use twin_core::decision::ThrusterStatus;
use twin_core::models::otter_twin;
use twin_core::twin::TwinConfig;
use twin_tests::trust::{
    DETECT_WITHIN_S, Draw, MATRIX_OTHER_DRAWS, MATRIX_OWN_DRAWS, MATRIX_SEED, MUST_DETECT_LOSS,
    diagnosed_profile, matrix_draws, run, run_matrix_with, simulate, with_identified_profile,
    with_known_antenna,
};

/// What the twin is told of each draw's vessel beyond the Otter's profile.
#[derive(Debug, Clone, Copy, Default)]
struct Told {
    /// The antenna's true position.
    antenna: bool,
    /// A profile identified from a healthy trial of the vessel.
    identified: bool,
    /// The profile a diagnosis of a healthy trial of the vessel writes.
    diagnosed: bool,
    /// Every draw with a rate gyro (true) or none (false), in place of
    /// the drawn one.
    gyro: Option<bool>,
    /// Each gyro's bias, deg/s, its sign alternating from draw to draw.
    gyro_bias_deg_s: f64,
    /// The twin reads the rate sensor as exact.
    hold_gyro_bias: bool,
    /// Every draw in water without random forces.
    calm_water: bool,
    /// The project's simulator's sensor noise times this, in place of 1.
    sensor_noise_scale: Option<f64>,
    /// The gain's part in the extended twin's filter's faults' sensitivity.
    gain_sensitivity: GainSensitivity,
    /// That part on the profile's errors alone, not on the losses.
    gain_sensitivity_profile_only: bool,
}

/// The matrix's draws of `seed`, with the gyro `told` sets.
fn draws(own: usize, other: usize, seed: u64, told: Told) -> Vec<Draw> {
    let mut all = matrix_draws(own, other, seed);
    if let Some(gyro) = told.gyro {
        for d in &mut all {
            d.gyro = gyro;
        }
    }
    for (i, d) in all.iter_mut().enumerate() {
        let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
        d.gyro_bias_deg_s = sign * told.gyro_bias_deg_s;
        d.calm_water = told.calm_water;
        if let Some(scale) = told.sensor_noise_scale {
            d.sensor_noise_scale = scale;
        }
    }
    all
}

/// The twin's configuration for `draw`: the default, with what `told`
/// adds. With `say`, what a diagnosed profile carried is printed.
fn config_of(draw: &Draw, told: Told, say: bool) -> Result<TwinConfig, String> {
    let mut config = TwinConfig::default();
    config.kinetic.estimate_yaw_rate_bias = !told.hold_gyro_bias;
    if told.antenna {
        config = with_known_antenna(config, draw);
    }
    if told.diagnosed {
        let diagnosed = diagnosed_profile(&config, draw)?;
        if say {
            println!(
                "diagnosed profile: carried {:?}, not carried {:?}",
                diagnosed.carried, diagnosed.not_carried
            );
        }
        config = diagnosed.profile.twin_config(config);
    }
    if told.identified {
        config = with_identified_profile(config, draw)?;
    }
    config.kinetic.filter.gain_sensitivity = told.gain_sensitivity;
    if told.gain_sensitivity_profile_only {
        config.kinetic.filter.gain_sensitivity_faults = otter_twin::fault::IS_PROFILE;
    }
    Ok(config)
}

/// Reads the option `a` (and its value from `args`) into `told` if it is
/// one of what the twin is told: whether it was.
fn told_option(
    a: &str,
    args: &mut impl Iterator<Item = String>,
    told: &mut Told,
) -> Result<bool, String> {
    match a {
        "--known-antenna" => told.antenna = true,
        "--identified" => told.identified = true,
        "--diagnosed" => told.diagnosed = true,
        "--hold-gyro-bias" => told.hold_gyro_bias = true,
        "--gain-sensitivity" => {
            told.gain_sensitivity = match args.next().as_deref() {
                Some("covariance") => GainSensitivity::ThroughCovariance,
                Some("covariance-profile") => {
                    told.gain_sensitivity_profile_only = true;
                    GainSensitivity::ThroughCovariance
                }
                Some("exact") => GainSensitivity::Exact,
                _ => {
                    return Err(
                        "--gain-sensitivity needs covariance, covariance-profile or exact".into(),
                    );
                }
            }
        }
        "--calm" => told.calm_water = true,
        "--sensor-noise-scale" => {
            let scale = args
                .next()
                .and_then(|v| v.parse::<f64>().ok())
                .filter(|s| s.is_finite() && *s > 0.0)
                .ok_or("--sensor-noise-scale needs a number above 0")?;
            told.sensor_noise_scale = Some(scale);
        }
        "--gyro" => {
            told.gyro = match args.next().as_deref() {
                Some("all") => Some(true),
                Some("none") => Some(false),
                other => return Err(format!("--gyro needs all or none, got {other:?}")),
            }
        }
        "--gyro-bias-deg-s" => {
            told.gyro_bias_deg_s = args
                .next()
                .and_then(|v| v.parse::<f64>().ok())
                .filter(|b| b.is_finite())
                .ok_or("--gyro-bias-deg-s needs a number")?;
        }
        _ => return Ok(false),
    }
    Ok(true)
}

fn main() -> Result<(), String> {
    let mut own = MATRIX_OWN_DRAWS;
    let mut other = MATRIX_OTHER_DRAWS;
    let mut seed = MATRIX_SEED;
    let mut threads = 2;
    let mut failures = false;
    let mut trace: Option<usize> = None;
    let mut every_s = 10.0;
    let mut list = false;
    let mut onsets = false;
    let mut told = Told::default();
    let mut seeds: Option<(u64, u64)> = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        if told_option(&a, &mut args, &mut told)? {
            continue;
        }
        let mut value = |name: &str| {
            args.next()
                .and_then(|v| v.parse::<u64>().ok())
                .ok_or(format!("{name} needs a number"))
        };
        match a.as_str() {
            "--own" => own = value("--own")? as usize,
            "--other" => other = value("--other")? as usize,
            "--seed" => seed = value("--seed")?,
            "--threads" => threads = value("--threads")? as usize,
            "--failures" => failures = true,
            "--list" => list = true,
            "--onsets" => onsets = true,
            "--trace" => trace = Some(value("--trace")? as usize),
            "--every" => every_s = value("--every")? as f64,
            "--seeds" => {
                let text = args.next().unwrap_or_default();
                let range = text
                    .split_once('-')
                    .and_then(|(a, b)| Some((a.parse().ok()?, b.parse().ok()?)))
                    .filter(|(a, b)| a <= b);
                seeds = Some(range.ok_or(format!("--seeds needs A-B, got {text:?}"))?);
            }
            _ => return Err(format!("unknown argument {a}")),
        }
    }
    if onsets {
        let range = seeds.unwrap_or((seed, seed));
        return print_onsets(own, other, range.0..=range.1, told);
    }
    if let Some((first, last)) = seeds {
        return print_seeds(own, other, first..=last, threads, failures, told);
    }
    let all = draws(own, other, seed, told);
    if list {
        for d in &all {
            println!("{}", d.describe());
        }
        return Ok(());
    }
    if let Some(i) = trace {
        let draw = all
            .iter()
            .find(|d| d.index == i)
            .ok_or(format!("no draw {i}"))?;
        return print_trace(draw, config_of(draw, told, true)?, every_s);
    }
    let matrix = run_matrix_with(&all, threads, |d| config_of(d, told, false))?;
    println!(
        "Trust matrix: {own} draws on twin-sim, {other} on the independent simulator (seed {seed})."
    );
    println!();
    print!("{}", matrix.report());
    if failures {
        println!();
        for f in matrix.failures() {
            println!("- {f}");
        }
    }
    Ok(())
}

/// Runs the matrix of each seed in `seeds` and prints a row of counts per
/// seed and their total; with `failures`, each seed's failed draws after.
fn print_seeds(
    own: usize,
    other: usize,
    seeds: std::ops::RangeInclusive<u64>,
    threads: usize,
    failures: bool,
    told: Told,
) -> Result<(), String> {
    println!(
        "Trust matrix per seed: {own} draws on twin-sim, {other} on the independent simulator each."
    );
    println!();
    println!(
        "| seed | draws | healthy propellers | false FAULTs | losses >= 0.15 | not declared in time | flapping | late onsets | losses ending nominal | healthy ending not_excited | mid-trial losses >= 0.2 on a manoeuvring vessel | declared within 15 s |"
    );
    println!("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    let mut total = [0usize; 11];
    let mut failed = Vec::new();
    for seed in seeds {
        let matrix = run_matrix_with(&draws(own, other, seed, told), threads, |d| {
            config_of(d, told, false)
        })?;
        let (goal_in_time, goal_losses) = matrix.goal_detections();
        let row = [
            matrix.draws(),
            matrix.healthy_propellers(),
            matrix.false_faults(),
            matrix.losses_to_detect(),
            matrix.missed(),
            matrix.flapping(),
            matrix.late_onsets(),
            matrix.losses_ending_nominal(),
            matrix.healthy_ending_not_excited(),
            goal_losses,
            goal_in_time,
        ];
        for (t, r) in total.iter_mut().zip(row) {
            *t += r;
        }
        let cells: Vec<String> = row.iter().map(ToString::to_string).collect();
        println!("| {seed} | {} |", cells.join(" | "));
        if failures {
            failed.extend(
                matrix
                    .failures()
                    .into_iter()
                    .map(|f| format!("seed {seed} {f}")),
            );
        }
    }
    let cells: Vec<String> = total.iter().map(ToString::to_string).collect();
    println!("| all | {} |", cells.join(" | "));
    if failures {
        println!();
        for f in failed {
            println!("- {f}");
        }
    }
    Ok(())
}

/// Prints what the twin published over `draw`, every `every_s`, with the
/// filter's profile errors, water current, heading sensor offset and own
/// losses.
fn print_trace(draw: &Draw, config: TwinConfig, every_s: f64) -> Result<(), String> {
    println!("{}", draw.describe());
    let trial = twin_tests::trust::simulate(draw)?;
    let record = twin_tests::trust::run(&trial, config);
    let mut next = 0.0;
    for s in &record.samples {
        if s.elapsed_s < next {
            continue;
        }
        next = s.elapsed_s.floor() + every_s;
        let r = &s.report;
        let side = |k: usize| {
            let t = r.thrusters[k];
            format!(
                "{:+.3}±{:.3}{} rel {:+.3}±{:.3}{} {}",
                t.loss,
                t.sigma,
                if t.excited { "*" } else { " " },
                t.relative_loss,
                t.relative_sigma,
                if t.relative_excited { "*" } else { " " },
                t.decision.status.name()
            )
        };
        let damping = r
            .profile_errors
            .map(|d| {
                format!(
                    "du {:+.2}±{:.2} dr {:+.2}±{:.2} dk {:+.2}±{:.2} dm {:+.2}±{:.2}",
                    d[0].0, d[0].1, d[1].0, d[1].1, d[2].0, d[2].1, d[3].0, d[3].1
                )
            })
            .unwrap_or_default();
        let mismatch = r
            .profile_mismatch
            .map(|m| {
                format!(
                    "  mismatch: yaw damping {:+.2} (bound {:.2}), mass {:+.2} (bound {:.2}), thrust {:+.2} (bound {:.2}), NIS/dof {:.2} (bound {:.2})",
                    m.yaw_damping_error,
                    m.yaw_damping_bound,
                    m.mass_error,
                    m.mass_bound,
                    m.thrust_error,
                    m.thrust_bound,
                    m.nis_per_dof,
                    m.max_nis_per_dof
                )
            })
            .unwrap_or_default();
        let filter = s
            .filter
            .map(|f| {
                let [n, e] = f.current_mps;
                let [(lp, sp), (ls, ss)] = f.losses;
                format!(
                    " current n {n:+.2} e {e:+.2} m/s, heading offset {:+.1} deg, filter losses {lp:+.2}±{sp:.2} {ls:+.2}±{ss:.2}",
                    f.heading_offset_rad.to_degrees()
                )
            })
            .unwrap_or_default();
        println!(
            "{:6.1} s  port {}  stb {}  {damping}{filter}{mismatch}",
            s.elapsed_s,
            side(0),
            side(1)
        );
    }
    Ok(())
}

/// What one mid-trial loss looked like over the [`DETECT_WITHIN_S`] after
/// its onset.
struct OnsetWindow {
    /// The draw, described.
    draw: String,
    /// The loss.
    loss: f64,
    /// From its onset to its FAULT, s (none: never declared).
    declared_after_s: Option<f64>,
    /// Whether the profile's plausibility guard was out just before the
    /// onset.
    guard_out_before: bool,
    /// The share of the window's reports with the guard out.
    guard_out_share: f64,
    /// The relative loss at the window's end, its standard deviation, and
    /// whether it was told, or told weakly.
    relative: (f64, f64, bool, bool),
}

/// Follows the loss of `draw` (of the matrix of `seed`; the loss must
/// start mid-trial) through its window.
fn onset_window(seed: u64, draw: &Draw, told: Told) -> Result<OnsetWindow, String> {
    let trial = simulate(draw)?;
    let record = run(&trial, config_of(draw, told, false)?);
    let k = usize::from(draw.loss[0] < draw.loss[1]);
    let onset_s = draw.onset_s;
    let end_s = onset_s + DETECT_WITHIN_S;
    let report_at = |t: f64| {
        record
            .samples
            .iter()
            .find(|s| s.elapsed_s >= t)
            .map(|s| s.report)
    };
    let window: Vec<_> = record
        .samples
        .iter()
        .filter(|s| s.elapsed_s >= onset_s && s.elapsed_s <= end_s)
        .collect();
    let guard_out = window
        .iter()
        .filter(|s| s.report.profile_mismatch.is_some())
        .count();
    let relative = report_at(end_s)
        .map(|r| {
            let t = r.thrusters[k];
            (
                t.relative_loss,
                t.relative_sigma,
                t.relative_excited,
                t.relative_weakly_told,
            )
        })
        .unwrap_or((f64::NAN, f64::NAN, false, false));
    Ok(OnsetWindow {
        draw: format!("matrix seed {seed}, {}", draw.describe()),
        loss: draw.loss[k],
        declared_after_s: record
            .samples
            .iter()
            .find(|s| {
                s.elapsed_s >= onset_s
                    && s.report.thrusters[k].decision.status == ThrusterStatus::Fault
            })
            .map(|s| s.elapsed_s - onset_s),
        guard_out_before: report_at(onset_s - 1.0).is_some_and(|r| r.profile_mismatch.is_some()),
        guard_out_share: guard_out as f64 / window.len().max(1) as f64,
        relative,
    })
}

/// Prints [`onset_window`] for every loss of at least [`MUST_DETECT_LOSS`]
/// that starts mid-trial in the matrices of `seeds`, and the counts.
fn print_onsets(
    own: usize,
    other: usize,
    seeds: std::ops::RangeInclusive<u64>,
    told: Told,
) -> Result<(), String> {
    let draws: Vec<(u64, Draw)> = seeds
        .flat_map(|seed| {
            draws(own, other, seed, told)
                .into_iter()
                .map(move |d| (seed, d))
        })
        .filter(|(_, d)| d.onset_s > 0.0 && d.loss.iter().any(|l| *l >= MUST_DETECT_LOSS))
        .collect();
    let windows: Vec<OnsetWindow> = std::thread::scope(|scope| {
        let workers: Vec<_> = draws
            .chunks(draws.len().div_ceil(2).max(1))
            .map(|chunk| {
                scope.spawn(move || {
                    chunk
                        .iter()
                        .map(|(seed, d)| onset_window(*seed, d, told))
                        .collect::<Result<Vec<_>, String>>()
                })
            })
            .collect();
        workers
            .into_iter()
            .map(|w| w.join().expect("a worker finishes"))
            .collect::<Result<Vec<Vec<_>>, String>>()
    })?
    .into_iter()
    .flatten()
    .collect();
    println!(
        "| draw | loss | FAULT after (s) | guard out before the onset | guard out over the {DETECT_WITHIN_S:.0} s after | relative loss {DETECT_WITHIN_S:.0} s after | told |"
    );
    println!("|---|---:|---:|---|---:|---|---|");
    for w in &windows {
        let (rel, sigma, excited, weak) = w.relative;
        println!(
            "| {} | {:.2} | {} | {} | {:.2} | {rel:+.3} +- {sigma:.3} | {} |",
            w.draw,
            w.loss,
            w.declared_after_s
                .map_or("never".to_string(), |d| format!("{d:.0}")),
            if w.guard_out_before { "yes" } else { "no" },
            w.guard_out_share,
            if excited {
                "yes"
            } else if weak {
                "weakly"
            } else {
                "no"
            }
        );
    }
    let count = |f: &dyn Fn(&OnsetWindow) -> bool| windows.iter().filter(|w| f(w)).count();
    let in_time = |w: &OnsetWindow| w.declared_after_s.is_some_and(|d| d <= DETECT_WITHIN_S);
    println!();
    println!(
        "{} losses starting mid-trial: FAULT within {DETECT_WITHIN_S:.0} s {}, ever {}; the guard out for most of the window {} (tripped after the onset {}); of the rest not in time, the relative loss told {} and not told {} at the window's end",
        windows.len(),
        count(&in_time),
        count(&|w| w.declared_after_s.is_some()),
        count(&|w| w.guard_out_share >= 0.5),
        count(&|w| w.guard_out_share >= 0.5 && !w.guard_out_before),
        count(&|w| !in_time(w) && w.guard_out_share < 0.5 && w.relative.2),
        count(&|w| !in_time(w) && w.guard_out_share < 0.5 && !w.relative.2),
    );
    Ok(())
}
