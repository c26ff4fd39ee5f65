//! gpsd's JSON reports (what `?WATCH={"enable":true,"json":true}` streams
//! on TCP port 2947, and what `gpspipe -w` writes to a log) to
//! [`Record`](crate::measurement::Record)s.
//!
//! # Reports read
//! - `TPV` (time-position-velocity): `lat`/`lon` give a position when
//!   `mode` is 2 (2D) or 3 (3D); mode 0 or 1 with a position is refused as
//!   not valid. `status` gives the fix method (2 DGPS, 3 RTK fixed, 4 RTK
//!   float, 5 and 6 dead reckoning, 8 simulated; otherwise standalone).
//!   `altHAE` (height above the ellipsoid) is kept. `track` (true course,
//!   degrees) and `speed` (m/s) give course and speed; `magtrack` is not
//!   used.
//! - `ATT` (attitude): `heading`, degrees from true north, gives a heading;
//!   `rot`, the rate of turn in degrees per minute (negative turning to
//!   port, as NMEA 0183's `ROT` that gpsd passes on), gives a yaw rate,
//!   refused beyond the contract's
//!   [`MAX_ABS_YAW_RATE_RADPS`](crate::messages::MAX_ABS_YAW_RATE_RADPS).
//!   The gyro's `gyro_z` is not read: gpsd's documentation (gpsd_json(5))
//!   gives its unit, degrees per second, but not the direction of its axis.
//!   `IMU` reports (the same fields on the sensor's own time scale) are
//!   ignored.
//! - `SKY`: its `hdop` is kept and given to the following positions of the
//!   same device.
//!
//! Every other class (`VERSION`, `DEVICES`, `WATCH`, `PPS`, `TOFF`, ...) is
//! counted as ignored. A line that is not JSON, or a report whose fields
//! have the wrong type, is refused (`Message`).
//!
//! # Sources and time
//! Each device gpsd names (`device`, e.g. `/dev/ttyUSB0`) is a source
//! [`Source::Gpsd`], numbered in the order first seen (at most 256). A
//! report's `time` (the receiver's GNSS time, RFC 3339) is its time. An
//! `ATT` without time (gpsd sends its heading before the epoch's `TPV`)
//! takes the latest time of the stream, and is refused (`NoTime`) before
//! there is one. A `TPV` without time takes the time it was received when
//! the decoder is live (`Clock::Receiver`) and the stream has not yet given
//! a time of its own; otherwise it is refused (`NoTime`). The first report
//! on the receiver's clock after receive-stamped ones starts a new time
//! line (it is not refused as time going back).

use serde::Deserialize;

use super::clock::DayClock;
use super::{Clock, Counted, Emit, LineDecoder, ReadOptions, RejectReason};
use crate::measurement::{FixMethod, MAX_SPEED_MPS, Measurement, Source};
use crate::messages::{MAX_ABS_YAW_RATE_RADPS, MessageError};
use crate::time::parse_rfc3339;

/// The most devices numbered; later ones share the last number.
pub const MAX_DEVICES: usize = 256;

/// The fields read from any report (others are ignored).
#[derive(Debug, Default, Deserialize)]
struct Report {
    class: String,
    #[serde(default)]
    device: Option<String>,
    #[serde(default)]
    mode: Option<u8>,
    #[serde(default)]
    status: Option<u8>,
    #[serde(default)]
    time: Option<String>,
    #[serde(default)]
    lat: Option<f64>,
    #[serde(default)]
    lon: Option<f64>,
    #[serde(default, rename = "altHAE")]
    alt_hae: Option<f64>,
    #[serde(default)]
    track: Option<f64>,
    #[serde(default)]
    speed: Option<f64>,
    #[serde(default)]
    heading: Option<f64>,
    /// Rate of turn, degrees per minute.
    #[serde(default)]
    rot: Option<f64>,
    #[serde(default)]
    hdop: Option<f64>,
}

/// The state of the gpsd decoder (devices, hdop, clock).
#[derive(Debug, Clone)]
pub struct GpsdState {
    options: ReadOptions,
    devices: Vec<String>,
    /// The latest SKY hdop of each device (by number).
    hdop: Vec<Option<f64>>,
    clock: DayClock,
    /// A report with its own time has been seen.
    own_time_seen: bool,
    receive_time_s: Option<f64>,
    receiver_stamped: bool,
}

/// The gpsd decoder.
pub type GpsdDecoder = Counted<GpsdState>;

/// True when a line looks like a gpsd report (a JSON object with `class`).
pub fn looks_like_gpsd(line: &[u8]) -> bool {
    let line = line.trim_ascii();
    line.first() == Some(&b'{')
        && serde_json::from_slice::<Report>(line).is_ok_and(|r| !r.class.is_empty())
}

fn in_range(value: f64, field: &'static str, ok: bool) -> Result<f64, RejectReason> {
    if !value.is_finite() {
        return Err(RejectReason::BadField { field });
    }
    if ok {
        Ok(value)
    } else {
        Err(RejectReason::OutOfRange { field })
    }
}

fn degrees(value: Option<f64>, field: &'static str) -> Result<Option<f64>, RejectReason> {
    value
        .map(|d| {
            in_range(d, field, (0.0..=360.0).contains(&d))
                .map(|d| twin_core::geodesy::wrap_two_pi(d.to_radians()))
        })
        .transpose()
}

impl Counted<GpsdState> {
    /// A decoder with `options`.
    pub fn new(options: ReadOptions) -> Self {
        Counted::from_state(GpsdState {
            options,
            devices: Vec::new(),
            hdop: Vec::new(),
            clock: DayClock::default(),
            own_time_seen: false,
            receive_time_s: None,
            receiver_stamped: false,
        })
    }
}

impl GpsdState {
    fn device(&mut self, name: Option<&str>) -> u8 {
        let name = name.unwrap_or("");
        let index = match self.devices.iter().position(|d| d == name) {
            Some(i) => i,
            None if self.devices.len() < MAX_DEVICES => {
                self.devices.push(name.to_owned());
                self.hdop.push(None);
                self.devices.len() - 1
            }
            None => MAX_DEVICES - 1,
        };
        index as u8
    }

    /// The time of a report (see the module doc).
    fn time(&mut self, report: &Report, untimed_ok: bool) -> Result<f64, RejectReason> {
        let tolerance = self.options.backwards_tolerance_s;
        if let Some(text) = &report.time {
            let t = parse_rfc3339(text).map_err(RejectReason::BadTime)?;
            if !std::mem::replace(&mut self.own_time_seen, true) {
                // The first report on the receiver's own clock after
                // reports on receive times: a new time line (the two
                // clocks need not agree), not a jump back.
                self.clock = DayClock::default();
            }
            return self.clock.exact(t, tolerance).map(|s| s.time_s);
        }
        if untimed_ok {
            // An ATT: gpsd sends it before the epoch's TPV, without time.
            return self.clock.untimed().map(|s| s.time_s);
        }
        match (self.options.clock, self.receive_time_s) {
            (Clock::Receiver, Some(t)) if !self.own_time_seen => {
                self.receiver_stamped = true;
                self.clock.exact(t, tolerance).map(|s| s.time_s)
            }
            _ => Err(RejectReason::NoTime),
        }
    }

    fn report(&mut self, line: &[u8], emit: &mut Emit<'_>) -> Result<(), RejectReason> {
        let line = line.trim_ascii();
        if line.is_empty() {
            emit.stats.blank += 1;
            return Ok(());
        }
        if line.first() != Some(&b'{') {
            return Err(RejectReason::UnknownFormat);
        }
        let report: Report = serde_json::from_slice(line)
            .map_err(|e| RejectReason::Message(MessageError::from(e)))?;
        match report.class.as_str() {
            "TPV" => self.tpv(&report, emit),
            "ATT" => self.att(&report, emit),
            "SKY" => {
                let device = self.device(report.device.as_deref());
                let hdop = report
                    .hdop
                    .filter(|h| h.is_finite() && *h > 0.0 && *h < 100.0);
                if let Some(slot) = self.hdop.get_mut(usize::from(device)) {
                    *slot = hdop;
                }
                emit.stats.ignored += 1;
                Ok(())
            }
            _ => {
                emit.stats.ignored += 1;
                Ok(())
            }
        }
    }

    /// An attitude report: its heading and its rate of turn, each where
    /// given; a field out of its range refuses the report.
    fn att(&mut self, report: &Report, emit: &mut Emit<'_>) -> Result<(), RejectReason> {
        let device = self.device(report.device.as_deref());
        let heading = degrees(report.heading, "heading")?;
        let yaw_rate = report
            .rot
            .map(|deg_per_min| {
                let radps = deg_per_min.to_radians() / 60.0;
                in_range(radps, "rot", radps.abs() <= MAX_ABS_YAW_RATE_RADPS)
            })
            .transpose()?;
        if heading.is_none() && yaw_rate.is_none() {
            emit.stats.empty += 1;
            return Ok(());
        }
        let time_s = self.time(report, true)?;
        let source = Source::Gpsd(device);
        if let Some(heading_rad) = heading {
            emit.record(time_s, source, Measurement::Heading { heading_rad });
        }
        if let Some(radps) = yaw_rate {
            emit.record(time_s, source, Measurement::RateOfTurn { radps });
        }
        Ok(())
    }

    fn tpv(&mut self, report: &Report, emit: &mut Emit<'_>) -> Result<(), RejectReason> {
        let device = self.device(report.device.as_deref());
        let source = Source::Gpsd(device);
        let mode = report.mode.unwrap_or(0);
        let position = match (report.lat, report.lon) {
            (Some(lat), Some(lon)) => {
                if mode < 2 {
                    return Err(RejectReason::NotValid { what: "TPV mode" });
                }
                let lat = in_range(lat, "lat", lat.abs() <= 90.0)?;
                let lon = in_range(lon, "lon", lon.abs() <= 180.0)?;
                Some((lat, lon))
            }
            _ => None,
        };
        let cog = degrees(report.track, "track")?;
        let sog = report
            .speed
            .map(|v| in_range(v, "speed", (0.0..=MAX_SPEED_MPS).contains(&v)))
            .transpose()?;
        if position.is_none() && cog.is_none() && sog.is_none() {
            emit.stats.empty += 1;
            return Ok(());
        }
        let time_s = self.time(report, false)?;
        if let Some((lat_deg, lon_deg)) = position {
            let method = match report.status.unwrap_or(1) {
                2 => FixMethod::Dgnss,
                3 => FixMethod::RtkFixed,
                4 => FixMethod::RtkFloat,
                5 | 6 => FixMethod::DeadReckoning,
                8 => FixMethod::Simulated,
                _ => FixMethod::Gnss,
            };
            emit.record(
                time_s,
                source,
                Measurement::Position {
                    lat_deg,
                    lon_deg,
                    hdop: self.hdop.get(usize::from(device)).copied().flatten(),
                    method: Some(method),
                    altitude_m: report.alt_hae.filter(|a| a.is_finite()),
                },
            );
        }
        if cog.is_some() || sog.is_some() {
            emit.record(
                time_s,
                source,
                Measurement::CourseSpeed {
                    cog_rad: cog,
                    sog_mps: sog,
                },
            );
        }
        Ok(())
    }
}

impl LineDecoder for GpsdState {
    fn line(&mut self, line: &[u8], emit: &mut Emit<'_>) -> Result<(), RejectReason> {
        self.report(line, emit)
    }

    fn state_bytes(&self) -> usize {
        self.devices.iter().map(String::capacity).sum::<usize>()
            + self.hdop.capacity() * std::mem::size_of::<Option<f64>>()
    }

    fn set_receive_time(&mut self, time_s: f64) {
        self.receive_time_s = Some(time_s);
    }

    fn receiver_stamped(&self) -> bool {
        self.receiver_stamped
    }

    fn begin_line(&mut self) {
        self.receiver_stamped = false;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::read::{Decoder, Item, ReadStats, RejectKind};

    fn decode(lines: &[&str]) -> (Vec<Item>, ReadStats) {
        let mut d = GpsdDecoder::new(ReadOptions::default());
        let mut out = Vec::new();
        for (i, l) in lines.iter().enumerate() {
            d.decode_line(l.as_bytes(), i as u64 + 1, &mut out);
        }
        (out, d.stats().clone())
    }

    #[test]
    fn tpv_att_and_sky() {
        let (items, stats) = decode(&[
            r#"{"class":"VERSION","release":"3.22","proto_major":3,"proto_minor":14}"#,
            r#"{"class":"SKY","device":"/dev/ttyUSB0","hdop":0.9}"#,
            r#"{"class":"TPV","device":"/dev/ttyUSB0","mode":3,"status":2,"time":"2026-08-03T04:27:20.500Z","lat":34.41,"lon":133.54,"altHAE":40.5,"track":90.0,"magtrack":97.0,"speed":2.5}"#,
            r#"{"class":"ATT","device":"/dev/ttyUSB0","heading":87.5}"#,
            r#"{"class":"TPV","device":"/dev/ttyS1","mode":1,"time":"2026-08-03T04:27:21Z"}"#,
        ]);
        assert_eq!(stats.ignored, 2, "VERSION and SKY");
        assert_eq!(stats.empty, 1, "the no-fix TPV without position");
        assert_eq!(items.len(), 3, "{items:?}");
        let t = parse_rfc3339("2026-08-03T04:27:20.500Z").unwrap();
        let position = items[0].as_ref().unwrap();
        assert_eq!(position.source, Source::Gpsd(0));
        assert_eq!(position.time_s, t);
        assert_eq!(
            position.measurement,
            Measurement::Position {
                lat_deg: 34.41,
                lon_deg: 133.54,
                hdop: Some(0.9),
                method: Some(FixMethod::Dgnss),
                altitude_m: Some(40.5)
            }
        );
        let Measurement::CourseSpeed { cog_rad, sog_mps } = items[1].as_ref().unwrap().measurement
        else {
            panic!()
        };
        assert!((cog_rad.unwrap() - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert_eq!(sog_mps, Some(2.5));
        // The ATT without time takes the latest TPV time.
        let heading = items[2].as_ref().unwrap();
        assert_eq!(heading.time_s, t);
        assert_eq!(
            heading.measurement,
            Measurement::Heading {
                heading_rad: 87.5f64.to_radians()
            }
        );
    }

    #[test]
    fn att_rate_of_turn_is_a_yaw_rate() {
        let (items, stats) = decode(&[
            r#"{"class":"TPV","device":"/dev/ttyUSB0","mode":3,"time":"2026-08-03T04:27:20Z","lat":34.41,"lon":133.54}"#,
            // A satellite compass's heading and rate of turn: 60 deg/min
            // to port is -1 deg/s.
            r#"{"class":"ATT","device":"/dev/ttyUSB1","heading":87.5,"rot":-60.0}"#,
            r#"{"class":"ATT","device":"/dev/ttyUSB1","rot":30.0}"#,
            r#"{"class":"ATT","device":"/dev/ttyUSB1","pitch":1.5,"roll":-2.0}"#,
            r#"{"class":"IMU","device":"/dev/ttyUSB1","rot":30.0}"#,
        ]);
        assert_eq!(stats.empty, 1, "the ATT with neither heading nor rot");
        assert_eq!(stats.ignored, 1, "the IMU report");
        let measurements: Vec<_> = items
            .iter()
            .map(|i| {
                let r = i.as_ref().unwrap();
                (r.source, r.time_s, r.measurement)
            })
            .collect();
        assert_eq!(measurements.len(), 4, "{measurements:?}");
        let t = parse_rfc3339("2026-08-03T04:27:20Z").unwrap();
        assert_eq!(
            &measurements[1..],
            &[
                (
                    Source::Gpsd(1),
                    t,
                    Measurement::Heading {
                        heading_rad: 87.5f64.to_radians()
                    }
                ),
                (
                    Source::Gpsd(1),
                    t,
                    Measurement::RateOfTurn {
                        radps: -(1f64.to_radians())
                    }
                ),
                (
                    Source::Gpsd(1),
                    t,
                    Measurement::RateOfTurn {
                        radps: 0.5f64.to_radians()
                    }
                ),
            ]
        );
    }

    #[test]
    fn bad_reports_are_refused_with_reasons() {
        for (line, kind) in [
            (
                r#"{"class":"TPV","mode":1,"time":"2026-08-03T04:27:21Z","lat":1.0,"lon":2.0}"#,
                RejectKind::NotValid,
            ),
            (
                r#"{"class":"TPV","mode":3,"time":"2026-08-03T04:27:21Z","lat":91.0,"lon":2.0}"#,
                RejectKind::OutOfRange,
            ),
            (
                r#"{"class":"TPV","mode":3,"time":"2026-08-03T04:27:21Z","lat":1.0,"lon":2.0,"speed":-1}"#,
                RejectKind::OutOfRange,
            ),
            (
                r#"{"class":"TPV","mode":3,"lat":1.0,"lon":2.0}"#,
                RejectKind::NoTime,
            ),
            (
                r#"{"class":"TPV","mode":3,"time":"yesterday","lat":1.0,"lon":2.0}"#,
                RejectKind::BadTime,
            ),
            (r#"{"class":"TPV","mode":"3D"}"#, RejectKind::Message),
            // 5 rad/s is about 17,189 deg/min.
            (
                r#"{"class":"ATT","time":"2026-08-03T04:27:21Z","rot":17200.0}"#,
                RejectKind::OutOfRange,
            ),
            (
                r#"{"class":"ATT","time":"2026-08-03T04:27:21Z","heading":87.0,"rot":-17200.0}"#,
                RejectKind::OutOfRange,
            ),
            (r#"{"class":"ATT","rot":"fast"}"#, RejectKind::Message),
            (r#"{"class":"TPV""#, RejectKind::Message),
            ("$GPGGA,1", RejectKind::UnknownFormat),
        ] {
            let (items, stats) = decode(&[line]);
            assert_eq!(items.len(), 1, "{line}");
            assert_eq!(stats.rejected(kind), 1, "{line}: {items:?}");
        }
        assert!(looks_like_gpsd(br#"{"class":"TPV"}"#));
        assert!(!looks_like_gpsd(br#"{"type":"gnss"}"#));
    }

    #[test]
    fn live_reports_without_time_take_the_receive_time() {
        let mut d = GpsdDecoder::new(ReadOptions {
            clock: Clock::Receiver,
            ..ReadOptions::default()
        });
        // The receiving computer's clock is hours after the GNSS time.
        d.set_receive_time(1_785_831_240.0);
        let mut out = Vec::new();
        d.decode_line(br#"{"class":"ATT","heading":10.0}"#, 1, &mut out);
        assert!(out[0].is_err(), "a heading before any time: {out:?}");
        d.decode_line(
            br#"{"class":"TPV","mode":2,"lat":1.0,"lon":2.0}"#,
            2,
            &mut out,
        );
        assert_eq!(out[1].as_ref().unwrap().time_s, 1_785_831_240.0);
        assert!(d.receiver_stamped());
        d.decode_line(
            br#"{"class":"TPV","mode":2,"time":"2026-08-03T04:27:21Z","lat":1.0,"lon":2.0}"#,
            3,
            &mut out,
        );
        assert!(!d.receiver_stamped());
        assert!(out[2].is_ok(), "the GNSS time is a new time line: {out:?}");
        // From then on an ATT without time takes the latest GNSS time.
        d.decode_line(br#"{"class":"ATT","heading":11.0}"#, 4, &mut out);
        assert!(!d.receiver_stamped());
        assert_eq!(
            out[3].as_ref().unwrap().time_s,
            out[2].as_ref().unwrap().time_s
        );
        d.decode_line(
            br#"{"class":"TPV","mode":2,"lat":1.0,"lon":2.0}"#,
            5,
            &mut out,
        );
        assert!(out[4].is_err());
    }
}
