//! One vessel's twin as a task: it owns the vessel's `VesselTwin`, reads a
//! closed enum of events from a bounded channel, and publishes the vessel's
//! outputs. Nothing else touches the twin, so there are no locks on the hot
//! path.
//!
//! Rules this task keeps:
//! - the estimator steps on message time; every rejection is counted with a
//!   typed reason and leaves the estimate as it was (the twin guarantees it);
//! - state and fault are published on every accepted fix, a forecast each
//!   `prediction_interval_s` of message time (computed on the forecast
//!   threads, at most one in flight per vessel: [`crate::forecast`]), an
//!   alarm on every status change;
//! - with no fix for `stale_after_s` (wall clock) the state is published again
//!   marked `stale` while the forecast keeps running from the last fix;
//! - after `drop_after_silence_s` without any message the task saves the
//!   calibration and ends (the dispatcher starts a new one if the vessel
//!   returns, restoring the calibration);
//! - the live residual monitor keeps the recent past and, when due (on an
//!   interval, or early when the innovations turn biased), diagnoses it on a
//!   blocking thread (at most `diagnose.max_concurrent` across the daemon)
//!   and publishes `twin/finding` when the named causes change;
//! - on shutdown (its channel closed by the dispatcher) it handles what is
//!   queued, publishes the forecast being computed (and one more if one fell
//!   due meanwhile), a last state and fault, saves the calibration, and
//!   ends; its liveliness token goes with it.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

use tokio::sync::{Semaphore, mpsc, oneshot};
use twin_core::decision::StatusChange;
use twin_core::diagnose::{
    BaseModel, DiagEvent, DiagnoseConfig, LiveMonitor, Trigger, diagnose, prepare,
};
use twin_core::sample::{GnssFix, PropellerSpeeds};
use twin_core::twin::{Rejection, StepOutput, TwinConfig, VesselTwin};
use twin_core::vessel::VesselParams;
use twin_wire::assemble::{Assembled, AssemblerConfig, FixAssembler};
use twin_wire::measurement::Measurement;
use twin_wire::measurement::ThrustCommand;
use twin_wire::messages::{ActuatorCommand, decode_actuators_limited, decode_gnss_limited};
use twin_wire::outputs::{
    AlarmMessage, FaultMessage, FindingJson, FindingsMessage, StateMessage, StatsMessage,
    UnexplainedJson, payload_time,
};
use twin_wire::profile::VesselProfile;
use twin_wire::read::{NmeaDecoder, ReadOptions};
use twin_wire::{Topic, VesselId};
use zenoh::bytes::Encoding;
use zenoh::key_expr::KeyExpr;
use zenoh::qos::CongestionControl;
use zenoh::{Session, Wait};

use crate::fleet::Fleet;
use crate::forecast::{FaultPathLoad, ForecastJob, Forecaster};
use crate::metrics::{Metrics, Update};
use crate::persist;
use crate::ros2::{Ros2Node, VesselPublishers};
use crate::settings::{LiveTimeSettings, Settings};
use crate::stats::{Counters, Refused};
use crate::{
    Kept, LatestOutputs, LatestStates, OutputEvent, OutputSlot, OutputTap, SaveFailures, StateSlot,
};

/// What the dispatcher hands a vessel's task.
#[derive(Debug)]
pub enum VesselEvent {
    /// A payload received on one of the vessel's input topics.
    Payload {
        /// Which topic.
        topic: Topic,
        /// The payload (already checked against the size limit).
        bytes: Vec<u8>,
    },
    /// A message refused before it could be handed over (e.g. too large).
    Refused {
        /// The topic it came on.
        topic: Topic,
        /// The reason, as counted.
        reason: &'static str,
        /// A detail for the log.
        detail: String,
    },
}

/// A key of the vessel's, declared to the daemon's own session
/// (`Session::declare_keyexpr`) the first time it is used.
///
/// With Zenoh 1.10 a message on a key that is not a node of the routing
/// session's resource tree has its route computed afresh, by a walk that
/// visits every node under `{prefix}/`: each vessel's liveliness token is
/// such a node, so with N tokens every message costs O(N) and the fleet
/// O(N^2) (about 400 vessels at 10 Hz on two cores). A declared key
/// expression is a node whose route is cached, so the daemon's routing of
/// its own outputs does not walk the tree (`twin-bench daemon` measures
/// it; docs/performance.md). (The vessel's input keys are declared by
/// the dispatcher: `dispatch::VesselRoute`.) Unlike a publisher or a token
/// a declared key expression is not announced when declared, though Zenoh
/// may declare it to a peer it routes the key to (which then makes a node
/// too). Declaring costs a walk, so a key is declared only once it is
/// used (a vessel without alarms never has its `alarm` key declared).
/// Not a declared Zenoh publisher: six of those per vessel make the whole
/// fleet slower as it grows.
struct VesselKey {
    key: KeyExpr<'static>,
    declared: OnceLock<KeyExpr<'static>>,
}

impl VesselKey {
    fn new(key: String) -> zenoh::Result<Self> {
        Ok(Self {
            key: KeyExpr::try_from(key)?,
            declared: OnceLock::new(),
        })
    }

    /// The key, declared to `session` on the first call. Should Zenoh
    /// refuse, the undeclared key (it routes the same, uncached).
    fn declared(&self, session: &Session) -> &KeyExpr<'static> {
        self.declared
            .get_or_init(|| declare_key(session, self.key.clone()))
    }
}

/// `key` declared to `session` (see [`VesselKey`]); should Zenoh refuse,
/// the undeclared key (it routes the same, uncached).
pub(crate) fn declare_key(session: &Session, key: KeyExpr<'static>) -> KeyExpr<'static> {
    match session.declare_keyexpr(key.clone()).wait() {
        Ok(declared) => declared,
        Err(e) => {
            tracing::debug!(%key, "key expression not declared: {e}");
            key
        }
    }
}

impl std::fmt::Display for VesselKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.key.fmt(f)
    }
}

/// The vessel's output keys, each declared at its first use.
struct VesselKeys {
    state: VesselKey,
    fault: VesselKey,
    prediction: VesselKey,
    alarm: VesselKey,
    stats: VesselKey,
    finding: VesselKey,
}

impl VesselKeys {
    fn new(keys: &twin_wire::KeySpace, id: &VesselId) -> zenoh::Result<Self> {
        Ok(Self {
            state: VesselKey::new(keys.twin_state(id))?,
            fault: VesselKey::new(keys.twin_fault(id))?,
            prediction: VesselKey::new(keys.twin_prediction(id))?,
            alarm: VesselKey::new(keys.twin_alarm(id))?,
            stats: VesselKey::new(keys.twin_stats(id))?,
            finding: VesselKey::new(keys.key(id, Topic::TwinFinding))?,
        })
    }
}

/// A vessel's task.
pub struct VesselTask {
    id: VesselId,
    settings: Arc<Settings>,
    /// The twin's configuration for this vessel's profile.
    twin_config: TwinConfig,
    /// The profile the vessel runs on.
    profile: Arc<VesselProfile>,
    session: Session,
    /// The daemon's latest states...
    latest: LatestStates,
    /// ... and this vessel's slot there, made at its first state (a vessel
    /// that never has one leaves nothing behind).
    latest_slot: OnceLock<StateSlot>,
    /// The daemon's latest fault, alarms and finding...
    outputs: LatestOutputs,
    /// ... and this vessel's slot there, made at its first such output.
    outputs_slot: OnceLock<OutputSlot>,
    tap: OutputTap,
    save_failures: SaveFailures,
    metrics: Metrics,
    twin: VesselTwin,
    nmea: NmeaDecoder,
    assembler: FixAssembler,
    counters: Counters,
    replay: bool,
    last_prediction_time_s: Option<f64>,
    last_fix_wall: Option<Instant>,
    last_event_wall: Instant,
    stale_published: bool,
    unsaved: bool,
    /// The time of the last fix of the calibration the twin was restored
    /// from (a file or the network), s.
    restored_time_s: Option<f64>,
    monitor: Option<LiveMonitor>,
    diagnose_slots: Arc<Semaphore>,
    diagnosis: Option<oneshot::Receiver<Option<FindingsMessage>>>,
    published_causes: Option<Vec<String>>,
    forecaster: Forecaster,
    /// Told when an event routed to this task has been handled.
    load: FaultPathLoad,
    /// The forecast being computed on the forecast threads, if any.
    forecast: Option<oneshot::Receiver<Option<Vec<u8>>>>,
    /// A forecast fell due while one was being computed: ask again when it
    /// is out.
    forecast_wanted: bool,
    /// A fix changed which deadline is the nearest: re-arm the timer.
    rearm_timer: bool,
    /// The daemon's ROS 2 node, when enabled...
    ros2_node: Option<Arc<Ros2Node>>,
    /// ... and this vessel's ROS 2 publishers, declared at its first output.
    ros2: OnceLock<Option<VesselPublishers>>,
    /// The fleet this daemon belongs to (alone: every vessel's owner)...
    fleet: Fleet,
    /// ... and whether it is this vessel's active owner, as of a generation
    /// of the fleet's members (`generation << 1 | active`). A standby runs
    /// the twin and publishes nothing.
    role: AtomicU64,
}

/// The wall-clock instants the task's periodic work counts from.
struct WallTimers {
    last_stats: Instant,
    last_save: Instant,
}

/// Added to the timer's deadline so that the wake comes strictly after it.
const TIMER_SLACK_S: f64 = 0.001;

/// `start + seconds`, or a year after `start` when that is further (the
/// intervals are validated positive, not bounded); `start` itself only if
/// even that does not fit in an `Instant`, which a clock counting from boot
/// does not reach.
fn later(start: Instant, seconds: f64) -> Instant {
    let year = Duration::from_secs(365 * 24 * 3600);
    let d = Duration::try_from_secs_f64(seconds)
        .unwrap_or(year)
        .min(year);
    start.checked_add(d).unwrap_or(start)
}

/// The answer of work handed to another thread (a diagnosis, a forecast):
/// `None` if it gave none or was dropped; pending while nothing is asked.
async fn answer_of<T>(pending: &mut Option<oneshot::Receiver<Option<T>>>) -> Option<T> {
    match pending.as_mut() {
        Some(rx) => rx.await.ok().flatten(),
        None => std::future::pending().await,
    }
}

/// Diagnoses `events` (blocking: call it on a blocking thread) and says
/// what the daemon publishes: `None` when the events are too few.
fn diagnose_events(
    vessel: &str,
    events: &[DiagEvent],
    config: &DiagnoseConfig,
    trigger: Trigger,
    replay: bool,
) -> Option<FindingsMessage> {
    let prep = prepare(events)?;
    let first = prep.steps.first()?.fix.time_s;
    let last = prep.steps.last()?.fix.time_s;
    let d = diagnose(&prep, config);
    Some(FindingsMessage {
        vessel: vessel.to_string(),
        time: payload_time(last),
        window_s: last - first,
        base_model: match d.base {
            BaseModel::Kinetic => "kinetic",
            BaseModel::Water => "water",
        }
        .to_string(),
        nominal_nis_per_dof: d.nominal.nis_per_dof,
        trigger: trigger.name().to_string(),
        findings: d.findings.iter().map(FindingJson::from).collect(),
        unexplained: d.unexplained.as_ref().map(UnexplainedJson::from),
        replay,
    })
}

/// What every vessel task of a daemon shares.
#[derive(Clone)]
pub struct VesselShared {
    /// The daemon's session.
    pub session: Session,
    /// The latest states, shared with the queryable and the web page.
    pub latest: LatestStates,
    /// The latest fault, alarms and finding, for the queryable.
    pub outputs: LatestOutputs,
    /// Where outputs are copied for in-process listeners.
    pub tap: OutputTap,
    /// Bounds how many diagnoses run at once.
    pub diagnose_slots: Arc<Semaphore>,
    /// The forecast threads.
    pub forecaster: Forecaster,
    /// Counts the events routed and not yet handled.
    pub load: FaultPathLoad,
    /// Counts (and logs, rate-limited) the calibration saves that failed.
    pub save_failures: SaveFailures,
    /// The ROS 2 node, when `[ros2]` is enabled.
    pub ros2: Option<Arc<Ros2Node>>,
    /// The daemon's metrics (the fleet's counts, the estimator's time).
    pub metrics: Metrics,
    /// Which vessels this daemon is the active owner of ([`crate::fleet`]).
    pub fleet: Fleet,
}

impl VesselTask {
    /// A task for vessel `id`, with its calibration restored if one is saved.
    pub fn new(id: VesselId, settings: Arc<Settings>, shared: &VesselShared) -> Self {
        let VesselShared {
            session,
            latest,
            outputs,
            tap,
            diagnose_slots,
            forecaster,
            load,
            save_failures,
            ros2,
            metrics,
            fleet,
        } = shared.clone();
        let id_str = id.as_str().to_string();
        let (twin_config, profile) = settings.twin_for(id.as_str());
        let mut twin =
            VesselTwin::new(twin_config).expect("the settings' twin configuration was validated");
        let mut restored_time_s = None;
        if let Some(dir) = &settings.persistence.dir {
            match persist::load(dir, id.as_str(), &profile.identity()) {
                Ok(Some(calibration)) => {
                    tracing::info!(vessel = id.as_str(), theta = ?calibration.theta, "calibration restored");
                    restored_time_s = Some(calibration.time_s);
                    twin.restore(calibration);
                }
                Ok(None) => {}
                Err(e) => save_failures.not_restored(id.as_str(), &e),
            }
        }
        let assembler = FixAssembler::new(AssemblerConfig {
            // Live data: decide the position source within a second.
            decision_window_s: 1.0,
            ..AssemblerConfig::default()
        });
        let monitor = settings
            .diagnose
            .enabled
            .then(|| LiveMonitor::new(settings.diagnose.monitor));
        Self {
            id,
            settings,
            twin_config,
            profile,
            session,
            latest,
            latest_slot: OnceLock::new(),
            outputs,
            outputs_slot: OnceLock::new(),
            tap,
            save_failures,
            twin,
            nmea: NmeaDecoder::new(ReadOptions::default()),
            assembler,
            counters: Counters::for_fleet(metrics.fleet()),
            metrics,
            replay: false,
            last_prediction_time_s: None,
            last_fix_wall: None,
            last_event_wall: Instant::now(),
            stale_published: false,
            unsaved: false,
            restored_time_s,
            monitor,
            diagnose_slots,
            diagnosis: None,
            published_causes: None,
            forecaster,
            load,
            forecast: None,
            forecast_wanted: false,
            rearm_timer: false,
            ros2_node: ros2,
            ros2: OnceLock::new(),
            role: AtomicU64::new(
                fleet.generation() << 1 | u64::from(fleet.is_active(id_str.as_str())),
            ),
            fleet,
        }
    }

    /// The twin (for tests and the demo's summary).
    pub fn twin(&self) -> &VesselTwin {
        &self.twin
    }

    /// Runs until the channel closes (the dispatcher is done: shutdown, after
    /// everything queued has been handled) or the vessel falls silent.
    pub async fn run(mut self, mut rx: mpsc::Receiver<VesselEvent>) -> Counters {
        let keys = self.settings.keys.clone();
        let vessel_keys = match VesselKeys::new(&keys, &self.id) {
            Ok(p) => p,
            Err(e) => {
                tracing::error!(vessel = self.id.as_str(), "bad key: {e}");
                return self.counters;
            }
        };
        for ev in self.restore_from_network(&mut rx).await {
            self.last_event_wall = Instant::now();
            self.handle(ev, &vessel_keys).await;
            self.load.handled();
        }
        // Whether the task acts as the vessel's active owner (its token
        // held), changed only in `on_fleet_change`.
        let mut owning = self.active();
        let mut token = if owning {
            self.declare_token().await
        } else {
            None
        };
        let mut roles = self.fleet.subscribe();
        // One timer, armed for the earliest thing that can fall due (the
        // stale state, the statistics, the save, the silence), rather than a
        // periodic tick: a vessel sending fixes wakes for it about once per
        // `stale_after_s`, not four times a second.
        let started = Instant::now();
        let mut timers = WallTimers {
            last_stats: started,
            last_save: started,
        };
        let timer = tokio::time::sleep_until(self.next_wake(&timers).into());
        tokio::pin!(timer);
        loop {
            tokio::select! {
                biased;
                done = answer_of(&mut self.diagnosis), if self.diagnosis.is_some() => {
                    self.diagnosis = None;
                    if let Some(findings) = done {
                        self.publish_findings(findings, &vessel_keys).await;
                    }
                }
                json = answer_of(&mut self.forecast), if self.forecast.is_some() => {
                    self.forecast = None;
                    if let Some(json) = json {
                        self.publish_prediction(json, &vessel_keys).await;
                    }
                    if std::mem::take(&mut self.forecast_wanted) {
                        self.request_forecast();
                    }
                }
                Ok(()) = roles.changed() => {
                    self.on_fleet_change(&mut owning, &mut token, &vessel_keys).await;
                }
                ev = rx.recv() => match ev {
                    Some(ev) => {
                        self.last_event_wall = Instant::now();
                        self.handle(ev, &vessel_keys).await;
                        self.load.handled();
                        // A fix after a stale state, or the first unsaved
                        // one, brings a deadline nearer than the armed one.
                        if std::mem::take(&mut self.rearm_timer) {
                            timer.as_mut().reset(self.next_wake(&timers).into());
                        }
                    }
                    None => break,
                },
                () = &mut timer => {
                    let now = Instant::now();
                    if now.duration_since(self.last_event_wall).as_secs_f64() > self.settings.vessels.drop_after_silence_s {
                        tracing::info!(vessel = self.id.as_str(), "silent: dropping the vessel's twin");
                        break;
                    }
                    self.check_stale(&vessel_keys).await;
                    if now.duration_since(timers.last_stats).as_secs_f64() >= self.settings.publish.stats_interval_s {
                        timers.last_stats = now;
                        self.publish_stats(&vessel_keys).await;
                    }
                    if self.unsaved && now.duration_since(timers.last_save).as_secs_f64() >= self.settings.persistence.save_interval_s {
                        timers.last_save = now;
                        self.save().await;
                    }
                    timer.as_mut().reset(self.next_wake(&timers).into());
                }
            }
        }
        // Fallen silent (or shut down, when this finds nothing): no more
        // events come in, and any routed in the meantime are handled, not
        // lost (the dispatcher counts each in flight until it is).
        rx.close();
        while let Some(ev) = rx.recv().await {
            self.handle(ev, &vessel_keys).await;
            self.load.handled();
        }
        // A forecast still being computed is published, and one that fell
        // due meanwhile is made: what the twin computed is not lost (a
        // replay's last forecast included).
        while let Some(answer) = self.forecast.take() {
            if let Ok(Some(json)) = answer.await {
                self.publish_prediction(json, &vessel_keys).await;
            }
            if std::mem::take(&mut self.forecast_wanted) {
                self.request_forecast();
            }
        }
        // Last words: state, fault and statistics, then the calibration.
        self.publish_state_and_fault(&vessel_keys, false).await;
        self.publish_stats(&vessel_keys).await;
        self.save().await;
        drop(token);
        // The last clone of a declared key expression undeclares it.
        drop(vessel_keys);
        self.counters
    }

    /// When the task's timer should next fire: the earliest of the silence
    /// deadline, the next statistics, the next save (while something is
    /// unsaved) and the stale deadline (while fixes come), plus a
    /// millisecond so that the strict comparisons at the wake hold.
    fn next_wake(&self, timers: &WallTimers) -> Instant {
        let s = &self.settings;
        let mut wake = later(self.last_event_wall, s.vessels.drop_after_silence_s)
            .min(later(timers.last_stats, s.publish.stats_interval_s));
        if self.unsaved {
            wake = wake.min(later(timers.last_save, s.persistence.save_interval_s));
        }
        if let Some(last_fix) = self.last_fix_wall
            && !self.stale_published
        {
            wake = wake.min(later(last_fix, s.vessels.stale_after_s));
        }
        later(wake, TIMER_SLACK_S)
    }

    /// Puts `bytes` on `key`, blocking when Zenoh's queues are full (nothing
    /// the twin computed is dropped on the way out). A standby puts nothing;
    /// in a fleet every put carries the attachment `daemon=<id>`.
    async fn put(&self, key: &VesselKey, bytes: Vec<u8>) -> zenoh::Result<()> {
        if !self.active() {
            return Ok(());
        }
        // Declared only when the vessels' tokens are on: they are what
        // makes an undeclared key's routing walk the fleet, and declaring a
        // key walks it too (a fleet starting at once would cost the square
        // of its size; `twin-bench cold-start`).
        let key = if self.settings.publish.vessel_liveliness {
            key.declared(&self.session)
        } else {
            &key.key
        };
        self.put_on(key, bytes).await
    }

    /// Puts `bytes` on `key` as JSON, blocking when Zenoh's queues are
    /// full; in a fleet with the attachment `daemon=<id>`.
    async fn put_on(&self, key: &KeyExpr<'_>, bytes: Vec<u8>) -> zenoh::Result<()> {
        let put = self
            .session
            .put(key, bytes)
            .encoding(Encoding::APPLICATION_JSON)
            .congestion_control(CongestionControl::Block);
        match self.fleet.daemon_id() {
            Some(id) => put.attachment(format!("daemon={id}")).await,
            None => put.await,
        }
    }

    /// Whether this daemon is the vessel's active owner (always, alone).
    fn active(&self) -> bool {
        let role = self.role.load(Ordering::Relaxed);
        let now = self.fleet.generation();
        if now == role >> 1 {
            return role & 1 == 1;
        }
        let active = self.fleet.is_active(self.id.as_str());
        self.role
            .store(now << 1 | u64::from(active), Ordering::Relaxed);
        active
    }

    /// The vessel's `twin/alive` token, when the settings ask for one.
    async fn declare_token(&self) -> Option<zenoh::liveliness::LivelinessToken> {
        if !self.settings.publish.vessel_liveliness {
            return None;
        }
        let key = self
            .settings
            .publish
            .liveliness_key(&self.settings.keys, &self.id);
        match self.session.liveliness().declare_token(key).await {
            Ok(token) => Some(token),
            Err(e) => {
                tracing::warn!(vessel = self.id.as_str(), "no liveliness token: {e}");
                None
            }
        }
    }

    /// The fleet's members changed: on becoming the active owner, the
    /// vessel's token and its state and fault at once (from the twin kept
    /// as a standby); on becoming a standby, the token goes.
    async fn on_fleet_change(
        &mut self,
        owning: &mut bool,
        token: &mut Option<zenoh::liveliness::LivelinessToken>,
        p: &VesselKeys,
    ) {
        let now = self.active();
        if now == *owning {
            return;
        }
        *owning = now;
        if now {
            tracing::info!(
                vessel = self.id.as_str(),
                "taking over the vessel: this daemon is its active owner"
            );
            *token = self.declare_token().await;
            self.publish_state_and_fault(p, self.stale_published).await;
        } else {
            tracing::info!(
                vessel = self.id.as_str(),
                "standing by: another daemon is the vessel's active owner"
            );
            *token = None;
        }
    }

    /// Saves the calibration to the state directory, and, in a fleet that
    /// shares calibrations, puts it on the network when this daemon is the
    /// vessel's active owner.
    async fn save(&mut self) {
        let Some(c) = self.twin.calibration() else {
            return;
        };
        let profile = self.profile.identity();
        match &self.settings.persistence.dir {
            Some(dir) => match persist::save(dir, self.id.as_str(), &c, &profile) {
                Ok(()) => self.unsaved = false,
                Err(e) => self.save_failures.failed(self.id.as_str(), &e),
            },
            None => self.unsaved = false,
        }
        let Some(key) = self.settings.fleet.calibration_key(self.id.as_str()) else {
            return;
        };
        if !self.active() {
            return;
        }
        let shared = match (
            persist::encode(self.id.as_str(), &c, &profile),
            KeyExpr::try_from(key.as_str()),
        ) {
            (Ok(text), Ok(key)) => self
                .put_on(&key, text.into_bytes())
                .await
                .map_err(|e| e.to_string()),
            (Err(e), _) => Err(e),
            (_, Err(e)) => Err(e.to_string()),
        };
        if let Err(e) = shared {
            tracing::warn!(
                vessel = self.id.as_str(),
                key,
                "calibration not shared: {e}"
            );
        }
    }

    /// In a fleet that shares calibrations, asks the network for the
    /// vessel's calibration (a storage on the routers keeps what the owners
    /// put) and restores it when it is newer than the one restored from the
    /// state directory, if any. One learnt with another profile, or not the
    /// vessel's, is refused and logged.
    ///
    /// The vessel's events that arrive meanwhile are taken from `rx` and
    /// returned, in order, for the caller to handle after the restore: a
    /// full queue would stop the dispatcher, and with it Zenoh's reading
    /// of the answer itself.
    async fn restore_from_network(
        &mut self,
        rx: &mut mpsc::Receiver<VesselEvent>,
    ) -> Vec<VesselEvent> {
        let mut meanwhile = Vec::new();
        let Some(key) = self.settings.fleet.calibration_key(self.id.as_str()) else {
            return meanwhile;
        };
        let wait = Duration::from_secs_f64(self.settings.fleet.calibration_wait_s);
        let replies = match self.session.get(&key).timeout(wait).await {
            Ok(replies) => replies,
            Err(e) => {
                tracing::warn!(
                    vessel = self.id.as_str(),
                    key,
                    "cannot ask for the calibration: {e}"
                );
                return meanwhile;
            }
        };
        let profile = self.profile.identity();
        let mut newest: Option<twin_core::twin::Calibration> = None;
        let mut open = true;
        loop {
            let reply = tokio::select! {
                reply = replies.recv_async() => match reply {
                    Ok(reply) => reply,
                    Err(_) => break,
                },
                ev = rx.recv(), if open => {
                    match ev {
                        Some(ev) => meanwhile.push(ev),
                        None => open = false,
                    }
                    continue;
                }
            };
            let Ok(sample) = reply.result() else {
                continue;
            };
            match persist::decode(&sample.payload().to_bytes(), self.id.as_str(), &profile) {
                Ok(c) if newest.as_ref().is_none_or(|n| c.time_s > n.time_s) => newest = Some(c),
                Ok(_) => {}
                Err(why) => tracing::warn!(
                    vessel = self.id.as_str(),
                    key,
                    "a calibration from the network refused: {why}"
                ),
            }
        }
        if let Some(c) = newest
            && self.restored_time_s.is_none_or(|t| c.time_s > t)
        {
            tracing::info!(
                vessel = self.id.as_str(),
                theta = ?c.theta,
                learnt_until_s = c.time_s,
                "calibration restored from the network"
            );
            self.restored_time_s = Some(c.time_s);
            self.twin.restore(c);
        }
        meanwhile
    }

    async fn handle(&mut self, ev: VesselEvent, p: &VesselKeys) {
        match ev {
            VesselEvent::Refused {
                topic,
                reason,
                detail,
            } => {
                self.counters.receive(topic);
                self.counters.reject(self.id.as_str(), reason, &detail)
            }
            VesselEvent::Payload { topic, bytes } => self.handle_payload(topic, &bytes, p).await,
        }
    }

    async fn handle_payload(&mut self, topic: Topic, bytes: &[u8], p: &VesselKeys) {
        self.counters.receive(topic);
        let who = self.id.as_str();
        match topic {
            Topic::Gnss => {
                let d = match decode_gnss_limited(bytes, self.settings.max_payload_bytes) {
                    Ok(d) => d,
                    Err(e) => return self.counters.reject(who, e.reason(), &e),
                };
                if let Err((reason, detail)) =
                    check_live_time(&self.settings.live_time, d.replay, d.value.time_s)
                {
                    return self.counters.reject(who, reason, &detail);
                }
                self.replay = d.replay;
                match self.on_fix(&d.value, p).await {
                    Ok(()) => self.counters.accept(Topic::Gnss),
                    Err(r) => self.counters.reject(self.id.as_str(), r.reason(), &r),
                }
            }
            Topic::Actuators => {
                let d = match decode_actuators_limited(bytes, self.settings.max_payload_bytes) {
                    Ok(d) => d,
                    Err(e) => return self.counters.reject(who, e.reason(), &e),
                };
                let speeds = speeds_of(d.value, &self.twin_config.kinetic.params);
                if let Err((reason, detail)) =
                    check_live_time(&self.settings.live_time, d.replay, speeds.time_s)
                {
                    return self.counters.reject(who, reason, &detail);
                }
                self.replay = d.replay;
                match self.on_propellers(&speeds) {
                    Ok(()) => self.counters.accept(Topic::Actuators),
                    Err(r) => self.counters.reject(self.id.as_str(), r.reason(), &r),
                }
            }
            Topic::Nmea => self.handle_nmea(bytes, p).await,
            other => self
                .counters
                .reject(who, "not_an_input_topic", &other.suffix()),
        }
    }

    /// An NMEA payload: accepted when at least one sentence gives a record
    /// (the others counted as refused sentences), else refused with the
    /// first sentence's reason; the fixes and shaft speeds assembled from
    /// the records then go to the twin, their refusals counted apart
    /// ([`twin_wire::outputs::NmeaStats`]). NMEA carries no replay flag: its
    /// times are live, held to the daemon's clock.
    async fn handle_nmea(&mut self, bytes: &[u8], p: &VesselKeys) {
        let mut items = Vec::new();
        self.nmea.decode_payload(bytes, &mut items);
        if !items.iter().any(|i| i.is_ok()) {
            let who = self.id.as_str();
            return match items.into_iter().find_map(Result::err) {
                Some(r) => self.counters.reject(who, r.reason.kind().name(), &r),
                None => self.counters.reject(who, EMPTY_NMEA, &"no NMEA sentence"),
            };
        }
        self.counters.accept(Topic::Nmea);
        let mut assembled = Vec::new();
        for item in items {
            match item {
                Ok(record) => {
                    if let (Measurement::SpeedThroughWater { mps }, Some(m)) =
                        (&record.measurement, self.monitor.as_mut())
                    {
                        m.push(DiagEvent::SpeedThroughWater {
                            time_s: record.time_s,
                            mps: *mps,
                        });
                    }
                    self.assembler.push(record, &mut assembled)
                }
                Err(rejection) => {
                    let reason = rejection.reason.kind().name();
                    self.counters.refuse(
                        Refused::NmeaSentence,
                        self.id.as_str(),
                        reason,
                        &rejection,
                    );
                }
            }
        }
        for a in assembled {
            match a {
                Assembled::Fix(fix) => {
                    if let Err((reason, detail)) =
                        check_live_time(&self.settings.live_time, false, fix.time_s)
                    {
                        self.counters
                            .refuse(Refused::NmeaFix, self.id.as_str(), reason, &detail);
                        continue;
                    }
                    self.replay = false;
                    match self.on_fix(&fix, p).await {
                        Ok(()) => self.counters.nmea.fixes += 1,
                        Err(r) => {
                            self.counters
                                .refuse(Refused::NmeaFix, self.id.as_str(), r.reason(), &r)
                        }
                    }
                }
                Assembled::Propellers(s) => self.on_nmea_propellers(s),
                Assembled::Thrust(t) => self.on_nmea_propellers(speeds_of(
                    ActuatorCommand::Thrust(t),
                    &self.twin_config.kinetic.params,
                )),
            }
        }
    }

    /// Shaft speeds assembled from NMEA, held to the daemon's clock.
    fn on_nmea_propellers(&mut self, speeds: PropellerSpeeds) {
        let result =
            check_live_time(&self.settings.live_time, false, speeds.time_s).and_then(|()| {
                self.on_propellers(&speeds)
                    .map_err(|r| (r.reason(), r.to_string()))
            });
        match result {
            Ok(()) => self.counters.nmea.propellers += 1,
            Err((reason, detail)) => {
                self.counters
                    .refuse(Refused::NmeaPropellers, self.id.as_str(), reason, &detail)
            }
        }
    }

    /// Shaft speeds to the twin (and, once taken, to the live monitor).
    fn on_propellers(&mut self, speeds: &PropellerSpeeds) -> Result<(), Rejection> {
        let started = Instant::now();
        let taken = self.twin.on_propellers(speeds);
        self.metrics.observe(Update::Propellers, started.elapsed());
        taken?;
        if let Some(m) = self.monitor.as_mut() {
            m.push(DiagEvent::Propellers(*speeds));
        }
        Ok(())
    }

    /// A fix to the twin; once taken, its outputs are published.
    async fn on_fix(&mut self, fix: &GnssFix, p: &VesselKeys) -> Result<(), Rejection> {
        let started = Instant::now();
        let taken = self.twin.on_gnss(fix);
        self.metrics.observe(Update::Fix, started.elapsed());
        let out = taken?;
        // The armed timer was set without a stale or a save deadline.
        self.rearm_timer |= self.stale_published || !self.unsaved || self.last_fix_wall.is_none();
        self.last_fix_wall = Some(Instant::now());
        self.stale_published = false;
        self.unsaved = true;
        self.monitor_fix(fix, &out);
        self.publish_step(&out, p).await;
        Ok(())
    }

    /// Feeds the live monitor an accepted fix and starts a diagnosis when
    /// one is due and none is running.
    fn monitor_fix(&mut self, fix: &GnssFix, out: &StepOutput) {
        let Some(monitor) = self.monitor.as_mut() else {
            return;
        };
        monitor.push(DiagEvent::Fix(*fix));
        let position = (out.innovation_available[0] && out.innovation_available[1])
            .then_some([out.innovation[0], out.innovation[1]]);
        monitor.record_innovation(fix.time_s, position);
        if self.diagnosis.is_some() {
            return;
        }
        let Some(trigger) = monitor.due(fix.time_s) else {
            return;
        };
        let events = monitor.start(fix.time_s);
        let config = DiagnoseConfig {
            threads: 1,
            twin: TwinConfig {
                kinetic: self.twin_config.kinetic.for_search(),
                ..self.twin_config
            },
            ..DiagnoseConfig::default()
        };
        let vessel = self.id.as_str().to_string();
        let replay = self.replay;
        let slots = self.diagnose_slots.clone();
        let (tx, rx) = oneshot::channel();
        self.diagnosis = Some(rx);
        tracing::debug!(
            vessel,
            trigger = trigger.name(),
            events = events.len(),
            "diagnosing"
        );
        tokio::spawn(async move {
            // The permit bounds the diagnoses running across the daemon; it
            // is held until the blocking work is done.
            let Ok(_permit) = slots.acquire_owned().await else {
                return;
            };
            let result = tokio::task::spawn_blocking(move || {
                diagnose_events(&vessel, &events, &config, trigger, replay)
            })
            .await
            .unwrap_or_else(|e| {
                tracing::error!("a diagnosis failed: {e}");
                None
            });
            let _ = tx.send(result);
        });
    }

    /// Publishes a diagnosis when its causes differ from the last published.
    async fn publish_findings(&mut self, findings: FindingsMessage, p: &VesselKeys) {
        let causes = findings.causes();
        if self.published_causes.as_ref() == Some(&causes) {
            return;
        }
        tracing::info!(
            vessel = self.id.as_str(),
            trigger = %findings.trigger,
            "model findings: {}",
            match (causes.is_empty(), findings.unexplained.is_some()) {
                (false, _) => causes.join(", "),
                (true, false) => "none (the nominal model explains the data)".to_string(),
                (true, true) => "none (no cause of the catalogue clears the bars)".to_string(),
            }
        );
        self.published_causes = Some(causes);
        self.put_kept(
            Topic::TwinFinding,
            Some(Kept::Finding),
            &p.finding,
            &findings,
        )
        .await;
    }

    async fn publish_step(&mut self, out: &StepOutput, p: &VesselKeys) {
        let vessel = self.id.as_str();
        let state = StateMessage::new(vessel, &out.state, false, self.replay);
        self.put_state(&state, p).await;
        self.put_fault(&FaultMessage::new(vessel, &out.faults, self.replay), p)
            .await;
        for change in &out.changes {
            self.publish_alarm(change, p).await;
        }
        let t = out.state.time_s;
        let due = self
            .last_prediction_time_s
            .is_none_or(|last| t - last >= self.settings.publish.prediction_interval_s - 1e-9);
        if due {
            self.last_prediction_time_s = Some(t);
            self.request_forecast();
        }
    }

    async fn publish_alarm(&self, change: &StatusChange, p: &VesselKeys) {
        let alarm = AlarmMessage::new(self.id.as_str(), change, self.replay);
        tracing::info!(
            vessel = self.id.as_str(),
            "{} (confidence {:.2})",
            alarm.what,
            alarm.confidence
        );
        self.put_kept(Topic::TwinAlarm, Some(Kept::Alarm), &p.alarm, &alarm)
            .await;
    }

    /// Asks the forecast threads for a forecast from the twin as it is now,
    /// or, while one is being computed, for another as soon as that one is
    /// out (see [`crate::forecast`]).
    fn request_forecast(&mut self) {
        if self.forecast.is_some() {
            self.forecast_wanted = true;
            return;
        }
        let s = &self.settings.publish;
        let (reply, answer) = oneshot::channel();
        let job = ForecastJob {
            twin: Box::new(self.twin.clone()),
            vessel: self.id.as_str().to_string(),
            horizon_s: s.prediction_horizon_s,
            step_s: s.prediction_step_s,
            replay: self.replay,
            reply,
        };
        match self.forecaster.submit(job) {
            Ok(()) => self.forecast = Some(answer),
            Err(_) => tracing::error!(vessel = self.id.as_str(), "the forecast threads have ended"),
        }
    }

    async fn publish_prediction(&self, json: Vec<u8>, p: &VesselKeys) {
        self.tap_out(Topic::TwinPrediction, &json);
        if let Some(ros) = self.ros2_publishers() {
            ros.prediction(&self.session, &json).await;
        }
        if let Err(e) = self.put(&p.prediction, json).await {
            tracing::warn!(key = %p.prediction, "not published: {e}");
        }
    }

    async fn put_state(&self, state: &StateMessage, p: &VesselKeys) {
        let Ok(bytes) = encode_json(state, OUTPUT_CAPACITY_BYTES) else {
            return;
        };
        self.latest_slot
            .get_or_init(|| self.latest.slot(self.id.as_str()))
            .set(&bytes);
        self.tap_out(Topic::TwinState, &bytes);
        if let Err(e) = self.put(&p.state, bytes).await {
            tracing::warn!(vessel = self.id.as_str(), "state not published: {e}");
        }
        if let Some(ros) = self.ros2_publishers() {
            ros.state(&self.session, state).await;
        }
    }

    /// Hands an output to the in-process listeners (the web page), if any.
    fn tap_out(&self, topic: Topic, bytes: &[u8]) {
        if !self.active() {
            return;
        }
        if let Some(tx) = &self.tap
            && tx.receiver_count() > 0
        {
            let _ = tx.send(OutputEvent {
                vessel: self.id.as_str().to_string(),
                topic,
                json: String::from_utf8_lossy(bytes).into(),
            });
        }
    }

    async fn put_json<T: serde::Serialize>(&self, topic: Topic, key: &VesselKey, value: &T) {
        self.put_kept(topic, None, key, value).await
    }

    /// [`Self::put_json`], the payload also kept as the vessel's latest
    /// `kept` output for the queryable.
    async fn put_kept<T: serde::Serialize>(
        &self,
        topic: Topic,
        kept: Option<Kept>,
        key: &VesselKey,
        value: &T,
    ) {
        match encode_json(value, OUTPUT_CAPACITY_BYTES) {
            Ok(bytes) => {
                if let Some(kind) = kept {
                    self.outputs_slot
                        .get_or_init(|| self.outputs.slot(self.id.as_str()))
                        .set(kind, &bytes);
                }
                self.tap_out(topic, &bytes);
                if let Err(e) = self.put(key, bytes).await {
                    tracing::warn!(key = %key, "not published: {e}");
                }
            }
            Err(e) => tracing::error!("cannot encode a payload: {e}"),
        }
    }

    async fn publish_state_and_fault(&self, p: &VesselKeys, stale: bool) {
        let Some(state) = self.twin.state_report() else {
            return;
        };
        let msg = StateMessage::new(self.id.as_str(), &state, stale, self.replay);
        self.put_state(&msg, p).await;
        let faults = self.twin.fault_report(state.time_s);
        self.put_fault(
            &FaultMessage::new(self.id.as_str(), &faults, self.replay),
            p,
        )
        .await;
    }

    async fn put_fault(&self, fault: &FaultMessage, p: &VesselKeys) {
        self.put_kept(Topic::TwinFault, Some(Kept::Fault), &p.fault, fault)
            .await;
        if let Some(ros) = self.ros2_publishers() {
            ros.fault(&self.session, fault).await;
        }
    }

    /// This vessel's ROS 2 publishers, declared on the first call; `None`
    /// when `[ros2]` is off (or Zenoh refused the keys, which is logged).
    fn ros2_publishers(&self) -> Option<&VesselPublishers> {
        if !self.active() {
            return None;
        }
        let node = self.ros2_node.as_ref()?;
        self.ros2
            .get_or_init(|| {
                VesselPublishers::declare(node, &self.session, self.id.as_str())
                    .map_err(|e| {
                        tracing::error!(vessel = self.id.as_str(), "no ROS 2 publishers: {e}")
                    })
                    .ok()
            })
            .as_ref()
    }

    async fn check_stale(&mut self, p: &VesselKeys) {
        let Some(last) = self.last_fix_wall else {
            return;
        };
        let silent_s = last.elapsed().as_secs_f64();
        if silent_s > self.settings.vessels.stale_after_s && !self.stale_published {
            tracing::info!(
                vessel = self.id.as_str(),
                "no fix for {silent_s:.1} s: state is stale"
            );
            self.stale_published = true;
            self.publish_state_and_fault(p, true).await;
            self.request_forecast();
        }
    }

    /// The counters as published on `twin/stats`.
    pub fn stats_message(&self) -> StatsMessage {
        StatsMessage {
            vessel: self.id.as_str().to_string(),
            profile: self.profile.identity(),
            received: self.counters.received(),
            accepted: self.counters.accepted(),
            rejected: self.counters.rejected.clone(),
            nmea: self.counters.nmea.clone(),
        }
    }

    async fn publish_stats(&self, p: &VesselKeys) {
        self.put_json(Topic::TwinStats, &p.stats, &self.stats_message())
            .await;
    }
}

/// The reason of an NMEA payload that holds no sentence at all.
pub(crate) const EMPTY_NMEA: &str = "empty_nmea";

/// A live message's time stamp (`replay` false) held to the daemon's
/// clock: more than `max_ahead_s` ahead of it or `max_behind_s` behind it
/// is refused with the reason and a detail. A replay's times are its log's
/// and are not compared with the clock (the twin holds them to its own
/// timeline).
pub(crate) fn check_live_time(
    bounds: &LiveTimeSettings,
    replay: bool,
    time_s: f64,
) -> Result<(), (&'static str, String)> {
    if replay {
        return Ok(());
    }
    let now_s = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64());
    let ahead_s = time_s - now_s;
    if ahead_s > bounds.max_ahead_s {
        Err((
            "time_ahead_of_clock",
            format!(
                "stamped {ahead_s:.0} s ahead of the daemon's clock (at most {} s)",
                bounds.max_ahead_s
            ),
        ))
    } else if -ahead_s > bounds.max_behind_s {
        Err((
            "time_behind_clock",
            format!(
                "stamped {:.0} s behind the daemon's clock (at most {} s)",
                -ahead_s, bounds.max_behind_s
            ),
        ))
    } else {
        Ok(())
    }
}

/// An actuator command as shaft speeds (a thrust through the Otter's
/// propeller curve).
pub(crate) fn speeds_of(command: ActuatorCommand, params: &VesselParams) -> PropellerSpeeds {
    match command {
        ActuatorCommand::Speeds(s) => s,
        ActuatorCommand::Thrust(ThrustCommand {
            time_s,
            port_n,
            starboard_n,
        }) => PropellerSpeeds {
            time_s,
            port_radps: params.shaft_speed_for_thrust_radps(port_n),
            starboard_radps: params.shaft_speed_for_thrust_radps(starboard_n),
        },
    }
}

/// Room reserved for an output payload: a state or fault message is about
/// 600 bytes, so each is written into one allocation.
const OUTPUT_CAPACITY_BYTES: usize = 1024;

/// `value` as JSON, written into a buffer of `capacity_bytes` to start with
/// (`serde_json::to_vec` starts empty and reallocates as it grows, about
/// seven times for a fault message).
pub(crate) fn encode_json<T: serde::Serialize + ?Sized>(
    value: &T,
    capacity_bytes: usize,
) -> serde_json::Result<Vec<u8>> {
    let mut bytes = Vec::with_capacity(capacity_bytes);
    serde_json::to_writer(&mut bytes, value)?;
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::lone_session;

    #[tokio::test(flavor = "multi_thread", worker_threads = 1)]
    async fn a_vessel_key_is_declared_on_its_first_use() {
        let session = lone_session().await;
        let fault = VesselKey::new("asv/b1/twin/fault".into()).unwrap();
        let state = VesselKey::new("asv/b1/twin/state".into()).unwrap();
        // An undeclared key expression cannot be undeclared: what the
        // checks below tell apart.
        assert!(session.undeclare(fault.key.clone()).await.is_err());
        assert!(
            fault.declared.get().is_none(),
            "declared before its first use"
        );
        assert!(state.declared.get().is_none());

        let declared = fault.declared(&session).clone();
        assert_eq!(declared.as_str(), "asv/b1/twin/fault");
        assert_eq!(fault.declared(&session).as_str(), "asv/b1/twin/fault");
        let state_declared = state.declared(&session).clone();

        // They are declarations of the session's (undeclaring an undeclared
        // key fails), which go with the last clone of the key.
        drop(fault);
        drop(state);
        assert!(session.undeclare(declared).await.is_ok());
        assert!(session.undeclare(state_declared).await.is_ok());
        session.close().await.unwrap();
    }
}
