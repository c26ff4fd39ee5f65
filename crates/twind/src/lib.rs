//! `twind`: the live digital-twin daemon.
//!
//! # Layout
//! - [`settings`]: the daemon's own settings (`config/twind.toml`), raw and
//!   validated.
//! - [`vessel`]: one task per vessel owning that vessel's twin.
//! - [`demo`]: `twind --demo`, the daemon with bundled trials replayed
//!   through an embedded peer.
//! - [`forecast`]: the forecast threads, off the fault path.
//! - [`persist`]: calibration files saved and restored per vessel.
//! - [`fleet`]: with `[fleet] enabled`, the election of each vessel's
//!   active owner among the daemons sharing a fleet (hot standbys), and the
//!   fleet's report of overlapping shares and vessels without an owner.
//! - [`ros2`]: with `[ros2] enabled`, the outputs as ROS 2 messages and
//!   GNSS input from ROS 2, over rmw_zenoh on the same session.
//! - [`metrics`]: the Prometheus metrics (`GET /metrics`).
//! - [`notify`]: systemd's notifications (ready, watchdog, stopping).
//! - [`stats`]: counting and rate-limited logging of rejections.
//! - [`record`]: `--record FILE`, inputs and outputs into an MCAP file.
//! - [`signalk`]: the estimates pushed to a Signal K server (`[signalk]`).
//! - [`web`]: the operator's page (HTTP and server-sent events), served
//!   from the outputs the daemon publishes.
//! - `dispatch`: the dispatcher, in the input subscriber's callback:
//!   routes each message, in arrival order, to its vessel's task, and counts
//!   what is in flight (the forecast threads yield while the fault path does
//!   not keep up: [`forecast::FaultPathLoad`]).
//! - [`run`] (here): one Zenoh subscriber for every input topic of the
//!   vessels this daemon owns, with the dispatcher as its callback; the
//!   queryable for the latest state, fault, alarm and finding; the
//!   graceful shutdown.
//!
//! # Shutdown
//! Decide, tell, wait (tokio's guide): the caller cancels the token; `run`
//! undeclares the input subscriber (every message Zenoh delivered has been
//! routed by then) and closes the dispatcher, which closes every vessel's
//! queue; every vessel task drains its queue, publishes a last state and
//! saves its calibration; `run` waits for all of them and returns. The
//! caller closes the Zenoh session last. Nothing received is lost.
//!
//! # Invariants
//! The daemon never crashes on input from the network: every payload is
//! size-checked before parsing, every parse error and estimator rejection is
//! a typed reason, counted per vessel (published on `twin/stats`) and logged
//! at most once a minute per reason. Messages for vessel ids that are not
//! plain names are refused and counted by the daemon.

pub mod demo;
mod dispatch;
pub mod fleet;
pub mod forecast;
pub mod metrics;
pub mod notify;
pub mod persist;
pub mod record;
pub mod ros2;
pub mod settings;
pub mod signalk;
pub mod stats;
pub mod vessel;
pub mod web;

use std::collections::HashMap;
use std::sync::{Arc, Mutex, RwLock};

use tokio::sync::mpsc;
use tokio_util::sync::CancellationToken;
use tokio_util::task::TaskTracker;
use twin_wire::Topic;
use zenoh::Session;
use zenoh::bytes::Encoding;
use zenoh::key_expr::KeyExpr;

use crate::settings::Settings;
use crate::stats::Counters;

/// The latest state payload of every vessel, for the queryable and the web
/// page. Each vessel writes its own slot, registered once, so the fixes of
/// different vessels never wait on one lock (the map's write lock is taken
/// only when a vessel is first seen).
#[derive(Debug, Clone, Default)]
pub struct LatestStates(Arc<RwLock<HashMap<String, StateSlot>>>);

/// One vessel's latest state payload (empty until its first state).
#[derive(Debug, Clone, Default)]
pub struct StateSlot(Arc<Mutex<Vec<u8>>>);

impl LatestStates {
    /// The slot of `vessel`, made empty the first time.
    pub fn slot(&self, vessel: &str) -> StateSlot {
        if let Ok(map) = self.0.read()
            && let Some(slot) = map.get(vessel)
        {
            return slot.clone();
        }
        match self.0.write() {
            Ok(mut map) => map.entry(vessel.to_string()).or_default().clone(),
            // A poisoned map: a slot of its own, written but never read.
            Err(_) => StateSlot::default(),
        }
    }

    /// The vessels with a state, sorted.
    pub fn vessels(&self) -> Vec<String> {
        let mut ids: Vec<String> = match self.0.read() {
            Ok(map) => map
                .iter()
                .filter(|(_, slot)| slot.0.lock().is_ok_and(|b| !b.is_empty()))
                .map(|(id, _)| id.clone())
                .collect(),
            Err(_) => Vec::new(),
        };
        ids.sort();
        ids
    }

    /// Every vessel's latest state, sorted by vessel; vessels without a
    /// state yet are left out.
    pub fn snapshot(&self) -> Vec<(String, Vec<u8>)> {
        let slots: Vec<(String, StateSlot)> = match self.0.read() {
            Ok(map) => map.iter().map(|(k, v)| (k.clone(), v.clone())).collect(),
            Err(_) => Vec::new(),
        };
        let mut out: Vec<(String, Vec<u8>)> = slots
            .into_iter()
            .filter_map(|(vessel, slot)| {
                let json = slot.0.lock().ok()?.clone();
                (!json.is_empty()).then_some((vessel, json))
            })
            .collect();
        out.sort_by(|a, b| a.0.cmp(&b.0));
        out
    }
}

impl StateSlot {
    /// Replaces the payload (reusing the slot's allocation).
    pub fn set(&self, json: &[u8]) {
        if let Ok(mut bytes) = self.0.lock() {
            bytes.clear();
            bytes.extend_from_slice(json);
        }
    }
}

/// The latest fault, alarm and finding of every vessel, for the queryable:
/// a controller or an operator that starts after the last alarm learns at
/// once that a propeller is in fault (the fault gives both thrusters'
/// status; the alarm is the last status change). One reply per key, as a
/// query's default consolidation keeps. Each vessel writes its own slot, as
/// with [`LatestStates`].
#[derive(Debug, Clone, Default)]
pub struct LatestOutputs(Arc<RwLock<HashMap<String, OutputSlot>>>);

/// One vessel's latest outputs (each empty until its first).
#[derive(Debug, Clone, Default)]
pub struct OutputSlot(Arc<Mutex<[Vec<u8>; 3]>>);

/// Which of a vessel's latest outputs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kept {
    /// `twin/fault`.
    Fault,
    /// `twin/alarm`.
    Alarm,
    /// `twin/finding`.
    Finding,
}

impl Kept {
    /// Every kind, in the slot's order.
    pub const ALL: [Kept; 3] = [Kept::Fault, Kept::Alarm, Kept::Finding];

    /// The topic it is published on.
    pub fn topic(self) -> Topic {
        match self {
            Kept::Fault => Topic::TwinFault,
            Kept::Alarm => Topic::TwinAlarm,
            Kept::Finding => Topic::TwinFinding,
        }
    }

    fn index(self) -> usize {
        self as usize
    }
}

impl LatestOutputs {
    /// The slot of `vessel`, made empty the first time.
    pub fn slot(&self, vessel: &str) -> OutputSlot {
        if let Ok(map) = self.0.read()
            && let Some(slot) = map.get(vessel)
        {
            return slot.clone();
        }
        match self.0.write() {
            Ok(mut map) => map.entry(vessel.to_string()).or_default().clone(),
            Err(_) => OutputSlot::default(),
        }
    }

    /// Every vessel's latest outputs, sorted by vessel then kind; empty
    /// ones left out.
    pub fn snapshot(&self) -> Vec<(String, Kept, Vec<u8>)> {
        let slots: Vec<(String, OutputSlot)> = match self.0.read() {
            Ok(map) => map.iter().map(|(k, v)| (k.clone(), v.clone())).collect(),
            Err(_) => Vec::new(),
        };
        let mut out = Vec::new();
        for (vessel, slot) in slots {
            let Ok(kept) = slot.0.lock() else { continue };
            for kind in Kept::ALL {
                let bytes = &kept[kind.index()];
                if !bytes.is_empty() {
                    out.push((vessel.clone(), kind, bytes.clone()));
                }
            }
        }
        out.sort_by(|a, b| (&a.0, a.1.index()).cmp(&(&b.0, b.1.index())));
        out
    }
}

impl OutputSlot {
    /// Replaces the payload of `kind`.
    pub fn set(&self, kind: Kept, json: &[u8]) {
        if let Ok(mut kept) = self.0.lock() {
            let bytes = &mut kept[kind.index()];
            bytes.clear();
            bytes.extend_from_slice(json);
        }
    }
}

/// Calibrations that could not be saved or restored, across the daemon:
/// the failed saves counted (on the daemon's statistics), and each kind
/// logged at most once a minute, so that a full disk or a missing directory
/// writes one line a minute, not one per vessel per save.
#[derive(Debug, Clone)]
pub struct SaveFailures(Arc<Mutex<StorageLog>>);

#[derive(Debug)]
struct StorageLog {
    failed_saves: u64,
    saves: crate::stats::RateLimit,
    loads: crate::stats::RateLimit,
}

impl Default for SaveFailures {
    fn default() -> Self {
        let limit = || crate::stats::RateLimit::new(crate::stats::LOG_EVERY, 1);
        Self(Arc::new(Mutex::new(StorageLog {
            failed_saves: 0,
            saves: limit(),
            loads: limit(),
        })))
    }
}

impl SaveFailures {
    /// Counts a failed save of `vessel` and logs it if a minute has passed
    /// since the last one logged.
    pub fn failed(&self, vessel: &str, error: &dyn std::fmt::Display) {
        let Ok(mut log) = self.0.lock() else {
            return;
        };
        log.failed_saves += 1;
        let failures = log.failed_saves;
        if let Some(not_logged) = log.saves.check(std::time::Instant::now()) {
            tracing::error!(
                vessel,
                failures,
                not_logged,
                "calibration not saved: {error}"
            );
        }
    }

    /// Logs that the calibration of `vessel` was not restored, if a minute
    /// has passed since the last such line.
    pub fn not_restored(&self, vessel: &str, error: &dyn std::fmt::Display) {
        let Ok(mut log) = self.0.lock() else {
            return;
        };
        if let Some(not_logged) = log.loads.check(std::time::Instant::now()) {
            tracing::warn!(vessel, not_logged, "calibration not restored: {error}");
        }
    }

    /// Failed saves so far.
    pub fn count(&self) -> u64 {
        self.0.lock().map_or(0, |log| log.failed_saves)
    }
}

/// One output as published, handed to in-process listeners (the web page).
#[derive(Debug, Clone)]
pub struct OutputEvent {
    /// Vessel id.
    pub vessel: String,
    /// Which output topic.
    pub topic: Topic,
    /// The JSON payload.
    pub json: Arc<str>,
}

/// Where outputs are copied for in-process listeners; `None` copies nothing.
pub type OutputTap = Option<tokio::sync::broadcast::Sender<OutputEvent>>;

/// What a run did, for the caller's final log line and for tests.
#[derive(Debug, Default, Clone)]
pub struct RunSummary {
    /// Messages received on the input subscription.
    pub received: u64,
    /// Messages the daemon refused before any vessel's twin saw them (bad
    /// key, a vessel not admitted: invalid first message, too many vessels,
    /// admission rate), by reason.
    pub refused: Counters,
    /// Messages routed to vessels.
    pub routed: u64,
    /// ROS 2 input messages their publishers numbered but that never
    /// arrived (see `DaemonStatsMessage::ros2_missed`).
    pub ros2_missed: u64,
    /// Per-vessel counters of every vessel task that ended.
    pub vessels: HashMap<String, Counters>,
    /// What the Signal K output did, when it was on.
    pub signalk: Option<crate::signalk::SignalkStats>,
    /// What the recording wrote, when there was one.
    pub record: Option<crate::record::RecordSummary>,
}

/// The key expression of every input message of the owned vessels:
/// `{prefix}/{own}/*` (the last chunk is the topic; outputs under
/// `twin/...` have one chunk more and do not match).
pub fn input_key_expr(settings: &Settings) -> String {
    format!("{}/{}/*", settings.keys.prefix(), settings.vessels.own)
}

/// Everything a run of the daemon needs: its settings, an open Zenoh
/// session, the token that stops it, and where in-process listeners (the web
/// page, tests, the benchmark) see what it does.
pub struct RunConfig {
    /// The daemon's validated settings.
    pub settings: Settings,
    /// An open Zenoh session; the caller closes it after [`run`] returns.
    pub session: Session,
    /// Cancelled by the caller to stop the daemon (it drains first).
    pub shutdown: CancellationToken,
    /// Where every output is copied for in-process listeners (`None`: nowhere).
    pub tap: OutputTap,
    /// The latest state of every vessel (shared with the web page).
    pub latest: LatestStates,
    /// Whether the fault path keeps up; the forecast threads yield to it and
    /// the caller can read it.
    pub load: crate::forecast::FaultPathLoad,
    /// The daemon's metrics, filled by the run (the caller serves them).
    pub metrics: crate::metrics::Metrics,
    /// Tells systemd when the daemon serves, that it lives, and when it
    /// stops (disabled unless the caller enables it).
    pub notify: crate::notify::Notifier,
    /// Record inputs and outputs into this MCAP file ([`record`]).
    pub record: Option<std::path::PathBuf>,
}

impl RunConfig {
    /// A run with no output tap, its own latest states and its own load gauge.
    pub fn new(settings: Settings, session: Session, shutdown: CancellationToken) -> Self {
        Self {
            settings,
            session,
            shutdown,
            tap: None,
            latest: LatestStates::default(),
            load: crate::forecast::FaultPathLoad::new(),
            metrics: crate::metrics::Metrics::default(),
            notify: crate::notify::Notifier::disabled(),
            record: None,
        }
    }
}

/// Runs the daemon until `config.shutdown` is cancelled, then drains every
/// vessel and returns what it did.
pub async fn run(config: RunConfig) -> anyhow::Result<RunSummary> {
    let RunConfig {
        settings,
        session,
        shutdown,
        tap,
        latest,
        load,
        metrics,
        notify,
        record,
    } = config;
    let settings = Arc::new(settings);
    let (tap, signalk) = crate::signalk::attach(settings.signalk.as_ref(), tap);
    let daemon_id = match &settings.daemon.id {
        Some(id) => id.clone(),
        None => session.zid().to_string(),
    };
    let daemon_stats_key = settings.keys.daemon_stats(
        &twin_wire::VesselId::new(&daemon_id)
            .map_err(|e| anyhow::anyhow!("the daemon's id {daemon_id:?}: {e}"))?,
    );
    // In a fleet, the other daemons are known before anything is served.
    let (fleet, fleet_membership) =
        crate::fleet::join(&session, &settings, &daemon_id, shutdown.clone()).await?;
    // One queryable for the outputs kept (state, fault, alarm, finding).
    let outputs_key = format!("{}/{}/twin/*", settings.keys.prefix(), settings.vessels.own);
    let queryable = session
        .declare_queryable(&outputs_key)
        .await
        .map_err(|e| anyhow::anyhow!("cannot declare the queryable {outputs_key}: {e}"))?;

    let forecaster =
        crate::forecast::Forecaster::start(settings.publish.forecast_threads, load.clone())
            .map_err(|e| anyhow::anyhow!("cannot start the forecast threads: {e}"))?;
    let tracker = TaskTracker::new();
    let (done_tx, mut done_rx) = mpsc::unbounded_channel::<(String, Counters)>();
    // Diagnoses are CPU-heavy (seconds each): this bounds how many run at once.
    let diagnose_slots = Arc::new(tokio::sync::Semaphore::new(
        settings.diagnose.max_concurrent,
    ));
    let outputs = LatestOutputs::default();
    let save_failures = SaveFailures::default();
    let ros2 = settings
        .ros2
        .enabled
        .then(|| Arc::new(crate::ros2::Ros2Node::new(settings.ros2.clone(), &session)));
    let ros2_token = match &ros2 {
        Some(node) => Some(
            session
                .liveliness()
                .declare_token(node.token_key())
                .await
                .map_err(|e| anyhow::anyhow!("cannot declare the ROS 2 node's token: {e}"))?,
        ),
        None => None,
    };
    let dispatcher = crate::dispatch::Dispatcher::new(
        settings.clone(),
        crate::dispatch::VesselSpawner {
            runtime: tokio::runtime::Handle::current(),
            tracker: tracker.clone(),
            shared: crate::vessel::VesselShared {
                session: session.clone(),
                latest: latest.clone(),
                outputs: outputs.clone(),
                tap,
                diagnose_slots,
                forecaster,
                load: load.clone(),
                save_failures: save_failures.clone(),
                ros2,
                metrics: metrics.clone(),
                fleet: fleet.clone(),
            },
            done_tx,
        },
    );
    metrics.attach(
        daemon_id.clone(),
        dispatcher.clone(),
        save_failures.clone(),
        load,
    );
    // Recording starts before the inputs flow, so it holds the first.
    let recorder = match &record {
        Some(path) => Some(crate::record::Recorder::start(&session, &settings, path).await?),
        None => None,
    };
    let subscriber = {
        let dispatcher = dispatcher.clone();
        session
            .declare_subscriber(input_key_expr(&settings))
            .callback(move |sample| dispatcher.on_sample(&sample))
            .await
            .map_err(|e| {
                anyhow::anyhow!("cannot subscribe to {}: {e}", input_key_expr(&settings))
            })?
    };
    let ros2_input = if settings.ros2.enabled {
        Some(crate::ros2::Ros2Input::start(&session, settings.clone(), dispatcher.clone()).await?)
    } else {
        None
    };
    tracing::info!(
        inputs = %input_key_expr(&settings),
        daemon = %daemon_stats_key,
        "twind running"
    );

    // The queryable answers from the shared maps; it needs no vessel task.
    let answer_latest = tokio::spawn(answer_latest_queries(
        queryable,
        latest.clone(),
        outputs.clone(),
        (settings.keys.clone(), fleet.clone()),
        shutdown.clone(),
    ));
    // Without a token per vessel: one for the daemon, and its vessels on
    // a queryable.
    let daemon_presence = if settings.publish.vessel_liveliness {
        None
    } else {
        Some(DaemonPresence::declare(&session, &settings, &daemon_id, latest.clone(), fleet).await?)
    };

    let publish_daemon_stats = |dispatcher: &crate::dispatch::Dispatcher| {
        let message = dispatcher.daemon_stats(&daemon_id, save_failures.count());
        let put = crate::vessel::encode_json(&message, 1024).map(|bytes| {
            session
                .put(&daemon_stats_key, bytes)
                .encoding(Encoding::APPLICATION_JSON)
        });
        async move {
            match put {
                Ok(put) => {
                    if let Err(e) = put.await {
                        tracing::warn!("daemon statistics not published: {e}");
                    }
                }
                Err(e) => tracing::error!("cannot encode the daemon's statistics: {e}"),
            }
        }
    };
    let mut stats_tick = tokio::time::interval(std::time::Duration::from_secs_f64(
        settings.publish.stats_interval_s,
    ));
    stats_tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut watchdog_tick = notify.watchdog_interval().map(|every| {
        let mut tick = tokio::time::interval(every);
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        tick
    });
    notify.ready();
    loop {
        tokio::select! {
            _ = shutdown.cancelled() => break,
            () = watchdog_due(&mut watchdog_tick) => {
                // Alive: this loop runs and the dispatcher's lock is free
                // (the subscriber's callback is not stuck holding it).
                let _ = dispatcher.queues();
                notify.watchdog();
            }
            Some(done) = done_rx.recv() => {
                let mut ended = vec![done];
                while let Ok(done) = done_rx.try_recv() {
                    ended.push(done);
                }
                dispatcher.forget_ended(ended);
            }
            _ = stats_tick.tick() => publish_daemon_stats(&dispatcher).await,
        }
    }

    notify.stopping();
    // Stop reading first (every sample Zenoh delivered has been routed by
    // the callback), then close the vessels' queues and let every vessel
    // finish.
    if let Err(e) = subscriber.undeclare().await {
        tracing::warn!("the input subscriber was not undeclared: {e}");
    }
    if let Some(input) = ros2_input {
        input.stop().await;
    }
    publish_daemon_stats(&dispatcher).await;
    let mut summary = dispatcher.close();
    tracker.close();
    tracker.wait().await;
    while let Ok((vessel, counters)) = done_rx.try_recv() {
        summary.vessels.insert(vessel, counters);
    }
    if let Some(signalk) = signalk {
        summary.signalk = Some(signalk.finish(std::time::Duration::from_secs(5)).await);
    }
    if let Some(recorder) = recorder {
        summary.record = Some(recorder.finish().await);
    }
    answer_latest.abort();
    drop(ros2_token);
    drop(fleet_membership);
    drop(daemon_presence);
    tracing::info!(
        received = summary.received,
        routed = summary.routed,
        refused = summary.refused.total_rejected(),
        vessels = summary.vessels.len(),
        "twind stopped"
    );
    Ok(summary)
}

/// With `[publish] vessel_liveliness = false`: the daemon's one liveliness
/// token, `{prefix}/@twind/{id}/alive`, and the queryable
/// `{prefix}/@twind/{id}/vessels` that answers the vessels it publishes
/// (JSON `{"daemon": id, "vessels": [ids]}`), in place of a token per
/// vessel (docs/contracts.md: each vessel's token costs every session a
/// walk of the fleet, and a fleet starting at once the square of its size).
struct DaemonPresence {
    _token: zenoh::liveliness::LivelinessToken,
    answer: tokio::task::JoinHandle<()>,
}

impl DaemonPresence {
    async fn declare(
        session: &Session,
        settings: &Settings,
        daemon_id: &str,
        latest: LatestStates,
        fleet: crate::fleet::Fleet,
    ) -> anyhow::Result<Self> {
        let base = format!("{}/@twind/{daemon_id}", settings.keys.prefix());
        let token = session
            .liveliness()
            .declare_token(format!("{base}/alive"))
            .await
            .map_err(|e| anyhow::anyhow!("cannot declare the daemon's token: {e}"))?;
        let key = format!("{base}/vessels");
        let queryable = session
            .declare_queryable(&key)
            .await
            .map_err(|e| anyhow::anyhow!("cannot declare the queryable {key}: {e}"))?;
        let daemon = daemon_id.to_string();
        let answer = tokio::spawn(async move {
            while let Ok(query) = queryable.recv_async().await {
                let vessels: Vec<String> = latest
                    .vessels()
                    .into_iter()
                    .filter(|v| fleet.is_active(v))
                    .collect();
                let body = serde_json::json!({ "daemon": daemon, "vessels": vessels });
                if let Err(e) = query
                    .reply(&key, body.to_string())
                    .encoding(Encoding::APPLICATION_JSON)
                    .await
                {
                    tracing::warn!("query not answered: {e}");
                }
            }
        });
        Ok(Self {
            _token: token,
            answer,
        })
    }
}

impl Drop for DaemonPresence {
    fn drop(&mut self) {
        self.answer.abort();
    }
}

/// The next watchdog tick, or never when systemd does not watch.
async fn watchdog_due(tick: &mut Option<tokio::time::Interval>) {
    match tick {
        Some(t) => {
            t.tick().await;
        }
        None => std::future::pending().await,
    }
}

/// Answers queries on the latest outputs' queryable from the shared maps,
/// until `shutdown` or the queryable ends.
async fn answer_latest_queries(
    queryable: zenoh::query::Queryable<zenoh::handlers::FifoChannelHandler<zenoh::query::Query>>,
    latest: LatestStates,
    outputs: LatestOutputs,
    (keys, fleet): (twin_wire::KeySpace, crate::fleet::Fleet),
    shutdown: CancellationToken,
) {
    loop {
        let query = tokio::select! {
            _ = shutdown.cancelled() => break,
            q = queryable.recv_async() => match q { Ok(q) => q, Err(_) => break },
        };
        let replies = latest_replies(&keys, &latest, &outputs, query.key_expr());
        // In a fleet, only the vessels this daemon is the active owner of.
        for (vessel, key, bytes) in replies {
            if !fleet.is_active(&vessel) {
                continue;
            }
            if let Err(e) = query
                .reply(key, bytes)
                .encoding(Encoding::APPLICATION_JSON)
                .await
            {
                tracing::warn!("query not answered: {e}");
            }
        }
    }
}

/// The replies to a query on `asked`: every kept output (latest state,
/// fault, alarms, finding) whose key it intersects, as (vessel, key,
/// payload).
fn latest_replies(
    keys: &twin_wire::KeySpace,
    latest: &LatestStates,
    outputs: &LatestOutputs,
    asked: &KeyExpr<'_>,
) -> Vec<(String, String, Vec<u8>)> {
    let states = latest
        .snapshot()
        .into_iter()
        .map(|(vessel, bytes)| (vessel, Topic::TwinState, bytes));
    let others = outputs
        .snapshot()
        .into_iter()
        .map(|(vessel, kind, bytes)| (vessel, kind.topic(), bytes));
    states
        .chain(others)
        .filter_map(|(vessel, topic, bytes)| {
            let id = twin_wire::VesselId::new(&vessel).ok()?;
            let key = keys.key(&id, topic);
            let ke = KeyExpr::try_from(key.as_str()).ok()?;
            asked.intersects(&ke).then_some((vessel, key, bytes))
        })
        .collect()
}

/// Helpers shared by the unit tests.
#[cfg(test)]
pub(crate) mod test_support {
    use zenoh::Session;

    /// A session of its own: no links, no scouting.
    pub async fn lone_session() -> Session {
        let mut c = zenoh::Config::default();
        for (key, value) in [
            ("mode", "\"peer\""),
            ("listen/endpoints", "[]"),
            ("connect/endpoints", "[]"),
            ("scouting/multicast/enabled", "false"),
            ("scouting/gossip/enabled", "false"),
        ] {
            c.insert_json5(key, value).unwrap();
        }
        zenoh::open(c).await.unwrap()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn latest_states_keep_each_vessels_newest_sorted_without_empty_slots() {
        let latest = LatestStates::default();
        let b = latest.slot("b");
        let _never_written = latest.slot("c");
        b.set(b"old");
        latest.slot("a").set(b"first");
        b.set(b"new");
        // A second slot for a vessel is the same slot.
        latest.slot("a").set(b"second");
        assert_eq!(
            latest.snapshot(),
            vec![
                ("a".to_string(), b"second".to_vec()),
                ("b".to_string(), b"new".to_vec()),
            ]
        );
    }
}
