//! The dispatcher: routes every input message, in arrival order, to its
//! vessel's task, starting the task the first time the vessel is seen.
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
//! - a message whose vessel's queue is full waits for room on the Zenoh
//!   thread, holding up Zenoh's reading (back-pressure onto the sender, not
//!   loss). The wait happens outside the router's lock.
//! - each vessel input key (`gnss`, `nmea`, `actuators`) is declared to the
//!   session at its first message, before the message is routed on
//!   ([`VesselRoute::inputs`]).
//! - every routed event is counted in [`FaultPathLoad`] until its task has
//!   handled it, which is how the forecast threads know whether the fault
//!   path keeps up.
//! - once closed (shutdown), nothing more is routed; the vessels' queues
//!   close with it and each task drains what it was given.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use tokio::sync::mpsc;
use tokio_util::task::TaskTracker;
use twin_wire::Topic;
use zenoh::bytes::ZBytes;
use zenoh::key_expr::KeyExpr;
use zenoh::sample::Sample;

use crate::RunSummary;
use crate::forecast::FaultPathLoad;
use crate::settings::Settings;
use crate::stats::Counters;
use crate::vessel::{VesselEvent, VesselShared, VesselTask, declare_key};

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
    summary: RunSummary,
    /// `None` once closed: nothing more is routed.
    spawner: Option<VesselSpawner>,
}

impl Router {
    /// Routes one message to its vessel's queue, starting the vessel's task
    /// the first time; `Some` when the queue is full.
    fn route(&mut self, key: &KeyExpr<'_>, payload: &ZBytes) -> Option<Blocked> {
        let spawner = self.spawner.as_ref()?;
        let settings = &self.settings;
        let key_str = key.as_str();
        let (vessel, topic) = match settings.keys.parse_borrowed(key_str) {
            Ok(parsed) => parsed,
            Err(e) => {
                self.summary
                    .refused
                    .reject("-", "bad_key", &format!("{key_str}: {e}"));
                return None;
            }
        };
        let Some(slot) = input_slot(topic) else {
            self.summary
                .refused
                .reject(vessel, "not_an_input_topic", &key_str.to_string());
            return None;
        };
        // Looked up by the borrowed id: no allocation for a known vessel.
        let route = match self.vessels.get_mut(vessel).filter(|r| !r.tx.is_closed()) {
            Some(route) => route,
            None => {
                if self.vessels.len() >= settings.vessels.max_vessels {
                    self.summary.refused.reject(
                        vessel,
                        "too_many_vessels",
                        &settings.vessels.max_vessels,
                    );
                    return None;
                }
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
                };
                self.vessels
                    .entry(vessel.to_string())
                    .insert_entry(route)
                    .into_mut()
            }
        };
        let len = payload.len();
        // Built once the message has a vessel to go to: a message refused
        // above costs no copy.
        let event = if len > settings.max_payload_bytes {
            VesselEvent::Refused {
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
        if route.inputs[slot].is_none() {
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

    /// A routed message was not taken, its vessel's task having ended: no
    /// longer in flight, and counted as refused.
    fn task_ended(&mut self, vessel: &str) {
        self.load.handled();
        self.summary
            .refused
            .reject(vessel, TASK_ENDED, &"the task ended before the message");
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
        Self(Arc::new(Mutex::new(Router {
            settings,
            load: spawner.shared.load.clone(),
            vessels: HashMap::new(),
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
    fn on_message(&self, key: &KeyExpr<'_>, payload: &ZBytes) {
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
            {
                router.vessels.remove(&vessel);
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
        std::mem::take(&mut router.summary)
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
                        tap: None,
                        diagnose_slots: Arc::new(tokio::sync::Semaphore::new(1)),
                        forecaster: crate::forecast::Forecaster::start(1, load.clone()).unwrap(),
                        load: load.clone(),
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

    #[tokio::test(flavor = "multi_thread", worker_threads = 1)]
    async fn a_vessels_input_key_is_declared_at_its_first_message() {
        let rig = Rig::new("").await;
        let (session, dispatcher) = (&rig.session, &rig.dispatcher);
        let input = |vessel: &str, slot: usize| {
            dispatcher.0.lock().unwrap().vessels[vessel].inputs[slot].clone()
        };
        assert!(route(dispatcher, "asv/d1/gnss", b"{}").is_none());
        let gnss = input("d1", 0).expect("declared at the first message");
        assert_eq!(gnss.as_str(), "asv/d1/gnss");
        assert!(input("d1", 2).is_none(), "actuators: not seen yet");
        route(dispatcher, "asv/d1/actuators", b"{}");
        assert!(input("d1", 2).is_some());
        // An output topic is refused, not routed.
        route(dispatcher, "asv/d1/twin/state", b"{}");
        // Only a declared key expression can be undeclared: the key held is
        // the session's declaration.
        assert!(session.undeclare(gnss).await.is_ok());
        let summary = dispatcher.close();
        assert_eq!(summary.routed, 2);
        assert_eq!(summary.refused.total_rejected(), 1);
        rig.finish().await;
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 1)]
    async fn a_full_queue_hands_the_message_back_and_a_closed_dispatcher_routes_nothing() {
        let rig = Rig::new("[vessels]\nqueue_depth = 1\n").await;
        let (dispatcher, load) = (&rig.dispatcher, &rig.load);
        assert!(route(dispatcher, "asv/d2/gnss", b"first").is_none());
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
    /// routed.
    #[tokio::test(flavor = "multi_thread", worker_threads = 1)]
    async fn a_vessel_beyond_max_vessels_is_refused_and_the_others_still_routed() {
        let rig = Rig::new("[vessels]\nmax_vessels = 1\n").await;
        let (dispatcher, load) = (&rig.dispatcher, &rig.load);
        assert!(route(dispatcher, "asv/d5/gnss", b"{}").is_none());
        assert!(route(dispatcher, "asv/d6/gnss", b"{}").is_none());
        assert!(route(dispatcher, "asv/d5/actuators", b"{}").is_none());
        assert!(!dispatcher.0.lock().unwrap().vessels.contains_key("d6"));
        assert_eq!(load.in_flight(), 2, "only the routed messages");
        let summary = dispatcher.close();
        assert_eq!(summary.routed, 2);
        assert_eq!(summary.refused.rejected.get("too_many_vessels"), Some(&1));
        assert_eq!(summary.refused.total_rejected(), 1);
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
        dispatcher.on_message(&key, &ZBytes::from(b"first".to_vec()));
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
