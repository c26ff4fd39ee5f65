//! `twind --demo`: the daemon with an embedded Zenoh peer, replaying two
//! bundled trials through Zenoh while it prints the per-thruster estimates as
//! they converge. Needs nothing but this binary: the trials are compiled in.
//!
//! - `otter-sim`: a simulated Otter with a 25 % loss on its port propeller
//!   (`data/demo/otter-broken-port.jsonl`, made by `twin simulate`; see
//!   `data/demo/README.md`): GNSS, heading and measured shaft speeds, so the
//!   extended twin estimates each propeller's loss.
//! - `furuno-real`: a real motor vessel's wide starboard turn recorded on its
//!   NMEA 2000 bus (`tests/fixtures/real/furuno-130842-wide-turn.raw`,
//!   Apache-2.0, attribution beside it): GNSS only, so the twin runs the
//!   seed's method and says that thrust loss cannot be told from it.

use std::collections::HashMap;
use std::io::Cursor;
use std::time::{Duration, Instant};

use tokio_util::sync::CancellationToken;
use twin_replay::replay::{Rate, ReplayOptions, replay_reader};
use twin_wire::VesselId;
use twin_wire::outputs::FaultMessage;
use zenoh::Session;

use crate::settings::Settings;
use crate::{LatestStates, OutputTap};

/// The simulated trial, compiled in.
pub const OTTER_TRIAL: &[u8] = include_bytes!("../../../data/demo/otter-broken-port.jsonl");
/// The true port loss of the simulated trial.
pub const OTTER_TRUE_PORT_LOSS: f64 = 0.25;
/// The real log, compiled in.
pub const REAL_LOG: &[u8] =
    include_bytes!("../../../tests/fixtures/real/furuno-130842-wide-turn.raw");

/// How the demo runs.
#[derive(Debug, Clone, Copy)]
pub struct DemoOptions {
    /// Replay pace, times the recorded pace.
    pub rate: f64,
    /// Replay the trials over and over until stopped.
    pub looping: bool,
}

fn describe(f: &FaultMessage) -> String {
    let side = |t: &twin_wire::outputs::ThrusterMessage| match (t.loss, t.sigma) {
        (Some(l), Some(s)) => format!("{:5.1} % +- {:4.1} ({:?})", 100.0 * l, 100.0 * s, t.status),
        _ => "   n/a".to_string(),
    };
    match f.model {
        twin_wire::outputs::ModelName::Kinetic => format!(
            "port {}   starboard {}   port/starboard effectiveness {}   [extended twin]",
            side(&f.thrusters.port),
            side(&f.thrusters.starboard),
            f.effectiveness_ratio.map_or("n/a".to_string(), |r| format!(
                "{:.3} +- {:.3}",
                r.value, r.sigma
            ))
        ),
        twin_wire::outputs::ModelName::SeedMethod => format!(
            "no propeller data: thrust loss not observable from GNSS alone (seed method input faults a {:.2}, r {:.2})",
            f.seed_input_faults[0], f.seed_input_faults[1]
        ),
    }
}

/// Runs the demo on `session` until the trials end (or, looping, until
/// `shutdown`). Returns the last fault message of each vessel.
pub async fn run(
    settings: Settings,
    session: Session,
    options: DemoOptions,
    tap: OutputTap,
    latest: LatestStates,
    metrics: crate::metrics::Metrics,
    shutdown: CancellationToken,
) -> anyhow::Result<HashMap<String, FaultMessage>> {
    let stop_daemon = CancellationToken::new();
    let keys = settings.keys.clone();
    let daemon = tokio::spawn(crate::run(crate::RunConfig {
        tap,
        latest,
        metrics,
        ..crate::RunConfig::new(settings, session.clone(), stop_daemon.clone())
    }));

    // Print the estimates as they converge, once a second per vessel.
    let faults = session
        .declare_subscriber(format!("{}/*/twin/fault", keys.prefix()))
        .with(zenoh::handlers::FifoChannel::new(10_000))
        .await
        .map_err(|e| anyhow::anyhow!("cannot subscribe to the fault topic: {e}"))?;
    let last = std::sync::Arc::new(std::sync::Mutex::new(HashMap::<String, FaultMessage>::new()));
    let shared = last.clone();
    let printer = tokio::spawn(async move {
        let mut printed: HashMap<String, Instant> = HashMap::new();
        let started = Instant::now();
        while let Ok(sample) = faults.recv_async().await {
            let Ok(f) = serde_json::from_slice::<FaultMessage>(&sample.payload().to_bytes()) else {
                continue;
            };
            let due = printed
                .get(&f.vessel)
                .is_none_or(|t| t.elapsed() >= Duration::from_secs(1));
            if due {
                println!(
                    "{:>6.1} s  {:12} {}",
                    started.elapsed().as_secs_f64(),
                    f.vessel,
                    describe(&f)
                );
                printed.insert(f.vessel.clone(), Instant::now());
            }
            if let Ok(mut map) = shared.lock() {
                map.insert(f.vessel.clone(), f);
            }
        }
    });

    let replay = |vessel: &str, data: &'static [u8]| {
        let mut o = ReplayOptions::new(VesselId::new(vessel).expect("a plain vessel id"));
        o.keys = keys.clone();
        o.rate = Rate::factor(options.rate).unwrap_or(Rate::Max);
        o.loops = if options.looping { 0 } else { 1 };
        let session = session.clone();
        let name = vessel.to_string();
        async move { replay_reader(&session, &name, || Ok(Cursor::new(data)), &o, |_| {}).await }
    };
    println!(
        "twind demo: replaying a simulated Otter with a {:.0} % port-propeller loss (otter-sim) and a real \
         vessel's NMEA 2000 log (furuno-real) through Zenoh at {}x their recorded pace",
        100.0 * OTTER_TRUE_PORT_LOSS,
        options.rate
    );
    let both = async {
        tokio::join!(
            replay("otter-sim", OTTER_TRIAL),
            replay("furuno-real", REAL_LOG)
        )
    };
    let (a, b) = tokio::select! {
        r = both => r,
        _ = shutdown.cancelled() => (Ok(Default::default()), Ok(Default::default())),
    };
    for (name, result) in [("otter-sim", a), ("furuno-real", b)] {
        if let Err(e) = result {
            tracing::error!("replay of {name} failed: {e}");
        }
    }
    // Let the last messages through, then stop the daemon (it drains).
    tokio::time::sleep(Duration::from_millis(500)).await;
    stop_daemon.cancel();
    let summary = daemon.await??;
    // Give the printer the daemon's last words, then stop it.
    tokio::time::sleep(Duration::from_millis(200)).await;
    printer.abort();
    let last = last.lock().map(|m| m.clone()).unwrap_or_default();
    println!(
        "\ntwind demo: done ({} messages routed, {} refused by the daemon).",
        summary.routed,
        summary.refused.total_rejected()
    );
    // By name: the summary's map has no order, the printout does.
    let mut vessels: Vec<_> = summary.vessels.iter().collect();
    vessels.sort_by(|a, b| a.0.cmp(b.0));
    for (vessel, counters) in vessels {
        println!(
            "  {vessel}: accepted {:?}, rejected {:?}",
            counters.accepted(),
            counters.rejected
        );
    }
    if let Some(f) = last.get("otter-sim") {
        println!(
            "  otter-sim final: {} (true port loss {:.0} %, starboard healthy)",
            describe(f),
            100.0 * OTTER_TRUE_PORT_LOSS
        );
    }
    if let Some(f) = last.get("furuno-real") {
        println!("  furuno-real final: {}", describe(f));
    }
    Ok(last)
}
