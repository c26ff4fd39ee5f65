//! Per-vessel calibration files: what the twin has learnt (the fault
//! estimate, its covariance, the anti-windup memory and the decisions),
//! saved periodically and on shutdown, restored when the vessel's twin
//! starts, so a restart does not re-learn for minutes.
//!
//! One JSON file per vessel, `{dir}/{vessel}.json`, written atomically (a
//! temporary file renamed over the old one), so a crash mid-write leaves the
//! previous calibration intact.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use twin_core::decision::{ThrusterDecision, ThrusterStatus};
use twin_core::twin::{Calibration, FaultSource};

/// The file format (version 1).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CalibrationFile {
    /// Format version.
    pub version: u32,
    /// Vessel id.
    pub vessel: String,
    /// `kinetic` or `seed_method`.
    pub source: String,
    /// Fault estimate `[port, starboard]` (or the seed's `[a, r]`).
    pub theta: [f64; 2],
    /// Fault covariance, row-major.
    pub theta_covariance: [f64; 4],
    /// Anti-windup memory per fault.
    pub held_information: [f64; 2],
    /// Status per thruster.
    pub status: [String; 2],
    /// Onset per thruster, seconds since the epoch.
    pub onset_time_s: [Option<f64>; 2],
    /// Time of the last fix learnt from, seconds since the epoch.
    pub time_s: f64,
}

/// Why a calibration could not be loaded or saved.
#[derive(Debug, thiserror::Error)]
pub enum PersistError {
    /// Reading or writing failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The error.
        source: std::io::Error,
    },
    /// The file is not a calibration.
    #[error("{path}: not a calibration file: {message}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}

fn status_name(s: ThrusterStatus) -> String {
    s.name().to_string()
}

fn status_from(name: &str) -> Option<ThrusterStatus> {
    Some(match name {
        "not_excited" => ThrusterStatus::NotExcited,
        "nominal" => ThrusterStatus::Nominal,
        "suspect" => ThrusterStatus::Suspect,
        "fault" => ThrusterStatus::Fault,
        _ => return None,
    })
}

impl CalibrationFile {
    /// From the twin's calibration.
    pub fn new(vessel: &str, c: &Calibration) -> Self {
        Self {
            version: 1,
            vessel: vessel.to_string(),
            source: match c.source {
                FaultSource::Kinetic => "kinetic",
                FaultSource::SeedMethod => "seed_method",
            }
            .to_string(),
            theta: c.theta,
            theta_covariance: c.theta_covariance,
            held_information: c.held_information,
            status: c.decisions.map(|d| status_name(d.status)),
            onset_time_s: c.decisions.map(|d| d.onset_time_s),
            time_s: c.time_s,
        }
    }

    /// Back to the twin's calibration, checked.
    pub fn to_calibration(&self) -> Result<Calibration, String> {
        if self.version != 1 {
            return Err(format!("unknown version {}", self.version));
        }
        let source = match self.source.as_str() {
            "kinetic" => FaultSource::Kinetic,
            "seed_method" => FaultSource::SeedMethod,
            other => return Err(format!("unknown source {other:?}")),
        };
        let numbers = self
            .theta
            .iter()
            .chain(&self.theta_covariance)
            .chain(&self.held_information)
            .chain(std::iter::once(&self.time_s));
        if numbers.into_iter().any(|v| !v.is_finite()) {
            return Err("non-finite number".into());
        }
        let c = self.theta_covariance;
        if !(c[0] > 0.0 && c[3] > 0.0 && c[0] * c[3] - c[1] * c[2] > 0.0) {
            return Err("covariance is not positive definite".into());
        }
        let decision = |i: usize| -> Result<ThrusterDecision, String> {
            Ok(ThrusterDecision {
                status: status_from(&self.status[i])
                    .ok_or_else(|| format!("unknown status {:?}", self.status[i]))?,
                onset_time_s: self.onset_time_s[i],
            })
        };
        let decisions = [decision(0)?, decision(1)?];
        Ok(Calibration {
            source,
            theta: self.theta,
            theta_covariance: self.theta_covariance,
            held_information: self.held_information,
            decisions,
            time_s: self.time_s,
        })
    }
}

/// The file of `vessel` in `dir`.
pub fn path_for(dir: &Path, vessel: &str) -> PathBuf {
    dir.join(format!("{vessel}.json"))
}

/// Saves atomically.
pub fn save(dir: &Path, vessel: &str, calibration: &Calibration) -> Result<(), PersistError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| PersistError::Io { path, source }
    };
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let file = CalibrationFile::new(vessel, calibration);
    let text = serde_json::to_string_pretty(&file).map_err(|e| PersistError::Format {
        path: path_for(dir, vessel),
        message: e.to_string(),
    })?;
    let tmp = dir.join(format!(".{vessel}.json.tmp"));
    std::fs::write(&tmp, text).map_err(io(&tmp))?;
    let target = path_for(dir, vessel);
    std::fs::rename(&tmp, &target).map_err(io(&target))
}

/// Loads the calibration of `vessel`, if there is one.
pub fn load(dir: &Path, vessel: &str) -> Result<Option<Calibration>, PersistError> {
    let path = path_for(dir, vessel);
    let text = match std::fs::read_to_string(&path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(source) => return Err(PersistError::Io { path, source }),
    };
    let file: CalibrationFile = serde_json::from_str(&text).map_err(|e| PersistError::Format {
        path: path.clone(),
        message: e.to_string(),
    })?;
    if file.vessel != vessel {
        return Err(PersistError::Format {
            path,
            message: format!("belongs to vessel {:?}", file.vessel),
        });
    }
    file.to_calibration()
        .map(Some)
        .map_err(|message| PersistError::Format { path, message })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn calibration() -> Calibration {
        Calibration {
            source: FaultSource::Kinetic,
            theta: [0.18, 0.01],
            theta_covariance: [1e-4, 2e-5, 2e-5, 2e-4],
            held_information: [1234.5, 987.6],
            decisions: [
                ThrusterDecision {
                    status: ThrusterStatus::Fault,
                    onset_time_s: Some(1_700_000_012.5),
                },
                ThrusterDecision {
                    status: ThrusterStatus::Nominal,
                    onset_time_s: None,
                },
            ],
            time_s: 1_700_000_100.0,
        }
    }

    #[test]
    fn save_then_load_gives_the_same_calibration() {
        let dir = std::env::temp_dir().join(format!("twind-persist-{}", std::process::id()));
        save(&dir, "otter-1", &calibration()).unwrap();
        assert_eq!(load(&dir, "otter-1").unwrap(), Some(calibration()));
        assert_eq!(load(&dir, "otter-2").unwrap(), None);
        // A damaged file is an error, not a silent reset.
        std::fs::write(path_for(&dir, "otter-3"), "{not json").unwrap();
        assert!(load(&dir, "otter-3").is_err());
        // A file renamed to another vessel is refused.
        std::fs::copy(path_for(&dir, "otter-1"), path_for(&dir, "otter-4")).unwrap();
        assert!(load(&dir, "otter-4").is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_broken_covariance_is_refused() {
        let mut f = CalibrationFile::new("v", &calibration());
        f.theta_covariance = [1e-4, 1.0, 1.0, 1e-4];
        assert!(f.to_calibration().is_err());
        f.theta_covariance = [f64::NAN, 0.0, 0.0, 1e-4];
        assert!(f.to_calibration().is_err());
    }
}
