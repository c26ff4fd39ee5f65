//! The `cold-start` subcommand: a whole fleet starting at once. A daemon
//! (`twind::run`, in this process, its own Zenoh session) hears nothing; then
//! every one of `N` vessels sends its shaft speeds and a GNSS fix once a
//! second (the fleet spread evenly over each second), and a subscriber of
//! `asv/*/twin/fault` notes when each vessel's first fault arrives. The
//! figure is the time from the first message sent to the first fault of the
//! last vessel: the fleet is served.
//!
//! Every point runs in a fresh child process (hidden subcommand
//! `cold-start-point`, one JSON line back), as `daemon` does. The daemon's
//! settings are the benchmark's (`load::bench_settings`) with the admission
//! burst raised to the fleet (`[vessels] admit_burst`: by default a daemon
//! admits 500 new vessels at once, then 50 a second, which would spread a
//! 10,000-vessel start over minutes by design). Each point waits at most
//! [`LIMIT`] for the fleet to be served.

use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::Context;
use serde::{Deserialize, Serialize};
use tokio_util::sync::CancellationToken;
use twin_wire::messages::{ActuatorCommand, encode_actuators, encode_gnss};
use zenoh::Wait;
use zenoh::key_expr::KeyExpr;
use zenoh::qos::CongestionControl;

use super::load::{
    FLEET_SPEED_MPS, daemon_runtime, free_port, open_session, vessel_id, vessel_index, zerr,
};
use super::motion::{Circle, Fleet};
use super::procstat;
use crate::rng::SplitMix64;

/// Longest a point waits for every vessel's first fault.
pub const LIMIT: Duration = Duration::from_secs(60);

/// The fleet sizes of the table.
pub const FLEETS: [usize; 3] = [1_000, 3_000, 10_000];

/// One point's figures.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ColdStart {
    /// Vessels.
    pub vessels: usize,
    /// Vessels with at least one fault received.
    pub served: usize,
    /// From the first message to the first fault of half the fleet, s.
    pub half_s: Option<f64>,
    /// ... of 90 % of it, s.
    pub ninety_s: Option<f64>,
    /// ... of every vessel, s (`None`: not within [`LIMIT`]).
    pub all_s: Option<f64>,
    /// Resident memory at the end, MiB.
    pub rss_mib: f64,
    /// CPU time of the process over the start, % of one core.
    pub cpu_pct: f64,
}

/// Runs one point in this process.
pub fn point(vessels: usize, vessel_liveliness: bool) -> anyhow::Result<ColdStart> {
    anyhow::ensure!((1..=99_999).contains(&vessels), "1 to 99,999 vessels");
    let rt = daemon_runtime()?;
    let port = free_port()?;
    let open = |listen: &[u16], connect: &[u16]| open_session(&rt, listen, connect);
    let daemon = open(&[port], &[])?;
    let generator = open(&[], &[port])?;
    let watcher = open(&[], &[port])?;
    let seen: Arc<Vec<AtomicBool>> =
        Arc::new((0..vessels).map(|_| AtomicBool::new(false)).collect());
    let served = Arc::new(AtomicUsize::new(0));
    let subscriber = {
        let (seen, served) = (seen.clone(), served.clone());
        watcher
            .declare_subscriber("asv/*/twin/fault")
            .callback(move |sample| {
                let vessel = sample.key_expr().as_str().split('/').nth(1).unwrap_or("");
                if let Some(v) = vessel_index(vessel)
                    && let Some(flag) = seen.get(v)
                    && !flag.swap(true, Ordering::Relaxed)
                {
                    served.fetch_add(1, Ordering::Relaxed);
                }
            })
            .wait()
            .map_err(zerr("subscribing to the faults"))?
    };
    let mut settings = super::load::bench_settings(vessel_liveliness, false)?;
    settings.vessels.admit_burst = settings.vessels.admit_burst.max(vessels);
    let cancel = CancellationToken::new();
    let task = rt.spawn(twind::run(twind::RunConfig::new(
        settings,
        daemon.clone(),
        cancel.clone(),
    )));
    let keys = declare_keys(&generator, vessels)?;
    rt.block_on(wait_subscribed(&generator))?;

    let ticks_before = procstat::process_ticks();
    let start = Instant::now();
    let stop = Arc::new(AtomicBool::new(false));
    let sent = Arc::new(AtomicU64::new(0));
    let publishing = {
        let (stop, sent, generator) = (stop.clone(), sent.clone(), generator.clone());
        std::thread::spawn(move || publish(&generator, &keys, start, &stop, &sent))
    };
    let mut marks: [Option<f64>; 3] = [None; 3];
    let targets = [vessels.div_ceil(2), (vessels * 9).div_ceil(10), vessels];
    while start.elapsed() < LIMIT && marks[2].is_none() {
        let n = served.load(Ordering::Relaxed);
        for (mark, target) in marks.iter_mut().zip(targets) {
            if mark.is_none() && n >= target {
                *mark = Some(start.elapsed().as_secs_f64());
            }
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let elapsed_s = start.elapsed().as_secs_f64();
    let ticks = procstat::process_ticks()
        .zip(ticks_before)
        .map_or(0, |(a, b)| a.saturating_sub(b));
    stop.store(true, Ordering::Relaxed);
    let _ = publishing.join();
    let rss_mib = procstat::rss_kib().unwrap_or(0) as f64 / 1024.0;
    cancel.cancel();
    rt.block_on(async {
        let _ = tokio::time::timeout(super::load::DRAIN_LIMIT, task).await;
        let _ = subscriber.undeclare().await;
        for s in [&generator, &watcher, &daemon] {
            let _ = tokio::time::timeout(super::load::CLOSE_LIMIT, s.close()).await;
        }
    });
    rt.shutdown_timeout(super::load::CLOSE_LIMIT);
    Ok(ColdStart {
        vessels,
        served: served.load(Ordering::Relaxed),
        half_s: marks[0],
        ninety_s: marks[1],
        all_s: marks[2],
        rss_mib,
        cpu_pct: 100.0 * ticks as f64 / procstat::TICKS_PER_S / elapsed_s,
    })
}

/// Each vessel's (actuators, gnss) keys, declared to the generator's
/// session (the vessels are separate programs: their keys' cost is theirs).
pub(crate) fn declare_keys(
    session: &zenoh::Session,
    vessels: usize,
) -> anyhow::Result<Vec<[KeyExpr<'static>; 2]>> {
    (0..vessels)
        .map(|v| {
            let id = vessel_id(v);
            let declare = |topic: &str| {
                session
                    .declare_keyexpr(format!("asv/{id}/{topic}"))
                    .wait()
                    .map_err(zerr("declaring a key"))
            };
            Ok([declare("actuators")?, declare("gnss")?])
        })
        .collect()
}

/// Waits until the daemon's input subscription is visible.
pub(crate) async fn wait_subscribed(session: &zenoh::Session) -> anyhow::Result<()> {
    let probe = session
        .declare_publisher(format!("asv/{}/gnss", vessel_id(0)))
        .await
        .map_err(zerr("declaring a probe"))?;
    super::load::wait_matching(&probe, Duration::from_secs(20)).await
}

/// Every vessel's shaft speeds and fix once a second, spread evenly over
/// the second, until `stop`.
fn publish(
    session: &zenoh::Session,
    keys: &[[KeyExpr<'static>; 2]],
    start: Instant,
    stop: &AtomicBool,
    sent: &AtomicU64,
) {
    let Ok(circle) = Circle::from_simulator(FLEET_SPEED_MPS) else {
        return;
    };
    let Ok(fleet) = Fleet::new(circle, keys.len()) else {
        return;
    };
    let epoch_s = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64());
    let mut rng = SplitMix64::new(7);
    let n = keys.len();
    for i in 0_u64.. {
        if stop.load(Ordering::Relaxed) {
            return;
        }
        let v = (i % n as u64) as usize;
        let due_s = i as f64 / n as f64;
        let wait = due_s - start.elapsed().as_secs_f64();
        if wait > 0.0 {
            std::thread::sleep(Duration::from_secs_f64(wait));
        }
        let time_s = epoch_s + start.elapsed().as_secs_f64();
        let shafts = fleet.shafts(time_s, &mut rng);
        let fix = fleet.fix(v, time_s, due_s, &mut rng);
        for (key, bytes) in [
            (
                &keys[v][0],
                encode_actuators(&ActuatorCommand::Speeds(shafts), false),
            ),
            (&keys[v][1], encode_gnss(&fix, false)),
        ] {
            if let Ok(bytes) = bytes
                && session
                    .put(key, bytes)
                    .congestion_control(CongestionControl::Block)
                    .wait()
                    .is_ok()
            {
                sent.fetch_add(1, Ordering::Relaxed);
            }
        }
    }
}

/// Runs every fleet size in its own child process and prints the table.
pub fn run(
    exe: &std::path::Path,
    fleets: &[usize],
    vessel_liveliness: bool,
) -> anyhow::Result<String> {
    let mut out = String::from(
        "| vessels | served | half served | 90 % served | all served | RSS | CPU |\n\
         |---|---|---|---|---|---|---|\n",
    );
    let s = |v: Option<f64>| v.map_or_else(|| "-".to_string(), |v| format!("{v:.2} s"));
    for &n in fleets {
        let mut command = Command::new(exe);
        command.args(["cold-start-point", "--vessels", &n.to_string()]);
        if !vessel_liveliness {
            command.arg("--no-vessel-liveliness");
        }
        let output = command
            .stdin(Stdio::null())
            .stderr(Stdio::inherit())
            .output()
            .context("running a cold-start point")?;
        anyhow::ensure!(output.status.success(), "the {n}-vessel point failed");
        let line = String::from_utf8_lossy(&output.stdout);
        let p: ColdStart = serde_json::from_str(line.lines().last().unwrap_or(""))
            .with_context(|| format!("the {n}-vessel point's answer: {line}"))?;
        let row = format!(
            "| {} | {} | {} | {} | {} | {:.0} MiB | {:.0} % |\n",
            crate::core::thousands(p.vessels as u64),
            crate::core::thousands(p.served as u64),
            s(p.half_s),
            s(p.ninety_s),
            p.all_s.map_or_else(
                || format!("not within {} s", LIMIT.as_secs()),
                |v| format!("{v:.2} s")
            ),
            p.rss_mib,
            p.cpu_pct
        );
        eprint!("{row}");
        out.push_str(&row);
    }
    out.push_str(&format!(
        "\n{} cores ({}), load before: {}\n",
        crate::machine::cores(),
        crate::machine::cpu_model(),
        crate::machine::load_average_text()
    ));
    Ok(out)
}
