//! The trust matrix as a command: runs draws on both simulators and prints
//! the tables of `twin_tests::trust` (the CI test, `tests/trust_matrix.rs`,
//! runs the default matrix with the same bars; other seeds and sizes are
//! this command's).
//!
//! ```text
//! cargo run --release -p twin-tests --example trust_matrix -- [--own N] [--other N] [--seed S] [--seeds A-B] [--threads T] [--failures] [--trace I] [--list] [--known-antenna] [--identified]
//! ```
//!
//! `--trace I` prints what the twin published over draw `I`, every 10 s;
//! `--list` lists the draws; `--seeds A-B` runs the matrix of each seed
//! from `A` to `B` and prints one row of counts per seed, with the total;
//! `--known-antenna` gives the twin each draw's true antenna position, as
//! a profile that states it does (the twin does not estimate it);
//! `--identified` sails each draw on the profile `twin identify` gives
//! from a healthy trial of the draw's vessel first
//! (`twin_tests::trust::with_identified_profile`).

use twin_core::twin::TwinConfig;
use twin_tests::trust::{
    Draw, MATRIX_OTHER_DRAWS, MATRIX_OWN_DRAWS, MATRIX_SEED, matrix_draws, run_matrix_with,
    with_identified_profile, with_known_antenna,
};

/// What the twin is told of each draw's vessel beyond the Otter's profile.
#[derive(Debug, Clone, Copy, Default)]
struct Told {
    /// The antenna's true position.
    antenna: bool,
    /// A profile identified from a healthy trial of the vessel.
    identified: bool,
}

/// The twin's configuration for `draw`: the default, with what `told`
/// adds.
fn config_of(draw: &Draw, told: Told) -> Result<TwinConfig, String> {
    let mut config = TwinConfig::default();
    if told.antenna {
        config = with_known_antenna(config, draw);
    }
    if told.identified {
        config = with_identified_profile(config, draw)?;
    }
    Ok(config)
}

fn main() -> Result<(), String> {
    let mut own = MATRIX_OWN_DRAWS;
    let mut other = MATRIX_OTHER_DRAWS;
    let mut seed = MATRIX_SEED;
    let mut threads = 2;
    let mut failures = false;
    let mut trace: Option<usize> = None;
    let mut list = false;
    let mut told = Told::default();
    let mut seeds: Option<(u64, u64)> = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
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
            "--known-antenna" => told.antenna = true,
            "--identified" => told.identified = true,
            "--trace" => trace = Some(value("--trace")? as usize),
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
    if let Some((first, last)) = seeds {
        return print_seeds(own, other, first..=last, threads, failures, told);
    }
    let all = matrix_draws(own, other, seed);
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
        return print_trace(draw, config_of(draw, told)?);
    }
    let matrix = run_matrix_with(&all, threads, |d| config_of(d, told))?;
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
        "| seed | draws | healthy propellers | false FAULTs | losses >= 0.15 | not declared in time | flapping | late onsets | losses ending nominal | healthy ending not_excited |"
    );
    println!("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    let mut total = [0usize; 9];
    let mut failed = Vec::new();
    for seed in seeds {
        let matrix = run_matrix_with(&matrix_draws(own, other, seed), threads, |d| {
            config_of(d, told)
        })?;
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

/// Prints what the twin published over `draw`, every 10 s.
fn print_trace(draw: &Draw, config: TwinConfig) -> Result<(), String> {
    println!("{}", draw.describe());
    let trial = twin_tests::trust::simulate(draw)?;
    let record = twin_tests::trust::run(&trial, config);
    let mut next = 0.0;
    for s in &record.samples {
        if s.elapsed_s < next {
            continue;
        }
        next = s.elapsed_s.floor() + 10.0;
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
                    "  mismatch: yaw damping {:+.2} (bound {:.2}), mass {:+.2} (bound {:.2}), NIS/dof {:.2} (bound {:.2})",
                    m.yaw_damping_error,
                    m.yaw_damping_bound,
                    m.mass_error,
                    m.mass_bound,
                    m.nis_per_dof,
                    m.max_nis_per_dof
                )
            })
            .unwrap_or_default();
        println!(
            "{:6.1} s  port {}  stb {}  {damping}{mismatch}",
            s.elapsed_s,
            side(0),
            side(1)
        );
    }
    Ok(())
}
