//! NMEA 0183 on a serial line, through a pseudo-terminal pair made by
//! socat (Debian `socat`): the bridge opens one end as a serial port, the
//! test writes a boat's sentences into the other. Then the device
//! disappears (socat stops) and returns (socat again, same names): the
//! bridge counts the loss, reopens the port with its backoff, and what is
//! written after the return is published too, fix for fix.

mod common;

use std::io::Write;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::*;
use twin_bridge::bench::boat_sentences;

fn socat(dir: &std::path::Path) -> Child {
    let program = require_program("socat", "apt-get install socat");
    let child = Child::spawn(
        Command::new(program)
            .arg(format!(
                "pty,raw,echo=0,link={}",
                dir.join("bridge").display()
            ))
            .arg(format!(
                "pty,raw,echo=0,link={}",
                dir.join("boat").display()
            ))
            .stdout(Stdio::null())
            .stderr(Stdio::null()),
    )
    .expect("socat starts");
    let deadline = Instant::now() + PATIENCE;
    while !(dir.join("bridge").exists() && dir.join("boat").exists()) {
        assert!(Instant::now() < deadline, "socat made no pty pair");
        std::thread::sleep(Duration::from_millis(20));
    }
    child
}

fn write_sentences(dir: &std::path::Path, sentences: &[String]) {
    let mut boat = std::fs::OpenOptions::new()
        .write(true)
        .open(dir.join("boat"))
        .expect("the boat's end opens");
    for s in sentences {
        boat.write_all(s.as_bytes()).unwrap();
        boat.write_all(b"\r\n").unwrap();
    }
    boat.flush().unwrap();
}

#[test]
fn a_serial_port_that_disappears_and_returns() {
    let dir = std::env::temp_dir().join(format!("twin-bridge-serial-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let sentences = boat_sentences(40);
    let (first, second) = sentences.split_at(sentences.len() / 2);

    let peer = socat(&dir);
    let bridge = start(&[&format!(
        "nmea0183:serial:{},baud=4800",
        dir.join("bridge").display()
    )]);
    bridge.wait_stats("the port opened", |s| {
        s.sources.first().is_some_and(|s| s.connected)
    });
    write_sentences(&dir, first);
    // 20 epochs of RMC + GGA (the same fix twice): 20 fixes.
    bridge.wait_until("the first half's fixes", |sink| fixes(sink).len() == 20);

    drop(peer);
    bridge.wait_stats("the loss counted", |s| {
        s.sources
            .first()
            .is_some_and(|s| !s.connected && !s.disconnects.is_empty())
    });
    let _peer = socat(&dir);
    bridge.wait_stats("the port reopened", |s| {
        s.sources
            .first()
            .is_some_and(|s| s.connected && s.connects >= 2)
    });
    write_sentences(&dir, second);
    bridge.wait_until("the second half's fixes", |sink| fixes(sink).len() == 40);
    let sink = bridge.sink.clone();
    let stats = bridge.stop();

    // The fixes are what the log reader makes of the same text, all live.
    let expected = expected_fixes(&sentences.join("\r\n"));
    let got = fixes(&sink);
    assert_eq!(got.len(), expected.len());
    for (g, e) in got.iter().zip(&expected) {
        assert_eq!(g.value, *e);
        assert!(!g.replay);
        assert_eq!(g.time_source, twin_wire::messages::TimeSource::Source);
    }
    let source = &stats.sources[0];
    assert_eq!(source.published.gnss, 40);
    assert_eq!(source.published.actuators, 40, "RPM port + starboard pairs");
    assert!(source.rejected.is_empty(), "{:?}", source.rejected);
    std::fs::remove_dir_all(&dir).ok();
}
