//! `twin simulate` round trips: the log written for a simulated run reads
//! back through `twin_wire::LogReader` + `FixAssembler` as the same fixes and
//! propeller samples: exactly (times to the microsecond) from JSON lines,
//! within the writers' precision from NMEA 0183. The measured NMEA losses
//! are printed (`--nocapture`) and bounded here; `simulate`'s module doc
//! quotes them.

use std::path::PathBuf;
use std::process::Command;

use twin_cli::demo::{SCENARIO, workspace_root};
use twin_cli::simulate::{OutputFormat, fixes_as_logged, write_log};
use twin_core::geodesy::angle_diff;
use twin_core::sample::{GnssFix, PropellerSpeeds, RADPS_PER_RPM};
use twin_sim::{ManualCommand, ManualSpec, Scenario, SimRun};
use twin_wire::assemble::{AssembleStats, Assembled, AssemblerConfig, FixAssembler};
use twin_wire::read::{LogFormat, LogReader, ReadOptions, ReadStats};

/// The demo scenario, one minute of it, with the heading at 10 Hz and the
/// GNSS stamped 50 ms late, so headings and fixes have different stamps.
fn scenario() -> Scenario {
    let mut sc = Scenario::from_path(&workspace_root().join(SCENARIO)).expect("demo scenario");
    sc.duration_s = 60.0;
    sc.sensors.heading.enabled = true;
    sc.sensors.heading.rate_hz = 10.0;
    sc.sensors.gnss.latency_s = -0.05;
    sc
}

struct ReadBack {
    format: LogFormat,
    fixes: Vec<GnssFix>,
    propellers: Vec<PropellerSpeeds>,
    read: ReadStats,
    assembled: AssembleStats,
}

fn read_back(bytes: &[u8]) -> ReadBack {
    let mut reader = LogReader::open(bytes, ReadOptions::default()).expect("the log opens");
    let mut assembler = FixAssembler::new(AssemblerConfig::default());
    let mut out = Vec::new();
    for item in reader.by_ref() {
        assembler.push(item.expect("no rejection"), &mut out);
    }
    assembler.finish(&mut out);
    let mut fixes = Vec::new();
    let mut propellers = Vec::new();
    for a in out {
        match a {
            Assembled::Fix(f) => fixes.push(f),
            Assembled::Propellers(p) => propellers.push(p),
            Assembled::Thrust(_) => panic!("no thrust written"),
        }
    }
    ReadBack {
        format: reader.format(),
        fixes,
        propellers,
        read: reader.stats().clone(),
        assembled: assembler.stats().clone(),
    }
}

fn write(run: &SimRun, format: OutputFormat) -> Vec<u8> {
    let mut bytes = Vec::new();
    write_log(run, format, &mut bytes).expect("the run writes");
    bytes
}

#[test]
fn json_lines_read_back_exactly() {
    let run = twin_sim::simulate(&scenario()).expect("simulates");
    let expected = fixes_as_logged(&run);
    let measured: Vec<PropellerSpeeds> = run.measured_propellers().copied().collect();
    let back = read_back(&write(&run, OutputFormat::JsonLines));
    assert_eq!(back.format, LogFormat::JsonLines);
    assert_eq!(back.read.total_rejected(), 0);
    assert_eq!(back.fixes.len(), expected.len());
    assert_eq!(back.fixes.len(), 301);
    assert!(expected.iter().all(|f| f.heading_rad.is_some()));
    for (got, want) in back.fixes.iter().zip(&expected) {
        // Times to the microsecond (RFC 3339 with six decimals) ...
        assert!((got.time_s - want.time_s).abs() < 1e-6, "{got:?} {want:?}");
        // ... everything else bit for bit.
        assert_eq!(
            (got.position, got.sog_mps, got.heading_rad, got.hdop),
            (want.position, want.sog_mps, want.heading_rad, want.hdop)
        );
        assert_eq!(got.cog_rad, want.cog_rad);
    }
    assert_eq!(back.propellers.len(), measured.len());
    for (got, want) in back.propellers.iter().zip(&measured) {
        assert!((got.time_s - want.time_s).abs() < 1e-6);
        for (g, w) in [
            (got.port_radps, want.port_radps),
            (got.starboard_radps, want.starboard_radps),
        ] {
            assert!((g - w).abs() <= 1e-13 * w.abs(), "{g} vs {w}");
        }
    }
}

#[test]
fn nmea_reads_back_within_the_written_precision() {
    let run = twin_sim::simulate(&scenario()).expect("simulates");
    let expected = fixes_as_logged(&run);
    let measured: Vec<PropellerSpeeds> = run.measured_propellers().copied().collect();
    let bytes = write(&run, OutputFormat::Nmea);
    let back = read_back(&bytes);
    assert_eq!(back.format, LogFormat::Nmea0183);
    assert_eq!(back.read.total_rejected(), 0);
    assert_eq!(back.read.without_checksum, 0);
    assert_eq!(back.read.undated, 0, "the leading ZDA gives the date");
    assert_eq!(back.fixes.len(), expected.len());
    // GGA then RMC: the RMC's position repeats the GGA's (same time).
    assert_eq!(
        back.assembled.positions_not_after_previous,
        expected.len() as u64
    );
    let mut worst = [0.0f64; 7];
    for (got, want) in back.fixes.iter().zip(&expected) {
        let e = [
            (got.time_s - want.time_s).abs(),
            (got.position.lat_deg - want.position.lat_deg).abs(),
            (got.position.lon_deg - want.position.lon_deg).abs(),
            (got.sog_mps.unwrap() - want.sog_mps.unwrap()).abs(),
            angle_diff(got.cog_rad.unwrap(), want.cog_rad.unwrap()).abs(),
            angle_diff(got.heading_rad.unwrap(), want.heading_rad.unwrap()).abs(),
            (got.hdop.unwrap() - want.hdop.unwrap()).abs(),
        ];
        for (w, e) in worst.iter_mut().zip(e) {
            *w = w.max(e);
        }
    }
    let mut worst_rpm = 0.0f64;
    assert_eq!(back.propellers.len(), measured.len());
    for (got, want) in back.propellers.iter().zip(&measured) {
        assert!(
            (got.time_s - want.time_s).abs() < 1e-6,
            "RPM keeps its time"
        );
        worst_rpm = worst_rpm
            .max((got.port_radps - want.port_radps).abs() / RADPS_PER_RPM)
            .max((got.starboard_radps - want.starboard_radps).abs() / RADPS_PER_RPM);
    }
    println!(
        "NMEA 0183 round trip, largest errors: time {:.1e} s, lat {:.1e} deg ({:.2} mm), lon {:.1e} deg, SOG {:.1e} m/s, COG {:.1e} deg, heading {:.1e} deg, HDOP {:.1e}, shaft {:.1e} rpm",
        worst[0],
        worst[1],
        worst[1] * 111_000.0 * 1000.0,
        worst[2],
        worst[3],
        worst[4].to_degrees(),
        worst[5].to_degrees(),
        worst[6],
        worst_rpm
    );
    // The sample times are whole milliseconds: nothing lost but the f64 ulp.
    assert!(worst[0] < 1e-6);
    // 1e-6 minute of arc.
    assert!(worst[1] <= 0.5e-6 / 60.0 + 1e-12 && worst[2] <= 0.5e-6 / 60.0 + 1e-12);
    // 0.001 kn, 0.001 deg, 0.01 (HDOP), 0.01 rpm: half a unit at most.
    assert!(worst[3] <= 0.0005 * 1852.0 / 3600.0 + 1e-12);
    assert!(worst[4].to_degrees() <= 0.0005 + 1e-9 && worst[5].to_degrees() <= 0.0005 + 1e-9);
    assert!(worst[6] <= 0.005 + 1e-12);
    assert!(worst_rpm <= 0.005 + 1e-9);
}

#[test]
fn both_formats_give_the_same_twin_inputs() {
    let run = twin_sim::simulate(&scenario()).expect("simulates");
    let json = read_back(&write(&run, OutputFormat::JsonLines));
    let nmea = read_back(&write(&run, OutputFormat::Nmea));
    assert_eq!(json.fixes.len(), nmea.fixes.len());
    assert_eq!(json.propellers.len(), nmea.propellers.len());
    // The heading joined by the simulate writer (JSON) is the one the
    // assembler joins from the HDT sentences (NMEA).
    for (j, n) in json.fixes.iter().zip(&nmea.fixes) {
        assert!(angle_diff(j.heading_rad.unwrap(), n.heading_rad.unwrap()).abs() < 1e-5);
    }
    assert_eq!(
        json.assembled.fixes_with_heading,
        nmea.assembled.fixes_with_heading
    );
}

#[test]
fn fixes_without_a_course_are_kept_in_nmea_and_counted_out_of_json() {
    // Manual mode from rest: no COG below the simulator's 0.2 m/s.
    let mut sc = scenario();
    sc.duration_s = 20.0;
    sc.path = None;
    sc.initial = None;
    sc.manual = Some(ManualSpec {
        commands: vec![
            ManualCommand {
                time_s: 0.0,
                port_rpm: 0.0,
                starboard_rpm: 0.0,
            },
            ManualCommand {
                time_s: 5.0,
                port_rpm: 600.0,
                starboard_rpm: 650.0,
            },
        ],
    });
    let run = twin_sim::simulate(&sc).expect("simulates");
    let without = run.gnss_fixes().filter(|f| f.cog_rad.is_none()).count();
    assert!(without > 10, "{without}");
    let mut bytes = Vec::new();
    let summary = write_log(&run, OutputFormat::JsonLines, &mut bytes).unwrap();
    assert_eq!(summary.fixes_without_course, without);
    assert_eq!(summary.fixes + without, run.gnss_fixes().count());
    let nmea = read_back(&write(&run, OutputFormat::Nmea));
    assert_eq!(nmea.fixes.len(), run.gnss_fixes().count());
    assert_eq!(
        nmea.fixes.iter().filter(|f| f.cog_rad.is_none()).count(),
        without
    );
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("twin-cli-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn the_binary_picks_the_format_from_the_name_or_the_flag() {
    let dir = temp_dir("simulate");
    let scenario_path = dir.join("short.toml");
    let mut sc = scenario();
    sc.duration_s = 10.0;
    std::fs::write(&scenario_path, sc.to_toml_string().unwrap()).unwrap();
    let twin = env!("CARGO_BIN_EXE_twin");
    let run = |args: &[&str]| {
        let out = Command::new(twin).args(args).output().unwrap();
        (
            out.status.success(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    let s = scenario_path.to_str().unwrap();
    let nmea = dir.join("a.nmea");
    let jsonl = dir.join("b.jsonl");
    let forced = dir.join("c.log");
    let truth = dir.join("truth.jsonl");
    assert!(run(&["simulate", "--scenario", s, "--out", nmea.to_str().unwrap()]).0);
    assert!(
        run(&[
            "simulate",
            "--scenario",
            s,
            "--out",
            jsonl.to_str().unwrap(),
            "--truth",
            truth.to_str().unwrap()
        ])
        .0
    );
    assert!(
        run(&[
            "simulate",
            "--scenario",
            s,
            "--out",
            forced.to_str().unwrap(),
            "--format",
            "jsonl"
        ])
        .0
    );
    assert!(
        std::fs::read_to_string(&nmea)
            .unwrap()
            .starts_with("$GPZDA,")
    );
    // The GNSS is stamped 50 ms late here: the shaft speeds come first.
    for path in [&jsonl, &forced] {
        let text = std::fs::read_to_string(path).unwrap();
        assert!(text.starts_with("{\"type\":\"actuators\""), "{text:.80}");
        assert_eq!(
            text.lines()
                .filter(|l| l.contains("\"type\":\"gnss\""))
                .count(),
            51
        );
    }
    let truth_points = twin_cli::truth::read_truth(std::io::BufReader::new(
        std::fs::File::open(&truth).unwrap(),
    ))
    .unwrap();
    assert_eq!(truth_points.len(), 51);
    assert_eq!(truth_points[0].loss, Some([0.25, 0.0]));
    // No format: a clear refusal.
    let (ok, err) = run(&[
        "simulate",
        "--scenario",
        s,
        "--out",
        dir.join("d.bin").to_str().unwrap(),
    ]);
    assert!(!ok && err.contains("cannot tell the log format"), "{err}");
    let (ok, err) = run(&[
        "simulate",
        "--scenario",
        "/nonexistent.toml",
        "--out",
        nmea.to_str().unwrap(),
    ]);
    assert!(!ok && err.contains("/nonexistent.toml"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}
