//! `twin-bench`: the side-by-side benchmark command. Parses the command line
//! and calls the library; one subcommand per comparison.
//!
//! ```text
//! cargo run --release -p twin-bench -- numpy     # the AEKF step against NumPy
//! cargo run --release -p twin-bench -- core      # estimator and offline path, with targets
//! cargo run --release -p twin-bench -- daemon    # twind under load against raw Zenoh
//! cargo run --release -p twin-bench -- flood     # a real vessel's latency under a flood of new ids
//! cargo run --release -p twin-bench -- cold-start   # 1,000 / 3,000 / 10,000 vessels starting at once
//! cargo run --release -p twin-bench -- soak     # a fleet through the daemon for 24 h of vessel time
//! ```

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};
use twin_bench::core::CoreOptions;
use twin_bench::daemon::DaemonOptions;
use twin_bench::daemon::load::{self, PointSpec};
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
    /// The estimator and the offline path in one table with the project's
    /// targets: the seed and extended AEKF steps, NumPy and the ratio, the
    /// whole twin per fix, the forecast, a 120 s trial, parsing per format
    /// (MB/s) and a 4-hour log analysed offline.
    Core(CoreArgs),
    /// twind under load against raw Zenoh, in-process on loopback: N
    /// vessels x R Hz of GNSS fixes and shaft speeds; throughput, p50/p99/max
    /// latency GNSS publish -> fault receive, CPU, RSS and memory per vessel;
    /// 10 to 10,000 vessels; each path's maximum sustained rate and their
    /// ratio. One table with the project's targets.
    Daemon(DaemonArgs),
    /// One real vessel's fix -> fault latency (p50/p99/max) and the
    /// process's memory before, during and after a burst of messages on new
    /// vessel ids (default 10,000 one-byte payloads), and the liveliness
    /// tokens left behind.
    Flood(FloodArgs),
    /// One point of `daemon`, run in a child process; prints one JSON line.
    #[command(hide = true)]
    DaemonPoint(DaemonPointArgs),
    /// A whole fleet starting at once: the time from the first message to
    /// the first fault of every vessel, for 1,000, 3,000 and 10,000
    /// vessels (each sending a fix and its shaft speeds once a second).
    ColdStart(ColdStartArgs),
    /// One point of `cold-start`, run in a child process; prints one JSON line.
    #[command(hide = true)]
    ColdStartPoint(ColdStartPointArgs),
    /// A fleet through the daemon for a day of vessel time at high speed:
    /// every vessel-hour the memory, the counts received, refused and
    /// rejected, a healthy vessel's loss estimates (drift from 0) and whether
    /// the covariances stayed positive definite.
    Soak(SoakArgs),
}

#[derive(Debug, Args)]
struct SoakArgs {
    /// Vessels.
    #[arg(long, default_value_t = 2)]
    vessels: usize,
    /// Hours of vessel time.
    #[arg(long, default_value_t = 24.0)]
    hours: f64,
    /// Fixes per second of vessel time, per vessel (a GNSS receiver's 10 Hz;
    /// at 1 Hz the twin's gates reject many fixes of the benchmark's turn).
    #[arg(long, default_value_t = 10.0)]
    rate_hz: f64,
}

fn run_soak(args: SoakArgs) -> anyhow::Result<ExitCode> {
    if cfg!(debug_assertions) {
        eprintln!("warning: a debug build; the figures mean little (use --release)");
    }
    let opts = twin_bench::soak::SoakOptions {
        vessels: args.vessels,
        hours: args.hours,
        rate_hz: args.rate_hz,
    };
    let soak = twin_bench::soak::run(&opts)?;
    print!("{}", twin_bench::soak::table(&opts, &soak));
    Ok(ExitCode::SUCCESS)
}

#[derive(Debug, Args)]
struct ColdStartArgs {
    /// Fleet sizes (comma-separated; default 1000,3000,10000).
    #[arg(long, value_delimiter = ',')]
    vessels: Option<Vec<usize>>,
    /// Run the daemon with `publish.vessel_liveliness = false`.
    #[arg(long)]
    no_vessel_liveliness: bool,
}

#[derive(Debug, Args)]
struct ColdStartPointArgs {
    #[arg(long)]
    vessels: usize,
    #[arg(long)]
    no_vessel_liveliness: bool,
}

fn run_cold_start(args: ColdStartArgs) -> anyhow::Result<ExitCode> {
    if cfg!(debug_assertions) {
        eprintln!("warning: a debug build; the figures mean little (use --release)");
    }
    let fleets = args
        .vessels
        .unwrap_or_else(|| twin_bench::daemon::cold_start::FLEETS.to_vec());
    let table = twin_bench::daemon::cold_start::run(
        &std::env::current_exe()?,
        &fleets,
        !args.no_vessel_liveliness,
    )?;
    print!("{table}");
    Ok(ExitCode::SUCCESS)
}

fn run_cold_start_point(args: ColdStartPointArgs) -> anyhow::Result<ExitCode> {
    let point = twin_bench::daemon::cold_start::point(args.vessels, !args.no_vessel_liveliness)?;
    println!("{}", serde_json::to_string(&point)?);
    use std::io::Write as _;
    std::io::stdout().flush()?;
    // Sessions still closing in the background: leave now.
    std::process::exit(0);
}

#[derive(Debug, Args)]
struct DaemonArgs {
    /// Two fleet sizes, 3 s windows: a smoke test, not a measurement.
    #[arg(long)]
    quick: bool,
    /// Fleet sizes of the scaling table (comma-separated; default
    /// 10,100,1000,10000, with --quick 10,1000).
    #[arg(long, value_delimiter = ',')]
    vessels: Option<Vec<usize>>,
    /// Fixes per second per vessel in the scaling table.
    #[arg(long, default_value_t = 10.0)]
    rate_hz: f64,
    /// Measurement window of each scaling point, s (default 10, with --quick 3).
    #[arg(long)]
    window_s: Option<f64>,
    /// Least warm-up before each window, s (default 5, with --quick 1).
    #[arg(long)]
    warmup_s: Option<f64>,
    /// Fleet of the flat-out runs.
    #[arg(long, default_value_t = twin_bench::daemon::HEADLINE_VESSELS)]
    saturation_vessels: usize,
    /// Run the daemon with `publish.vessel_liveliness = false` (no token per
    /// vessel under the prefix).
    #[arg(long)]
    no_vessel_liveliness: bool,
    /// Declare the tokens at `asv-twins/alive/{vessel}`, outside the data prefix
    /// (`publish.vessel_liveliness_key`), instead of the contract's key.
    #[arg(long, conflicts_with = "no_vessel_liveliness")]
    liveliness_outside_prefix: bool,
}

fn run_daemon(args: DaemonArgs) -> anyhow::Result<ExitCode> {
    if cfg!(debug_assertions) {
        eprintln!("warning: a debug build; the figures mean little (use --release)");
    }
    let mut opts = DaemonOptions::new(args.quick, std::env::current_exe()?);
    if let Some(v) = args.vessels {
        anyhow::ensure!(
            !v.is_empty() && v.iter().all(|&n| (1..=99_999).contains(&n)),
            "--vessels: 1 to 99,999 each"
        );
        opts.vessels = v;
    }
    anyhow::ensure!(
        args.rate_hz > 0.0 && args.rate_hz.is_finite(),
        "--rate-hz must be positive"
    );
    opts.rate_hz = args.rate_hz;
    if let Some(w) = args.window_s {
        anyhow::ensure!(w > 0.0 && w.is_finite(), "--window-s must be positive");
        opts.window_s = w;
    }
    if let Some(w) = args.warmup_s {
        anyhow::ensure!(w >= 0.0 && w.is_finite(), "--warmup-s must not be negative");
        opts.warmup_s = w;
    }
    anyhow::ensure!(
        (1..=99_999).contains(&args.saturation_vessels),
        "--saturation-vessels: 1 to 99,999"
    );
    opts.saturation_vessels = args.saturation_vessels;
    opts.vessel_liveliness = !args.no_vessel_liveliness;
    opts.liveliness_outside_prefix = args.liveliness_outside_prefix;
    let report = twin_bench::daemon::run(&opts)?;
    print!("{}", report.table());
    // A missed target is reported, not an error.
    Ok(ExitCode::SUCCESS)
}

#[derive(Debug, Args)]
struct FloodArgs {
    /// New vessel ids in the burst, one message each.
    #[arg(long, default_value_t = 10_000)]
    ids: usize,
    /// Bytes of every flood message (each is that many `x`).
    #[arg(long, default_value_t = 1)]
    payload_bytes: usize,
    /// The real vessel's fixes per second.
    #[arg(long, default_value_t = 10.0)]
    rate_hz: f64,
    /// Length of the quiet phases before and after, s.
    #[arg(long, default_value_t = 10.0)]
    quiet_s: f64,
    /// How long the flood phase lasts after the burst was sent, s.
    #[arg(long, default_value_t = 15.0)]
    settle_s: f64,
}

fn run_flood(args: FloodArgs) -> anyhow::Result<ExitCode> {
    if cfg!(debug_assertions) {
        eprintln!("warning: a debug build; the figures mean little (use --release)");
    }
    let opts = twin_bench::daemon::flood::FloodOptions {
        ids: args.ids,
        payload: vec![b'x'; args.payload_bytes],
        rate_hz: args.rate_hz,
        quiet_s: args.quiet_s,
        settle_s: args.settle_s,
    };
    let report = twin_bench::daemon::flood::run(&opts)?;
    print!("{}", report.table());
    use std::io::Write as _;
    std::io::stdout().flush()?;
    // The daemon and its sessions were left running: leave now.
    std::process::exit(0);
}

#[derive(Debug, Args)]
struct DaemonPointArgs {
    #[arg(long, value_enum)]
    path: load::Path,
    #[arg(long)]
    vessels: usize,
    #[arg(
        long,
        conflicts_with = "flat_out",
        required_unless_present = "flat_out"
    )]
    rate_hz: Option<f64>,
    #[arg(long)]
    flat_out: bool,
    #[arg(long)]
    warmup_s: f64,
    #[arg(long)]
    window_s: f64,
    #[arg(long)]
    grace_s: f64,
    #[arg(long)]
    no_vessel_liveliness: bool,
    #[arg(long, conflicts_with = "no_vessel_liveliness")]
    liveliness_outside_prefix: bool,
}

fn run_daemon_point(args: DaemonPointArgs) -> anyhow::Result<ExitCode> {
    let spec = PointSpec {
        path: args.path,
        vessels: args.vessels,
        rate_hz: if args.flat_out { None } else { args.rate_hz },
        warmup_s: args.warmup_s,
        window_s: args.window_s,
        grace_s: args.grace_s,
        vessel_liveliness: !args.no_vessel_liveliness,
        liveliness_outside_prefix: args.liveliness_outside_prefix,
    };
    // A watchdog: a point that hangs must not hang the whole run. Its
    // shutdown is bounded too (load::DRAIN_LIMIT and the others).
    let shutdown_s =
        (load::GENERATOR_STOP_LIMIT + load::DRAIN_LIMIT + 4 * load::CLOSE_LIMIT).as_secs_f64();
    let limit = spec.warmup_s * load::WARMUP_CAP + spec.window_s + spec.grace_s + shutdown_s + 90.0;
    std::thread::spawn(move || {
        std::thread::sleep(std::time::Duration::from_secs_f64(limit));
        eprintln!("error: the point did not finish within {limit:.0} s");
        std::process::exit(3);
    });
    let result = load::measure(&spec)?;
    println!("{}", twin_bench::daemon::point_line(&result)?);
    Ok(ExitCode::SUCCESS)
}

#[derive(Debug, Args)]
struct CoreArgs {
    /// The Python interpreter for the NumPy reference.
    #[arg(long, default_value = "python3")]
    python: String,
    /// Timed runs of the seed trial in Rust.
    #[arg(long, default_value_t = 201)]
    rust_repeats: usize,
    /// Timed runs of the seed trial in NumPy.
    #[arg(long, default_value_t = 7)]
    numpy_repeats: usize,
    /// Where to write the trial files and the synthetic 4-hour log (default:
    /// a twin-bench-core folder in the system's temporary directory).
    #[arg(long)]
    work_dir: Option<PathBuf>,
    /// Few repeats and a 10-minute long log instead of 4 hours: a smoke
    /// test, not a measurement.
    #[arg(long)]
    quick: bool,
}

fn run_core(args: CoreArgs) -> anyhow::Result<ExitCode> {
    if cfg!(debug_assertions) {
        eprintln!("warning: a debug build; the figures mean little (use --release)");
    }
    let defaults = CoreOptions::default();
    let report = twin_bench::core::run(&CoreOptions {
        python: args.python,
        rust_repeats: args.rust_repeats,
        numpy_repeats: args.numpy_repeats,
        work_dir: args.work_dir.unwrap_or(defaults.work_dir),
        quick: args.quick,
    })?;
    print!("{}", report.table());
    // A missed speed target is reported, not an error; a disagreement with
    // NumPy is.
    Ok(if report.numpy_agrees {
        ExitCode::SUCCESS
    } else {
        eprintln!("error: NumPy and Rust disagree (see the note under the table)");
        ExitCode::FAILURE
    })
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
        Bench::Core(args) => run_core(args),
        Bench::Daemon(args) => run_daemon(args),
        Bench::Flood(args) => run_flood(args),
        Bench::DaemonPoint(args) => run_daemon_point(args),
        Bench::ColdStart(args) => run_cold_start(args),
        Bench::ColdStartPoint(args) => run_cold_start_point(args),
        Bench::Soak(args) => run_soak(args),
    };
    // Printed here, once, without the backtrace anyhow would add under
    // RUST_BACKTRACE: these are setup errors, not bugs.
    result.unwrap_or_else(|e| {
        eprintln!("error: {e:#}");
        ExitCode::from(2)
    })
}
