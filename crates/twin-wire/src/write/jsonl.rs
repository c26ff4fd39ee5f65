//! The JSON-lines writer (format: [`crate::read::jsonl`]).

use std::io::Write;

use twin_core::sample::GnssFix;

use super::WriteError;
use crate::messages::{ActuatorCommand, ActuatorsMessage, GnssMessage};
use crate::read::jsonl::JsonLine;

/// Writes GNSS fixes and actuator commands as JSON lines.
#[derive(Debug)]
pub struct JsonlWriter<W> {
    out: W,
}

impl<W: Write> JsonlWriter<W> {
    /// A writer to `out`.
    pub fn new(out: W) -> Self {
        Self { out }
    }

    fn line(&mut self, line: &JsonLine) -> Result<(), WriteError> {
        serde_json::to_writer(&mut self.out, line).map_err(|e| WriteError::Message(e.into()))?;
        self.out.write_all(b"\n")?;
        Ok(())
    }

    /// Writes a fix (it must carry SOG and COG, as the contract requires).
    pub fn gnss(&mut self, fix: &GnssFix) -> Result<(), WriteError> {
        let message = GnssMessage::from_fix(fix, false)?;
        self.line(&JsonLine::Gnss(message))
    }

    /// Writes an actuators command.
    pub fn actuators(&mut self, command: &ActuatorCommand) -> Result<(), WriteError> {
        let message = ActuatorsMessage::from_command(command, false)?;
        self.line(&JsonLine::Actuators(message))
    }

    /// Flushes and gives the output back.
    pub fn into_inner(mut self) -> Result<W, WriteError> {
        self.out.flush()?;
        Ok(self.out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measurement::{Measurement, ThrustCommand};
    use crate::read::{LogFormat, LogReader, ReadOptions};
    use proptest::prelude::*;
    use twin_core::geodesy::LatLon;
    use twin_core::sample::PropellerSpeeds;

    #[test]
    fn written_lines_read_back_exactly() {
        let fix = GnssFix {
            time_s: 1_785_731_240.588,
            position: LatLon {
                lat_deg: 34.41,
                lon_deg: 133.54,
            },
            sog_mps: Some(2.77),
            cog_rad: Some(5.0265),
            heading_rad: Some(5.01),
            yaw_rate_radps: None,
            hdop: None,
        };
        let speeds = PropellerSpeeds {
            time_s: 1_785_731_240.6,
            port_radps: 125.0,
            starboard_radps: -3.5,
        };
        let thrust = ThrustCommand {
            time_s: 1_785_731_240.7,
            port_n: 40.0,
            starboard_n: 38.5,
        };
        let mut w = JsonlWriter::new(Vec::new());
        w.gnss(&fix).unwrap();
        w.actuators(&ActuatorCommand::Speeds(speeds)).unwrap();
        w.actuators(&ActuatorCommand::Thrust(thrust)).unwrap();
        let bytes = w.into_inner().unwrap();
        let text = String::from_utf8(bytes.clone()).unwrap();
        assert!(
            text.starts_with(
                r#"{"type":"gnss","time":"2026-08-03T04:27:20.588Z","lat_deg":34.41,"#
            ),
            "{text}"
        );
        let reader = LogReader::open(&bytes[..], ReadOptions::default()).unwrap();
        assert_eq!(reader.format(), LogFormat::JsonLines);
        let records: Vec<_> = reader.map(|i| i.unwrap().measurement).collect();
        assert_eq!(records[0], Measurement::GnssFix(fix));
        let Measurement::Propellers(p) = records[1] else {
            panic!()
        };
        assert!((p.time_s - speeds.time_s).abs() < 1e-6);
        assert!((p.port_radps - 125.0).abs() < 1e-9 && (p.starboard_radps + 3.5).abs() < 1e-9);
        assert!(matches!(records[2], Measurement::Thrust(t) if t.port_n == 40.0));
    }

    proptest! {
        #[test]
        fn generated_lines_round_trip(lat in -90.0f64..=90.0, lon in -180.0f64..=180.0, sog in 0.0f64..=50.0, cog in 0.0f64..std::f64::consts::TAU) {
            let fix = GnssFix {
                time_s: 1.7e9, position: LatLon { lat_deg: lat, lon_deg: lon },
                sog_mps: Some(sog), cog_rad: Some(cog), heading_rad: None, yaw_rate_radps: None, hdop: Some(1.1),
            };
            let mut w = JsonlWriter::new(Vec::new());
            w.gnss(&fix).unwrap();
            let bytes = w.into_inner().unwrap();
            let mut reader = LogReader::open(&bytes[..], ReadOptions::default()).unwrap();
            prop_assert_eq!(reader.next().unwrap().unwrap().measurement, Measurement::GnssFix(fix));
        }
    }
}
