//! `twin-bench`: the side-by-side benchmark command. Parses the command line
//! and calls the library; one subcommand per comparison.
//!
//! ```text
//! cargo run --release -p twin-bench -- numpy     # the AEKF step against NumPy
//! ```

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};
use twin_bench::estimator::{self, NumpyOptions};
use twin_bench::numpy;
use twin_bench::trial::{Adaptation, TrialSpec};

/// Side-by-side performance measurements of the USV twin.
#[derive(Debug, Parser)]
#[command(name = "twin-bench", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Bench,
}

#[derive(Debug, Subcommand)]
enum Bench {
    /// One AEKF step of the seed model in Rust against the same recursion in
    /// NumPy (bench/numpy_aekf.py): ns per step, the ratio, and the largest
    /// difference of the estimates. Exits non-zero if they disagree.
    Numpy(NumpyArgs),
}

#[derive(Debug, Args)]
struct NumpyArgs {
    /// Filter steps in the trial.
    #[arg(long, default_value_t = 3000)]
    steps: usize,
    /// Nominal sample interval, seconds.
    #[arg(long, default_value_t = 0.2)]
    dt: f64,
    /// Seed of the trial's noise, jitter and dropouts.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Q/R adaptation of the filter.
    #[arg(long, value_enum, default_value_t = Adaptation::Off)]
    noise_adaptation: Adaptation,
    /// Timed repeats of the whole trial in Rust.
    #[arg(long, default_value_t = 201)]
    rust_repeats: usize,
    /// Timed repeats of the whole trial in NumPy.
    #[arg(long, default_value_t = 7)]
    numpy_repeats: usize,
    /// The Python interpreter.
    #[arg(long, default_value = "python3")]
    python: String,
    /// The NumPy reference script (default: bench/numpy_aekf.py in this tree).
    #[arg(long)]
    script: Option<PathBuf>,
    /// Where to write the trial and both runs' estimates (default: a
    /// twin-bench-numpy folder in the system's temporary directory).
    #[arg(long)]
    work_dir: Option<PathBuf>,
    /// Largest difference of theta and x accepted.
    #[arg(long, default_value_t = estimator::DEFAULT_TOLERANCE)]
    tolerance: f64,
}

fn run_numpy(args: NumpyArgs) -> anyhow::Result<ExitCode> {
    anyhow::ensure!(args.steps > 0, "--steps must be positive");
    anyhow::ensure!(
        args.dt > 0.0 && args.dt.is_finite(),
        "--dt must be positive"
    );
    let spec = TrialSpec {
        steps: args.steps,
        dt_s: args.dt,
        seed: args.seed,
        adaptation: args.noise_adaptation,
    };
    let defaults = NumpyOptions::default();
    let opts = NumpyOptions {
        python: args.python,
        script: args.script.unwrap_or(defaults.script),
        work_dir: args.work_dir.unwrap_or(defaults.work_dir),
        rust_repeats: args.rust_repeats,
        numpy_repeats: args.numpy_repeats,
        tolerance: args.tolerance,
    };
    if let Some(reason) = numpy::unavailable_reason(&opts.python) {
        anyhow::bail!("{reason}");
    }
    if cfg!(debug_assertions) {
        eprintln!("warning: a debug build; the Rust figures mean little (use --release)");
    }
    let outcome = estimator::compare_with_numpy(&spec, &opts)?;
    print!("{}", outcome.table());
    println!(
        "files: {}, {}, {}",
        outcome.trial_path.display(),
        outcome.rust_path.display(),
        outcome.numpy_path.display()
    );
    if outcome.agrees() {
        Ok(ExitCode::SUCCESS)
    } else {
        eprintln!(
            "error: NumPy and Rust disagree (worst estimate at step {}): {}",
            outcome.difference.worst_step,
            outcome.difference.failures(outcome.tolerance).join("; ")
        );
        Ok(ExitCode::FAILURE)
    }
}

fn main() -> ExitCode {
    let result = match Cli::parse().command {
        Bench::Numpy(args) => run_numpy(args),
    };
    // Printed here, once, without the backtrace anyhow would add under
    // RUST_BACKTRACE: these are setup errors, not bugs.
    result.unwrap_or_else(|e| {
        eprintln!("error: {e:#}");
        ExitCode::from(2)
    })
}
