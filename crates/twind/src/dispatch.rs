//! The dispatcher: routes every input message, in arrival order, to its
//! vessel's task, admitting the vessel (and starting its task) at its first
//! valid message.
//!
//! It runs inside the input subscriber's callback, on the Zenoh thread that
//! received the message: no queue and no task of its own between Zenoh and
//! the vessels. A task on the runtime's workers reading a Zenoh FIFO channel
//! would be one serial loop competing with the vessel tasks it feeds for the
//! same workers; at 1,000 vessels flat out that design carried about half
//! the fixes per second this one does (docs/performance.md, "The
//! dispatcher").
//!
//! Rules it keeps:
//! - a vessel is admitted, and gets a task, a liveliness token and its keys
//!   declared, only at a first message that is valid input
//!   ([`admissible`]), and, unless listed in `[vessels] known`, while fewer
//!   than `max_vessels` unlisted vessels run and the admission bucket
//!   (`admit_per_s`, `admit_burst`) has a token. Anything refused before a
//!   vessel's twin sees it is counted by reason in the daemon's own
//!   statistics (`{prefix}/@twind/{id}/stats`) with the sender in a short
//!   list of recent refusals, and costs nothing that outlives the message:
//!   a flood of garbage on new ids makes no task, no token, no key and no
//!   entry that grows with the ids.
//! - a message whose vessel's queue is full waits for room on the Zenoh
//!   thread, holding up Zenoh's reading (back-pressure onto the sender).
//!   A sender that publishes with `CongestionControl::Block` (`twin-replay`,
//!   `twin-bridge`) then waits and loses nothing; one with Zenoh's default,
//!   `Drop` (rmw_zenoh on most topics), loses messages on its own side,
//!   which only the ROS 2 input's sequence numbers reveal
//!   ([`Dispatcher::missed_upstream`]). The wait happens outside the
//!   router's lock.
//! - each vessel input key (`gnss`, `nmea`, `actuators`) is declared to the
//!   session at its first message, before the message is routed on
//!   ([`VesselRoute::inputs`]).
//! - every routed event is counted in [`FaultPathLoad`] until its task has
//!   handled it, which is how the forecast threads know whether the fault
//!   path keeps up.
//! - once closed (shutdown), nothing more is routed; the vessels' queues
//!   close with it and each task drains what it was given.

use std::collections::{HashMap, VecDeque};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use tokio::sync::mpsc;
use tokio_util::task::TaskTracker;
use twin_core::twin::VesselTwin;
use twin_wire::Topic;
use twin_wire::messages::{decode_actuators_limited, decode_gnss_limited};
use twin_wire::outputs::{DaemonStatsMessage, RefusedSender, payload_time};
use twin_wire::read::{NmeaDecoder, ReadOptions};
use zenoh::bytes::ZBytes;
use zenoh::key_expr::KeyExpr;
use zenoh::sample::Sample;

use crate::RunSummary;
use crate::forecast::FaultPathLoad;
use crate::settings::Settings;
use crate::stats::Counters;
use crate::vessel::{
    EMPTY_NMEA, VesselEvent, VesselShared, VesselTask, check_live_time, declare_key, speeds_of,
};

/// The reason counted for a message whose vessel task had already ended.
const TASK_ENDED: &str = "vessel_task_ended";

/// What a new vessel task is made from.
pub(crate) struct VesselSpawner {
    /// The runtime the vessel tasks run on (the callback runs on Zenoh's).
    pub runtime: tokio::runtime::Handle,
    /// Tracks the vessel tasks, for the shutdown's wait.
    pub tracker: TaskTracker,
    /// What the tasks share (the session, the forecast threads, ...).
    pub shared: VesselShared,
    /// Each ended task sends its vessel and counters here.
    pub done_tx: mpsc::UnboundedSender<(String, Counters)>,
}

/// A vessel as the dispatcher knows it.
struct VesselRoute {
    /// Its task's queue.
    tx: mpsc::Sender<VesselEvent>,
    /// Its input keys (in [`input_slot`] order), each declared to the
    /// session at its first message, before that message is routed on, and
    /// dropped (undeclared) with the route.
    ///
    /// With Zenoh 1.10 a message on a key that is not a node of the
    /// session's resource tree has its route computed afresh, by a walk
    /// over every node under `{prefix}/`; a declared key is a node whose
    /// route is cached (docs/performance.md, "Declared keys"). Declared
    /// here rather than by the vessel's task, so that a vessel's messages
    /// are not routed uncached while its task is still starting: were the
    /// tasks to declare, a fleet of 5,000 vessels starting at once would
    /// never get going (Zenoh's receiving thread spends its time computing
    /// those routes, under the routing tables' lock that the tasks'
    /// declarations wait for).
    inputs: [Option<KeyExpr<'static>>; 3],
    /// Whether the vessel is in `[vessels] known` (not counted against
    /// `max_vessels`).
    listed: bool,
}

/// The index of an input topic in [`VesselRoute::inputs`]; `None` for
/// output topics.
fn input_slot(topic: Topic) -> Option<usize> {
    match topic {
        Topic::Gnss => Some(0),
        Topic::Nmea => Some(1),
        Topic::Actuators => Some(2),
        _ => None,
    }
}

/// Whether `payload`, the first message of a vessel not yet admitted, on
/// `topic`, is valid input for the twin of its profile: it decodes, a
/// live one is stamped within the bounds of the daemon's clock, and a twin
/// that has seen nothing takes it (a GNSS fix or shaft speeds), or at
/// least one of its NMEA sentences
/// decodes. Costs a decode (and, for a well-formed message, a throwaway
/// twin); keeps nothing.
pub(crate) fn admissible(
    settings: &Settings,
    vessel: &str,
    topic: Topic,
    payload: &[u8],
) -> Result<(), (&'static str, String)> {
    let (twin_config, _) = settings.twin_for(vessel);
    let fresh = || {
        VesselTwin::new(twin_config)
            .map_err(|e| ("estimator", format!("the twin's configuration: {e}")))
    };
    match topic {
        Topic::Gnss => {
            let d = decode_gnss_limited(payload, settings.max_payload_bytes)
                .map_err(|e| (e.reason(), e.to_string()))?;
            check_live_time(&settings.live_time, d.replay, d.value.time_s)?;
            fresh()?
                .on_gnss(&d.value)
                .map(|_| ())
                .map_err(|r| (r.reason(), r.to_string()))
        }
        Topic::Actuators => {
            let d = decode_actuators_limited(payload, settings.max_payload_bytes)
                .map_err(|e| (e.reason(), e.to_string()))?;
            let speeds = speeds_of(d.value, &twin_config.kinetic.params);
            check_live_time(&settings.live_time, d.replay, speeds.time_s)?;
            fresh()?
                .on_propellers(&speeds)
                .map_err(|r| (r.reason(), r.to_string()))
        }
        Topic::Nmea => {
            let mut items = Vec::new();
            NmeaDecoder::new(ReadOptions::default()).decode_payload(payload, &mut items);
            match items.iter().find(|i| i.is_ok()) {
                Some(_) => Ok(()),
                None => Err(match items.into_iter().find_map(Result::err) {
                    Some(r) => (r.reason.kind().name(), r.to_string()),
                    None => (EMPTY_NMEA, "no NMEA sentence".to_string()),
                }),
            }
        }
        other => Err(("not_an_input_topic", other.suffix().to_string())),
    }
}

/// A message whose vessel's queue is full: it waits for room outside the
/// router's lock.
struct Blocked {
    tx: mpsc::Sender<VesselEvent>,
    event: VesselEvent,
    vessel: String,
}

/// The dispatcher's state.
struct Router {
    settings: Arc<Settings>,
    /// Counts each routed event until its task has handled it (the tasks'
    /// own copy is in the spawner's `shared`).
    load: FaultPathLoad,
    vessels: HashMap<String, VesselRoute>,
    /// How many of `vessels` are not in `settings.vessels.known`.
    unlisted: usize,
    /// New vessels not in `known` may be admitted while this has a token.
    admissions: TokenBucket,
    /// The most recently refused senders, newest first.
    refused_recently: VecDeque<RecentRefusal>,
    summary: RunSummary,
    /// `None` once closed: nothing more is routed.
    spawner: Option<VesselSpawner>,
}

/// How many recent refusals the daemon's statistics list.
pub(crate) const RECENT_REFUSALS: usize = 32;

/// The longest sender (a key that names no vessel) kept in the list, bytes.
const SENDER_MAX_BYTES: usize = 128;

/// A sender the daemon refused, as kept for its statistics.
#[derive(Debug, Clone)]
pub(crate) struct RecentRefusal {
    pub sender: String,
    pub reason: &'static str,
    pub count: u64,
    pub last: std::time::SystemTime,
}

/// A token bucket: `rate_per_s` tokens a second, at most `size` held.
#[derive(Debug, Clone)]
struct TokenBucket {
    rate_per_s: f64,
    size: f64,
    tokens: f64,
    at: Instant,
}

impl TokenBucket {
    fn full(rate_per_s: f64, size: usize) -> Self {
        Self {
            rate_per_s,
            size: size as f64,
            tokens: size as f64,
            at: Instant::now(),
        }
    }

    /// Takes a token if one is there at `now`.
    fn take(&mut self, now: Instant) -> bool {
        let dt = now.saturating_duration_since(self.at).as_secs_f64();
        self.at = now;
        self.tokens = (self.tokens + dt * self.rate_per_s).min(self.size);
        if self.tokens >= 1.0 {
            self.tokens -= 1.0;
            true
        } else {
            false
        }
    }
}

/// The first bytes of `s`, at most `max` and cut on a character boundary.
fn head(s: &str, max: usize) -> &str {
    let mut end = s.len().min(max);
    while !s.is_char_boundary(end) {
        end -= 1;
    }
    &s[..end]
}

impl Router {
    /// Counts a message refused by the daemon (no vessel's twin saw it) and
    /// notes its sender in the recent list.
    fn refuse(&mut self, sender: &str, reason: &'static str, detail: &dyn std::fmt::Display) {
        self.summary.refused.reject(sender, reason, detail);
        let sender = head(sender, SENDER_MAX_BYTES);
        let now = std::time::SystemTime::now();
        let list = &mut self.refused_recently;
        match list.iter().position(|r| r.sender == sender) {
            Some(i) => {
                if let Some(mut r) = list.remove(i) {
                    r.reason = reason;
                    r.count += 1;
                    r.last = now;
                    list.push_front(r);
                }
            }
            None => {
                list.truncate(RECENT_REFUSALS - 1);
                list.push_front(RecentRefusal {
                    sender: sender.to_string(),
                    reason,
                    count: 1,
                    last: now,
                });
            }
        }
    }

    /// Routes one message to its vessel's queue, admitting the vessel (and
    /// starting its task) at its first valid message; `Some` when the queue
    /// is full.
    fn route(&mut self, key: &KeyExpr<'_>, payload: &ZBytes) -> Option<Blocked> {
        self.spawner.as_ref()?;
        self.summary.received += 1;
        let settings = self.settings.clone();
        let key_str = key.as_str();
        let (vessel, topic) = match settings.keys.parse_borrowed(key_str) {
            Ok(parsed) => parsed,
            Err(e) => {
                self.refuse(key_str, "bad_key", &format_args!("{key_str}: {e}"));
                return None;
            }
        };
        let Some(slot) = input_slot(topic) else {
            self.refuse(vessel, "not_an_input_topic", &key_str);
            return None;
        };
        let len = payload.len();
        let admitted = self.vessels.get(vessel).is_some_and(|r| !r.tx.is_closed());
        if !admitted {
            self.admit(vessel, topic, payload)?;
        }
        let spawner = self.spawner.as_ref()?;
        // Looked up by the borrowed id: no allocation for a known vessel.
        let route = self.vessels.get_mut(vessel)?;
        // Built once the message has a vessel to go to: a message refused
        // above costs no copy.
        let event = if len > settings.max_payload_bytes {
            VesselEvent::Refused {
                topic,
                reason: "payload_too_large",
                detail: format!(
                    "{len} bytes on {key_str}, limit {}",
                    settings.max_payload_bytes
                ),
            }
        } else {
            // A copy: a payload handed on as Zenoh's own buffer would keep
            // the receive buffer it lies in from being recycled while it
            // waits in a vessel's queue, and with enough of them queued the
            // session stops reading (a test with several daemons in one
            // process stalls).
            VesselEvent::Payload {
                topic,
                bytes: payload.to_bytes().into_owned(),
            }
        };
        // Declared when the vessels' tokens are on (see `VesselTask::put`).
        if route.inputs[slot].is_none() && settings.publish.vessel_liveliness {
            route.inputs[slot] = Some(declare_key(
                &spawner.shared.session,
                key.clone().into_owned(),
            ));
        }
        self.summary.routed += 1;
        self.load.routed();
        match route.tx.try_send(event) {
            Ok(()) => None,
            Err(mpsc::error::TrySendError::Full(event)) => Some(Blocked {
                tx: route.tx.clone(),
                event,
                vessel: vessel.to_string(),
            }),
            Err(mpsc::error::TrySendError::Closed(_)) => {
                self.task_ended(vessel);
                None
            }
        }
    }

    /// Admits `vessel`, whose first message (on `topic`) is `payload`: it
    /// must be valid input ([`admissible`]), and unless the vessel is listed
    /// in `known` there must be room under `max_vessels` and a token in
    /// the admission bucket. Starts the vessel's task; `None` (the message
    /// refused and counted) when the vessel is not admitted. Nothing is
    /// made for a message refused here: no task, no token, no key.
    fn admit(&mut self, vessel: &str, topic: Topic, payload: &ZBytes) -> Option<()> {
        let settings = self.settings.clone();
        let len = payload.len();
        if len > settings.max_payload_bytes {
            self.refuse(
                vessel,
                "payload_too_large",
                &format_args!("{len} bytes, limit {}", settings.max_payload_bytes),
            );
            return None;
        }
        if let Err((reason, detail)) = admissible(&settings, vessel, topic, &payload.to_bytes()) {
            self.refuse(vessel, reason, &format_args!("not admitted: {detail}"));
            return None;
        }
        let listed = settings
            .vessels
            .known
            .binary_search_by(|k| k.as_str().cmp(vessel))
            .is_ok();
        if !listed {
            if self.unlisted >= settings.vessels.max_vessels {
                self.refuse(vessel, "too_many_vessels", &settings.vessels.max_vessels);
                return None;
            }
            if !self.admissions.take(Instant::now()) {
                self.refuse(
                    vessel,
                    "admission_rate",
                    &format_args!(
                        "more than {} new vessels a second",
                        settings.vessels.admit_per_s
                    ),
                );
                return None;
            }
        }
        let spawner = self.spawner.as_ref()?;
        // Validated by `parse_borrowed`: cannot fail.
        let id = twin_wire::VesselId::new(vessel).ok()?;
        let (tx, rx) = mpsc::channel(settings.vessels.queue_depth);
        let task = VesselTask::new(id, settings.clone(), &spawner.shared);
        let done = spawner.done_tx.clone();
        let name = vessel.to_string();
        spawner.tracker.spawn_on(
            async move {
                let counters = task.run(rx).await;
                let _ = done.send((name, counters));
            },
            &spawner.runtime,
        );
        let route = VesselRoute {
            tx,
            inputs: [None, None, None],
            listed,
        };
        // A vessel whose task ended and is admitted again replaces its route.
        if let Some(old) = self.vessels.insert(vessel.to_string(), route)
            && !old.listed
        {
            self.unlisted -= 1;
        }
        if !listed {
            self.unlisted += 1;
        }
        Some(())
    }

    /// A routed message was not taken, its vessel's task having ended: no
    /// longer in flight, and counted as refused.
    fn task_ended(&mut self, vessel: &str) {
        self.load.handled();
        self.summary.routed -= 1;
        self.refuse(vessel, TASK_ENDED, &"the task ended before the message");
    }
}

/// The dispatcher, shared by the input subscriber's callback (which
/// routes) and the daemon's run (which forgets ended tasks and closes it).
#[derive(Clone)]
pub(crate) struct Dispatcher(Arc<Mutex<Router>>);

impl Dispatcher {
    /// A dispatcher starting vessel tasks from `spawner` (and counting the
    /// events in flight in its `shared.load`).
    pub fn new(settings: Arc<Settings>, spawner: VesselSpawner) -> Self {
        let admissions =
            TokenBucket::full(settings.vessels.admit_per_s, settings.vessels.admit_burst);
        Self(Arc::new(Mutex::new(Router {
            settings,
            load: spawner.shared.load.clone(),
            vessels: HashMap::new(),
            unlisted: 0,
            admissions,
            refused_recently: VecDeque::new(),
            summary: RunSummary::default(),
            spawner: Some(spawner),
        })))
    }

    /// The subscriber's callback: routes `sample`.
    pub fn on_sample(&self, sample: &Sample) {
        self.on_message(sample.key_expr(), sample.payload());
    }

    /// Routes one message; when its vessel's queue is full, waits for room
    /// on this thread (Zenoh's, which then stops reading: back-pressure
    /// onto the sender, not loss).
    pub(crate) fn on_message(&self, key: &KeyExpr<'_>, payload: &ZBytes) {
        let blocked = match self.0.lock() {
            Ok(mut router) => router.route(key, payload),
            Err(_) => return,
        };
        let Some(Blocked { tx, event, vessel }) = blocked else {
            return;
        };
        // Unconstrained: this thread belongs to one of Zenoh's runtimes,
        // and tokio's per-task budget there would make the send pending
        // again and again without any task yielding in between.
        if wait_here(tokio::task::unconstrained(tx.send(event))).is_err()
            && let Ok(mut router) = self.0.lock()
        {
            router.task_ended(&vessel);
        }
    }

    /// Counts a message refused before it could be routed (the ROS 2
    /// input's undecodable messages), with its sender in the recent list.
    pub(crate) fn refuse(
        &self,
        sender: &str,
        reason: &'static str,
        detail: &dyn std::fmt::Display,
    ) {
        if let Ok(mut router) = self.0.lock() {
            router.summary.received += 1;
            router.refuse(sender, reason, detail);
        }
    }

    /// Vessel tasks have ended: their counters go into the summary, and
    /// each queue leaves the map unless a new task for the vessel has
    /// replaced it.
    pub fn forget_ended(&self, ended: impl IntoIterator<Item = (String, Counters)>) {
        let Ok(mut router) = self.0.lock() else {
            return;
        };
        let router = &mut *router;
        for (vessel, counters) in ended {
            if router
                .vessels
                .get(&vessel)
                .is_some_and(|route| route.tx.is_closed())
                && let Some(route) = router.vessels.remove(&vessel)
                && !route.listed
            {
                router.unlisted -= 1;
            }
            router.summary.vessels.insert(vessel, counters);
        }
    }

    /// Stops routing and closes every vessel's queue (each task handles
    /// what it was given, then ends); returns the summary so far.
    pub fn close(&self) -> RunSummary {
        let Ok(mut router) = self.0.lock() else {
            return RunSummary::default();
        };
        router.spawner = None;
        router.vessels.clear();
        router.unlisted = 0;
        std::mem::take(&mut router.summary)
    }

    /// The events waiting in the vessels' queues (for the metrics).
    pub fn queues(&self) -> crate::metrics::Queues {
        let Ok(router) = self.0.lock() else {
            return crate::metrics::Queues::default();
        };
        let mut q = crate::metrics::Queues {
            capacity: router.settings.vessels.queue_depth as u64,
            ..Default::default()
        };
        for route in router.vessels.values().filter(|r| !r.tx.is_closed()) {
            let waiting = (route.tx.max_capacity() - route.tx.capacity()) as u64;
            q.queued += waiting;
            q.deepest = q.deepest.max(waiting);
        }
        q
    }

    /// The daemon's own statistics so far, for `{prefix}/@twind/{id}/stats`.
    pub fn daemon_stats(&self, daemon: &str, save_failures: u64) -> DaemonStatsMessage {
        let Ok(router) = self.0.lock() else {
            return DaemonStatsMessage::default();
        };
        let time = |t: std::time::SystemTime| {
            t.duration_since(std::time::UNIX_EPOCH)
                .map(|d| payload_time(d.as_secs_f64()))
                .unwrap_or_default()
        };
        DaemonStatsMessage {
            daemon: daemon.to_string(),
            time: time(std::time::SystemTime::now()),
            vessels: router
                .vessels
                .values()
                .filter(|r| !r.tx.is_closed())
                .count(),
            max_vessels: router.settings.vessels.max_vessels,
            received: router.summary.received,
            routed: router.summary.routed,
            refused: router.summary.refused.rejected.clone(),
            refused_recently: router
                .refused_recently
                .iter()
                .map(|r| RefusedSender {
                    sender: r.sender.clone(),
                    reason: r.reason.to_string(),
                    count: r.count,
                    last: time(r.last),
                })
                .collect(),
            save_failures,
            ros2_missed: router.summary.ros2_missed,
        }
    }

    /// Counts `n` ROS 2 input messages their publisher numbered but that
    /// never arrived.
    pub(crate) fn missed_upstream(&self, n: u64) {
        if n == 0 {
            return;
        }
        if let Ok(mut router) = self.0.lock() {
            router.summary.ros2_missed = router.summary.ros2_missed.saturating_add(n);
        }
    }
}

/// Runs `future` to completion on this thread, parking the thread while the
/// future is pending: for the subscriber's callback, which Zenoh calls
/// outside any task of the daemon's.
fn wait_here<F: std::future::Future>(future: F) -> F::Output {
    /// Wakes the parked thread.
    struct Unpark(std::thread::Thread);
    impl std::task::Wake for Unpark {
        fn wake(self: Arc<Self>) {
            self.0.unpark();
        }
        fn wake_by_ref(self: &Arc<Self>) {
            self.0.unpark();
        }
    }
    let waker = std::task::Waker::from(Arc::new(Unpark(std::thread::current())));
    let mut cx = std::task::Context::from_waker(&waker);
    let mut future = std::pin::pin!(future);
    loop {
        if let std::task::Poll::Ready(out) = future.as_mut().poll(&mut cx) {
            return out;
        }
        std::thread::park();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::lone_session;
    use zenoh::Session;

    /// A dispatcher on a session of its own whose vessel tasks are spawned
    /// on `idle`, a runtime nobody drives: they never take an event, so what
    /// the queues hold is what the dispatcher put there.
    struct Rig {
        session: Session,
        idle: tokio::runtime::Runtime,
        dispatcher: Dispatcher,
        load: FaultPathLoad,
    }

    impl Rig {
        /// A rig with the settings of `toml`.
        async fn new(toml: &str) -> Self {
            let session = lone_session().await;
            let idle = tokio::runtime::Builder::new_current_thread()
                .build()
                .unwrap();
            let load = FaultPathLoad::new();
            let (done_tx, _) = mpsc::unbounded_channel();
            let dispatcher = Dispatcher::new(
                Arc::new(Settings::from_toml(toml).unwrap()),
                VesselSpawner {
                    runtime: idle.handle().clone(),
                    tracker: TaskTracker::new(),
                    shared: VesselShared {
                        session: session.clone(),
                        latest: crate::LatestStates::default(),
                        outputs: crate::LatestOutputs::default(),
                        tap: None,
                        diagnose_slots: Arc::new(tokio::sync::Semaphore::new(1)),
                        forecaster: crate::forecast::Forecaster::start(1, load.clone()).unwrap(),
                        load: load.clone(),
                        save_failures: crate::SaveFailures::default(),
                        ros2: None,
                        metrics: crate::metrics::Metrics::default(),
                        fleet: crate::fleet::Fleet::solo(),
                    },
                    done_tx,
                },
            );
            Self {
                session,
                idle,
                dispatcher,
                load,
            }
        }

        /// Drops the never-run tasks and closes the session.
        async fn finish(self) {
            self.idle.shutdown_background();
            self.session.close().await.unwrap();
        }
    }

    /// `route` as the callback calls it, on a key given as text.
    fn route(dispatcher: &Dispatcher, key: &str, payload: &[u8]) -> Option<Blocked> {
        let key = KeyExpr::try_from(key.to_string()).unwrap();
        dispatcher
            .0
            .lock()
            .unwrap()
            .route(&key, &ZBytes::from(payload.to_vec()))
    }

    /// A valid fix, `i` tenths of a second into a replayed trial.
    fn fix(i: u32) -> Vec<u8> {
        format!(
            "{{\"time\":\"2024-06-01T12:00:{:02}.{}Z\",\"lat_deg\":59.9,\"lon_deg\":10.7,\
             \"sog_mps\":1.0,\"cog_rad\":0.0,\"replay\":true}}",
            i / 10,
            i % 10
        )
        .into_bytes()
    }

    /// Valid shaft speeds of a replayed trial.
    const SPEEDS: &[u8] =
        b"{\"time\":\"2024-06-01T12:00:00Z\",\"rpm\":{\"port\":500,\"starboard\":500},\"replay\":true}";

    fn admitted(dispatcher: &Dispatcher) -> Vec<String> {
        let mut v: Vec<String> = dispatcher
            .0
            .lock()
            .unwrap()
            .vessels
            .keys()
            .cloned()
            .collect();
        v.sort();
        v
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 1)]
    async fn a_vessels_input_key_is_declared_at_its_first_message() {
        let rig = Rig::new("").await;
        let (session, dispatcher) = (&rig.session, &rig.dispatcher);
        let input = |vessel: &str, slot: usize| {
            dispatcher.0.lock().unwrap().vessels[vessel].inputs[slot].clone()
        };
        assert!(route(dispatcher, "asv/d1/gnss", &fix(0)).is_none());
        let gnss = input("d1", 0).expect("declared at the first message");
        assert_eq!(gnss.as_str(), "asv/d1/gnss");
        assert!(input("d1", 2).is_none(), "actuators: not seen yet");
        // Once admitted, every message is the vessel's task's to judge.
        route(dispatcher, "asv/d1/actuators", b"{}");
        assert!(input("d1", 2).is_some());
        // An output topic is refused, not routed.
        route(dispatcher, "asv/d1/twin/state", b"{}");
        // Only a declared key expression can be undeclared: the key held is
        // the session's declaration.
        assert!(session.undeclare(gnss).await.is_ok());
        let summary = dispatcher.close();
        assert_eq!(summary.received, 3);
        assert_eq!(summary.routed, 2);
        assert_eq!(summary.refused.total_rejected(), 1);
        rig.finish().await;
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 1)]
    async fn a_full_queue_hands_the_message_back_and_a_closed_dispatcher_routes_nothing() {
        let rig = Rig::new("[vessels]\nqueue_depth = 1\n").await;
        let (dispatcher, load) = (&rig.dispatcher, &rig.load);
        assert!(route(dispatcher, "asv/d2/gnss", &fix(0)).is_none());
        let blocked = route(dispatcher, "asv/d2/gnss", b"second").expect("the queue is full");
        assert_eq!(blocked.vessel, "d2");
        assert!(
            matches!(&blocked.event, VesselEvent::Payload { topic: Topic::Gnss, bytes } if bytes == b"second")
        );
        assert_eq!(load.in_flight(), 2, "both count until handled");
        let summary = dispatcher.close();
        assert_eq!(summary.routed, 2);
        assert!(route(dispatcher, "asv/d2/gnss", b"third").is_none());
        assert_eq!(load.in_flight(), 2, "nothing routed once closed");
        rig.finish().await;
    }

    /// A vessel beyond `max_vessels` is refused with a reason, starts no
    /// task and is not counted in flight; the known vessels are still
    /// routed, and one listed in `known` is admitted beyond the limit.
    #[tokio::test(flavor = "multi_thread", worker_threads = 1)]
    async fn a_vessel_beyond_max_vessels_is_refused_and_the_others_still_routed() {
        let rig = Rig::new("[vessels]\nmax_vessels = 1\nknown = [\"listed\"]\n").await;
        let (dispatcher, load) = (&rig.dispatcher, &rig.load);
        assert!(route(dispatcher, "asv/d5/gnss", &fix(0)).is_none());
        assert!(route(dispatcher, "asv/d6/gnss", &fix(0)).is_none());
        assert!(route(dispatcher, "asv/d5/actuators", SPEEDS).is_none());
        assert!(route(dispatcher, "asv/listed/actuators", SPEEDS).is_none());
        assert_eq!(admitted(dispatcher), ["d5", "listed"]);
        assert_eq!(load.in_flight(), 3, "only the routed messages");
        let summary = dispatcher.close();
        assert_eq!(summary.routed, 3);
        assert_eq!(summary.refused.rejected.get("too_many_vessels"), Some(&1));
        assert_eq!(summary.refused.total_rejected(), 1);
        rig.finish().await;
    }

    /// Garbage on new ids admits nothing: no task, no declared key, no
    /// entry per id; each message is refused by the daemon with the
    /// decoder's reason, and the list of recent refusals stays bounded.
    /// A real vessel is then admitted at once, however small
    /// `max_vessels`.
    #[tokio::test(flavor = "multi_thread", worker_threads = 1)]
    async fn garbage_on_new_ids_admits_nothing_and_costs_nothing_that_stays() {
        let rig = Rig::new("[vessels]\nmax_vessels = 2\n").await;
        let (dispatcher, load) = (&rig.dispatcher, &rig.load);
        for i in 0..1000 {
            let (topic, payload): (&str, &[u8]) = match i % 3 {
                0 => ("gnss", b"x"),
                1 => ("actuators", b"{\"time\":\"2024-06-01T12:00:00Z\"}"),
                _ => ("nmea", b"not nmea\r\n"),
            };
            assert!(route(dispatcher, &format!("asv/junk-{i}/{topic}"), payload).is_none());
        }
        // A fix out of range, and one far in the future of a live vessel.
        route(
            dispatcher,
            "asv/junk-a/gnss",
            &String::from_utf8(fix(0))
                .unwrap()
                .replace("59.9", "95")
                .into_bytes(),
        );
        route(
            dispatcher,
            "asv/junk-b/gnss",
            b"{\"time\":\"2099-01-01T00:00:00Z\",\"lat_deg\":59.9,\"lon_deg\":10.7,\
              \"sog_mps\":1.0,\"cog_rad\":0.0}",
        );
        assert!(admitted(dispatcher).is_empty());
        assert_eq!(load.in_flight(), 0);
        {
            let router = dispatcher.0.lock().unwrap();
            assert_eq!(router.refused_recently.len(), RECENT_REFUSALS);
            assert_eq!(router.refused_recently[0].sender, "junk-b");
            assert_eq!(router.refused_recently[0].reason, "time_ahead_of_clock");
        }
        assert!(route(dispatcher, "asv/real/gnss", &fix(0)).is_none());
        assert_eq!(admitted(dispatcher), ["real"]);
        let stats = dispatcher.daemon_stats("d", 0);
        assert_eq!(stats.vessels, 1);
        assert_eq!(stats.received, 1003);
        assert_eq!(stats.routed, 1);
        assert_eq!(stats.refused.values().sum::<u64>(), 1002);
        assert!(stats.refused["bad_json"] >= 333, "{:?}", stats.refused);
        assert_eq!(stats.refused["out_of_range"], 1, "{:?}", stats.refused);
        rig.finish().await;
    }

    /// New vessels are admitted at most `admit_burst` at once, then at
    /// `admit_per_s`; a vessel listed in `known` is admitted regardless,
    /// and a refused vessel is admitted at a later message once a token is
    /// there.
    #[tokio::test(flavor = "multi_thread", worker_threads = 1)]
    async fn new_vessels_are_admitted_at_a_bounded_rate_the_known_ones_always() {
        let rig =
            Rig::new("[vessels]\nadmit_burst = 2\nadmit_per_s = 5.0\nknown = [\"k1\"]\n").await;
        let dispatcher = &rig.dispatcher;
        for v in ["n1", "n2", "n3", "k1"] {
            route(dispatcher, &format!("asv/{v}/gnss"), &fix(0));
        }
        assert_eq!(admitted(dispatcher), ["k1", "n1", "n2"]);
        // 5 a second: a token within 0.2 s.
        tokio::time::sleep(std::time::Duration::from_millis(250)).await;
        route(dispatcher, "asv/n3/gnss", &fix(1));
        route(dispatcher, "asv/n4/gnss", &fix(1));
        assert_eq!(admitted(dispatcher), ["k1", "n1", "n2", "n3"]);
        let summary = dispatcher.close();
        assert_eq!(summary.refused.rejected.get("admission_rate"), Some(&2));
        rig.finish().await;
    }

    /// A message for a full queue waits on the calling thread (Zenoh's);
    /// if the vessel's task ends instead of taking it, it is counted as
    /// refused and no longer as in flight.
    #[tokio::test(flavor = "multi_thread", worker_threads = 1)]
    async fn a_message_waits_for_a_full_queue_and_is_counted_if_its_task_ends() {
        let Rig {
            session,
            idle,
            dispatcher,
            load,
        } = Rig::new("[vessels]\nqueue_depth = 1\n").await;
        let key = KeyExpr::try_from("asv/d4/nmea").unwrap();
        let rmc = b"$GPRMC,120000.00,A,5954.000,N,01042.000,E,1.9,0.0,010624,,,A*5E
"
        .to_vec();
        dispatcher.on_message(&key, &ZBytes::from(rmc));
        let waiting = {
            let dispatcher = dispatcher.clone();
            let key = key.clone().into_owned();
            std::thread::spawn(move || {
                dispatcher.on_message(&key, &ZBytes::from(b"second".to_vec()))
            })
        };
        tokio::time::sleep(std::time::Duration::from_millis(200)).await;
        assert!(!waiting.is_finished(), "waits while the queue is full");
        assert_eq!(load.in_flight(), 2);
        // The task (never run) and its queue go with the runtime.
        idle.shutdown_background();
        waiting.join().unwrap();
        assert_eq!(load.in_flight(), 1, "the second no longer in flight");
        let summary = dispatcher.close();
        assert_eq!(summary.refused.rejected.get(TASK_ENDED), Some(&1));
        session.close().await.unwrap();
    }

    #[test]
    fn waiting_here_parks_until_another_thread_completes_the_future() {
        let (tx, rx) = tokio::sync::oneshot::channel();
        let sender = std::thread::spawn(move || {
            std::thread::sleep(std::time::Duration::from_millis(50));
            tx.send(7).unwrap();
        });
        assert_eq!(wait_here(rx), Ok(7));
        sender.join().unwrap();
    }
}
