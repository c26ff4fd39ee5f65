//! The JSON input payloads of the contract (docs/contracts.md): GNSS fixes on
//! `{prefix}/{vessel}/gnss` and propeller commands on
//! `{prefix}/{vessel}/actuators`, their validation into the estimator's
//! types, and their encoders (used by the replay tool and the simulator).
//!
//! GNSS fix:
//! ```json
//! {"time":"2026-08-03T04:27:20.588Z","lat_deg":34.41,"lon_deg":133.54,
//!  "sog_mps":2.77,"cog_rad":5.0265,"heading_rad":5.01,"yaw_rate_radps":0.02,
//!  "hdop":0.9,"replay":true}
//! ```
//! `heading_rad`, `yaw_rate_radps` (a rate gyro or rate-of-turn sensor,
//! positive turning to starboard), `hdop`, `replay` and `time_source` are
//! optional. Angles are radians; one outside [-2 pi, 4 pi] is refused (most
//! likely degrees). Actuators:
//! ```json
//! {"time":"2026-08-03T04:27:20.588Z","rpm":{"port":1200.0,"starboard":1185.5}}
//! {"time":"2026-08-03T04:27:20.588Z","thrust_n":{"port":40.0,"starboard":38.5}}
//! ```
//! exactly one of `rpm` and `thrust_n`; `replay` and `time_source` optional.
//! Unknown fields are ignored (so the contract can grow), missing required
//! ones are errors.
//!
//! `time_source` says whose clock `time` is: `"source"` (the default, and
//! what a payload without the field means) for the source's own time stamp,
//! a GNSS time or a logger's; `"receiver"` when the source gave none and
//! the sender stamped the message with the time it received it (the bridge
//! does that for NMEA 2000 frames and for MAVLink before the vehicle's
//! clock is known). Encoders leave the field out when it is `"source"`, so
//! such payloads are byte for byte what they were before the field existed.
//!
//! Payloads larger than the limit (default [`DEFAULT_MAX_PAYLOAD_BYTES`]) are
//! refused before any parsing.

use schemars::JsonSchema;
use std::f64::consts::TAU;

use serde::{Deserialize, Serialize};
use twin_core::geodesy::{LatLon, wrap_two_pi};
use twin_core::sample::{GnssFix, PropellerSpeeds, RADPS_PER_RPM};

use crate::measurement::{MAX_SPEED_MPS, ThrustCommand};
use crate::time::{TimeError, format_rfc3339, parse_rfc3339};

/// The default largest payload accepted, bytes (64 KiB).
pub const DEFAULT_MAX_PAYLOAD_BYTES: usize = 64 * 1024;

/// The largest propeller speed accepted, rpm (either direction).
pub const MAX_ABS_RPM: f64 = 20_000.0;

/// The largest propeller thrust accepted, N (either direction).
pub const MAX_ABS_THRUST_N: f64 = 1.0e6;

/// The largest yaw rate accepted, rad/s (either direction): about 290 deg/s,
/// beyond any hull's turn.
pub const MAX_ABS_YAW_RATE_RADPS: f64 = 5.0;

/// Whether an angle is one a sender could mean in radians: within
/// [-2 pi, 4 pi] (a heading in degrees would mostly fall outside).
pub fn plausible_radians(angle_rad: f64) -> bool {
    (-std::f64::consts::TAU..=2.0 * std::f64::consts::TAU).contains(&angle_rad)
}

/// Whose clock a payload's `time` is (see the module doc).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "lowercase")]
pub enum TimeSource {
    /// The source's own time stamp (a GNSS time, a logger's time stamp).
    #[default]
    Source,
    /// The time the sender received the data: the source gave no time.
    Receiver,
}

impl TimeSource {
    /// True for [`TimeSource::Source`], the default left out on the wire.
    pub fn is_source(&self) -> bool {
        *self == TimeSource::Source
    }

    /// `"source"` or `"receiver"`, as on the wire.
    pub fn name(self) -> &'static str {
        match self {
            TimeSource::Source => "source",
            TimeSource::Receiver => "receiver",
        }
    }
}

/// The GNSS fix payload, as on the wire.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct GnssMessage {
    /// RFC 3339 UTC time of the fix.
    pub time: String,
    /// Latitude, degrees.
    #[schemars(range(min = -90.0, max = 90.0))]
    pub lat_deg: f64,
    /// Longitude, degrees.
    #[schemars(range(min = -180.0, max = 180.0))]
    pub lon_deg: f64,
    /// Speed over ground, m/s.
    #[schemars(range(min = 0.0, max = MAX_SPEED_MPS))]
    pub sog_mps: f64,
    /// Course over ground, rad clockwise from true north.
    #[schemars(range(min = -TAU, max = 2.0 * TAU))]
    pub cog_rad: f64,
    /// True heading, rad clockwise from true north.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = -TAU, max = 2.0 * TAU))]
    pub heading_rad: Option<f64>,
    /// Yaw rate from a rate gyro or rate-of-turn sensor, rad/s, positive
    /// turning to starboard.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = -MAX_ABS_YAW_RATE_RADPS, max = MAX_ABS_YAW_RATE_RADPS))]
    pub yaw_rate_radps: Option<f64>,
    /// Horizontal dilution of precision, above 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub hdop: Option<f64>,
    /// True when the fix is replayed from a log rather than live.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub replay: bool,
    /// Whose clock `time` is; absent means the source's.
    #[serde(default, skip_serializing_if = "TimeSource::is_source")]
    pub time_source: TimeSource,
}

/// A port/starboard pair of numbers, as on the wire.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct PortStarboard {
    /// Port propeller.
    pub port: f64,
    /// Starboard propeller.
    pub starboard: f64,
}

/// The actuators payload, as on the wire.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[schemars(extend("oneOf" = [{"required": ["rpm"]}, {"required": ["thrust_n"]}]))]
pub struct ActuatorsMessage {
    /// RFC 3339 UTC time of the command.
    pub time: String,
    /// Propeller speeds, rpm (positive ahead).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rpm: Option<PortStarboard>,
    /// Propeller thrusts, N (positive ahead).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thrust_n: Option<PortStarboard>,
    /// True when replayed from a log rather than live.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub replay: bool,
    /// Whose clock `time` is; absent means the source's.
    #[serde(default, skip_serializing_if = "TimeSource::is_source")]
    pub time_source: TimeSource,
}

/// Why a payload is refused. The JSON parser's own error is summarised into
/// copyable fields so that a rejection can be counted and compared.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum MessageError {
    /// The payload is larger than the limit; it was not parsed.
    #[error("payload of {len} bytes exceeds the limit of {limit} bytes")]
    TooLarge {
        /// Payload size, bytes.
        len: usize,
        /// The limit, bytes.
        limit: usize,
    },
    /// The payload is not JSON, is truncated, or does not have the message's
    /// shape (a required field missing, a string where a number should be).
    #[error("invalid JSON ({category:?}) at line {line}, column {column}")]
    Json {
        /// What kind of JSON error.
        category: JsonCategory,
        /// 1-based line of the error.
        line: usize,
        /// 1-based column of the error.
        column: usize,
    },
    /// `time` is not an RFC 3339 timestamp.
    #[error("bad time: {0}")]
    Time(#[from] TimeError),
    /// A number is NaN or infinite (possible in messages built in memory).
    #[error("{field} is not finite")]
    NotFinite {
        /// The field.
        field: &'static str,
    },
    /// A number is outside its allowed range (|lat| <= 90, |lon| <= 180,
    /// 0 <= sog <= 50 m/s, angles within [-2 pi, 4 pi], |yaw rate| <= 5
    /// rad/s, hdop > 0, |rpm| <= 20 000, |thrust| <= 1e6 N).
    #[error("{field} out of range")]
    OutOfRange {
        /// The field.
        field: &'static str,
    },
    /// An actuators message with neither `rpm` nor `thrust_n`.
    #[error("actuators message has neither rpm nor thrust_n")]
    NoCommand,
    /// An actuators message with both `rpm` and `thrust_n`.
    #[error("actuators message has both rpm and thrust_n")]
    BothCommands,
    /// A fix to encode lacks a field the contract requires (`sog_mps`,
    /// `cog_rad`).
    #[error("{field} is required by the contract")]
    MissingField {
        /// The field.
        field: &'static str,
    },
}

impl MessageError {
    /// A short, stable name of the reason, for counting rejections.
    pub fn reason(&self) -> &'static str {
        match self {
            MessageError::TooLarge { .. } => "payload_too_large",
            MessageError::Json { .. } => "bad_json",
            MessageError::Time(_) => "bad_time",
            MessageError::NotFinite { .. } => "non_finite",
            MessageError::OutOfRange { .. } => "out_of_range",
            MessageError::NoCommand => "no_command",
            MessageError::BothCommands => "both_commands",
            MessageError::MissingField { .. } => "missing_field",
        }
    }
}

/// The kind of a JSON error (mirrors `serde_json::error::Category`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JsonCategory {
    /// Not well-formed JSON.
    Syntax,
    /// Well-formed JSON of the wrong shape (missing field, wrong type,
    /// unknown `type` tag).
    Data,
    /// The input ended in the middle of a value.
    Eof,
    /// An I/O error while reading.
    Io,
}

impl From<serde_json::Error> for MessageError {
    fn from(e: serde_json::Error) -> Self {
        use serde_json::error::Category;
        let category = match e.classify() {
            Category::Syntax => JsonCategory::Syntax,
            Category::Data => JsonCategory::Data,
            Category::Eof => JsonCategory::Eof,
            Category::Io => JsonCategory::Io,
        };
        MessageError::Json {
            category,
            line: e.line(),
            column: e.column(),
        }
    }
}

/// A decoded input with its replay flag and the clock of its time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Decoded<T> {
    /// The validated value.
    pub value: T,
    /// True when the sender marked it as replayed.
    pub replay: bool,
    /// Whose clock the value's time is.
    pub time_source: TimeSource,
}

/// A validated actuators command: speeds or thrusts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ActuatorCommand {
    /// Propeller speeds (from `rpm`).
    Speeds(PropellerSpeeds),
    /// Propeller thrusts (from `thrust_n`).
    Thrust(ThrustCommand),
}

fn finite(value: f64, field: &'static str) -> Result<f64, MessageError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(MessageError::NotFinite { field })
    }
}

fn within(value: f64, field: &'static str, ok: bool) -> Result<f64, MessageError> {
    if ok {
        Ok(value)
    } else {
        Err(MessageError::OutOfRange { field })
    }
}

impl GnssMessage {
    /// Validates the message into the estimator's fix: time parsed, numbers
    /// finite and in range, course and heading wrapped to [0, 2 pi).
    pub fn to_fix(&self) -> Result<GnssFix, MessageError> {
        let time_s = parse_rfc3339(&self.time)?;
        let lat_deg = finite(self.lat_deg, "lat_deg")?;
        let lat_deg = within(lat_deg, "lat_deg", lat_deg.abs() <= 90.0)?;
        let lon_deg = finite(self.lon_deg, "lon_deg")?;
        let lon_deg = within(lon_deg, "lon_deg", lon_deg.abs() <= 180.0)?;
        let sog_mps = finite(self.sog_mps, "sog_mps")?;
        let sog_mps = within(sog_mps, "sog_mps", (0.0..=MAX_SPEED_MPS).contains(&sog_mps))?;
        let angle = |v: f64, field| {
            let v = finite(v, field)?;
            within(v, field, plausible_radians(v)).map(wrap_two_pi)
        };
        let cog_rad = angle(self.cog_rad, "cog_rad")?;
        let heading_rad = self
            .heading_rad
            .map(|h| angle(h, "heading_rad"))
            .transpose()?;
        let yaw_rate_radps = self
            .yaw_rate_radps
            .map(|r| {
                let r = finite(r, "yaw_rate_radps")?;
                within(r, "yaw_rate_radps", r.abs() <= MAX_ABS_YAW_RATE_RADPS)
            })
            .transpose()?;
        let hdop = match self.hdop {
            Some(h) => Some(within(finite(h, "hdop")?, "hdop", h > 0.0)?),
            None => None,
        };
        Ok(GnssFix {
            time_s,
            position: LatLon { lat_deg, lon_deg },
            sog_mps: Some(sog_mps),
            cog_rad: Some(cog_rad),
            heading_rad,
            yaw_rate_radps,
            hdop,
        })
    }

    /// The wire message of a fix. The contract requires speed and course, so
    /// a fix without them cannot be encoded.
    pub fn from_fix(fix: &GnssFix, replay: bool) -> Result<Self, MessageError> {
        let sog_mps = fix
            .sog_mps
            .ok_or(MessageError::MissingField { field: "sog_mps" })?;
        let cog_rad = fix
            .cog_rad
            .ok_or(MessageError::MissingField { field: "cog_rad" })?;
        let message = GnssMessage {
            time: format_rfc3339(fix.time_s)?,
            lat_deg: fix.position.lat_deg,
            lon_deg: fix.position.lon_deg,
            sog_mps,
            cog_rad,
            heading_rad: fix.heading_rad,
            yaw_rate_radps: fix.yaw_rate_radps,
            hdop: fix.hdop,
            replay,
            time_source: TimeSource::Source,
        };
        // Encode only what decodes: the same checks both ways.
        message.to_fix()?;
        Ok(message)
    }
}

fn check_pair(
    pair: PortStarboard,
    field: &'static str,
    limit: f64,
) -> Result<PortStarboard, MessageError> {
    for v in [pair.port, pair.starboard] {
        finite(v, field)?;
        within(v, field, v.abs() <= limit)?;
    }
    Ok(pair)
}

impl ActuatorsMessage {
    /// Validates the message: time parsed, exactly one command, numbers
    /// finite and in range, rpm converted to rad/s.
    pub fn to_command(&self) -> Result<ActuatorCommand, MessageError> {
        let time_s = parse_rfc3339(&self.time)?;
        match (self.rpm, self.thrust_n) {
            (None, None) => Err(MessageError::NoCommand),
            (Some(_), Some(_)) => Err(MessageError::BothCommands),
            (Some(rpm), None) => {
                let rpm = check_pair(rpm, "rpm", MAX_ABS_RPM)?;
                Ok(ActuatorCommand::Speeds(PropellerSpeeds {
                    time_s,
                    port_radps: rpm.port * RADPS_PER_RPM,
                    starboard_radps: rpm.starboard * RADPS_PER_RPM,
                }))
            }
            (None, Some(thrust)) => {
                let thrust = check_pair(thrust, "thrust_n", MAX_ABS_THRUST_N)?;
                Ok(ActuatorCommand::Thrust(ThrustCommand {
                    time_s,
                    port_n: thrust.port,
                    starboard_n: thrust.starboard,
                }))
            }
        }
    }

    /// The wire message of a command (speeds go out in rpm).
    pub fn from_command(command: &ActuatorCommand, replay: bool) -> Result<Self, MessageError> {
        let message = match command {
            ActuatorCommand::Speeds(s) => ActuatorsMessage {
                time: format_rfc3339(s.time_s)?,
                rpm: Some(PortStarboard {
                    port: s.port_radps / RADPS_PER_RPM,
                    starboard: s.starboard_radps / RADPS_PER_RPM,
                }),
                thrust_n: None,
                replay,
                time_source: TimeSource::Source,
            },
            ActuatorCommand::Thrust(t) => ActuatorsMessage {
                time: format_rfc3339(t.time_s)?,
                rpm: None,
                thrust_n: Some(PortStarboard {
                    port: t.port_n,
                    starboard: t.starboard_n,
                }),
                replay,
                time_source: TimeSource::Source,
            },
        };
        message.to_command()?;
        Ok(message)
    }
}

fn check_size(bytes: &[u8], limit: usize) -> Result<(), MessageError> {
    if bytes.len() > limit {
        return Err(MessageError::TooLarge {
            len: bytes.len(),
            limit,
        });
    }
    Ok(())
}

/// Decodes and validates a GNSS payload, refusing payloads over
/// [`DEFAULT_MAX_PAYLOAD_BYTES`] before parsing.
pub fn decode_gnss(bytes: &[u8]) -> Result<Decoded<GnssFix>, MessageError> {
    decode_gnss_limited(bytes, DEFAULT_MAX_PAYLOAD_BYTES)
}

/// [`decode_gnss`] with a payload limit of `max_bytes`.
pub fn decode_gnss_limited(
    bytes: &[u8],
    max_bytes: usize,
) -> Result<Decoded<GnssFix>, MessageError> {
    check_size(bytes, max_bytes)?;
    let message: GnssMessage = serde_json::from_slice(bytes)?;
    Ok(Decoded {
        value: message.to_fix()?,
        replay: message.replay,
        time_source: message.time_source,
    })
}

/// Decodes and validates an actuators payload, refusing payloads over
/// [`DEFAULT_MAX_PAYLOAD_BYTES`] before parsing.
pub fn decode_actuators(bytes: &[u8]) -> Result<Decoded<ActuatorCommand>, MessageError> {
    decode_actuators_limited(bytes, DEFAULT_MAX_PAYLOAD_BYTES)
}

/// [`decode_actuators`] with a payload limit of `max_bytes`.
pub fn decode_actuators_limited(
    bytes: &[u8],
    max_bytes: usize,
) -> Result<Decoded<ActuatorCommand>, MessageError> {
    check_size(bytes, max_bytes)?;
    let message: ActuatorsMessage = serde_json::from_slice(bytes)?;
    Ok(Decoded {
        value: message.to_command()?,
        replay: message.replay,
        time_source: message.time_source,
    })
}

/// Encodes a fix as a GNSS payload (fails when it would not decode).
pub fn encode_gnss(fix: &GnssFix, replay: bool) -> Result<Vec<u8>, MessageError> {
    encode_gnss_stamped(fix, replay, TimeSource::Source)
}

/// [`encode_gnss`], saying whose clock the fix's time is.
pub fn encode_gnss_stamped(
    fix: &GnssFix,
    replay: bool,
    time_source: TimeSource,
) -> Result<Vec<u8>, MessageError> {
    let message = GnssMessage {
        time_source,
        ..GnssMessage::from_fix(fix, replay)?
    };
    Ok(serde_json::to_vec(&message)?)
}

/// Encodes a command as an actuators payload (fails when it would not decode).
pub fn encode_actuators(command: &ActuatorCommand, replay: bool) -> Result<Vec<u8>, MessageError> {
    encode_actuators_stamped(command, replay, TimeSource::Source)
}

/// [`encode_actuators`], saying whose clock the command's time is.
pub fn encode_actuators_stamped(
    command: &ActuatorCommand,
    replay: bool,
    time_source: TimeSource,
) -> Result<Vec<u8>, MessageError> {
    let message = ActuatorsMessage {
        time_source,
        ..ActuatorsMessage::from_command(command, replay)?
    };
    Ok(serde_json::to_vec(&message)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const FIX: &str = r#"{"time":"2026-08-03T04:27:20.588Z","lat_deg":34.41,"lon_deg":133.54,"sog_mps":2.77,"cog_rad":-1.0,"heading_rad":7.0,"hdop":0.9,"replay":true}"#;

    #[test]
    fn gnss_payload_decodes_with_wrapping() {
        let d = decode_gnss(FIX.as_bytes()).unwrap();
        assert!(d.replay);
        let f = d.value;
        assert!((f.time_s - 1_785_731_240.588).abs() < 1e-6, "{}", f.time_s);
        assert_eq!(f.position.lat_deg, 34.41);
        assert_eq!(f.sog_mps, Some(2.77));
        // -1 rad wraps to 2 pi - 1; 7 rad to 7 - 2 pi.
        assert!((f.cog_rad.unwrap() - (std::f64::consts::TAU - 1.0)).abs() < 1e-12);
        assert!((f.heading_rad.unwrap() - (7.0 - std::f64::consts::TAU)).abs() < 1e-12);
        assert_eq!(f.hdop, Some(0.9));
    }

    #[test]
    fn gnss_payload_minimal_and_unknown_fields() {
        let d = decode_gnss(
            br#"{"time":"2026-08-03T04:27:20Z","lat_deg":0,"lon_deg":0,"sog_mps":0,"cog_rad":0,"extra":[1,2]}"#,
        )
        .unwrap();
        assert!(!d.replay);
        assert_eq!(d.value.heading_rad, None);
        assert_eq!(d.value.hdop, None);
    }

    #[test]
    fn time_source_defaults_to_the_source_and_round_trips() {
        // Without the field: the source's clock (old payloads stay valid).
        assert_eq!(
            decode_gnss(FIX.as_bytes()).unwrap().time_source,
            TimeSource::Source
        );
        let fix = decode_gnss(FIX.as_bytes()).unwrap().value;
        // The default is left out on the wire: byte for byte the old payload.
        let plain = encode_gnss(&fix, false).unwrap();
        assert!(!String::from_utf8_lossy(&plain).contains("time_source"));
        assert_eq!(
            encode_gnss_stamped(&fix, false, TimeSource::Source).unwrap(),
            plain
        );
        let stamped = encode_gnss_stamped(&fix, false, TimeSource::Receiver).unwrap();
        assert!(String::from_utf8_lossy(&stamped).contains(r#""time_source":"receiver""#));
        let back = decode_gnss(&stamped).unwrap();
        assert_eq!(back.time_source, TimeSource::Receiver);
        assert_eq!(back.value, fix);
        let explicit = FIX.replace("\"replay\":true", "\"time_source\":\"source\"");
        assert_eq!(
            decode_gnss(explicit.as_bytes()).unwrap().time_source,
            TimeSource::Source
        );
        // Any other clock is refused as the wrong shape.
        let bad = FIX.replace("\"replay\":true", "\"time_source\":\"gps\"");
        assert!(matches!(
            decode_gnss(bad.as_bytes()),
            Err(MessageError::Json {
                category: JsonCategory::Data,
                ..
            })
        ));
        // Actuators carry it the same way.
        let cmd = ActuatorCommand::Thrust(ThrustCommand {
            time_s: fix.time_s,
            port_n: 10.0,
            starboard_n: -5.0,
        });
        let payload = encode_actuators_stamped(&cmd, false, TimeSource::Receiver).unwrap();
        let d = decode_actuators(&payload).unwrap();
        assert_eq!((d.value, d.time_source), (cmd, TimeSource::Receiver));
        assert_eq!(
            decode_actuators(&encode_actuators(&cmd, false).unwrap())
                .unwrap()
                .time_source,
            TimeSource::Source
        );
    }

    #[test]
    fn gnss_payload_rejections_are_typed() {
        let cases: [(&str, MessageError); 7] = [
            (
                r#"{"time":"2026-08-03T04:27:20Z","lat_deg":90.5,"lon_deg":0,"sog_mps":0,"cog_rad":0}"#,
                MessageError::OutOfRange { field: "lat_deg" },
            ),
            (
                r#"{"time":"2026-08-03T04:27:20Z","lat_deg":0,"lon_deg":-180.1,"sog_mps":0,"cog_rad":0}"#,
                MessageError::OutOfRange { field: "lon_deg" },
            ),
            (
                r#"{"time":"2026-08-03T04:27:20Z","lat_deg":0,"lon_deg":0,"sog_mps":-0.1,"cog_rad":0}"#,
                MessageError::OutOfRange { field: "sog_mps" },
            ),
            (
                r#"{"time":"2026-08-03T04:27:20Z","lat_deg":0,"lon_deg":0,"sog_mps":50.01,"cog_rad":0}"#,
                MessageError::OutOfRange { field: "sog_mps" },
            ),
            (
                r#"{"time":"2026-08-03T04:27:20Z","lat_deg":0,"lon_deg":0,"sog_mps":1,"cog_rad":0,"hdop":0}"#,
                MessageError::OutOfRange { field: "hdop" },
            ),
            (
                r#"{"time":"yesterday","lat_deg":0,"lon_deg":0,"sog_mps":1,"cog_rad":0}"#,
                MessageError::Time(TimeError::Malformed {
                    expected: "a four-digit year",
                }),
            ),
            (
                r#"{"time":"2026-08-03T04:27:20Z","lat_deg":0,"lon_deg":0,"sog_mps":1}"#,
                MessageError::Json {
                    category: JsonCategory::Data,
                    line: 1,
                    column: 67,
                },
            ),
        ];
        for (text, expected) in cases {
            assert_eq!(decode_gnss(text.as_bytes()), Err(expected), "{text}");
        }
        assert!(matches!(
            decode_gnss(b"{\"time\":"),
            Err(MessageError::Json {
                category: JsonCategory::Eof,
                ..
            })
        ));
        // 1e400 is out of f64 range: serde_json refuses it as a number.
        assert!(
            decode_gnss(
                br#"{"time":"2026-08-03T04:27:20Z","lat_deg":1e400,"lon_deg":0,"sog_mps":1,"cog_rad":0}"#
            )
            .is_err()
        );
    }

    #[test]
    fn oversized_payloads_are_refused_before_parsing() {
        // Not even JSON: the size check must come first.
        let big = vec![b'x'; DEFAULT_MAX_PAYLOAD_BYTES + 1];
        assert_eq!(
            decode_gnss(&big),
            Err(MessageError::TooLarge {
                len: DEFAULT_MAX_PAYLOAD_BYTES + 1,
                limit: DEFAULT_MAX_PAYLOAD_BYTES
            })
        );
        assert!(matches!(
            decode_actuators_limited(br#"{"time":"x"}"#, 4),
            Err(MessageError::TooLarge { len: 12, limit: 4 })
        ));
        assert!(decode_gnss_limited(FIX.as_bytes(), FIX.len()).is_ok());
    }

    #[test]
    fn actuators_payloads() {
        let d = decode_actuators(
            br#"{"time":"2026-08-03T04:27:20Z","rpm":{"port":600,"starboard":-60}}"#,
        )
        .unwrap();
        let ActuatorCommand::Speeds(s) = d.value else {
            panic!("expected speeds")
        };
        // 600 rpm = 10 rev/s = 20 pi rad/s.
        assert!((s.port_radps - 20.0 * std::f64::consts::PI).abs() < 1e-9);
        assert!((s.starboard_radps + 2.0 * std::f64::consts::PI).abs() < 1e-9);
        let d = decode_actuators(
            br#"{"time":"2026-08-03T04:27:20Z","thrust_n":{"port":10.5,"starboard":-3},"replay":true}"#,
        )
        .unwrap();
        assert!(d.replay);
        assert!(
            matches!(d.value, ActuatorCommand::Thrust(t) if t.port_n == 10.5 && t.starboard_n == -3.0)
        );
        assert_eq!(
            decode_actuators(br#"{"time":"2026-08-03T04:27:20Z"}"#),
            Err(MessageError::NoCommand)
        );
        assert_eq!(
            decode_actuators(
                br#"{"time":"2026-08-03T04:27:20Z","rpm":{"port":1,"starboard":1},"thrust_n":{"port":1,"starboard":1}}"#
            ),
            Err(MessageError::BothCommands)
        );
        assert_eq!(
            decode_actuators(
                br#"{"time":"2026-08-03T04:27:20Z","rpm":{"port":20001,"starboard":1}}"#
            ),
            Err(MessageError::OutOfRange { field: "rpm" })
        );
    }

    #[test]
    fn encoders_refuse_what_would_not_decode() {
        let fix = GnssFix {
            time_s: 0.0,
            position: LatLon {
                lat_deg: 1.0,
                lon_deg: 2.0,
            },
            sog_mps: None,
            cog_rad: Some(0.0),
            heading_rad: None,
            yaw_rate_radps: None,
            hdop: None,
        };
        assert_eq!(
            encode_gnss(&fix, false),
            Err(MessageError::MissingField { field: "sog_mps" })
        );
        let nan = GnssFix {
            sog_mps: Some(f64::NAN),
            ..fix
        };
        assert_eq!(
            encode_gnss(&nan, false),
            Err(MessageError::NotFinite { field: "sog_mps" })
        );
    }

    proptest! {
        #[test]
        fn gnss_round_trip(
            t in 0.0f64..4.0e9, lat in -90.0f64..=90.0, lon in -180.0f64..=180.0,
            sog in 0.0f64..=50.0, cog in 0.0f64..std::f64::consts::TAU, heading in proptest::option::of(0.0f64..std::f64::consts::TAU),
            hdop in proptest::option::of(0.1f64..50.0), replay in any::<bool>(),
        ) {
            let fix = GnssFix {
                time_s: t, position: LatLon { lat_deg: lat, lon_deg: lon },
                sog_mps: Some(sog), cog_rad: Some(cog), heading_rad: heading, yaw_rate_radps: None, hdop,
            };
            let bytes = encode_gnss(&fix, replay).unwrap();
            let back = decode_gnss(&bytes).unwrap();
            prop_assert_eq!(back.replay, replay);
            prop_assert!((back.value.time_s - t).abs() < 1e-6);
            // serde_json prints f64 in shortest round-trip form: exact.
            prop_assert_eq!(back.value.position, fix.position);
            prop_assert_eq!(back.value.sog_mps, fix.sog_mps);
            prop_assert_eq!(back.value.cog_rad, fix.cog_rad);
            prop_assert_eq!(back.value.heading_rad, fix.heading_rad);
            prop_assert_eq!(back.value.hdop, fix.hdop);
        }

        #[test]
        fn actuators_round_trip(t in 0.0f64..4.0e9, port in -2000.0f64..2000.0, stbd in -2000.0f64..2000.0) {
            let cmd = ActuatorCommand::Speeds(PropellerSpeeds { time_s: t, port_radps: port, starboard_radps: stbd });
            let back = decode_actuators(&encode_actuators(&cmd, false).unwrap()).unwrap();
            let ActuatorCommand::Speeds(s) = back.value else { panic!("speeds expected") };
            prop_assert!((s.port_radps - port).abs() < 1e-9 && (s.starboard_radps - stbd).abs() < 1e-9);
        }

        #[test]
        fn random_payloads_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..256)) {
            let _ = decode_gnss(&bytes);
            let _ = decode_actuators(&bytes);
        }
    }
}
