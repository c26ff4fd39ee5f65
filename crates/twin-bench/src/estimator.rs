//! The estimator side by side with NumPy: one trial of the seed's model run
//! by `twin_core`'s filter and by `bench/numpy_aekf.py`, both timed (median of
//! whole-trial repeats, per step), their estimates compared step by step, and
//! a table of the figures with the machine's load beside them.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::Context;

use crate::machine;
use crate::numpy::{self, Difference, NumpyTiming};
use crate::trial::{self, Timing, TrialSpec};

/// The tolerance on theta and x (and, relatively, on NIS).
pub const DEFAULT_TOLERANCE: f64 = 1e-9;

/// The speed target (docs/performance.md): Rust at least this many times faster.
pub const TARGET_RATIO: f64 = 100.0;

/// How to run the comparison.
#[derive(Debug, Clone)]
pub struct NumpyOptions {
    /// The Python interpreter.
    pub python: String,
    /// The NumPy reference script.
    pub script: PathBuf,
    /// Where the trial, the NumPy result and the Rust estimates are written.
    pub work_dir: PathBuf,
    /// Timed repeats of the whole trial in Rust.
    pub rust_repeats: usize,
    /// Timed repeats of the whole trial in NumPy.
    pub numpy_repeats: usize,
    /// Largest difference accepted.
    pub tolerance: f64,
}

impl Default for NumpyOptions {
    fn default() -> Self {
        Self {
            python: "python3".into(),
            script: numpy::default_script(),
            work_dir: std::env::temp_dir().join("twin-bench-numpy"),
            rust_repeats: 201,
            numpy_repeats: 7,
            tolerance: DEFAULT_TOLERANCE,
        }
    }
}

/// What a comparison found.
#[derive(Debug, Clone)]
pub struct NumpyOutcome {
    /// The trial that was run.
    pub spec: TrialSpec,
    /// Its duration, seconds.
    pub duration_s: f64,
    /// Steps with missing measurement components.
    pub masked_steps: usize,
    /// Where the trial file was written.
    pub trial_path: PathBuf,
    /// Where the NumPy result was written.
    pub numpy_path: PathBuf,
    /// Where the Rust estimates were written.
    pub rust_path: PathBuf,
    /// Rust timing.
    pub rust: Timing,
    /// NumPy timing.
    pub numpy: NumpyTiming,
    /// How far the two runs are apart.
    pub difference: Difference,
    /// Load average when the measurement started.
    pub load_before: String,
    /// Load average when it ended.
    pub load_after: String,
    /// Cores available.
    pub cores: usize,
    /// The tolerance it was held to.
    pub tolerance: f64,
}

impl NumpyOutcome {
    /// NumPy's median time per step over Rust's.
    pub fn ratio(&self) -> f64 {
        self.numpy.ns_per_step_median / self.rust.ns_per_step_median
    }

    /// True if the two implementations agree within the tolerance.
    pub fn agrees(&self) -> bool {
        self.difference.within(self.tolerance)
    }

    /// The figures as a Markdown table with its context.
    pub fn table(&self) -> String {
        let mut s = String::new();
        let d = &self.difference;
        let _ = writeln!(
            s,
            "AEKF step, seed kinematic model (state 4, measurement 4, faults 2), noise adaptation {:?}",
            self.spec.adaptation
        );
        let _ = writeln!(
            s,
            "trial: {} steps at {:.0} Hz ({:.1} s), seed {}, {} steps with missing components",
            self.spec.steps,
            1.0 / self.spec.dt_s,
            self.duration_s,
            self.spec.seed,
            self.masked_steps
        );
        let _ = writeln!(
            s,
            "machine: {} cores, load average (1/5/15 min) {} before, {} after",
            self.cores, self.load_before, self.load_after
        );
        let _ = writeln!(s);
        let rows = [
            (
                "Rust (twin-core, release)".to_string(),
                self.rust.ns_per_step_median,
                self.rust.ns_per_step_min,
                self.rust.repeats,
            ),
            (
                format!("NumPy {} (Python {})", self.numpy.numpy, self.numpy.python),
                self.numpy.ns_per_step_median,
                self.numpy.ns_per_step_min,
                self.numpy.repeats,
            ),
        ];
        let _ = writeln!(
            s,
            "| {:<34} | {:>16} | {:>13} | {:>7} |",
            "implementation", "ns/step (median)", "ns/step (min)", "repeats"
        );
        let _ = writeln!(s, "|{:-<36}|{:->17}:|{:->14}:|{:->8}:|", "", "", "", "");
        for (name, median, min, repeats) in rows {
            let _ = writeln!(
                s,
                "| {name:<34} | {median:>16.1} | {min:>13.1} | {repeats:>7} |"
            );
        }
        let _ = writeln!(s);
        let ratio = self.ratio();
        let _ = writeln!(
            s,
            "ratio NumPy/Rust (medians): {ratio:.0}x (target at least {TARGET_RATIO:.0}x: {})",
            if ratio >= TARGET_RATIO {
                "met"
            } else {
                "NOT met"
            }
        );
        let _ = writeln!(
            s,
            "max |difference| over {} steps: {:.2e} (theta {:.2e}, x {:.2e} with the course wrapped; \
             NIS {:.2e} relative); worst at step {}; refusals differing {}; courses out of range {}; \
             tolerance {:.0e}: {}",
            d.steps,
            d.max_estimate(),
            d.theta,
            d.x,
            d.nis_relative,
            d.worst_step,
            d.refusal_mismatches,
            d.course_out_of_range,
            self.tolerance,
            if self.agrees() { "agree" } else { "DISAGREE" }
        );
        s
    }
}

/// Generates the trial of `spec`, runs and times it in Rust and in NumPy, and
/// compares the two. An error only if something could not run; a
/// disagreement is in the outcome ([`NumpyOutcome::agrees`]).
pub fn compare_with_numpy(spec: &TrialSpec, opts: &NumpyOptions) -> anyhow::Result<NumpyOutcome> {
    std::fs::create_dir_all(&opts.work_dir)
        .with_context(|| format!("creating {}", opts.work_dir.display()))?;
    let trial_path = opts.work_dir.join("trial.json");
    let numpy_path = opts.work_dir.join("numpy_result.json");
    let rust_path = opts.work_dir.join("rust_estimates.json");

    let trial = trial::generate(spec);
    let prepared = trial.prepare()?;
    std::fs::write(&trial_path, serde_json::to_vec(&trial)?)
        .with_context(|| format!("writing {}", trial_path.display()))?;

    let load_before = machine::load_average_text();
    let rust_estimates = prepared.run_recorded();
    let rust = prepared.time(opts.rust_repeats);
    std::fs::write(&rust_path, serde_json::to_vec(&rust_estimates)?)
        .with_context(|| format!("writing {}", rust_path.display()))?;
    let numpy = numpy::run_reference(
        &opts.python,
        &opts.script,
        &trial_path,
        &numpy_path,
        opts.numpy_repeats,
    )?;
    let load_after = machine::load_average_text();

    let difference = numpy::compare(&rust_estimates, &numpy.estimates())?;
    Ok(NumpyOutcome {
        spec: *spec,
        duration_s: trial.duration_s(),
        masked_steps: trial.masked_steps(),
        trial_path,
        numpy_path,
        rust_path,
        rust,
        numpy: numpy.timing,
        difference,
        load_before,
        load_after,
        cores: machine::cores(),
        tolerance: opts.tolerance,
    })
}
