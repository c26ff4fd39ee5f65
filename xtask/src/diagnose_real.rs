//! `cargo xtask diagnose-real`: `twin diagnose` over every log of a
//! directory (by default `tests/fixtures/real/`), as markdown tables for
//! `docs/accuracy.md`: per log what the nominal model gets wrong on held-out data, the
//! causes named with their parameters and uncertainty, the gain each brings
//! on held-out data, and, where a log carries the instrument's own set and
//! drift (NMEA 2000 PGN 130577), the current estimate beside it with their
//! difference; and, for each log with positions and a measured yaw rate,
//! the same log diagnosed again with its yaw-rate records removed
//! ([`yaw_rate_comparison`]): what the measured yaw rate buys.
//!
//! Files in no log format (README, licences) are skipped; a log without
//! positions is diagnosed from its velocities (its model column says so);
//! a log with too few fixes to diagnose gets a row that says so; every other
//! failure is an error. Logs are taken in name order.

use std::fmt::Write;
use std::path::{Path, PathBuf};

use twin_core::diagnose::{COMPONENTS, DiagnoseConfig};
use twin_wire::SourceChoice;
use twin_wire::outputs::FindingJson;
use twin_wire::read::OpenError;

use crate::real_logs::files_by_name;
use twin_cli::diagnose::{DiagnoseError, DiagnoseReport, diagnose_path};
use twin_wire::profile::VesselProfile;

/// Why the report failed.
#[derive(Debug, thiserror::Error)]
pub enum DiagnoseRealError {
    /// The directory cannot be listed.
    #[error("cannot list {path}: {source}")]
    List {
        /// The directory.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A log could not be diagnosed.
    #[error(transparent)]
    Diagnose(#[from] DiagnoseError),
    /// A log's copy without its yaw rates could not be written or read.
    #[error("cannot copy {path} without its yaw rates: {source}")]
    Copy {
        /// The log.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
}

/// One log's outcome.
#[derive(Debug)]
pub enum LogOutcome {
    /// Diagnosed.
    Diagnosed(Box<DiagnoseReport>),
    /// Too few fixes (or, without positions, course/speed records).
    TooFewFixes,
}

/// Diagnoses every log in `dir` (name order).
pub fn diagnose_dir(
    dir: &Path,
    config: &DiagnoseConfig,
) -> Result<Vec<(String, LogOutcome)>, DiagnoseRealError> {
    let files = files_by_name(dir).map_err(|source| DiagnoseRealError::List {
        path: dir.to_path_buf(),
        source,
    })?;
    let mut out = Vec::new();
    for (name, path) in files {
        match diagnose_path(&path, SourceChoice::Best, config, &VesselProfile::otter()) {
            Ok(r) => out.push((name, LogOutcome::Diagnosed(Box::new(r)))),
            Err(DiagnoseError::TooShort { .. }) => out.push((name, LogOutcome::TooFewFixes)),
            Err(DiagnoseError::Log {
                source: OpenError::UnknownFormat | OpenError::Empty,
                ..
            }) => continue,
            Err(e) => return Err(e.into()),
        }
    }
    Ok(out)
}

/// The parameters a reader looks at first, per cause (the others, e.g. the
/// current's north and east components, are in `twin diagnose --json`).
fn headline_parameters(cause: &str) -> &'static [&'static str] {
    match cause {
        "current" => &["speed_mps", "toward_deg"],
        "thruster_loss" => &["side", "loss"],
        "heading_offset" => &["offset_deg"],
        "sog_scale" | "stw_scale" => &["scale"],
        "gnss_latency" => &["latency_s"],
        "lever_arm" => &["x_m", "y_m"],
        "sideslip" | "sideslip_with_speed" => &["lateral_mps_per_radps"],
        _ => &[],
    }
}

fn parameters_text(f: &FindingJson) -> String {
    let wanted = headline_parameters(&f.cause);
    f.parameters
        .iter()
        .filter(|(k, _)| wanted.is_empty() || wanted.contains(&k.as_str()))
        .map(|(k, v)| match (v.as_f64(), f.uncertainty.get(k)) {
            (Some(x), Some(s)) => format!("{k} {x:.3} ± {s:.3}"),
            (Some(x), None) => format!("{k} {x:.3}"),
            _ => format!("{k} {}", v.as_str().unwrap_or_default()),
        })
        .collect::<Vec<_>>()
        .join(", ")
}

fn what_is_wrong(r: &DiagnoseReport) -> String {
    let n = &r.nominal;
    let mut biased: Vec<(usize, f64)> = (0..COMPONENTS.len())
        .filter(|&c| n.measured[c] && n.bias_z[c].abs() > 3.0)
        .map(|c| (c, n.bias_z[c]))
        .collect();
    biased.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
    let mut parts = vec![format!("NIS/dof {:.2}", n.nis_per_dof)];
    parts.extend(
        biased
            .iter()
            .take(3)
            .map(|(c, z)| format!("{} biased ({z:+.1} SE)", COMPONENTS[*c])),
    );
    if let Some(s) = n.signatures.iter().find(|s| s.correlation.abs() >= 0.5) {
        parts.push(format!(
            "{} follows {} ({:+.2})",
            s.component, s.signature, s.correlation
        ));
    }
    parts.join("; ")
}

fn gain_text(f: &FindingJson) -> String {
    let g = &f.gain;
    let mut s = format!(
        "log-lik +{:.0}; NIS/dof {:.2} → {:.2}",
        g.heldout_nll_gain, g.nis_per_dof.before, g.nis_per_dof.after
    );
    for h in &g.prediction_rmse_m {
        let _ = write!(
            s,
            "; {:.0} s RMSE {:.1} → {:.1} m",
            h.horizon_s, h.before, h.after
        );
    }
    if g.prediction_rmse_m.is_empty() {
        s.push_str("; forecast RMSE - (no positions)");
    }
    s
}

/// The instrument comparison of a report with both a current finding and
/// the instrument's set and drift: `(estimate [speed, toward], instrument
/// [speed, toward], |difference| m/s, direction difference deg)`.
pub fn instrument_comparison(r: &DiagnoseReport) -> Option<([f64; 2], [f64; 2], f64, f64)> {
    let i = r.instrument.as_ref()?;
    let f = r.findings.iter().find(|f| f.cause == "current")?;
    let get = |k: &str| f.parameters.get(k).and_then(|v| v.as_f64());
    let (speed, toward) = (get("speed_mps")?, get("toward_deg")?);
    let vec = |s: f64, d: f64| [s * d.to_radians().cos(), s * d.to_radians().sin()];
    let (a, b) = (vec(speed, toward), vec(i.speed_mps, i.toward_deg));
    let diff = (a[0] - b[0]).hypot(a[1] - b[1]);
    let ddir = (toward - i.toward_deg + 540.0).rem_euclid(360.0) - 180.0;
    Some(([speed, toward], [i.speed_mps, i.toward_deg], diff, ddir))
}

/// The base model, the steps and what the log measured.
fn model_text(r: &DiagnoseReport) -> String {
    let measured: Vec<&str> = [
        (!r.measured.position, "no positions: SOG/COG"),
        (r.measured.heading, "heading"),
        (r.measured.speed_through_water, "STW"),
        (r.measured.propellers, "propellers"),
    ]
    .iter()
    .filter(|(m, _)| *m)
    .map(|(_, n)| *n)
    .collect();
    format!(
        "{} ({} steps; {})",
        r.base_model,
        r.steps,
        if measured.is_empty() {
            "position only".to_string()
        } else {
            measured.join(", ")
        }
    )
}

/// The markdown of the diagnosed logs.
pub fn markdown(logs: &[(String, LogOutcome)]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| log | base model | what the nominal model gets wrong (held-out) | cause named (± 1σ) | gain on held-out data |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|");
    for (name, outcome) in logs {
        let r = match outcome {
            LogOutcome::TooFewFixes => {
                let _ = writeln!(
                    s,
                    "| {name} | - | too few fixes or course/speed records: nothing to diagnose | - | - |"
                );
                continue;
            }
            LogOutcome::Diagnosed(r) => r,
        };
        let model = model_text(r);
        if r.findings.is_empty() {
            let _ = writeln!(
                s,
                "| {name} | {model} | {} | none: no cause clears the bars{} | - |",
                what_is_wrong(r),
                if r.unexplained.is_some() {
                    "; **unexplained**"
                } else {
                    ""
                }
            );
            continue;
        }
        for (i, f) in r.findings.iter().enumerate() {
            let (log, model, wrong) = if i == 0 {
                (name.as_str(), model.clone(), what_is_wrong(r))
            } else {
                ("", String::new(), "(and)".to_string())
            };
            let _ = writeln!(
                s,
                "| {log} | {model} | {wrong} | `{}`: {} | {} |",
                f.cause,
                parameters_text(f),
                gain_text(f)
            );
        }
        if let Some(u) = &r.unexplained {
            let _ = writeln!(
                s,
                "|  |  | (after the findings) | **unexplained**: held-out NIS/dof {:.2}{} | - |",
                u.nis_per_dof,
                u.biased
                    .iter()
                    .map(|b| format!("; {} biased ({:+.1} SE)", b.component, b.bias_z))
                    .collect::<String>()
            );
        }
    }
    let comparisons: Vec<String> = logs
        .iter()
        .filter_map(|(name, o)| match o {
            LogOutcome::Diagnosed(r) => instrument_comparison(r).map(|c| (name, r, c)),
            LogOutcome::TooFewFixes => None,
        })
        .map(|(name, r, (est, inst, diff, ddir))| {
            format!(
                "| {name} | {:.2} m/s toward {:.0}° | {:.2} m/s toward {:.0}° | {} | {diff:.2} m/s | {:+.2} m/s | {ddir:+.0}° |",
                est[0],
                est[1],
                inst[0],
                inst[1],
                r.instrument.as_ref().map_or(0, |i| i.samples),
                est[0] - inst[0],
            )
        })
        .collect();
    if !comparisons.is_empty() {
        let _ = writeln!(s);
        let _ = writeln!(
            s,
            "| log | the twin's current | the instrument's set and drift (PGN 130577, mean) | messages | difference as a vector | in speed | in direction |"
        );
        let _ = writeln!(s, "|---|---|---|---:|---:|---:|---:|");
        for c in comparisons {
            let _ = writeln!(s, "{c}");
        }
    }
    s
}

/// The lines of a log's text that carry no yaw rate: without the NMEA 2000
/// rate of turn (PGN 127251) and Furuno gyro rates (PGN 130842) of a
/// canboat text log, nor NMEA 0183 `ROT` sentences.
pub fn without_yaw_rates(text: &str) -> String {
    text.lines()
        .filter(|line| {
            let rate_of_turn_0183 = line.starts_with('$') && line.get(3..7) == Some("ROT,");
            !(line.contains(",127251,") || line.contains(",130842,") || rate_of_turn_0183)
        })
        .map(|line| format!("{line}\n"))
        .collect()
}

/// One log diagnosed with its yaw rates and without them.
#[derive(Debug)]
pub struct YawRateComparison {
    /// The log's file name.
    pub name: String,
    /// As recorded.
    pub with: Box<DiagnoseReport>,
    /// Its yaw-rate records removed ([`without_yaw_rates`]).
    pub without: Box<DiagnoseReport>,
}

/// Every log of `logs` (read from `dir`) that has positions and measures
/// a yaw rate, diagnosed again without its yaw rates (a copy in a
/// temporary directory, removed after).
pub fn yaw_rate_comparison(
    dir: &Path,
    logs: &[(String, LogOutcome)],
    config: &DiagnoseConfig,
) -> Result<Vec<YawRateComparison>, DiagnoseRealError> {
    let scratch = std::env::temp_dir().join(format!("twin-xtask-yaw-rate-{}", std::process::id()));
    let copy_error = |path: &Path| {
        let path = path.to_path_buf();
        move |source| DiagnoseRealError::Copy { path, source }
    };
    std::fs::create_dir_all(&scratch).map_err(copy_error(&scratch))?;
    let mut out = Vec::new();
    for (name, outcome) in logs {
        let LogOutcome::Diagnosed(with) = outcome else {
            continue;
        };
        if !(with.measured.position && with.measured.yaw_rate) {
            continue;
        }
        let source = dir.join(name);
        let text = std::fs::read_to_string(&source).map_err(copy_error(&source))?;
        let copy = scratch.join(name);
        std::fs::write(&copy, without_yaw_rates(&text)).map_err(copy_error(&copy))?;
        let without = diagnose_path(&copy, SourceChoice::Best, config, &VesselProfile::otter());
        std::fs::remove_file(&copy).map_err(copy_error(&copy))?;
        out.push(YawRateComparison {
            name: name.clone(),
            with: with.clone(),
            without: Box::new(without?),
        });
    }
    std::fs::remove_dir(&scratch).map_err(copy_error(&scratch))?;
    Ok(out)
}

/// The position forecast RMSE at `horizon_s` on the held-out part of the
/// model every finding extends, m (each finding's gain is against that
/// model); NaN where nothing was found or there is no forecast at that
/// horizon.
pub fn extended_forecast_rmse_m(report: &DiagnoseReport, horizon_s: f64) -> f64 {
    report
        .findings
        .first()
        .and_then(|f| {
            f.gain
                .prediction_rmse_m
                .iter()
                .find(|h| h.horizon_s == horizon_s)
        })
        .map_or(f64::NAN, |h| h.after)
}

/// The comparison as a markdown table: per log, with and without its yaw
/// rates, the causes named and the extended model's held-out forecast
/// RMSE at 5, 15 and 30 s.
pub fn yaw_rate_markdown(comparisons: &[YawRateComparison]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| log | yaw rate | causes named | forecast RMSE 5 s | 15 s | 30 s |"
    );
    let _ = writeln!(s, "|---|---|---|---:|---:|---:|");
    for c in comparisons {
        for (log, label, r) in [
            (c.name.as_str(), "measured", &c.with),
            ("", "records removed", &c.without),
        ] {
            let causes: Vec<String> = r
                .findings
                .iter()
                .map(|f| format!("`{}` {}", f.cause, parameters_text(f)))
                .collect();
            let rmse = [5.0, 15.0, 30.0].map(|h| {
                let v = extended_forecast_rmse_m(r, h);
                if v.is_finite() {
                    format!("{v:.1} m")
                } else {
                    "-".to_string()
                }
            });
            let _ = writeln!(
                s,
                "| {log} | {label} | {} | {} | {} | {} |",
                if causes.is_empty() {
                    "none".to_string()
                } else {
                    causes.join("; ")
                },
                rmse[0],
                rmse[1],
                rmse[2]
            );
        }
    }
    s
}
