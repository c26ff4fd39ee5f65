//! MCAP recordings of the twin's inputs and outputs, for Foxglove and any
//! MCAP tool: one channel per topic per vessel, named like the contract's
//! key without its prefix (`/{vessel}/gnss`, `/{vessel}/twin/state`...),
//! each message the contract's JSON payload (message encoding `json`, a
//! JSON Schema per channel, schema encoding `jsonschema`), and beside the
//! states a `/{vessel}/twin/location` channel of `foxglove.LocationFix`
//! (the estimated position with its covariance) that Foxglove's map draws.
//! Raw NMEA input is recorded as `{"text": ...}`.
//!
//! The schemas are written here, in [`schema`], one per topic, until the
//! generated ones replace them.
//!
//! Reading back ([`input_json_lines`]): the input channels (`gnss`,
//! `actuators`) of a recording become the project's JSON lines, in log time
//! order, which every log reader takes; so `twin-replay` and `twin analyze`
//! read an MCAP recording like any other log.
//!
//! Log times are nanoseconds since the Unix epoch, given by the caller:
//! `twin analyze --mcap` stamps each message with its own time (the fix's),
//! `twind --record` with the time it received or published it.

use std::collections::{BTreeMap, HashMap};
use std::io::{Seek, Write};

use serde_json::{Value, json};

use crate::keys::Topic;
use crate::outputs::StateMessage;

/// The first bytes of every MCAP file.
pub const MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";

/// Why a recording cannot be written or read.
#[derive(Debug, thiserror::Error)]
pub enum McapError {
    /// The MCAP library refused (an I/O error, a malformed file).
    #[error("MCAP: {0}")]
    Mcap(#[from] ::mcap::McapError),
    /// A payload is not JSON.
    #[error("a payload on {topic} is not JSON: {source}")]
    NotJson {
        /// The channel.
        topic: String,
        /// The parser's error.
        source: serde_json::Error,
    },
    /// A time before 1970 or not finite.
    #[error("log time {0} s cannot be recorded")]
    BadTime(f64),
}

fn gnss_properties() -> Value {
    let number = json!({ "type": "number" });
    let optional = json!({ "type": ["number", "null"] });
    json!({ "time": { "type": "string", "description": "RFC 3339, UTC" },
            "lat_deg": number, "lon_deg": number, "sog_mps": number, "cog_rad": number,
            "heading_rad": optional, "yaw_rate_radps": optional, "hdop": optional,
            "replay": { "type": "boolean" },
            "time_source": { "enum": ["source", "receiver"] } })
}

fn state_properties() -> Value {
    let number = json!({ "type": "number" });
    json!({ "vessel": { "type": "string" },
            "time": { "type": "string", "description": "RFC 3339, UTC" },
            "lat_deg": number, "lon_deg": number, "north_m": number, "east_m": number,
            "sog_mps": number, "cog_rad": number, "heading_rad": { "type": ["number", "null"] },
            "sigma": { "type": "object" }, "nis": number,
            "current": { "type": ["object", "null"] }, "model": { "type": "string" },
            "stale": { "type": "boolean" }, "replay": { "type": "boolean" } })
}

/// The schema name and JSON Schema of a topic's payloads.
pub fn schema(topic: Topic) -> (&'static str, Value) {
    let number = json!({ "type": "number" });
    let time = json!({ "type": "string", "description": "RFC 3339, UTC" });
    let object = |title: &str, required: &[&str], properties: Value| {
        json!({
            "$schema": "https://json-schema.org/draft/2020-12/schema",
            "title": title,
            "type": "object",
            "required": required,
            "properties": properties,
        })
    };
    match topic {
        Topic::Gnss => (
            "twin_wire.GnssMessage",
            object(
                "GnssMessage",
                &["time", "lat_deg", "lon_deg", "sog_mps", "cog_rad"],
                gnss_properties(),
            ),
        ),
        Topic::Nmea => (
            "twin_wire.NmeaText",
            object(
                "NmeaText",
                &["text"],
                json!({ "text": { "type": "string" } }),
            ),
        ),
        Topic::Actuators => (
            "twin_wire.ActuatorsMessage",
            object(
                "ActuatorsMessage",
                &["time"],
                json!({ "time": time, "rpm": { "type": "object" },
                        "thrust_n": { "type": "object" }, "replay": { "type": "boolean" } }),
            ),
        ),
        Topic::TwinState => (
            "twin_wire.StateMessage",
            object(
                "StateMessage",
                &[
                    "vessel", "time", "lat_deg", "lon_deg", "sog_mps", "cog_rad", "sigma", "stale",
                ],
                state_properties(),
            ),
        ),
        Topic::TwinFault => (
            "twin_wire.FaultMessage",
            object(
                "FaultMessage",
                &["vessel", "time", "thrusters", "status"],
                json!({ "vessel": { "type": "string" }, "time": time,
                        "thrusters": { "type": "object", "required": ["port", "starboard"] },
                        "status": { "enum": ["not_excited", "nominal", "suspect", "fault"] },
                        "excited": { "type": "boolean" },
                        "effectiveness_ratio": { "type": ["object", "null"] } }),
            ),
        ),
        Topic::TwinPrediction => (
            "twin_wire.PredictionMessage",
            object(
                "PredictionMessage",
                &["vessel", "start", "points"],
                json!({ "vessel": { "type": "string" }, "start": time,
                        "horizon_s": number, "step_s": number,
                        "points": { "type": "array", "items": { "type": "object" } } }),
            ),
        ),
        Topic::TwinAlarm => (
            "twin_wire.AlarmMessage",
            object(
                "AlarmMessage",
                &["vessel", "time", "side", "from", "to"],
                json!({ "vessel": { "type": "string" }, "time": time, "what": { "type": "string" },
                        "side": { "enum": ["port", "starboard"] },
                        "from": { "type": "string" }, "to": { "type": "string" },
                        "onset": time, "confidence": number }),
            ),
        ),
        Topic::TwinFinding => (
            "twin_wire.FindingsMessage",
            object(
                "FindingsMessage",
                &["vessel", "time", "findings"],
                json!({ "vessel": { "type": "string" }, "time": time,
                        "findings": { "type": "array", "items": { "type": "object" } } }),
            ),
        ),
        Topic::TwinStats | Topic::TwinAlive => (
            "twin_wire.StatsMessage",
            object(
                "StatsMessage",
                &["vessel"],
                json!({ "vessel": { "type": "string" }, "received": { "type": "object" },
                        "accepted": { "type": "object" }, "rejected": { "type": "object" } }),
            ),
        ),
    }
}

/// The name of Foxglove's position schema.
pub const LOCATION_FIX: &str = "foxglove.LocationFix";

/// The JSON Schema of `foxglove.LocationFix`.
pub fn location_fix_schema() -> Value {
    let number = json!({ "type": "number" });
    json!({
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": LOCATION_FIX,
        "description": "A navigation satellite fix",
        "type": "object",
        "properties": {
            "timestamp": { "type": "object", "properties": {
                "sec": { "type": "integer", "minimum": 0 },
                "nsec": { "type": "integer", "minimum": 0, "maximum": 999_999_999 } } },
            "frame_id": { "type": "string" },
            "latitude": number,
            "longitude": number,
            "altitude": number,
            "position_covariance": { "type": "array", "items": number, "minItems": 9, "maxItems": 9 },
            "position_covariance_type": { "type": "integer", "enum": [0, 1, 2, 3] },
        },
    })
}

/// A state as a `foxglove.LocationFix`: the position, no altitude (0), the
/// covariance diagonal in east, north, up (m²; up unknown, 0), of type 2
/// (diagonal known).
pub fn location_fix(state: &StateMessage, time_ns: u64) -> Value {
    json!({
        "timestamp": { "sec": time_ns / 1_000_000_000, "nsec": time_ns % 1_000_000_000 },
        "frame_id": state.vessel,
        "latitude": state.lat_deg,
        "longitude": state.lon_deg,
        "altitude": 0.0,
        "position_covariance": [
            state.sigma.east_m.powi(2), 0.0, 0.0,
            0.0, state.sigma.north_m.powi(2), 0.0,
            0.0, 0.0, 0.0,
        ],
        "position_covariance_type": 2,
    })
}

/// Nanoseconds since the Unix epoch of a time in seconds.
pub fn time_ns(time_s: f64) -> Result<u64, McapError> {
    if (0.0..1.8e10).contains(&time_s) {
        Ok((time_s * 1e9).round() as u64)
    } else {
        Err(McapError::BadTime(time_s))
    }
}

/// Which channel: a contract topic, or the location derived from states.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum ChannelKind {
    Topic(Topic),
    Location,
}

/// Writes a recording.
pub struct McapRecorder<W: Write + Seek> {
    writer: ::mcap::Writer<W>,
    schemas: HashMap<ChannelKind, u16>,
    channels: HashMap<(String, ChannelKind), (u16, u32)>,
    counts: BTreeMap<String, u64>,
}

impl<W: Write + Seek> std::fmt::Debug for McapRecorder<W> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("McapRecorder")
            .field("counts", &self.counts)
            .finish_non_exhaustive()
    }
}

impl<W: Write + Seek> McapRecorder<W> {
    /// Starts a recording on `out` (uncompressed chunks, with the summary
    /// and indexes that let readers seek).
    pub fn new(out: W) -> Result<Self, McapError> {
        let writer = ::mcap::WriteOptions::new()
            .compression(None)
            .profile("")
            .library("usv-twin")
            .create(out)?;
        Ok(Self {
            writer,
            schemas: HashMap::new(),
            channels: HashMap::new(),
            counts: BTreeMap::new(),
        })
    }

    fn channel(&mut self, vessel: &str, kind: ChannelKind) -> Result<(u16, u32), McapError> {
        if let Some(&(id, sequence)) = self.channels.get(&(vessel.to_string(), kind)) {
            return Ok((id, sequence));
        }
        let schema_id = match self.schemas.get(&kind) {
            Some(&id) => id,
            None => {
                let (name, schema) = match kind {
                    ChannelKind::Topic(t) => schema(t),
                    ChannelKind::Location => (LOCATION_FIX, location_fix_schema()),
                };
                let id =
                    self.writer
                        .add_schema(name, "jsonschema", schema.to_string().as_bytes())?;
                self.schemas.insert(kind, id);
                id
            }
        };
        let topic = channel_topic(vessel, kind);
        let id = self
            .writer
            .add_channel(schema_id, &topic, "json", &BTreeMap::new())?;
        self.channels.insert((vessel.to_string(), kind), (id, 0));
        Ok((id, 0))
    }

    fn write(
        &mut self,
        vessel: &str,
        kind: ChannelKind,
        data: &[u8],
        log_time_ns: u64,
    ) -> Result<(), McapError> {
        let (channel_id, sequence) = self.channel(vessel, kind)?;
        self.writer.write_to_known_channel(
            &::mcap::records::MessageHeader {
                channel_id,
                sequence,
                log_time: log_time_ns,
                publish_time: log_time_ns,
            },
            data,
        )?;
        if let Some(entry) = self.channels.get_mut(&(vessel.to_string(), kind)) {
            entry.1 = sequence.wrapping_add(1);
        }
        *self.counts.entry(channel_topic(vessel, kind)).or_default() += 1;
        Ok(())
    }

    /// Records one payload of `vessel` on `topic` at `log_time_s`: JSON
    /// payloads as they are (a state also as a location), raw NMEA wrapped
    /// as `{"text": ...}`.
    pub fn record(
        &mut self,
        vessel: &str,
        topic: Topic,
        payload: &[u8],
        log_time_s: f64,
    ) -> Result<(), McapError> {
        let log_time_ns = time_ns(log_time_s)?;
        if topic == Topic::Nmea {
            let text = json!({ "text": String::from_utf8_lossy(payload) }).to_string();
            return self.write(
                vessel,
                ChannelKind::Topic(topic),
                text.as_bytes(),
                log_time_ns,
            );
        }
        let not_json = |source| McapError::NotJson {
            topic: channel_topic(vessel, ChannelKind::Topic(topic)),
            source,
        };
        if topic == Topic::TwinState {
            let state: StateMessage = serde_json::from_slice(payload).map_err(not_json)?;
            let fix = location_fix(&state, log_time_ns).to_string();
            self.write(vessel, ChannelKind::Location, fix.as_bytes(), log_time_ns)?;
        } else {
            serde_json::from_slice::<serde::de::IgnoredAny>(payload).map_err(not_json)?;
        }
        self.write(vessel, ChannelKind::Topic(topic), payload, log_time_ns)
    }

    /// Messages written so far per channel topic.
    pub fn counts(&self) -> &BTreeMap<String, u64> {
        &self.counts
    }

    /// Writes the summary and the end of the file; the messages written per
    /// channel topic.
    pub fn finish(mut self) -> Result<BTreeMap<String, u64>, McapError> {
        self.writer.finish()?;
        Ok(self.counts)
    }
}

/// The channel topic of a vessel's topic.
fn channel_topic(vessel: &str, kind: ChannelKind) -> String {
    match kind {
        ChannelKind::Topic(t) => format!("/{vessel}/{}", t.suffix()),
        ChannelKind::Location => format!("/{vessel}/twin/location"),
    }
}

/// The `gnss` and `actuators` messages of a recording as the project's JSON
/// lines (`{"type": "gnss", ...}`), in log time order (the order recorded
/// among equal times); other channels are left out. With more than one
/// vessel, every vessel's inputs are given.
pub fn input_json_lines(recording: &[u8]) -> Result<Vec<u8>, McapError> {
    let mut inputs: Vec<(u64, usize, Vec<u8>)> = Vec::new();
    for (i, message) in ::mcap::MessageStream::new(recording)?.enumerate() {
        let message = message?;
        let kind = match message.channel.topic.rsplit('/').next() {
            Some("gnss") => "gnss",
            Some("actuators") => "actuators",
            _ => continue,
        };
        let mut value: Value =
            serde_json::from_slice(&message.data).map_err(|source| McapError::NotJson {
                topic: message.channel.topic.clone(),
                source,
            })?;
        if let Value::Object(map) = &mut value {
            map.insert("type".to_string(), Value::from(kind));
        }
        let mut line = value.to_string().into_bytes();
        line.push(b'\n');
        inputs.push((message.log_time, i, line));
    }
    inputs.sort_by_key(|(t, i, _)| (*t, *i));
    Ok(inputs.into_iter().flat_map(|(_, _, line)| line).collect())
}

/// A log file ready for [`crate::LogReader`]: an MCAP recording (known by
/// its first bytes) as its inputs' JSON lines ([`input_json_lines`], the
/// whole recording read into memory), any other file as it is, buffered.
pub fn open_log_file(path: &std::path::Path) -> std::io::Result<Box<dyn std::io::BufRead + Send>> {
    use std::io::{BufRead, Read};
    let mut file = std::io::BufReader::with_capacity(1 << 16, std::fs::File::open(path)?);
    if !file.fill_buf()?.starts_with(MAGIC) {
        return Ok(Box::new(file));
    }
    let mut recording = Vec::new();
    file.read_to_end(&mut recording)?;
    let lines = input_json_lines(&recording)
        .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidData, e))?;
    Ok(Box::new(std::io::Cursor::new(lines)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inputs_read_back_as_json_lines_in_log_time_order() {
        let mut out = std::io::Cursor::new(Vec::new());
        let mut rec = McapRecorder::new(&mut out).unwrap();
        let fix = br#"{"time":"2024-05-01T10:00:01Z","lat_deg":59.9,"lon_deg":10.7,"sog_mps":1.0,"cog_rad":0.1}"#;
        let act = br#"{"time":"2024-05-01T10:00:00Z","rpm":{"port":100.0,"starboard":100.0}}"#;
        rec.record("v1", Topic::Gnss, fix, 1_714_557_601.0).unwrap();
        rec.record("v1", Topic::Actuators, act, 1_714_557_600.0)
            .unwrap();
        rec.record("v1", Topic::Nmea, b"$GPRMC,garbage", 1_714_557_602.0)
            .unwrap();
        assert!(
            rec.record("v1", Topic::TwinFault, b"{not json", 1.0)
                .is_err()
        );
        let counts = rec.finish().unwrap();
        assert_eq!(counts["/v1/gnss"], 1);
        assert_eq!(counts["/v1/nmea"], 1);
        let bytes = out.into_inner();
        assert!(bytes.starts_with(MAGIC));
        let lines = String::from_utf8(input_json_lines(&bytes).unwrap()).unwrap();
        let types: Vec<String> = lines
            .lines()
            .map(|l| serde_json::from_str::<Value>(l).unwrap()["type"].to_string())
            .collect();
        assert_eq!(types, ["\"actuators\"", "\"gnss\""]);
    }
}
