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
//! - [`run`] (here): the dispatcher: one Zenoh subscriber for every input
//!   topic of the vessels this daemon owns, routing each message, in arrival
//!   order, to its vessel's task, and saying whether it keeps up (the
//!   forecast threads yield to it while it does not:
//!   [`forecast::FaultPathLoad`]); the queryable for the latest states; and
//!   the graceful shutdown.
//!
//! # Shutdown
//! Decide, tell, wait (tokio's guide): the caller cancels the token; the
//! dispatcher routes what Zenoh has already delivered and stops reading;
//! every vessel task drains its queue, publishes a last state and saves its
//! calibration; `run` waits for all of them and returns. The caller closes
//! the Zenoh session last. Nothing received is lost.
//!
//! # Invariants
//! The daemon never crashes on input from the network: every payload is
//! size-checked before parsing, every parse error and estimator rejection is
//! a typed reason, counted per vessel (published on `twin/stats`) and logged
//! at most once a minute per reason. Messages for vessel ids that are not
//! plain names are refused and counted by the daemon.

pub mod demo;
pub mod forecast;
pub mod persist;
pub mod settings;
pub mod stats;
pub mod vessel;

use std::collections::HashMap;
use std::sync::{Arc, Mutex, RwLock};

use tokio::sync::mpsc;
use tokio_util::sync::CancellationToken;
use tokio_util::task::TaskTracker;
use twin_wire::Topic;
use zenoh::Session;
use zenoh::handlers::FifoChannel;
use zenoh::key_expr::KeyExpr;

use crate::settings::Settings;
use crate::stats::Counters;
use crate::vessel::{VesselEvent, VesselTask};

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

/// A vessel task has ended: its counters go into the summary, and its queue
/// leaves the map unless a new task for the vessel has replaced it.
fn forget_ended(
    vessels: &mut HashMap<String, mpsc::Sender<VesselEvent>>,
    summary: &mut RunSummary,
    vessel: String,
    counters: Counters,
) {
    if vessels.get(&vessel).is_some_and(|tx| tx.is_closed()) {
        vessels.remove(&vessel);
    }
    summary.vessels.insert(vessel, counters);
}

/// Runs the daemon on an open Zenoh `session` until `shutdown` is cancelled.
pub async fn run(
    settings: Settings,
    session: Session,
    shutdown: CancellationToken,
) -> anyhow::Result<RunSummary> {
    run_with_tap(settings, session, shutdown, None, LatestStates::default()).await
}

/// [`run`], also copying every output to `tap` and keeping the latest states
/// in `latest` (shared with the web page).
pub async fn run_with_tap(
    settings: Settings,
    session: Session,
    shutdown: CancellationToken,
    tap: OutputTap,
    latest: LatestStates,
) -> anyhow::Result<RunSummary> {
    let load = crate::forecast::FaultPathLoad::new();
    run_observed(settings, session, shutdown, tap, latest, load).await
}

/// [`run_with_tap`], with the dispatcher reporting whether it keeps up to
/// `load` (which the forecast threads yield to, and the caller can read).
pub async fn run_observed(
    settings: Settings,
    session: Session,
    shutdown: CancellationToken,
    tap: OutputTap,
    latest: LatestStates,
    load: crate::forecast::FaultPathLoad,
) -> anyhow::Result<RunSummary> {
    let settings = Arc::new(settings);
    let subscriber = session
        .declare_subscriber(input_key_expr(&settings))
        .with(FifoChannel::new(4096))
        .await
        .map_err(|e| anyhow::anyhow!("cannot subscribe to {}: {e}", input_key_expr(&settings)))?;
    let state_key = format!(
        "{}/{}/twin/state",
        settings.keys.prefix(),
        settings.vessels.own
    );
    let queryable = session
        .declare_queryable(&state_key)
        .await
        .map_err(|e| anyhow::anyhow!("cannot declare the queryable {state_key}: {e}"))?;
    tracing::info!(inputs = %input_key_expr(&settings), "twind running");

    let forecaster =
        crate::forecast::Forecaster::start(settings.publish.forecast_threads, load.clone())
            .map_err(|e| anyhow::anyhow!("cannot start the forecast threads: {e}"))?;
    let tracker = TaskTracker::new();
    let (done_tx, mut done_rx) = mpsc::unbounded_channel::<(String, Counters)>();
    let mut vessels: HashMap<String, mpsc::Sender<VesselEvent>> = HashMap::new();
    let mut summary = RunSummary::default();
    // Diagnoses are CPU-heavy (seconds each): this bounds how many run at once.
    let diagnose_slots = Arc::new(tokio::sync::Semaphore::new(
        settings.diagnose.max_concurrent,
    ));

    // The queryable answers from the shared map; it needs no vessel task.
    let answer_latest = {
        let latest = latest.clone();
        let keys = settings.keys.clone();
        let shutdown = shutdown.clone();
        tokio::spawn(async move {
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
        })
    };

    let mut draining = false;
    load.note_routing();
    loop {
        // A sample already waiting is taken without a wait; only when the
        // queue is empty has the dispatcher caught up (the forecast threads
        // yield to it until then) and does it wait for what comes first.
        let sample = match subscriber.try_recv() {
            Ok(Some(s)) => {
                if !draining && shutdown.is_cancelled() {
                    draining = true;
                }
                while let Ok((vessel, counters)) = done_rx.try_recv() {
                    forget_ended(&mut vessels, &mut summary, vessel, counters);
                }
                s
            }
            // Shutting down: what Zenoh already delivered is routed; stop.
            Ok(None) if draining => break,
            Ok(None) => {
                load.note_waiting();
                tokio::select! {
                    _ = shutdown.cancelled() => {
                        draining = true;
                        continue;
                    }
                    Some((vessel, counters)) = done_rx.recv() => {
                        forget_ended(&mut vessels, &mut summary, vessel, counters);
                        continue;
                    }
                    s = subscriber.recv_async() => match s {
                        Ok(s) => {
                            load.note_routing();
                            s
                        }
                        Err(_) => break,
                    },
                }
            }
            Err(_) => break,
        };
        let key = sample.key_expr().as_str();
        let (vessel, topic) = match settings.keys.parse_borrowed(key) {
            Ok(parsed) => parsed,
            Err(e) => {
                summary
                    .refused
                    .reject("-", "bad_key", &format!("{key}: {e}"));
                continue;
            }
        };
        if !matches!(topic, Topic::Gnss | Topic::Nmea | Topic::Actuators) {
            summary
                .refused
                .reject(vessel, "not_an_input_topic", &key.to_string());
            continue;
        }
        let len = sample.payload().len();
        let event = if len > settings.max_payload_bytes {
            VesselEvent::Refused {
                reason: "payload_too_large",
                detail: format!("{len} bytes on {key}, limit {}", settings.max_payload_bytes),
            }
        } else {
            // A copy: a payload handed on as Zenoh's own buffer would keep
            // the receive buffer it lies in from being recycled while it
            // waits in a vessel's queue, and with enough of them queued the
            // session stops reading (seen as a stalled test with several
            // daemons in one process).
            VesselEvent::Payload {
                topic,
                bytes: sample.payload().to_bytes().into_owned(),
            }
        };
        // Looked up by the borrowed id: no allocation for a known vessel.
        let tx = match vessels.get(vessel).filter(|tx| !tx.is_closed()) {
            Some(tx) => tx.clone(),
            None => {
                if vessels.len() >= settings.vessels.max_vessels {
                    summary.refused.reject(
                        vessel,
                        "too_many_vessels",
                        &settings.vessels.max_vessels,
                    );
                    continue;
                }
                // Validated by `parse_borrowed`: cannot fail.
                let Ok(id) = twin_wire::VesselId::new(vessel) else {
                    continue;
                };
                let (tx, rx) = mpsc::channel(settings.vessels.queue_depth);
                let task = VesselTask::new(
                    id,
                    settings.clone(),
                    session.clone(),
                    latest.clone(),
                    tap.clone(),
                    diagnose_slots.clone(),
                    forecaster.clone(),
                );
                let done = done_tx.clone();
                let name = vessel.to_string();
                tracker.spawn(async move {
                    let counters = task.run(rx).await;
                    let _ = done.send((name, counters));
                });
                vessels.insert(vessel.to_string(), tx.clone());
                tx
            }
        };
        summary.routed += 1;
        // Waits while the vessel's queue is full: back-pressure, not loss.
        if tx.send(event).await.is_err() {
            summary.refused.reject(
                vessel,
                "vessel_task_ended",
                &"the task ended before the message",
            );
        }
    }

    // Stop reading first, then let every vessel finish.
    drop(subscriber);
    drop(vessels);
    tracker.close();
    tracker.wait().await;
    drop(done_tx);
    while let Some((vessel, counters)) = done_rx.recv().await {
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
