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
//! - [`stats`]: counting and rate-limited logging of rejections.
//! - [`web`]: the operator's page (HTTP and server-sent events), served
//!   from the outputs the daemon publishes.
//! - `dispatch`: the dispatcher, in the input subscriber's callback:
//!   routes each message, in arrival order, to its vessel's task, and counts
//!   what is in flight (the forecast threads yield while the fault path does
//!   not keep up: [`forecast::FaultPathLoad`]).
//! - [`run`] (here): one Zenoh subscriber for every input topic of the
//!   vessels this daemon owns, with the dispatcher as its callback; the
//!   queryable for the latest states; the graceful shutdown.
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
pub mod forecast;
pub mod persist;
pub mod settings;
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
    /// Messages the daemon refused before any vessel could be named
    /// (bad key, bad vessel id, too many vessels).
    pub refused: Counters,
    /// Messages routed to vessels.
    pub routed: u64,
    /// Per-vessel counters of every vessel task that ended.
    pub vessels: HashMap<String, Counters>,
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
    } = config;
    let settings = Arc::new(settings);
    let state_key = format!(
        "{}/{}/twin/state",
        settings.keys.prefix(),
        settings.vessels.own
    );
    let queryable = session
        .declare_queryable(&state_key)
        .await
        .map_err(|e| anyhow::anyhow!("cannot declare the queryable {state_key}: {e}"))?;

    let forecaster =
        crate::forecast::Forecaster::start(settings.publish.forecast_threads, load.clone())
            .map_err(|e| anyhow::anyhow!("cannot start the forecast threads: {e}"))?;
    let tracker = TaskTracker::new();
    let (done_tx, mut done_rx) = mpsc::unbounded_channel::<(String, Counters)>();
    // Diagnoses are CPU-heavy (seconds each): this bounds how many run at once.
    let diagnose_slots = Arc::new(tokio::sync::Semaphore::new(
        settings.diagnose.max_concurrent,
    ));
    let dispatcher = crate::dispatch::Dispatcher::new(
        settings.clone(),
        crate::dispatch::VesselSpawner {
            runtime: tokio::runtime::Handle::current(),
            tracker: tracker.clone(),
            shared: crate::vessel::VesselShared {
                session: session.clone(),
                latest: latest.clone(),
                tap,
                diagnose_slots,
                forecaster,
                load,
            },
            done_tx,
        },
    );
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
    tracing::info!(inputs = %input_key_expr(&settings), "twind running");

    // The queryable answers from the shared map; it needs no vessel task.
    let answer_latest = tokio::spawn(answer_state_queries(
        queryable,
        latest.clone(),
        settings.keys.clone(),
        shutdown.clone(),
    ));

    loop {
        tokio::select! {
            _ = shutdown.cancelled() => break,
            Some(done) = done_rx.recv() => {
                let mut ended = vec![done];
                while let Ok(done) = done_rx.try_recv() {
                    ended.push(done);
                }
                dispatcher.forget_ended(ended);
            }
        }
    }

    // Stop reading first (every sample Zenoh delivered has been routed by
    // the callback), then close the vessels' queues and let every vessel
    // finish.
    if let Err(e) = subscriber.undeclare().await {
        tracing::warn!("the input subscriber was not undeclared: {e}");
    }
    let mut summary = dispatcher.close();
    tracker.close();
    tracker.wait().await;
    while let Ok((vessel, counters)) = done_rx.try_recv() {
        summary.vessels.insert(vessel, counters);
    }
    answer_latest.abort();
    tracing::info!(
        routed = summary.routed,
        refused = summary.refused.total_rejected(),
        vessels = summary.vessels.len(),
        "twind stopped"
    );
    Ok(summary)
}

/// Answers queries on the state queryable from the latest states, until
/// `shutdown` or the queryable ends.
async fn answer_state_queries(
    queryable: zenoh::query::Queryable<zenoh::handlers::FifoChannelHandler<zenoh::query::Query>>,
    latest: LatestStates,
    keys: twin_wire::KeySpace,
    shutdown: CancellationToken,
) {
    loop {
        let query = tokio::select! {
            _ = shutdown.cancelled() => break,
            q = queryable.recv_async() => match q { Ok(q) => q, Err(_) => break },
        };
        let replies: Vec<(String, Vec<u8>)> = latest
            .snapshot()
            .into_iter()
            .filter_map(|(vessel, bytes)| {
                let id = twin_wire::VesselId::new(&vessel).ok()?;
                let key = keys.twin_state(&id);
                let ke = KeyExpr::try_from(key.as_str()).ok()?;
                query.key_expr().intersects(&ke).then_some((key, bytes))
            })
            .collect();
        for (key, bytes) in replies {
            if let Err(e) = query.reply(key, bytes).await {
                tracing::warn!("query not answered: {e}");
            }
        }
    }
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
