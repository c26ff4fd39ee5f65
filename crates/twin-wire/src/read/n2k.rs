//! canboat NMEA 2000 text (`plain` and `FAST`) to [`Record`](crate::measurement::Record)s.
//!
//! A line is `time,priority,PGN,source,destination,length,b0,b1,...` with
//! the time in ISO 8601 / RFC 3339 and the data bytes in hex. A first line
//! `# format=FAST` says multi-frame (fast-packet) messages are already joined;
//! without it, a fast-packet PGN the reader decodes (129029, 130577, 130842)
//! that arrives as 8-byte frames is reassembled by
//! [`FastPackets`](super::fast_packet::FastPackets), the same assembler the
//! candump and Yacht Devices RAW readers use. A message of more than 8 bytes
//! is always taken as already joined.
//!
//! Fields are little-endian bit fields (layouts in `N2K.md`, facts from the
//! canboat PGN database). For fields of 8 bits or more, an unsigned value with
//! all bits set is "not available" and the two values below it are "out of
//! range" and "reserved": all three read as absent. A signed field's largest
//! positive value is "not available"; the two below it are treated the same
//! way (no field read here has a physical value there). Small lookup fields
//! (2-bit references, the 4-bit fix method) are matched value by value.
//!
//! The record time is the line's timestamp (the time the logger received the
//! message), also for 129029, whose own date and time fields are not used:
//! every record of a log then shares one clock.
//!
//! PGNs read: 127250 heading, 127251 rate of turn, 127257 attitude, 127488
//! engine speed (instance 0 port, 1 starboard), 128259 speed through water,
//! 129025 and 129029 positions, 129026 course and speed, 130577 set and
//! drift (its course, speed, heading and STW repeat the dedicated PGNs of the
//! same instrument and are not emitted), Furuno 130842 gyro rates (only with
//! manufacturer code 1855, industry 4). 128259's ground-referenced speed is
//! not read (it has no course; 129026 gives SOG). Every other PGN, and
//! another maker's 130842, is counted as ignored.

use twin_core::geodesy::wrap_two_pi;
use twin_core::sample::{RADPS_PER_RPM, Side};

use super::fast_packet::{FastFrame, FastPackets, is_fast};
use super::n2k_raw::CanId;
use super::{
    Decoder, Emit, Item, Monotonic, ReadOptions, ReadStats, RejectReason, reject_whole_line,
    trim_line,
};
use crate::measurement::{FixMethod, MAX_SPEED_MPS, Measurement, Source};
use crate::time::parse_rfc3339;

/// The largest data length accepted, bytes (an ISO 11783 transport-protocol
/// message; fast packets are at most 223).
pub const MAX_DATA_BYTES: usize = 1785;

/// Furuno's NMEA 2000 manufacturer code.
pub const FURUNO_MANUFACTURER_CODE: u64 = 1855;

/// The stateful canboat-text decoder (newest time, fast-packet reassembly).
#[derive(Debug, Clone)]
pub struct N2kDecoder {
    options: ReadOptions,
    stats: ReadStats,
    state: State,
}

#[derive(Debug, Clone, Default)]
struct State {
    /// Set by a `# format=FAST` header: every message is already joined.
    joined: bool,
    monotonic: Monotonic,
    /// The data bytes of the current line (reused).
    data: Vec<u8>,
    fast: FastPackets,
}

impl N2kDecoder {
    /// A decoder with `options`.
    pub fn new(options: ReadOptions) -> Self {
        Self {
            options,
            stats: ReadStats::default(),
            state: State::default(),
        }
    }
}

impl Decoder for N2kDecoder {
    fn decode_line(&mut self, line: &[u8], line_no: u64, out: &mut Vec<Item>) {
        self.stats.lines += 1;
        let mut emit = Emit {
            out,
            stats: &mut self.stats,
            line: line_no,
        };
        if let Err(reason) = self.state.line(line, &self.options, &mut emit) {
            emit.reject(reason);
        }
    }

    fn reject_line(&mut self, line_no: u64, reason: RejectReason, out: &mut Vec<Item>) {
        reject_whole_line(&mut self.stats, line_no, reason, out);
    }

    fn stats(&self) -> &ReadStats {
        &self.stats
    }

    fn state_bytes(&self) -> usize {
        self.state.data.capacity() + self.state.fast.state_bytes()
    }
}

/// True when a line has the shape of a canboat message (timestamp and at
/// least six comma-separated numeric fields); used to detect the format.
pub fn looks_like_n2k(line: &[u8]) -> bool {
    let Ok(text) = std::str::from_utf8(trim_line(line)) else {
        return false;
    };
    let mut parts = text.split(',');
    let time_ok = parts.next().is_some_and(|t| parse_rfc3339(t).is_ok());
    time_ok
        && parts
            .by_ref()
            .take(5)
            .filter(|p| !p.is_empty() && p.bytes().all(|b| b.is_ascii_digit()))
            .count()
            == 5
}

/// `len` bits at bit `offset` of `data`, little-endian; `None` past the end.
pub fn bits(data: &[u8], offset: usize, len: usize) -> Option<u64> {
    if len == 0 || len > 64 {
        return None;
    }
    let end = offset.checked_add(len)?;
    if end > data.len().checked_mul(8)? {
        return None;
    }
    let first = offset / 8;
    let last = (end - 1) / 8;
    let mut wide: u128 = 0;
    for (i, b) in data[first..=last].iter().enumerate() {
        wide |= u128::from(*b) << (8 * i);
    }
    let mask = if len == 64 {
        u128::from(u64::MAX)
    } else {
        (1u128 << len) - 1
    };
    Some(((wide >> (offset % 8)) & mask) as u64)
}

/// An unsigned field of 8 bits or more, scaled; the top three raw values
/// (not available, out of range, reserved) read as `None`.
pub fn unsigned(data: &[u8], offset: usize, len: usize, resolution: f64) -> Option<f64> {
    let raw = bits(data, offset, len)?;
    let max = if len == 64 {
        u64::MAX
    } else {
        (1u64 << len) - 1
    };
    (raw < max - 2).then_some(raw as f64 * resolution)
}

/// A signed (two's complement) field, scaled; the largest positive value
/// (not available) and the two below it read as `None`.
pub fn signed(data: &[u8], offset: usize, len: usize, resolution: f64) -> Option<f64> {
    let raw = bits(data, offset, len)?;
    let shift = 64 - len as u32;
    // Sign-extend by moving the field's top bit to bit 63 and back.
    let value = ((raw << shift) as i64) >> shift;
    let max_positive = if len == 64 {
        i64::MAX
    } else {
        (1i64 << (len - 1)) - 1
    };
    (value < max_positive - 2).then_some(value as f64 * resolution)
}

/// The fields of PGN 130577 "Direction Data" (all of them, for tests and
/// callers that want more than the set and drift the reader emits).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DirectionData {
    /// Data mode (0 autonomous, 1 differential, 2 estimated, 3 simulator,
    /// 4 manual); 15 when not available.
    pub data_mode: u8,
    /// COG reference (0 true, 1 magnetic, 2 error, 3 not available).
    pub cog_reference: u8,
    /// Course over ground, rad.
    pub cog_rad: Option<f64>,
    /// Speed over ground, m/s.
    pub sog_mps: Option<f64>,
    /// Heading, rad.
    pub heading_rad: Option<f64>,
    /// Speed through water, m/s.
    pub stw_mps: Option<f64>,
    /// Set (direction the current flows toward), rad.
    pub set_rad: Option<f64>,
    /// Drift (current speed), m/s.
    pub drift_mps: Option<f64>,
}

/// Decodes PGN 130577; `None` when shorter than its 14 bytes.
pub fn direction_data(data: &[u8]) -> Option<DirectionData> {
    if data.len() < 14 {
        return None;
    }
    Some(DirectionData {
        data_mode: bits(data, 0, 4)? as u8,
        cog_reference: bits(data, 4, 2)? as u8,
        cog_rad: unsigned(data, 16, 16, 1e-4),
        sog_mps: unsigned(data, 32, 16, 0.01),
        heading_rad: unsigned(data, 48, 16, 1e-4),
        stw_mps: unsigned(data, 64, 16, 0.01),
        set_rad: unsigned(data, 80, 16, 1e-4),
        drift_mps: unsigned(data, 96, 16, 0.01),
    })
}

fn need(pgn: u32, data: &[u8], bytes: usize) -> Result<(), RejectReason> {
    if data.len() < bytes {
        Err(RejectReason::TooShort {
            pgn,
            len: data.len(),
            needed: bytes,
        })
    } else {
        Ok(())
    }
}

/// A direction read as unsigned 1e-4 rad must be below 2 pi (plus rounding).
fn compass(value: Option<f64>, field: &'static str) -> Result<Option<f64>, RejectReason> {
    match value {
        Some(v) if v > std::f64::consts::TAU + 1e-3 => Err(RejectReason::OutOfRange { field }),
        Some(v) => Ok(Some(wrap_two_pi(v))),
        None => Ok(None),
    }
}

fn speed(value: Option<f64>, field: &'static str) -> Result<Option<f64>, RejectReason> {
    match value {
        Some(v) if v > MAX_SPEED_MPS => Err(RejectReason::OutOfRange { field }),
        other => Ok(other),
    }
}

fn lat_lon(lat: Option<f64>, lon: Option<f64>) -> Result<Option<(f64, f64)>, RejectReason> {
    let (Some(lat), Some(lon)) = (lat, lon) else {
        return Ok(None);
    };
    if lat.abs() > 90.0 {
        return Err(RejectReason::OutOfRange { field: "latitude" });
    }
    if lon.abs() > 180.0 {
        return Err(RejectReason::OutOfRange { field: "longitude" });
    }
    Ok(Some((lat, lon)))
}

/// The header of a canboat text line: its time and the message's id.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MessageHeader {
    /// The line's time, seconds since the epoch.
    pub time_s: f64,
    /// Priority, PGN, source and destination.
    pub id: CanId,
}

/// Parses one canboat text line (not a comment) into its header, putting
/// its data bytes in `data`: shared by the decoder and by whatever carries
/// the text into another layout.
pub fn parse_message(line: &[u8], data: &mut Vec<u8>) -> Result<MessageHeader, RejectReason> {
    let text = std::str::from_utf8(trim_line(line)).map_err(|_| RejectReason::NotText)?;
    let mut parts = text.split(',');
    let time = parts.next().unwrap_or("");
    if !time.as_bytes().first().is_some_and(u8::is_ascii_digit) {
        return Err(RejectReason::UnknownFormat);
    }
    let time_s = parse_rfc3339(time).map_err(RejectReason::BadTime)?;
    let mut header = [0u32; 5];
    const NAMES: [&str; 5] = ["priority", "PGN", "source", "destination", "length"];
    for (value, what) in header.iter_mut().zip(NAMES) {
        let field = parts.next().ok_or(RejectReason::Malformed { what })?;
        if field.is_empty() || field.len() > 7 || !field.bytes().all(|b| b.is_ascii_digit()) {
            return Err(RejectReason::Malformed { what });
        }
        *value = field
            .parse()
            .map_err(|_| RejectReason::Malformed { what })?;
    }
    let [priority, pgn, source, destination, length] = header;
    if priority > 7 {
        return Err(RejectReason::Malformed { what: "priority" });
    }
    let source = u8::try_from(source).map_err(|_| RejectReason::Malformed { what: "source" })?;
    let destination = u8::try_from(destination).map_err(|_| RejectReason::Malformed {
        what: "destination",
    })?;
    let length = length as usize;
    if length > MAX_DATA_BYTES {
        return Err(RejectReason::Malformed { what: "length" });
    }
    data.clear();
    for byte in parts {
        if byte.len() != 2 || data.len() == length {
            return Err(RejectReason::Malformed { what: "data bytes" });
        }
        let b = u8::from_str_radix(byte, 16)
            .map_err(|_| RejectReason::Malformed { what: "data bytes" })?;
        if !byte.bytes().all(|c| c.is_ascii_hexdigit()) {
            return Err(RejectReason::Malformed { what: "data bytes" });
        }
        data.push(b);
    }
    if data.len() != length {
        return Err(RejectReason::Malformed {
            what: "data length",
        });
    }
    Ok(MessageHeader {
        time_s,
        id: CanId {
            priority: priority as u8,
            pgn,
            source,
            destination,
        },
    })
}

impl State {
    fn line(
        &mut self,
        line: &[u8],
        options: &ReadOptions,
        emit: &mut Emit<'_>,
    ) -> Result<(), RejectReason> {
        let line = trim_line(line);
        if line.is_empty() {
            emit.stats.blank += 1;
            return Ok(());
        }
        if line.first() == Some(&b'#') {
            if let Some(format) = line.strip_prefix(b"# format=") {
                self.joined = format.eq_ignore_ascii_case(b"FAST");
            }
            emit.stats.blank += 1;
            return Ok(());
        }
        let header = parse_message(line, &mut self.data)?;
        let time_s = header.time_s;
        let (pgn, source) = (header.id.pgn, header.id.source);
        self.monotonic
            .check(time_s, options.backwards_tolerance_s)?;
        let data = std::mem::take(&mut self.data);
        let result = decode_message_or_frame(
            &mut self.fast,
            !self.joined,
            pgn,
            source,
            &data,
            time_s,
            emit,
        );
        self.data = data;
        result
    }
}

/// Decodes what one line carries: a whole message, or, when the log is
/// frame by frame (`frames`), an 8-byte frame of a fast-packet PGN the
/// readers decode, joined with [`FastPackets`] and decoded once complete.
/// Shared by every NMEA 2000 reader.
pub(crate) fn decode_message_or_frame(
    fast: &mut FastPackets,
    frames: bool,
    pgn: u32,
    address: u8,
    data: &[u8],
    time_s: f64,
    emit: &mut Emit<'_>,
) -> Result<(), RejectReason> {
    let source = Source::N2k(address);
    if frames && is_fast(pgn) && data.len() <= 8 {
        return match fast.push(address, pgn, data) {
            FastFrame::Complete(message) => decode_pgn(pgn, &message, time_s, source, emit),
            // A frame of a message still being joined: nothing yet.
            FastFrame::Pending => Ok(()),
            FastFrame::Lost(reason) => Err(reason),
        };
    }
    decode_pgn(pgn, data, time_s, source, emit)
}

/// PGN 127250, vessel heading: true, or magnetic corrected by deviation and
/// variation.
fn vessel_heading(data: &[u8]) -> Result<Option<Measurement>, RejectReason> {
    let heading = compass(unsigned(data, 8, 16, 1e-4), "heading")?;
    let deviation = signed(data, 24, 16, 1e-4);
    let variation = signed(data, 40, 16, 1e-4);
    let Some(h) = heading else {
        return Ok(None);
    };
    let true_heading = match bits(data, 56, 2) {
        Some(0) => h,
        Some(1) => {
            let v = variation.ok_or(RejectReason::MagneticWithoutVariation)?;
            h + deviation.unwrap_or(0.0) + v
        }
        _ => return Err(RejectReason::UnknownReference { field: "heading" }),
    };
    Ok(Some(Measurement::Heading {
        heading_rad: wrap_two_pi(true_heading),
    }))
}

/// PGN 127488, engine parameters (rapid): one shaft's speed.
fn engine_speed(data: &[u8]) -> Result<Option<Measurement>, RejectReason> {
    let Some(rpm) = unsigned(data, 8, 16, 0.25) else {
        return Ok(None);
    };
    let side = match bits(data, 0, 8) {
        Some(0) => Side::Port,
        Some(1) => Side::Starboard,
        other => {
            return Err(RejectReason::UnknownPropeller {
                number: other.unwrap_or(255) as u32,
            });
        }
    };
    Ok(Some(Measurement::PropellerSpeed {
        side,
        radps: rpm * RADPS_PER_RPM,
    }))
}

/// PGN 129026, COG and SOG (rapid): a magnetic or unknown course is dropped
/// and rejected after the speed is kept.
fn course_speed(data: &[u8]) -> Result<(Option<Measurement>, Option<RejectReason>), RejectReason> {
    let sog = speed(unsigned(data, 32, 16, 0.01), "sog")?;
    let mut cog = compass(unsigned(data, 16, 16, 1e-4), "cog")?;
    let mut late_rejection = None;
    if cog.is_some() {
        match bits(data, 8, 2) {
            Some(0) => {}
            Some(1) => {
                cog = None;
                late_rejection = Some(RejectReason::MagneticCourse);
            }
            _ => {
                cog = None;
                late_rejection = Some(RejectReason::UnknownReference { field: "cog" });
            }
        }
    }
    let measurement = (cog.is_some() || sog.is_some()).then_some(Measurement::CourseSpeed {
        cog_rad: cog,
        sog_mps: sog,
    });
    Ok((measurement, late_rejection))
}

/// PGN 129029, GNSS position data: position, altitude, method and HDOP.
fn gnss_position(data: &[u8]) -> Result<Option<Measurement>, RejectReason> {
    let method = match bits(data, 252, 4) {
        Some(0) => {
            return Err(RejectReason::NotValid {
                what: "129029 method",
            });
        }
        Some(code) => FixMethod::from_code(code),
        None => None,
    };
    let position = lat_lon(signed(data, 56, 64, 1e-16), signed(data, 120, 64, 1e-16))?;
    let altitude_m = signed(data, 184, 64, 1e-6);
    let hdop = signed(data, 272, 16, 0.01).filter(|h| *h > 0.0);
    Ok(position.map(|(lat_deg, lon_deg)| Measurement::Position {
        lat_deg,
        lon_deg,
        hdop,
        method,
        altitude_m,
    }))
}

/// Furuno's PGN 130842 gyro rates (roll, pitch, yaw).
fn furuno_gyro_rates(data: &[u8]) -> Option<Measurement> {
    let rate = |offset| signed(data, offset, 32, 1e-3).map(f64::to_radians);
    let (roll, pitch, yaw) = (rate(120), rate(152), rate(184));
    (roll.is_some() || pitch.is_some() || yaw.is_some()).then_some(Measurement::GyroRates {
        roll_radps: roll,
        pitch_radps: pitch,
        yaw_radps: yaw,
    })
}

/// Decodes one message of a PGN the reader reads, or counts it as ignored.
fn decode_pgn(
    pgn: u32,
    data: &[u8],
    time_s: f64,
    source: Source,
    emit: &mut Emit<'_>,
) -> Result<(), RejectReason> {
    let mut measurement: Option<Measurement> = None;
    let mut late_rejection = None;
    match pgn {
        127_250 => {
            need(pgn, data, 8)?;
            measurement = vessel_heading(data)?;
        }
        127_251 => {
            need(pgn, data, 5)?;
            measurement =
                signed(data, 8, 32, 3.125e-8).map(|radps| Measurement::RateOfTurn { radps });
        }
        127_257 => {
            need(pgn, data, 7)?;
            let yaw = signed(data, 8, 16, 1e-4);
            let pitch = signed(data, 24, 16, 1e-4);
            let roll = signed(data, 40, 16, 1e-4);
            if yaw.is_some() || pitch.is_some() || roll.is_some() {
                measurement = Some(Measurement::Attitude {
                    yaw_rad: yaw,
                    pitch_rad: pitch,
                    roll_rad: roll,
                });
            }
        }
        127_488 => {
            need(pgn, data, 3)?;
            measurement = engine_speed(data)?;
        }
        128_259 => {
            need(pgn, data, 3)?;
            measurement = speed(unsigned(data, 8, 16, 0.01), "stw")?
                .map(|mps| Measurement::SpeedThroughWater { mps });
        }
        129_025 => {
            need(pgn, data, 8)?;
            let position = lat_lon(signed(data, 0, 32, 1e-7), signed(data, 32, 32, 1e-7))?;
            measurement = position.map(|(lat_deg, lon_deg)| Measurement::Position {
                lat_deg,
                lon_deg,
                hdop: None,
                method: None,
                altitude_m: None,
            });
        }
        129_026 => {
            need(pgn, data, 6)?;
            (measurement, late_rejection) = course_speed(data)?;
        }
        129_029 => {
            need(pgn, data, 36)?;
            measurement = gnss_position(data)?;
        }
        130_577 => {
            need(pgn, data, 14)?;
            if let Some(d) = direction_data(data)
                && let (Some(set), Some(drift)) = (compass(d.set_rad, "set")?, d.drift_mps)
            {
                measurement = Some(Measurement::SetDrift {
                    set_rad: set,
                    drift_mps: drift,
                });
            }
        }
        130_842 => {
            let maker = bits(data, 0, 11);
            let industry = bits(data, 13, 3);
            if maker != Some(FURUNO_MANUFACTURER_CODE) || industry != Some(4) {
                emit.stats.ignored += 1;
                return Ok(());
            }
            need(pgn, data, 27)?;
            measurement = furuno_gyro_rates(data);
        }
        _ => {
            emit.stats.ignored += 1;
            return Ok(());
        }
    }
    let any = measurement.is_some();
    if let Some(m) = measurement {
        emit.record(time_s, source, m);
    }
    match late_rejection {
        Some(reason) => emit.reject(reason),
        None if !any => emit.stats.empty += 1,
        None => {}
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measurement::Record;
    use crate::read::{RejectKind, Rejection};

    fn decode(lines: &[&str]) -> (Vec<Item>, ReadStats) {
        let mut d = N2kDecoder::new(ReadOptions::default());
        let mut out = Vec::new();
        for (i, l) in lines.iter().enumerate() {
            d.decode_line(l.as_bytes(), i as u64 + 1, &mut out);
        }
        (out, d.stats().clone())
    }

    fn one(line: &str) -> Record {
        let (items, _) = decode(&[line]);
        assert_eq!(items.len(), 1, "{items:?}");
        items[0].clone().expect("record")
    }

    fn hex(text: &str) -> Vec<u8> {
        text.split(',')
            .map(|b| u8::from_str_radix(b, 16).unwrap())
            .collect()
    }

    #[test]
    fn bit_fields() {
        let d = [0x3f, 0x9f, 0xff];
        // 0x9f3f & 0x7ff = 0x73f = 1855 (Furuno); 0x9f3f >> 13 = 4 (marine).
        assert_eq!(bits(&d, 0, 11), Some(1855));
        assert_eq!(bits(&d, 13, 3), Some(4));
        assert_eq!(bits(&d, 16, 8), Some(0xff));
        assert_eq!(bits(&d, 17, 8), None);
        assert_eq!(bits(&d, 0, 0), None);
        assert_eq!(bits(&d, usize::MAX, 8), None);
        let all = [0xffu8; 8];
        assert_eq!(bits(&all, 0, 64), Some(u64::MAX));
        assert_eq!(unsigned(&all, 0, 16, 1.0), None);
        assert_eq!(unsigned(&[0xfd, 0xff], 0, 16, 1.0), None); // reserved
        assert_eq!(unsigned(&[0xfc, 0xff], 0, 16, 1.0), Some(65_532.0));
        assert_eq!(signed(&[0xff, 0x7f], 0, 16, 1.0), None);
        assert_eq!(signed(&[0xfc, 0x7f], 0, 16, 1.0), Some(32_764.0));
        assert_eq!(signed(&[0x00, 0x80], 0, 16, 1.0), Some(-32_768.0));
        assert_eq!(signed(&[0xff, 0xff], 0, 16, 1.0), Some(-1.0));
        assert_eq!(signed(&all, 0, 64, 1.0), Some(-1.0));
    }

    #[test]
    fn golden_127251_rate_of_turn_negative() {
        // Bytes 1-4: f2 74 fa ff -> 0xfffa74f2 = -363 278 x 3.125e-8 = -0.011 352 4 rad/s.
        let r = one("2026-08-03T04:27:20.588Z,3,127251,27,255,8,00,f2,74,fa,ff,27,02,ff");
        assert_eq!(r.source, Source::N2k(27));
        let Measurement::RateOfTurn { radps } = r.measurement else {
            panic!()
        };
        assert!((radps + 0.011_352_437_5).abs() < 1e-12, "{radps}");
        assert_eq!(r.time_s, parse_rfc3339("2026-08-03T04:27:20.588Z").unwrap());
    }

    #[test]
    fn golden_129026_cog_sog() {
        // Byte 1 0xfc: reference bits 0 = true. COG 0xc459 = 50 265 -> 5.0265 rad;
        // SOG 0x0115 = 277 -> 2.77 m/s.
        let r = one("2026-08-03T04:27:21.000Z,2,129026,25,255,8,e9,fc,59,c4,15,01,ff,ff");
        let Measurement::CourseSpeed { cog_rad, sog_mps } = r.measurement else {
            panic!()
        };
        assert!((cog_rad.unwrap() - 5.0265).abs() < 1e-12);
        assert!((sog_mps.unwrap() - 2.77).abs() < 1e-12);
        // Same with reference 1 (magnetic, byte 1 = 0xfd): speed kept, course rejected.
        let (items, stats) =
            decode(&["2026-08-03T04:27:21.000Z,2,129026,25,255,8,e9,fd,59,c4,15,01,ff,ff"]);
        assert_eq!(
            items[0].as_ref().unwrap().measurement,
            Measurement::CourseSpeed {
                cog_rad: None,
                sog_mps: Some(2.77)
            }
        );
        assert_eq!(
            items[1].as_ref().unwrap_err().reason,
            RejectReason::MagneticCourse
        );
        assert_eq!(stats.rejected(RejectKind::MagneticCourse), 1);
        // COG and SOG both "not available" (ff ff): an empty message.
        let (items, stats) =
            decode(&["2026-08-03T04:27:21.000Z,2,129026,25,255,8,e9,fc,ff,ff,ff,ff,ff,ff"]);
        assert!(items.is_empty());
        assert_eq!(stats.empty, 1);
    }

    #[test]
    fn golden_130577_direction_data() {
        // c0: mode 0, reference 0. COG 0x85f8 = 34 296 -> 3.4296 rad; SOG 0x015b = 347
        // -> 3.47 m/s; heading ffff, STW ffff n/a; set 0x5570 = 21 872 -> 2.1872 rad;
        // drift 0x0027 = 39 -> 0.39 m/s.
        let bytes = hex("c0,87,f8,85,5b,01,ff,ff,ff,ff,70,55,27,00");
        let d = direction_data(&bytes).unwrap();
        assert_eq!((d.data_mode, d.cog_reference), (0, 0));
        assert!((d.cog_rad.unwrap() - 3.4296).abs() < 1e-12);
        assert!((d.sog_mps.unwrap() - 3.47).abs() < 1e-12);
        assert_eq!((d.heading_rad, d.stw_mps), (None, None));
        let r = one(
            "2014-08-15T19:00:00.537Z,3,130577,160,255,14,c0,87,f8,85,5b,01,ff,ff,ff,ff,70,55,27,00",
        );
        let Measurement::SetDrift { set_rad, drift_mps } = r.measurement else {
            panic!()
        };
        assert!((set_rad - 2.1872).abs() < 1e-12 && (drift_mps - 0.39).abs() < 1e-12);
    }

    #[test]
    fn golden_129029_gnss_position_data() {
        // aava-n2k.data line 1. lat bytes 7..15 = 00 58 67 11 cf db 49 08
        // = 0x0849dbcf11675800 = 597 250 108 000 000 000 x 1e-16 = 59.725 010 8 deg;
        // lon bytes 15..23 = 00 f4 15 47 c4 d2 6e 03 = 0x036ed2c44715f400
        // = 247 366 770 000 000 000 x 1e-16 = 24.736 677 deg;
        // altitude bytes 23..31 = 80 66 23 00 00 00 00 00 = 2 320 000 x 1e-6 = 2.32 m;
        // byte 31 = 0x10: type 0 (GPS), method 1 (GNSS fix);
        // HDOP bytes 34..36 = 0x0050 = 80 x 0.01 = 0.8.
        let r = one(
            "2014-08-15T19:00:00.042Z,3,129029,160,255,43,87,a9,3f,fc,ed,c4,28,00,58,67,11,cf,db,49,08,00,f4,15,47,c4,d2,6e,03,80,66,23,00,00,00,00,00,10,fc,0a,50,00,ff,7f,ff,ff,ff,7f,00",
        );
        let Measurement::Position {
            lat_deg,
            lon_deg,
            hdop,
            method,
            altitude_m,
        } = r.measurement
        else {
            panic!()
        };
        assert!((lat_deg - 59.725_010_8).abs() < 1e-12, "{lat_deg}");
        assert!((lon_deg - 24.736_677).abs() < 1e-12, "{lon_deg}");
        assert!((altitude_m.unwrap() - 2.32).abs() < 1e-9);
        assert_eq!(method, Some(FixMethod::Gnss));
        assert!((hdop.unwrap() - 0.8).abs() < 1e-12);
    }

    #[test]
    fn golden_129025_127257_128259_130842() {
        // 129025: lat 0x14813336 = 344 011 574 -> 34.401 157 4; lon 0x4f9b8288
        // = 1 335 591 560 -> 133.559 156 deg.
        let r = one("2026-08-03T04:47:01.360Z,2,129025,25,255,8,36,33,81,14,88,82,9b,4f");
        assert_eq!(
            r.measurement,
            Measurement::Position {
                lat_deg: 344_011_574.0 * 1e-7,
                lon_deg: 1_335_591_560.0 * 1e-7,
                hdop: None,
                method: None,
                altitude_m: None
            }
        );
        // 127257: yaw 0xd0bd = -12 099 -> -1.2099 rad; pitch 0xfedd = -291 -> -0.0291;
        // roll 0x029a = 666 -> 0.0666 rad.
        let r = one("2026-08-03T03:19:45.829Z,3,127257,52,255,8,ff,bd,d0,dd,fe,9a,02,ff");
        let Measurement::Attitude {
            yaw_rad,
            pitch_rad,
            roll_rad,
        } = r.measurement
        else {
            panic!()
        };
        assert!((yaw_rad.unwrap() + 1.2099).abs() < 1e-12);
        assert!((pitch_rad.unwrap() + 0.0291).abs() < 1e-12);
        assert!((roll_rad.unwrap() - 0.0666).abs() < 1e-12);
        // 127257 of the Precision-9: yaw 0x7fff not available, pitch 0x0091 = 145,
        // roll 0xfd91 = -623.
        let r = one("2026-08-03T03:19:45.803Z,3,127257,27,255,8,00,ff,7f,91,00,91,fd,ff");
        assert_eq!(
            r.measurement,
            Measurement::Attitude {
                yaw_rad: None,
                pitch_rad: Some(145.0 * 1e-4),
                roll_rad: Some(-623.0 * 1e-4)
            }
        );
        // 128259: STW 0x00e7 = 231 -> 2.31 m/s.
        let r = one("2026-08-03T04:55:51.525Z,2,128259,35,255,8,ff,e7,00,ff,ff,00,ff,ff");
        assert_eq!(r.measurement, Measurement::SpeedThroughWater { mps: 2.31 });
        // 130842 Furuno: roll rate bytes 15..19 = 6d 01 00 00 = 365 -> 0.365 deg/s;
        // pitch 51 ff ff ff = -175 -> -0.175 deg/s; yaw fd ff ff ff = -3 -> -0.003 deg/s.
        let r = one(
            "2026-08-03T03:19:45.843Z,7,130842,52,255,29,3f,9f,b9,ff,ff,ff,f0,ff,ff,ff,aa,00,00,00,00,6d,01,00,00,51,ff,ff,ff,fd,ff,ff,ff,00,00",
        );
        let Measurement::GyroRates {
            roll_radps,
            pitch_radps,
            yaw_radps,
        } = r.measurement
        else {
            panic!()
        };
        assert!((roll_radps.unwrap() - 0.365f64.to_radians()).abs() < 1e-12);
        assert!((pitch_radps.unwrap() + 0.175f64.to_radians()).abs() < 1e-12);
        assert!((yaw_radps.unwrap() + 0.003f64.to_radians()).abs() < 1e-12);
    }

    #[test]
    fn golden_127250_true_and_magnetic() {
        // aava: heading 0x87be = 34 750 -> 3.475 rad; deviation 7fff n/a;
        // variation 0x0586 = 1414 -> 0.1414 rad; byte 7 0xfc: reference 0 (true).
        let r = one("2014-08-15T19:00:00.892Z,2,127250,160,255,8,ff,be,87,ff,7f,86,05,fc");
        assert_eq!(r.measurement, Measurement::Heading { heading_rad: 3.475 });
        // Reference 1 (magnetic, 0xfd): 3.475 + 0.1414 = 3.6164 rad true.
        let r = one("2014-08-15T19:00:00.892Z,2,127250,160,255,8,ff,be,87,ff,7f,86,05,fd");
        let Measurement::Heading { heading_rad } = r.measurement else {
            panic!()
        };
        assert!((heading_rad - 3.6164).abs() < 1e-12);
        // Magnetic with variation not available.
        let (items, _) =
            decode(&["2014-08-15T19:00:00.892Z,2,127250,160,255,8,ff,be,87,ff,7f,ff,7f,fd"]);
        assert_eq!(
            items[0].as_ref().unwrap_err().reason,
            RejectReason::MagneticWithoutVariation
        );
    }

    #[test]
    fn golden_127488_engine_instances() {
        // Instance 1 (starboard), speed 0x1770 = 6000 x 0.25 = 1500 rpm.
        let r = one("2026-08-03T04:00:00.000Z,2,127488,0,255,8,01,70,17,ff,ff,7f,ff,ff");
        assert_eq!(
            r.measurement,
            Measurement::PropellerSpeed {
                side: Side::Starboard,
                radps: 1500.0 * RADPS_PER_RPM
            }
        );
        let r = one("2026-08-03T04:00:00.000Z,2,127488,0,255,8,00,00,00,ff,ff,7f,ff,ff");
        assert_eq!(
            r.measurement,
            Measurement::PropellerSpeed {
                side: Side::Port,
                radps: 0.0
            }
        );
        let (items, _) =
            decode(&["2026-08-03T04:00:00.000Z,2,127488,0,255,8,02,70,17,ff,ff,7f,ff,ff"]);
        assert_eq!(
            items[0].as_ref().unwrap_err().reason,
            RejectReason::UnknownPropeller { number: 2 }
        );
    }

    #[test]
    fn other_makers_130842_and_unknown_pgns_are_ignored() {
        // Simrad (1857 = 0x741): 0x741 | 4 << 13 = 0x8741.
        let (items, stats) = decode(&[
            "2026-08-03T03:19:45.843Z,7,130842,52,255,29,41,87,b9,ff,ff,ff,f0,ff,ff,ff,aa,00,00,00,00,6d,01,00,00,51,ff,ff,ff,fd,ff,ff,ff,00,00",
            "2026-08-03T03:19:45.900Z,7,65306,115,255,8,3b,9f,e7,00,ff,ff,ff,ff",
        ]);
        assert!(items.is_empty());
        assert_eq!(stats.ignored, 2);
    }

    #[test]
    fn structural_rejections() {
        let cases = [
            (
                "2026-08-03T04:27:20.588Z,3,127251,27,255,8,00,f2,74,fa,ff,27,02",
                RejectReason::Malformed {
                    what: "data length",
                },
            ),
            (
                "2026-08-03T04:27:20.588Z,3,127251,27,255,7,00,f2,74,fa,ff,27,02,ff",
                RejectReason::Malformed { what: "data bytes" },
            ),
            (
                "2026-08-03T04:27:20.588Z,3,127251,27,255,8,00,f2,74,fa,ff,27,02,fg",
                RejectReason::Malformed { what: "data bytes" },
            ),
            (
                "2026-08-03T04:27:20.588Z,3,127251,27,255,8,00,f2,74,fa,ff,27,02,+f",
                RejectReason::Malformed { what: "data bytes" },
            ),
            (
                "2026-08-03T04:27:20.588Z,9,127251,27,255,8,00,f2,74,fa,ff,27,02,ff",
                RejectReason::Malformed { what: "priority" },
            ),
            (
                "2026-08-03T04:27:20.588Z,3,127251,256,255,8,00,f2,74,fa,ff,27,02,ff",
                RejectReason::Malformed { what: "source" },
            ),
            (
                "2026-08-03T04:27:20.588Z,3,127251",
                RejectReason::Malformed { what: "source" },
            ),
            (
                "2026-08-03T04:27:20.588Z,3,127251,27,255,2,00,f2",
                RejectReason::TooShort {
                    pgn: 127_251,
                    len: 2,
                    needed: 5,
                },
            ),
            (
                "2026-08-33T04:27:20.588Z,3,127251,27,255,8,00,f2,74,fa,ff,27,02,ff",
                RejectReason::BadTime(crate::time::TimeError::OutOfRange { field: "day" }),
            ),
            ("hello", RejectReason::UnknownFormat),
            (
                "2026-08-03T04:27:20.588Z,3,129025,25,255,8,00,00,00,80,00,00,00,00",
                RejectReason::OutOfRange { field: "latitude" },
            ),
        ];
        for (line, reason) in cases {
            let (items, _) = decode(&[line]);
            assert_eq!(items.len(), 1, "{line}");
            assert_eq!(items[0].as_ref().unwrap_err().reason, reason, "{line}");
        }
    }

    #[test]
    fn plain_frames_of_fast_packets_are_joined() {
        // 129029 of aava split into canboat plain frames: frame 0 carries the
        // length (43) and 6 bytes, then 7 bytes a frame; sequence 3 (0x60).
        let joined = "87,a9,3f,fc,ed,c4,28,00,58,67,11,cf,db,49,08,00,f4,15,47,c4,d2,6e,03,80,66,23,00,00,00,00,00,10,fc,0a,50,00,ff,7f,ff,ff,ff,7f,00";
        let bytes = hex(joined);
        let mut lines = Vec::new();
        let mut frame = vec![0x60u8, 43];
        frame.extend_from_slice(&bytes[..6]);
        lines.push(frame);
        for (i, chunk) in bytes[6..].chunks(7).enumerate() {
            let mut frame = vec![0x60 | (i as u8 + 1)];
            frame.extend_from_slice(chunk);
            frame.resize(8, 0xff);
            lines.push(frame);
        }
        let text: Vec<String> = lines
            .iter()
            .map(|f| {
                let hex: Vec<String> = f.iter().map(|b| format!("{b:02x}")).collect();
                format!(
                    "2014-08-15T19:00:00.042Z,3,129029,160,255,8,{}",
                    hex.join(",")
                )
            })
            .collect();
        let refs: Vec<&str> = text.iter().map(String::as_str).collect();
        let (items, stats) = decode(&refs);
        let whole = one(&format!(
            "2014-08-15T19:00:00.042Z,3,129029,160,255,43,{joined}"
        ));
        assert_eq!(items, vec![Ok(whole)]);
        assert_eq!(stats.total_rejected(), 0);
        // Missing frame 2: the partial message is lost, nothing decoded, and
        // every frame that could not be used says why (frame 3 out of order,
        // 4 to 6 without their first frame).
        let mut gap = refs.clone();
        gap.remove(2);
        let (items, stats) = decode(&gap);
        assert_eq!(items.len(), 4, "{items:?}");
        assert!(items.iter().all(|i| matches!(
            i,
            Err(Rejection { reason: RejectReason::Malformed { what }, .. }) if what.starts_with("fast packet")
        )));
        assert_eq!(stats.rejected(RejectKind::Malformed), 4);
        // With the FAST header, an 8-byte 129029 is simply too short.
        let (items, _) = decode(&["# format=FAST", refs[0]]);
        assert_eq!(
            items[0].as_ref().unwrap_err().reason,
            RejectReason::TooShort {
                pgn: 129_029,
                len: 8,
                needed: 36
            }
        );
    }
}
