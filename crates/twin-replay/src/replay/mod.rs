//! Replaying a log over Zenoh: the log is streamed through
//! `twin_wire::LogReader` and `FixAssembler`, and each assembled input is
//! published as the contract's JSON on `{prefix}/{vessel}/gnss` (fixes) or
//! `{prefix}/{vessel}/actuators` (propeller speeds and thrusts), in log time
//! order, with the original time stamps and `replay: true`. An MCAP
//! recording (`twind --record`, `twin analyze --mcap`) is replayed from its
//! input channels (`twin_wire::mcap::input_json_lines`).
//!
//! # Pace
//! The message of log time `t` is published at
//! `wall_start + (t - window_start) / rate`, where `window_start` is the log
//! time `start_offset_s` after the log's first record and `wall_start` the
//! instant the pass began; [`Rate::Max`] never waits. When the replay falls
//! behind (a slow receiver), it publishes at once and does not skip anything
//! to catch up.
//!
//! # Nothing dropped
//! The publishers are declared with `CongestionControl::Block` (and Zenoh's
//! default reliability, reliable): when the network or a subscriber cannot
//! keep up, `put` waits. Zenoh's `put` is synchronous under its `async`
//! surface, so that wait blocks the calling thread: in a process that also
//! drains an in-process subscriber, run the replay on a multi-threaded
//! runtime, or use a callback subscriber.
//!
//! # Nothing published into the void
//! Zenoh sends a put only to the subscribers its session knows of: one
//! published before the daemon has subscribed (a daemon still starting,
//! or one whose subscription has not yet reached this session) is gone.
//! Before its first message the replay therefore waits, up to
//! `wait_for_subscriber_s`, until a subscriber takes its fixes
//! ([`ReplayError::NoSubscriber`] otherwise, with nothing published).
//! `0` publishes at once, to whoever listens.
//!
//! # Window and loops
//! `start_offset_s` and `duration_s` are log seconds from the first record
//! the reader gives. The whole log is still read and assembled from its
//! beginning, so the assembler chooses its sources and pairs its samples
//! exactly as it does without a window; only what is published changes: an
//! output is published when `start <= t - first < start + duration`. Each
//! loop re-opens the log and replays the same window again, with the same
//! time stamps.
//!
//! # What is not published
//! An assembled input the contract cannot carry (a fix without course or
//! speed, a value out of the contract's range) is counted in
//! [`ReplaySummary::skipped`] and logged once per replay, not published.
//!
//! # Cancelling
//! Dropping the future returned by [`replay_log`] or [`replay_reader`] stops
//! the replay between two messages (publishers are undeclared on drop); [`run`]
//! does that on its `shutdown` future and still returns a summary.

mod counting;
mod report;

use std::fs::File;
use std::future::Future;
use std::io::{self, BufRead};
use std::path::Path;
use std::str::FromStr;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use twin_wire::assemble::{Assembled, AssemblerConfig, FixAssembler};
use twin_wire::messages::{ActuatorCommand, encode_actuators, encode_gnss};
use twin_wire::read::OpenError;
use twin_wire::{KeySpace, LogReader, ReadOptions, VesselId};
use zenoh::Session;
use zenoh::bytes::Encoding;
use zenoh::pubsub::Publisher;
use zenoh::qos::CongestionControl;

use counting::Counting;
pub use report::{Progress, Published, ReplaySummary, Skipped};

/// How often [`Progress`] is reported, wall time.
pub const PROGRESS_INTERVAL: Duration = Duration::from_secs(1);

/// In [`Rate::Max`], how many messages are published between two yields to
/// the async runtime (so a replay never starves the runtime's other tasks).
const MAX_RATE_YIELD_EVERY: u64 = 256;

/// How fast to replay.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Rate {
    /// This many times the recorded pace (1 = as recorded). Finite, > 0.
    Factor(f64),
    /// As fast as the receivers keep up, nothing dropped.
    Max,
}

impl Default for Rate {
    fn default() -> Self {
        Rate::Factor(1.0)
    }
}

/// Why a rate does not parse.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RateError {
    /// Neither `max` nor a number.
    #[error("{0:?} is neither a number nor \"max\"")]
    NotANumber(String),
    /// A number that is not finite and greater than zero.
    #[error("rate {0} is not a finite number greater than 0")]
    NotPositive(f64),
}

impl Rate {
    /// Checks that a factor is finite and greater than zero.
    pub fn factor(factor: f64) -> Result<Self, RateError> {
        if factor.is_finite() && factor > 0.0 {
            Ok(Rate::Factor(factor))
        } else {
            Err(RateError::NotPositive(factor))
        }
    }
}

/// `max` (any case) or a number: `1`, `10`, `0.5`.
impl FromStr for Rate {
    type Err = RateError;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let text = text.trim();
        if text.eq_ignore_ascii_case("max") {
            return Ok(Rate::Max);
        }
        let factor: f64 = text
            .parse()
            .map_err(|_| RateError::NotANumber(text.to_owned()))?;
        Rate::factor(factor)
    }
}

impl std::fmt::Display for Rate {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Rate::Factor(x) => write!(f, "{x}"),
            Rate::Max => f.write_str("max"),
        }
    }
}

/// What to replay and how.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayOptions {
    /// The key prefix (`asv` by default).
    pub keys: KeySpace,
    /// The vessel the log is published as.
    pub vessel: VesselId,
    /// The pace.
    pub rate: Rate,
    /// Log seconds after the first record where publishing starts (>= 0).
    pub start_offset_s: f64,
    /// Log seconds published from the start offset (> 0); `None`: to the end.
    pub duration_s: Option<f64>,
    /// Passes over the log: 1 = once, 0 = until cancelled.
    pub loops: u32,
    /// How records become fixes and propeller samples.
    pub assembler: AssemblerConfig,
    /// How long to wait, before publishing anything, for a subscriber to
    /// the fixes (the module doc), s; 0: do not wait.
    pub wait_for_subscriber_s: f64,
}

/// The default of [`ReplayOptions::wait_for_subscriber_s`], s: more than a
/// daemon takes to start and subscribe.
pub const DEFAULT_WAIT_FOR_SUBSCRIBER_S: f64 = 10.0;

impl ReplayOptions {
    /// The whole log once, at the recorded pace, under the default prefix,
    /// with the default assembler.
    pub fn new(vessel: VesselId) -> Self {
        Self {
            keys: KeySpace::default(),
            vessel,
            rate: Rate::default(),
            start_offset_s: 0.0,
            duration_s: None,
            loops: 1,
            assembler: AssemblerConfig::default(),
            wait_for_subscriber_s: DEFAULT_WAIT_FOR_SUBSCRIBER_S,
        }
    }

    /// Checks the numbers: a finite positive rate factor, a finite
    /// non-negative start offset, a finite positive duration, a finite
    /// non-negative wait for a subscriber.
    pub fn validate(&self) -> Result<(), ReplayError> {
        let invalid = |option, value, expected| {
            Err(ReplayError::InvalidOption {
                option,
                value,
                expected,
            })
        };
        if let Rate::Factor(x) = self.rate
            && !(x.is_finite() && x > 0.0)
        {
            return invalid("rate", x, "a finite number greater than 0");
        }
        if !(self.start_offset_s.is_finite() && self.start_offset_s >= 0.0) {
            return invalid("start offset", self.start_offset_s, "finite seconds >= 0");
        }
        if let Some(d) = self.duration_s
            && !(d.is_finite() && d > 0.0)
        {
            return invalid("duration", d, "finite seconds > 0");
        }
        let wait = self.wait_for_subscriber_s;
        if !(wait.is_finite() && wait >= 0.0) {
            return invalid("wait for a subscriber", wait, "finite seconds >= 0");
        }
        Ok(())
    }
}

/// Why a replay failed.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// An option is out of its range (see [`ReplayOptions::validate`]).
    #[error("{option} {value} is invalid: expected {expected}")]
    InvalidOption {
        /// The option.
        option: &'static str,
        /// Its value.
        value: f64,
        /// What it must be.
        expected: &'static str,
    },
    /// The log cannot be opened (missing file, no permission).
    #[error("cannot open the log {name}")]
    Open {
        /// The log's path or name.
        name: String,
        /// The I/O error.
        #[source]
        source: io::Error,
    },
    /// The log opens but cannot be read as a log at all: empty, or none of
    /// its first lines is in a known format.
    #[error("cannot read {name} as a log")]
    Unreadable {
        /// The log's path or name.
        name: String,
        /// The reader's reason.
        #[source]
        source: OpenError,
    },
    /// The Zenoh session cannot be opened ([`run`] only).
    #[error("cannot open the Zenoh session")]
    Session(#[source] zenoh::Error),
    /// A publisher cannot be declared.
    #[error("cannot declare a publisher on {key}")]
    Declare {
        /// Its key.
        key: String,
        /// Zenoh's reason.
        #[source]
        source: zenoh::Error,
    },
    /// No subscriber took the fixes within the wait
    /// ([`ReplayOptions::wait_for_subscriber_s`]); nothing was published.
    #[error(
        "no subscriber on {key} within {waited_s} s, nothing published (is the daemon running and connected? a wait of 0 publishes regardless)"
    )]
    NoSubscriber {
        /// The fixes' key.
        key: String,
        /// How long the replay waited, s.
        waited_s: f64,
    },
    /// Zenoh refused a publication (the session was closed, or an access
    /// control rule denies the key).
    #[error("cannot publish on {key}")]
    Publish {
        /// The key.
        key: String,
        /// Zenoh's reason.
        #[source]
        source: zenoh::Error,
    },
}

/// Replays the log file at `path` on `session` (see the module doc).
/// `progress` is called about once a second and once at the end.
pub async fn replay_log(
    session: &Session,
    path: &Path,
    options: &ReplayOptions,
    progress: impl FnMut(&Progress),
) -> Result<ReplaySummary, ReplayError> {
    let mut summary = ReplaySummary::default();
    let (name, size, open) = file_opener(path);
    Replay::new(options, progress, &mut summary, size)
        .run(session, &name, open)
        .await?;
    Ok(summary)
}

/// Replays the log that `open` gives (called once per pass: it must give
/// the same log each time), e.g. `|| Ok(std::io::Cursor::new(BUNDLED))` for
/// bundled data. `name` appears in errors and in the summary.
pub async fn replay_reader<F, R>(
    session: &Session,
    name: &str,
    open: F,
    options: &ReplayOptions,
    progress: impl FnMut(&Progress),
) -> Result<ReplaySummary, ReplayError>
where
    F: FnMut() -> io::Result<R>,
    R: BufRead,
{
    let mut summary = ReplaySummary::default();
    Replay::new(options, progress, &mut summary, None)
        .run(session, name, open)
        .await?;
    Ok(summary)
}

/// What the binary does: checks that the log at `path` can be read, opens a
/// Zenoh session with `config`, replays, and closes the session. When
/// `shutdown` completes first, the replay stops and the summary so far is
/// returned with [`ReplaySummary::interrupted`] set.
pub async fn run(
    config: zenoh::Config,
    path: &Path,
    options: &ReplayOptions,
    progress: impl FnMut(&Progress),
    shutdown: impl Future<Output = ()>,
) -> Result<ReplaySummary, ReplayError> {
    options.validate()?;
    let (name, size, mut open) = file_opener(path);
    // Refuse an unreadable log before touching the network.
    open_log(&name, &mut open)?;
    let session = zenoh::open(config).await.map_err(ReplayError::Session)?;
    let started = Instant::now();
    let mut summary = ReplaySummary::default();
    let (result, interrupted) = {
        let replay = Replay::new(options, progress, &mut summary, size).run(&session, &name, open);
        tokio::select! {
            result = replay => (result, false),
            () = shutdown => (Ok(()), true),
        }
    };
    if interrupted {
        summary.interrupted = true;
        summary.wall = started.elapsed();
    }
    // Closing drains what is still queued for the network.
    if let Err(error) = session.close().await {
        tracing::warn!(%error, "closing the Zenoh session failed");
    }
    result.map(|()| summary)
}

type FileOpener = Box<dyn FnMut() -> io::Result<Box<dyn BufRead + Send>> + Send>;

/// Opens the log at `path` for each pass: an MCAP recording as its input
/// channels (`twin_wire::mcap::open_log_file`), whose size in bytes is not
/// what the reader consumes (so none is given for progress).
fn file_opener(path: &Path) -> (String, Option<u64>, FileOpener) {
    let is_mcap = File::open(path)
        .and_then(|mut f| {
            let mut magic = [0u8; 8];
            io::Read::read_exact(&mut f, &mut magic).map(|()| &magic == twin_wire::mcap::MAGIC)
        })
        .unwrap_or(false);
    let size = if is_mcap {
        None
    } else {
        std::fs::metadata(path).ok().map(|m| m.len())
    };
    let owned = path.to_owned();
    let open: FileOpener = Box::new(move || twin_wire::mcap::open_log_file(&owned));
    (path.display().to_string(), size, open)
}

/// Opens one pass over the log, counting the bytes it consumes.
fn open_log<F, R>(
    name: &str,
    open: &mut F,
) -> Result<(LogReader<Counting<R>>, Arc<AtomicU64>), ReplayError>
where
    F: FnMut() -> io::Result<R>,
    R: BufRead,
{
    let input = open().map_err(|source| ReplayError::Open {
        name: name.to_owned(),
        source,
    })?;
    let bytes = Arc::new(AtomicU64::new(0));
    let reader = LogReader::open(Counting::new(input, bytes.clone()), ReadOptions::default())
        .map_err(|source| ReplayError::Unreadable {
            name: name.to_owned(),
            source,
        })?;
    Ok((reader, bytes))
}

async fn declare(session: &Session, key: String) -> Result<Publisher<'static>, ReplayError> {
    match session
        .declare_publisher(key.clone())
        .congestion_control(CongestionControl::Block)
        .encoding(Encoding::APPLICATION_JSON)
        .await
    {
        Ok(publisher) => Ok(publisher),
        Err(source) => Err(ReplayError::Declare { key, source }),
    }
}

/// Waits up to `wait_s` until `publisher` (on `key`) has a subscriber
/// (the module doc); at once when `wait_s` is 0.
async fn wait_for_subscriber(
    publisher: &Publisher<'static>,
    key: &str,
    wait_s: f64,
) -> Result<(), ReplayError> {
    if wait_s <= 0.0 {
        return Ok(());
    }
    let matched = || async {
        publisher
            .matching_status()
            .await
            .is_ok_and(|m| m.matching())
    };
    if matched().await {
        return Ok(());
    }
    tracing::info!(key, "waiting up to {wait_s} s for a subscriber");
    let deadline = Instant::now() + Duration::from_secs_f64(wait_s);
    while Instant::now() < deadline {
        tokio::time::sleep(SUBSCRIBER_POLL).await;
        if matched().await {
            return Ok(());
        }
    }
    Err(ReplayError::NoSubscriber {
        key: key.to_owned(),
        waited_s: wait_s,
    })
}

/// How often [`wait_for_subscriber`] looks.
const SUBSCRIBER_POLL: Duration = Duration::from_millis(20);

/// One replay in progress: the options, the counts, the clocks.
struct Replay<'a, P> {
    options: &'a ReplayOptions,
    progress: P,
    summary: &'a mut ReplaySummary,
    size_bytes: Option<u64>,
    started: Instant,
    next_report: Instant,
    /// Index of the pass under way, from 0.
    pass: u32,
    /// Bytes of the log consumed in this pass.
    bytes_read: Arc<AtomicU64>,
    /// Time of this pass's first record.
    first_record_s: Option<f64>,
    /// Time of the latest message published.
    last_published_s: Option<f64>,
    published_since_yield: u64,
    warned_gnss: bool,
    warned_actuators: bool,
}

/// The two publishers and their keys.
struct Outputs {
    gnss: Publisher<'static>,
    gnss_key: String,
    actuators: Publisher<'static>,
    actuators_key: String,
}

impl<'a, P: FnMut(&Progress)> Replay<'a, P> {
    fn new(
        options: &'a ReplayOptions,
        progress: P,
        summary: &'a mut ReplaySummary,
        size_bytes: Option<u64>,
    ) -> Self {
        let started = Instant::now();
        Self {
            options,
            progress,
            summary,
            size_bytes,
            started,
            next_report: started + PROGRESS_INTERVAL,
            pass: 0,
            bytes_read: Arc::new(AtomicU64::new(0)),
            first_record_s: None,
            last_published_s: None,
            published_since_yield: 0,
            warned_gnss: false,
            warned_actuators: false,
        }
    }

    async fn run<F, R>(
        mut self,
        session: &Session,
        name: &str,
        mut open: F,
    ) -> Result<(), ReplayError>
    where
        F: FnMut() -> io::Result<R>,
        R: BufRead,
    {
        self.options.validate()?;
        self.summary.name = name.to_owned();
        // Open the log before declaring anything: an unreadable log fails
        // without a trace on the network.
        let mut log = Some(open_log(name, &mut open)?);
        let outputs = Outputs {
            gnss: declare(session, self.options.keys.gnss(&self.options.vessel)).await?,
            gnss_key: self.options.keys.gnss(&self.options.vessel),
            actuators: declare(session, self.options.keys.actuators(&self.options.vessel)).await?,
            actuators_key: self.options.keys.actuators(&self.options.vessel),
        };
        wait_for_subscriber(
            &outputs.gnss,
            &outputs.gnss_key,
            self.options.wait_for_subscriber_s,
        )
        .await?;
        loop {
            let (reader, bytes_read) = match log.take() {
                Some(opened) => opened,
                None => open_log(name, &mut open)?,
            };
            self.summary.format = Some(reader.format());
            self.bytes_read = bytes_read;
            self.first_record_s = None;
            let before = self.summary.published.total();
            self.play_pass(reader, &outputs).await?;
            self.summary.passes += 1;
            self.pass += 1;
            let last = self.options.loops != 0 && self.pass >= self.options.loops;
            // A pass that published nothing will not publish anything the
            // next time either: stop instead of spinning forever.
            if last || self.summary.published.total() == before {
                break;
            }
        }
        self.summary.wall = self.started.elapsed();
        let report = self.report(true);
        (self.progress)(&report);
        Ok(())
    }

    /// One pass over the log.
    async fn play_pass<R: BufRead>(
        &mut self,
        mut reader: LogReader<R>,
        outputs: &Outputs,
    ) -> Result<(), ReplayError> {
        let mut assembler = FixAssembler::new(self.options.assembler);
        let mut ready: Vec<Assembled> = Vec::new();
        let pass_start = Instant::now();
        let mut reading = true;
        'pass: while reading {
            match reader.next() {
                Some(Ok(record)) => {
                    self.first_record_s.get_or_insert(record.time_s);
                    assembler.push(record, &mut ready);
                }
                // Counted by the reader, reported in the summary.
                Some(Err(_)) => {}
                None => {
                    assembler.finish(&mut ready);
                    reading = false;
                }
            }
            for input in ready.drain(..) {
                let Some(first_s) = self.first_record_s else {
                    continue;
                };
                let offset_s = input.time_s() - first_s;
                if offset_s < self.options.start_offset_s {
                    continue;
                }
                if let Some(d) = self.options.duration_s
                    && offset_s >= self.options.start_offset_s + d
                {
                    break 'pass;
                }
                self.wait_for(pass_start, offset_s - self.options.start_offset_s)
                    .await;
                self.publish(input, outputs).await?;
            }
        }
        self.summary.read_stats = reader.stats().clone();
        self.summary.assemble_stats = assembler.stats().clone();
        Ok(())
    }

    /// Waits until the wall time of a message `since_start_s` log seconds
    /// after the window start, reporting progress meanwhile.
    async fn wait_for(&mut self, pass_start: Instant, since_start_s: f64) {
        let Rate::Factor(rate) = self.options.rate else {
            self.report_if_due();
            self.published_since_yield += 1;
            if self.published_since_yield >= MAX_RATE_YIELD_EVERY {
                self.published_since_yield = 0;
                tokio::task::yield_now().await;
            }
            return;
        };
        let deadline = Duration::try_from_secs_f64((since_start_s / rate).max(0.0))
            .ok()
            .and_then(|d| pass_start.checked_add(d));
        loop {
            self.report_if_due();
            let now = Instant::now();
            let until = match deadline {
                Some(d) if d <= now => return,
                Some(d) => d.min(self.next_report),
                // Beyond what an Instant holds: wait report by report.
                None => self.next_report,
            };
            tokio::time::sleep_until(until.into()).await;
        }
    }

    async fn publish(&mut self, input: Assembled, outputs: &Outputs) -> Result<(), ReplayError> {
        let time_s = input.time_s();
        let (encoded, publisher, key, is_gnss) = match input {
            Assembled::Fix(fix) => (
                encode_gnss(&fix, true),
                &outputs.gnss,
                &outputs.gnss_key,
                true,
            ),
            Assembled::Propellers(speeds) => (
                encode_actuators(&ActuatorCommand::Speeds(speeds), true),
                &outputs.actuators,
                &outputs.actuators_key,
                false,
            ),
            Assembled::Thrust(thrust) => (
                encode_actuators(&ActuatorCommand::Thrust(thrust), true),
                &outputs.actuators,
                &outputs.actuators_key,
                false,
            ),
        };
        let payload = match encoded {
            Ok(payload) => payload,
            Err(error) => {
                let (count, warned) = if is_gnss {
                    (&mut self.summary.skipped.gnss, &mut self.warned_gnss)
                } else {
                    (
                        &mut self.summary.skipped.actuators,
                        &mut self.warned_actuators,
                    )
                };
                *count += 1;
                if !std::mem::replace(warned, true) {
                    tracing::warn!(
                        key = %key, time_s, %error,
                        "not publishing an input the contract cannot carry (logged once, all counted)"
                    );
                }
                return Ok(());
            }
        };
        publisher
            .put(payload)
            .await
            .map_err(|source| ReplayError::Publish {
                key: key.clone(),
                source,
            })?;
        if is_gnss {
            self.summary.published.gnss += 1;
        } else {
            self.summary.published.actuators += 1;
        }
        self.last_published_s = Some(time_s);
        let first = self.summary.first_published_s.get_or_insert(time_s);
        *first = first.min(time_s);
        let last = self.summary.last_published_s.get_or_insert(time_s);
        *last = last.max(time_s);
        Ok(())
    }

    fn report_if_due(&mut self) {
        let now = Instant::now();
        if now >= self.next_report {
            self.next_report = now + PROGRESS_INTERVAL;
            let report = self.report(false);
            (self.progress)(&report);
        }
    }

    fn report(&self, finished: bool) -> Progress {
        let pass_fraction = if finished {
            Some(1.0)
        } else if let Some(d) = self.options.duration_s {
            let done = match (self.last_published_s, self.first_record_s) {
                (Some(t), Some(first)) => t - first - self.options.start_offset_s,
                _ => 0.0,
            };
            Some((done / d).clamp(0.0, 1.0))
        } else {
            self.size_bytes.map(|size| {
                if size == 0 {
                    1.0
                } else {
                    (self.bytes_read.load(Ordering::Relaxed) as f64 / size as f64).min(1.0)
                }
            })
        };
        let fraction = match (self.options.loops, pass_fraction) {
            (0, _) | (_, None) => None,
            (_, Some(_)) if finished => Some(1.0),
            (loops, Some(f)) => Some(((f64::from(self.pass) + f) / f64::from(loops)).min(1.0)),
        };
        Progress {
            pass: self.pass,
            loops: self.options.loops,
            log_time_s: self.last_published_s,
            log_offset_s: self
                .last_published_s
                .zip(self.first_record_s)
                .map(|(t, first)| t - first),
            fraction,
            pass_fraction,
            published: self.summary.published,
            wall: self.started.elapsed(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rates_parse() {
        assert_eq!("max".parse(), Ok(Rate::Max));
        assert_eq!("MAX".parse(), Ok(Rate::Max));
        assert_eq!("10".parse(), Ok(Rate::Factor(10.0)));
        assert_eq!("0.5".parse(), Ok(Rate::Factor(0.5)));
        assert_eq!("0".parse::<Rate>(), Err(RateError::NotPositive(0.0)));
        assert_eq!("-2".parse::<Rate>(), Err(RateError::NotPositive(-2.0)));
        assert!(matches!(
            "inf".parse::<Rate>(),
            Err(RateError::NotPositive(_))
        ));
        assert!(matches!(
            "NaN".parse::<Rate>(),
            Err(RateError::NotPositive(_))
        ));
        assert_eq!(
            "fast".parse::<Rate>(),
            Err(RateError::NotANumber("fast".into()))
        );
        assert_eq!(Rate::Max.to_string().parse(), Ok(Rate::Max));
        assert_eq!(Rate::Factor(2.5).to_string().parse(), Ok(Rate::Factor(2.5)));
    }

    #[test]
    fn options_are_validated() {
        let base = ReplayOptions::new(VesselId::new("v").unwrap());
        assert!(base.validate().is_ok());
        for bad in [
            ReplayOptions {
                rate: Rate::Factor(0.0),
                ..base.clone()
            },
            ReplayOptions {
                rate: Rate::Factor(f64::NAN),
                ..base.clone()
            },
            ReplayOptions {
                start_offset_s: -1.0,
                ..base.clone()
            },
            ReplayOptions {
                start_offset_s: f64::INFINITY,
                ..base.clone()
            },
            ReplayOptions {
                duration_s: Some(0.0),
                ..base.clone()
            },
            ReplayOptions {
                wait_for_subscriber_s: -1.0,
                ..base.clone()
            },
            ReplayOptions {
                wait_for_subscriber_s: f64::NAN,
                ..base.clone()
            },
        ] {
            assert!(
                matches!(bad.validate(), Err(ReplayError::InvalidOption { .. })),
                "{bad:?}"
            );
        }
    }
}
