//! `cargo xtask real-logs`: `twin analyze` over every log of a directory
//! (by default `tests/fixtures/real/`), as one markdown table for
//! `docs/accuracy.md`:
//! log, format, span, fixes used, rejected, innovation RMS of position, mean
//! NIS per degree of freedom, the seed method's input faults and the water
//! current where the extended twin ran.
//!
//! Files that are not logs (README, licences: no known format in their first
//! lines) are skipped; every other failure is an error. Logs are taken in
//! name order, so the table is the same on every machine.

use std::fmt::Write;
use std::path::{Path, PathBuf};

use twin_wire::read::OpenError;

use twin_cli::analyze::{Analysis, AnalyzeError, AnalyzeOptions, analyze_path, duration_text};

/// The real logs' directory, relative to the workspace root.
pub const DEFAULT_DIR: &str = "tests/fixtures/real";

/// Why the report failed.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// The directory cannot be listed.
    #[error("cannot list {path}: {source}")]
    List {
        /// The directory.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A log could not be analysed.
    #[error(transparent)]
    Analyze(#[from] AnalyzeError),
}

/// The files of `dir` in name order, each with its file name.
pub fn files_by_name(dir: &Path) -> Result<Vec<(String, PathBuf)>, std::io::Error> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)?
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.is_file())
        .collect();
    paths.sort();
    Ok(paths
        .into_iter()
        .map(|p| {
            let name = p
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            (name, p)
        })
        .collect())
}

/// Analyses every log in `dir` (name order); skips files in no log format.
pub fn analyze_dir(
    dir: &Path,
    options: &AnalyzeOptions,
) -> Result<Vec<(String, Analysis)>, ReportError> {
    let paths = files_by_name(dir).map_err(|source| ReportError::List {
        path: dir.to_path_buf(),
        source,
    })?;
    let mut out = Vec::new();
    for (name, path) in paths {
        match analyze_path(&path, options) {
            Ok(a) => out.push((name, a)),
            Err(AnalyzeError::Log {
                source: OpenError::UnknownFormat | OpenError::Empty,
                ..
            }) => continue,
            Err(e) => return Err(e.into()),
        }
    }
    Ok(out)
}

fn fmt_opt(v: Option<f64>, decimals: usize) -> String {
    v.map_or("-".to_string(), |v| format!("{v:.decimals$}"))
}

/// The markdown table of analysed logs.
pub fn markdown_table(logs: &[(String, Analysis)]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| log | format | span | fixes used | rejected | innovation RMS position (m) | mean NIS/dof (95 % band) | seed-method input faults [a, r] | current |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|");
    for (name, a) in logs {
        let q = a
            .quality
            .kinetic
            .as_ref()
            .or(a.quality.seed_method.as_ref());
        let rejected: Vec<String> = a
            .rejected_by_reason
            .reader
            .iter()
            .chain(&a.rejected_by_reason.twin_fixes)
            .chain(&a.rejected_by_reason.twin_propellers)
            .map(|(k, v)| format!("{v} {k}"))
            .collect();
        let nis = q.map_or("-".to_string(), |q| {
            format!(
                "{:.2} ({:.2}-{:.2}{})",
                q.mean_nis_per_dof,
                q.nis_band_95[0],
                q.nis_band_95[1],
                if q.nis_within_band { "" } else { ", outside" }
            )
        });
        let faults = a
            .seed_method
            .input_faults
            .map_or("-".to_string(), |f| format!("[{:.3}, {:.3}]", f[0], f[1]));
        let current = a.current.map_or("-".to_string(), |c| {
            format!("{:.2} m/s toward {:.0} deg", c.speed_mps, c.toward_deg)
        });
        let _ = writeln!(
            s,
            "| {name} | {} | {} | {} | {} | {} | {nis} | {faults} | {current} |",
            a.format,
            a.span
                .as_ref()
                .map_or("-".to_string(), |sp| duration_text(sp.duration_s)),
            a.samples_by_kind.fixes,
            if rejected.is_empty() {
                "0".to_string()
            } else {
                format!("{} ({})", a.rejected, rejected.join(", "))
            },
            fmt_opt(q.and_then(|q| q.innovation_rms.position_m), 2),
        );
    }
    s
}
