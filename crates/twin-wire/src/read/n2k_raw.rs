//! NMEA 2000 as the gateways and SocketCAN capture it, frame by frame or
//! message by message, to [`Record`](crate::measurement::Record)s through
//! the same PGN decoder as the canboat text reader ([`super::n2k`]).
//!
//! # Formats
//! - **candump** (Linux can-utils), three layouts: the log file of
//!   `candump -l`/`-L`, `(1436509052.249713) can0 09F8027F#00FCFFFF0000FFFF`;
//!   the default screen output `can0  09F8027F   [8]  00 FC FF FF 00 00 FF FF`
//!   (no time); and the same with a time in front, `candump -ta`:
//!   `(1436509052.249713)  can0  09F8027F   [8]  00 FC ...`. One CAN frame a
//!   line.
//! - **Yacht Devices RAW** (YDWG-02, YDNU-02, YDEN-02):
//!   `17:33:21.107 R 19F51323 01 2F 30 70 00 2F 30 70`, a time of day, `R`
//!   (received from the bus) or `T` (sent by the gateway), the 29-bit CAN id
//!   and up to 8 data bytes. One CAN frame a line.
//! - **Actisense N2K ASCII** (W2K-1):
//!   `A173321.107 23FF7 1F513 012F3070002F30709F`, a time of day, source,
//!   destination and priority in hex (`SSDDP`), the PGN in hex, and the whole
//!   message's data (fast packets already joined). One message a line.
//!
//! The 29-bit CAN id gives priority, PGN, source and destination by the ISO
//! 11783 rule ([`CanId`]). Frames of the fast-packet PGNs the readers decode
//! are joined by [`FastPackets`](super::fast_packet::FastPackets), the
//! assembler the canboat plain reader uses, so the same frames make the same
//! records in every format. Standard (11-bit) frames, remote frames and CAN
//! FD frames are not NMEA 2000: counted as ignored.
//!
//! # Time
//! In a log (`Clock::Log`), a record takes its line's time stamp: candump's
//! seconds since the epoch; the time of day of Yacht Devices and Actisense
//! lines on the current date (`ReadOptions::assumed_date` until a receive
//! time gives one; midnight advances the date, as for NMEA 0183 time-of-day
//! sentences, [`super::clock`]). A line without a time (candump's screen
//! output) is refused as `NoTime`. Live (`Clock::Receiver`), every record
//! takes the time the line was received ([`Decoder::set_receive_time`]):
//! NMEA 2000 frames carry no time of their own, and a gateway's stamp is
//! only another receiver's clock.

use super::clock::{DayClock, Stamp};
use super::fast_packet::FastPackets;
use super::n2k::{MAX_DATA_BYTES, decode_message_or_frame};
use super::{Clock, Counted, Emit, Item, LineDecoder, ReadOptions, RejectReason};

/// The largest 29-bit CAN id.
pub const MAX_EXTENDED_ID: u32 = 0x1FFF_FFFF;

/// Priority, PGN, source and destination of a 29-bit NMEA 2000 CAN id.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CanId {
    /// Priority, 0 (highest) to 7.
    pub priority: u8,
    /// Parameter group number.
    pub pgn: u32,
    /// Source address.
    pub source: u8,
    /// Destination address (255: global).
    pub destination: u8,
}

impl CanId {
    /// Splits a 29-bit id (ISO 11783): bits 26-28 priority, 8-25 the PGN,
    /// 0-7 the source; for a PDU1 PGN (PDU format below 240) the low byte of
    /// the PGN field is the destination and the PGN's own low byte is 0.
    /// `None` for an id over 29 bits.
    pub fn from_raw(id: u32) -> Option<CanId> {
        if id > MAX_EXTENDED_ID {
            return None;
        }
        let field = (id >> 8) & 0x3_FFFF;
        let pdu_format = (field >> 8) & 0xFF;
        let (pgn, destination) = if pdu_format < 240 {
            (field & 0x3_FF00, (field & 0xFF) as u8)
        } else {
            (field, 255)
        };
        Some(CanId {
            priority: ((id >> 26) & 0x7) as u8,
            pgn,
            source: (id & 0xFF) as u8,
            destination,
        })
    }

    /// The 29-bit id (the inverse of [`CanId::from_raw`] for a valid id).
    pub fn to_raw(self) -> u32 {
        let pdu_format = (self.pgn >> 8) & 0xFF;
        let field = if pdu_format < 240 {
            (self.pgn & 0x3_FF00) | u32::from(self.destination)
        } else {
            self.pgn & 0x3_FFFF
        };
        (u32::from(self.priority & 0x7) << 26) | (field << 8) | u32::from(self.source)
    }
}

/// Which raw layout a [`N2kRawDecoder`] reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RawFormat {
    /// Linux can-utils `candump` (log or screen layout).
    Candump,
    /// Yacht Devices RAW.
    YdRaw,
    /// Actisense N2K ASCII.
    ActisenseAscii,
}

/// A line's own time.
#[derive(Debug, Clone, Copy, PartialEq)]
enum LineTime {
    /// Seconds since the epoch.
    Epoch(f64),
    /// Seconds since midnight.
    TimeOfDay(f64),
    /// None.
    Absent,
}

/// What a line carries, before decoding.
struct Parsed {
    time: LineTime,
    /// `None`: not an NMEA 2000 frame (standard id, remote, CAN FD).
    id: Option<CanId>,
    /// The bytes are a whole message (Actisense) rather than one frame.
    whole: bool,
}

/// The state of a raw-format decoder (clock, fast-packet joins).
#[derive(Debug, Clone)]
pub struct RawState {
    format: RawFormat,
    options: ReadOptions,
    clock: DayClock,
    fast: FastPackets,
    /// The data bytes of the current line (reused).
    data: Vec<u8>,
    receive_time_s: Option<f64>,
    receiver_stamped: bool,
}

/// The decoder of one raw format.
pub type N2kRawDecoder = Counted<RawState>;

impl Counted<RawState> {
    /// A decoder of `format` with `options`.
    pub fn new(format: RawFormat, options: ReadOptions) -> Self {
        Counted::from_state(RawState {
            format,
            options,
            clock: DayClock::default(),
            fast: FastPackets::default(),
            data: Vec::new(),
            receive_time_s: None,
            receiver_stamped: false,
        })
    }

    /// The layout read.
    pub fn format(&self) -> RawFormat {
        self.state.format
    }

    /// Decodes one CAN frame read from a live interface (SocketCAN): the
    /// same as a candump line of it, without the text. `raw_id` is the
    /// 29-bit id; `extended` false (an 11-bit frame) is not NMEA 2000.
    pub fn decode_can_frame(
        &mut self,
        raw_id: u32,
        extended: bool,
        data: &[u8],
        line_no: u64,
        out: &mut Vec<Item>,
    ) {
        self.decode_with(line_no, out, |state, emit| match CanId::from_raw(raw_id) {
            Some(id) if extended && data.len() <= 8 => {
                state.data.clear();
                state.data.extend_from_slice(data);
                let frame = Parsed {
                    time: LineTime::Absent,
                    id: Some(id),
                    whole: false,
                };
                state.message(frame, emit)
            }
            Some(_) if extended => Err(RejectReason::Malformed {
                what: "data length",
            }),
            _ => {
                emit.stats.ignored += 1;
                Ok(())
            }
        });
    }
}

impl RawState {
    fn parse(&mut self, line: &[u8], emit: &mut Emit<'_>) -> Result<(), RejectReason> {
        let line = line.trim_ascii();
        if line.is_empty() || line.first() == Some(&b'#') {
            emit.stats.blank += 1;
            return Ok(());
        }
        let text = std::str::from_utf8(line).map_err(|_| RejectReason::NotText)?;
        self.data.clear();
        let parsed = match self.format {
            RawFormat::Candump => parse_candump(text, &mut self.data)?,
            RawFormat::YdRaw => parse_ydraw(text, &mut self.data)?,
            RawFormat::ActisenseAscii => parse_actisense(text, &mut self.data)?,
        };
        self.message(parsed, emit)
    }

    /// Decodes the frame or message parsed into `self.data`.
    fn message(&mut self, parsed: Parsed, emit: &mut Emit<'_>) -> Result<(), RejectReason> {
        let Some(id) = parsed.id else {
            emit.stats.ignored += 1;
            return Ok(());
        };
        let stamp = self.stamp(parsed.time)?;
        self.receiver_stamped = matches!(self.options.clock, Clock::Receiver);
        let before = emit.out.len();
        let data = std::mem::take(&mut self.data);
        let result = decode_message_or_frame(
            &mut self.fast,
            !parsed.whole,
            id.pgn,
            id.source,
            &data,
            stamp.time_s,
            emit,
        );
        self.data = data;
        if stamp.undated {
            let records = emit.out[before..].iter().filter(|i| i.is_ok()).count();
            emit.stats.undated += records as u64;
        }
        result
    }

    /// The time of a line (see the module doc).
    fn stamp(&mut self, own: LineTime) -> Result<Stamp, RejectReason> {
        let tolerance = self.options.backwards_tolerance_s;
        match (self.options.clock, self.receive_time_s, own) {
            (Clock::Receiver, Some(received), _) => self.clock.exact(received, tolerance),
            (_, _, LineTime::Epoch(t)) => self.clock.exact(t, tolerance),
            (_, received, LineTime::TimeOfDay(tod)) => {
                let date = received
                    .and_then(|t| crate::time::split_date_time_ms(t).ok())
                    .map(|(date, _)| date)
                    .or(self.options.assumed_date);
                self.clock.time_of_day(tod, date, tolerance)
            }
            (Clock::Receiver, None, LineTime::Absent) | (Clock::Log, _, LineTime::Absent) => {
                Err(RejectReason::NoTime)
            }
        }
    }
}

impl LineDecoder for RawState {
    fn line(&mut self, line: &[u8], emit: &mut Emit<'_>) -> Result<(), RejectReason> {
        self.parse(line, emit)
    }

    fn state_bytes(&self) -> usize {
        self.data.capacity() + self.fast.state_bytes()
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

const MALFORMED_ID: RejectReason = RejectReason::Malformed { what: "CAN id" };
const MALFORMED_DATA: RejectReason = RejectReason::Malformed { what: "data bytes" };

/// Reads hex byte pairs (`"0A"`, separated or not) into `out`.
fn hex_bytes(text: &str, out: &mut Vec<u8>, limit: usize) -> Result<(), RejectReason> {
    let bytes = text.as_bytes();
    if !bytes.len().is_multiple_of(2) {
        return Err(MALFORMED_DATA);
    }
    for pair in bytes.chunks_exact(2) {
        if out.len() == limit {
            return Err(RejectReason::Malformed {
                what: "data length",
            });
        }
        let digit = |b: u8| (b as char).to_digit(16).ok_or(MALFORMED_DATA);
        out.push((digit(pair[0])? * 16 + digit(pair[1])?) as u8);
    }
    Ok(())
}

/// A CAN id in hex: 8 digits is an extended (NMEA 2000) id, 3 a standard
/// one (`None`: not NMEA 2000).
fn can_id(text: &str) -> Result<Option<CanId>, RejectReason> {
    if !text.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(MALFORMED_ID);
    }
    match text.len() {
        3 => Ok(None),
        8 => {
            let raw = u32::from_str_radix(text, 16).map_err(|_| MALFORMED_ID)?;
            CanId::from_raw(raw).map(Some).ok_or(MALFORMED_ID)
        }
        _ => Err(MALFORMED_ID),
    }
}

/// `(seconds.micro)`: seconds since the epoch.
fn candump_time(token: &str) -> Result<f64, RejectReason> {
    let inner = token
        .strip_prefix('(')
        .and_then(|t| t.strip_suffix(')'))
        .ok_or(RejectReason::Malformed { what: "time" })?;
    let ok = !inner.is_empty()
        && inner.bytes().all(|b| b.is_ascii_digit() || b == b'.')
        && inner.bytes().filter(|&b| b == b'.').count() <= 1;
    let seconds: f64 = if ok { inner.parse().ok() } else { None }
        .ok_or(RejectReason::Malformed { what: "time" })?;
    Ok(seconds)
}

fn parse_candump(text: &str, data: &mut Vec<u8>) -> Result<Parsed, RejectReason> {
    let mut tokens = text.split_ascii_whitespace().peekable();
    let time = match tokens.peek() {
        Some(t) if t.starts_with('(') => {
            let t = candump_time(t)?;
            tokens.next();
            LineTime::Epoch(t)
        }
        _ => LineTime::Absent,
    };
    let interface = tokens.next().ok_or(RejectReason::UnknownFormat)?;
    if interface.is_empty()
        || interface.len() > 15
        || !interface
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-' || b == b'.')
    {
        return Err(RejectReason::UnknownFormat);
    }
    let frame = tokens.next().ok_or(MALFORMED_ID)?;
    if let Some((id, payload)) = frame.split_once('#') {
        // Log layout: ID#DATA, ID#R (remote), ID##FDATA (CAN FD).
        if tokens.next().is_some() {
            return Err(RejectReason::Malformed {
                what: "text after the frame",
            });
        }
        let id = can_id(id)?;
        if payload.starts_with('#') || payload.starts_with('R') {
            return Ok(Parsed {
                time,
                id: None,
                whole: false,
            });
        }
        hex_bytes(payload, data, 8)?;
        return Ok(Parsed {
            time,
            id,
            whole: false,
        });
    }
    // Screen layout: ID  [n]  bytes...
    let id = can_id(frame)?;
    let length = tokens
        .next()
        .and_then(|t| t.strip_prefix('['))
        .and_then(|t| t.strip_suffix(']'))
        .and_then(|n| n.parse::<usize>().ok())
        .filter(|&n| n <= 8)
        .ok_or(RejectReason::Malformed {
            what: "frame length",
        })?;
    for byte in tokens {
        if byte.len() != 2 {
            return Err(MALFORMED_DATA);
        }
        hex_bytes(byte, data, 8)?;
    }
    if data.len() != length {
        return Err(RejectReason::Malformed {
            what: "data length",
        });
    }
    Ok(Parsed {
        time,
        id,
        whole: false,
    })
}

/// `hh:mm:ss.sss` to seconds since midnight.
fn clock_time(text: &str) -> Result<f64, RejectReason> {
    let bad = RejectReason::Malformed { what: "time" };
    let mut parts = text.split(':');
    let (Some(h), Some(m), Some(s), None) =
        (parts.next(), parts.next(), parts.next(), parts.next())
    else {
        return Err(bad);
    };
    let two = |t: &str| {
        (t.len() == 2 && t.bytes().all(|b| b.is_ascii_digit()))
            .then(|| t.parse::<u32>().ok())
            .flatten()
    };
    let (Some(h), Some(m)) = (two(h), two(m)) else {
        return Err(bad);
    };
    let (whole, frac) = s.split_once('.').unwrap_or((s, ""));
    let Some(whole) = two(whole) else {
        return Err(bad);
    };
    if frac.len() > 9 || !frac.bytes().all(|b| b.is_ascii_digit()) {
        return Err(bad);
    }
    if h > 23 || m > 59 || whole > 60 {
        return Err(RejectReason::BadTime(crate::time::TimeError::OutOfRange {
            field: "time of day",
        }));
    }
    let frac = if frac.is_empty() {
        0.0
    } else {
        format!("0.{frac}").parse::<f64>().map_err(|_| bad)?
    };
    Ok(f64::from(h * 3600 + m * 60 + whole) + frac)
}

fn parse_ydraw(text: &str, data: &mut Vec<u8>) -> Result<Parsed, RejectReason> {
    let mut tokens = text.split_ascii_whitespace().peekable();
    let time = match tokens.peek() {
        Some(t) if t.contains(':') => {
            let t = clock_time(t)?;
            tokens.next();
            let direction = tokens.next().ok_or(RejectReason::UnknownFormat)?;
            if direction != "R" && direction != "T" {
                return Err(RejectReason::Malformed { what: "direction" });
            }
            LineTime::TimeOfDay(t)
        }
        _ => LineTime::Absent,
    };
    let id = tokens.next().ok_or(MALFORMED_ID)?;
    if id.len() != 8 {
        return Err(MALFORMED_ID);
    }
    let id = can_id(id)?;
    for byte in tokens {
        if byte.len() != 2 {
            return Err(MALFORMED_DATA);
        }
        hex_bytes(byte, data, 8)?;
    }
    Ok(Parsed {
        time,
        id,
        whole: false,
    })
}

fn parse_actisense(text: &str, data: &mut Vec<u8>) -> Result<Parsed, RejectReason> {
    let mut tokens = text.split_ascii_whitespace();
    let time = tokens
        .next()
        .and_then(|t| t.strip_prefix('A'))
        .ok_or(RejectReason::UnknownFormat)?;
    // hhmmss.sss
    let time = crate::time::parse_hhmmss(time).map_err(RejectReason::BadTime)?;
    let addresses = tokens
        .next()
        .ok_or(RejectReason::Malformed { what: "addresses" })?;
    if addresses.len() != 5 || !addresses.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(RejectReason::Malformed { what: "addresses" });
    }
    let hex = |range: std::ops::Range<usize>| {
        u32::from_str_radix(&addresses[range], 16)
            .map_err(|_| RejectReason::Malformed { what: "addresses" })
    };
    let (source, destination, priority) = (hex(0..2)?, hex(2..4)?, hex(4..5)?);
    if priority > 7 {
        return Err(RejectReason::Malformed { what: "priority" });
    }
    let pgn = tokens
        .next()
        .ok_or(RejectReason::Malformed { what: "PGN" })?;
    if pgn.is_empty() || pgn.len() > 5 || !pgn.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(RejectReason::Malformed { what: "PGN" });
    }
    let pgn = u32::from_str_radix(pgn, 16).map_err(|_| RejectReason::Malformed { what: "PGN" })?;
    hex_bytes(tokens.next().unwrap_or(""), data, MAX_DATA_BYTES)?;
    if tokens.next().is_some() {
        return Err(RejectReason::Malformed {
            what: "text after the data",
        });
    }
    Ok(Parsed {
        time: LineTime::TimeOfDay(time),
        id: Some(CanId {
            priority: priority as u8,
            pgn,
            source: source as u8,
            destination: destination as u8,
        }),
        whole: true,
    })
}

/// True when a line has the shape of `format` (used to detect a log's
/// format): it parses as one, whatever its data.
pub fn looks_like(format: RawFormat, line: &[u8]) -> bool {
    let Ok(text) = std::str::from_utf8(line.trim_ascii()) else {
        return false;
    };
    let mut data = Vec::new();
    let parsed = match format {
        RawFormat::Candump => {
            // The screen layout without time starts with any interface
            // name: ask for the frame too, so words do not pass.
            parse_candump(text, &mut data)
        }
        RawFormat::YdRaw => parse_ydraw(text, &mut data),
        RawFormat::ActisenseAscii => parse_actisense(text, &mut data),
    };
    parsed.is_ok_and(|p| p.id.is_some() || format == RawFormat::Candump)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measurement::{Measurement, Source};
    use crate::read::{Decoder, ReadStats, RejectKind, Rejection};

    fn decode(format: RawFormat, lines: &[&str]) -> (Vec<Item>, ReadStats) {
        let mut d = N2kRawDecoder::new(format, ReadOptions::default());
        let mut out = Vec::new();
        for (i, l) in lines.iter().enumerate() {
            d.decode_line(l.as_bytes(), i as u64 + 1, &mut out);
        }
        (out, d.stats().clone())
    }

    #[test]
    fn can_ids_split_and_join() {
        // 127250 (PDU2) from 160, priority 2.
        let id = CanId::from_raw(0x09F1_12A0).unwrap();
        assert_eq!(
            id,
            CanId {
                priority: 2,
                pgn: 127_250,
                source: 160,
                destination: 255
            }
        );
        assert_eq!(id.to_raw(), 0x09F1_12A0);
        // 59904 ISO request (PDU1, PF 0xEA) to 0x23 from 0x01, priority 6.
        let id = CanId::from_raw(0x18EA_2301).unwrap();
        assert_eq!(
            (id.pgn, id.destination, id.source, id.priority),
            (59_904, 0x23, 1, 6)
        );
        assert_eq!(id.to_raw(), 0x18EA_2301);
        assert_eq!(CanId::from_raw(0x2000_0000), None);
    }

    const HEADING: &str = "ff,be,87,ff,7f,86,05,fc";

    #[test]
    fn the_three_layouts_give_the_canboat_record() {
        let canboat = {
            let mut d = crate::read::N2kDecoder::new(ReadOptions::default());
            let mut out = Vec::new();
            d.decode_line(
                format!("2014-08-15T19:00:00.892Z,2,127250,160,255,8,{HEADING}").as_bytes(),
                1,
                &mut out,
            );
            out.remove(0).unwrap()
        };
        assert_eq!(canboat.source, Source::N2k(160));
        let bytes = HEADING.replace(',', "");
        let spaced = HEADING.replace(',', " ").to_uppercase();
        let t = canboat.time_s;
        let cases = [
            (
                RawFormat::Candump,
                format!("({t:.6}) can0 09F112A0#{}", bytes.to_uppercase()),
            ),
            (
                RawFormat::Candump,
                format!(" ({t:.6})  can0  09F112A0   [8]  {spaced}"),
            ),
            (
                RawFormat::YdRaw,
                format!("19:00:00.892 R 09F112A0 {spaced}"),
            ),
            (
                RawFormat::ActisenseAscii,
                format!("A190000.892 A0FF2 1F112 {}", bytes.to_uppercase()),
            ),
        ];
        for (format, line) in cases {
            assert!(looks_like(format, line.as_bytes()), "{line}");
            let options = ReadOptions {
                assumed_date: Some(crate::time::CivilDate::new(2014, 8, 15).unwrap()),
                ..ReadOptions::default()
            };
            let mut d = N2kRawDecoder::new(format, options);
            let mut out = Vec::new();
            d.decode_line(line.as_bytes(), 1, &mut out);
            let record = out[0].clone().unwrap();
            assert_eq!(record.measurement, canboat.measurement, "{line}");
            assert_eq!(record.source, canboat.source, "{line}");
            assert!((record.time_s - t).abs() < 1e-5, "{line}");
        }
    }

    #[test]
    fn screen_output_without_time_needs_a_receive_time() {
        let line = format!("can0  09F112A0   [8]  {}", HEADING.replace(',', " "));
        let (items, stats) = decode(RawFormat::Candump, &[&line]);
        assert_eq!(
            items,
            vec![Err(Rejection {
                line: 1,
                reason: RejectReason::NoTime
            })]
        );
        assert_eq!(stats.rejected(RejectKind::NoTime), 1);
        let mut d = N2kRawDecoder::new(
            RawFormat::Candump,
            ReadOptions {
                clock: Clock::Receiver,
                ..ReadOptions::default()
            },
        );
        d.set_receive_time(1_700_000_000.25);
        let mut out = Vec::new();
        d.decode_line(line.as_bytes(), 1, &mut out);
        let r = out[0].clone().unwrap();
        assert_eq!(r.time_s, 1_700_000_000.25);
        assert!(matches!(r.measurement, Measurement::Heading { .. }));
        assert!(d.receiver_stamped());
    }

    #[test]
    fn non_n2k_frames_are_ignored_and_broken_lines_refused() {
        let (items, stats) = decode(
            RawFormat::Candump,
            &[
                "(1.0) can0 123#0102",
                "(1.0) can0 09F112A0#R",
                "(1.0) can0 09F112A0##1020304",
            ],
        );
        assert!(items.is_empty());
        assert_eq!(stats.ignored, 3);
        for (format, line) in [
            (RawFormat::Candump, "(1.0) can0 09F112A0#0102030"),
            (RawFormat::Candump, "(1.0) can0 09F112A0#010203040506070809"),
            (RawFormat::Candump, "(x) can0 09F112A0#01"),
            (RawFormat::Candump, "can0 09F112A0 [3] 01 02"),
            (RawFormat::Candump, "(1.0) can0 3FFFFFFF#01"),
            (RawFormat::YdRaw, "25:00:00.000 R 09F112A0 01"),
            (RawFormat::YdRaw, "10:00:00.000 X 09F112A0 01"),
            (RawFormat::YdRaw, "10:00:00.000 R 09F112A 01"),
            (RawFormat::ActisenseAscii, "A100000.000 A0FF9 1F112 00"),
            (RawFormat::ActisenseAscii, "A100000.000 A0FF2 1F112 0"),
            (RawFormat::ActisenseAscii, "A100000.000 A0FF2 FFFFFF 00"),
        ] {
            let (items, stats) = decode(format, &[line]);
            assert_eq!(items.len(), 1, "{line}");
            assert!(items[0].is_err(), "{line}");
            assert_eq!(stats.total_rejected(), 1, "{line}");
        }
    }

    #[test]
    fn time_of_day_lines_cross_midnight() {
        let options = ReadOptions {
            assumed_date: Some(crate::time::CivilDate::new(2026, 8, 3).unwrap()),
            ..ReadOptions::default()
        };
        let mut d = N2kRawDecoder::new(RawFormat::YdRaw, options);
        let mut out = Vec::new();
        for (i, l) in [
            "23:59:59.900 R 09F112A0 FF BE 87 FF 7F 86 05 FC",
            "00:00:00.100 R 09F112A0 FF BE 87 FF 7F 86 05 FC",
        ]
        .iter()
        .enumerate()
        {
            d.decode_line(l.as_bytes(), i as u64 + 1, &mut out);
        }
        let t: Vec<f64> = out.iter().map(|i| i.as_ref().unwrap().time_s).collect();
        assert!((t[1] - t[0] - 0.2).abs() < 1e-6, "{t:?}");
        assert_eq!(d.stats().undated, 2);
    }
}
