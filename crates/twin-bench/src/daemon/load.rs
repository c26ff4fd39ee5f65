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
//! Zenoh's keys stay strings (see `VesselKeys` for why, and why not one
//! declared publisher per key, as `twin-replay` has in its own session).
//!
//! # Ending
//! The generator stops, the subscriber is undeclared, the daemon is told to
//! stop and drains its queues, and the Zenoh sessions close last, each wait
//! bounded ([`DRAIN_LIMIT`], [`CLOSE_LIMIT`], [`GENERATOR_STOP_LIMIT`]): a
//! daemon saturated at the window's end could otherwise take minutes to
//! drain work nobody measures.
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
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::Context;
use serde::{Deserialize, Serialize};
use tokio_util::sync::CancellationToken;
use twin_wire::{KeySpace, Topic, VesselId};
use zenoh::Wait;
use zenoh::key_expr::KeyExpr;
use zenoh::pubsub::{Publisher, Subscriber};

use super::generator::{GenShared, Generator};
use super::histogram::Histogram;
use super::motion::{Circle, Fleet};
use super::procstat;
use super::receiver::{Receiver, Window};

/// The warm-up ends at most this many times its least length.
pub const WARMUP_CAP: f64 = 12.0;

/// The warm-up ends only once the generator is no further than this behind
/// its schedule, and the newest delivery took no longer than this from
/// publish to receive (in [`CAUGHT_UP_SAMPLES`] samples in a row, 20 ms
/// apart, so for 2 s). A fleet that all starts at once costs a burst of
/// start-up work (each vessel's token and keys enter Zenoh's resource
/// trees, at a cost that grows with the fleet), which leaves a backlog, and
/// then every vessel's first forecast at once; the window should measure
/// the steady load (docs/performance.md: a whole fleet starting at once).
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

/// What the daemon counted (once it has drained, see [`DRAIN_LIMIT`]).
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
    /// The daemon's own counters (daemon path; none when it did not drain
    /// within [`DRAIN_LIMIT`]).
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

pub(crate) fn vessel_index(id: &str) -> Option<usize> {
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

/// How long the daemon may take to drain its queues once told to stop. A
/// daemon saturated at the window's end can hold minutes of queued work
/// nobody measures: past this, its counters are not reported and the point
/// ends without them.
pub const DRAIN_LIMIT: Duration = Duration::from_secs(15);

/// How long each Zenoh session may take to close, and the runtime to stop
/// its remaining tasks. Closing a session that has declared tens of
/// thousands of keys walks them all; past this the point ends anyway.
pub const CLOSE_LIMIT: Duration = Duration::from_secs(10);

/// How long the generator's threads may take to see the stop and return
/// (a put blocked on a saturated path waits for room).
pub const GENERATOR_STOP_LIMIT: Duration = Duration::from_secs(10);

/// The runtime, the Zenoh sessions and the daemon of one point.
struct Rig {
    /// The daemon's runtime: tokio's multi-threaded scheduler with a worker
    /// per core, as `twind`'s `#[tokio::main]` has.
    rt: tokio::runtime::Runtime,
    /// The daemon's session (daemon path only; it listens).
    daemon: Option<zenoh::Session>,
    /// The generator's session (connects).
    generator: zenoh::Session,
    /// The subscriber's session (connects on the daemon path, listens on
    /// raw Zenoh).
    subscriber: zenoh::Session,
    /// Stops the daemon.
    cancel: CancellationToken,
    /// The daemon's run, once started.
    daemon_task: Option<tokio::task::JoinHandle<anyhow::Result<twind::RunSummary>>>,
}

impl Rig {
    /// The runtime and the three sessions (two on raw Zenoh), linked on a
    /// free loopback port.
    fn open(path: Path) -> anyhow::Result<Self> {
        let rt = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(crate::machine::cores())
            .thread_name("twind-rt")
            .enable_all()
            .build()
            .context("building the daemon's runtime")?;
        let port = free_port()?;
        let open = |listen: &[u16], connect: &[u16]| -> anyhow::Result<zenoh::Session> {
            let config = zenoh_config(listen, connect)?;
            rt.block_on(async { zenoh::open(config).await })
                .map_err(|e| anyhow::anyhow!("opening a Zenoh session: {e}"))
        };
        let (daemon, generator, subscriber) = match path {
            Path::Daemon => {
                let daemon = open(&[port], &[])?;
                (Some(daemon), open(&[], &[port])?, open(&[], &[port])?)
            }
            Path::Raw => {
                let subscriber = open(&[port], &[])?;
                (None, open(&[], &[port])?, subscriber)
            }
        };
        Ok(Self {
            rt,
            daemon,
            generator,
            subscriber,
            cancel: CancellationToken::new(),
            daemon_task: None,
        })
    }

    /// Starts twind on the daemon's session (daemon path).
    fn start_daemon(&mut self, settings: &twind::settings::Settings) {
        if let Some(session) = &self.daemon {
            self.daemon_task = Some(self.rt.spawn(twind::run(twind::RunConfig::new(
                settings.clone(),
                session.clone(),
                self.cancel.clone(),
            ))));
        }
    }

    /// Waits until the generator's session sees the subscriber and, on the
    /// daemon's path, the daemon's session sees the fault subscriber before
    /// the first vessel task declares its keys.
    fn wait_until_matched(
        &self,
        first_gnss: &KeyExpr<'static>,
        keys: &KeySpace,
    ) -> anyhow::Result<()> {
        self.rt.block_on(async {
            probe(&self.generator, first_gnss.clone()).await?;
            if let Some(d) = &self.daemon {
                let fault = keys.twin_fault(&VesselId::new(&vessel_id(0))?);
                probe(d, KeyExpr::try_from(fault).map_err(zerr("a fault key"))?).await?;
            }
            anyhow::Ok(())
        })
    }

    /// Stops the daemon (it drains its queues, at most [`DRAIN_LIMIT`]),
    /// closes the sessions (each at most [`CLOSE_LIMIT`]) and the runtime:
    /// decide, tell, wait, and the sessions last. Returns the daemon's
    /// counters when it drained in time.
    fn shut_down(self) -> anyhow::Result<Option<DaemonCounters>> {
        let Self {
            rt,
            daemon,
            generator,
            subscriber,
            cancel,
            daemon_task,
        } = self;
        cancel.cancel();
        let counters = rt.block_on(async {
            let summary = match daemon_task {
                Some(task) => match tokio::time::timeout(DRAIN_LIMIT, task).await {
                    Ok(joined) => Some(joined.context("the daemon's task failed")??),
                    Err(_) => {
                        eprintln!(
                            "twin-bench: the daemon did not drain within {DRAIN_LIMIT:?}; its counters are not reported"
                        );
                        None
                    }
                },
                None => None,
            };
            for s in [Some(&generator), Some(&subscriber), daemon.as_ref()]
                .into_iter()
                .flatten()
            {
                if tokio::time::timeout(CLOSE_LIMIT, s.close()).await.is_err() {
                    eprintln!("twin-bench: a Zenoh session did not close within {CLOSE_LIMIT:?}");
                }
            }
            anyhow::Ok(summary.as_ref().map(DaemonCounters::of))
        })?;
        rt.shutdown_timeout(CLOSE_LIMIT);
        Ok(counters)
    }
}

/// Declares a publisher on `key`, waits until it has a subscriber, and
/// undeclares it.
async fn probe(session: &zenoh::Session, key: KeyExpr<'static>) -> anyhow::Result<()> {
    let probe = session
        .declare_publisher(key)
        .await
        .map_err(zerr("declaring the probe"))?;
    wait_matching(&probe, Duration::from_secs(20)).await?;
    probe
        .undeclare()
        .await
        .map_err(zerr("undeclaring the probe"))
}

impl DaemonCounters {
    /// The daemon's counters over every vessel and its own refusals.
    fn of(summary: &twind::RunSummary) -> Self {
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
    }
}

/// Every vessel's keys, as the generator puts on them (`[actuators, gnss]`)
/// and as the subscriber receives on them (daemon path: `twin/fault`).
///
/// On the daemon's path the generator puts through its session on each
/// vessel's key, declared to that session (`declare_keyexpr`, not announced
/// when declared) so that its routing finds a node with a cached route, as
/// the daemon declares its own (see twind's `vessel.rs`): with Zenoh 1.10 a
/// key that is not a node is routed by a walk over every node under `asv/`,
/// each vessel's liveliness token among them, and one session standing in
/// for N vessels would pay that N times over. Not one declared publisher per
/// key, as `twin-replay` has in its own session: 2 N publishers in one
/// session cost O(N^2) to declare in Zenoh 1.10 (an artefact of one process
/// standing in for N vessels, each of which would have its own session with
/// two publishers). The subscriber, standing for a program that watches the
/// fleet, declares the keys it receives on to its own session for the same
/// reason (docs/deploy.md advises it for such programs).
///
/// Raw Zenoh has no tokens, so no per-vessel node for an undeclared key's
/// routing to walk: its keys stay strings, as a plain Zenoh program's would.
/// Declaring them costs O(N^2) too (the session searches its declared keys
/// one by one): 4 N declarations at 40,000 vessels took longer than a point
/// may.
struct VesselKeys {
    sent: Vec<[KeyExpr<'static>; 2]>,
    /// Held until the point ends.
    _received: Vec<KeyExpr<'static>>,
}

impl VesselKeys {
    fn declare(rig: &Rig, path: Path, keys: &KeySpace, n: usize) -> anyhow::Result<Self> {
        let declare = |session: &zenoh::Session, k: String| -> anyhow::Result<KeyExpr<'static>> {
            match path {
                Path::Daemon => session
                    .declare_keyexpr(k)
                    .wait()
                    .map_err(zerr("declaring a vessel's key")),
                Path::Raw => KeyExpr::try_from(k).map_err(zerr("a vessel's key")),
            }
        };
        let mut sent = Vec::with_capacity(n);
        let mut received = Vec::with_capacity(n);
        for v in 0..n {
            let id = VesselId::new(&vessel_id(v))?;
            sent.push([
                declare(&rig.generator, keys.actuators(&id))?,
                declare(&rig.generator, keys.gnss(&id))?,
            ]);
            if path == Path::Daemon {
                received.push(declare(&rig.subscriber, keys.twin_fault(&id))?);
            }
        }
        Ok(Self {
            sent,
            _received: received,
        })
    }
}

/// The load generator's threads and what they share with this one.
struct Load {
    threads: Vec<JoinHandle<()>>,
    shared: Arc<GenShared>,
}

impl Load {
    /// Starts the generator. Raw Zenoh: one thread per core (each with a
    /// contiguous share of the fleet, all through the one session), since
    /// one thread alone cannot load Zenoh to its limit. The daemon path: one
    /// thread, which uses under a third of a core there, while a second one
    /// through the same session cost about 8 % of a core more in contention
    /// (at 5,000 vessels x 10 Hz): CPU taken from the daemon.
    fn start(
        spec: &PointSpec,
        session: &zenoh::Session,
        mut keys_left: Vec<[KeyExpr<'static>; 2]>,
        fleet: Fleet,
        clock: &Clock,
    ) -> anyhow::Result<Self> {
        let n = keys_left.len();
        let threads = match spec.path {
            Path::Raw => std::thread::available_parallelism().map_or(1, |c| c.get()),
            Path::Daemon => 1,
        };
        let share = n.div_ceil(threads.clamp(1, n));
        let fleet = Arc::new(fleet);
        let shared = Arc::new(GenShared::default());
        let mut handles = Vec::new();
        while !keys_left.is_empty() {
            let k = handles.len();
            let rest = keys_left.split_off(share.min(keys_left.len()));
            let generator = Generator {
                session: session.clone(),
                keys: std::mem::replace(&mut keys_left, rest),
                first_vessel: k * share,
                seed: 0x7717_b0a7 + k as u64,
                fleet: fleet.clone(),
                rate_hz: spec.rate_hz,
                start: clock.start,
                epoch_s: clock.epoch_s,
                window: clock.window.clone(),
                shared: shared.clone(),
            };
            handles.push(
                std::thread::Builder::new()
                    .name(format!("bench-gen-{k}"))
                    .spawn(move || generator.run())
                    .context("starting the generator")?,
            );
        }
        Ok(Self {
            threads: handles,
            shared,
        })
    }

    /// The generator's lag behind its schedule now, ms.
    fn lag_ms(&self) -> f64 {
        self.shared.lag_us.load(Ordering::Relaxed) as f64 / 1e3
    }

    /// Tells the threads to stop.
    fn stop(&self) {
        self.shared.stop.store(true, Ordering::Relaxed);
    }

    /// Waits for the threads to stop, at most [`GENERATOR_STOP_LIMIT`] (a
    /// thread still blocked then is left to end with the process).
    fn join(self) -> anyhow::Result<()> {
        self.stop();
        let deadline = Instant::now() + GENERATOR_STOP_LIMIT;
        while self.threads.iter().any(|t| !t.is_finished()) && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(10));
        }
        for t in self.threads {
            if t.is_finished() {
                t.join()
                    .map_err(|_| anyhow::anyhow!("the generator panicked"))?;
            } else {
                eprintln!(
                    "twin-bench: a generator thread did not stop within {GENERATOR_STOP_LIMIT:?}"
                );
            }
        }
        Ok(())
    }
}

/// The point's time base: the instant every stamp counts from, the Unix
/// second it stands for, and the measurement window on it.
struct Clock {
    start: Instant,
    epoch_s: f64,
    window: Arc<Window>,
}

impl Clock {
    fn now_us(&self) -> i64 {
        self.start.elapsed().as_micros() as i64
    }

    /// Sleeps until `t_us` on this clock.
    fn sleep_until(&self, t_us: i64) {
        let now = self.now_us();
        if t_us > now {
            std::thread::sleep(Duration::from_micros((t_us - now) as u64));
        }
    }
}

/// How the warm-up went.
struct WarmUp {
    used_s: f64,
    capped: bool,
    vessels_heard_at_start: usize,
    generator_lag_at_start_ms: f64,
}

/// Warm-up: at least `warmup_s`, and until every vessel has been heard from
/// (every daemon task started and publishing) and, paced, the generator is
/// back on its schedule and what it sends comes back promptly (the start-up
/// backlog has drained; [`caught_up`]), up to [`WARMUP_CAP`] times.
fn warm_up(spec: &PointSpec, receiver: &Receiver, load: &Load) -> anyhow::Result<WarmUp> {
    let warm_start = Instant::now();
    let cap = Duration::from_secs_f64(spec.warmup_s * WARMUP_CAP);
    let least = Duration::from_secs_f64(spec.warmup_s);
    let mut on_schedule = 0;
    let capped = loop {
        let elapsed = warm_start.elapsed();
        let (heard, newest_latency_ns) = {
            let st = receiver.lock();
            (st.heard, st.newest_latency_ns)
        };
        let latency_ms = newest_latency_ns as f64 / 1e6;
        on_schedule = if caught_up(spec.rate_hz.is_some(), load.lag_ms(), latency_ms) {
            on_schedule + 1
        } else {
            0
        };
        if elapsed >= least && heard >= spec.vessels && on_schedule >= CAUGHT_UP_SAMPLES {
            break false;
        }
        if elapsed >= cap {
            break true;
        }
        anyhow::ensure!(
            !load.threads.iter().any(JoinHandle::is_finished),
            "the generator stopped during the warm-up"
        );
        std::thread::sleep(Duration::from_millis(20));
    };
    let warm = WarmUp {
        used_s: warm_start.elapsed().as_secs_f64(),
        capped,
        vessels_heard_at_start: receiver.lock().heard,
        generator_lag_at_start_ms: load.lag_ms(),
    };
    load.shared.max_lag_us.store(0, Ordering::Relaxed);
    Ok(warm)
}

/// What the process did during the window.
struct WindowFigures {
    window_s: f64,
    cpu_pct_of_core: Option<f64>,
    cpu_pct_by_group: BTreeMap<String, f64>,
    rss_end_kib: Option<u64>,
    forecasts: u64,
}

/// Opens the window, sleeps through it and the grace period, and closes
/// the receiver: the process's CPU and RSS over the window, and the
/// forecasts computed in it.
fn measure_window(spec: &PointSpec, clock: &Clock, receiver: &Receiver) -> WindowFigures {
    let threads_before = procstat::thread_ticks();
    let cpu_before = procstat::process_ticks();
    let forecasts_before = twind::forecast::computed_total();
    let w0 = clock.now_us();
    let w1 = w0 + (spec.window_s * 1e6) as i64;
    clock.window.start_us.store(w0, Ordering::Release);
    clock.window.end_us.store(w1, Ordering::Release);
    clock.sleep_until(w1);
    let forecasts = twind::forecast::computed_total() - forecasts_before;
    let cpu_after = procstat::process_ticks();
    let threads_after = procstat::thread_ticks();
    let rss_end_kib = procstat::rss_kib();
    let window_s = (w1 - w0) as f64 * 1e-6;
    clock.sleep_until(w1 + (spec.grace_s * 1e6) as i64);
    receiver.closed.store(true, Ordering::Release);
    let pct = |ticks: u64| ticks as f64 / procstat::TICKS_PER_S / window_s * 100.0;
    WindowFigures {
        window_s,
        cpu_pct_of_core: match (cpu_before, cpu_after) {
            (Some(b), Some(a)) => Some(pct(a.saturating_sub(b))),
            _ => None,
        },
        cpu_pct_by_group: procstat::group_ticks(&threads_before, &threads_after)
            .into_iter()
            .map(|(g, t)| (g, pct(t)))
            .collect(),
        rss_end_kib,
        forecasts,
    }
}

/// Everything one point measured, before the daemon's counters.
fn point_result(
    spec: &PointSpec,
    circle: &Circle,
    warm: &WarmUp,
    w: WindowFigures,
    receiver: &Receiver,
    load: &Load,
    rss_base_kib: Option<u64>,
) -> PointResult {
    let n = spec.vessels;
    let shared = &load.shared;
    let window_s = w.window_s;
    let fixes_sent = shared.fixes_in_window.load(Ordering::Relaxed);
    let sent_total = shared.sent.load(Ordering::Relaxed).max(1) as f64;
    let st = receiver.lock();
    let per_vessel_delivered: Vec<u32> = st.vessels.iter().map(|v| v.delivered).collect();
    PointResult {
        spec: *spec,
        circle_speed_mps: circle.speed_mps,
        circle_radius_m: circle.radius_m(),
        circle_rpm: circle.rpm,
        warmup_used_s: warm.used_s,
        warmup_capped: warm.capped,
        generator_lag_at_start_ms: spec.rate_hz.map(|_| warm.generator_lag_at_start_ms),
        window_s,
        fixes_sent,
        actuators_sent: shared.actuators_in_window.load(Ordering::Relaxed),
        planned_fixes_per_s: spec.rate_hz.map(|r| r * n as f64),
        offered_fixes_per_s: fixes_sent as f64 / window_s,
        received_per_s: st.received_in_window as f64 / window_s,
        delivered: st.delivered,
        repeats: st.repeats,
        unparsable: st.unparsable,
        unparsable_first: st.unparsable_first.clone(),
        vessels_delivered: per_vessel_delivered.iter().filter(|&&d| d > 0).count(),
        vessels_heard: st.heard,
        vessels_heard_at_start: warm.vessels_heard_at_start,
        per_vessel_delivered,
        latency: Latency::of(&st.latency),
        generator_max_lag_ms: spec
            .rate_hz
            .map(|_| shared.max_lag_us.load(Ordering::Relaxed) as f64 / 1e3),
        cpu_pct_of_core: w.cpu_pct_of_core,
        cpu_pct_by_group: w.cpu_pct_by_group,
        rss_base_kib,
        rss_end_kib: w.rss_end_kib,
        gnss_bytes_mean: shared.gnss_bytes.load(Ordering::Relaxed) as f64 / sent_total,
        actuators_bytes_mean: shared.actuators_bytes.load(Ordering::Relaxed) as f64 / sent_total,
        received_bytes_mean: if st.measured_count > 0 {
            st.measured_bytes as f64 / st.measured_count as f64
        } else {
            0.0
        },
        daemon: None,
        generator_threads: load.threads.len(),
        forecasts_per_s: matches!(spec.path, Path::Daemon).then(|| w.forecasts as f64 / window_s),
    }
}

/// Checks what a point asks for.
fn validate(spec: &PointSpec) -> anyhow::Result<()> {
    anyhow::ensure!((1..=99_999).contains(&spec.vessels), "1 to 99,999 vessels");
    anyhow::ensure!(
        spec.window_s > 0.0 && spec.warmup_s >= 0.0 && spec.grace_s >= 0.0,
        "window, warm-up and grace must be positive"
    );
    if let Some(r) = spec.rate_hz {
        anyhow::ensure!(r > 0.0 && r.is_finite(), "the rate must be positive");
    }
    Ok(())
}

/// Runs one point: sets up the sessions (and the daemon), declares the
/// keys, starts the load, warms up, measures one window, and shuts
/// everything down in order (see [`Rig::shut_down`]).
pub fn measure(spec: &PointSpec) -> anyhow::Result<PointResult> {
    validate(spec)?;
    let circle = Circle::from_simulator(FLEET_SPEED_MPS)?;
    let fleet = Fleet::new(circle, spec.vessels)?;
    let keys = KeySpace::new("asv")?;
    let settings = bench_settings(spec.vessel_liveliness, spec.liveliness_outside_prefix)?;
    let mut rig = Rig::open(spec.path)?;
    let clock = Clock {
        start: Instant::now(),
        epoch_s: SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .context("the system clock is before 1970")?
            .as_secs() as f64,
        window: Arc::new(Window::new()),
    };
    let receiver = Arc::new(Receiver::new(
        spec.path,
        spec.vessels,
        clock.start,
        clock.epoch_s,
        clock.window.clone(),
    ));
    rig.start_daemon(&settings);
    let subscriber = subscribe(&rig, spec.path, &keys, &settings, receiver.clone())?;
    let vessel_keys = VesselKeys::declare(&rig, spec.path, &keys, spec.vessels)?;
    rig.wait_until_matched(&vessel_keys.sent[0][1], &keys)?;

    let rss_base_kib = procstat::rss_kib();
    let load = Load::start(
        spec,
        &rig.generator,
        vessel_keys.sent.clone(),
        fleet,
        &clock,
    )?;
    let warm = warm_up(spec, &receiver, &load)?;
    let window = measure_window(spec, &clock, &receiver);
    load.stop();
    let result = point_result(spec, &circle, &warm, window, &receiver, &load, rss_base_kib);
    let errors = load.shared.errors.load(Ordering::Relaxed);
    load.join()?;
    anyhow::ensure!(errors == 0, "{errors} messages could not be encoded or put");
    subscriber
        .undeclare()
        .wait()
        .map_err(zerr("undeclaring the subscriber"))?;
    let daemon = rig.shut_down()?;
    Ok(PointResult { daemon, ..result })
}

/// The subscriber of what the point measures: faults on the daemon's path,
/// the fixes themselves on raw Zenoh.
fn subscribe(
    rig: &Rig,
    path: Path,
    keys: &KeySpace,
    settings: &twind::settings::Settings,
    receiver: Arc<Receiver>,
) -> anyhow::Result<Subscriber<()>> {
    let key = match path {
        Path::Daemon => keys.all_vessels(Topic::TwinFault),
        Path::Raw => twind::input_key_expr(settings),
    };
    rig.subscriber
        .declare_subscriber(key)
        .callback(move |s| receiver.on_sample(&s))
        .wait()
        .map_err(zerr("subscribing"))
}

/// The runtime the benchmarks run the daemon on: a worker per core.
pub fn daemon_runtime() -> anyhow::Result<tokio::runtime::Runtime> {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(crate::machine::cores())
        .thread_name("twind-rt")
        .enable_all()
        .build()
        .context("building the daemon's runtime")
}

/// A loopback Zenoh session on `rt`, listening on and connecting to the
/// given local ports.
pub fn open_session(
    rt: &tokio::runtime::Runtime,
    listen: &[u16],
    connect: &[u16],
) -> anyhow::Result<zenoh::Session> {
    let config = zenoh_config(listen, connect)?;
    rt.block_on(async { zenoh::open(config).await })
        .map_err(|e| anyhow::anyhow!("opening a Zenoh session: {e}"))
}

#[cfg(test)]
mod tests {
    use super::super::receiver::{Receiver, Window};
    use super::{CAUGHT_UP_LAG_MS, Path, caught_up};
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
