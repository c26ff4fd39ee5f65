//! A gpsd JSON log (`gpspipe -w` of a receiver and a satellite compass) read
//! and assembled as `twin analyze` reads one: the compass's `ATT` heading and
//! rate of turn reach every fix as its heading and yaw rate.

use twin_wire::assemble::{Assembled, AssemblerConfig, FixAssembler};
use twin_wire::read::{LogFormat, LogReader, ReadOptions};

/// `epochs` epochs at 5 Hz of a vessel turning to port at `rot_deg_per_min`:
/// a TPV and an ATT each, both with the epoch's time, as gpsd reports a
/// satellite compass that time-stamps its attitude.
fn gpspipe_log(epochs: usize, rot_deg_per_min: f64) -> String {
    let mut lines = vec![
        r#"{"class":"VERSION","release":"3.25","rev":"3.25","proto_major":3,"proto_minor":15}"#
            .to_owned(),
    ];
    for k in 0..epochs {
        let second = 20.0 + 0.2 * k as f64;
        let time = format!("2026-08-03T04:27:{second:06.3}Z");
        let heading = 90.0 + rot_deg_per_min / 60.0 * 0.2 * k as f64;
        lines.push(format!(
            r#"{{"class":"TPV","device":"/dev/ttyUSB0","mode":3,"time":"{time}","lat":34.41,"lon":{lon:.7},"track":{heading:.2},"speed":2.5}}"#,
            lon = 133.54 + 1e-6 * k as f64,
        ));
        lines.push(format!(
            r#"{{"class":"ATT","device":"/dev/ttyUSB1","time":"{time}","heading":{heading:.2},"rot":{rot_deg_per_min:.1},"pitch":0.5,"roll":-1.2}}"#
        ));
    }
    lines.join("\n") + "\n"
}

#[test]
fn a_compass_rate_of_turn_reaches_every_fix_as_its_yaw_rate() {
    let log = gpspipe_log(25, -45.0);
    let mut reader = LogReader::open(log.as_bytes(), ReadOptions::default()).unwrap();
    assert_eq!(reader.format(), LogFormat::GpsdJson);
    let mut assembler = FixAssembler::new(AssemblerConfig::default());
    let mut out = Vec::new();
    for item in reader.by_ref() {
        assembler.push(item.expect("every report is read"), &mut out);
    }
    assembler.finish(&mut out);
    assert_eq!(reader.stats().total_rejected(), 0);
    let fixes: Vec<_> = out
        .iter()
        .filter_map(|a| match a {
            Assembled::Fix(f) => Some(f),
            _ => None,
        })
        .collect();
    assert_eq!(fixes.len(), 25);
    // 45 deg/min to port.
    let expected_radps = -(45f64.to_radians()) / 60.0;
    for fix in &fixes {
        let rate = fix.yaw_rate_radps.expect("a yaw rate on every fix");
        assert!((rate - expected_radps).abs() < 1e-12, "{rate}");
        assert!(fix.heading_rad.is_some());
    }
    assert_eq!(assembler.stats().fixes_with_yaw_rate, 25);
}
