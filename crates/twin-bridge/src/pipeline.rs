//! One source's path from bytes to published payloads: the bytes are cut
//! into lines (or MAVLink frames), each goes through `twin_wire`'s decoder
//! of the format (the very decoders `twin analyze` and `twin-replay` read
//! logs with), the records through a `FixAssembler`, and each assembled
//! fix, propeller pair or thrust is encoded as the contract's payload and
//! published. NMEA 0183 sources can instead forward the sentences that
//! decode, as they came, on `{prefix}/{vessel}/nmea`.
//!
//! # Time
//! Each decoder is live (`Clock::Receiver`): it is told when each line was
//! received and stamps with that time only what has no time of its own
//! (NMEA 2000 frames, MAVLink before the vehicle's clock is known, a gpsd
//! report without `time`). A published input whose time is such a receive
//! time says so: `"time_source":"receiver"`. An NMEA 0183 time of day with
//! no date yet takes the date of the receiving computer's clock. When a
//! source moves from receive times to a clock of its own (MAVLink once the
//! vehicle's clock is known), the two need not agree: the decoder starts a
//! new time line, and the pipeline a new assembler (what was pending is
//! published first).
//!
//! # Never malformed, nothing decodable lost
//! What is published is what the contract's own encoders make, and they
//! encode only what their decoders accept; an assembled input the contract
//! cannot carry (a fix without course or speed) is counted by reason and
//! not published. Every line that does not decode is counted by reason.
//! Publishing blocks rather than drops (see [`crate::output`]).
//!
//! # A quiet source
//! A fix is complete when a record with a later time arrives. A source that
//! goes quiet for `idle_flush` (default 200 ms; bursts of one epoch come
//! within milliseconds) has its pending fix published then, so a 1 Hz
//! receiver's fix does not wait a second for the next one.

use std::collections::VecDeque;
use std::sync::Arc;
use std::time::{Duration, Instant};

use twin_wire::assemble::{Assembled, AssemblerConfig, FixAssembler};
use twin_wire::messages::{
    ActuatorCommand, TimeSource, encode_actuators_stamped, encode_gnss_stamped,
};
use twin_wire::read::mavlink::{FrameEvent, MavlinkDecoder, MavlinkFramer};
use twin_wire::read::{
    AnyDecoder, Decoder, Item, LogFormat, N2kRawDecoder, RawFormat, ReadOptions, RejectReason,
};

use crate::output::{Key, Sink};
use crate::spec::{Format, NmeaPublish};
use crate::stats::Counter;

/// How long a source must be quiet before its pending fix is published.
pub const DEFAULT_IDLE_FLUSH: Duration = Duration::from_millis(200);

/// The most receive-stamped record times remembered while their inputs
/// are being assembled.
const MAX_STAMPS: usize = 100_000;

/// How a pipeline decodes and assembles.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PipelineConfig {
    /// The decoders' options (live: `Clock::Receiver`).
    pub read: ReadOptions,
    /// The assembler's settings.
    pub assembler: AssemblerConfig,
    /// NMEA 0183: fixes or sentences.
    pub nmea_publish: NmeaPublish,
    /// Quiet time after which a pending fix is published.
    pub idle_flush: Duration,
}

enum Decoding {
    /// Line formats: NMEA 0183, candump, YDRAW, Actisense, gpsd.
    Lines {
        decoder: AnyDecoder,
        /// The line being received on a stream.
        buf: Vec<u8>,
        /// The line being received is over the limit: skip to its end.
        too_long: bool,
    },
    /// MAVLink frames found in the bytes.
    Mavlink {
        decoder: MavlinkDecoder,
        framer: MavlinkFramer,
    },
    /// CAN frames from a SocketCAN interface.
    Can { decoder: N2kRawDecoder },
}

/// Everything but the decoder.
struct Core {
    config: PipelineConfig,
    line_no: u64,
    items: Vec<Item>,
    assembler: FixAssembler,
    ready: Vec<Assembled>,
    /// Times of the records stamped with their receive time, oldest first.
    stamps: VecDeque<f64>,
    /// Sentences to forward (sentences mode), `\r\n`-terminated.
    sentences: Vec<u8>,
    sink: Arc<dyn Sink>,
    counter: Arc<Counter>,
    last_data: Option<Instant>,
    flushed: bool,
    /// The latest line decoded without a refusal.
    last_line_clean: bool,
    /// The time of the latest record.
    latest_record_s: Option<f64>,
}

/// One source's decoder, assembler and counters.
pub struct Pipeline {
    decoding: Decoding,
    core: Core,
}

impl Pipeline {
    /// A pipeline for a source of `format` publishing to `sink`.
    pub fn new(
        format: Format,
        config: PipelineConfig,
        sink: Arc<dyn Sink>,
        counter: Arc<Counter>,
        can: bool,
    ) -> Self {
        let read = config.read;
        let lines = |f: LogFormat| Decoding::Lines {
            decoder: AnyDecoder::new(f, read),
            buf: Vec::new(),
            too_long: false,
        };
        let decoding = match format {
            Format::Nmea0183 => lines(LogFormat::Nmea0183),
            Format::Candump if can => Decoding::Can {
                decoder: N2kRawDecoder::new(RawFormat::Candump, read),
            },
            Format::Candump => lines(LogFormat::Candump),
            Format::YdRaw => lines(LogFormat::YdRaw),
            Format::Actisense => lines(LogFormat::ActisenseAscii),
            Format::Gpsd => lines(LogFormat::GpsdJson),
            Format::Mavlink => Decoding::Mavlink {
                decoder: MavlinkDecoder::new(read, false),
                framer: MavlinkFramer::new(false),
            },
        };
        let sentences_mode =
            format == Format::Nmea0183 && config.nmea_publish == NmeaPublish::Sentences;
        Self {
            decoding,
            core: Core {
                config: PipelineConfig {
                    nmea_publish: if sentences_mode {
                        NmeaPublish::Sentences
                    } else {
                        NmeaPublish::Fixes
                    },
                    ..config
                },
                line_no: 0,
                items: Vec::new(),
                assembler: FixAssembler::new(config.assembler),
                ready: Vec::new(),
                stamps: VecDeque::new(),
                sentences: Vec::new(),
                sink,
                counter,
                last_data: None,
                flushed: true,
                last_line_clean: true,
                latest_record_s: None,
            },
        }
    }

    /// Bytes received at `received_s` (seconds since the epoch). A
    /// `datagram` is whole: a line or frame does not continue in the next.
    pub fn on_bytes(&mut self, bytes: &[u8], received_s: f64, datagram: bool) {
        self.core.counter.lock().bytes += bytes.len() as u64;
        self.core.data_arrived();
        match &mut self.decoding {
            Decoding::Lines {
                decoder,
                buf,
                too_long,
            } => {
                let limit = self.core.config.read.max_line_bytes;
                let mut rest = bytes;
                while let Some(i) = rest.iter().position(|&b| b == b'\n') {
                    Self::add(buf, too_long, &rest[..i], limit);
                    self.core.end_line(decoder, buf, too_long, received_s);
                    rest = &rest[i + 1..];
                }
                Self::add(buf, too_long, rest, limit);
                if datagram && (!buf.is_empty() || *too_long) {
                    self.core.end_line(decoder, buf, too_long, received_s);
                }
                self.core.sync(decoder.stats());
            }
            Decoding::Mavlink { decoder, framer } => {
                framer.push(bytes);
                loop {
                    let event = if datagram {
                        framer.drain_event()
                    } else {
                        framer.next_event()
                    };
                    match event {
                        Some(FrameEvent::Frame(frame)) => {
                            self.core.decode(decoder, frame, received_s)
                        }
                        Some(FrameEvent::Skipped { reason, .. }) => {
                            self.core.line_no += 1;
                            decoder.reject_line(self.core.line_no, reason, &mut self.core.items);
                            self.core.take_items(false);
                        }
                        None => break,
                    }
                }
                self.core.sync(decoder.stats());
            }
            Decoding::Can { decoder } => {
                // A CAN source given bytes: not possible by construction.
                self.core.line_no += 1;
                decoder.reject_line(
                    self.core.line_no,
                    RejectReason::UnknownFormat,
                    &mut self.core.items,
                );
                self.core.take_items(false);
                self.core.sync(decoder.stats());
            }
        }
        self.core.publish_ready();
    }

    /// One CAN frame read from a SocketCAN interface at `received_s`.
    pub fn on_can_frame(&mut self, raw_id: u32, extended: bool, data: &[u8], received_s: f64) {
        let Decoding::Can { decoder } = &mut self.decoding else {
            return;
        };
        self.core.counter.lock().bytes += data.len() as u64;
        self.core.data_arrived();
        self.core.line_no += 1;
        decoder.set_receive_time(received_s);
        decoder.decode_can_frame(
            raw_id,
            extended,
            data,
            self.core.line_no,
            &mut self.core.items,
        );
        let stamped = decoder.receiver_stamped();
        self.core.take_items(stamped);
        self.core.sync(decoder.stats());
        self.core.publish_ready();
    }

    /// Time passes with nothing received: publishes the pending fix once
    /// the source has been quiet for `idle_flush`.
    pub fn on_idle(&mut self, now: Instant) {
        let core = &mut self.core;
        if core.flushed
            || core
                .last_data
                .is_some_and(|t| now.saturating_duration_since(t) < core.config.idle_flush)
        {
            return;
        }
        core.flushed = true;
        core.assembler.flush_idle(&mut core.ready);
        core.publish_ready();
    }

    /// The connection was lost: a line or frame cut in the middle is
    /// dropped (not decoded as if whole).
    pub fn on_disconnect(&mut self) {
        match &mut self.decoding {
            Decoding::Lines { buf, too_long, .. } => {
                buf.clear();
                *too_long = false;
            }
            Decoding::Mavlink { framer, .. } => *framer = MavlinkFramer::new(false),
            Decoding::Can { .. } => {}
        }
    }

    /// The source has ended (stdin closed, shutdown): publishes what is
    /// still being assembled.
    pub fn finish(&mut self) {
        if let Decoding::Lines {
            decoder,
            buf,
            too_long,
        } = &mut self.decoding
            && (!buf.is_empty() || *too_long)
        {
            let received_s = crate::now_s();
            self.core.end_line(decoder, buf, too_long, received_s);
            self.core.sync(decoder.stats());
        }
        let core = &mut self.core;
        core.assembler.finish(&mut core.ready);
        core.publish_ready();
    }

    /// The MAVLink system followed, once known.
    pub fn mavlink_system(&self) -> Option<u8> {
        match &self.decoding {
            Decoding::Mavlink { decoder, .. } => decoder.system(),
            _ => None,
        }
    }

    fn add(buf: &mut Vec<u8>, too_long: &mut bool, bytes: &[u8], limit: usize) {
        if *too_long {
            return;
        }
        if buf.len() + bytes.len() > limit {
            *too_long = true;
            buf.clear();
        } else {
            buf.extend_from_slice(bytes);
        }
    }
}

impl Core {
    fn data_arrived(&mut self) {
        self.last_data = Some(Instant::now());
        self.flushed = false;
    }

    /// Decodes the line in `buf` (or refuses it as too long) and clears it.
    fn end_line(
        &mut self,
        decoder: &mut AnyDecoder,
        buf: &mut Vec<u8>,
        too_long: &mut bool,
        received_s: f64,
    ) {
        if std::mem::take(too_long) {
            self.line_no += 1;
            let limit = self.config.read.max_line_bytes;
            decoder.reject_line(
                self.line_no,
                RejectReason::LineTooLong { limit },
                &mut self.items,
            );
            self.take_items(false);
        } else if !buf.trim_ascii().is_empty() {
            let ignored = decoder.stats().ignored;
            self.decode(decoder, buf, received_s);
            let forward = self.config.nmea_publish == NmeaPublish::Sentences
                && decoder.stats().ignored == ignored
                && self.last_line_clean;
            if forward {
                self.sentences.extend_from_slice(buf.trim_ascii());
                self.sentences.extend_from_slice(b"\r\n");
            }
        }
        buf.clear();
    }

    fn decode(&mut self, decoder: &mut dyn Decoder, line: &[u8], received_s: f64) {
        self.line_no += 1;
        decoder.set_receive_time(received_s);
        decoder.decode_line(line, self.line_no, &mut self.items);
        let stamped = decoder.receiver_stamped();
        self.take_items(stamped);
    }

    /// Hands the decoded records to the assembler and counts refusals.
    fn take_items(&mut self, stamped: bool) {
        self.last_line_clean = true;
        let sentences = self.config.nmea_publish == NmeaPublish::Sentences;
        for item in self.items.drain(..) {
            match item {
                Ok(record) => {
                    if sentences {
                        continue;
                    }
                    let tolerance = self.config.read.backwards_tolerance_s;
                    if self
                        .latest_record_s
                        .is_some_and(|t| record.time_s < t - tolerance)
                    {
                        // The decoder let time go back: its source moved to
                        // another clock (the vehicle's after receive
                        // times). A new time line needs a new assembler.
                        self.assembler.finish(&mut self.ready);
                        self.assembler = FixAssembler::new(self.config.assembler);
                        self.stamps.clear();
                    }
                    self.latest_record_s = Some(record.time_s);
                    if stamped {
                        if self.stamps.len() == MAX_STAMPS {
                            self.stamps.pop_front();
                        }
                        self.stamps.push_back(record.time_s);
                    }
                    self.assembler.push(record, &mut self.ready);
                }
                Err(rejection) => {
                    self.last_line_clean = false;
                    self.counter
                        .reject(rejection.reason.kind().name(), &rejection.reason);
                }
            }
        }
    }

    /// Copies the decoder's counts.
    fn sync(&mut self, stats: &twin_wire::ReadStats) {
        let mut s = self.counter.lock();
        s.lines = stats.lines;
        s.ignored = stats.ignored;
        for (kind, n) in stats.records_by_kind() {
            match s.records.get_mut(kind.name()) {
                Some(count) => *count = n,
                None => {
                    s.records.insert(kind.name().to_owned(), n);
                }
            }
        }
    }

    /// Whether an input of time `time_s` was stamped with a receive time.
    fn receiver_stamped(&mut self, time_s: f64) -> bool {
        // Older stamps than a minute before the input will not be asked.
        while self.stamps.front().is_some_and(|t| *t < time_s - 60.0) {
            self.stamps.pop_front();
        }
        self.stamps.iter().any(|t| *t == time_s)
    }

    /// Publishes the assembled inputs and forwarded sentences.
    fn publish_ready(&mut self) {
        let ready = std::mem::take(&mut self.ready);
        for input in &ready {
            let stamped = self.receiver_stamped(input.time_s());
            let time_source = if stamped {
                TimeSource::Receiver
            } else {
                TimeSource::Source
            };
            let (key, encoded) = match *input {
                Assembled::Fix(fix) => (Key::Gnss, encode_gnss_stamped(&fix, false, time_source)),
                Assembled::Propellers(p) => (
                    Key::Actuators,
                    encode_actuators_stamped(&ActuatorCommand::Speeds(p), false, time_source),
                ),
                Assembled::Thrust(t) => (
                    Key::Actuators,
                    encode_actuators_stamped(&ActuatorCommand::Thrust(t), false, time_source),
                ),
            };
            match encoded {
                Ok(payload) => {
                    if self.put(key, payload) {
                        self.counter.lock().receiver_stamped += u64::from(stamped);
                    }
                }
                Err(error) => {
                    *self
                        .counter
                        .lock()
                        .not_published
                        .entry(error.reason().to_owned())
                        .or_default() += 1;
                    self.counter.log(
                        error.reason(),
                        &format_args!("not published (the contract cannot carry it): {error}"),
                    );
                }
            }
        }
        self.ready = ready;
        self.ready.clear();
        if !self.sentences.is_empty() {
            let payload = std::mem::take(&mut self.sentences);
            self.put(Key::Nmea, payload);
        }
    }

    fn put(&mut self, key: Key, payload: Vec<u8>) -> bool {
        match self.sink.put(key, payload) {
            Ok(()) => {
                let mut s = self.counter.lock();
                match key {
                    Key::Gnss => s.published.gnss += 1,
                    Key::Actuators => s.published.actuators += 1,
                    Key::Nmea => s.published.nmea += 1,
                    Key::Stats => {}
                }
                true
            }
            Err(error) => {
                self.counter.reject(
                    "publish_failed",
                    &format_args!("publishing failed: {error}"),
                );
                false
            }
        }
    }
}
