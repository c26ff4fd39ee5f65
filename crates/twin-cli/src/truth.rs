//! The truth file of a simulated trial: JSON lines, one [`TruthRecord`] per
//! sample of the simulator's true state (`twin simulate --truth FILE`), read
//! back by `twin analyze --truth FILE` to score the twin's forecast.
//!
//! # Format
//! One JSON object a line, at the GNSS rate (the simulator's true sample
//! times, without the GNSS latency):
//! ```text
//! {"time":"2024-06-01T10:00:00.200Z","time_s":1717236000.2,"elapsed_s":0.2,
//!  "lat_deg":62.47,"lon_deg":6.15,"north_m":0.3,"east_m":0.0,
//!  "heading_rad":0.0,"u_mps":1.5,"v_mps":0.0,"r_radps":0.0,
//!  "sog_mps":1.5,"cog_rad":0.0,"u_water_mps":1.5,"v_water_mps":0.0,
//!  "shaft_radps":{"port":60.1,"starboard":52.0},
//!  "shaft_cmd_radps":{"port":60.1,"starboard":52.0},
//!  "thrust_n":{"port":30.0,"starboard":30.0},
//!  "loss":{"port":0.25,"starboard":0.0},
//!  "current_mps":{"north":0.0,"east":0.0}}
//! ```
//! `north_m`/`east_m` are in the simulator's frame (origin: the scenario's
//! `[origin]`), the heading and courses in rad clockwise from true north in
//! [0, 2 pi), `u`/`v` body-frame velocities over ground, `*_water_*` through
//! the water, `r` positive turning to starboard.
//!
//! Reading is lenient where it can be: `time` may be RFC 3339 text or epoch
//! seconds, or `time_s` alone may give it; only the time and `lat_deg`,
//! `lon_deg` are required, unknown fields are ignored (so other simulators'
//! truth can be used).

use std::io::{BufRead, Write};

use serde::{Deserialize, Serialize};
use twin_core::geodesy::LatLon;
use twin_sim::TruthSample;
use twin_wire::time::{format_rfc3339, parse_rfc3339};

/// A port/starboard pair.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pair {
    /// Port.
    pub port: f64,
    /// Starboard.
    pub starboard: f64,
}

impl From<[f64; 2]> for Pair {
    fn from(v: [f64; 2]) -> Self {
        Self {
            port: v[0],
            starboard: v[1],
        }
    }
}

/// A north/east pair, m/s.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct NorthEastMps {
    /// North component.
    pub north: f64,
    /// East component.
    pub east: f64,
}

/// One line of a truth file, as written.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TruthRecord {
    /// RFC 3339 UTC time.
    pub time: String,
    /// The same time, seconds since the Unix epoch.
    pub time_s: f64,
    /// Seconds since the trial's start.
    pub elapsed_s: f64,
    /// Latitude of the body origin, degrees.
    pub lat_deg: f64,
    /// Longitude of the body origin, degrees.
    pub lon_deg: f64,
    /// North of the simulator's origin, m.
    pub north_m: f64,
    /// East of the simulator's origin, m.
    pub east_m: f64,
    /// Heading, rad.
    pub heading_rad: f64,
    /// Surge velocity over ground, m/s.
    pub u_mps: f64,
    /// Sway velocity over ground, m/s.
    pub v_mps: f64,
    /// Yaw rate, rad/s.
    pub r_radps: f64,
    /// Speed over ground, m/s.
    pub sog_mps: f64,
    /// Course over ground, rad.
    pub cog_rad: f64,
    /// Surge velocity through the water, m/s.
    pub u_water_mps: f64,
    /// Sway velocity through the water, m/s.
    pub v_water_mps: f64,
    /// Actual shaft speeds, rad/s.
    pub shaft_radps: Pair,
    /// Commanded shaft speeds, rad/s.
    pub shaft_cmd_radps: Pair,
    /// Effective thrusts `(1 - loss) T`, N.
    pub thrust_n: Pair,
    /// Loss of effectiveness, 0..1.
    pub loss: Pair,
    /// Water current, m/s.
    pub current_mps: NorthEastMps,
}

/// Why a truth file cannot be written or read.
#[derive(Debug, thiserror::Error)]
pub enum TruthError {
    /// A time cannot be written as RFC 3339.
    #[error("truth time {time_s} s cannot be written: {source}")]
    Time {
        /// The time.
        time_s: f64,
        /// Why.
        source: twin_wire::time::TimeError,
    },
    /// Reading or writing failed.
    #[error("truth file I/O: {0}")]
    Io(#[from] std::io::Error),
    /// A line is not a truth record.
    #[error("truth file line {line}: {reason}")]
    Line {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// Writing JSON failed.
    #[error("truth record cannot be encoded: {0}")]
    Json(#[from] serde_json::Error),
}

impl TruthRecord {
    /// The record of one simulator sample.
    pub fn from_sample(t: &TruthSample) -> Result<Self, TruthError> {
        Ok(Self {
            time: format_rfc3339(t.time_s).map_err(|source| TruthError::Time {
                time_s: t.time_s,
                source,
            })?,
            time_s: t.time_s,
            elapsed_s: t.elapsed_s,
            lat_deg: t.position.lat_deg,
            lon_deg: t.position.lon_deg,
            north_m: t.north_m,
            east_m: t.east_m,
            heading_rad: t.heading_rad,
            u_mps: t.u_mps,
            v_mps: t.v_mps,
            r_radps: t.r_radps,
            sog_mps: t.sog_mps,
            cog_rad: t.cog_rad,
            u_water_mps: t.u_water_mps,
            v_water_mps: t.v_water_mps,
            shaft_radps: t.shaft_radps.into(),
            shaft_cmd_radps: t.shaft_cmd_radps.into(),
            thrust_n: t.thrust_n.into(),
            loss: t.loss.into(),
            current_mps: NorthEastMps {
                north: t.current_ned_mps[0],
                east: t.current_ned_mps[1],
            },
        })
    }
}

/// Writes the truth of a run as JSON lines; returns the lines written.
pub fn write_truth<W: Write>(samples: &[TruthSample], mut out: W) -> Result<usize, TruthError> {
    for t in samples {
        serde_json::to_writer(&mut out, &TruthRecord::from_sample(t)?)?;
        out.write_all(b"\n")?;
    }
    out.flush()?;
    Ok(samples.len())
}

/// A truth sample as read back: what the analysis compares with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthPoint {
    /// Seconds since the Unix epoch.
    pub time_s: f64,
    /// Position of the body origin.
    pub position: LatLon,
    /// Speed over ground, m/s, if given.
    pub sog_mps: Option<f64>,
    /// Losses `[port, starboard]`, if given.
    pub loss: Option<[f64; 2]>,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum TimeField {
    Text(String),
    Seconds(f64),
}

#[derive(Deserialize)]
struct TruthLine {
    time: Option<TimeField>,
    time_s: Option<f64>,
    lat_deg: f64,
    lon_deg: f64,
    sog_mps: Option<f64>,
    loss: Option<Pair>,
}

/// Reads a truth file (see the module doc). Blank lines and `#` comments
/// are skipped; the points come back sorted by time.
pub fn read_truth<R: BufRead>(input: R) -> Result<Vec<TruthPoint>, TruthError> {
    let mut points = Vec::new();
    for (i, line) in input.lines().enumerate() {
        let line = line?;
        let text = line.trim();
        if text.is_empty() || text.starts_with('#') {
            continue;
        }
        let bad = |reason: String| TruthError::Line {
            line: i + 1,
            reason,
        };
        let parsed: TruthLine = serde_json::from_str(text).map_err(|e| bad(e.to_string()))?;
        let time_s = match (&parsed.time, parsed.time_s) {
            (Some(TimeField::Text(t)), _) => {
                parse_rfc3339(t).map_err(|e| bad(format!("time: {e}")))?
            }
            (Some(TimeField::Seconds(s)), _) => *s,
            (None, Some(s)) => s,
            (None, None) => return Err(bad("no `time` or `time_s`".to_string())),
        };
        let position = LatLon {
            lat_deg: parsed.lat_deg,
            lon_deg: parsed.lon_deg,
        };
        if !(time_s.is_finite() && position.is_valid()) {
            return Err(bad("time or position out of range".to_string()));
        }
        points.push(TruthPoint {
            time_s,
            position,
            sog_mps: parsed.sog_mps,
            loss: parsed.loss.map(|p| [p.port, p.starboard]),
        });
    }
    points.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    Ok(points)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_as_text_number_or_time_s() {
        let text = r#"
# comment
{"time":"2024-06-01T10:00:01Z","lat_deg":62.0,"lon_deg":6.0,"loss":{"port":0.25,"starboard":0.0}}
{"time":1717236000.5,"lat_deg":62.0,"lon_deg":6.0}
{"time_s":1717236000.0,"lat_deg":62.0,"lon_deg":6.0,"extra":1}
"#;
        let pts = read_truth(text.as_bytes()).unwrap();
        let times: Vec<f64> = pts.iter().map(|p| p.time_s).collect();
        assert_eq!(times, [1_717_236_000.0, 1_717_236_000.5, 1_717_236_001.0]);
        assert_eq!(pts[2].loss, Some([0.25, 0.0]));
        let err = read_truth(r#"{"lat_deg":1,"lon_deg":2}"#.as_bytes()).unwrap_err();
        assert!(err.to_string().contains("line 1"), "{err}");
        assert!(read_truth(r#"{"time_s":1,"lat_deg":91,"lon_deg":2}"#.as_bytes()).is_err());
    }
}
