//! `twin identify`: a vessel profile from a trial of the healthy vessel
//! (`twin_core::diagnose::identify`): each parameter with its uncertainty,
//! what the trial could not excite, the gain on the held-out part of the
//! trial, and the identified profile as a file (docs/profiles.md).

use std::io::BufRead;
use std::path::{Path, PathBuf};

use serde::Serialize;
use twin_core::diagnose::{Fallback, Identification, IdentifyConfig, identify, prepare};
use twin_wire::assemble::SourceChoice;
use twin_wire::profile::{IdentifiedProfile, VesselProfile};

use crate::diagnose::{DiagnoseError, LoadedLog, load, load_path};

/// Why a trial gave no profile.
#[derive(Debug, thiserror::Error)]
pub enum IdentifyError {
    /// The log cannot be read.
    #[error(transparent)]
    Log(#[from] DiagnoseError),
    /// The log has no propeller speeds, or too few fixes.
    #[error(
        "{path}: identification needs a trial with propeller speeds and at least 10 GNSS fixes"
    )]
    NotATrial {
        /// The log.
        path: PathBuf,
    },
}

/// One parameter as reported.
#[derive(Debug, Clone, Serialize)]
pub struct ParameterJson {
    /// What it is.
    pub name: &'static str,
    /// The identified value over the starting profile's.
    pub scale: f64,
    /// Relative standard deviation after the trial; `null` in the JSON
    /// where the likelihood has no curvature to give one (infinite: not
    /// identifiable).
    pub sigma: f64,
    /// `identified`, `not_identifiable` (see `fallback`) or `held` (the
    /// force scale, kept from the starting profile).
    pub verdict: &'static str,
    /// What the written profile holds when the trial did not pin the
    /// parameter down: `starting_profile` (its value there) or
    /// `follows_the_mass` (the yaw inertia: the starting profile's times
    /// the identified mass scale, its radius of gyration kept).
    pub fallback: &'static str,
}

/// What `twin identify` reports (`--json`).
#[derive(Debug, Clone, Serialize)]
pub struct IdentifyReport {
    /// `twin-identify/2`.
    pub schema: &'static str,
    /// The trial.
    pub log: String,
    /// The starting profile, `name@fingerprint`.
    pub start_profile: String,
    /// The identified profile, `name@fingerprint`.
    pub profile: String,
    /// Rounds of the fit.
    pub rounds: usize,
    /// Steps fitted on and held out.
    pub training_steps: usize,
    /// Held-out steps.
    pub heldout_steps: usize,
    /// Each parameter.
    pub parameters: Vec<ParameterJson>,
    /// Held-out negative log-likelihood per step, starting and identified.
    pub heldout_nll_per_step: [f64; 2],
    /// Held-out position prediction RMSE per horizon: `[horizon s, starting m, identified m]`.
    pub heldout_rmse_m: Vec<[f64; 3]>,
    /// The identified profile, as written.
    #[serde(skip)]
    pub identified: VesselProfile,
}

/// Identifies the profile of the vessel of the trial at `path`, starting
/// from `start`, and names the result `name`.
pub fn identify_path(
    path: &Path,
    source: SourceChoice,
    start: &VesselProfile,
    name: &str,
    config: &IdentifyConfig,
) -> Result<IdentifyReport, IdentifyError> {
    identify_log(&load_path(path, source)?, path, start, name, config)
}

/// [`identify_path`] of a log read from `input` (named `path` in the
/// report and in errors).
pub fn identify_reader(
    input: impl BufRead,
    path: &Path,
    source: SourceChoice,
    start: &VesselProfile,
    name: &str,
    config: &IdentifyConfig,
) -> Result<IdentifyReport, IdentifyError> {
    identify_log(&load(input, path, source)?, path, start, name, config)
}

/// The identification of the loaded `log` of the trial at `path`.
fn identify_log(
    log: &LoadedLog,
    path: &Path,
    start: &VesselProfile,
    name: &str,
    config: &IdentifyConfig,
) -> Result<IdentifyReport, IdentifyError> {
    let not_a_trial = || IdentifyError::NotATrial {
        path: path.to_path_buf(),
    };
    let prep = prepare(&log.events).ok_or_else(not_a_trial)?;
    let found = identify(&prep, &start.params(), config).ok_or_else(not_a_trial)?;
    Ok(report(&path.display().to_string(), start, name, &found))
}

/// The report of `found`, and the identified profile.
fn report(log: &str, start: &VesselProfile, name: &str, found: &Identification) -> IdentifyReport {
    let mut identified = start.with_params(&found.params);
    identified.name = name.to_owned();
    identified.description = format!("{} (identified from {log})", start.description)
        .trim_start_matches(' ')
        .to_owned();
    let [surge, yaw, thrust, mass] = found.profile_sigma;
    identified.identified = Some(IdentifiedProfile {
        surge_damping_sigma: surge,
        yaw_damping_sigma: yaw,
        thrust_sigma: thrust,
        mass_sigma: mass,
        trial: log.to_owned(),
    });
    let parameters = found
        .estimates
        .iter()
        .map(|e| ParameterJson {
            name: e.name,
            scale: e.scale,
            sigma: e.sigma,
            verdict: if e.held {
                "held"
            } else if e.identified {
                "identified"
            } else {
                "not_identifiable"
            },
            fallback: match e.fallback {
                Fallback::StartingProfile => "starting_profile",
                Fallback::FollowsTheMass => "follows_the_mass",
            },
        })
        .collect();
    let heldout_rmse_m = found
        .before
        .rmse_m
        .iter()
        .zip(&found.after.rmse_m)
        .map(|((h, before), (_, after))| [*h, *before, *after])
        .collect();
    IdentifyReport {
        schema: "twin-identify/2",
        log: log.to_owned(),
        start_profile: start.identity(),
        profile: identified.identity(),
        rounds: found.rounds,
        training_steps: found.training_steps,
        heldout_steps: found.heldout_steps,
        parameters,
        heldout_nll_per_step: [found.before.nll_per_step, found.after.nll_per_step],
        heldout_rmse_m,
        identified,
    }
}

/// The human summary.
pub fn render_text(r: &IdentifyReport) -> String {
    use std::fmt::Write;
    let mut o = String::new();
    let _ = writeln!(o, "twin identify {}", r.log);
    let _ = writeln!(o, "  from profile {}", r.start_profile);
    let _ = writeln!(
        o,
        "  fitted on {} steps, judged on {} held-out steps, {} rounds",
        r.training_steps, r.heldout_steps, r.rounds
    );
    let _ = writeln!(o, "  parameter             x start   sigma   verdict");
    for p in &r.parameters {
        let verdict = match p.verdict {
            "held" => "held: the force scale, from the starting profile",
            "not_identifiable" if p.fallback == "follows_the_mass" => {
                "not identifiable from this trial: follows the mass"
            }
            "not_identifiable" => {
                "not identifiable from this trial: kept from the starting profile"
            }
            _ => "identified",
        };
        let _ = writeln!(
            o,
            "  {:<20}  {:>7.3}  {:>6.3}   {verdict}",
            p.name, p.scale, p.sigma
        );
    }
    let [before, after] = r.heldout_nll_per_step;
    let _ = writeln!(
        o,
        "  held out: log-likelihood per step {:.3} -> {:.3} (gain {:.3})",
        -before,
        -after,
        before - after
    );
    for [h, before, after] in &r.heldout_rmse_m {
        let _ = writeln!(
            o,
            "  held out: position error at {h:.0} s {before:.2} m -> {after:.2} m"
        );
    }
    let _ = writeln!(o, "  profile {}", r.profile);
    o
}
