//! The daemon's log under a flood, from the outside in (item 4): whatever
//! the number of misbehaving vessels, the refusal warnings of a minute stay
//! within one process-wide budget, and a calibration save that keeps
//! failing is logged once a minute and counted on the daemon's statistics.
//!
//! Its own test binary: it installs a process-wide log subscriber that
//! captures every line.

use std::io::Write;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use twin_tests::daemon::{Rig, rig};
use twin_tests::wire::{messages, nth_fix, receive_until, simulate, stamped, time_of};
use twin_wire::outputs::DaemonStatsMessage;
use twind::settings::Settings;
use twind::stats::GLOBAL_WARNINGS_PER_MINUTE;
use zenoh::qos::CongestionControl;

/// Every log line written, plain text.
#[derive(Clone, Default)]
struct Captured(Arc<Mutex<Vec<u8>>>);

impl Write for Captured {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Captured {
    fn lines(&self) -> Vec<String> {
        String::from_utf8_lossy(&self.0.lock().unwrap())
            .lines()
            .map(str::to_string)
            .collect()
    }
}

async fn put(rig: &Rig, key: String, payload: Vec<u8>) {
    rig.input
        .put(key, payload)
        .congestion_control(CongestionControl::Block)
        .await
        .unwrap();
}

/// 1,000 garbage first messages on new ids, then 200 admitted vessels
/// each sending a duplicate fix, with a calibration directory that cannot
/// be made (a file stands in its way) and saves due every 50 ms: at most
/// [`GLOBAL_WARNINGS_PER_MINUTE`] refusal warnings, one save error and one
/// failed restore are written, while the counts stay exact.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_log_stays_short_whatever_the_flood() {
    let captured = Captured::default();
    let writer = captured.clone();
    tracing::subscriber::set_global_default(
        tracing_subscriber::fmt()
            .with_ansi(false)
            .with_max_level(tracing::Level::INFO)
            .with_writer(move || writer.clone())
            .finish(),
    )
    .unwrap();
    let blocker = std::env::temp_dir().join(format!("twin-logs-blocker-{}", std::process::id()));
    std::fs::write(&blocker, "not a directory").unwrap();
    let mut settings = Settings::from_toml(
        "[daemon]\nid = \"logs\"\n[vessels]\nadmit_burst = 1000\n\
         [publish]\nstats_interval_s = 0.2\n[persistence]\nsave_interval_s = 0.05\n\
         [diagnose]\nenabled = false\n",
    )
    .unwrap();
    settings.persistence.dir = Some(blocker.join("calibrations"));
    let rig = rig(settings).await;
    let stats_sub = rig
        .watch("asv/@twind/*/stats", "asv/@twind/logs/stats")
        .await;
    let probe = rig.input.declare_publisher("asv/probe/gnss").await.unwrap();
    twin_tests::daemon::wait_matching(&probe).await;

    for i in 0..1000 {
        put(&rig, format!("asv/junk-{i}/gnss"), b"x".to_vec()).await;
    }
    let msgs = messages(&simulate("s-manoeuvre_new-new", 0.0, 81));
    let fix = &msgs[nth_fix(&msgs, 0)].1;
    let t = time_of(fix);
    for i in 0..200 {
        let f = stamped(fix, t + i as f64);
        put(&rig, format!("asv/dup-{i}/gnss"), f.clone()).await;
        put(&rig, format!("asv/dup-{i}/gnss"), f).await;
    }
    let got = receive_until(&stats_sub, Duration::from_secs(30), |s| {
        serde_json::from_slice::<DaemonStatsMessage>(&s.payload().to_bytes())
            .is_ok_and(|m| m.received >= 1400 && m.save_failures >= 400)
    })
    .await;
    let summary = rig.stop().await;
    let _ = std::fs::remove_file(&blocker);

    let last: DaemonStatsMessage =
        serde_json::from_slice(&got.last().expect("statistics").payload().to_bytes()).unwrap();
    let lines = captured.lines();
    let warnings = lines
        .iter()
        .filter(|l| l.contains("WARN") && l.contains("rejected"))
        .count();
    let save_errors = lines
        .iter()
        .filter(|l| l.contains("ERROR") && l.contains("calibration not saved"))
        .count();
    let restore_warnings = lines
        .iter()
        .filter(|l| l.contains("calibration not restored"))
        .count();
    println!(
        "{} lines: {warnings} refusal warnings, {save_errors} save errors; {} saves failed",
        lines.len(),
        last.save_failures
    );
    // The counts are exact ...
    assert_eq!(summary.refused.rejected.get("bad_json"), Some(&1000));
    assert_eq!(summary.vessels.len(), 200);
    assert!(
        summary
            .vessels
            .values()
            .all(|c| c.rejected.get("duplicate") == Some(&1))
    );
    assert!(last.save_failures >= 400, "{}", last.save_failures);
    // ... the log is not: the 1,200 misbehaving senders write no more than
    // the budget of a minute, 30 lines (docs/deploy.md).
    assert_eq!(GLOBAL_WARNINGS_PER_MINUTE, 30);
    assert!(warnings <= 30, "{warnings} refusal warnings");
    assert_eq!(save_errors, 1);
    assert_eq!(restore_warnings, 1);
}
