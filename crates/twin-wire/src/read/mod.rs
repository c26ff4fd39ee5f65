//! Streaming log readers, picked by content: NMEA 0183 text; NMEA 2000 as
//! canboat text, candump, Yacht Devices RAW and Actisense N2K ASCII; gpsd's
//! JSON reports; MAVLink telemetry logs (`.tlog`); the project's JSON lines.
//!
//! # Shape
//! Each format has a line [`Decoder`] (stateful: the NMEA 0183 one keeps the
//! date and the latest time, the NMEA 2000 one reassembles fast packets) that
//! turns one line into zero or more [`Item`]s, each a [`Record`] or a typed
//! [`Rejection`], and counts everything in its [`ReadStats`]. A [`Reader`]
//! drives a decoder over any `BufRead` as an `Iterator<Item = Item>`:
//! it holds one line at a time (at most `max_line_bytes`; longer lines are
//! skipped to their end and rejected as `LineTooLong`) and at most the few
//! items of one line, so memory stays constant whatever the log's length.
//! [`LogReader::open`] looks at the first non-blank lines to pick the format
//! (a `.tlog` is binary: it is recognised by its first bytes, and its
//! "lines" are its records, found by [`mavlink::MavlinkFramer`]).
//!
//! The decoders are public on their own too: the daemon feeds them payloads
//! of `{prefix}/{vessel}/nmea` line by line, keeping one decoder per vessel,
//! and the bridge feeds them what it receives live, telling each decoder
//! when it received a line ([`Decoder::set_receive_time`]).
//!
//! # Time
//! Every record's `time_s` is UTC seconds since the Unix epoch. NMEA 2000 and
//! JSON lines carry a full timestamp on every line. NMEA 0183 timing is
//! described in [`nmea0183`], that of the other formats in their modules;
//! [`Clock`] says whether a format without time of its own takes its log's
//! time stamps or the time a line was received. In every format a record more than
//! `backwards_tolerance_s` older than the newest time seen so far is
//! rejected as `TimeBackwards`; gaps forward are accepted as they are.
//!
//! # Never panics
//! Every input byte sequence gives records, rejections or nothing; tests and
//! fuzz targets feed random bytes to each decoder.

pub(crate) mod clock;
pub mod fast_packet;
pub mod gpsd;
pub mod jsonl;
pub mod mavlink;
pub mod n2k;
pub mod n2k_raw;
pub mod nmea0183;

use std::collections::VecDeque;
use std::io::{self, BufRead};

use serde::ser::{Serialize, SerializeMap, Serializer};

use crate::measurement::{Measurement, MeasurementKind, Record, Source};
use crate::messages::MessageError;
use crate::time::{CivilDate, TimeError};

pub use gpsd::GpsdDecoder;
pub use jsonl::JsonlDecoder;
pub use mavlink::{MavlinkDecoder, MavlinkOptions};
pub use n2k::N2kDecoder;
pub use n2k_raw::{N2kRawDecoder, RawFormat};
pub use nmea0183::NmeaDecoder;

/// What a reader yields: a record, or why a line (or part of it) was refused.
pub type Item = Result<Record, Rejection>;

/// A refused line or message, with the 1-based line number it came from.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("line {line}: {reason}")]
pub struct Rejection {
    /// 1-based line number in the log (or in the payload).
    pub line: u64,
    /// Why.
    pub reason: RejectReason,
}

/// Why a line or a message was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RejectReason {
    /// The line is longer than the reader's `max_line_bytes`; it was skipped
    /// without being kept in memory.
    #[error("line longer than {limit} bytes")]
    LineTooLong {
        /// The limit, bytes.
        limit: usize,
    },
    /// The line is not printable ASCII text (NMEA, NMEA 2000) or not UTF-8.
    #[error("line is not text")]
    NotText,
    /// The line does not look like this reader's format at all (an NMEA
    /// line that does not start with `$`/`!`, an NMEA 2000 line without a
    /// timestamp, a JSON line that is not an object).
    #[error("line is not in the log's format")]
    UnknownFormat,
    /// The line looks like the format but its structure is broken; `what`
    /// says where (address, checksum field, field count, hex byte, length).
    #[error("malformed {what}")]
    Malformed {
        /// What is broken.
        what: &'static str,
    },
    /// The NMEA 0183 checksum does not match the sentence.
    #[error("checksum {expected:02X} in the sentence, {computed:02X} computed")]
    BadChecksum {
        /// The checksum written in the sentence.
        expected: u8,
        /// The checksum of the sentence's characters.
        computed: u8,
    },
    /// A field does not parse (not a number, a wrong unit or hemisphere
    /// letter, half of a pair missing).
    #[error("bad field {field}")]
    BadField {
        /// The field.
        field: &'static str,
    },
    /// A field parses but is outside its physical range (latitude over 90,
    /// negative or over 50 m/s speed, minutes of arc over 60, ...).
    #[error("field {field} out of range")]
    OutOfRange {
        /// The field.
        field: &'static str,
    },
    /// An NMEA 2000 message too short for the fields read from it.
    #[error("PGN {pgn} has {len} data bytes, {needed} needed")]
    TooShort {
        /// The PGN.
        pgn: u32,
        /// Its data length, bytes.
        len: usize,
        /// The bytes needed.
        needed: usize,
    },
    /// The sender flags the data as invalid (RMC/GLL status `V`, mode `N`,
    /// GGA quality 0, RPM status `V`, 129029 method "no fix").
    #[error("sender flags {what} as not valid")]
    NotValid {
        /// What was flagged.
        what: &'static str,
    },
    /// A course over ground given only relative to magnetic north: the twin
    /// uses true courses and does not convert them.
    #[error("course over ground is magnetic")]
    MagneticCourse,
    /// A magnetic heading with no known magnetic variation to make it true.
    #[error("magnetic heading without a known variation")]
    MagneticWithoutVariation,
    /// A direction whose reference is neither true nor magnetic (NMEA 2000
    /// reference field "error" or "not available").
    #[error("{field} has no usable reference")]
    UnknownReference {
        /// The direction field.
        field: &'static str,
    },
    /// A propeller that is neither port nor starboard: RPM shaft 0 (centre
    /// line), 127488 engine instance above 1.
    #[error("propeller {number} is neither port nor starboard")]
    UnknownPropeller {
        /// The shaft number or engine instance.
        number: u32,
    },
    /// The timestamp does not parse.
    #[error("bad time: {0}")]
    BadTime(TimeError),
    /// A sentence without time (VTG, HDT, VHW, RPM...) before any timed one.
    #[error("no time known yet")]
    NoTime,
    /// A time-of-day-only sentence while no date is known and no date is
    /// assumed (`ReadOptions::assumed_date` is `None`).
    #[error("no date known")]
    NoDate,
    /// The record is older than the newest time seen, beyond the tolerance.
    #[error("time goes back by {by_s} s")]
    TimeBackwards {
        /// How far back, seconds.
        by_s: f64,
    },
    /// A JSON line that is not a valid project message.
    #[error("invalid message: {0}")]
    Message(MessageError),
    /// Telemetry from a MAVLink system other than the one followed.
    #[error("message of MAVLink system {system}, another than the one followed")]
    OtherSystem {
        /// Its system id.
        system: u8,
    },
    /// Reading the input failed; the reader stops after this.
    #[error("read error: {0:?}")]
    Io(io::ErrorKind),
}

/// The kinds of [`RejectReason`], without their data (for counting).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum RejectKind {
    /// [`RejectReason::LineTooLong`].
    LineTooLong,
    /// [`RejectReason::NotText`].
    NotText,
    /// [`RejectReason::UnknownFormat`].
    UnknownFormat,
    /// [`RejectReason::Malformed`].
    Malformed,
    /// [`RejectReason::BadChecksum`].
    BadChecksum,
    /// [`RejectReason::BadField`].
    BadField,
    /// [`RejectReason::OutOfRange`].
    OutOfRange,
    /// [`RejectReason::TooShort`].
    TooShort,
    /// [`RejectReason::NotValid`].
    NotValid,
    /// [`RejectReason::MagneticCourse`].
    MagneticCourse,
    /// [`RejectReason::MagneticWithoutVariation`].
    MagneticWithoutVariation,
    /// [`RejectReason::UnknownReference`].
    UnknownReference,
    /// [`RejectReason::UnknownPropeller`].
    UnknownPropeller,
    /// [`RejectReason::BadTime`].
    BadTime,
    /// [`RejectReason::NoTime`].
    NoTime,
    /// [`RejectReason::NoDate`].
    NoDate,
    /// [`RejectReason::TimeBackwards`].
    TimeBackwards,
    /// [`RejectReason::Message`].
    Message,
    /// [`RejectReason::OtherSystem`].
    OtherSystem,
    /// [`RejectReason::Io`].
    Io,
}

impl RejectKind {
    /// Every kind, in declaration order.
    pub const ALL: [RejectKind; 20] = [
        RejectKind::LineTooLong,
        RejectKind::NotText,
        RejectKind::UnknownFormat,
        RejectKind::Malformed,
        RejectKind::BadChecksum,
        RejectKind::BadField,
        RejectKind::OutOfRange,
        RejectKind::TooShort,
        RejectKind::NotValid,
        RejectKind::MagneticCourse,
        RejectKind::MagneticWithoutVariation,
        RejectKind::UnknownReference,
        RejectKind::UnknownPropeller,
        RejectKind::BadTime,
        RejectKind::NoTime,
        RejectKind::NoDate,
        RejectKind::TimeBackwards,
        RejectKind::Message,
        RejectKind::OtherSystem,
        RejectKind::Io,
    ];

    /// snake_case name, for reports.
    pub fn name(self) -> &'static str {
        match self {
            RejectKind::LineTooLong => "line_too_long",
            RejectKind::NotText => "not_text",
            RejectKind::UnknownFormat => "unknown_format",
            RejectKind::Malformed => "malformed",
            RejectKind::BadChecksum => "bad_checksum",
            RejectKind::BadField => "bad_field",
            RejectKind::OutOfRange => "out_of_range",
            RejectKind::TooShort => "too_short",
            RejectKind::NotValid => "not_valid",
            RejectKind::MagneticCourse => "magnetic_course",
            RejectKind::MagneticWithoutVariation => "magnetic_without_variation",
            RejectKind::UnknownReference => "unknown_reference",
            RejectKind::UnknownPropeller => "unknown_propeller",
            RejectKind::BadTime => "bad_time",
            RejectKind::NoTime => "no_time",
            RejectKind::NoDate => "no_date",
            RejectKind::TimeBackwards => "time_backwards",
            RejectKind::Message => "message",
            RejectKind::OtherSystem => "other_system",
            RejectKind::Io => "io",
        }
    }
}

impl RejectReason {
    /// The kind of this reason.
    pub fn kind(&self) -> RejectKind {
        match self {
            RejectReason::LineTooLong { .. } => RejectKind::LineTooLong,
            RejectReason::NotText => RejectKind::NotText,
            RejectReason::UnknownFormat => RejectKind::UnknownFormat,
            RejectReason::Malformed { .. } => RejectKind::Malformed,
            RejectReason::BadChecksum { .. } => RejectKind::BadChecksum,
            RejectReason::BadField { .. } => RejectKind::BadField,
            RejectReason::OutOfRange { .. } => RejectKind::OutOfRange,
            RejectReason::TooShort { .. } => RejectKind::TooShort,
            RejectReason::NotValid { .. } => RejectKind::NotValid,
            RejectReason::MagneticCourse => RejectKind::MagneticCourse,
            RejectReason::MagneticWithoutVariation => RejectKind::MagneticWithoutVariation,
            RejectReason::UnknownReference { .. } => RejectKind::UnknownReference,
            RejectReason::UnknownPropeller { .. } => RejectKind::UnknownPropeller,
            RejectReason::BadTime(_) => RejectKind::BadTime,
            RejectReason::NoTime => RejectKind::NoTime,
            RejectReason::NoDate => RejectKind::NoDate,
            RejectReason::TimeBackwards { .. } => RejectKind::TimeBackwards,
            RejectReason::Message(_) => RejectKind::Message,
            RejectReason::OtherSystem { .. } => RejectKind::OtherSystem,
            RejectReason::Io(_) => RejectKind::Io,
        }
    }
}

/// What a reader has seen so far. Every line lands in exactly one of
/// `blank`, `ignored`, `empty`, `time_only`, a rejection, or gives one or more
/// records (a line can also give records and a rejection, e.g. a VTG whose
/// speed is kept and whose magnetic-only course is rejected).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ReadStats {
    /// Lines read, including blank and too-long ones.
    pub lines: u64,
    /// Blank lines and comments (`#...`).
    pub blank: u64,
    /// Well-formed messages of a type the reader does not read (other
    /// sentences and PGNs, another maker's PGN 130842): skipped, not errors.
    pub ignored: u64,
    /// Messages of a type the reader reads whose every field it reads is
    /// absent (empty NMEA fields, NMEA 2000 "not available").
    pub empty: u64,
    /// Messages that only set the clock (ZDA).
    pub time_only: u64,
    /// NMEA 0183 sentences without a checksum (accepted).
    pub without_checksum: u64,
    /// Records whose date was assumed (`ReadOptions::assumed_date`) because
    /// the log had not given one.
    pub undated: u64,
    records: [u64; MeasurementKind::ALL.len()],
    rejected: [u64; RejectKind::ALL.len()],
}

impl ReadStats {
    /// Records of one kind.
    pub fn records(&self, kind: MeasurementKind) -> u64 {
        self.records[kind.index()]
    }

    /// Rejections of one kind.
    pub fn rejected(&self, kind: RejectKind) -> u64 {
        self.rejected[kind as usize]
    }

    /// All records.
    pub fn total_records(&self) -> u64 {
        self.records.iter().sum()
    }

    /// All rejections.
    pub fn total_rejected(&self) -> u64 {
        self.rejected.iter().sum()
    }

    /// Non-zero record counts by kind.
    pub fn records_by_kind(&self) -> impl Iterator<Item = (MeasurementKind, u64)> + '_ {
        MeasurementKind::ALL
            .into_iter()
            .map(|k| (k, self.records(k)))
            .filter(|(_, n)| *n > 0)
    }

    /// Non-zero rejection counts by kind.
    pub fn rejected_by_kind(&self) -> impl Iterator<Item = (RejectKind, u64)> + '_ {
        RejectKind::ALL
            .into_iter()
            .map(|k| (k, self.rejected(k)))
            .filter(|(_, n)| *n > 0)
    }

    fn count_record(&mut self, kind: MeasurementKind) {
        self.records[kind.index()] += 1;
    }

    fn count_rejection(&mut self, kind: RejectKind) {
        self.rejected[kind as usize] += 1;
    }
}

/// Serialised as `{"lines":..,"blank":..,"ignored":..,"empty":..,
/// "time_only":..,"without_checksum":..,"undated":..,"records":{kind:n},
/// "rejected":{reason:n}}` with only non-zero kinds in the two maps.
impl Serialize for ReadStats {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        struct Counts<'a, K>(&'a [(K, u64)], fn(&K) -> &'static str);
        impl<K> Serialize for Counts<'_, K> {
            fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
                let mut map = serializer.serialize_map(Some(self.0.len()))?;
                for (k, n) in self.0 {
                    map.serialize_entry((self.1)(k), n)?;
                }
                map.end()
            }
        }
        let records: Vec<_> = self.records_by_kind().collect();
        let rejected: Vec<_> = self.rejected_by_kind().collect();
        let mut map = serializer.serialize_map(Some(9))?;
        map.serialize_entry("lines", &self.lines)?;
        map.serialize_entry("blank", &self.blank)?;
        map.serialize_entry("ignored", &self.ignored)?;
        map.serialize_entry("empty", &self.empty)?;
        map.serialize_entry("time_only", &self.time_only)?;
        map.serialize_entry("without_checksum", &self.without_checksum)?;
        map.serialize_entry("undated", &self.undated)?;
        map.serialize_entry("records", &Counts(&records, |k| k.name()))?;
        map.serialize_entry("rejected", &Counts(&rejected, |k| k.name()))?;
        map.end()
    }
}

/// Which clock stamps the records of a format that has no time of its own
/// (NMEA 2000 frames), or no time in a given line (a gpsd report without
/// `time`, MAVLink before the vehicle's clock is known).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Clock {
    /// The log's own time stamps (a logger's, a `.tlog`'s): reading files.
    #[default]
    Log,
    /// The time each line was received, given by
    /// [`Decoder::set_receive_time`]: live inputs.
    Receiver,
}

/// Options shared by the readers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReadOptions {
    /// Longest line kept, bytes; longer lines are rejected (`LineTooLong`).
    pub max_line_bytes: usize,
    /// How far a record may be older than the newest time seen before it is
    /// rejected as `TimeBackwards`, seconds.
    pub backwards_tolerance_s: f64,
    /// The date given to NMEA 0183 time-of-day-only sentences until the log
    /// gives one (ZDA with a date, RMC). `None` rejects them (`NoDate`)
    /// instead. The default, 1970-01-01, keeps a dateless log usable (its
    /// times are then seconds since its first midnight) and counts each such
    /// record in `ReadStats::undated`.
    pub assumed_date: Option<CivilDate>,
    /// Which clock stamps what has no time of its own (see [`Clock`]).
    pub clock: Clock,
    /// How MAVLink is read (system, motors, PWM -> thrust map).
    pub mavlink: MavlinkOptions,
}

/// The default line limit, bytes (a JSON line may be a full payload).
pub const DEFAULT_MAX_LINE_BYTES: usize = crate::messages::DEFAULT_MAX_PAYLOAD_BYTES;

impl Default for ReadOptions {
    fn default() -> Self {
        Self {
            max_line_bytes: DEFAULT_MAX_LINE_BYTES,
            backwards_tolerance_s: 0.5,
            assumed_date: Some(CivilDate::UNIX_EPOCH),
            clock: Clock::Log,
            mavlink: MavlinkOptions::default(),
        }
    }
}

/// A line-by-line decoder of one log format.
pub trait Decoder {
    /// Decodes one line (without its line ending), appending what it gives
    /// to `out`. Counts the line in the stats.
    fn decode_line(&mut self, line: &[u8], line_no: u64, out: &mut Vec<Item>);

    /// Counts a line refused before decoding (too long, unreadable) and
    /// appends the rejection to `out`.
    fn reject_line(&mut self, line_no: u64, reason: RejectReason, out: &mut Vec<Item>);

    /// The counts so far.
    fn stats(&self) -> &ReadStats;

    /// Bytes of state the decoder holds beyond its fixed size (buffers), for
    /// checking that reading stays in constant memory.
    fn state_bytes(&self) -> usize {
        0
    }

    /// The time the lines that follow were received, seconds since the
    /// epoch: live inputs tell it before each line (or datagram), and the
    /// decoders of formats without time of their own stamp records with it
    /// under [`Clock::Receiver`]. Ignored by the others.
    fn set_receive_time(&mut self, _time_s: f64) {}

    /// True when the records of the line just decoded were stamped with the
    /// receive time rather than a time of the source's.
    fn receiver_stamped(&self) -> bool {
        false
    }
}

/// What a format's decoder does with one line, apart from counting it: the
/// part that differs between formats. [`Counted`] adds the counts and makes
/// it a [`Decoder`].
pub trait LineDecoder {
    /// Decodes one line, emitting records (and rejections that do not end
    /// the line); `Err` refuses the line.
    fn line(&mut self, line: &[u8], emit: &mut Emit<'_>) -> Result<(), RejectReason>;

    /// Bytes of state held beyond the fixed size.
    fn state_bytes(&self) -> usize {
        0
    }

    /// See [`Decoder::set_receive_time`].
    fn set_receive_time(&mut self, _time_s: f64) {}

    /// See [`Decoder::receiver_stamped`].
    fn receiver_stamped(&self) -> bool {
        false
    }

    /// A new line begins (forget what was said of the previous one).
    fn begin_line(&mut self) {}
}

/// A format's [`LineDecoder`] with its [`ReadStats`]: the decoders of
/// candump, Yacht Devices RAW, Actisense, gpsd and MAVLink.
#[derive(Debug, Clone)]
pub struct Counted<S> {
    state: S,
    stats: ReadStats,
}

impl<S: LineDecoder> Counted<S> {
    fn from_state(state: S) -> Self {
        Self {
            state,
            stats: ReadStats::default(),
        }
    }

    /// Counts a line and decodes it with `body`, counting its refusal.
    fn decode_with(
        &mut self,
        line_no: u64,
        out: &mut Vec<Item>,
        body: impl FnOnce(&mut S, &mut Emit<'_>) -> Result<(), RejectReason>,
    ) {
        self.stats.lines += 1;
        self.state.begin_line();
        let mut emit = Emit {
            out,
            stats: &mut self.stats,
            line: line_no,
        };
        if let Err(reason) = body(&mut self.state, &mut emit) {
            emit.reject(reason);
        }
    }
}

impl<S: LineDecoder> Decoder for Counted<S> {
    fn decode_line(&mut self, line: &[u8], line_no: u64, out: &mut Vec<Item>) {
        self.decode_with(line_no, out, |state, emit| state.line(line, emit));
    }

    fn reject_line(&mut self, line_no: u64, reason: RejectReason, out: &mut Vec<Item>) {
        reject_whole_line(&mut self.stats, line_no, reason, out);
    }

    fn stats(&self) -> &ReadStats {
        &self.stats
    }

    fn state_bytes(&self) -> usize {
        self.state.state_bytes()
    }

    fn set_receive_time(&mut self, time_s: f64) {
        self.state.set_receive_time(time_s);
    }

    fn receiver_stamped(&self) -> bool {
        self.state.receiver_stamped()
    }
}

/// Appends records and rejections to an output while counting them.
pub struct Emit<'a> {
    pub(crate) out: &'a mut Vec<Item>,
    pub(crate) stats: &'a mut ReadStats,
    pub(crate) line: u64,
}

impl Emit<'_> {
    pub(crate) fn record(&mut self, time_s: f64, source: Source, measurement: Measurement) {
        self.stats.count_record(measurement.kind());
        self.out.push(Ok(Record {
            time_s,
            source,
            measurement,
        }));
    }

    pub(crate) fn reject(&mut self, reason: RejectReason) {
        self.stats.count_rejection(reason.kind());
        self.out.push(Err(Rejection {
            line: self.line,
            reason,
        }));
    }
}

/// Counts a pre-decoding rejection; shared by the decoders' `reject_line`.
pub(crate) fn reject_whole_line(
    stats: &mut ReadStats,
    line_no: u64,
    reason: RejectReason,
    out: &mut Vec<Item>,
) {
    stats.lines += 1;
    Emit {
        out,
        stats,
        line: line_no,
    }
    .reject(reason);
}

/// The newest time seen and the backwards check against it.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Monotonic {
    newest_s: Option<f64>,
}

impl Monotonic {
    /// Accepts `time_s` unless it is more than `tolerance_s` before the
    /// newest time; an accepted time may raise the newest.
    pub(crate) fn check(&mut self, time_s: f64, tolerance_s: f64) -> Result<(), RejectReason> {
        if let Some(newest) = self.newest_s {
            if time_s < newest - tolerance_s {
                return Err(RejectReason::TimeBackwards {
                    by_s: newest - time_s,
                });
            }
            if time_s > newest {
                self.newest_s = Some(time_s);
            }
        } else {
            self.newest_s = Some(time_s);
        }
        Ok(())
    }
}

/// Strips a trailing `\r` and surrounding ASCII whitespace.
pub(crate) fn trim_line(line: &[u8]) -> &[u8] {
    line.trim_ascii()
}

/// One line event from the input.
enum LineEvent {
    /// A line is in the buffer.
    Line,
    /// A line longer than the limit was skipped.
    TooLong,
    /// Bytes of a binary log that are not a record were skipped.
    Skipped(RejectReason),
    /// Reading failed.
    Io(io::ErrorKind),
    /// End of input.
    Eof,
}

/// Reads bounded lines from a `BufRead`, or the records of a `.tlog`.
struct Lines<R> {
    inner: R,
    buf: Vec<u8>,
    max_line_bytes: usize,
    line_no: u64,
    /// Set for a `.tlog`: its records instead of lines.
    framer: Option<mavlink::MavlinkFramer>,
}

impl<R: BufRead> Lines<R> {
    fn new(inner: R, max_line_bytes: usize) -> Self {
        Self {
            inner,
            buf: Vec::new(),
            max_line_bytes,
            line_no: 0,
            framer: None,
        }
    }

    /// Reads the next `.tlog` record (stamp + frame) into `self.buf`.
    fn next_record(&mut self) -> LineEvent {
        let Some(framer) = self.framer.as_mut() else {
            return LineEvent::Eof;
        };
        loop {
            match framer.next_event() {
                Some(mavlink::FrameEvent::Frame(record)) => {
                    self.buf.clear();
                    self.buf.extend_from_slice(record);
                    self.line_no += 1;
                    return LineEvent::Line;
                }
                Some(mavlink::FrameEvent::Skipped { reason, .. }) => {
                    self.line_no += 1;
                    return LineEvent::Skipped(reason);
                }
                None => {}
            }
            let available = match self.inner.fill_buf() {
                Ok(bytes) => bytes,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return LineEvent::Io(e.kind()),
            };
            if available.is_empty() {
                self.line_no += 1;
                return match framer.drain_event() {
                    Some(mavlink::FrameEvent::Frame(record)) => {
                        self.buf.clear();
                        self.buf.extend_from_slice(record);
                        LineEvent::Line
                    }
                    Some(mavlink::FrameEvent::Skipped { reason, .. }) => LineEvent::Skipped(reason),
                    None => {
                        self.line_no -= 1;
                        LineEvent::Eof
                    }
                };
            }
            let n = available.len();
            framer.push(available);
            self.inner.consume(n);
        }
    }

    /// Reads the next line into `self.buf` (without `\n`). Never holds more
    /// than `max_line_bytes` of a line: the rest of a longer one is consumed
    /// and dropped.
    fn next_line(&mut self) -> LineEvent {
        if self.framer.is_some() {
            return self.next_record();
        }
        self.buf.clear();
        let mut too_long = false;
        let mut got_any = false;
        loop {
            let available = match self.inner.fill_buf() {
                Ok(bytes) => bytes,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return LineEvent::Io(e.kind()),
            };
            if available.is_empty() {
                if !got_any {
                    return LineEvent::Eof;
                }
                break;
            }
            got_any = true;
            let newline = available.iter().position(|&b| b == b'\n');
            let chunk = &available[..newline.unwrap_or(available.len())];
            if !too_long {
                if self.buf.len() + chunk.len() > self.max_line_bytes {
                    too_long = true;
                    self.buf.clear();
                } else {
                    self.buf.extend_from_slice(chunk);
                }
            }
            let used = newline.map_or(available.len(), |i| i + 1);
            self.inner.consume(used);
            if newline.is_some() {
                break;
            }
        }
        self.line_no += 1;
        if too_long {
            LineEvent::TooLong
        } else {
            LineEvent::Line
        }
    }
}

/// A line read ahead (to detect the format) and not yet decoded.
enum Prefetched {
    Line(Vec<u8>),
    TooLong,
    Skipped(RejectReason),
}

/// Drives a [`Decoder`] over a `BufRead`: an iterator of [`Item`]s in
/// constant memory.
pub struct Reader<R, D> {
    lines: Lines<R>,
    decoder: D,
    /// Items of the current line, in reverse order (popped from the end).
    pending: Vec<Item>,
    prefetched: VecDeque<(u64, Prefetched)>,
    done: bool,
}

impl<R: BufRead, D: Decoder> Reader<R, D> {
    /// A reader of `input` with `decoder`, keeping lines up to
    /// `max_line_bytes`.
    pub fn new(input: R, decoder: D, max_line_bytes: usize) -> Self {
        Self {
            lines: Lines::new(input, max_line_bytes),
            decoder,
            pending: Vec::new(),
            prefetched: VecDeque::new(),
            done: false,
        }
    }

    /// The counts so far.
    pub fn stats(&self) -> &ReadStats {
        self.decoder.stats()
    }

    /// The decoder.
    pub fn decoder(&self) -> &D {
        &self.decoder
    }

    /// Bytes held in buffers (line buffer, pending items, decoder state): a
    /// diagnostic for the constant-memory guarantee.
    pub fn buffered_bytes(&self) -> usize {
        self.lines.buf.capacity()
            + self.pending.capacity() * std::mem::size_of::<Item>()
            + self
                .prefetched
                .iter()
                .map(|(_, p)| match p {
                    Prefetched::Line(l) => l.capacity(),
                    Prefetched::TooLong | Prefetched::Skipped(_) => 0,
                })
                .sum::<usize>()
            + self.decoder.state_bytes()
    }
}

impl<R: BufRead, D: Decoder> Iterator for Reader<R, D> {
    type Item = Item;

    fn next(&mut self) -> Option<Item> {
        loop {
            if let Some(item) = self.pending.pop() {
                return Some(item);
            }
            if self.done {
                return None;
            }
            let limit = self.lines.max_line_bytes;
            if let Some((line_no, line)) = self.prefetched.pop_front() {
                match line {
                    Prefetched::Line(bytes) => {
                        self.decoder.decode_line(&bytes, line_no, &mut self.pending)
                    }
                    Prefetched::TooLong => self.decoder.reject_line(
                        line_no,
                        RejectReason::LineTooLong { limit },
                        &mut self.pending,
                    ),
                    Prefetched::Skipped(reason) => {
                        self.decoder.reject_line(line_no, reason, &mut self.pending)
                    }
                }
            } else {
                match self.lines.next_line() {
                    LineEvent::Line => self.decoder.decode_line(
                        &self.lines.buf,
                        self.lines.line_no,
                        &mut self.pending,
                    ),
                    LineEvent::TooLong => self.decoder.reject_line(
                        self.lines.line_no,
                        RejectReason::LineTooLong { limit },
                        &mut self.pending,
                    ),
                    LineEvent::Skipped(reason) => {
                        self.decoder
                            .reject_line(self.lines.line_no, reason, &mut self.pending)
                    }
                    LineEvent::Io(kind) => {
                        self.done = true;
                        self.decoder.reject_line(
                            self.lines.line_no + 1,
                            RejectReason::Io(kind),
                            &mut self.pending,
                        );
                    }
                    LineEvent::Eof => self.done = true,
                }
            }
            self.pending.reverse();
        }
    }
}

/// The log formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LogFormat {
    /// NMEA 0183 sentences, one a line.
    Nmea0183,
    /// canboat plain or FAST NMEA 2000 text.
    N2k,
    /// The project's JSON lines.
    JsonLines,
    /// NMEA 2000 CAN frames as Linux `candump` prints or logs them.
    Candump,
    /// NMEA 2000 CAN frames in Yacht Devices RAW.
    YdRaw,
    /// NMEA 2000 messages in Actisense N2K ASCII.
    ActisenseAscii,
    /// gpsd's JSON reports.
    GpsdJson,
    /// A MAVLink telemetry log (`.tlog`).
    MavlinkTlog,
}

impl LogFormat {
    /// A short snake_case name, for reports: `nmea0183`, `n2k`,
    /// `json_lines`, `candump`, `ydraw`, `actisense_ascii`, `gpsd_json`,
    /// `mavlink_tlog`.
    pub fn name(self) -> &'static str {
        match self {
            LogFormat::Nmea0183 => "nmea0183",
            LogFormat::N2k => "n2k",
            LogFormat::JsonLines => "json_lines",
            LogFormat::Candump => "candump",
            LogFormat::YdRaw => "ydraw",
            LogFormat::ActisenseAscii => "actisense_ascii",
            LogFormat::GpsdJson => "gpsd_json",
            LogFormat::MavlinkTlog => "mavlink_tlog",
        }
    }

    /// What it is, for people.
    pub fn description(self) -> &'static str {
        match self {
            LogFormat::Nmea0183 => "NMEA 0183",
            LogFormat::N2k => "canboat NMEA 2000",
            LogFormat::JsonLines => "JSON lines",
            LogFormat::Candump => "NMEA 2000 candump",
            LogFormat::YdRaw => "NMEA 2000 Yacht Devices RAW",
            LogFormat::ActisenseAscii => "NMEA 2000 Actisense N2K ASCII",
            LogFormat::GpsdJson => "gpsd JSON",
            LogFormat::MavlinkTlog => "MAVLink telemetry log",
        }
    }

    /// Every format.
    pub const ALL: [LogFormat; 8] = [
        LogFormat::Nmea0183,
        LogFormat::N2k,
        LogFormat::JsonLines,
        LogFormat::Candump,
        LogFormat::YdRaw,
        LogFormat::ActisenseAscii,
        LogFormat::GpsdJson,
        LogFormat::MavlinkTlog,
    ];
}

/// How many non-blank lines [`LogReader::open`] looks at to pick a format.
pub const DETECT_LINES: usize = 16;

/// The format of one line, if it clearly has one. Blank lines and `#`
/// comments other than canboat's `# format=` header have none. (A `.tlog`
/// is binary and found by its first bytes, not by a line.)
pub fn detect_line_format(line: &[u8]) -> Option<LogFormat> {
    let line = trim_line(line);
    let line = line.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(line);
    match line.first()? {
        b'$' | b'!' => Some(LogFormat::Nmea0183),
        b'{' if gpsd::looks_like_gpsd(line) => Some(LogFormat::GpsdJson),
        b'{' => Some(LogFormat::JsonLines),
        b'#' => line.starts_with(b"# format=").then_some(LogFormat::N2k),
        b'0'..=b'9' if n2k::looks_like_n2k(line) => Some(LogFormat::N2k),
        b'0'..=b'9' => n2k_raw::looks_like(RawFormat::YdRaw, line).then_some(LogFormat::YdRaw),
        b'A' if n2k_raw::looks_like(RawFormat::ActisenseAscii, line) => {
            Some(LogFormat::ActisenseAscii)
        }
        b'(' | b'a'..=b'z' | b'A'..=b'Z' | b' ' => {
            n2k_raw::looks_like(RawFormat::Candump, line).then_some(LogFormat::Candump)
        }
        _ => None,
    }
}

/// The format of a log from its first lines: the format of the first line
/// that clearly has one.
pub fn detect_format<'a>(lines: impl IntoIterator<Item = &'a [u8]>) -> Option<LogFormat> {
    lines.into_iter().find_map(detect_line_format)
}

/// Why a log cannot be opened.
#[derive(Debug, thiserror::Error)]
pub enum OpenError {
    /// The input has no non-blank line.
    #[error("the log is empty")]
    Empty,
    /// None of the first [`DETECT_LINES`] non-blank lines is in a known format.
    #[error("unknown log format")]
    UnknownFormat,
    /// Reading the input failed.
    #[error("read error: {0:?}")]
    Io(io::ErrorKind),
}

/// The decoder of whichever format a log is in.
#[derive(Debug)]
pub enum AnyDecoder {
    /// NMEA 0183.
    Nmea0183(NmeaDecoder),
    /// canboat NMEA 2000 text.
    N2k(N2kDecoder),
    /// JSON lines.
    JsonLines(JsonlDecoder),
    /// candump, Yacht Devices RAW or Actisense N2K ASCII.
    N2kRaw(N2kRawDecoder),
    /// gpsd JSON.
    Gpsd(GpsdDecoder),
    /// MAVLink `.tlog` records.
    Mavlink(MavlinkDecoder),
}

impl AnyDecoder {
    /// A decoder for `format`.
    pub fn new(format: LogFormat, options: ReadOptions) -> Self {
        match format {
            LogFormat::Nmea0183 => AnyDecoder::Nmea0183(NmeaDecoder::new(options)),
            LogFormat::N2k => AnyDecoder::N2k(N2kDecoder::new(options)),
            LogFormat::JsonLines => AnyDecoder::JsonLines(JsonlDecoder::new(options)),
            LogFormat::Candump => {
                AnyDecoder::N2kRaw(N2kRawDecoder::new(RawFormat::Candump, options))
            }
            LogFormat::YdRaw => AnyDecoder::N2kRaw(N2kRawDecoder::new(RawFormat::YdRaw, options)),
            LogFormat::ActisenseAscii => {
                AnyDecoder::N2kRaw(N2kRawDecoder::new(RawFormat::ActisenseAscii, options))
            }
            LogFormat::GpsdJson => AnyDecoder::Gpsd(GpsdDecoder::new(options)),
            LogFormat::MavlinkTlog => AnyDecoder::Mavlink(MavlinkDecoder::new(options, true)),
        }
    }

    /// The format decoded.
    pub fn format(&self) -> LogFormat {
        match self {
            AnyDecoder::Nmea0183(_) => LogFormat::Nmea0183,
            AnyDecoder::N2k(_) => LogFormat::N2k,
            AnyDecoder::JsonLines(_) => LogFormat::JsonLines,
            AnyDecoder::N2kRaw(d) => match d.format() {
                RawFormat::Candump => LogFormat::Candump,
                RawFormat::YdRaw => LogFormat::YdRaw,
                RawFormat::ActisenseAscii => LogFormat::ActisenseAscii,
            },
            AnyDecoder::Gpsd(_) => LogFormat::GpsdJson,
            AnyDecoder::Mavlink(_) => LogFormat::MavlinkTlog,
        }
    }

    fn inner(&mut self) -> &mut dyn Decoder {
        match self {
            AnyDecoder::Nmea0183(d) => d,
            AnyDecoder::N2k(d) => d,
            AnyDecoder::JsonLines(d) => d,
            AnyDecoder::N2kRaw(d) => d,
            AnyDecoder::Gpsd(d) => d,
            AnyDecoder::Mavlink(d) => d,
        }
    }

    fn inner_ref(&self) -> &dyn Decoder {
        match self {
            AnyDecoder::Nmea0183(d) => d,
            AnyDecoder::N2k(d) => d,
            AnyDecoder::JsonLines(d) => d,
            AnyDecoder::N2kRaw(d) => d,
            AnyDecoder::Gpsd(d) => d,
            AnyDecoder::Mavlink(d) => d,
        }
    }
}

impl Decoder for AnyDecoder {
    fn decode_line(&mut self, line: &[u8], line_no: u64, out: &mut Vec<Item>) {
        self.inner().decode_line(line, line_no, out);
    }

    fn reject_line(&mut self, line_no: u64, reason: RejectReason, out: &mut Vec<Item>) {
        self.inner().reject_line(line_no, reason, out);
    }

    fn stats(&self) -> &ReadStats {
        self.inner_ref().stats()
    }

    fn state_bytes(&self) -> usize {
        self.inner_ref().state_bytes()
    }

    fn set_receive_time(&mut self, time_s: f64) {
        self.inner().set_receive_time(time_s);
    }

    fn receiver_stamped(&self) -> bool {
        self.inner_ref().receiver_stamped()
    }
}

/// A reader of a log in any of the formats, picked by content.
pub type LogReader<R> = Reader<R, AnyDecoder>;

impl<R: BufRead> Reader<R, AnyDecoder> {
    /// Opens a log: reads up to [`DETECT_LINES`] non-blank lines to pick the
    /// format, then reads them again as records.
    pub fn open(input: R, options: ReadOptions) -> Result<Self, OpenError> {
        let mut lines = Lines::new(input, options.max_line_bytes);
        if lines.starts_like_tlog()? {
            lines.framer = Some(mavlink::MavlinkFramer::new(true));
            return Ok(Self {
                lines,
                decoder: AnyDecoder::new(LogFormat::MavlinkTlog, options),
                pending: Vec::new(),
                prefetched: VecDeque::new(),
                done: false,
            });
        }
        let mut prefetched = VecDeque::new();
        let mut non_blank = 0;
        let mut format = None;
        while non_blank < DETECT_LINES {
            match lines.next_line() {
                LineEvent::Line => {
                    if !trim_line(&lines.buf).is_empty() {
                        non_blank += 1;
                        format = detect_line_format(&lines.buf);
                    }
                    prefetched.push_back((lines.line_no, Prefetched::Line(lines.buf.clone())));
                    if format.is_some() {
                        break;
                    }
                }
                LineEvent::TooLong => {
                    non_blank += 1;
                    prefetched.push_back((lines.line_no, Prefetched::TooLong));
                }
                LineEvent::Skipped(reason) => {
                    prefetched.push_back((lines.line_no, Prefetched::Skipped(reason)));
                }
                LineEvent::Io(kind) => return Err(OpenError::Io(kind)),
                LineEvent::Eof => break,
            }
        }
        let format = match format {
            Some(f) => f,
            None if non_blank == 0 => return Err(OpenError::Empty),
            None => return Err(OpenError::UnknownFormat),
        };
        Ok(Self {
            lines,
            decoder: AnyDecoder::new(format, options),
            pending: Vec::new(),
            prefetched,
            done: false,
        })
    }

    /// The format picked.
    pub fn format(&self) -> LogFormat {
        self.decoder.format()
    }
}

impl<R: BufRead> Lines<R> {
    /// Looks at the first bytes (without consuming them): a `.tlog` stamp
    /// and a MAVLink start byte.
    fn starts_like_tlog(&mut self) -> Result<bool, OpenError> {
        loop {
            match self.inner.fill_buf() {
                Ok(bytes) => return Ok(mavlink::looks_like_tlog(bytes)),
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(OpenError::Io(e.kind())),
            }
        }
    }
}

/// A reader of NMEA 0183 text.
pub fn nmea0183_reader<R: BufRead>(input: R, options: ReadOptions) -> Reader<R, NmeaDecoder> {
    Reader::new(input, NmeaDecoder::new(options), options.max_line_bytes)
}

/// A reader of canboat NMEA 2000 text.
pub fn n2k_reader<R: BufRead>(input: R, options: ReadOptions) -> Reader<R, N2kDecoder> {
    Reader::new(input, N2kDecoder::new(options), options.max_line_bytes)
}

/// A reader of the project's JSON lines.
pub fn jsonl_reader<R: BufRead>(input: R, options: ReadOptions) -> Reader<R, JsonlDecoder> {
    Reader::new(input, JsonlDecoder::new(options), options.max_line_bytes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    #[test]
    fn formats_are_detected_by_content() {
        let cases: [(&str, Option<LogFormat>); 7] = [
            ("$IIVHW,,T,,M,06.11,N,11.31,K*51", Some(LogFormat::Nmea0183)),
            (
                "!AIVDM,1,1,,A,13u?etPv2;0n:dDPwUM1U1Cb069D,0*24",
                Some(LogFormat::Nmea0183),
            ),
            ("# format=FAST", Some(LogFormat::N2k)),
            (
                "2026-08-03T04:27:20.588Z,3,127251,27,255,8,00,f2,74,fa,ff,27,02,ff",
                Some(LogFormat::N2k),
            ),
            (r#"{"type":"gnss"}"#, Some(LogFormat::JsonLines)),
            ("# a comment", None),
            ("2026-08-03 nothing", None),
        ];
        for (line, format) in cases {
            assert_eq!(detect_line_format(line.as_bytes()), format, "{line}");
        }
        let lines: [&[u8]; 3] = [b"", b"hello", b"$GPZDA,095559,,,,00,*4D"];
        assert_eq!(detect_format(lines), Some(LogFormat::Nmea0183));
    }

    #[test]
    fn open_refuses_empty_and_unknown_logs() {
        assert!(matches!(
            LogReader::open(Cursor::new("\n\n  \n"), ReadOptions::default()),
            Err(OpenError::Empty)
        ));
        let garbage = "garbage\n".repeat(DETECT_LINES + 1);
        assert!(matches!(
            LogReader::open(Cursor::new(garbage), ReadOptions::default()),
            Err(OpenError::UnknownFormat)
        ));
    }

    #[test]
    fn open_replays_the_lines_it_looked_at() {
        // The garbage line before the first NMEA line is looked at, then
        // decoded (and rejected) like any other.
        let log = "junk\n$GPZDA,095559,15,08,2014,00,\n$IIHDT,123.4,T\n";
        let mut reader = LogReader::open(Cursor::new(log), ReadOptions::default()).unwrap();
        assert_eq!(reader.format(), LogFormat::Nmea0183);
        let items: Vec<_> = reader.by_ref().collect();
        assert_eq!(items.len(), 2, "{items:?}");
        assert_eq!(
            items[0],
            Err(Rejection {
                line: 1,
                reason: RejectReason::UnknownFormat
            })
        );
        assert!(items[1].is_ok());
        assert_eq!(reader.stats().lines, 3);
        assert_eq!(reader.stats().time_only, 1);
    }

    #[test]
    fn long_lines_are_skipped_not_kept() {
        let mut log = String::from("$IIHDT,10.0,T\n");
        log.push_str(&"x".repeat(10_000));
        log.push_str("\n$IIHDT,20.0,T\n");
        let options = ReadOptions {
            max_line_bytes: 100,
            ..ReadOptions::default()
        };
        let mut reader =
            nmea0183_reader(io::BufReader::with_capacity(16, Cursor::new(log)), options);
        let items: Vec<_> = reader.by_ref().collect();
        // Untimed HDT before any time: rejected as NoTime, which is fine here.
        assert_eq!(items.len(), 3);
        assert_eq!(
            items[1],
            Err(Rejection {
                line: 2,
                reason: RejectReason::LineTooLong { limit: 100 }
            })
        );
        let bound = 2 * 100 + 8 * std::mem::size_of::<Item>();
        assert!(
            reader.buffered_bytes() <= bound,
            "{}",
            reader.buffered_bytes()
        );
    }

    #[test]
    fn io_errors_end_the_reader_with_a_rejection() {
        struct Failing;
        impl io::Read for Failing {
            fn read(&mut self, _: &mut [u8]) -> io::Result<usize> {
                Err(io::Error::new(io::ErrorKind::ConnectionReset, "gone"))
            }
        }
        let mut reader = nmea0183_reader(io::BufReader::new(Failing), ReadOptions::default());
        assert_eq!(
            reader.next(),
            Some(Err(Rejection {
                line: 1,
                reason: RejectReason::Io(io::ErrorKind::ConnectionReset)
            }))
        );
        assert_eq!(reader.next(), None);
        assert_eq!(reader.stats().rejected(RejectKind::Io), 1);
    }

    #[test]
    fn stats_serialise_with_names() {
        let mut stats = ReadStats {
            lines: 3,
            ..ReadStats::default()
        };
        stats.count_record(MeasurementKind::Position);
        stats.count_rejection(RejectKind::BadChecksum);
        let json = serde_json::to_string(&stats).unwrap();
        assert_eq!(
            json,
            r#"{"lines":3,"blank":0,"ignored":0,"empty":0,"time_only":0,"without_checksum":0,"undated":0,"records":{"position":1},"rejected":{"bad_checksum":1}}"#
        );
    }
}
