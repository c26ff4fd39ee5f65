//! The `flood` subcommand: one real vessel's fix -> fault latency, and the
//! daemon's memory, while a burst of messages on new vessel ids arrives
//! (what a broken or hostile peer sends: by default 10,000 one-byte
//! payloads on `asv/flood-NNNNN/gnss`, as fast as Zenoh takes them).
//!
//! # How
//! twind runs in this process (`twind::run`, default settings but the live
//! diagnose off, as in `daemon`) on its own Zenoh session, listening on a
//! loopback port. Three more sessions connect to it: the real vessel's
//! generator (vessel `real-1`, shaft speeds and a GNSS fix at `--rate-hz`,
//! the fleet motion of `daemon`), the flooder, and a subscriber to
//! `asv/real-1/twin/fault` that takes each fault's receive instant. The
//! latency of a fix is the instant its fault arrived minus the instant the
//! generator stamped the fix (the fault echoes the fix's time; see
//! [`super::load`]).
//!
//! Phases, by the stamp of the real vessel's fixes:
//! 1. `quiet`: `--quiet-s` seconds with no flood;
//! 2. `flood`: from the first flood message until `--settle-s` after the
//!    last one was handed to Zenoh;
//! 3. `after`: `--quiet-s` seconds more.
//!
//! Per phase: the real vessel's fixes, how many of them had no fault back,
//! and p50 / p99 / max latency. Memory is the process's resident set
//! (`VmRSS`): before the burst, its peak during the flood phase (sampled
//! every 50 ms), and at the end. The process holds the daemon and the three
//! other sessions; before the burst it is the daemon's baseline with one
//! vessel. At the end the liveliness tokens under `asv/*/twin/alive` are
//! counted (a daemon that gives every id a twin leaves one per flood id
//! until `drop_after_silence_s`).
//!
//! One run, one process: start it afresh for each measurement
//! (`cargo run --release -p twin-bench -- flood`).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::Context;
use tokio_util::sync::CancellationToken;
use twin_wire::messages::{ActuatorCommand, encode_actuators, encode_gnss};
use twin_wire::time::parse_rfc3339;
use twin_wire::{KeySpace, VesselId};
use zenoh::Wait;
use zenoh::qos::CongestionControl;

use super::histogram::Histogram;
use super::load::{
    FLEET_SPEED_MPS, bench_settings, daemon_runtime, free_port, open_session, wait_matching, zerr,
};
use super::motion::{Circle, Fleet};
use super::procstat;
use crate::rng::SplitMix64;

/// The real vessel's id.
pub const REAL_VESSEL: &str = "real-1";

/// How to run `flood`.
#[derive(Debug, Clone)]
pub struct FloodOptions {
    /// New vessel ids in the burst, one message each.
    pub ids: usize,
    /// The payload of every flood message.
    pub payload: Vec<u8>,
    /// The real vessel's fixes per second.
    pub rate_hz: f64,
    /// Length of the quiet phases, s.
    pub quiet_s: f64,
    /// How long the flood phase lasts after the burst was sent, s.
    pub settle_s: f64,
}

impl Default for FloodOptions {
    fn default() -> Self {
        Self {
            ids: 10_000,
            payload: b"x".to_vec(),
            rate_hz: 10.0,
            quiet_s: 10.0,
            settle_s: 15.0,
        }
    }
}

/// The real vessel's latencies in one phase.
#[derive(Debug, Clone)]
pub struct Phase {
    /// `quiet`, `flood` or `after`.
    pub name: &'static str,
    /// Its length, s.
    pub length_s: f64,
    /// Fixes of the real vessel stamped in the phase.
    pub fixes: u64,
    /// Of those, how many had no fault back by the end of the run.
    pub lost: u64,
    /// Latency percentiles over the fixes that came back, ns.
    pub p50_ns: Option<u64>,
    /// 99th percentile, ns.
    pub p99_ns: Option<u64>,
    /// Largest, ns.
    pub max_ns: Option<u64>,
}

/// What `flood` measured.
#[derive(Debug, Clone)]
pub struct FloodReport {
    /// The options it ran with.
    pub options: FloodOptions,
    /// The three phases.
    pub phases: Vec<Phase>,
    /// How long putting the burst took, s.
    pub burst_s: f64,
    /// The last fix of the flood and after phases whose latency was over
    /// [`FloodReport::slow_threshold_ns`], s after the burst began (`None`:
    /// none was).
    pub slow_until_s: Option<f64>,
    /// Twice the quiet phase's p99, at least 5 ms.
    pub slow_threshold_ns: u64,
    /// Resident set before the burst, KiB.
    pub rss_before_kib: Option<u64>,
    /// Its peak during the flood phase, KiB.
    pub rss_peak_kib: Option<u64>,
    /// At the end, KiB.
    pub rss_end_kib: Option<u64>,
    /// Liveliness tokens under `asv/*/twin/alive` at the end.
    pub tokens_end: usize,
    /// Load average before and after.
    pub load: (String, String),
}

/// A fault received: the fix's stamp and the receive instant, both in
/// microseconds since the start.
#[derive(Debug, Clone, Copy)]
struct Arrival {
    sent_us: i64,
    received_us: i64,
}

/// Runs the measurement. The daemon, its sessions and its runtime are left
/// running: call it in a process that exits next.
#[allow(clippy::too_many_lines)] // The benchmark's phases in order, each timed where it runs.
pub fn run(opts: &FloodOptions) -> anyhow::Result<FloodReport> {
    anyhow::ensure!((1..=999_999).contains(&opts.ids), "1 to 999,999 ids");
    anyhow::ensure!(
        opts.rate_hz > 0.0 && opts.quiet_s > 0.0 && opts.settle_s >= 0.0,
        "rate and phases must be positive"
    );
    let load_before = crate::machine::load_average_text();
    let keys = KeySpace::new("asv")?;
    let settings = bench_settings(true, false)?;
    let rt = daemon_runtime()?;
    let port = free_port()?;
    let open = |listen: &[u16], connect: &[u16]| open_session(&rt, listen, connect);
    let daemon = open(&[port], &[])?;
    let vessel = open(&[], &[port])?;
    let flooder = open(&[], &[port])?;
    let watcher = open(&[], &[port])?;

    let start = Instant::now();
    let epoch_s = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .context("the system clock is before 1970")?
        .as_secs() as f64;
    let now_us = move || start.elapsed().as_micros() as i64;
    let cancel = CancellationToken::new();
    rt.spawn(twind::run(twind::RunConfig::new(
        settings,
        daemon.clone(),
        cancel.clone(),
    )));

    let id = VesselId::new(REAL_VESSEL)?;
    let arrivals: Arc<Mutex<Vec<Arrival>>> = Arc::new(Mutex::new(Vec::with_capacity(100_000)));
    let fault_key = watcher
        .declare_keyexpr(keys.twin_fault(&id))
        .wait()
        .map_err(zerr("declaring the fault key"))?;
    let _subscriber = {
        let arrivals = arrivals.clone();
        watcher
            .declare_subscriber(fault_key)
            .callback(move |sample| {
                let received_us = now_us();
                let bytes = sample.payload().to_bytes();
                let sent = serde_json::from_slice::<serde_json::Value>(&bytes)
                    .ok()
                    .and_then(|v| v["time"].as_str().and_then(|t| parse_rfc3339(t).ok()));
                if let Some(t) = sent
                    && let Ok(mut a) = arrivals.lock()
                {
                    a.push(Arrival {
                        sent_us: ((t - epoch_s) * 1e6).round() as i64,
                        received_us,
                    });
                }
            })
            .wait()
            .map_err(zerr("subscribing to the faults"))?
    };

    // The real vessel: its keys declared to its session, as a vessel's
    // publishers are.
    let gnss_key = vessel
        .declare_keyexpr(keys.gnss(&id))
        .wait()
        .map_err(zerr("declaring a key"))?;
    let actuators_key = vessel
        .declare_keyexpr(keys.actuators(&id))
        .wait()
        .map_err(zerr("declaring a key"))?;
    rt.block_on(async {
        let probe = vessel
            .declare_publisher(gnss_key.clone())
            .await
            .map_err(zerr("declaring the probe"))?;
        wait_matching(&probe, Duration::from_secs(20)).await?;
        probe.undeclare().await.map_err(zerr("undeclaring"))?;
        let probe = daemon
            .declare_publisher(keys.twin_fault(&id))
            .await
            .map_err(zerr("declaring the probe"))?;
        wait_matching(&probe, Duration::from_secs(20)).await?;
        probe.undeclare().await.map_err(zerr("undeclaring"))
    })?;
    let fleet = Fleet::new(Circle::from_simulator(FLEET_SPEED_MPS)?, 1)?;
    let stop = Arc::new(AtomicBool::new(false));
    let stamps: Arc<Mutex<Vec<i64>>> = Arc::new(Mutex::new(Vec::with_capacity(100_000)));
    let generator = {
        let stop = stop.clone();
        let stamps = stamps.clone();
        let period_us = (1e6 / opts.rate_hz) as i64;
        std::thread::Builder::new()
            .name("bench-gen-real".into())
            .spawn(move || {
                let mut rng = SplitMix64::new(0xf100d);
                let mut last_us = i64::MIN;
                let mut next_us = now_us();
                while !stop.load(Ordering::Relaxed) {
                    let wait = next_us - now_us();
                    if wait > 0 {
                        std::thread::sleep(Duration::from_micros(wait as u64));
                    }
                    next_us += period_us;
                    let a_us = now_us().max(last_us + 1);
                    let shafts = fleet.shafts(epoch_s + a_us as f64 * 1e-6, &mut rng);
                    if let Ok(bytes) = encode_actuators(&ActuatorCommand::Speeds(shafts), false) {
                        let _ = vessel
                            .put(&actuators_key, bytes)
                            .congestion_control(CongestionControl::Block)
                            .wait();
                    }
                    let g_us = now_us().max(a_us + 1);
                    last_us = g_us;
                    let fix = fleet.fix(
                        0,
                        epoch_s + g_us as f64 * 1e-6,
                        g_us as f64 * 1e-6,
                        &mut rng,
                    );
                    if let Ok(bytes) = encode_gnss(&fix, false) {
                        if let Ok(mut s) = stamps.lock() {
                            s.push(g_us);
                        }
                        let _ = vessel
                            .put(&gnss_key, bytes)
                            .congestion_control(CongestionControl::Block)
                            .wait();
                    }
                }
            })
            .context("starting the generator")?
    };

    // Warm-up: the vessel's first fault, then 3 s.
    let deadline = Instant::now() + Duration::from_secs(30);
    while arrivals.lock().map(|a| a.is_empty()).unwrap_or(true) {
        anyhow::ensure!(
            Instant::now() < deadline,
            "no fault from the daemon in 30 s"
        );
        anyhow::ensure!(!generator.is_finished(), "the generator stopped");
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_secs(3));

    let sleep_s = |s: f64| std::thread::sleep(Duration::from_secs_f64(s));
    let quiet0 = now_us();
    sleep_s(opts.quiet_s);
    let rss_before_kib = procstat::rss_kib();

    // The burst, on its own thread; the main thread samples the RSS.
    let flood0 = now_us();
    let burst = {
        let payload = opts.payload.clone();
        let n = opts.ids;
        std::thread::Builder::new()
            .name("bench-flood".into())
            .spawn(move || {
                let t0 = Instant::now();
                let mut errors = 0u64;
                for i in 0..n {
                    let put = flooder
                        .put(format!("asv/flood-{i:06}/gnss"), payload.clone())
                        .congestion_control(CongestionControl::Block)
                        .wait();
                    errors += u64::from(put.is_err());
                }
                (t0.elapsed().as_secs_f64(), errors)
            })
            .context("starting the flooder")?
    };
    let mut rss_peak_kib = rss_before_kib;
    let sample_rss = |peak: &mut Option<u64>| {
        if let Some(r) = procstat::rss_kib() {
            *peak = Some(peak.map_or(r, |p| p.max(r)));
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    while !burst.is_finished() {
        sample_rss(&mut rss_peak_kib);
    }
    let (burst_s, burst_errors) = burst
        .join()
        .map_err(|_| anyhow::anyhow!("the flooder panicked"))?;
    anyhow::ensure!(burst_errors == 0, "{burst_errors} flood messages not put");
    let settle_end = Instant::now() + Duration::from_secs_f64(opts.settle_s);
    while Instant::now() < settle_end {
        sample_rss(&mut rss_peak_kib);
    }
    let after0 = now_us();
    sleep_s(opts.quiet_s);
    let after1 = now_us();
    // The faults of the last fixes: a second's grace.
    sleep_s(1.0);
    stop.store(true, Ordering::Relaxed);
    let rss_end_kib = procstat::rss_kib();
    // A channel as large as any count: with Zenoh 1.10 the replies for the
    // tokens already known are handed over inside the call, and a full
    // channel there would wait for a reader that is still in the call.
    let tokens_end = rt
        .block_on(async {
            watcher
                .liveliness()
                .get("asv/*/twin/alive")
                .with(zenoh::handlers::FifoChannel::new(1 << 20))
                .await
        })
        .map_err(zerr("querying the tokens"))?
        .iter()
        .filter(|r| r.result().is_ok())
        .count();
    let _ = generator.join();

    let arrivals = arrivals.lock().map(|a| a.clone()).unwrap_or_default();
    let stamps = stamps.lock().map(|s| s.clone()).unwrap_or_default();
    let phase = |name: &'static str, from: i64, to: i64| -> Phase {
        let mut h = Histogram::new();
        let mut came = std::collections::HashSet::new();
        for a in arrivals.iter().filter(|a| (from..to).contains(&a.sent_us)) {
            // A fault repeated for the same fix (a stale state) counts once.
            if came.insert(a.sent_us) {
                h.record((a.received_us - a.sent_us).max(0) as u64 * 1000);
            }
        }
        let sent = stamps.iter().filter(|t| (from..to).contains(*t)).count() as u64;
        Phase {
            name,
            length_s: (to - from) as f64 * 1e-6,
            fixes: sent,
            lost: sent.saturating_sub(came.len() as u64),
            p50_ns: h.quantile(0.50),
            p99_ns: h.quantile(0.99),
            max_ns: h.max(),
        }
    };
    let quiet = phase("quiet", quiet0, flood0);
    let slow_threshold_ns = quiet.p99_ns.map_or(5_000_000, |p| (2 * p).max(5_000_000));
    let slow_until_s = arrivals
        .iter()
        .filter(|a| {
            (flood0..after1).contains(&a.sent_us)
                && (a.received_us - a.sent_us) * 1000 > slow_threshold_ns as i64
        })
        .map(|a| (a.sent_us - flood0) as f64 * 1e-6)
        .fold(None, |m: Option<f64>, t| Some(m.map_or(t, |m| m.max(t))));
    let phases = vec![
        quiet,
        phase("flood", flood0, after0),
        phase("after", after0, after1),
    ];
    Ok(FloodReport {
        options: opts.clone(),
        phases,
        burst_s,
        slow_until_s,
        slow_threshold_ns,
        rss_before_kib,
        rss_peak_kib,
        rss_end_kib,
        tokens_end,
        load: (load_before, crate::machine::load_average_text()),
    })
}

fn ms(ns: Option<u64>) -> String {
    ns.map_or("-".into(), |v| format!("{:.2}", v as f64 / 1e6))
}

fn mb(kib: Option<u64>) -> String {
    kib.map_or("not measured".into(), |v| {
        format!("{:.0} MB", v as f64 / 1024.0)
    })
}

impl FloodReport {
    /// The report as a Markdown table and notes.
    pub fn table(&self) -> String {
        let o = &self.options;
        let mut s = format!(
            "twin-bench flood: {} messages of {} B on new ids (asv/flood-NNNNNN/gnss) in a burst; \
             vessel {REAL_VESSEL} at {} Hz; {} cores, load {} -> {}\n\n",
            o.ids,
            o.payload.len(),
            o.rate_hz,
            crate::machine::cores(),
            self.load.0,
            self.load.1
        );
        s.push_str("| phase | length | fixes | no fault | p50 ms | p99 ms | max ms |\n");
        s.push_str("|---|---:|---:|---:|---:|---:|---:|\n");
        for p in &self.phases {
            s.push_str(&format!(
                "| {} | {:.1} s | {} | {} | {} | {} | {} |\n",
                p.name,
                p.length_s,
                p.fixes,
                p.lost,
                ms(p.p50_ns),
                ms(p.p99_ns),
                ms(p.max_ns)
            ));
        }
        s.push_str(&format!(
            "\nburst put in {:.2} s; the real vessel's latency last above {:.1} ms {}\n",
            self.burst_s,
            self.slow_threshold_ns as f64 / 1e6,
            match self.slow_until_s {
                Some(t) => format!("{t:.1} s after the burst began"),
                None => "never, from the burst to the end of the after phase".into(),
            }
        ));
        s.push_str(&format!(
            "resident memory: {} before the burst, {} at its peak, {} at the end\n",
            mb(self.rss_before_kib),
            mb(self.rss_peak_kib),
            mb(self.rss_end_kib)
        ));
        s.push_str(&format!(
            "liveliness tokens under asv/*/twin/alive at the end: {}\n",
            self.tokens_end
        ));
        s
    }
}
