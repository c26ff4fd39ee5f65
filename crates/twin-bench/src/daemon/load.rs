//! One measurement point: a fleet of `N` vessels publishing GNSS fixes and
//! shaft speeds through Zenoh on loopback, either to twind (started here, in
//! this process) and back as `twin/fault` messages, or straight to a
//! subscriber with no daemon in between ("raw Zenoh"); measured at the
//! subscriber for one window.
//!
//! # How latency is measured
//! The generator stamps each message with `Instant::now()` (to the
//! microsecond, relative to an `Instant` taken once at the start) and writes
//! that same instant into the payload's `time` field (a Unix time: a whole
//! second taken at the start plus the stamp). The fix is then encoded
//! (`twin_wire::messages::encode_gnss`, as `twin-replay` does) and put. The
//! daemon's fault message carries the fix's time (`FaultMessage::time` is
//! the time of the fix that produced it), so the subscriber recovers the
//! publish instant of the very fix that produced each fault from the fault
//! itself: no side table, nothing that grows with the run. Its receive
//! instant is taken first thing in the Zenoh callback. The latency therefore
//! includes encoding the fix (about a microsecond), Zenoh both ways, the
//! daemon's dispatch, decode, estimator step, encoding and publishing of
//! state and fault, and decoding the fault's time at the subscriber.
//!
//! # What counts
//! Fixes are counted by their publish instant: those stamped inside the
//! window are "sent"; of those, the ones whose fault came back before the
//! window's end plus a grace period are "delivered"; the rest are "lost"
//! (dropped, or still queued: either way not delivered in time). A fault
//! whose time is not newer than the vessel's last one (the daemon's "stale"
//! or shutdown republications) is a "repeat", never a delivery. Received
//! throughput counts faults by their receive instant inside the window.
//!
//! # Keys
//! The generator puts on each vessel's keys through one session. On the
//! daemon's path each key is declared to that session (`declare_keyexpr`),
//! and the subscriber declares the keys it receives on to its own, as the
//! daemon does: with Zenoh 1.10 only a declared key's route is cached. Raw
//! Zenoh's keys stay strings (see [`measure`] for why, and why not one
//! declared publisher per key, as `twin-replay` has in its own session).
//!
//! # Warm-up
//! At least the warm-up asked for, and until every vessel has been heard
//! from and, paced, the generator is back on its schedule and deliveries
//! come back promptly, for 2 s in a row ([`caught_up`]); at most
//! [`WARMUP_CAP`] times the warm-up asked for.
//!
//! # Pacing
//! Paced: the fleet's messages are spread evenly over each period (vessel
//! `v` of `N` at `v/N` of the period), the generator sleeping until each is
//! due; a late generator publishes at once (never skips), and its largest
//! lag is reported. For raw Zenoh the generator runs one thread per core,
//! each pacing its own contiguous share of the fleet the same way (see
//! [`measure`]). Flat out: no pacing, the publishers' back-pressure
//! (`CongestionControl::Block`, as `twin-replay` publishes) sets the pace.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicI64, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::Context;
use serde::{Deserialize, Serialize};
use tokio_util::sync::CancellationToken;
use twin_wire::messages::{ActuatorCommand, encode_actuators, encode_gnss};
use twin_wire::time::parse_rfc3339;
use twin_wire::{KeySpace, Topic, VesselId};
use zenoh::Wait;
use zenoh::key_expr::KeyExpr;
use zenoh::pubsub::Publisher;
use zenoh::qos::CongestionControl;
use zenoh::sample::Sample;

use super::histogram::Histogram;
use super::motion::{Circle, Fleet};
use super::procstat;
use crate::rng::SplitMix64;

/// The warm-up ends at most this many times its least length.
pub const WARMUP_CAP: f64 = 12.0;

/// The warm-up ends only once the generator is no further than this behind
/// its schedule, and the newest delivery took no longer than this from
/// publish to receive (in [`CAUGHT_UP_SAMPLES`] samples in a row, 20 ms
/// apart, so for 2 s). A fleet that all starts at once costs a burst of
/// start-up work (each vessel's token and keys enter Zenoh's resource
/// trees, at a cost that grows with the fleet), which leaves a backlog, and
/// then every vessel's first forecast at once; the window should measure
/// the steady load. At 5,000 vessels with tokens (2026-11-22): every vessel
/// heard after 7 s, the generator back on schedule after 17 s, deliveries
/// under a millisecond from 24 s.
pub const CAUGHT_UP_LAG_MS: f64 = 50.0;

/// See [`CAUGHT_UP_LAG_MS`].
pub const CAUGHT_UP_SAMPLES: u32 = 100;

/// Whether one warm-up sample counts towards the end of the warm-up: paced,
/// the generator no more than [`CAUGHT_UP_LAG_MS`] behind its schedule and
/// the newest delivery no slower than that; flat out always (there is no
/// schedule, and the latency is queueing by design).
pub fn caught_up(paced: bool, generator_lag_ms: f64, newest_latency_ms: f64) -> bool {
    !paced || (generator_lag_ms <= CAUGHT_UP_LAG_MS && newest_latency_ms <= CAUGHT_UP_LAG_MS)
}

/// The fleet's speed over ground, m/s.
pub const FLEET_SPEED_MPS: f64 = 1.5;

/// Which path the messages take.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Path {
    /// Generator -> twind -> subscriber of `twin/fault`.
    Daemon,
    /// Generator -> subscriber of the input topics, no daemon.
    Raw,
}

/// What to measure.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PointSpec {
    /// Daemon or raw Zenoh.
    pub path: Path,
    /// Vessels.
    pub vessels: usize,
    /// Fixes per second per vessel; `None`: flat out.
    pub rate_hz: Option<f64>,
    /// Least warm-up before the window, s (longer until every vessel has
    /// been heard from and, paced, the generator is back on its schedule and
    /// deliveries are prompt ([`caught_up`]), up to [`WARMUP_CAP`] times
    /// this).
    pub warmup_s: f64,
    /// Measurement window, s.
    pub window_s: f64,
    /// After the window, how long messages of fixes sent in it may still
    /// arrive and count as delivered, s.
    pub grace_s: f64,
    /// The daemon's `publish.vessel_liveliness`: a liveliness token per
    /// vessel under the prefix (the contract) or none.
    pub vessel_liveliness: bool,
    /// The tokens at [`OUTSIDE_PREFIX_LIVELINESS_KEY`] instead of the
    /// contract's key (`publish.vessel_liveliness_key`).
    #[serde(default)]
    pub liveliness_outside_prefix: bool,
}

/// The liveliness key measured with `--liveliness-outside-prefix`, as
/// docs/deploy.md suggests for a large fleet.
pub const OUTSIDE_PREFIX_LIVELINESS_KEY: &str = "asv-twins/alive/{vessel}";

/// How a point ends.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ending {
    /// Stop the daemon as `twind` does on a signal (it drains its queues),
    /// collect its counters, close the sessions.
    Graceful,
    /// Leave everything running (the caller exits the process at once): a
    /// saturated daemon would take minutes to drain queues nobody measures.
    Abandon,
}

/// Latency figures, nanoseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Latency {
    /// Samples.
    pub count: u64,
    /// Smallest.
    pub min_ns: Option<u64>,
    /// Median.
    pub p50_ns: Option<u64>,
    /// 90th percentile.
    pub p90_ns: Option<u64>,
    /// 99th percentile.
    pub p99_ns: Option<u64>,
    /// 99.9th percentile.
    pub p999_ns: Option<u64>,
    /// Largest.
    pub max_ns: Option<u64>,
    /// Mean.
    pub mean_ns: Option<f64>,
}

impl Latency {
    fn of(h: &Histogram) -> Self {
        Self {
            count: h.count(),
            min_ns: h.min(),
            p50_ns: h.quantile(0.5),
            p90_ns: h.quantile(0.9),
            p99_ns: h.quantile(0.99),
            p999_ns: h.quantile(0.999),
            max_ns: h.max(),
            mean_ns: h.mean(),
        }
    }
}

/// What the daemon counted (graceful ending only).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct DaemonCounters {
    /// Messages routed to vessel tasks.
    pub routed: u64,
    /// Accepted, by topic, over every vessel.
    pub accepted: BTreeMap<String, u64>,
    /// Rejected, by reason, over every vessel and the dispatcher.
    pub rejected: BTreeMap<String, u64>,
}

/// What one point measured.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PointResult {
    /// What was asked.
    pub spec: PointSpec,
    /// The steady turn the fleet followed.
    pub circle_speed_mps: f64,
    /// Its radius, m.
    pub circle_radius_m: f64,
    /// Its shaft speeds, rpm.
    pub circle_rpm: [f64; 2],
    /// Warm-up actually used, s.
    pub warmup_used_s: f64,
    /// True when the warm-up ended at its cap with vessels not yet heard,
    /// the generator still behind its schedule or deliveries still late
    /// (see [`CAUGHT_UP_LAG_MS`]).
    pub warmup_capped: bool,
    /// How far behind its schedule the generator was when the window
    /// started, ms (paced only).
    #[serde(default)]
    pub generator_lag_at_start_ms: Option<f64>,
    /// The window actually measured, s.
    pub window_s: f64,
    /// Fixes stamped inside the window.
    pub fixes_sent: u64,
    /// Shaft-speed messages stamped inside the window.
    pub actuators_sent: u64,
    /// Planned fixes per second (paced only).
    pub planned_fixes_per_s: Option<f64>,
    /// Fixes sent per second in the window.
    pub offered_fixes_per_s: f64,
    /// Measured messages (faults, or raw fixes) received per second in the
    /// window, by receive instant.
    pub received_per_s: f64,
    /// Of the fixes sent in the window, those whose message arrived by the
    /// window's end plus the grace period.
    pub delivered: u64,
    /// Faults whose time was not newer than their vessel's last one.
    pub repeats: u64,
    /// Messages the subscriber could not attribute (bad key or payload).
    pub unparsable: u64,
    /// The first of them: why, its key and the start of its payload.
    #[serde(default)]
    pub unparsable_first: Option<String>,
    /// Vessels with at least one delivery in the window.
    pub vessels_delivered: usize,
    /// Vessels heard from at all (a fault, or a raw fix) by the end.
    pub vessels_heard: usize,
    /// Vessels heard from when the window started.
    pub vessels_heard_at_start: usize,
    /// Deliveries per vessel, in vessel order.
    pub per_vessel_delivered: Vec<u32>,
    /// Publish to receive, of every delivered message.
    pub latency: Latency,
    /// The generator's largest lag behind its schedule from the window's
    /// start to the end of its grace period, ms (paced only).
    pub generator_max_lag_ms: Option<f64>,
    /// CPU time of the whole process over the window, % of one core.
    pub cpu_pct_of_core: Option<f64>,
    /// The same by thread group (live threads), % of one core.
    pub cpu_pct_by_group: BTreeMap<String, f64>,
    /// RSS with everything set up, before the first message, KiB.
    pub rss_base_kib: Option<u64>,
    /// RSS at the window's end, KiB.
    pub rss_end_kib: Option<u64>,
    /// Mean GNSS payload, bytes.
    pub gnss_bytes_mean: f64,
    /// Mean shaft-speed payload, bytes.
    pub actuators_bytes_mean: f64,
    /// Mean measured payload received (fault, or raw fix), bytes.
    pub received_bytes_mean: f64,
    /// The daemon's own counters (daemon path, graceful ending).
    pub daemon: Option<DaemonCounters>,
    /// Threads of the load generator (raw Zenoh: one per core, at most one
    /// per vessel; the daemon path: one).
    pub generator_threads: usize,
    /// Forecasts the daemon computed per second of the window (daemon
    /// path): they run on idle CPU time, so under load they come less often
    /// than one per vessel per `prediction_interval_s`.
    pub forecasts_per_s: Option<f64>,
}

impl PointResult {
    /// Sent fixes not delivered in time.
    pub fn lost(&self) -> u64 {
        self.fixes_sent.saturating_sub(self.delivered)
    }

    /// Delivered over sent (1 when nothing was sent).
    pub fn delivered_fraction(&self) -> f64 {
        if self.fixes_sent == 0 {
            1.0
        } else {
            self.delivered as f64 / self.fixes_sent as f64
        }
    }

    /// Sent over planned (1 when flat out).
    pub fn offered_fraction(&self) -> f64 {
        match self.planned_fixes_per_s {
            Some(p) if p > 0.0 => self.offered_fixes_per_s / p,
            _ => 1.0,
        }
    }

    /// CPU of the load generator's threads over the window, % of one core.
    pub fn generator_cpu_pct(&self) -> Option<f64> {
        self.cpu_pct_by_group
            .get(procstat::thread_group("bench-gen"))
            .copied()
    }

    /// Delivered per second of window.
    pub fn delivered_per_s(&self) -> f64 {
        self.delivered as f64 / self.window_s.max(1e-9)
    }

    /// Memory per vessel, KiB: (RSS at the end - RSS before) / vessels.
    pub fn kib_per_vessel(&self) -> Option<f64> {
        let (b, e) = (self.rss_base_kib?, self.rss_end_kib?);
        Some((e as f64 - b as f64) / self.spec.vessels.max(1) as f64)
    }
}

/// The daemon's settings for the benchmark: the defaults with the live
/// diagnose off (it runs `twin diagnose` on each vessel's recent past on a
/// blocking thread every few minutes of message time: seconds of CPU each,
/// unrelated to the per-fix path measured here).
pub fn bench_settings(
    vessel_liveliness: bool,
    liveliness_outside_prefix: bool,
) -> anyhow::Result<twind::settings::Settings> {
    let key = if liveliness_outside_prefix {
        format!("vessel_liveliness_key = \"{OUTSIDE_PREFIX_LIVELINESS_KEY}\"\n")
    } else {
        String::new()
    };
    Ok(twind::settings::Settings::from_toml(&format!(
        "[diagnose]\nenabled = false\n[publish]\nvessel_liveliness = {vessel_liveliness}\n{key}"
    ))?)
}

/// The vessel id of vessel `v`.
pub fn vessel_id(v: usize) -> String {
    format!("b{v:05}")
}

fn vessel_index(id: &str) -> Option<usize> {
    id.strip_prefix('b')?.parse().ok()
}

/// A free TCP port on loopback (bound, read, released).
pub(crate) fn free_port() -> anyhow::Result<u16> {
    Ok(std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port())
}

/// A peer on loopback listening on / connecting to the given ports, with
/// multicast scouting and gossip off: only the links asked for exist.
pub(crate) fn zenoh_config(listen: &[u16], connect: &[u16]) -> anyhow::Result<zenoh::Config> {
    let ends = |ports: &[u16]| {
        let v: Vec<String> = ports
            .iter()
            .map(|p| format!("\"tcp/127.0.0.1:{p}\""))
            .collect();
        format!("[{}]", v.join(","))
    };
    let mut c = zenoh::Config::default();
    for (key, value) in [
        ("mode", "\"peer\"".to_string()),
        ("listen/endpoints", ends(listen)),
        ("connect/endpoints", ends(connect)),
        ("scouting/multicast/enabled", "false".into()),
        ("scouting/gossip/enabled", "false".into()),
    ] {
        c.insert_json5(key, &value)
            .map_err(|e| anyhow::anyhow!("zenoh config {key}: {e}"))?;
    }
    Ok(c)
}

/// The window, in microseconds since the start; `i64::MAX` until set.
struct Window {
    start_us: AtomicI64,
    end_us: AtomicI64,
}

impl Window {
    fn new() -> Self {
        Self {
            start_us: AtomicI64::new(i64::MAX),
            end_us: AtomicI64::new(i64::MAX),
        }
    }

    fn contains(&self, t_us: i64) -> bool {
        t_us >= self.start_us.load(Ordering::Acquire) && t_us < self.end_us.load(Ordering::Acquire)
    }
}

#[derive(Debug, Clone, Copy)]
struct VesselRx {
    last_time_us: i64,
    delivered: u32,
}

struct RxState {
    vessels: Vec<VesselRx>,
    heard: usize,
    latency: Histogram,
    delivered: u64,
    received_in_window: u64,
    repeats: u64,
    unparsable: u64,
    unparsable_first: Option<String>,
    measured_bytes: u64,
    measured_count: u64,
    /// Publish to receive of the newest delivery, in the window or not, ns.
    newest_latency_ns: i64,
}

impl RxState {
    /// Counts a message that cannot be attributed, keeping the first for
    /// the report (the key and up to 160 bytes of its payload).
    fn count_unparsable(&mut self, why: &str, key: &str, payload: &[u8]) {
        self.unparsable += 1;
        if self.unparsable_first.is_none() {
            let head = &payload[..payload.len().min(160)];
            self.unparsable_first = Some(format!(
                "{why}: {key} ({} B) {}",
                payload.len(),
                String::from_utf8_lossy(head)
            ));
        }
    }
}

/// The subscriber's side: everything is allocated before the first message.
struct Receiver {
    path: Path,
    start: Instant,
    epoch_s: f64,
    window: Arc<Window>,
    /// After the grace period nothing more is counted.
    closed: AtomicBool,
    state: Mutex<RxState>,
}

/// The only field of a fault (or fix) payload the subscriber reads.
#[derive(Deserialize)]
struct Timed<'a> {
    time: &'a str,
}

impl Receiver {
    fn new(path: Path, n: usize, start: Instant, epoch_s: f64, window: Arc<Window>) -> Self {
        Self {
            path,
            start,
            epoch_s,
            window,
            closed: AtomicBool::new(false),
            state: Mutex::new(RxState {
                vessels: vec![
                    VesselRx {
                        last_time_us: i64::MIN,
                        delivered: 0,
                    };
                    n
                ],
                heard: 0,
                latency: Histogram::new(),
                delivered: 0,
                received_in_window: 0,
                repeats: 0,
                unparsable: 0,
                unparsable_first: None,
                measured_bytes: 0,
                measured_count: 0,
                newest_latency_ns: i64::MAX,
            }),
        }
    }

    fn on_sample(&self, sample: &Sample) {
        let received_ns = self.start.elapsed().as_nanos() as i64;
        if self.closed.load(Ordering::Acquire) {
            return;
        }
        let key = sample.key_expr().as_str();
        let mut parts = key.splitn(3, '/');
        let (_, id, topic) = (parts.next(), parts.next(), parts.next());
        let measured = match (self.path, topic) {
            (Path::Daemon, Some("twin/fault")) | (Path::Raw, Some("gnss")) => true,
            (Path::Raw, Some("actuators")) => false,
            _ => {
                self.lock().count_unparsable(
                    "not a measured topic",
                    key,
                    &sample.payload().to_bytes(),
                );
                return;
            }
        };
        if !measured {
            return;
        }
        let bytes = sample.payload().to_bytes();
        let index = id.and_then(vessel_index);
        let sent_us = serde_json::from_slice::<Timed>(&bytes)
            .ok()
            .and_then(|t| parse_rfc3339(t.time).ok())
            .map(|t| ((t - self.epoch_s) * 1e6).round() as i64);
        let mut guard = self.lock();
        let st = &mut *guard;
        let (Some(v), Some(sent_us)) = (index, sent_us) else {
            let why = if index.is_none() {
                "no vessel index in the key"
            } else {
                "no readable time in the payload"
            };
            st.count_unparsable(why, key, &bytes);
            return;
        };
        if v >= st.vessels.len() {
            st.count_unparsable("vessel index out of range", key, &bytes);
            return;
        }
        let vessel = &mut st.vessels[v];
        st.measured_bytes += bytes.len() as u64;
        st.measured_count += 1;
        if sent_us <= vessel.last_time_us {
            st.repeats += 1;
            return;
        }
        let first = vessel.last_time_us == i64::MIN;
        vessel.last_time_us = sent_us;
        let in_window = self.window.contains(sent_us);
        if in_window {
            vessel.delivered += 1;
        }
        if first {
            st.heard += 1;
        }
        let latency_ns = received_ns - sent_us * 1000;
        st.newest_latency_ns = latency_ns;
        if in_window {
            st.delivered += 1;
            st.latency.record(latency_ns.max(0) as u64);
        }
        if self.window.contains(received_ns / 1000) {
            st.received_in_window += 1;
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, RxState> {
        // A panic while holding the lock cannot leave the counters
        // inconsistent beyond one message: keep counting.
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// What the generator shares with the main thread.
#[derive(Default)]
struct GenShared {
    stop: AtomicBool,
    fixes_in_window: AtomicU64,
    actuators_in_window: AtomicU64,
    max_lag_us: AtomicU64,
    /// The lag of the newest message, us (0 when it was not late).
    lag_us: AtomicU64,
    gnss_bytes: AtomicU64,
    actuators_bytes: AtomicU64,
    sent: AtomicU64,
    errors: AtomicU64,
}

/// One of the generator's threads: it sends the messages of a contiguous
/// share of the fleet.
struct Generator {
    session: zenoh::Session,
    /// Per vessel of this share: the shaft-speed key, the GNSS key.
    keys: Vec<[KeyExpr<'static>; 2]>,
    /// The fleet index of the share's first vessel.
    first_vessel: usize,
    /// Seeds this thread's GNSS noise.
    seed: u64,
    fleet: Arc<Fleet>,
    rate_hz: Option<f64>,
    start: Instant,
    epoch_s: f64,
    window: Arc<Window>,
    shared: Arc<GenShared>,
}

impl Generator {
    fn now_us(&self) -> i64 {
        self.start.elapsed().as_micros() as i64
    }

    /// A stamp for a message of a vessel whose last one on this topic was
    /// stamped `last`: now, or one microsecond after `last` if the clock has
    /// not moved (times must increase per vessel and topic).
    fn stamp(&self, last: &mut i64) -> i64 {
        let t = self.now_us().max(*last + 1);
        *last = t;
        t
    }

    /// Puts reliably, blocking while Zenoh's queues are full (as
    /// `twin-replay`'s publishers, `CongestionControl::Block`).
    fn put(&self, key: &KeyExpr<'static>, bytes: Vec<u8>) -> zenoh::Result<()> {
        self.session
            .put(key, bytes)
            .congestion_control(CongestionControl::Block)
            .wait()
    }

    /// Puts one encoded message stamped at `stamp_us` and counts it: its
    /// bytes, whether its stamp lies in the window, or an error (encoding
    /// or putting).
    fn put_counted<E>(
        &self,
        key: &KeyExpr<'static>,
        encoded: Result<Vec<u8>, E>,
        stamp_us: i64,
        bytes_sent: &AtomicU64,
        sent_in_window: &AtomicU64,
    ) {
        let s = &self.shared;
        let Ok(bytes) = encoded else {
            s.errors.fetch_add(1, Ordering::Relaxed);
            return;
        };
        bytes_sent.fetch_add(bytes.len() as u64, Ordering::Relaxed);
        if self.put(key, bytes).is_err() {
            s.errors.fetch_add(1, Ordering::Relaxed);
        }
        if self.window.contains(stamp_us) {
            sent_in_window.fetch_add(1, Ordering::Relaxed);
        }
    }

    fn run(self) {
        let n = self.keys.len();
        let mut rng = SplitMix64::new(self.seed);
        let mut last = vec![[i64::MIN + 1; 2]; n];
        let begin_us = self.now_us();
        let per_s = self.rate_hz.map(|r| r * n as f64);
        let s = &self.shared;
        let mut i: u64 = 0;
        while !s.stop.load(Ordering::Relaxed) {
            let v = (i % n as u64) as usize;
            if let Some(per_s) = per_s {
                let due_us = begin_us + (i as f64 * 1e6 / per_s) as i64;
                let now = self.now_us();
                if due_us > now {
                    s.lag_us.store(0, Ordering::Relaxed);
                    std::thread::sleep(Duration::from_micros((due_us - now) as u64));
                } else {
                    let lag = (now - due_us) as u64;
                    s.lag_us.store(lag, Ordering::Relaxed);
                    s.max_lag_us.fetch_max(lag, Ordering::Relaxed);
                }
            }
            // Shaft speeds first, then the fix, each stamped just before
            // it is encoded. The load goes on after the window (through the
            // grace period) until the main thread says stop: the window's
            // last fixes are delivered under the same load as the others.
            let a_us = self.stamp(&mut last[v][0]);
            let t = self.epoch_s + a_us as f64 * 1e-6;
            let shafts = self.fleet.shafts(t, &mut rng);
            self.put_counted(
                &self.keys[v][0],
                encode_actuators(&ActuatorCommand::Speeds(shafts), false),
                a_us,
                &s.actuators_bytes,
                &s.actuators_in_window,
            );
            let g_us = self.stamp(&mut last[v][1]);
            let t = self.epoch_s + g_us as f64 * 1e-6;
            let fix = self
                .fleet
                .fix(self.first_vessel + v, t, g_us as f64 * 1e-6, &mut rng);
            self.put_counted(
                &self.keys[v][1],
                encode_gnss(&fix, false),
                g_us,
                &s.gnss_bytes,
                &s.fixes_in_window,
            );
            s.sent.fetch_add(1, Ordering::Relaxed);
            i += 1;
        }
    }
}

pub(crate) async fn wait_matching(p: &Publisher<'_>, within: Duration) -> anyhow::Result<()> {
    let deadline = Instant::now() + within;
    loop {
        let matching = p
            .matching_status()
            .await
            .map(|m| m.matching())
            .unwrap_or(false);
        if matching {
            return Ok(());
        }
        anyhow::ensure!(
            Instant::now() < deadline,
            "no subscriber for {} within {within:?}",
            p.key_expr()
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

pub(crate) fn zerr(what: &str) -> impl FnOnce(zenoh::Error) -> anyhow::Error + '_ {
    move |e| anyhow::anyhow!("{what}: {e}")
}

/// Runs one point. `Ending::Abandon` leaves the daemon, the sessions and
/// the runtime running (leaked): call it only in a process that exits next.
pub fn measure(spec: &PointSpec, ending: Ending) -> anyhow::Result<PointResult> {
    let n = spec.vessels;
    anyhow::ensure!((1..=99_999).contains(&n), "1 to 99,999 vessels");
    anyhow::ensure!(
        spec.window_s > 0.0 && spec.warmup_s >= 0.0 && spec.grace_s >= 0.0,
        "window, warm-up and grace must be positive"
    );
    if let Some(r) = spec.rate_hz {
        anyhow::ensure!(r > 0.0 && r.is_finite(), "the rate must be positive");
    }
    let circle = Circle::from_simulator(FLEET_SPEED_MPS)?;
    let fleet = Fleet::new(circle, n)?;
    let keys = KeySpace::new("asv")?;
    let settings = bench_settings(spec.vessel_liveliness, spec.liveliness_outside_prefix)?;

    // The daemon's runtime: tokio's multi-threaded scheduler with a worker
    // per core, as `twind`'s `#[tokio::main]` has.
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(crate::machine::cores())
        .thread_name("twind-rt")
        .enable_all()
        .build()
        .context("building the daemon's runtime")?;

    let port = free_port()?;
    let (daemon, generator_session, subscriber_session) = rt.block_on(async {
        let open = |listen: &[u16], connect: &[u16]| {
            let config = zenoh_config(listen, connect);
            async move {
                zenoh::open(config?)
                    .await
                    .map_err(|e| anyhow::anyhow!("opening a Zenoh session: {e}"))
            }
        };
        anyhow::Ok(match spec.path {
            Path::Daemon => {
                let daemon = open(&[port], &[]).await?;
                (
                    Some(daemon),
                    open(&[], &[port]).await?,
                    open(&[], &[port]).await?,
                )
            }
            Path::Raw => {
                let sub = open(&[port], &[]).await?;
                (None, open(&[], &[port]).await?, sub)
            }
        })
    })?;

    let start = Instant::now();
    let epoch_s = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .context("the system clock is before 1970")?
        .as_secs() as f64;
    let window = Arc::new(Window::new());
    let receiver = Arc::new(Receiver::new(spec.path, n, start, epoch_s, window.clone()));

    let cancel = CancellationToken::new();
    let daemon_task = daemon.as_ref().map(|session| {
        rt.spawn(twind::run(twind::RunConfig::new(
            settings.clone(),
            session.clone(),
            cancel.clone(),
        )))
    });
    let sub_key = match spec.path {
        Path::Daemon => keys.all_vessels(Topic::TwinFault),
        Path::Raw => twind::input_key_expr(&settings),
    };
    let rx = receiver.clone();
    let subscriber = subscriber_session
        .declare_subscriber(sub_key.clone())
        .callback(move |s| rx.on_sample(&s))
        .wait()
        .map_err(zerr("subscribing"))?;

    // On the daemon's path the generator puts through its session on each
    // vessel's key, declared to that session (`declare_keyexpr`, not
    // announced when declared) so that its routing finds a node with a cached
    // route, as the daemon declares its own (see twind's `vessel.rs`): with
    // Zenoh 1.10 a key that is not a node is routed by a walk over every
    // node under `asv/`, each vessel's liveliness token among them, and one
    // session standing in for N vessels would pay that N times over. Not one
    // declared publisher per key, as `twin-replay` has in its own session:
    // 2 N publishers in one session cost O(N^2) to declare in Zenoh 1.10 (an
    // artefact of one process standing in for N vessels, each of which
    // would have its own session with two publishers). The subscriber,
    // standing for a program that watches the fleet, declares the keys it
    // receives on to its own session for the same reason (docs/deploy.md
    // advises it for such programs).
    //
    // Raw Zenoh has no tokens, so no per-vessel node for an undeclared key's
    // routing to walk: its keys stay strings, as a plain Zenoh program's
    // would. Declaring them costs O(N^2) too (the session searches its
    // declared keys one by one): 4 N declarations at 40,000 vessels took
    // longer than a point may.
    let declare = |session: &zenoh::Session, k: String| -> anyhow::Result<KeyExpr<'static>> {
        match spec.path {
            Path::Daemon => session
                .declare_keyexpr(k)
                .wait()
                .map_err(zerr("declaring a vessel's key")),
            Path::Raw => KeyExpr::try_from(k).map_err(zerr("a vessel's key")),
        }
    };
    let mut vessel_keys = Vec::with_capacity(n);
    let mut received_keys = Vec::with_capacity(n);
    for v in 0..n {
        let id = VesselId::new(&vessel_id(v))?;
        vessel_keys.push([
            declare(&generator_session, keys.actuators(&id))?,
            declare(&generator_session, keys.gnss(&id))?,
        ]);
        if spec.path == Path::Daemon {
            received_keys.push(declare(&subscriber_session, keys.twin_fault(&id))?);
        }
    }
    rt.block_on(async {
        let probe = generator_session
            .declare_publisher(vessel_keys[0][1].clone())
            .await
            .map_err(zerr("declaring the probe"))?;
        wait_matching(&probe, Duration::from_secs(20)).await?;
        probe
            .undeclare()
            .await
            .map_err(zerr("undeclaring the probe"))?;
        if let Some(d) = &daemon {
            // The daemon's session must see the fault subscriber before the
            // first vessel task declares its publishers.
            let probe = d
                .declare_publisher(keys.twin_fault(&VesselId::new(&vessel_id(0))?))
                .await
                .map_err(zerr("declaring the probe"))?;
            wait_matching(&probe, Duration::from_secs(20)).await?;
            probe
                .undeclare()
                .await
                .map_err(zerr("undeclaring the probe"))?;
        }
        anyhow::Ok(())
    })?;

    let rss_base_kib = procstat::rss_kib();
    let shared = Arc::new(GenShared::default());
    // Raw Zenoh: one generator thread per core (each with a contiguous share
    // of the fleet, all through the one session), since one thread alone
    // cannot load Zenoh to its limit. The daemon path: one thread, which
    // uses under a third of a core there, while a second one through the
    // same session cost about 8 % of a core more in contention (measured at
    // 5,000 vessels x 10 Hz, 2026-11-22): CPU taken from the daemon.
    let threads = match spec.path {
        Path::Raw => std::thread::available_parallelism().map_or(1, |c| c.get()),
        Path::Daemon => 1,
    };
    let share = n.div_ceil(threads.clamp(1, n));
    let fleet = Arc::new(fleet);
    let mut gen_threads = Vec::new();
    let mut keys_left = vessel_keys;
    while !keys_left.is_empty() {
        let k = gen_threads.len();
        let rest = keys_left.split_off(share.min(keys_left.len()));
        let generator = Generator {
            session: generator_session.clone(),
            keys: std::mem::replace(&mut keys_left, rest),
            first_vessel: k * share,
            seed: 0x7717_b0a7 + k as u64,
            fleet: fleet.clone(),
            rate_hz: spec.rate_hz,
            start,
            epoch_s,
            window: window.clone(),
            shared: shared.clone(),
        };
        gen_threads.push(
            std::thread::Builder::new()
                .name(format!("bench-gen-{k}"))
                .spawn(move || generator.run())
                .context("starting the generator")?,
        );
    }

    // Warm-up: at least `warmup_s`, and until every vessel has been heard
    // from (every daemon task started and publishing) and, paced, the
    // generator is back on its schedule and what it sends comes back
    // promptly (the start-up backlog has drained; `caught_up`), up to
    // WARMUP_CAP times.
    let generator_threads = gen_threads.len();
    let warm_start = Instant::now();
    let cap = Duration::from_secs_f64(spec.warmup_s * WARMUP_CAP);
    let least = Duration::from_secs_f64(spec.warmup_s);
    let mut on_schedule = 0;
    let warmup_capped = loop {
        let elapsed = warm_start.elapsed();
        let (heard, newest_latency_ns) = {
            let st = receiver.lock();
            (st.heard, st.newest_latency_ns)
        };
        let lag_ms = shared.lag_us.load(Ordering::Relaxed) as f64 / 1e3;
        let latency_ms = newest_latency_ns as f64 / 1e6;
        on_schedule = if caught_up(spec.rate_hz.is_some(), lag_ms, latency_ms) {
            on_schedule + 1
        } else {
            0
        };
        if elapsed >= least && heard >= n && on_schedule >= CAUGHT_UP_SAMPLES {
            break false;
        }
        if elapsed >= cap {
            break true;
        }
        if gen_threads.iter().any(|t| t.is_finished()) {
            anyhow::bail!("the generator stopped during the warm-up");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let warmup_used_s = warm_start.elapsed().as_secs_f64();
    let vessels_heard_at_start = receiver.lock().heard;
    let generator_lag_at_start_ms = shared.lag_us.load(Ordering::Relaxed) as f64 / 1e3;
    shared.max_lag_us.store(0, Ordering::Relaxed);

    // The window.
    let threads_before = procstat::thread_ticks();
    let cpu_before = procstat::process_ticks();
    let forecasts_before = twind::forecast::computed_total();
    let w0 = start.elapsed().as_micros() as i64;
    let w1 = w0 + (spec.window_s * 1e6) as i64;
    window.start_us.store(w0, Ordering::Release);
    window.end_us.store(w1, Ordering::Release);
    let sleep_until = |t_us: i64| {
        let now = start.elapsed().as_micros() as i64;
        if t_us > now {
            std::thread::sleep(Duration::from_micros((t_us - now) as u64));
        }
    };
    sleep_until(w1);
    let forecasts_in_window = twind::forecast::computed_total() - forecasts_before;
    let cpu_after = procstat::process_ticks();
    let threads_after = procstat::thread_ticks();
    let rss_end_kib = procstat::rss_kib();
    let window_s = (w1 - w0) as f64 * 1e-6;
    sleep_until(w1 + (spec.grace_s * 1e6) as i64);
    receiver.closed.store(true, Ordering::Release);
    shared.stop.store(true, Ordering::Relaxed);

    let pct = |ticks: u64| ticks as f64 / procstat::TICKS_PER_S / window_s * 100.0;
    let cpu_pct_of_core = match (cpu_before, cpu_after) {
        (Some(b), Some(a)) => Some(pct(a.saturating_sub(b))),
        _ => None,
    };
    let cpu_pct_by_group = procstat::group_ticks(&threads_before, &threads_after)
        .into_iter()
        .map(|(g, t)| (g, pct(t)))
        .collect();

    let fixes_sent = shared.fixes_in_window.load(Ordering::Relaxed);
    let actuators_sent = shared.actuators_in_window.load(Ordering::Relaxed);
    let sent_total = shared.sent.load(Ordering::Relaxed).max(1) as f64;
    let errors = shared.errors.load(Ordering::Relaxed);
    anyhow::ensure!(errors == 0, "{errors} messages could not be encoded or put");
    let (per_vessel_delivered, rx_summary) = {
        let st = receiver.lock();
        (
            st.vessels.iter().map(|v| v.delivered).collect::<Vec<_>>(),
            (
                st.heard,
                st.delivered,
                st.received_in_window,
                st.repeats,
                st.unparsable,
                st.unparsable_first.clone(),
                Latency::of(&st.latency),
                if st.measured_count > 0 {
                    st.measured_bytes as f64 / st.measured_count as f64
                } else {
                    0.0
                },
            ),
        )
    };
    let (
        heard,
        delivered,
        received_in_window,
        repeats,
        unparsable,
        unparsable_first,
        latency,
        received_bytes_mean,
    ) = rx_summary;
    let result_without_daemon = PointResult {
        spec: *spec,
        circle_speed_mps: circle.speed_mps,
        circle_radius_m: circle.radius_m(),
        circle_rpm: circle.rpm,
        warmup_used_s,
        warmup_capped,
        generator_lag_at_start_ms: spec.rate_hz.map(|_| generator_lag_at_start_ms),
        window_s,
        fixes_sent,
        actuators_sent,
        planned_fixes_per_s: spec.rate_hz.map(|r| r * n as f64),
        offered_fixes_per_s: fixes_sent as f64 / window_s,
        received_per_s: received_in_window as f64 / window_s,
        delivered,
        repeats,
        unparsable,
        unparsable_first,
        vessels_delivered: per_vessel_delivered.iter().filter(|&&d| d > 0).count(),
        vessels_heard: heard,
        vessels_heard_at_start,
        per_vessel_delivered,
        latency,
        generator_max_lag_ms: spec
            .rate_hz
            .map(|_| shared.max_lag_us.load(Ordering::Relaxed) as f64 / 1e3),
        cpu_pct_of_core,
        cpu_pct_by_group,
        rss_base_kib,
        rss_end_kib,
        gnss_bytes_mean: shared.gnss_bytes.load(Ordering::Relaxed) as f64 / sent_total,
        actuators_bytes_mean: shared.actuators_bytes.load(Ordering::Relaxed) as f64 / sent_total,
        received_bytes_mean,
        daemon: None,
        generator_threads,
        forecasts_per_s: matches!(spec.path, Path::Daemon)
            .then(|| forecasts_in_window as f64 / window_s),
    };

    match ending {
        Ending::Abandon => {
            // Dropping these would wait for a saturated daemon to drain.
            std::mem::forget(gen_threads);
            std::mem::forget(subscriber);
            std::mem::forget(daemon_task);
            std::mem::forget(daemon);
            std::mem::forget(generator_session);
            std::mem::forget(subscriber_session);
            std::mem::forget(rt);
            Ok(result_without_daemon)
        }
        Ending::Graceful => {
            for t in gen_threads {
                t.join()
                    .map_err(|_| anyhow::anyhow!("the generator panicked"))?;
            }
            drop(subscriber);
            cancel.cancel();
            let counters = rt.block_on(async {
                let summary = match daemon_task {
                    Some(task) => Some(
                        tokio::time::timeout(Duration::from_secs(60), task)
                            .await
                            .context("the daemon did not stop within 60 s")?
                            .context("the daemon's task failed")??,
                    ),
                    None => None,
                };
                for s in [
                    Some(&generator_session),
                    Some(&subscriber_session),
                    daemon.as_ref(),
                ]
                .into_iter()
                .flatten()
                {
                    s.close().await.map_err(zerr("closing a session"))?;
                }
                anyhow::Ok(summary.map(|summary| {
                    let mut c = DaemonCounters {
                        routed: summary.routed,
                        ..DaemonCounters::default()
                    };
                    for counters in summary
                        .vessels
                        .values()
                        .chain(std::iter::once(&summary.refused))
                    {
                        for (k, v) in counters.accepted() {
                            *c.accepted.entry(k).or_default() += v;
                        }
                        for (k, v) in &counters.rejected {
                            *c.rejected.entry(k.clone()).or_default() += v;
                        }
                    }
                    c
                }))
            })?;
            Ok(PointResult {
                daemon: counters,
                ..result_without_daemon
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{CAUGHT_UP_LAG_MS, Path, Receiver, Window, caught_up};
    use std::sync::Arc;
    use std::time::Instant;

    /// Every unattributable message is counted; the first is kept, with
    /// why, its key and the start of its payload, for the report.
    #[test]
    fn the_first_unattributable_message_is_kept_for_the_report() {
        let rx = Receiver::new(
            Path::Daemon,
            2,
            Instant::now(),
            0.0,
            Arc::new(Window::new()),
        );
        let mut st = rx.lock();
        st.count_unparsable(
            "no readable time in the payload",
            "asv/v0/twin/fault",
            br#"{"x":1}"#,
        );
        st.count_unparsable("vessel index out of range", "asv/v9/twin/fault", b"{}");
        assert_eq!(st.unparsable, 2);
        assert_eq!(
            st.unparsable_first.as_deref(),
            Some(r#"no readable time in the payload: asv/v0/twin/fault (7 B) {"x":1}"#)
        );
    }

    #[test]
    fn a_paced_warm_up_waits_for_the_schedule_and_prompt_deliveries() {
        let late = CAUGHT_UP_LAG_MS + 1.0;
        assert!(caught_up(true, 0.0, 0.2));
        assert!(caught_up(true, CAUGHT_UP_LAG_MS, CAUGHT_UP_LAG_MS));
        assert!(!caught_up(true, late, 0.2), "the generator is behind");
        assert!(!caught_up(true, 0.0, late), "deliveries are late");
        // A fresh receiver's newest latency before any delivery.
        assert!(!caught_up(true, 0.0, i64::MAX as f64 / 1e6));
    }

    #[test]
    fn a_flat_out_warm_up_does_not_wait_for_prompt_deliveries() {
        // Flat out the latency is queueing by design and there is no
        // schedule: only the vessels heard from end its warm-up.
        assert!(caught_up(false, 0.0, 150.0));
        assert!(caught_up(false, 0.0, i64::MAX as f64 / 1e6));
    }
}
