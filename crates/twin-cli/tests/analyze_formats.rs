//! `twin analyze` on the formats a boat's own equipment logs: a MAVLink
//! telemetry log (`.tlog`, as a ground station or the bridge's autopilot
//! link records it) and NMEA 2000 as candump, Yacht Devices RAW and
//! Actisense N2K ASCII. The format is recognised by content; the `.tlog`
//! of the demo trial names the damaged propeller as the demo's own log
//! does; the raw layouts of a real log give the fixes of the original.

use std::path::PathBuf;
use std::process::Command;

use serde_json::Value;
use twin_cli::demo::{LOG, PORT_LOSS, workspace_root};
use twin_core::sample::RADPS_PER_RPM;
use twin_wire::measurement::Measurement;
use twin_wire::read::fast_packet::is_fast;
use twin_wire::read::mavlink::dialect::{self, MavMessage};
use twin_wire::read::n2k::parse_message;
use twin_wire::read::{LogReader, RawFormat, ReadOptions};
use twin_wire::write::mavlink::{frame_v2, tlog_record};
use twin_wire::write::n2k_raw::message_lines;

fn analyze(path: &std::path::Path) -> Value {
    let out = Command::new(env!("CARGO_BIN_EXE_twin"))
        .arg("analyze")
        .arg(path)
        .arg("--json")
        .current_dir(workspace_root())
        .output()
        .expect("the binary runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

fn scratch(name: &str, bytes: &[u8]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("twin-analyze-formats-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

/// The demo trial as an autopilot's telemetry log: each fix a GPS_RAW_INT
/// (GNSS time, heading from a dual-antenna `yaw`), each pair of shaft
/// speeds an ESC_TELEMETRY_1_TO_4 (ESC 1 port, ESC 3 starboard), stamped as
/// the ground station received them.
fn demo_as_tlog() -> Vec<u8> {
    let text = std::fs::read(workspace_root().join(LOG)).unwrap();
    let reader = LogReader::open(&text[..], ReadOptions::default()).unwrap();
    let mut tlog = Vec::new();
    for (i, record) in reader.filter_map(Result::ok).enumerate() {
        let (time_s, message) = match record.measurement {
            Measurement::GnssFix(f) => {
                let cdeg = |rad: f64| ((rad.to_degrees() * 100.0).round() as u16) % 36_000;
                let heading = f.heading_rad.map_or(0, |h| cdeg(h).max(1));
                (
                    f.time_s,
                    MavMessage::GPS_RAW_INT(dialect::GPS_RAW_INT_DATA {
                        time_usec: (f.time_s * 1e6).round() as u64,
                        lat: (f.position.lat_deg * 1e7).round() as i32,
                        lon: (f.position.lon_deg * 1e7).round() as i32,
                        eph: f.hdop.map_or(u16::MAX, |h| (h * 100.0).round() as u16),
                        vel: f.sog_mps.map_or(u16::MAX, |v| (v * 100.0).round() as u16),
                        cog: f.cog_rad.map_or(u16::MAX, cdeg),
                        fix_type: dialect::GpsFixType::GPS_FIX_TYPE_3D_FIX,
                        yaw: heading,
                        ..dialect::GPS_RAW_INT_DATA::default()
                    }),
                )
            }
            Measurement::Propellers(p) => {
                let rpm = |radps: f64| (radps / RADPS_PER_RPM).round().clamp(0.0, 65_000.0) as u16;
                (
                    p.time_s,
                    MavMessage::ESC_TELEMETRY_1_TO_4(dialect::ESC_TELEMETRY_1_TO_4_DATA {
                        rpm: [rpm(p.port_radps), 0, rpm(p.starboard_radps), 0],
                        ..dialect::ESC_TELEMETRY_1_TO_4_DATA::default()
                    }),
                )
            }
            _ => continue,
        };
        tlog.extend(tlog_record(time_s, &frame_v2(1, 1, i as u8, &message)));
    }
    tlog
}

#[test]
fn a_tlog_of_the_demo_names_the_port_propeller() {
    let path = scratch("demo.tlog", &demo_as_tlog());
    let j = analyze(&path);
    assert_eq!(j["format"], "mavlink_tlog");
    assert_eq!(j["sources"]["position"], "mavlink:1");
    assert_eq!(j["model"], "kinetic");
    let t = &j["thrusters"];
    let port = t["port"]["loss"].as_f64().expect("a port loss");
    let starboard = t["starboard"]["loss"].as_f64().expect("a starboard loss");
    assert!((port - PORT_LOSS).abs() <= 0.05, "port {port}");
    assert!(starboard < 0.05, "starboard {starboard}");
    assert_eq!(t["port"]["status"], "fault");
    assert_eq!(j["rejected_by_reason"]["reader"], serde_json::json!({}));
}

#[test]
fn candump_ydraw_and_actisense_files_give_the_fixes_of_the_original() {
    let name = "aava-n2k.data";
    let original = workspace_root().join("tests/fixtures/real").join(name);
    let want = analyze(&original);
    let text = std::fs::read_to_string(&original).unwrap();
    for (layout, format) in [
        (RawFormat::Candump, "candump"),
        (RawFormat::YdRaw, "ydraw"),
        (RawFormat::ActisenseAscii, "actisense_ascii"),
    ] {
        let mut out = String::new();
        let mut data = Vec::new();
        for (i, line) in text.lines().enumerate() {
            let header = parse_message(line.as_bytes(), &mut data).unwrap();
            let fast = is_fast(header.id.pgn);
            // A logger's own PGNs (over 18 bits) are not on a CAN bus.
            let Ok(lines) =
                message_lines(layout, header.time_s, header.id, &data, fast, (i % 8) as u8)
            else {
                continue;
            };
            for l in lines {
                out.push_str(&l);
                out.push('\n');
            }
        }
        let path = scratch(&format!("aava.{format}"), out.as_bytes());
        let got = analyze(&path);
        assert_eq!(got["format"], format);
        for key in ["samples_by_kind", "assembled", "sources"] {
            assert_eq!(got[key], want[key], "{format}: {key}");
        }
        // The time-of-day layouts have no date: the log's day is assumed.
        let fixes = got["samples_by_kind"]["fixes"].as_u64().unwrap();
        assert!(fixes > 500, "{format}: {fixes}");
    }
}
