//! The subscriber's side of a measurement point: the window, and the
//! callback that attributes each received message (a fault, or on raw
//! Zenoh a fix) to its vessel and the fix it answers, counting deliveries,
//! repeats and latencies. Everything is allocated before the first message.

use std::sync::Arc;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicI64, Ordering};
use std::time::Instant;

use serde::Deserialize;
use twin_wire::time::parse_rfc3339;
use zenoh::sample::Sample;

use super::histogram::Histogram;
use super::load::{Path, vessel_index};

/// The window, in microseconds since the start; `i64::MAX` until set.
pub(crate) struct Window {
    pub(crate) start_us: AtomicI64,
    pub(crate) end_us: AtomicI64,
}

impl Window {
    pub(crate) fn new() -> Self {
        Self {
            start_us: AtomicI64::new(i64::MAX),
            end_us: AtomicI64::new(i64::MAX),
        }
    }

    pub(crate) fn contains(&self, t_us: i64) -> bool {
        t_us >= self.start_us.load(Ordering::Acquire) && t_us < self.end_us.load(Ordering::Acquire)
    }
}

#[derive(Debug, Clone, Copy)]
pub(crate) struct VesselRx {
    pub(crate) last_time_us: i64,
    pub(crate) delivered: u32,
}

pub(crate) struct RxState {
    pub(crate) vessels: Vec<VesselRx>,
    pub(crate) heard: usize,
    pub(crate) latency: Histogram,
    pub(crate) delivered: u64,
    pub(crate) received_in_window: u64,
    pub(crate) repeats: u64,
    pub(crate) unparsable: u64,
    pub(crate) unparsable_first: Option<String>,
    pub(crate) measured_bytes: u64,
    pub(crate) measured_count: u64,
    /// Publish to receive of the newest delivery, in the window or not, ns.
    pub(crate) newest_latency_ns: i64,
}

impl RxState {
    /// Counts a message that cannot be attributed, keeping the first for
    /// the report (the key and up to 160 bytes of its payload).
    pub(crate) fn count_unparsable(&mut self, why: &str, key: &str, payload: &[u8]) {
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
pub(crate) struct Receiver {
    path: Path,
    start: Instant,
    epoch_s: f64,
    window: Arc<Window>,
    /// After the grace period nothing more is counted.
    pub(crate) closed: AtomicBool,
    state: Mutex<RxState>,
}

/// The only field of a fault (or fix) payload the subscriber reads.
#[derive(Deserialize)]
struct Timed<'a> {
    time: &'a str,
}

impl Receiver {
    pub(crate) fn new(
        path: Path,
        n: usize,
        start: Instant,
        epoch_s: f64,
        window: Arc<Window>,
    ) -> Self {
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

    pub(crate) fn on_sample(&self, sample: &Sample) {
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

    pub(crate) fn lock(&self) -> std::sync::MutexGuard<'_, RxState> {
        // A panic while holding the lock cannot leave the counters
        // inconsistent beyond one message: keep counting.
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }
}
