//! Forecasts off the fault path.
//!
//! A vessel's 60 s forecast costs a few hundred microseconds (the extended
//! twin's state and covariance through sixty 1 s steps, then sixty points of
//! JSON), against a few microseconds for the estimator step that produces a
//! fault. Computed in the vessel's task, on the tokio workers, each forecast
//! would hold up every other vessel's faults behind it: at 1,000 vessels
//! forecasts are about a third of the workers' time (docs/performance.md,
//! "The forecasts").
//!
//! Here they run on their own threads (`[publish] forecast_threads`) under
//! Linux's `SCHED_IDLE` policy: they run on the CPU time nothing else of
//! normal priority wants, so when the machine is busy the kernel gives the
//! estimates and the faults the CPU first. (At nice 10 they take about a
//! third of a core at 4,500 vessels x 10 Hz and the faults' p50 latency is
//! 7 ms; with `SCHED_IDLE` 0.8 ms.) A
//! vessel task hands over a copy of its twin (plain data, a few kilobytes)
//! and gets back the prediction's JSON; it keeps at most one forecast in
//! flight, and when the next is due before that one is out it asks again as
//! soon as it is (from its newest estimate). So under load forecasts come
//! less often and never queue up; on an idle machine they come every
//! `prediction_interval_s`. [`computed_total`] counts
//! them, so that a benchmark can say how often they came.
//!
//! `SCHED_IDLE` alone does not keep them off the fault path near the
//! daemon's limit: at 5,200 vessels x 10 Hz the faults' p50 is 98-278 ms
//! with forecasts that do not wait and 2.6 ms with no forecasts. An
//! idle-policy thread still takes a CPU in the gaps between the busy
//! threads' wake-ups, and the busy threads then run slower. So the threads
//! also wait while the fault path is
//! saturated ([`FaultPathLoad`]: events routed to the vessel tasks have
//! not all been handled for [`SATURATED_AFTER`]), each job at most
//! [`MAX_YIELD`], so that forecasts never stop altogether: on a saturated
//! daemon, one per thread per second (docs/performance.md).

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use tokio::sync::oneshot;
use twin_core::twin::VesselTwin;
use twin_wire::outputs::PredictionMessage;

/// Forecasts computed by every forecast thread of this process.
static COMPUTED: AtomicU64 = AtomicU64::new(0);

/// How many forecasts the forecast threads of this process have computed
/// (with an estimate to start from), since it started.
pub fn computed_total() -> u64 {
    COMPUTED.load(Ordering::Relaxed)
}

/// The fault path counts as saturated when events routed to the vessel
/// tasks have not all been handled for this long.
pub const SATURATED_AFTER: Duration = Duration::from_millis(20);

/// The longest a forecast thread waits, per job, for the fault path to
/// stop being saturated before it computes the forecast anyway.
pub const MAX_YIELD: Duration = Duration::from_secs(1);

/// How often a waiting forecast thread looks at the fault path again.
const YIELD_POLL: Duration = Duration::from_millis(2);

/// Whether the fault path keeps up, as the forecast threads see it. The
/// dispatcher counts every event it routes to a vessel's queue, and the
/// vessel's task counts it again once handled; the fault path is saturated
/// once some event has been waiting or in hand without a break for
/// [`SATURATED_AFTER`] (on a daemon that keeps up, the count falls to zero
/// between fixes). Cloning shares it.
#[derive(Clone, Debug)]
pub struct FaultPathLoad {
    inner: Arc<LoadInner>,
}

#[derive(Debug)]
struct LoadInner {
    epoch: Instant,
    /// Events routed to vessel tasks and not yet handled.
    in_flight: AtomicU64,
    /// When `in_flight` last rose from zero, us after `epoch`.
    busy_since_us: AtomicU64,
}

impl Default for FaultPathLoad {
    fn default() -> Self {
        Self::new()
    }
}

impl FaultPathLoad {
    /// A gauge with nothing in flight.
    pub fn new() -> Self {
        Self {
            inner: Arc::new(LoadInner {
                epoch: Instant::now(),
                in_flight: AtomicU64::new(0),
                busy_since_us: AtomicU64::new(0),
            }),
        }
    }

    fn now_us(&self) -> u64 {
        // Saturates after 584,000 years.
        u64::try_from(self.inner.epoch.elapsed().as_micros()).unwrap_or(u64::MAX)
    }

    /// An event was routed to a vessel's queue: the fault path is busy from
    /// now on if it was not already.
    pub fn routed(&self) {
        if self.inner.in_flight.fetch_add(1, Ordering::Relaxed) == 0 {
            // Between the count and this store a reader sees the previous
            // busy spell's start, and may wait one poll for nothing.
            self.inner
                .busy_since_us
                .store(self.now_us(), Ordering::Relaxed);
        }
    }

    /// A vessel task has handled an event routed to it (or a routed event
    /// was not taken): when none is left, the fault path has caught up.
    pub fn handled(&self) {
        let _ = self
            .inner
            .in_flight
            .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |n| n.checked_sub(1));
    }

    /// Events routed and not yet handled.
    pub fn in_flight(&self) -> u64 {
        self.inner.in_flight.load(Ordering::Relaxed)
    }

    /// Whether events have been in flight without a break for longer than
    /// [`SATURATED_AFTER`].
    pub fn saturated(&self) -> bool {
        self.saturated_at(self.now_us())
    }

    /// [`Self::saturated`] at `now_us` (us after the gauge's epoch).
    fn saturated_at(&self, now_us: u64) -> bool {
        self.in_flight() > 0
            && now_us.saturating_sub(self.inner.busy_since_us.load(Ordering::Relaxed))
                > SATURATED_AFTER.as_micros() as u64
    }

    /// Waits (sleeping) while the fault path is saturated, at most
    /// `at_most`.
    fn yield_while_saturated(&self, at_most: Duration) {
        let start = Instant::now();
        while self.saturated() && start.elapsed() < at_most {
            std::thread::sleep(YIELD_POLL);
        }
    }
}

/// One forecast to compute.
pub struct ForecastJob {
    /// A copy of the vessel's twin as it was when the forecast was asked for.
    pub twin: Box<VesselTwin>,
    /// Vessel id, for the message.
    pub vessel: String,
    /// Forecast horizon, s.
    pub horizon_s: f64,
    /// Forecast step, s.
    pub step_s: f64,
    /// Whether the inputs were replayed (copied into the message).
    pub replay: bool,
    /// Where the prediction's JSON goes (`None`: the twin has no estimate
    /// yet, or the message could not be encoded).
    pub reply: oneshot::Sender<Option<Vec<u8>>>,
}

/// The forecast threads. Cloning shares them; they end when the last clone
/// is dropped and the jobs already handed over are done.
#[derive(Clone)]
pub struct Forecaster {
    jobs: mpsc::Sender<ForecastJob>,
}

impl Forecaster {
    /// Starts `threads` forecast threads (at least one), yielding to the
    /// fault path while `load` says it is saturated.
    pub fn start(threads: usize, load: FaultPathLoad) -> std::io::Result<Self> {
        let (jobs, queue) = mpsc::channel::<ForecastJob>();
        let queue = Arc::new(Mutex::new(queue));
        for i in 0..threads.max(1) {
            let queue = queue.clone();
            let load = load.clone();
            std::thread::Builder::new()
                .name(format!("twind-forecast-{i}"))
                .spawn(move || {
                    lower_priority();
                    loop {
                        // The lock is held only while taking a job.
                        let job = match queue.lock() {
                            Ok(q) => q.recv(),
                            Err(_) => return,
                        };
                        let Ok(job) = job else { return };
                        load.yield_while_saturated(MAX_YIELD);
                        let json = prediction_json(&job);
                        if json.is_some() {
                            COMPUTED.fetch_add(1, Ordering::Relaxed);
                        }
                        // The vessel may have gone meanwhile: nothing to do.
                        let _ = job.reply.send(json);
                    }
                })?;
        }
        Ok(Self { jobs })
    }

    /// Hands a forecast over; the answer comes on the job's `reply`.
    /// Fails (returning the job) only if every thread has ended.
    pub fn submit(&self, job: ForecastJob) -> Result<(), Box<ForecastJob>> {
        self.jobs.send(job).map_err(|e| Box::new(e.0))
    }
}

/// The forecast and its message, as the daemon publishes it.
pub fn prediction_json(job: &ForecastJob) -> Option<Vec<u8>> {
    let state = job.twin.state_report()?;
    let points = job.twin.forecast(job.horizon_s, job.step_s);
    let msg = PredictionMessage::new(
        &job.vessel,
        state.time_s,
        job.horizon_s,
        job.step_s,
        state.source,
        &points,
        job.replay,
    );
    // About 310 bytes a point (18.8 KB for 60), and the header.
    match crate::vessel::encode_json(&msg, 512 + 320 * points.len()) {
        Ok(bytes) => Some(bytes),
        Err(e) => {
            tracing::error!("cannot encode a prediction: {e}");
            None
        }
    }
}

/// Puts the calling thread under `SCHED_IDLE`: it runs only on CPU time no
/// normally scheduled thread wants (Linux: the policy is per thread).
#[cfg(target_os = "linux")]
fn lower_priority() {
    use thread_priority::ThreadPriority;
    use thread_priority::unix::{
        NormalThreadSchedulePolicy, ThreadSchedulePolicy, set_thread_priority_and_policy,
        thread_native_id,
    };
    let result = set_thread_priority_and_policy(
        thread_native_id(),
        ThreadPriority::Min,
        ThreadSchedulePolicy::Normal(NormalThreadSchedulePolicy::Idle),
    );
    if let Err(e) = result {
        tracing::debug!("the forecast thread keeps its priority: {e}");
    }
}

/// Elsewhere the forecast threads keep the default priority.
#[cfg(not(target_os = "linux"))]
fn lower_priority() {}

#[cfg(test)]
mod tests {
    use super::*;
    use twin_core::sample::GnssFix;
    use twin_core::twin::TwinConfig;

    fn twin_with_fixes() -> VesselTwin {
        let mut twin = VesselTwin::new(TwinConfig::default()).unwrap();
        for k in 0..30 {
            let t = 1_700_000_000.0 + k as f64 * 0.2;
            twin.on_gnss(&GnssFix {
                time_s: t,
                position: twin_core::geodesy::LatLon {
                    lat_deg: 60.0 + k as f64 * 2.7e-6,
                    lon_deg: 20.0,
                },
                sog_mps: Some(1.5),
                cog_rad: Some(0.0),
                heading_rad: None,
                yaw_rate_radps: None,
                hdop: None,
            })
            .unwrap();
        }
        twin
    }

    /// The threads give exactly what the vessel task computed itself before
    /// (the same function on the same copy), run on a thread of lower
    /// priority, and end when the forecaster is dropped.
    #[test]
    fn forecasts_on_the_threads_equal_the_inline_ones() {
        let twin = twin_with_fixes();
        let forecaster = Forecaster::start(2, FaultPathLoad::new()).unwrap();
        let (reply, answer) = oneshot::channel();
        let job = |reply| ForecastJob {
            twin: Box::new(twin.clone()),
            vessel: "otter-1".into(),
            horizon_s: 60.0,
            step_s: 1.0,
            replay: false,
            reply,
        };
        let computed_before = computed_total();
        forecaster.submit(job(reply)).map_err(|_| "submit").unwrap();
        let threaded = answer.blocking_recv().unwrap().expect("a prediction");
        // Counted (other tests' forecasts may be counted too meanwhile).
        assert!(computed_total() > computed_before);
        let (unused, _) = oneshot::channel();
        let inline = prediction_json(&job(unused)).unwrap();
        assert_eq!(threaded, inline);
        let msg: serde_json::Value = serde_json::from_slice(&threaded).unwrap();
        assert_eq!(msg["points"].as_array().unwrap().len(), 60);
        drop(forecaster);
    }

    /// The gauge says "saturated" only once events have been in flight
    /// without a break for longer than [`SATURATED_AFTER`], and never while
    /// none is.
    #[test]
    fn the_fault_path_is_saturated_only_after_routing_without_a_break() {
        let limit_us = SATURATED_AFTER.as_micros() as u64;
        let load = FaultPathLoad::new();
        assert!(
            !load.saturated_at(10 * limit_us),
            "waiting is never saturated"
        );
        load.routed();
        let since_us = load.inner.busy_since_us.load(Ordering::Relaxed);
        // A second event in flight does not restart the spell.
        load.routed();
        assert_eq!(load.inner.busy_since_us.load(Ordering::Relaxed), since_us);
        assert!(
            !load.saturated_at(since_us + limit_us / 2),
            "routing for a moment"
        );
        assert!(
            load.saturated_at(since_us + 2 * limit_us),
            "routing without a break"
        );
        // And on the clock: after a real wait of twice the limit.
        std::thread::sleep(SATURATED_AFTER * 2);
        assert!(load.saturated());
        load.handled();
        assert!(load.saturated(), "one event still in hand");
        load.clone().handled();
        assert!(!load.saturated(), "caught up (seen through a clone)");
        assert!(!load.saturated_at(since_us + 10 * limit_us));
        // More handled than routed (not reached) leaves the count at zero.
        load.handled();
        assert_eq!(load.in_flight(), 0);
        load.routed();
        assert_eq!(load.in_flight(), 1);
    }

    /// While the fault path is saturated a forecast waits, but at most
    /// [`MAX_YIELD`]: forecasts never stop altogether.
    #[test]
    fn forecasts_wait_while_the_fault_path_is_saturated_but_not_forever() {
        let load = FaultPathLoad::new();
        load.routed();
        std::thread::sleep(SATURATED_AFTER * 2);
        let forecaster = Forecaster::start(1, load.clone()).unwrap();
        let (reply, mut answer) = oneshot::channel();
        let submitted = Instant::now();
        forecaster
            .submit(ForecastJob {
                twin: Box::new(twin_with_fixes()),
                vessel: "otter-1".into(),
                horizon_s: 60.0,
                step_s: 1.0,
                replay: false,
                reply,
            })
            .map_err(|_| "submit")
            .unwrap();
        std::thread::sleep(MAX_YIELD / 5);
        assert!(
            matches!(answer.try_recv(), Err(oneshot::error::TryRecvError::Empty)),
            "computed while the fault path was saturated"
        );
        assert!(load.saturated());
        let json = answer.blocking_recv().unwrap();
        assert!(json.is_some(), "a prediction after the longest wait");
        assert!(
            submitted.elapsed() >= MAX_YIELD,
            "{:?}",
            submitted.elapsed()
        );
    }

    /// A twin that has seen no fix has nothing to forecast: `None`, no panic.
    #[test]
    fn a_twin_without_an_estimate_gives_no_forecast() {
        let (reply, _) = oneshot::channel();
        let job = ForecastJob {
            twin: Box::new(VesselTwin::new(TwinConfig::default()).unwrap()),
            vessel: "otter-1".into(),
            horizon_s: 60.0,
            step_s: 1.0,
            replay: false,
            reply,
        };
        assert_eq!(prediction_json(&job), None);
    }

    /// The scheduling policy of the calling thread, from
    /// `/proc/thread-self/stat` (field 41; the command name in parentheses
    /// may hold spaces).
    #[cfg(target_os = "linux")]
    fn own_policy() -> u32 {
        let stat = std::fs::read_to_string("/proc/thread-self/stat").unwrap();
        let after_name = &stat[stat.rfind(')').unwrap() + 2..];
        // Fields from the 3rd on; the policy is the 41st.
        after_name.split(' ').nth(41 - 3).unwrap().parse().unwrap()
    }

    /// The forecast threads run under `SCHED_IDLE` (5).
    #[cfg(target_os = "linux")]
    #[test]
    fn the_threads_run_under_sched_idle() {
        const SCHED_IDLE: u32 = 5;
        let policy = std::thread::spawn(|| {
            lower_priority();
            own_policy()
        })
        .join()
        .unwrap();
        assert_eq!(policy, SCHED_IDLE);
    }
}
