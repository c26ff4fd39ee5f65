//! Forecasts off the fault path.
//!
//! A vessel's 60 s forecast costs a few hundred microseconds (the extended
//! twin's state and covariance through sixty 1 s steps, then sixty points of
//! JSON), against a few microseconds for the estimator step that produces a
//! fault. Computed in the vessel's task, on the tokio workers, each forecast
//! held up every other vessel's faults behind it: at 1,000 vessels they were
//! about a third of the workers' time (`twin-bench daemon`, CPU profile in
//! `docs/daemon-performance.md`).
//!
//! Here they run on their own threads (`[publish] forecast_threads`), whose
//! scheduling priority is lowered (Linux nice 10), so that when the machine
//! is busy the kernel gives the estimates and the faults the CPU first. A
//! vessel task hands over a copy of its twin (plain data, a few kilobytes)
//! and gets back the prediction's JSON; it keeps at most one forecast in
//! flight, and when the next is due before that one is out it asks again as
//! soon as it is (from its newest estimate). So under load forecasts come
//! less often, never queue up, and never delay a fault; on an idle machine
//! they come at `prediction_interval_s` as before.

use std::sync::mpsc;
use std::sync::{Arc, Mutex};

use tokio::sync::oneshot;
use twin_core::twin::VesselTwin;
use twin_wire::outputs::PredictionMessage;

/// The forecast threads' nice value on Linux (0 is the default, 19 the
/// lowest priority): under contention a nice-10 thread gets about a tenth
/// of the CPU share of a nice-0 one.
pub const FORECAST_NICE: i32 = 10;

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
    /// Starts `threads` forecast threads (at least one).
    pub fn start(threads: usize) -> std::io::Result<Self> {
        let (jobs, queue) = mpsc::channel::<ForecastJob>();
        let queue = Arc::new(Mutex::new(queue));
        for i in 0..threads.max(1) {
            let queue = queue.clone();
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
                        let json = prediction_json(&job);
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
    match serde_json::to_vec(&msg) {
        Ok(bytes) => Some(bytes),
        Err(e) => {
            tracing::error!("cannot encode a prediction: {e}");
            None
        }
    }
}

/// Lowers the calling thread's scheduling priority to the nice value
/// [`FORECAST_NICE`] (Linux: the nice value is per thread).
#[cfg(target_os = "linux")]
fn lower_priority() {
    use thread_priority::{ThreadPriority, ThreadPriorityValue, set_current_thread_priority};
    // thread-priority maps its 0..=99 onto the nice values 19..=-20 of a
    // normally scheduled thread, as (39 (1 - p / 99)) - 20 rounded down:
    // 22 is nice 10 (the test below reads it back).
    const CROSSPLATFORM_FOR_NICE_10: u8 = 22;
    let result = ThreadPriorityValue::try_from(CROSSPLATFORM_FOR_NICE_10)
        .map_err(|e| e.to_string())
        .and_then(|p| {
            set_current_thread_priority(ThreadPriority::Crossplatform(p)).map_err(|e| e.to_string())
        });
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
        let forecaster = Forecaster::start(2).unwrap();
        let (reply, answer) = oneshot::channel();
        let job = |reply| ForecastJob {
            twin: Box::new(twin.clone()),
            vessel: "otter-1".into(),
            horizon_s: 60.0,
            step_s: 1.0,
            replay: false,
            reply,
        };
        forecaster.submit(job(reply)).map_err(|_| "submit").unwrap();
        let threaded = answer.blocking_recv().unwrap().expect("a prediction");
        let (unused, _) = oneshot::channel();
        let inline = prediction_json(&job(unused)).unwrap();
        assert_eq!(threaded, inline);
        let msg: serde_json::Value = serde_json::from_slice(&threaded).unwrap();
        assert_eq!(msg["points"].as_array().unwrap().len(), 60);
        drop(forecaster);
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

    /// The nice value of the calling thread, from `/proc/thread-self/stat`
    /// (field 19; the command name in parentheses may hold spaces).
    #[cfg(target_os = "linux")]
    fn own_nice() -> i32 {
        let stat = std::fs::read_to_string("/proc/thread-self/stat").unwrap();
        let after_name = &stat[stat.rfind(')').unwrap() + 2..];
        // Fields from the 3rd on; nice is the 19th.
        after_name.split(' ').nth(19 - 3).unwrap().parse().unwrap()
    }

    /// The forecast threads run at nice 10 (from a caller at nice 10 or
    /// less: raising a priority back needs a privilege).
    #[cfg(target_os = "linux")]
    #[test]
    fn the_threads_run_at_nice_10() {
        let own = own_nice();
        let nice = std::thread::spawn(|| {
            lower_priority();
            own_nice()
        })
        .join()
        .unwrap();
        println!("caller nice {own}, forecast thread nice {nice}");
        if own <= FORECAST_NICE {
            assert_eq!(nice, FORECAST_NICE);
        } else {
            assert_eq!(nice, own, "a nicer caller is left as it is");
        }
    }
}
