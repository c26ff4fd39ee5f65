//! The load generator of a measurement point: threads that put each
//! vessel's shaft speeds and GNSS fix through one Zenoh session, paced
//! evenly over each period or flat out, stamping every message just before
//! it is encoded (see the `load` module doc for why and how).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use twin_wire::messages::{ActuatorCommand, encode_actuators, encode_gnss};
use zenoh::Wait;
use zenoh::key_expr::KeyExpr;
use zenoh::qos::CongestionControl;

use super::motion::Fleet;
use super::receiver::Window;
use crate::rng::SplitMix64;

/// What the generator shares with the main thread.
#[derive(Default)]
pub(crate) struct GenShared {
    pub(crate) stop: AtomicBool,
    pub(crate) fixes_in_window: AtomicU64,
    pub(crate) actuators_in_window: AtomicU64,
    pub(crate) max_lag_us: AtomicU64,
    /// The lag of the newest message, us (0 when it was not late).
    pub(crate) lag_us: AtomicU64,
    pub(crate) gnss_bytes: AtomicU64,
    pub(crate) actuators_bytes: AtomicU64,
    pub(crate) sent: AtomicU64,
    pub(crate) errors: AtomicU64,
}

/// One of the generator's threads: it sends the messages of a contiguous
/// share of the fleet.
pub(crate) struct Generator {
    pub(crate) session: zenoh::Session,
    /// Per vessel of this share: the shaft-speed key, the GNSS key.
    pub(crate) keys: Vec<[KeyExpr<'static>; 2]>,
    /// The fleet index of the share's first vessel.
    pub(crate) first_vessel: usize,
    /// Seeds this thread's GNSS noise.
    pub(crate) seed: u64,
    pub(crate) fleet: Arc<Fleet>,
    pub(crate) rate_hz: Option<f64>,
    pub(crate) start: Instant,
    pub(crate) epoch_s: f64,
    pub(crate) window: Arc<Window>,
    pub(crate) shared: Arc<GenShared>,
}

impl Generator {
    fn now_us(&self) -> i64 {
        self.start.elapsed().as_micros() as i64
    }

    /// A stamp for a message of a vessel whose last one on this topic was
    /// stamped `last`: now, or one microsecond after `last` if the clock has
    /// not moved (times must increase per vessel and topic).
    fn stamp(&self, last: &mut i64) -> i64 {
        let t = self.now_us().max(*last + 1);
        *last = t;
        t
    }

    /// Puts reliably, blocking while Zenoh's queues are full (as
    /// `twin-replay`'s publishers, `CongestionControl::Block`).
    fn put(&self, key: &KeyExpr<'static>, bytes: Vec<u8>) -> zenoh::Result<()> {
        self.session
            .put(key, bytes)
            .congestion_control(CongestionControl::Block)
            .wait()
    }

    /// Puts one encoded message stamped at `stamp_us` and counts it: its
    /// bytes, whether its stamp lies in the window, or an error (encoding
    /// or putting).
    fn put_counted<E>(
        &self,
        key: &KeyExpr<'static>,
        encoded: Result<Vec<u8>, E>,
        stamp_us: i64,
        bytes_sent: &AtomicU64,
        sent_in_window: &AtomicU64,
    ) {
        let s = &self.shared;
        let Ok(bytes) = encoded else {
            s.errors.fetch_add(1, Ordering::Relaxed);
            return;
        };
        bytes_sent.fetch_add(bytes.len() as u64, Ordering::Relaxed);
        if self.put(key, bytes).is_err() {
            s.errors.fetch_add(1, Ordering::Relaxed);
        }
        if self.window.contains(stamp_us) {
            sent_in_window.fetch_add(1, Ordering::Relaxed);
        }
    }

    pub(crate) fn run(self) {
        let n = self.keys.len();
        let mut rng = SplitMix64::new(self.seed);
        let mut last = vec![[i64::MIN + 1; 2]; n];
        let begin_us = self.now_us();
        let per_s = self.rate_hz.map(|r| r * n as f64);
        let s = &self.shared;
        let mut i: u64 = 0;
        while !s.stop.load(Ordering::Relaxed) {
            let v = (i % n as u64) as usize;
            if let Some(per_s) = per_s {
                let due_us = begin_us + (i as f64 * 1e6 / per_s) as i64;
                let now = self.now_us();
                if due_us > now {
                    s.lag_us.store(0, Ordering::Relaxed);
                    std::thread::sleep(Duration::from_micros((due_us - now) as u64));
                } else {
                    let lag = (now - due_us) as u64;
                    s.lag_us.store(lag, Ordering::Relaxed);
                    s.max_lag_us.fetch_max(lag, Ordering::Relaxed);
                }
            }
            // Shaft speeds first, then the fix, each stamped just before
            // it is encoded. The load goes on after the window (through the
            // grace period) until the main thread says stop: the window's
            // last fixes are delivered under the same load as the others.
            let a_us = self.stamp(&mut last[v][0]);
            let t = self.epoch_s + a_us as f64 * 1e-6;
            let shafts = self.fleet.shafts(t, &mut rng);
            self.put_counted(
                &self.keys[v][0],
                encode_actuators(&ActuatorCommand::Speeds(shafts), false),
                a_us,
                &s.actuators_bytes,
                &s.actuators_in_window,
            );
            let g_us = self.stamp(&mut last[v][1]);
            let t = self.epoch_s + g_us as f64 * 1e-6;
            let fix = self
                .fleet
                .fix(self.first_vessel + v, t, g_us as f64 * 1e-6, &mut rng);
            self.put_counted(
                &self.keys[v][1],
                encode_gnss(&fix, false),
                g_us,
                &s.gnss_bytes,
                &s.fixes_in_window,
            );
            s.sent.fetch_add(1, Ordering::Relaxed);
            i += 1;
        }
    }
}
