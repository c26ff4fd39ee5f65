//! `twin diagnose LOG`: what the twin's model gets wrong on a log, the named
//! cause, the extended model and the gain on held-out data
//! ([`twin_core::diagnose`] does the work; this module reads the log, adds
//! the instrument's own current where the log has one, and renders text,
//! JSON and SVG).
//!
//! # The JSON schema (`--json`), `"schema": "twin-diagnose/1"`
//! ```text
//! schema          "twin-diagnose/1"
//! log             the path given
//! base_model      "kinetic" (the Otter's twin, propeller data) | "water" (kinematic, any vessel)
//! steps, training_steps, heldout_steps
//! measured        {heading, speed_through_water, yaw_rate, propellers, position}: what the log has;
//!                 position false: no position records, the steps are the course/speed
//!                 instants and only the velocities are diagnosed
//! nominal         residuals of the nominal model on the held-out part (below)
//! extended        the same with every finding
//! findings        [{cause, parameters {name: value | "port"/"starboard"},
//!                   uncertainty {name: standard deviation},
//!                   evidence [text], gain {heldout_nll_gain, heldout_steps,
//!                   nis_per_dof {before, after}, prediction_rmse_m [{horizon_s, before, after}]}}]
//!                 an empty list when no cause clears the bars;
//!                 prediction_rmse_m is empty without positions (nothing to forecast against)
//! rejected        [{cause, parameters, heldout_nll_gain, reason}]: tried, not reported
//! unexplained     {nis_per_dof, biased [{component, bias_z}]} when the findings leave
//!                 the held-out residuals well outside what the filter expects, else null
//! instrument      {speed_mps, toward_deg, samples} the log's own set and drift
//!                 (NMEA 2000 PGN 130577), or null
//! residuals       {steps, mean [7], bias_z [7], rms [7], lag1 [7], nis_per_dof,
//!                  measured [7], signatures [{component, signature, correlation}]}
//!                 components: north, east, sog, cog, heading, stw, yaw_rate
//! ```
//! Causes and parameter names: `current` (`speed_mps`, `toward_deg`, and the
//! `north_mps`, `east_mps` components), `thruster_loss` (`side`, `loss`, and
//! `onset_s`: seconds from the first fix to the loss's onset),
//! `heading_offset` (`offset_deg`: sensor minus true), `sog_scale` (`scale`:
//! reported over true), `gnss_latency` (`latency_s`: how much older the GNSS
//! data are than their stamps), `lever_arm` (`x_m`, `y_m`: the antenna's
//! offset forward and to starboard from the profile's antenna),
//! `stw_scale` (`scale`), `sideslip` (`lateral_mps_per_radps`: the hull's
//! sway per yaw rate), `sideslip_with_speed` (`lateral_mps_per_radps`: a
//! sway growing with the speed through water, at the log's mean speed
//! under way),
//! `yaw_rate_scale` (`scale`: the rate sensor's yaw rate over the true one),
//! `yaw_rate_bias` (`bias_deg_s`: what the rate sensor reads at rest), and
//! the profile's own parameters on the kinetic base, each a `scale` over
//! the profile's value: `surge_damping` (the hull's resistance: fouling),
//! `yaw_damping`, `mass` (mass, inertia and added mass together).

// Measurement components are indexed across parallel arrays.
#![allow(clippy::needless_range_loop)]

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};

use serde::Serialize;
use twin_core::diagnose::{
    BaseModel, COMPONENT_COUNT, COMPONENTS, DiagEvent, DiagnoseConfig, Diagnosis, InnovationRecord,
    ResidualSummary, diagnose, prepare,
};
use twin_core::geodesy::rad_to_compass_deg;
use twin_wire::{
    Assembled, AssemblerConfig, FixAssembler, LogReader, Measurement, ReadOptions, SourceChoice,
};

use crate::svg::{Figure, PALETTE, Style};
use twin_wire::outputs::{FindingJson, UnexplainedJson};
use twin_wire::profile::VesselProfile;

/// Why a log cannot be diagnosed.
#[derive(Debug, thiserror::Error)]
pub enum DiagnoseError {
    /// The log cannot be opened.
    #[error("cannot open log {path}: {source}")]
    Open {
        /// The log.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The log is empty, in no known format, or unreadable.
    #[error("cannot read log {path}: {source}")]
    Log {
        /// The log.
        path: PathBuf,
        /// Why.
        source: twin_wire::read::OpenError,
    },
    /// The log has too few usable fixes.
    #[error(
        "{path}: too few usable GNSS fixes (or, without positions, course/speed records) to diagnose (at least 10 are needed)"
    )]
    TooShort {
        /// The log.
        path: PathBuf,
    },
}

/// The log's measurements as the diagnosis takes them, and the instrument's
/// own current estimate if the log has one.
pub struct LoadedLog {
    /// Fixes, speeds through water and propeller speeds.
    pub events: Vec<DiagEvent>,
    /// Mean set and drift of the log's own current estimate: `(north, east)` m/s and count.
    pub instrument_current: Option<([f64; 2], usize)>,
}

/// Reads a log (any format `twin_wire` reads).
pub fn load(
    input: impl BufRead,
    name: &Path,
    source: SourceChoice,
) -> Result<LoadedLog, DiagnoseError> {
    let reader =
        LogReader::open(input, ReadOptions::default()).map_err(|source| DiagnoseError::Log {
            path: name.to_path_buf(),
            source,
        })?;
    let mut assembler = FixAssembler::new(AssemblerConfig {
        position_source: source,
        ..AssemblerConfig::default()
    });
    // The time line of the log's course/speed instants, used when it has no
    // positions at all.
    let mut velocities = FixAssembler::new(AssemblerConfig {
        fixes_at_course: true,
        ..AssemblerConfig::default()
    });
    let mut events = Vec::new();
    let mut velocity_fixes = Vec::new();
    let mut out = Vec::new();
    let mut set_drift = ([0.0f64; 2], 0usize);
    for item in reader {
        let Ok(record) = item else { continue };
        velocities.push(record, &mut velocity_fixes);
        match record.measurement {
            Measurement::SpeedThroughWater { mps } => events.push(DiagEvent::SpeedThroughWater {
                time_s: record.time_s,
                mps,
            }),
            Measurement::SetDrift { set_rad, drift_mps }
                if set_rad.is_finite() && drift_mps.is_finite() =>
            {
                set_drift.0[0] += drift_mps * set_rad.cos();
                set_drift.0[1] += drift_mps * set_rad.sin();
                set_drift.1 += 1;
            }
            _ => {}
        }
        assembler.push(record, &mut out);
        for a in out.drain(..) {
            push_assembled(&mut events, a);
        }
    }
    assembler.finish(&mut out);
    for a in out.drain(..) {
        push_assembled(&mut events, a);
    }
    if !events.iter().any(|e| matches!(e, DiagEvent::Fix(_))) {
        velocities.finish(&mut velocity_fixes);
        events.extend(velocity_fixes.into_iter().filter_map(|a| match a {
            Assembled::Fix(f) => Some(DiagEvent::Velocity(f)),
            _ => None,
        }));
    }
    let instrument_current = (set_drift.1 > 0).then(|| {
        let n = set_drift.1 as f64;
        ([set_drift.0[0] / n, set_drift.0[1] / n], set_drift.1)
    });
    Ok(LoadedLog {
        events,
        instrument_current,
    })
}

fn push_assembled(events: &mut Vec<DiagEvent>, a: Assembled) {
    match a {
        Assembled::Fix(f) => events.push(DiagEvent::Fix(f)),
        Assembled::Propellers(p) => events.push(DiagEvent::Propellers(p)),
        Assembled::Thrust(_) => {}
    }
}

/// A cause tried and not reported.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RejectedJson {
    /// The cause.
    pub cause: &'static str,
    /// Its fitted parameters.
    pub parameters: BTreeMap<&'static str, f64>,
    /// Its held-out gain.
    pub heldout_nll_gain: f64,
    /// The bar it missed.
    pub reason: String,
}

/// Residual statistics as printed.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ResidualsJson {
    /// Steps.
    pub steps: usize,
    /// Mean innovation per component.
    pub mean: [f64; COMPONENT_COUNT],
    /// Bias in standard errors per component.
    pub bias_z: [f64; COMPONENT_COUNT],
    /// RMS per component.
    pub rms: [f64; COMPONENT_COUNT],
    /// Lag-1 autocorrelation per component.
    pub lag1: [f64; COMPONENT_COUNT],
    /// Mean NIS per degree of freedom.
    pub nis_per_dof: f64,
    /// Which components were measured.
    pub measured: [bool; COMPONENT_COUNT],
    /// Strongest correlations with signatures.
    pub signatures: Vec<SignatureJson>,
}

/// One correlation.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SignatureJson {
    /// Component.
    pub component: &'static str,
    /// Signature.
    pub signature: &'static str,
    /// Correlation.
    pub correlation: f64,
}

fn residuals_json(r: &ResidualSummary) -> ResidualsJson {
    ResidualsJson {
        steps: r.steps,
        mean: r.mean,
        bias_z: r.bias_z,
        rms: r.rms,
        lag1: r.lag1,
        nis_per_dof: r.nis_per_dof,
        measured: r.measured,
        signatures: r
            .signatures
            .iter()
            .map(|s| SignatureJson {
                component: s.component,
                signature: s.signature,
                correlation: s.correlation,
            })
            .collect(),
    }
}

/// The instrument's own current.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct InstrumentJson {
    /// Mean drift, m/s.
    pub speed_mps: f64,
    /// Mean set, degrees true.
    pub toward_deg: f64,
    /// Messages averaged.
    pub samples: usize,
}

/// What the log measures.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MeasuredJson {
    /// True heading.
    pub heading: bool,
    /// Speed through water.
    pub speed_through_water: bool,
    /// Yaw rate (a rate gyro, a rate of turn).
    pub yaw_rate: bool,
    /// Propeller speeds.
    pub propellers: bool,
    /// Positions (else the velocities alone are diagnosed).
    pub position: bool,
}

/// The whole report (`--json`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DiagnoseReport {
    /// `twin-diagnose/1`.
    pub schema: &'static str,
    /// The log.
    pub log: String,
    /// The vessel profile the twin ran on, `name@fingerprint`.
    pub profile: String,
    /// `kinetic` or `water`.
    pub base_model: &'static str,
    /// Steps.
    pub steps: usize,
    /// Training steps.
    pub training_steps: usize,
    /// Held-out steps.
    pub heldout_steps: usize,
    /// What the log measures.
    pub measured: MeasuredJson,
    /// Nominal residuals on the held-out part.
    pub nominal: ResidualsJson,
    /// Residuals with every finding.
    pub extended: ResidualsJson,
    /// The findings.
    pub findings: Vec<FindingJson>,
    /// Causes tried and not reported.
    pub rejected: Vec<RejectedJson>,
    /// What the findings leave unexplained, or null.
    pub unexplained: Option<UnexplainedJson>,
    /// The log's own current estimate, where it has one.
    pub instrument: Option<InstrumentJson>,
    /// The diagnosis itself (for plots; not printed).
    #[serde(skip)]
    pub diagnosis: Option<Diagnosis>,
}

/// Diagnoses loaded measurements.
pub fn diagnose_loaded(
    name: &str,
    log: &LoadedLog,
    config: &DiagnoseConfig,
    profile: &VesselProfile,
) -> Result<DiagnoseReport, DiagnoseError> {
    let prep = prepare(&log.events).ok_or_else(|| DiagnoseError::TooShort {
        path: PathBuf::from(name),
    })?;
    let config = DiagnoseConfig {
        twin: profile.twin_config(config.twin),
        ..config.clone()
    };
    let d = diagnose(&prep, &config);
    Ok(DiagnoseReport {
        schema: "twin-diagnose/1",
        log: name.to_string(),
        profile: profile.identity(),
        base_model: match d.base {
            BaseModel::Kinetic => "kinetic",
            BaseModel::Water => "water",
        },
        steps: d.steps,
        training_steps: d.training_steps,
        heldout_steps: d.steps - d.training_steps,
        measured: MeasuredJson {
            heading: prep.has_heading,
            speed_through_water: prep.has_stw,
            yaw_rate: prep.has_yaw_rate,
            propellers: prep.has_propellers,
            position: prep.has_position,
        },
        nominal: residuals_json(&d.nominal),
        extended: residuals_json(&d.extended),
        findings: d.findings.iter().map(FindingJson::from).collect(),
        rejected: d
            .rejected
            .iter()
            .map(|r| RejectedJson {
                cause: r.cause.name(),
                parameters: r.parameters.iter().map(|(n, v, _)| (*n, *v)).collect(),
                heldout_nll_gain: r.heldout_nll_gain,
                reason: r.reason.clone(),
            })
            .collect(),
        unexplained: d.unexplained.as_ref().map(UnexplainedJson::from),
        instrument: log
            .instrument_current
            .map(|([n, e], samples)| InstrumentJson {
                speed_mps: n.hypot(e),
                toward_deg: rad_to_compass_deg(e.atan2(n)),
                samples,
            }),
        diagnosis: Some(d),
    })
}

/// Diagnoses the log at `path`.
pub fn diagnose_path(
    path: &Path,
    source: SourceChoice,
    config: &DiagnoseConfig,
    profile: &VesselProfile,
) -> Result<DiagnoseReport, DiagnoseError> {
    let log = load_path(path, source)?;
    diagnose_loaded(&path.display().to_string(), &log, config, profile)
}

/// Opens and reads the log at `path` ([`load`]).
pub fn load_path(path: &Path, source: SourceChoice) -> Result<LoadedLog, DiagnoseError> {
    let file = File::open(path).map_err(|source| DiagnoseError::Open {
        path: path.to_path_buf(),
        source,
    })?;
    load(BufReader::new(file), path, source)
}

fn value_text(v: &serde_json::Value) -> String {
    match v {
        serde_json::Value::Number(n) => n.as_f64().map(|x| format!("{x:.3}")).unwrap_or_default(),
        other => other.to_string().trim_matches('"').to_string(),
    }
}

/// One finding of the human summary.
fn write_finding(o: &mut String, i: usize, f: &FindingJson) {
    use std::fmt::Write;
    let params: Vec<String> = f
        .parameters
        .iter()
        .map(|(k, v)| match f.uncertainty.get(k) {
            Some(s) => format!("{k} {} +- {s:.3}", value_text(v)),
            None => format!("{k} {}", value_text(v)),
        })
        .collect();
    let _ = writeln!(
        o,
        "  finding {}    {}: {}",
        i + 1,
        f.cause,
        params.join(", ")
    );
    for e in &f.evidence {
        let _ = writeln!(o, "               evidence: {e}");
    }
    let g = &f.gain;
    let rmse: Vec<String> = g
        .prediction_rmse_m
        .iter()
        .map(|h| format!("{:.0} s {:.2} m -> {:.2} m", h.horizon_s, h.before, h.after))
        .collect();
    let _ = writeln!(
        o,
        "               gain on held-out data: log-likelihood +{:.1}, NIS per dof {:.2} -> {:.2}; position prediction RMSE {}",
        g.heldout_nll_gain,
        g.nis_per_dof.before,
        g.nis_per_dof.after,
        if rmse.is_empty() {
            "- (no positions)".to_string()
        } else {
            rmse.join(", ")
        }
    );
}

/// The human summary.
pub fn render_text(r: &DiagnoseReport) -> String {
    use std::fmt::Write;
    let mut o = String::new();
    let _ = writeln!(o, "twin diagnose {}", r.log);
    let _ = writeln!(o, "profile: {}", r.profile);
    let _ = writeln!(
        o,
        "  model        {} ({}), {} steps: fitted on the first {}, judged on the last {}",
        r.base_model,
        if r.base_model == "kinetic" {
            "the Otter's twin driven by the logged propeller speeds"
        } else {
            "a kinematic vessel through water; no propeller data"
        },
        r.steps,
        r.training_steps,
        r.heldout_steps
    );
    let _ = writeln!(
        o,
        "  measured     position {}, heading {}, speed through water {}, yaw rate {}, propellers {}",
        r.measured.position,
        r.measured.heading,
        r.measured.speed_through_water,
        r.measured.yaw_rate,
        r.measured.propellers
    );
    let n = &r.nominal;
    let _ = writeln!(
        o,
        "  nominal      NIS per dof {:.2} on held-out data (1.0 when the model explains the data)",
        n.nis_per_dof
    );
    for c in 0..COMPONENT_COUNT {
        if n.measured[c] && n.bias_z[c].abs() > 3.0 {
            let _ = writeln!(
                o,
                "               {} innovations biased: mean {:.4} ({:.1} standard errors)",
                COMPONENTS[c], n.mean[c], n.bias_z[c]
            );
        }
    }
    for s in n
        .signatures
        .iter()
        .filter(|s| s.correlation.abs() >= 0.3)
        .take(3)
    {
        let _ = writeln!(
            o,
            "               {} innovations follow {} (correlation {:.2})",
            s.component, s.signature, s.correlation
        );
    }
    if r.findings.is_empty() {
        let _ = writeln!(
            o,
            "  findings     none: {}",
            if r.unexplained.is_some() {
                "no cause of the catalogue clears the bars"
            } else {
                "the nominal model explains the data (no cause clears the bars)"
            }
        );
    }
    for (i, f) in r.findings.iter().enumerate() {
        write_finding(&mut o, i, f);
    }
    if let Some(u) = &r.unexplained {
        let biased: Vec<String> = u
            .biased
            .iter()
            .map(|b| format!("{} mean at {:.1} standard errors", b.component, b.bias_z))
            .collect();
        let _ = writeln!(
            o,
            "  UNEXPLAINED  the model is still wrong on held-out data, in a way no cause of the catalogue describes: NIS per dof {:.2}{}{}",
            u.nis_per_dof,
            if biased.is_empty() { "" } else { "; " },
            biased.join(", ")
        );
    }
    if let Some(i) = &r.instrument {
        let _ = writeln!(
            o,
            "  instrument   the log's own set and drift: {:.2} m/s toward {:.0} deg ({} messages)",
            i.speed_mps, i.toward_deg, i.samples
        );
    }
    for rej in &r.rejected {
        let _ = writeln!(o, "  not named    {}: {}", rej.cause, rej.reason);
    }
    o
}

/// A profile with the findings that describe the vessel itself carried
/// into it (`twin diagnose --out`), and what was not carried.
#[derive(Debug, Clone, PartialEq)]
pub struct DiagnosedProfile {
    /// The starting profile with the findings applied.
    pub profile: VesselProfile,
    /// What was carried, one line each (`lever_arm: antenna ...`).
    pub carried: Vec<String>,
    /// The findings a profile does not hold: a sensor to calibrate, the
    /// water, a propeller; and an antenna the profile would have off the
    /// hull, with why.
    pub not_carried: Vec<String>,
}

/// The default name of a profile diagnosed from one named `start`: it ends
/// in `-diagnosed` (once), within a profile name's 64 characters.
pub fn diagnosed_name(start: &str) -> String {
    const SUFFIX: &str = "-diagnosed";
    if start.ends_with(SUFFIX) {
        return start.to_owned();
    }
    let keep = start.len().min(64 - SUFFIX.len());
    format!("{}{SUFFIX}", &start[..keep])
}

/// `start` with the `findings` of a diagnosis of `log` that describe the
/// vessel carried into it, named `name`: a `lever_arm` moves the antenna by its offset (a
/// lever arm is found against the profile's antenna), and a
/// `surge_damping`, `yaw_damping` or `mass` scale multiplies the
/// profile's numbers as the diagnosis scaled them
/// ([`twin_core::vessel::VesselParams::scaled`]; a mass scale applies to the
/// mass, the yaw inertia and the added mass alike). The rest stays out: a
/// heading offset, a scale, a latency or a rate sensor's bias belong to a
/// sensor, a current to the water, a loss to a propeller; and a lever arm
/// that would put the antenna off the hull (the profile's bounds) is
/// evidence of something else, not carried.
pub fn profile_with_findings(
    start: &VesselProfile,
    findings: &[FindingJson],
    log: &str,
    name: &str,
) -> DiagnosedProfile {
    let number = |f: &FindingJson, key: &str| f.parameters.get(key).and_then(|v| v.as_f64());
    let mut profile = start.clone();
    let mut scales = [1.0; 4];
    let mut carried = Vec::new();
    let mut not_carried = Vec::new();
    for f in findings {
        // The slot of `VesselParams::scaled`'s scales a cause sets.
        let scale_slot = match f.cause.as_str() {
            "lever_arm" => {
                let (Some(x), Some(y)) = (number(f, "x_m"), number(f, "y_m")) else {
                    not_carried.push(f.cause.clone());
                    continue;
                };
                let mut moved = profile.clone();
                moved.gnss.antenna_forward_m += x;
                moved.gnss.antenna_starboard_m += y;
                // An antenna the profile cannot hold (off the hull) is
                // evidence of something else (a latency aliased with a
                // fore-and-aft offset), not a place to write.
                if let Err(e) = moved.validate() {
                    not_carried.push(format!("lever_arm ({e})"));
                    continue;
                }
                profile = moved;
                carried.push(format!(
                    "lever_arm: antenna {:.2} m forward, {:.2} m to starboard",
                    profile.gnss.antenna_forward_m, profile.gnss.antenna_starboard_m
                ));
                continue;
            }
            "surge_damping" => 0,
            "yaw_damping" => 1,
            "mass" => 3,
            _ => {
                not_carried.push(f.cause.clone());
                continue;
            }
        };
        let Some(scale) = number(f, "scale") else {
            not_carried.push(f.cause.clone());
            continue;
        };
        scales[scale_slot] = scale;
        carried.push(format!("{}: the profile's times {scale:.3}", f.cause));
    }
    // As `VesselParams::scaled` scales them, on the profile's own numbers
    // (the others keep their bits, and the profile's fingerprint moves only
    // with what was carried).
    let [surge, yaw, _, mass] = scales;
    profile.damping.surge_n_per_mps *= surge;
    profile.damping.yaw_nm_per_radps *= yaw;
    let m = &mut profile.mass;
    for value in [
        &mut m.mass_kg,
        &mut m.yaw_inertia_kgm2,
        &mut m.added_mass_surge_kg,
        &mut m.added_mass_sway_kg,
        &mut m.added_inertia_yaw_kgm2,
    ] {
        *value *= mass;
    }
    profile.name = name.to_owned();
    profile.description = if carried.is_empty() {
        format!(
            "{} (diagnosed on {log}: nothing carried)",
            start.description
        )
    } else {
        let causes: Vec<&str> = carried
            .iter()
            .map(|c| c.split(':').next().unwrap_or(c))
            .collect();
        format!(
            "{} (with the findings of twin diagnose on {log}: {})",
            start.description,
            causes.join(", ")
        )
    }
    .trim_start_matches(' ')
    .to_owned();
    DiagnosedProfile {
        profile,
        carried,
        not_carried,
    }
}

/// Writes SVG figures of the held-out innovations before and after the
/// findings into `dir`: one file per measured component.
pub fn write_plots(r: &DiagnoseReport, dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir)?;
    let Some(d) = &r.diagnosis else {
        return Ok(Vec::new());
    };
    let mut written = Vec::new();
    let series = |records: &[InnovationRecord], c: usize| -> Vec<(f64, f64)> {
        let t0 = records.first().map(|r| r.time_s).unwrap_or(0.0);
        records
            .iter()
            .filter(|r| r.available[c])
            .map(|r| (r.time_s - t0, r.innovation[c]))
            .collect()
    };
    for c in 0..COMPONENT_COUNT {
        if !d.nominal.measured[c] {
            continue;
        }
        let mut fig = Figure::new(
            &format!(
                "{} innovations on held-out data, before and after the findings",
                COMPONENTS[c]
            ),
            "time into the held-out part, s",
            &format!("{} innovation", COMPONENTS[c]),
        );
        fig.line(
            "nominal model",
            PALETTE[1],
            Style::Dots,
            series(&d.nominal_records, c),
        );
        fig.line(
            "extended model",
            PALETTE[0],
            Style::Dots,
            series(&d.extended_records, c),
        );
        let path = dir.join(format!("diagnose_{}.svg", COMPONENTS[c]));
        std::fs::write(&path, fig.render())?;
        written.push(path);
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn finding(cause: &str, parameters: serde_json::Value) -> FindingJson {
        serde_json::from_value(serde_json::json!({
            "cause": cause,
            "parameters": parameters,
            "uncertainty": {},
            "evidence": [],
            "gain": {
                "heldout_nll_gain": 20.0,
                "heldout_steps": 100,
                "nis_per_dof": {"before": 1.3, "after": 1.0},
                "prediction_rmse_m": []
            }
        }))
        .unwrap()
    }

    fn residuals(nis_per_dof: f64) -> ResidualsJson {
        ResidualsJson {
            steps: 100,
            mean: [0.0; COMPONENT_COUNT],
            bias_z: [0.0; COMPONENT_COUNT],
            rms: [0.0; COMPONENT_COUNT],
            lag1: [0.0; COMPONENT_COUNT],
            nis_per_dof,
            measured: [true; COMPONENT_COUNT],
            signatures: Vec::new(),
        }
    }

    /// With no finding, the text says the nominal model explains the data
    /// only where nothing is left unexplained.
    #[test]
    fn no_finding_is_no_explanation_where_the_residual_is_unexplained() {
        let mut report = DiagnoseReport {
            schema: "twin-diagnose/1",
            log: "log.jsonl".to_string(),
            profile: "otter@0".to_string(),
            base_model: "kinetic",
            steps: 250,
            training_steps: 150,
            heldout_steps: 100,
            measured: MeasuredJson {
                heading: false,
                speed_through_water: false,
                yaw_rate: false,
                propellers: true,
                position: true,
            },
            nominal: residuals(1.1),
            extended: residuals(1.1),
            findings: Vec::new(),
            rejected: Vec::new(),
            unexplained: None,
            instrument: None,
            diagnosis: None,
        };
        let text = render_text(&report);
        assert!(text.contains("findings     none: the nominal model explains the data"));
        report.nominal = residuals(437.0);
        report.extended = residuals(437.0);
        report.unexplained = Some(UnexplainedJson {
            nis_per_dof: 437.0,
            biased: Vec::new(),
        });
        let text = render_text(&report);
        assert!(!text.contains("explains the data ("), "{text}");
        assert!(
            text.contains("findings     none: no cause of the catalogue clears the bars"),
            "{text}"
        );
        assert!(text.contains("UNEXPLAINED"), "{text}");
    }

    #[test]
    fn an_antenna_the_profile_would_have_off_the_hull_is_not_carried() {
        let otter = VesselProfile::otter();
        let half_length = otter.hull.length_m / 2.0;
        let findings = [finding(
            "lever_arm",
            serde_json::json!({"x_m": -(half_length + 0.1), "y_m": 0.1}),
        )];
        let d = profile_with_findings(&otter, &findings, "log.jsonl", "p");
        assert!(d.carried.is_empty(), "{:?}", d.carried);
        assert_eq!(d.not_carried.len(), 1);
        assert!(
            d.not_carried[0].starts_with("lever_arm (gnss."),
            "{:?}",
            d.not_carried
        );
        assert_eq!(d.profile.gnss, otter.gnss);
        d.profile.validate().unwrap();
        // On the hull, it is carried, onto the profile's own antenna.
        let mut start = otter.clone();
        start.gnss.antenna_forward_m = 0.2;
        let findings = [finding(
            "lever_arm",
            serde_json::json!({"x_m": 0.3, "y_m": -0.1}),
        )];
        let d = profile_with_findings(&start, &findings, "log.jsonl", "p");
        assert_eq!(d.profile.gnss.antenna_forward_m, 0.5);
        assert_eq!(d.profile.gnss.antenna_starboard_m, -0.1);
    }

    #[test]
    fn hull_scales_are_carried_as_the_diagnosis_ran_them_and_the_rest_stays_out() {
        let otter = VesselProfile::otter();
        let findings = [
            finding("heading_offset", serde_json::json!({"offset_deg": 4.0})),
            finding("mass", serde_json::json!({"scale": 1.25})),
            finding("yaw_damping", serde_json::json!({"scale": 0.8})),
            finding(
                "thruster_loss",
                serde_json::json!({"side": "port", "loss": 0.2}),
            ),
        ];
        let d = profile_with_findings(&otter, &findings, "trial.jsonl", "heavier");
        assert_eq!(d.not_carried, ["heading_offset", "thruster_loss"]);
        assert_eq!(d.carried.len(), 2);
        assert_eq!(d.profile.name, "heavier");
        assert!(
            d.profile
                .description
                .ends_with("trial.jsonl: mass, yaw_damping)")
        );
        let ran_on = otter.params().scaled([1.0, 0.8, 1.0, 1.25]);
        let written = d.profile.params();
        assert!((written.mass_matrix - ran_on.mass_matrix).norm() <= 1e-9);
        assert!((written.mass_kg - ran_on.mass_kg).abs() <= 1e-9);
        for (w, r) in written.added_mass.iter().zip(ran_on.added_mass) {
            assert!((w - r).abs() <= 1e-9);
        }
        for (w, r) in written.linear_damping.iter().zip(ran_on.linear_damping) {
            assert!((w - r).abs() <= 1e-9 * r.abs());
        }
        assert_eq!(d.profile.propellers, otter.propellers);
        assert_eq!(d.profile.hull, otter.hull);
    }

    #[test]
    fn a_diagnosed_profiles_name_ends_in_diagnosed_once_and_stays_a_name() {
        assert_eq!(diagnosed_name("otter"), "otter-diagnosed");
        assert_eq!(diagnosed_name("otter-diagnosed"), "otter-diagnosed");
        let long = "a".repeat(64);
        let name = diagnosed_name(&long);
        assert_eq!(name.len(), 64);
        assert!(name.ends_with("-diagnosed"));
    }
}
