//! The figures of `twin analyze --plot DIR` (SVG, [`crate::svg`]), like the
//! seed's:
//! - `track.svg`: the measured fixes and the twin's estimated track, north
//!   against east in metres from the first fix (with the truth when given);
//! - `faults.svg`: the fault estimates over time with their 1-sigma bands:
//!   the extended twin's per-propeller losses where the log has propeller
//!   speeds (with the true losses when a truth file gives them), else the
//!   seed method's input faults `[theta_a, theta_r]`, titled as what they
//!   are;
//! - with a truth file, `prediction.svg` (the forecast from the middle of the
//!   run against the true track) and `prediction_error.svg` (its north and
//!   east errors over time inside its own 2-sigma bands).

use std::path::{Path, PathBuf};

use crate::analyze::{Analysis, Series};
use crate::svg::{Figure, PALETTE, Style};

/// Why the figures could not be written.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// The analysis was run without keeping series.
    #[error("the analysis kept no series to plot")]
    NoSeries,
    /// A file or the directory cannot be written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
}

/// The figures of an analysis, by file name.
pub fn figures(analysis: &Analysis) -> Result<Vec<(&'static str, Figure)>, PlotError> {
    let series = analysis.series.as_ref().ok_or(PlotError::NoSeries)?;
    let mut out = vec![
        ("track.svg", track(analysis, series)),
        ("faults.svg", faults(analysis, series)),
    ];
    if !series.prediction.is_empty() {
        let (track, error) = prediction(analysis, series);
        out.push(("prediction.svg", track));
        out.push(("prediction_error.svg", error));
    }
    Ok(out)
}

/// Writes the figures into `dir` (created if needed); returns the paths.
pub fn write_plots(analysis: &Analysis, dir: &Path) -> Result<Vec<PathBuf>, PlotError> {
    std::fs::create_dir_all(dir).map_err(|source| PlotError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let mut paths = Vec::new();
    for (name, fig) in figures(analysis)? {
        let path = dir.join(name);
        std::fs::write(&path, fig.render()).map_err(|source| PlotError::Io {
            path: path.clone(),
            source,
        })?;
        paths.push(path);
    }
    Ok(paths)
}

fn log_name(analysis: &Analysis) -> String {
    Path::new(&analysis.log).file_name().map_or_else(
        || analysis.log.clone(),
        |n| n.to_string_lossy().into_owned(),
    )
}

fn track(analysis: &Analysis, s: &Series) -> Figure {
    let mut fig = Figure::new(
        &format!("{}: track, measured and estimated", log_name(analysis)),
        "east of the first fix (m)",
        "north of the first fix (m)",
    );
    fig.equal_aspect = true;
    fig.height_px = 560.0;
    let pts = s.track.items();
    if !s.truth_track.is_empty() {
        fig.line(
            "truth",
            PALETTE[5],
            Style::Line,
            s.truth_track.iter().map(|(_, p)| (p[1], p[0])).collect(),
        );
    }
    fig.line(
        "measured (GNSS)",
        PALETTE[0],
        Style::Dots,
        pts.iter().map(|p| (p.measured[1], p.measured[0])).collect(),
    );
    let model = match analysis.model {
        Some("kinetic") => "estimated (extended twin)",
        _ => "estimated (seed model)",
    };
    fig.line(
        model,
        PALETTE[1],
        Style::Line,
        pts.iter()
            .map(|p| (p.estimated[1], p.estimated[0]))
            .collect(),
    );
    fig
}

fn faults(analysis: &Analysis, s: &Series) -> Figure {
    let pts = s.faults.items();
    if analysis.thrusters.observable {
        let mut fig = Figure::new(
            &format!(
                "{}: propeller loss, extended twin (1-sigma bands)",
                log_name(analysis)
            ),
            "time since the start of the log (s)",
            "loss of effectiveness (-)",
        );
        let kin: Vec<_> = pts.iter().filter(|p| p.kinetic).collect();
        for (i, name) in [(0, "port"), (1, "starboard")] {
            let colour = PALETTE[i];
            fig.band(
                &format!("{name} +-1 sigma"),
                colour,
                kin.iter()
                    .map(|p| {
                        (
                            p.elapsed_s,
                            p.loss[i] - p.loss_sigma[i],
                            p.loss[i] + p.loss_sigma[i],
                        )
                    })
                    .collect(),
            );
            fig.line(
                &format!("{name} loss"),
                colour,
                Style::Line,
                kin.iter().map(|p| (p.elapsed_s, p.loss[i])).collect(),
            );
            if !s.truth_loss.is_empty() {
                fig.line(
                    &format!("{name} true loss"),
                    colour,
                    Style::Dashed,
                    s.truth_loss.iter().map(|(t, l)| (*t, l[i])).collect(),
                );
            }
        }
        fig
    } else {
        let mut fig = Figure::new(
            &format!(
                "{}: seed method input faults (not thrust loss: GNSS only)",
                log_name(analysis)
            ),
            "time since the start of the log (s)",
            "input fault (-)",
        );
        for (i, name) in [(0, "theta_a (acceleration)"), (1, "theta_r (course rate)")] {
            let colour = PALETTE[i + 2];
            fig.band(
                &format!("{name} +-1 sigma"),
                colour,
                pts.iter()
                    .map(|p| {
                        (
                            p.elapsed_s,
                            p.input_faults[i] - p.input_fault_sigma[i],
                            p.input_faults[i] + p.input_fault_sigma[i],
                        )
                    })
                    .collect(),
            );
            fig.line(
                name,
                colour,
                Style::Line,
                pts.iter()
                    .map(|p| (p.elapsed_s, p.input_faults[i]))
                    .collect(),
            );
        }
        fig
    }
}

fn prediction(analysis: &Analysis, s: &Series) -> (Figure, Figure) {
    let model = analysis
        .prediction
        .as_ref()
        .map_or("forecast", |p| match p.model {
            "kinetic" => "extended twin through the recorded shaft speeds",
            _ => "seed model, inputs held",
        });
    let mut track = Figure::new(
        &format!("{}: forecast from mid-run ({model})", log_name(analysis)),
        "east of the first fix (m)",
        "north of the first fix (m)",
    );
    track.equal_aspect = true;
    track.height_px = 560.0;
    let t0 = s.prediction.first().map_or(0.0, |p| p.elapsed_s);
    track.line(
        "truth",
        PALETTE[5],
        Style::Line,
        s.truth_track
            .iter()
            .filter(|(t, _)| *t >= t0 - 1e-9)
            .map(|(_, p)| (p[1], p[0]))
            .collect(),
    );
    track.line(
        "forecast",
        PALETTE[1],
        Style::Dashed,
        s.prediction
            .iter()
            .map(|p| (p.forecast[1], p.forecast[0]))
            .collect(),
    );
    let mut error = Figure::new(
        &format!("{}: forecast error against the truth", log_name(analysis)),
        "time since the start of the log (s)",
        "forecast minus truth (m)",
    );
    error.band(
        "north +-2 sigma",
        PALETTE[0],
        s.prediction
            .iter()
            .map(|p| (p.elapsed_s, -2.0 * p.sigma[0], 2.0 * p.sigma[0]))
            .collect(),
    );
    error.band(
        "east +-2 sigma",
        PALETTE[1],
        s.prediction
            .iter()
            .map(|p| (p.elapsed_s, -2.0 * p.sigma[1], 2.0 * p.sigma[1]))
            .collect(),
    );
    error.line(
        "north error",
        PALETTE[0],
        Style::Line,
        s.prediction
            .iter()
            .map(|p| (p.elapsed_s, p.forecast[0] - p.truth[0]))
            .collect(),
    );
    error.line(
        "east error",
        PALETTE[1],
        Style::Line,
        s.prediction
            .iter()
            .map(|p| (p.elapsed_s, p.forecast[1] - p.truth[1]))
            .collect(),
    );
    (track, error)
}
