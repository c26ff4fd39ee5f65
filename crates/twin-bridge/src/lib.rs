//! `twin-bridge`: the onboard bridge. Runs on the vessel's computer, reads
//! the boat's own sources live (NMEA 0183, NMEA 2000, MAVLink, gpsd) and
//! publishes them over Zenoh as the contract's payloads of one vessel
//! (`{prefix}/{vessel}/gnss`, `/actuators`, `/nmea`), with its counts on
//! `{prefix}/{vessel}/bridge/stats`.
//!
//! # Layout
//! - [`spec`]: what `--source` says (format, transport, options).
//! - [`transport`]: reading a source (UDP, TCP with reconnect, serial,
//!   stdin, SocketCAN), one thread each, faults retried with a backoff.
//! - [`pipeline`]: bytes -> `twin_wire`'s decoder of the format -> records
//!   -> `FixAssembler` -> the contract's encoders -> a [`output::Sink`].
//! - [`output`]: the Zenoh publishers (the shared `twin-zenoh` flags open
//!   the session).
//! - [`stats`]: counts per source and reason; the stderr lines and the
//!   stats payload.
//! - [`mavlink_config`]: the MAVLink motors and PWM -> thrust map (TOML).
//! - [`bench`]: `twin-bridge bench`, sentences forwarded per second.
//!
//! # Invariants
//! - One decoder per format, in `twin-wire`, shared with `twin analyze` and
//!   `twin-replay`: a boat's stream through the bridge and the same stream
//!   as a log file give the same records.
//! - Nothing from a source stops the bridge; every refusal is counted by
//!   reason and logged at most once a minute per reason and source.
//! - What is published decodes (the contract's encoders check it); the
//!   publishers block rather than drop.
//! - `replay` is false (the data is live); `time_source` is `receiver` on
//!   what the bridge had to stamp with the time it received it.

pub mod bench;
pub mod mavlink_config;
pub mod output;
pub mod pipeline;
pub mod spec;
pub mod stats;
pub mod transport;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use twin_wire::assemble::AssemblerConfig;
use twin_wire::read::{Clock, ReadOptions};
use twin_wire::time::split_date_time_ms;
use twin_wire::{KeySpace, VesselId};

use output::{Key, Sink};
use pipeline::{DEFAULT_IDLE_FLUSH, Pipeline, PipelineConfig};
use spec::{SourceSpec, Transport};
use stats::{BridgeStats, Counter};
use transport::Event;

/// Seconds since the Unix epoch, now.
pub fn now_s() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

/// The longest line kept from a text source other than gpsd, bytes.
pub const MAX_TEXT_LINE_BYTES: usize = 4096;

/// How often the counts are reported.
pub const STATS_EVERY: Duration = Duration::from_secs(1);

/// What a bridge runs.
#[derive(Debug, Clone)]
pub struct BridgeConfig {
    /// The key prefix.
    pub keys: KeySpace,
    /// The vessel published as.
    pub vessel: VesselId,
    /// The sources, each on its own thread.
    pub sources: Vec<SourceSpec>,
    /// The decoders' options; the bridge makes them live
    /// (`Clock::Receiver`, today's date for NMEA 0183 times of day).
    pub read: ReadOptions,
    /// The assembler's settings (live default: sources chosen on the first
    /// second, as the daemon does).
    pub assembler: AssemblerConfig,
    /// Quiet time after which a pending fix is published.
    pub idle_flush: Duration,
}

impl BridgeConfig {
    /// The defaults for `vessel` reading `sources`.
    pub fn new(vessel: VesselId, sources: Vec<SourceSpec>) -> Self {
        Self {
            keys: KeySpace::default(),
            vessel,
            sources,
            read: ReadOptions::default(),
            assembler: AssemblerConfig {
                decision_window_s: 1.0,
                ..AssemblerConfig::default()
            },
            idle_flush: DEFAULT_IDLE_FLUSH,
        }
    }
}

pub(crate) fn pipeline_config(config: &BridgeConfig, spec: &SourceSpec) -> PipelineConfig {
    let mut read = config.read;
    read.clock = Clock::Receiver;
    if let Ok((date, _)) = split_date_time_ms(now_s()) {
        read.assumed_date = Some(date);
    }
    if spec.mavlink_system.is_some() {
        read.mavlink.system = spec.mavlink_system;
    }
    if spec.format != spec::Format::Gpsd {
        // An NMEA sentence is at most 82 characters, a gateway's line of
        // a whole NMEA 2000 message under 4 KiB; gpsd's sky reports are
        // long and keep the readers' default.
        read.max_line_bytes = read.max_line_bytes.min(MAX_TEXT_LINE_BYTES);
    }
    PipelineConfig {
        read,
        assembler: config.assembler,
        nmea_publish: spec.nmea_publish,
        idle_flush: config.idle_flush,
    }
}

/// Runs the bridge until `stop` is set or every source has ended (only
/// standard input ends): one thread per source; the counts go to
/// `progress` and to the stats key every [`STATS_EVERY`]. Returns the
/// final counts.
pub fn run(
    config: &BridgeConfig,
    sink: Arc<dyn Sink>,
    stop: Arc<AtomicBool>,
    mut progress: impl FnMut(&BridgeStats),
) -> anyhow::Result<BridgeStats> {
    let started = Instant::now();
    let mut counters = Vec::new();
    let mut threads = Vec::new();
    for spec in &config.sources {
        let counter = Counter::new(&spec.name, spec.format.name(), spec.transport.name());
        counters.push(counter.clone());
        let mut pipeline = Pipeline::new(
            spec.format,
            pipeline_config(config, spec),
            sink.clone(),
            counter.clone(),
            matches!(spec.transport, Transport::Can { .. }),
        );
        let spec = spec.clone();
        let stop = stop.clone();
        let thread = std::thread::Builder::new()
            .name(format!("source {}", spec.name))
            .spawn(move || {
                let result = transport::run(&spec, &stop, &mut |event| match event {
                    Event::Connected(what) => counter.connected(&what),
                    Event::Disconnected { reason, detail } => {
                        counter.disconnected(reason, &detail);
                        pipeline.on_disconnect();
                    }
                    Event::Bytes {
                        bytes,
                        received_s,
                        datagram,
                    } => pipeline.on_bytes(bytes, received_s, datagram),
                    Event::CanFrame {
                        id,
                        extended,
                        data,
                        received_s,
                    } => pipeline.on_can_frame(id, extended, data, received_s),
                    Event::Idle => pipeline.on_idle(Instant::now()),
                });
                pipeline.finish();
                result
            })?;
        threads.push(thread);
    }
    let snapshot = |counters: &[Arc<Counter>]| BridgeStats {
        vessel: config.vessel.to_string(),
        uptime_s: started.elapsed().as_secs_f64(),
        sources: counters.iter().map(|c| c.snapshot()).collect(),
    };
    let report = |stats: &BridgeStats| {
        if let Ok(json) = serde_json::to_vec(stats)
            && let Err(e) = sink.put(Key::Stats, json)
        {
            tracing::warn!("cannot publish the bridge's counts: {e}");
        }
    };
    let mut next = Instant::now() + STATS_EVERY;
    while !stop.load(Ordering::Relaxed) && threads.iter().any(|t| !t.is_finished()) {
        std::thread::sleep(transport::TICK);
        if Instant::now() >= next {
            next += STATS_EVERY;
            let stats = snapshot(&counters);
            progress(&stats);
            report(&stats);
        }
    }
    stop.store(true, Ordering::Relaxed);
    let mut failure = None;
    for thread in threads {
        match thread.join() {
            Ok(Ok(())) => {}
            Ok(Err(e)) => failure = Some(anyhow::Error::new(e)),
            Err(_) => failure = Some(anyhow::anyhow!("a source's thread panicked")),
        }
    }
    let stats = snapshot(&counters);
    progress(&stats);
    report(&stats);
    match failure {
        Some(e) => Err(e),
        None => Ok(stats),
    }
}
