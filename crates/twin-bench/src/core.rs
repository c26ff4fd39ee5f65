//! The `core` subcommand: the estimator and the offline path, side by side
//! in one run, as one Markdown table with the project's targets (docs/performance.md) and a
//! PASS/MISS beside each: the seed model's AEKF step (and the same recursion
//! in NumPy, and their ratio), the extended model's step, the whole twin per
//! fix, the forecast, a whole 120 s trial, parsing per format in MB/s and a
//! 4-hour log analysed offline.
//!
//! Every figure is a median over repeated runs of a whole workload (never a
//! single call timed alone), single-threaded, printed beside the machine's
//! cores and load: the machine is shared.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use twin_core::aekf::GainSensitivity;
use twin_core::models::otter_twin;
use twin_core::twin::TwinConfig;

use crate::estimator::{self, NumpyOptions};
use crate::machine;
use crate::numpy;
use crate::trial::{self, Timing, TrialSpec};
use crate::workloads::{self, TwinInput};

/// Target (docs/performance.md): one AEKF step of the seed model, ns.
pub const TARGET_SEED_STEP_NS: f64 = 250.0;
/// Target (docs/performance.md): one AEKF step of the extended model, ns.
pub const TARGET_EXTENDED_STEP_NS: f64 = 2000.0;
/// Target (docs/performance.md): a 4-hour log analysed offline "in well under a second", s.
pub const TARGET_LONG_LOG_S: f64 = 1.0;

/// How to run `core`.
#[derive(Debug, Clone)]
pub struct CoreOptions {
    /// The Python interpreter for the NumPy reference.
    pub python: String,
    /// Timed runs of the seed trial in Rust.
    pub rust_repeats: usize,
    /// Timed runs of the seed trial in NumPy.
    pub numpy_repeats: usize,
    /// Where the trial, the NumPy result and the long log are written.
    pub work_dir: PathBuf,
    /// Fewer repeats everywhere (for tests): the figures are rougher.
    pub quick: bool,
}

impl Default for CoreOptions {
    fn default() -> Self {
        Self {
            python: "python3".into(),
            rust_repeats: 201,
            numpy_repeats: 7,
            work_dir: std::env::temp_dir().join("twin-bench-core"),
            quick: false,
        }
    }
}

/// One row of the table.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// What was measured.
    pub what: String,
    /// The median, formatted with its unit.
    pub value: String,
    /// The target, if the project sets one.
    pub target: Option<String>,
    /// Whether the target is met.
    pub pass: Option<bool>,
}

impl Row {
    fn plain(what: impl Into<String>, value: impl Into<String>) -> Self {
        Self {
            what: what.into(),
            value: value.into(),
            target: None,
            pass: None,
        }
    }

    fn judged(what: impl Into<String>, value: impl Into<String>, target: &str, pass: bool) -> Self {
        Self {
            what: what.into(),
            value: value.into(),
            target: Some(target.into()),
            pass: Some(pass),
        }
    }
}

/// What `core` measured.
#[derive(Debug, Clone)]
pub struct CoreReport {
    /// The rows, in order.
    pub rows: Vec<Row>,
    /// Lines printed under the table.
    pub notes: Vec<String>,
    /// Load average when the measurements started.
    pub load_before: String,
    /// Load average when they ended.
    pub load_after: String,
    /// True when the NumPy reference and the Rust filter agree (or NumPy
    /// could not run; see the notes).
    pub numpy_agrees: bool,
}

impl CoreReport {
    /// True if every judged row passes.
    pub fn all_pass(&self) -> bool {
        self.rows.iter().all(|r| r.pass != Some(false))
    }

    /// The table with its context, as Markdown.
    pub fn table(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "machine: {} cores ({}), load average (1/5/15 min) {} before, {} after; \
             `twin-bench core`, one thread, medians over repeated runs of each whole workload.",
            machine::cores(),
            machine::cpu_model(),
            self.load_before,
            self.load_after
        );
        let _ = writeln!(s);
        let _ = writeln!(s, "| measurement | median | target | verdict |");
        let _ = writeln!(s, "|---|---:|---|---|");
        for r in &self.rows {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} |",
                r.what,
                r.value,
                r.target.as_deref().unwrap_or(""),
                match r.pass {
                    Some(true) => "PASS",
                    Some(false) => "MISS",
                    None => "",
                }
            );
        }
        if !self.notes.is_empty() {
            let _ = writeln!(s);
            for n in &self.notes {
                let _ = writeln!(s, "{n}");
            }
        }
        s
    }
}

/// A duration in nanoseconds with a readable unit.
pub fn duration_text(ns: f64) -> String {
    if ns < 1e3 {
        format!("{ns:.0} ns")
    } else if ns < 1e6 {
        format!("{:.2} us", ns / 1e3)
    } else if ns < 1e9 {
        format!("{:.1} ms", ns / 1e6)
    } else {
        format!("{:.2} s", ns / 1e9)
    }
}

/// An integer with thousands separators.
pub fn thousands(n: u64) -> String {
    let digits = n.to_string();
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// Runs every measurement. An error only if a workload could not be set up.
pub fn run(opts: &CoreOptions) -> anyhow::Result<CoreReport> {
    std::fs::create_dir_all(&opts.work_dir)
        .with_context(|| format!("creating {}", opts.work_dir.display()))?;
    let mut m = Measurements {
        opts,
        rows: Vec::new(),
        notes: Vec::new(),
    };
    let load_before = machine::load_average_text();
    progress("starting");
    let numpy_agrees = m.seed_step()?;
    progress("seed step and NumPy");
    let demo = workloads::simulate("demo_broken-port")?;
    let demo_inputs = workloads::twin_inputs(&demo);
    m.extended_step(&demo_inputs)?;
    progress("extended step, whole twin");
    m.forecasts(&demo_inputs)?;
    progress("forecasts");
    m.whole_trial()?;
    progress("120 s trial");
    m.parsing()?;
    progress("parsing");
    m.long_logs()?;
    Ok(CoreReport {
        rows: m.rows,
        notes: m.notes,
        load_before,
        load_after: machine::load_average_text(),
        numpy_agrees,
    })
}

/// The rows and notes of a `core` run, filled one workload at a time.
struct Measurements<'a> {
    opts: &'a CoreOptions,
    rows: Vec<Row>,
    notes: Vec<String>,
}

/// Repeats of a workload: `full`, or a few for a quick run.
fn repeats(opts: &CoreOptions, full: usize) -> usize {
    if opts.quick { full.clamp(1, 3) } else { full }
}

impl Measurements<'_> {
    /// The seed model's step, in Rust and (if it can run) in NumPy, and its
    /// two copies; whether NumPy and Rust agree (true when NumPy could not
    /// run).
    fn seed_step(&mut self) -> anyhow::Result<bool> {
        let opts = self.opts;
        let (rows, notes) = (&mut self.rows, &mut self.notes);
        let reps = |full: usize| repeats(opts, full);
        let mut numpy_agrees = true;
        let spec = TrialSpec::default();
        let seed_rust: Timing;
        match numpy::unavailable_reason(&opts.python) {
            None => {
                let outcome = estimator::compare_with_numpy(
                    &spec,
                    &NumpyOptions {
                        python: opts.python.clone(),
                        work_dir: opts.work_dir.join("numpy"),
                        rust_repeats: reps(opts.rust_repeats),
                        numpy_repeats: reps(opts.numpy_repeats),
                        ..NumpyOptions::default()
                    },
                )?;
                seed_rust = outcome.rust;
                numpy_agrees = outcome.agrees();
                push_seed_row(rows, &spec, &seed_rust);
                rows.push(Row::plain(
                    format!(
                        "the same recursion in NumPy {} (Python {}), same trial, {} runs",
                        outcome.numpy.numpy, outcome.numpy.python, outcome.numpy.repeats
                    ),
                    duration_text(outcome.numpy.ns_per_step_median),
                ));
                let ratio = outcome.ratio();
                rows.push(Row::judged(
                    "NumPy / Rust, per step",
                    format!("{ratio:.0}x"),
                    ">= 100x",
                    ratio >= estimator::TARGET_RATIO,
                ));
                notes.push(format!(
                    "NumPy and Rust estimates over the {} steps: largest difference {:.1e} \
                     (tolerance {:.0e}): {}.",
                    outcome.difference.steps,
                    outcome.difference.max_estimate(),
                    outcome.tolerance,
                    if numpy_agrees { "agree" } else { "DISAGREE" }
                ));
            }
            Some(reason) => {
                let prepared = trial::generate(&spec).prepare()?;
                seed_rust = prepared.time(reps(opts.rust_repeats));
                push_seed_row(rows, &spec, &seed_rust);
                rows.push(Row::judged(
                    "NumPy / Rust, per step",
                    "not measured",
                    ">= 100x",
                    false,
                ));
                notes.push(format!("NumPy reference not run: {reason}"));
            }
        }

        let seed_trial = trial::generate(&spec).prepare()?;
        push_copies_row(
            rows,
            "seed",
            &seed_trial.time_both_copies(reps(opts.rust_repeats)),
        );
        Ok(numpy_agrees)
    }

    /// The extended twin's step and the whole twin per fix, on the bundled
    /// demo trial (5 min, GNSS and heading 5 Hz, shaft speeds 10 Hz, port
    /// propeller 25 % down).
    fn extended_step(&mut self, demo_inputs: &[TwinInput]) -> anyhow::Result<()> {
        let opts = self.opts;
        let rows = &mut self.rows;
        let reps = |full: usize| repeats(opts, full);
        let config = TwinConfig::default();
        let kinetic = workloads::kinetic_steps(demo_inputs, config)?;
        let t = kinetic.time(reps(101));
        rows.push(Row::judged(
            format!(
                "AEKF step, extended model (OtterTwin: 10 states, 6 measurements, 6 faults; {}-step trial)",
                thousands(kinetic.steps.len() as u64)
            ),
            duration_text(t.ns_per_step_median),
            "< 2 us",
            t.ns_per_step_median < TARGET_EXTENDED_STEP_NS,
        ));
        push_copies_row(rows, "extended", &kinetic.time_both_copies(reps(101)));
        // What the Kalman gain's part in the faults' sensitivity costs
        // (`AekfConfig::gain_sensitivity`, not the twin's default).
        for (form, faults, what) in [
            (
                GainSensitivity::ThroughCovariance,
                [true; otter_twin::FAULTS],
                "through the covariance",
            ),
            (
                GainSensitivity::ThroughCovariance,
                otter_twin::fault::IS_PROFILE,
                "through the covariance, the profile's errors only",
            ),
            (GainSensitivity::Exact, [true; otter_twin::FAULTS], "exact"),
        ] {
            let mut with_gain = config;
            with_gain.kinetic.filter.gain_sensitivity = form;
            with_gain.kinetic.filter.gain_sensitivity_faults = faults;
            let t = workloads::kinetic_steps(demo_inputs, with_gain)?.time(reps(31));
            rows.push(Row::plain(
                format!("AEKF step, extended model, the gain's part in Upsilon {what}"),
                duration_text(t.ns_per_step_median),
            ));
        }
        let fixes = workloads::fix_count(demo_inputs);
        let shafts = demo_inputs.len() - fixes;
        let t = workloads::per_item(fixes, reps(31), || {
            std::hint::black_box(workloads::run_twin(demo_inputs, config));
        });
        rows.push(Row::plain(
            format!(
                "whole twin per GNSS fix (validation, both estimators, decision; {:.0} shaft samples per fix)",
                shafts as f64 / fixes.max(1) as f64
            ),
            duration_text(t.ns_per_step_median),
        ));
        Ok(())
    }

    /// The forecast the daemon publishes: 60 s at 1 s with covariance, of
    /// the extended twin and of the seed model.
    fn forecasts(&mut self, demo_inputs: &[TwinInput]) -> anyhow::Result<()> {
        let opts = self.opts;
        let rows = &mut self.rows;
        let reps = |full: usize| repeats(opts, full);
        let config = TwinConfig::default();
        let twin = workloads::run_twin(demo_inputs, config);
        anyhow::ensure!(
            twin.kinetic_active(),
            "the demo trial ends without the extended twin"
        );
        let t = workloads::per_item(1000, reps(21), || {
            for _ in 0..1000 {
                std::hint::black_box(twin.forecast(std::hint::black_box(60.0), 1.0));
            }
        });
        rows.push(Row::plain(
            "forecast 60 s at 1 s, extended twin (60 points with covariance)",
            duration_text(t.ns_per_step_median),
        ));
        let seed_only: Vec<TwinInput> = demo_inputs
            .iter()
            .filter(|i| matches!(i, TwinInput::Fix(_)))
            .copied()
            .collect();
        let seed_twin = workloads::run_twin(&seed_only, config);
        let t = workloads::per_item(1000, reps(21), || {
            for _ in 0..1000 {
                std::hint::black_box(seed_twin.forecast(std::hint::black_box(60.0), 1.0));
            }
        });
        rows.push(Row::plain(
            "forecast 60 s at 1 s, seed model (no shaft speeds)",
            duration_text(t.ns_per_step_median),
        ));
        Ok(())
    }

    /// A whole 120 s trial offline: the S-manoeuvre of the seed's trials.
    fn whole_trial(&mut self) -> anyhow::Result<()> {
        let opts = self.opts;
        let rows = &mut self.rows;
        let reps = |full: usize| repeats(opts, full);
        let config = TwinConfig::default();
        let s_run = workloads::simulate("s-manoeuvre_new-broken")?;
        let s_inputs = workloads::twin_inputs(&s_run);
        let s_fixes = workloads::fix_count(&s_inputs);
        let t = workloads::per_item(1, reps(51), || {
            std::hint::black_box(workloads::run_twin(&s_inputs, config));
        });
        rows.push(Row::plain(
            format!(
                "120 s trial offline (S-manoeuvre: {} fixes, {} shaft samples, whole twin)",
                thousands(s_fixes as u64),
                thousands((s_inputs.len() - s_fixes) as u64)
            ),
            duration_text(t.ns_per_step_median),
        ));
        Ok(())
    }

    /// Parsing, per format, from memory.
    fn parsing(&mut self) -> anyhow::Result<()> {
        let opts = self.opts;
        let rows = &mut self.rows;
        let reps = |full: usize| repeats(opts, full);
        for (format, path) in workloads::parse_logs() {
            let bytes =
                std::fs::read(&path).with_context(|| format!("reading {}", path.display()))?;
            let mut mbps: Vec<f64> = (0..reps(9).max(1))
                .map(|_| {
                    let t0 = Instant::now();
                    std::hint::black_box(workloads::parse_all(&bytes));
                    bytes.len() as f64 / 1e6 / t0.elapsed().as_secs_f64()
                })
                .collect();
            let (records, _) = workloads::parse_all(&bytes);
            rows.push(Row::plain(
                format!(
                    "parse {format} ({}, {:.1} MB, {} records)",
                    path.file_name().unwrap_or_default().to_string_lossy(),
                    bytes.len() as f64 / 1e6,
                    thousands(records)
                ),
                format!("{:.0} MB/s", workloads::median(&mut mbps)),
            ));
        }
        Ok(())
    }

    /// A 4-hour log analysed offline, synthetic (the Otter at full rates)
    /// and real (plaka.log, NMEA 0183 every 2 s).
    fn long_logs(&mut self) -> anyhow::Result<()> {
        let opts = self.opts;
        let quick = opts.quick;
        let (rows, notes) = (&mut self.rows, &mut self.notes);
        let reps = |full: usize| repeats(opts, full);
        let long_path = opts.work_dir.join("serpentine-4h.jsonl");
        let duration_s = if quick { 600.0 } else { workloads::LONG_LOG_S };
        let t0 = Instant::now();
        let (size, long_fixes) = workloads::write_long_log(&long_path, duration_s)?;
        let simulated_s = t0.elapsed().as_secs_f64();
        progress("long log simulated");
        let analyze = twin_cli::analyze::AnalyzeOptions::default();
        for (what, path, fixes_text) in [
            (
                format!(
                    "{} h log analysed offline (`twin analyze`; synthetic JSON lines, {:.0} MB)",
                    duration_s / 3600.0,
                    size as f64 / 1e6
                ),
                long_path.clone(),
                thousands(long_fixes as u64),
            ),
            (
                "4 h log analysed offline (`twin analyze`; real plaka.log, NMEA 0183, 3.1 MB)"
                    .to_string(),
                workloads::real_log("plaka.log"),
                String::new(),
            ),
        ] {
            let mut secs = Vec::new();
            let mut fixes = 0;
            for _ in 0..reps(5) {
                let t0 = Instant::now();
                let a = twin_cli::analyze::analyze_path(&path, &analyze)
                    .map_err(|e| anyhow::anyhow!("analysing {}: {e}", path.display()))?;
                secs.push(t0.elapsed().as_secs_f64());
                fixes = a.assembled.fixes;
            }
            let s = workloads::median(&mut secs);
            let what = if fixes_text.is_empty() {
                format!("{what}, {} fixes", thousands(fixes))
            } else {
                format!("{what}, {fixes_text} fixes")
            };
            if quick {
                rows.push(Row::plain(what, duration_text(s * 1e9)));
            } else {
                rows.push(Row::judged(
                    what,
                    duration_text(s * 1e9),
                    "< 1 s",
                    s < TARGET_LONG_LOG_S,
                ));
            }
        }
        notes.push(format!(
            "The synthetic log: the Otter on a serpentine for {} h (twin-sim, simulated in {simulated_s:.1} s), \
             GNSS with heading at 5 Hz, shaft speeds at 10 Hz, written as the contract's JSON lines.",
            duration_s / 3600.0
        ));
        let _ = std::fs::remove_file(&long_path);
        Ok(())
    }
}

/// A line on standard error with the time since the first call, so that a
/// long run shows where it is (the table goes to standard output).
fn progress(what: &str) {
    static START: std::sync::OnceLock<Instant> = std::sync::OnceLock::new();
    let start = START.get_or_init(Instant::now);
    eprintln!("[{:6.1} s] {what}", start.elapsed().as_secs_f64());
}

fn push_seed_row(rows: &mut Vec<Row>, spec: &TrialSpec, t: &Timing) {
    rows.push(Row::judged(
        format!(
            "AEKF step, seed model (4 states, 4 measurements, 2 faults; {}-step trial, {} runs)",
            thousands(spec.steps as u64),
            t.repeats
        ),
        duration_text(t.ns_per_step_median),
        "< 250 ns",
        t.ns_per_step_median < TARGET_SEED_STEP_NS,
    ));
}

/// The step's AVX2 copy against its baseline code, timed alternately in one
/// run (`twin_core::simd`): how much of the row above the wider vectors
/// give. Without AVX2 both are the baseline code, and the row says so.
fn push_copies_row(rows: &mut Vec<Row>, model: &str, [dispatched, baseline]: &[Timing; 2]) {
    let value = if twin_core::avx2_available() {
        format!(
            "{} / {} ({:.2}x)",
            duration_text(dispatched.ns_per_step_median),
            duration_text(baseline.ns_per_step_median),
            baseline.ns_per_step_median / dispatched.ns_per_step_median
        )
    } else {
        format!(
            "no AVX2 here: {} both",
            duration_text(baseline.ns_per_step_median)
        )
    };
    rows.push(Row::plain(
        format!(
            "  the {model} step's AVX2 copy / baseline x86-64 code, alternating runs ({} each)",
            dispatched.repeats
        ),
        value,
    ));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_read_well() {
        assert_eq!(thousands(0), "0");
        assert_eq!(thousands(999), "999");
        assert_eq!(thousands(72_000), "72,000");
        assert_eq!(thousands(1_234_567), "1,234,567");
        assert_eq!(duration_text(248.4), "248 ns");
        assert_eq!(duration_text(1_500.0), "1.50 us");
        assert_eq!(duration_text(2.5e6), "2.5 ms");
        assert_eq!(duration_text(1.5e9), "1.50 s");
    }
}
