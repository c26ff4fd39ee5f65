//! The NumPy side of the estimator benchmark: finding Python and NumPy,
//! running `bench/numpy_aekf.py` on a trial file, reading its estimates and
//! timing, and comparing its estimates with the Rust filter's step by step.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, bail};
use serde::Deserialize;
use twin_core::geodesy::wrap_pi;

use crate::trial::Estimates;

/// The one-line setup printed wherever NumPy is missing.
pub const INSTALL_HINT: &str = "python3 -m pip install -r requirements.txt";

/// Exit status of `numpy_aekf.py` when NumPy cannot be imported.
const EXIT_NO_NUMPY: i32 = 3;

/// `bench/numpy_aekf.py` in this source tree.
pub fn default_script() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../bench/numpy_aekf.py")
        .components()
        .collect()
}

/// Why the NumPy reference cannot run here, or `None` if it can: `python`
/// cannot be started, or NumPy cannot be imported by it.
pub fn unavailable_reason(python: &str) -> Option<String> {
    match Command::new(python).args(["-c", "import numpy"]).output() {
        Err(e) => Some(format!(
            "cannot run {python:?} ({e}); install Python 3 and then NumPy: {INSTALL_HINT}"
        )),
        Ok(out) if !out.status.success() => Some(format!(
            "NumPy is not importable by {python:?}; install it with: {INSTALL_HINT}"
        )),
        Ok(_) => None,
    }
}

/// The NumPy reference's timing, as it reports it.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct NumpyTiming {
    /// Steps in the trial.
    pub steps: usize,
    /// Timed runs of the whole trial.
    pub repeats: usize,
    /// Median over the repeats, nanoseconds per step.
    pub ns_per_step_median: f64,
    /// Fastest repeat, nanoseconds per step.
    pub ns_per_step_min: f64,
    /// Python version.
    pub python: String,
    /// NumPy version.
    pub numpy: String,
}

/// What `numpy_aekf.py` writes.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct NumpyResult {
    /// `thetahat` after each step.
    pub theta: Vec<[f64; 2]>,
    /// `xhat` after each step.
    pub x: Vec<[f64; 4]>,
    /// NIS of each step, none where the step was refused.
    pub nis: Vec<Option<f64>>,
    /// Timing.
    pub timing: NumpyTiming,
}

impl NumpyResult {
    /// The estimates alone.
    pub fn estimates(&self) -> Estimates {
        Estimates {
            theta: self.theta.clone(),
            x: self.x.clone(),
            nis: self.nis.clone(),
        }
    }
}

/// Runs `script` with `python` on `trial` (timing `repeats` runs), writing
/// and then reading `out`.
pub fn run_reference(
    python: &str,
    script: &Path,
    trial: &Path,
    out: &Path,
    repeats: usize,
) -> anyhow::Result<NumpyResult> {
    anyhow::ensure!(
        script.is_file(),
        "NumPy reference {} not found",
        script.display()
    );
    let output = Command::new(python)
        .arg(script)
        .arg(trial)
        .arg("--out")
        .arg(out)
        .arg("--repeats")
        .arg(repeats.to_string())
        .output()
        .with_context(|| {
            format!("cannot run {python:?}: install Python 3 and then NumPy ({INSTALL_HINT})")
        })?;
    if !output.status.success() {
        let stderr = String::from_utf8_lossy(&output.stderr);
        if output.status.code() == Some(EXIT_NO_NUMPY) {
            bail!("NumPy is not installed for {python:?}; install it with:\n    {INSTALL_HINT}");
        }
        bail!(
            "{python} {} failed ({}):\n{stderr}",
            script.display(),
            output.status
        );
    }
    let text = std::fs::read_to_string(out)
        .with_context(|| format!("reading the NumPy result {}", out.display()))?;
    serde_json::from_str(&text)
        .with_context(|| format!("parsing the NumPy result {}", out.display()))
}

/// How far two runs of the same trial are apart.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Difference {
    /// Steps compared.
    pub steps: usize,
    /// Largest `|theta_a - theta_b|` over all steps and components.
    pub theta: f64,
    /// Largest `|x_a - x_b|` (the course difference wrapped to [-pi, pi)).
    pub x: f64,
    /// Largest `|nis_a - nis_b| / max(1, |nis_a|)`.
    pub nis_relative: f64,
    /// Step of the largest theta or x difference.
    pub worst_step: usize,
    /// Steps that one run refused and the other accepted.
    pub refusal_mismatches: usize,
    /// Estimates (of either run) whose course is outside [-pi, pi): the
    /// comparison wraps course differences, so an unwrapped course would
    /// otherwise pass unseen.
    pub course_out_of_range: usize,
}

impl Difference {
    /// The largest difference of the estimates (theta and x).
    pub fn max_estimate(&self) -> f64 {
        self.theta.max(self.x)
    }

    /// True if the runs agree to `tolerance` in theta, x and (relatively) NIS,
    /// refused the same steps and kept the course wrapped. A NaN anywhere fails.
    pub fn within(&self, tolerance: f64) -> bool {
        self.failures(tolerance).is_empty()
    }

    /// What exceeds `tolerance` (or is otherwise wrong), in words.
    pub fn failures(&self, tolerance: f64) -> Vec<String> {
        let mut out = Vec::new();
        // NaN fails.
        for (what, d) in [
            ("theta", self.theta),
            ("x", self.x),
            ("NIS (relative)", self.nis_relative),
        ] {
            if d.is_nan() || d > tolerance {
                out.push(format!("{what} differs by {d:e} > {tolerance:e}"));
            }
        }
        if self.refusal_mismatches > 0 {
            out.push(format!(
                "{} steps refused by one run only",
                self.refusal_mismatches
            ));
        }
        if self.course_out_of_range > 0 {
            out.push(format!(
                "{} course estimates outside [-pi, pi)",
                self.course_out_of_range
            ));
        }
        out
    }
}

/// Compares two runs step by step. Runs of different lengths are an error.
pub fn compare(a: &Estimates, b: &Estimates) -> anyhow::Result<Difference> {
    let n = a.theta.len();
    anyhow::ensure!(
        a.x.len() == n
            && a.nis.len() == n
            && b.theta.len() == n
            && b.x.len() == n
            && b.nis.len() == n,
        "the runs have different numbers of steps ({n} and {})",
        b.theta.len()
    );
    // NaN-propagating maximum: a NaN difference must not pass as small.
    let worse = |acc: f64, d: f64| if d.is_nan() || d > acc { d } else { acc };
    let mut diff = Difference {
        steps: n,
        ..Difference::default()
    };
    let mut worst = 0.0;
    for k in 0..n {
        let dt = (0..2).fold(0.0, |m, i| worse(m, (a.theta[k][i] - b.theta[k][i]).abs()));
        let dx = (0..4).fold(0.0, |m, i| {
            let d = a.x[k][i] - b.x[k][i];
            worse(m, if i == 3 { wrap_pi(d) } else { d }.abs())
        });
        diff.theta = worse(diff.theta, dt);
        diff.x = worse(diff.x, dx);
        let step_worst = dt.max(dx);
        if step_worst > worst || step_worst.is_nan() {
            worst = step_worst;
            diff.worst_step = k;
        }
        let pi = std::f64::consts::PI;
        diff.course_out_of_range += [a.x[k][3], b.x[k][3]]
            .iter()
            .filter(|c| !(-pi..pi).contains(*c))
            .count();
        match (a.nis[k], b.nis[k]) {
            (Some(p), Some(q)) => {
                diff.nis_relative = worse(diff.nis_relative, (p - q).abs() / p.abs().max(1.0));
            }
            (None, None) => {}
            _ => diff.refusal_mismatches += 1,
        }
    }
    Ok(diff)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    fn run(theta0: f64, course: f64, nis: Option<f64>) -> Estimates {
        Estimates {
            theta: vec![[theta0, 0.0]],
            x: vec![[1.0, 2.0, 3.0, course]],
            nis: vec![nis],
        }
    }

    #[test]
    fn course_differences_are_wrapped() {
        let pi = std::f64::consts::PI;
        let d = compare(
            &run(0.0, pi - 1e-12, Some(1.0)),
            &run(0.0, -pi + 1e-12, Some(1.0)),
        )
        .unwrap();
        assert!(d.x < 1e-11, "{d:?}");
        assert!(d.within(1e-9));
    }

    #[test]
    fn nan_and_refusals_fail() {
        let d = compare(&run(f64::NAN, 0.0, Some(1.0)), &run(0.0, 0.0, Some(1.0))).unwrap();
        assert!(!d.within(1e-9), "{d:?}");
        let d = compare(&run(0.0, 0.0, None), &run(0.0, 0.0, Some(1.0))).unwrap();
        assert_eq!(d.refusal_mismatches, 1);
        assert!(!d.within(1e-9));
        let d = compare(&run(1e-8, 0.0, Some(1.0)), &run(0.0, 0.0, Some(1.0))).unwrap();
        assert!(!d.within(1e-9));
        let d = compare(&run(0.0, 4.0, Some(1.0)), &run(0.0, 4.0 - TAU, Some(1.0))).unwrap();
        assert_eq!(d.course_out_of_range, 1);
        assert!(!d.within(1e-9));
    }

    #[test]
    fn the_default_script_is_in_the_tree() {
        assert!(default_script().is_file(), "{}", default_script().display());
    }
}
