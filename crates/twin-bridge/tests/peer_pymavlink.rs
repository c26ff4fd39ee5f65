//! MAVLink from pymavlink (PyPI), the reference implementation of the
//! protocol: `tests/peers/mavlink_peer.py` writes an ArduPilot-like boat
//! (and a second vehicle on the same link) to a `.tlog` and sends the same
//! frames over UDP to the bridge. What the bridge publishes is what the
//! log reader makes of the `.tlog` file: the same fixes (the GNSS receiver's,
//! at the vehicle's clock, with the yaw rate pymavlink wrote into
//! `ATTITUDE`), the same thrusts and shaft speeds; the second vehicle's
//! telemetry is refused and counted.

mod common;

use std::process::Command;

use common::*;
use twin_wire::ActuatorCommand;
use twin_wire::assemble::{Assembled, AssemblerConfig, FixAssembler};
use twin_wire::messages::TimeSource;
use twin_wire::read::{LogFormat, LogReader, ReadOptions};

#[test]
fn a_pymavlink_boat_over_udp_is_its_tlog() {
    let python = std::env::var("PYTHON").unwrap_or_else(|_| "python3".to_owned());
    require_python_module(
        &python,
        "pymavlink",
        "python3 -m pip install -r requirements.txt",
    );
    let dir = std::env::temp_dir().join(format!("twin-bridge-mavlink-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let tlog = dir.join("boat.tlog");
    let port = free_udp_port();
    let bridge = start(&[&format!("mavlink:udp:127.0.0.1:{port}")]);
    bridge.wait_stats("the socket bound", |s| {
        s.sources.first().is_some_and(|s| s.connected)
    });
    let status = Command::new(&python)
        .arg(repo().join("tests/peers/mavlink_peer.py"))
        .arg("--tlog")
        .arg(&tlog)
        .arg("--udp")
        .arg(format!("127.0.0.1:{port}"))
        .status()
        .expect("python runs");
    assert!(status.success(), "mavlink_peer.py failed");

    // The oracle: the .tlog through the log reader and the assembler.
    let bytes = std::fs::read(&tlog).unwrap();
    let mut reader = LogReader::open(&bytes[..], ReadOptions::default()).unwrap();
    assert_eq!(reader.format(), LogFormat::MavlinkTlog);
    let mut assembler = FixAssembler::new(AssemblerConfig::default());
    let mut expected = Vec::new();
    for record in reader.by_ref().filter_map(Result::ok) {
        assembler.push(record, &mut expected);
    }
    assembler.finish(&mut expected);
    let log_stats = reader.stats().clone();
    let expected_fixes: Vec<_> = expected
        .iter()
        .filter_map(|a| match a {
            Assembled::Fix(f) => Some(*f),
            _ => None,
        })
        .collect();
    let expected_commands: Vec<ActuatorCommand> = expected
        .iter()
        .filter_map(|a| match a {
            Assembled::Propellers(p) => Some(ActuatorCommand::Speeds(*p)),
            Assembled::Thrust(t) => Some(ActuatorCommand::Thrust(*t)),
            Assembled::Fix(_) => None,
        })
        .collect();
    assert_eq!(expected_fixes.len(), 50, "one fix an epoch");
    // The yaw rate of the fixes is the heading's rate of change from the
    // gyro rates pymavlink wrote into ATTITUDE (roll 0.01, pitch -0.02,
    // yaw rate 0.1 rad/s, as f32): 0.1 cos(0.01) / cos(-0.02).
    let (roll, pitch, yaw_rate) = (f64::from(0.01f32), f64::from(-0.02f32), f64::from(0.1f32));
    let heading_rate = yaw_rate * roll.cos() / pitch.cos();
    // The first fix comes before the first ATTITUDE.
    for fix in &expected_fixes[1..] {
        let got = fix.yaw_rate_radps.expect("a yaw rate with every later fix");
        assert!((got - heading_rate).abs() < 1e-9, "{got} vs {heading_rate}");
    }
    assert!(expected_commands.len() >= 50);

    bridge.wait_until("every fix and command", |sink| {
        fixes(sink).len() == expected_fixes.len() && commands(sink).len() == expected_commands.len()
    });
    let sink = bridge.sink.clone();
    let stats = bridge.stop();
    // The contract writes times to the microsecond.
    for (got, want) in fixes(&sink).iter().zip(&expected_fixes) {
        assert!((got.value.time_s - want.time_s).abs() < 1e-6);
        assert_eq!(
            twin_core::sample::GnssFix {
                time_s: want.time_s,
                ..got.value
            },
            *want
        );
        assert_eq!(got.time_source, TimeSource::Source, "the vehicle's clock");
    }
    for (got, want) in commands(&sink).iter().zip(&expected_commands) {
        match (got.value, want) {
            (ActuatorCommand::Speeds(g), ActuatorCommand::Speeds(w)) => {
                assert!((g.time_s - w.time_s).abs() < 1e-6);
                assert!((g.port_radps - w.port_radps).abs() < 1e-9);
                assert!((g.starboard_radps - w.starboard_radps).abs() < 1e-9);
            }
            (ActuatorCommand::Thrust(g), ActuatorCommand::Thrust(w)) => {
                assert!((g.time_s - w.time_s).abs() < 1e-6);
                assert_eq!((g.port_n, g.starboard_n), (w.port_n, w.starboard_n));
            }
            (g, w) => panic!("{g:?} is not {w:?}"),
        }
    }
    // The first command is the servo outputs through the Otter's map; the
    // starboard motor is astern, and so is its ESC's shaft speed.
    let ActuatorCommand::Thrust(first) = expected_commands[0] else {
        panic!("{:?}", expected_commands[0])
    };
    assert!((first.port_n - 0.5 * 119.7).abs() < 1e-9);
    assert!((first.starboard_n + 0.25 * 66.7).abs() < 1e-9);
    let ActuatorCommand::Speeds(speeds) = expected_commands[1] else {
        panic!("{:?}", expected_commands[1])
    };
    assert!(speeds.port_radps > 0.0 && speeds.starboard_radps < 0.0);
    // The second vehicle: refused, counted, in the log and live alike.
    let source = &stats.sources[0];
    assert_eq!(source.rejected.get("other_system"), Some(&50), "{source:?}");
    assert_eq!(log_stats.rejected(twin_wire::RejectKind::OtherSystem), 50);
    assert_eq!(source.rejected.len(), 1, "{:?}", source.rejected);
    std::fs::remove_dir_all(&dir).ok();
}
