//! gpsd as the source, the way a Raspberry Pi on a boat runs it: gpsfake
//! (Debian `gpsd-clients`, with Debian's `gpsd`) replays an NMEA 0183 log
//! into a real gpsd, the bridge asks it for `?WATCH={"json":true}` on its
//! TCP port and publishes its TPV reports as fixes. Then gpsd restarts:
//! the bridge counts the loss, reconnects and carries on.

mod common;

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::*;
use twin_bridge::bench::boat_sentences;
use twin_wire::messages::TimeSource;

/// A gpsfake (and its gpsd) replaying `log` once on `port`.
fn gpsfake(log: &std::path::Path, port: u16) -> Child {
    let program = require_program("gpsfake", "apt-get install gpsd gpsd-clients");
    require_program("gpsd", "apt-get install gpsd");
    let child = Child::spawn(
        Command::new(program)
            .args(["-1", "-q", "-c", "0.05", "-P", &port.to_string()])
            .arg(log)
            // gpsfake is Debian's Python script, run with Debian's python3.
            .env("PATH", "/usr/sbin:/usr/bin:/sbin:/bin")
            .stdout(Stdio::null())
            .stderr(Stdio::null()),
    )
    .expect("gpsfake starts");
    let deadline = Instant::now() + PATIENCE;
    while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
        assert!(Instant::now() < deadline, "gpsd never listened on {port}");
        std::thread::sleep(Duration::from_millis(50));
    }
    child
}

fn nmea_log(dir: &std::path::Path, name: &str, sentences: &[String]) -> std::path::PathBuf {
    let path = dir.join(name);
    let text: String = sentences
        .iter()
        .filter(|s| !s.contains("RPM"))
        .map(|s| format!("{s}\r\n"))
        .collect();
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn gpsd_reports_become_fixes_and_a_restart_is_survived() {
    let dir = std::env::temp_dir().join(format!("twin-bridge-gpsd-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let sentences = boat_sentences(40);
    let (first, second) = sentences.split_at(sentences.len() / 2);
    let expected = expected_fixes(&sentences.join("\r\n"));
    let port = free_tcp_port();

    let gpsd = gpsfake(&nmea_log(&dir, "first.nmea", first), port);
    let bridge = start(&[&format!("gpsd:tcp:127.0.0.1:{port}")]);
    bridge.wait_until("fixes from gpsd", |sink| fixes(sink).len() >= 15);
    drop(gpsd);
    bridge.wait_stats("the restart noticed", |s| {
        s.sources.first().is_some_and(|s| !s.disconnects.is_empty())
    });
    let before = fixes(&bridge.sink).len();
    let _gpsd = gpsfake(&nmea_log(&dir, "second.nmea", second), port);
    bridge.wait_until("fixes after the restart", |sink| {
        fixes(sink)
            .last()
            .is_some_and(|f| f.value.time_s > expected[35].time_s)
    });
    let sink = bridge.sink.clone();
    let stats = bridge.stop();

    let got = fixes(&sink);
    assert!(got.len() > before);
    // Each fix is one of the log's, at its GNSS time, position within
    // gpsd's 1e-9 degree, course and speed from RMC/VTG.
    for g in &got {
        let e = expected
            .iter()
            .find(|e| (e.time_s - g.value.time_s).abs() < 1e-6)
            .unwrap_or_else(|| panic!("no fix of the log at {}", g.value.time_s));
        assert!((e.position.lat_deg - g.value.position.lat_deg).abs() < 1e-7);
        assert!((e.position.lon_deg - g.value.position.lon_deg).abs() < 1e-7);
        assert!((e.sog_mps.unwrap() - g.value.sog_mps.unwrap()).abs() < 0.01);
        assert_eq!(g.time_source, TimeSource::Source);
        assert!(!g.replay);
    }
    let source = &stats.sources[0];
    assert!(source.connects >= 2, "{source:?}");
    // gpsd reports its first epoch twice (a 2D, then a 3D TPV at the same
    // time): the repeat is not a new fix.
    let positions = source.records.get("position").copied().unwrap_or(0) as usize;
    assert!(
        positions >= got.len() && positions <= got.len() + 2,
        "{source:?}"
    );
    // gpsd's first heading comes before any time: refused, counted.
    assert!(
        source.rejected.keys().all(|r| r == "no_time")
            && source.rejected.values().sum::<u64>() <= 2,
        "{:?}",
        source.rejected
    );
    std::fs::remove_dir_all(&dir).ok();
}
