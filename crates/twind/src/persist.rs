//! Per-vessel calibration files: what the twin has learnt (the fault
//! estimate, its covariance, the anti-windup memory, the current, the
//! heading sensor's offset and the rate sensor's bias it estimated, and the
//! decisions),
//! saved periodically and on shutdown, restored when the vessel's twin
//! starts, so a restart does not re-learn for minutes.
//!
//! One JSON file per vessel, `{dir}/{vessel}.json`, written atomically and
//! durably: a temporary file is written and flushed to the disk (`fsync`),
//! renamed over the old one, and the directory flushed too, so that a crash
//! or a power cut (routine on boats) leaves either the previous calibration
//! or the new one, never an empty or a missing file.
//!
//! A file that cannot be read as a calibration (damaged, another vessel's,
//! an unknown version) is never overwritten: it is moved aside as
//! `{vessel}.json.damaged-{n}` (the first `n` free) for a person to look
//! at, and the vessel starts from scratch.
//!
//! A calibration names the vessel profile it was learnt with
//! (`name@fingerprint`): what a twin learnt on one profile (the profile's
//! errors above all) means nothing on another. A file learnt with another
//! profile than the vessel's is not restored: it is moved aside as
//! `{vessel}.json.other-profile-{n}` and the vessel starts a new
//! calibration. A file without a profile was learnt before profiles
//! existed, with the Otter's.

use std::io::Write as _;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use twin_core::decision::{ThrusterDecision, ThrusterStatus};
use twin_core::estimator::{RateSensorBias, Surroundings};
use twin_core::twin::{Calibration, FaultSource};
use twin_wire::profile::VesselProfile;

/// The file format (version 2).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CalibrationFile {
    /// Format version.
    pub version: u32,
    /// Vessel id.
    pub vessel: String,
    /// `kinetic` or `seed_method`.
    pub source: String,
    /// Fault estimate: the extended twin's `[port loss, starboard loss,
    /// surge damping error, yaw damping error]`, or the seed's `[a, r]`.
    pub theta: Vec<f64>,
    /// Fault covariance, row-major.
    pub theta_covariance: Vec<f64>,
    /// Anti-windup memory per fault.
    pub held_information: Vec<f64>,
    /// The current `[north, east]` (m/s) and the heading sensor's offset
    /// (rad) the extended twin estimated, with their covariance (row-major
    /// 3 x 3), and the rate sensor's bias with its variance.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub surroundings: Option<SurroundingsFile>,
    /// Status per thruster.
    pub status: [String; 2],
    /// Onset per thruster, seconds since the epoch.
    pub onset_time_s: [Option<f64>; 2],
    /// Time of the last fix learnt from, seconds since the epoch.
    pub time_s: f64,
    /// The vessel profile it was learnt with, `name@fingerprint`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub profile: Option<String>,
}

/// The surroundings part of a calibration file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SurroundingsFile {
    /// Water current `[north, east]`, m/s.
    pub current_mps: [f64; 2],
    /// Heading sensor minus true heading, rad.
    pub heading_bias_rad: f64,
    /// Covariance of `[current north, current east, heading bias]`, row-major.
    pub covariance: [f64; 9],
    /// The rate sensor's bias, where the twin estimated it (absent from
    /// files saved before it was kept: the bias is then learnt from its
    /// prior).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub yaw_rate_bias: Option<RateSensorBiasFile>,
}

/// The rate sensor's bias in a calibration file.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RateSensorBiasFile {
    /// What the rate sensor reads when the vessel does not turn, rad/s.
    pub radps: f64,
    /// Its variance, (rad/s)^2.
    pub variance: f64,
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
    /// The file was learnt with another profile and has been moved aside.
    #[error("{path}: learnt with profile {learnt_with}, not {current}; kept as {kept}")]
    OtherProfile {
        /// Where it was.
        path: PathBuf,
        /// Where it is now.
        kept: PathBuf,
        /// The profile it was learnt with.
        learnt_with: String,
        /// The vessel's profile now.
        current: String,
    },
    /// The file was not a calibration and has been moved aside.
    #[error("{path}: not a calibration file ({message}); kept as {kept}")]
    Damaged {
        /// Where it was.
        path: PathBuf,
        /// Where it is now.
        kept: PathBuf,
        /// What is wrong with it.
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
    /// From the twin's calibration, learnt with `profile`.
    pub fn new(vessel: &str, c: &Calibration, profile: &str) -> Self {
        Self {
            version: 2,
            vessel: vessel.to_string(),
            source: match c.source {
                FaultSource::Kinetic => "kinetic",
                FaultSource::SeedMethod => "seed_method",
            }
            .to_string(),
            theta: c.theta.clone(),
            theta_covariance: c.theta_covariance.clone(),
            held_information: c.held_information.clone(),
            surroundings: c.surroundings.map(|s| SurroundingsFile {
                current_mps: s.current_mps,
                heading_bias_rad: s.heading_bias_rad,
                covariance: std::array::from_fn(|k| s.covariance[k / 3][k % 3]),
                yaw_rate_bias: s.yaw_rate_bias.map(|g| RateSensorBiasFile {
                    radps: g.radps,
                    variance: g.variance,
                }),
            }),
            status: c.decisions.map(|d| status_name(d.status)),
            onset_time_s: c.decisions.map(|d| d.onset_time_s),
            time_s: c.time_s,
            profile: Some(profile.to_owned()),
        }
    }

    /// Back to the twin's calibration, checked.
    pub fn to_calibration(&self) -> Result<Calibration, String> {
        if self.version != 2 {
            return Err(format!("unknown version {}", self.version));
        }
        let source = match self.source.as_str() {
            "kinetic" => FaultSource::Kinetic,
            "seed_method" => FaultSource::SeedMethod,
            other => return Err(format!("unknown source {other:?}")),
        };
        let surroundings_numbers = self.surroundings.iter().flat_map(|s| {
            s.current_mps
                .iter()
                .chain(s.covariance.iter())
                .chain([&s.heading_bias_rad])
                .chain(s.yaw_rate_bias.iter().flat_map(|g| [&g.radps, &g.variance]))
        });
        let numbers = self
            .theta
            .iter()
            .chain(&self.theta_covariance)
            .chain(&self.held_information)
            .chain(surroundings_numbers)
            .chain(std::iter::once(&self.time_s));
        if numbers.into_iter().any(|v| !v.is_finite()) {
            return Err("non-finite number".into());
        }
        let p = self.theta.len();
        if p == 0 || self.theta_covariance.len() != p * p || self.held_information.len() != p {
            return Err("fault sizes do not match".into());
        }
        if !positive_semi_definite(&self.theta_covariance, p) {
            return Err("covariance is not positive semi-definite".into());
        }
        if let Some(g) = self.surroundings.as_ref().and_then(|s| s.yaw_rate_bias)
            && g.variance < 0.0
        {
            return Err("the rate sensor's bias has a negative variance".into());
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
            theta: self.theta.clone(),
            theta_covariance: self.theta_covariance.clone(),
            held_information: self.held_information.clone(),
            surroundings: self.surroundings.as_ref().map(|s| Surroundings {
                current_mps: s.current_mps,
                heading_bias_rad: s.heading_bias_rad,
                covariance: std::array::from_fn(|i| {
                    std::array::from_fn(|j| s.covariance[3 * i + j])
                }),
                yaw_rate_bias: s.yaw_rate_bias.map(|g| RateSensorBias {
                    radps: g.radps,
                    variance: g.variance,
                }),
            }),
            decisions,
            time_s: self.time_s,
        })
    }
}

/// Whether the row-major `p x p` matrix `m` is symmetric and positive
/// semi-definite (a Cholesky factorisation that tolerates zero pivots of
/// held faults).
fn positive_semi_definite(m: &[f64], p: usize) -> bool {
    let at = |i: usize, j: usize| m[i * p + j];
    for i in 0..p {
        for j in 0..i {
            if (at(i, j) - at(j, i)).abs() > 1e-9 * (1.0 + at(i, i).abs() + at(j, j).abs()) {
                return false;
            }
        }
    }
    let mut l = vec![0.0; p * p];
    for j in 0..p {
        let mut d = at(j, j);
        for k in 0..j {
            d -= l[j * p + k] * l[j * p + k];
        }
        if d < -1e-12 * (1.0 + at(j, j).abs()) {
            return false;
        }
        let d = d.max(0.0).sqrt();
        l[j * p + j] = d;
        for i in j + 1..p {
            let mut s = at(i, j);
            for k in 0..j {
                s -= l[i * p + k] * l[j * p + k];
            }
            l[i * p + j] = if d > 0.0 { s / d } else { 0.0 };
        }
    }
    true
}

/// The file of `vessel` in `dir`.
pub fn path_for(dir: &Path, vessel: &str) -> PathBuf {
    dir.join(format!("{vessel}.json"))
}

/// Saves atomically and durably (see the module doc), as learnt with
/// `profile`.
pub fn save(
    dir: &Path,
    vessel: &str,
    calibration: &Calibration,
    profile: &str,
) -> Result<(), PersistError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| PersistError::Io { path, source }
    };
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let text = encode(vessel, calibration, profile).map_err(|message| PersistError::Format {
        path: path_for(dir, vessel),
        message,
    })?;
    let tmp = dir.join(format!(".{vessel}.json.tmp"));
    {
        let mut f = std::fs::File::create(&tmp).map_err(io(&tmp))?;
        f.write_all(text.as_bytes()).map_err(io(&tmp))?;
        // The data on the disk before the name points at it.
        f.sync_all().map_err(io(&tmp))?;
    }
    let target = path_for(dir, vessel);
    std::fs::rename(&tmp, &target).map_err(io(&target))?;
    // The rename itself on the disk.
    std::fs::File::open(dir)
        .and_then(|d| d.sync_all())
        .map_err(io(dir))
}

/// Loads the calibration of `vessel`, if there is one, for the profile
/// `profile`. A file that is not a calibration is moved aside
/// ([`PersistError::Damaged`]), and so is one learnt with another profile
/// ([`PersistError::OtherProfile`]).
pub fn load(dir: &Path, vessel: &str, profile: &str) -> Result<Option<Calibration>, PersistError> {
    let path = path_for(dir, vessel);
    let text = match std::fs::read(&path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(source) => return Err(PersistError::Io { path, source }),
    };
    match parse(&text, vessel) {
        Ok((_, learnt_with)) if learnt_with != profile => {
            let kept = move_aside(&path, "other-profile")?;
            Err(PersistError::OtherProfile {
                path,
                kept,
                learnt_with,
                current: profile.to_owned(),
            })
        }
        Ok((c, _)) => Ok(Some(c)),
        Err(message) => {
            let kept = move_aside(&path, "damaged")?;
            Err(PersistError::Damaged {
                path,
                kept,
                message,
            })
        }
    }
}

/// The calibration file of `vessel` learnt with `profile`, as text: what
/// [`save`] writes and a fleet daemon puts on the network.
pub fn encode(vessel: &str, calibration: &Calibration, profile: &str) -> Result<String, String> {
    serde_json::to_string_pretty(&CalibrationFile::new(vessel, calibration, profile))
        .map_err(|e| e.to_string())
}

/// A calibration received from the network for `vessel`, checked as a
/// file is ([`load`]): refused when it is not a calibration of that vessel
/// or was learnt with another profile than `profile`.
pub fn decode(bytes: &[u8], vessel: &str, profile: &str) -> Result<Calibration, String> {
    let (c, learnt_with) = parse(bytes, vessel)?;
    if learnt_with == profile {
        Ok(c)
    } else {
        Err(format!(
            "learnt with the profile {learnt_with}, not the vessel's {profile}"
        ))
    }
}

/// A calibration file's bytes, checked to be `vessel`'s calibration, and
/// the profile it was learnt with.
fn parse(text: &[u8], vessel: &str) -> Result<(Calibration, String), String> {
    let file: CalibrationFile = serde_json::from_slice(text).map_err(|e| e.to_string())?;
    if file.vessel != vessel {
        return Err(format!("belongs to vessel {:?}", file.vessel));
    }
    let profile = file
        .profile
        .clone()
        .unwrap_or_else(|| VesselProfile::otter().identity());
    Ok((file.to_calibration()?, profile))
}

/// Renames `path` to the first free `{path}.{why}-{n}`, durably.
fn move_aside(path: &Path, why: &str) -> Result<PathBuf, PersistError> {
    let io = |p: &Path| {
        let p = p.to_path_buf();
        move |source| PersistError::Io { path: p, source }
    };
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    let dir = path.parent().unwrap_or(Path::new("."));
    for n in 1..10_000 {
        let aside = dir.join(format!("{name}.{why}-{n}"));
        if aside.exists() {
            continue;
        }
        std::fs::rename(path, &aside).map_err(io(path))?;
        std::fs::File::open(dir)
            .and_then(|d| d.sync_all())
            .map_err(io(dir))?;
        return Ok(aside);
    }
    Err(PersistError::Io {
        path: path.to_path_buf(),
        source: std::io::Error::other(format!("no free name to move the {why} file aside")),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const OTTER: &str = "otter@0000000000000000";
    const CATAMARAN: &str = "catamaran@1111111111111111";

    fn calibration() -> Calibration {
        Calibration {
            source: FaultSource::Kinetic,
            theta: vec![0.18, 0.01, 0.2, -0.05],
            theta_covariance: vec![
                1e-4, 2e-5, 0.0, 0.0, //
                2e-5, 2e-4, 0.0, 0.0, //
                0.0, 0.0, 0.01, 1e-3, //
                0.0, 0.0, 1e-3, 0.02,
            ],
            held_information: vec![1234.5, 987.6, 55.0, 12.0],
            surroundings: Some(Surroundings {
                current_mps: [0.1, -0.2],
                heading_bias_rad: 0.05,
                covariance: [[1e-3, 1e-4, 0.0], [1e-4, 2e-3, 0.0], [0.0, 0.0, 1e-4]],
                yaw_rate_bias: Some(RateSensorBias {
                    radps: 0.004,
                    variance: 2e-8,
                }),
            }),
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
        save(&dir, "otter-1", &calibration(), OTTER).unwrap();
        assert_eq!(load(&dir, "otter-1", OTTER).unwrap(), Some(calibration()));
        assert_eq!(load(&dir, "otter-2", OTTER).unwrap(), None);
        // No temporary file is left behind.
        let names: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(names, ["otter-1.json"]);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A file that is not this vessel's calibration is an error, not a
    /// silent reset, and it is kept aside (each damaged file under its own
    /// name), never overwritten by the next save.
    #[test]
    fn a_damaged_file_is_moved_aside_and_kept() {
        let dir = std::env::temp_dir().join(format!("twind-damaged-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let damaged = path_for(&dir, "otter-3");
        for (round, text) in ["{not json", "", "{\"version\": 1}"]
            .into_iter()
            .enumerate()
        {
            std::fs::write(&damaged, text).unwrap();
            let err = load(&dir, "otter-3", OTTER).unwrap_err();
            let kept = dir.join(format!("otter-3.json.damaged-{}", round + 1));
            assert!(
                matches!(&err, PersistError::Damaged { kept: k, .. } if *k == kept),
                "{err}"
            );
            assert_eq!(std::fs::read_to_string(&kept).unwrap(), text);
            assert!(!damaged.exists());
            // Nothing there now: the vessel starts from scratch.
            assert_eq!(load(&dir, "otter-3", OTTER).unwrap(), None);
        }
        save(&dir, "otter-3", &calibration(), OTTER).unwrap();
        assert_eq!(
            std::fs::read_to_string(dir.join("otter-3.json.damaged-1")).unwrap(),
            "{not json"
        );
        // A file renamed to another vessel is refused and kept aside too.
        std::fs::copy(path_for(&dir, "otter-3"), path_for(&dir, "otter-4")).unwrap();
        assert!(matches!(
            load(&dir, "otter-4", OTTER),
            Err(PersistError::Damaged { .. })
        ));
        assert!(dir.join("otter-4.json.damaged-1").exists());
        assert_eq!(load(&dir, "otter-3", OTTER).unwrap(), Some(calibration()));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_broken_covariance_is_refused() {
        let mut f = CalibrationFile::new("v", &calibration(), OTTER);
        f.theta_covariance = vec![1e-4, 1.0, 1.0, 1e-4];
        f.theta = vec![0.1, 0.1];
        f.held_information = vec![1.0, 1.0];
        assert!(f.to_calibration().is_err());
        f.theta_covariance = vec![f64::NAN, 0.0, 0.0, 1e-4];
        assert!(f.to_calibration().is_err());
        // Sizes that do not match each other.
        f.theta_covariance = vec![1e-4, 0.0, 0.0, 1e-4];
        f.held_information = vec![1.0];
        assert!(f.to_calibration().is_err());
    }

    /// A file saved before the rate sensor's bias was kept loads, with the
    /// bias to be learnt from its prior; a bias that is not a number, or a
    /// negative variance, is refused.
    #[test]
    fn the_rate_sensors_bias_is_optional_and_checked() {
        let f = CalibrationFile::new("v", &calibration(), OTTER);
        let mut json: serde_json::Value = serde_json::to_value(&f).unwrap();
        assert_eq!(json["surroundings"]["yaw_rate_bias"]["radps"], 0.004);
        json["surroundings"]
            .as_object_mut()
            .unwrap()
            .remove("yaw_rate_bias");
        let old: CalibrationFile = serde_json::from_value(json).unwrap();
        let restored = old.to_calibration().unwrap();
        let s = restored.surroundings.unwrap();
        assert_eq!(s.yaw_rate_bias, None);
        assert_eq!(s.heading_bias_rad, 0.05);
        for (radps, variance) in [(f64::NAN, 1e-8), (0.0, f64::INFINITY), (0.0, -1e-8)] {
            let mut bad = f.clone();
            bad.surroundings.as_mut().unwrap().yaw_rate_bias =
                Some(RateSensorBiasFile { radps, variance });
            assert!(bad.to_calibration().is_err(), "{radps} {variance}");
        }
    }

    /// A calibration learnt with one profile is not restored on another:
    /// it is kept aside, and the vessel starts a new one; a file from
    /// before profiles is the Otter's.
    #[test]
    fn a_calibration_from_the_network_is_checked_as_a_file_is() {
        let text = encode("cat-1", &calibration(), CATAMARAN).unwrap();
        assert_eq!(
            decode(text.as_bytes(), "cat-1", CATAMARAN).unwrap(),
            calibration()
        );
        let other_profile = decode(text.as_bytes(), "cat-1", OTTER).unwrap_err();
        assert!(other_profile.contains(CATAMARAN), "{other_profile}");
        let other_vessel = decode(text.as_bytes(), "cat-2", CATAMARAN).unwrap_err();
        assert!(other_vessel.contains("cat-1"), "{other_vessel}");
        assert!(decode(b"{\"vessel\": 1}", "cat-1", CATAMARAN).is_err());
    }

    #[test]
    fn a_calibration_of_another_profile_is_kept_aside_not_restored() {
        let dir = std::env::temp_dir().join(format!("twind-profile-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        save(&dir, "cat-1", &calibration(), CATAMARAN).unwrap();
        let err = load(&dir, "cat-1", OTTER).unwrap_err();
        let kept = dir.join("cat-1.json.other-profile-1");
        assert!(
            matches!(&err, PersistError::OtherProfile { kept: k, learnt_with, .. }
                if *k == kept && learnt_with == CATAMARAN),
            "{err}"
        );
        assert_eq!(load(&dir, "cat-1", OTTER).unwrap(), None);
        std::fs::rename(&kept, path_for(&dir, "cat-1")).unwrap();
        assert_eq!(load(&dir, "cat-1", CATAMARAN).unwrap(), Some(calibration()));
        // Without a profile: learnt with the Otter's.
        let mut file = CalibrationFile::new("old-1", &calibration(), OTTER);
        file.profile = None;
        std::fs::write(path_for(&dir, "old-1"), serde_json::to_vec(&file).unwrap()).unwrap();
        let otter = VesselProfile::otter().identity();
        assert_eq!(load(&dir, "old-1", &otter).unwrap(), Some(calibration()));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
