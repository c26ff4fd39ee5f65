//! The project's own JSON-lines log format, and its decoder.
//!
//! # Format
//! UTF-8 text, one JSON object per line (`\n` or `\r\n`), blank lines and
//! lines starting with `#` skipped. Each object has a `"type"` tag and
//! otherwise exactly the fields of the matching Zenoh payload
//! ([`crate::messages`]):
//! ```text
//! {"type":"gnss","time":"2026-08-03T04:27:20.588Z","lat_deg":34.41,"lon_deg":133.54,"sog_mps":2.77,"cog_rad":5.0265,"heading_rad":5.01,"hdop":0.9}
//! {"type":"actuators","time":"2026-08-03T04:27:20.600Z","rpm":{"port":1200.0,"starboard":1185.5}}
//! {"type":"actuators","time":"2026-08-03T04:27:20.700Z","thrust_n":{"port":40.0,"starboard":38.5}}
//! ```
//! A GNSS line gives a [`Measurement::GnssFix`], an actuators line a
//! [`Measurement::Propellers`] (rpm, converted to rad/s) or a
//! [`Measurement::Thrust`]. The source of every record is [`Source::Json`].
//! The same validation as for payloads applies (ranges, time, one command);
//! times must not go backwards beyond the tolerance. Another `type` is a
//! `Message` rejection (JSON data error), not an ignored line: the format is
//! the project's own, so an unknown type is a mistake.

use serde::{Deserialize, Serialize};

use super::{
    Decoder, Emit, Item, Monotonic, ReadOptions, ReadStats, RejectReason, reject_whole_line,
    trim_line,
};
use crate::measurement::{Measurement, Source};
use crate::messages::{ActuatorCommand, ActuatorsMessage, GnssMessage, MessageError};

/// One line of a JSON-lines log, as on the wire.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase")]
pub enum JsonLine {
    /// A GNSS fix.
    Gnss(GnssMessage),
    /// A propeller command.
    Actuators(ActuatorsMessage),
}

/// The JSON-lines decoder.
#[derive(Debug, Clone)]
pub struct JsonlDecoder {
    options: ReadOptions,
    stats: ReadStats,
    monotonic: Monotonic,
}

impl JsonlDecoder {
    /// A decoder with `options`.
    pub fn new(options: ReadOptions) -> Self {
        Self {
            options,
            stats: ReadStats::default(),
            monotonic: Monotonic::default(),
        }
    }
}

/// Decodes one line; `Err` rejects it.
fn decode_json_line(
    monotonic: &mut Monotonic,
    options: &ReadOptions,
    line: &[u8],
    emit: &mut Emit<'_>,
) -> Result<(), RejectReason> {
    let line = trim_line(line);
    if line.is_empty() || line.first() == Some(&b'#') {
        emit.stats.blank += 1;
        return Ok(());
    }
    if line.first() != Some(&b'{') {
        return Err(RejectReason::UnknownFormat);
    }
    let parsed: JsonLine =
        serde_json::from_slice(line).map_err(|e| RejectReason::Message(MessageError::from(e)))?;
    let measurement = match parsed {
        JsonLine::Gnss(m) => Measurement::GnssFix(m.to_fix().map_err(RejectReason::Message)?),
        JsonLine::Actuators(m) => match m.to_command().map_err(RejectReason::Message)? {
            ActuatorCommand::Speeds(s) => Measurement::Propellers(s),
            ActuatorCommand::Thrust(t) => Measurement::Thrust(t),
        },
    };
    let time_s = match &measurement {
        Measurement::GnssFix(f) => f.time_s,
        Measurement::Propellers(p) => p.time_s,
        Measurement::Thrust(t) => t.time_s,
        _ => return Ok(()),
    };
    monotonic.check(time_s, options.backwards_tolerance_s)?;
    emit.record(time_s, Source::Json, measurement);
    Ok(())
}

impl Decoder for JsonlDecoder {
    fn decode_line(&mut self, line: &[u8], line_no: u64, out: &mut Vec<Item>) {
        self.stats.lines += 1;
        let mut emit = Emit {
            out,
            stats: &mut self.stats,
            line: line_no,
        };
        if let Err(reason) = decode_json_line(&mut self.monotonic, &self.options, line, &mut emit) {
            emit.reject(reason);
        }
    }

    fn reject_line(&mut self, line_no: u64, reason: RejectReason, out: &mut Vec<Item>) {
        reject_whole_line(&mut self.stats, line_no, reason, out);
    }

    fn stats(&self) -> &ReadStats {
        &self.stats
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::messages::JsonCategory;
    use crate::read::RejectKind;
    use crate::time::parse_rfc3339;
    use twin_core::sample::RADPS_PER_RPM;

    fn decode(lines: &[&str]) -> (Vec<Item>, ReadStats) {
        let mut d = JsonlDecoder::new(ReadOptions::default());
        let mut out = Vec::new();
        for (i, l) in lines.iter().enumerate() {
            d.decode_line(l.as_bytes(), i as u64 + 1, &mut out);
        }
        (out, d.stats().clone())
    }

    #[test]
    fn documented_example_lines_decode() {
        let (items, stats) = decode(&[
            "# a log",
            r#"{"type":"gnss","time":"2026-08-03T04:27:20.588Z","lat_deg":34.41,"lon_deg":133.54,"sog_mps":2.77,"cog_rad":5.0265,"heading_rad":5.01,"hdop":0.9}"#,
            r#"{"type":"actuators","time":"2026-08-03T04:27:20.600Z","rpm":{"port":1200.0,"starboard":1185.5}}"#,
            r#"{"type":"actuators","time":"2026-08-03T04:27:20.700Z","thrust_n":{"port":40.0,"starboard":38.5}}"#,
        ]);
        assert_eq!(stats.total_rejected(), 0);
        assert_eq!(stats.blank, 1);
        let t0 = parse_rfc3339("2026-08-03T04:27:20.588Z").unwrap();
        let r = items[0].as_ref().unwrap();
        assert_eq!((r.time_s, r.source), (t0, Source::Json));
        let Measurement::GnssFix(f) = r.measurement else {
            panic!()
        };
        assert_eq!(
            (f.position.lat_deg, f.sog_mps, f.hdop),
            (34.41, Some(2.77), Some(0.9))
        );
        let Measurement::Propellers(p) = items[1].as_ref().unwrap().measurement else {
            panic!()
        };
        assert!((p.port_radps - 1200.0 * RADPS_PER_RPM).abs() < 1e-9);
        assert!(matches!(
            items[2].as_ref().unwrap().measurement,
            Measurement::Thrust(t) if t.port_n == 40.0 && t.starboard_n == 38.5
        ));
    }

    #[test]
    fn bad_lines_are_typed() {
        let (items, stats) = decode(&[
            r#"{"type":"wind","time":"2026-08-03T04:27:20Z"}"#,
            r#"{"type":"gnss","time":"2026-08-03T04:27:20Z","lat_deg":91,"lon_deg":0,"sog_mps":0,"cog_rad":0}"#,
            "[1,2]",
            r#"{"type":"gnss""#,
            r#"{"type":"gnss","time":"2026-08-03T04:27:20Z","lat_deg":1,"lon_deg":0,"sog_mps":0,"cog_rad":0}"#,
            r#"{"type":"gnss","time":"2026-08-03T04:27:10Z","lat_deg":1,"lon_deg":0,"sog_mps":0,"cog_rad":0}"#,
        ]);
        let reasons: Vec<RejectKind> = items
            .iter()
            .filter_map(|i| i.as_ref().err().map(|r| r.reason.kind()))
            .collect();
        assert_eq!(
            reasons,
            [
                RejectKind::Message,
                RejectKind::Message,
                RejectKind::UnknownFormat,
                RejectKind::Message,
                RejectKind::TimeBackwards
            ]
        );
        assert!(matches!(
            items[0].as_ref().unwrap_err().reason,
            RejectReason::Message(MessageError::Json {
                category: JsonCategory::Data,
                ..
            })
        ));
        assert_eq!(
            items[1].as_ref().unwrap_err().reason,
            RejectReason::Message(MessageError::OutOfRange { field: "lat_deg" })
        );
        assert_eq!(stats.total_records(), 1);
    }
}
