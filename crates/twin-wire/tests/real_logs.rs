//! Every real log in `tests/fixtures/real/` read to the end, with what it
//! contains pinned: records by kind and source, rejections by reason,
//! ignored and empty messages, fixes assembled, and the span and rates that
//! the data README states (so a count that is "stable" but wrong still
//! fails). The counts were computed, checked against the README's rates and
//! durations, then pinned.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufReader;
use std::path::PathBuf;

use twin_wire::assemble::{AssembleStats, AssemblerConfig, FixAssembler};
use twin_wire::measurement::{MeasurementKind, Source};
use twin_wire::read::{LogFormat, LogReader, ReadOptions, ReadStats, RejectKind};

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/fixtures/real")
        .join(name)
}

struct Read {
    format: LogFormat,
    stats: ReadStats,
    by_source: BTreeMap<(String, &'static str), u64>,
    first_s: f64,
    last_s: f64,
    assembler: FixAssembler,
    assembled: AssembleStats,
}

fn read(name: &str) -> Read {
    let file = File::open(fixture(name)).expect("fixture present");
    let mut reader = LogReader::open(BufReader::new(file), ReadOptions::default()).expect("opens");
    let mut assembler = FixAssembler::new(AssemblerConfig::default());
    let mut out = Vec::new();
    let mut by_source = BTreeMap::new();
    let (mut first_s, mut last_s) = (None, f64::NAN);
    let mut previous_out_s = f64::NEG_INFINITY;
    for item in reader.by_ref() {
        let Ok(record) = item else { continue };
        first_s.get_or_insert(record.time_s);
        last_s = record.time_s;
        *by_source
            .entry((record.source.to_string(), record.measurement.kind().name()))
            .or_insert(0) += 1;
        assembler.push(record, &mut out);
        for a in out.drain(..) {
            // The assembled stream is in time order.
            assert!(a.time_s() >= previous_out_s);
            previous_out_s = a.time_s();
        }
    }
    assembler.finish(&mut out);
    Read {
        format: reader.format(),
        stats: reader.stats().clone(),
        by_source,
        first_s: first_s.expect("some record"),
        last_s,
        assembled: assembler.stats().clone(),
        assembler,
    }
}

fn count(r: &Read, source: &str, kind: MeasurementKind) -> u64 {
    r.by_source
        .get(&(source.to_owned(), kind.name()))
        .copied()
        .unwrap_or(0)
}

fn records(r: &Read) -> Vec<(MeasurementKind, u64)> {
    r.stats.records_by_kind().collect()
}

/// Records per second of a source and kind over the log's span.
fn rate_hz(r: &Read, source: &str, kind: MeasurementKind) -> f64 {
    count(r, source, kind) as f64 / (r.last_s - r.first_s)
}

use MeasurementKind::{
    Attitude, CourseSpeed, GyroRates, Heading, Position, RateOfTurn, SetDrift, SpeedThroughWater,
};

#[test]
fn plaka_nmea0183() {
    let r = read("plaka.log");
    assert_eq!(r.format, LogFormat::Nmea0183);
    // 7250 bursts of 16 sentences, about one every 2 s over 4 h 07 min.
    assert_eq!(r.stats.lines, 116_000);
    assert!((r.last_s - r.first_s - 14_845.0).abs() < 1e-6);
    assert_eq!(
        records(&r),
        [
            (Position, 7250),
            (CourseSpeed, 7249),
            (SpeedThroughWater, 7249)
        ]
    );
    // GLL positions from GP; VTG and VHW from II. No heading at all: every
    // HDT (2 a burst) and HDM is empty, which is absence, not an error.
    assert_eq!(count(&r, "nmea:GP", Position), 7250);
    assert_eq!(count(&r, "nmea:II", CourseSpeed), 7249);
    assert_eq!(count(&r, "nmea:II", SpeedThroughWater), 7249);
    assert_eq!(r.stats.empty, 3 * 7250);
    assert_eq!(r.stats.records(Heading), 0);
    // ZDA only sets the clock; wind, depth, XTE, GSV, VPW... are not read.
    assert_eq!(r.stats.time_only, 7250);
    assert_eq!(r.stats.ignored, 9 * 7250);
    // The log starts mid-burst: its first VHW and VTG come before any time.
    assert_eq!(
        r.stats.rejected_by_kind().collect::<Vec<_>>(),
        [(RejectKind::NoTime, 2)]
    );
    // No date anywhere (ZDA has empty date fields, no RMC): every record is
    // on the assumed date.
    assert_eq!(r.stats.undated, r.stats.total_records());
    assert_eq!(r.stats.without_checksum, 0);
    // One fix a burst; the last GLL has no VTG after it.
    assert_eq!(r.assembled.fixes, 7250);
    assert_eq!(r.assembled.fixes_with_course, 7249);
    assert_eq!(r.assembled.fixes_with_heading, 0);
    assert!((r.assembled.fixes as f64 / (r.last_s - r.first_s) - 0.49).abs() < 0.01);
}

#[test]
fn aava_n2k() {
    let r = read("aava-n2k.data");
    assert_eq!(r.format, LogFormat::N2k);
    assert_eq!(r.stats.lines, 21_595);
    assert!((r.last_s - r.first_s - 599.928).abs() < 1e-6);
    assert_eq!(
        records(&r),
        [
            (Position, 1194),
            (CourseSpeed, 596),
            (Heading, 596),
            (SpeedThroughWater, 1201),
            (SetDrift, 597)
        ]
    );
    // Source 160 at 1 Hz: 129029 and 129025 positions (597 each), 129026,
    // 127250 (true), 130577 set and drift.
    assert_eq!(count(&r, "n2k:160", Position), 1194);
    assert!((rate_hz(&r, "n2k:160", SetDrift) - 1.0).abs() < 0.01);
    // STW from the log (115) at 2 Hz; 160's 128259 has only a ground speed
    // (not read), so all 597 of them are empty.
    assert_eq!(count(&r, "n2k:115", SpeedThroughWater), 1201);
    assert_eq!(count(&r, "n2k:160", SpeedThroughWater), 0);
    assert_eq!(r.stats.empty, 597);
    // AIS, wind, depth, engine, ... are ignored, nothing is rejected.
    assert_eq!(r.stats.ignored, 16_814);
    assert_eq!(r.stats.total_rejected(), 0);
    assert_eq!(
        r.assembler.sources(),
        (
            Some(Source::N2k(160)),
            Some(Source::N2k(160)),
            Some(Source::N2k(160))
        )
    );
    // Each fix comes twice: in 129025, then ~0.5 s later with the same
    // coordinates in 129029 (whose own GNSS time is the earlier epoch). The
    // re-sent copies are dropped: one fix a second, each with its COG/SOG and
    // heading.
    assert_eq!(r.assembled.positions_repeated, 593);
    assert_eq!(r.assembled.fixes, 601);
    assert_eq!(r.assembled.fixes_with_course, 596);
    assert_eq!(r.assembled.fixes_with_heading, 596);
    assert!((r.assembled.fixes as f64 / (r.last_s - r.first_s) - 1.0).abs() < 0.01);
}

/// The five Furuno trials share one bus: (file, lines, span s, positions of
/// 25, positions of 52, COG/SOG of 25, COG/SOG of 52, STW, ROT of 27, ROT of
/// 52, attitudes, gyro rates, ignored, fixes, fixes with course, fixes with
/// heading, positions dropped as re-sent).
#[allow(clippy::type_complexity)]
const FURUNO: [(&str, u64, f64, [u64; 14]); 5] = [
    (
        "furuno-130842.raw",
        18_924,
        240.752,
        [0, 0, 860, 0, 1204, 4816, 2408, 4816, 2408, 2411, 0, 0, 0, 0],
    ),
    (
        "furuno-130842-accel.raw",
        26_593,
        338.561,
        [
            0, 0, 1220, 0, 1693, 6757, 3386, 6765, 3386, 3385, 0, 0, 0, 0,
        ],
    ),
    (
        "furuno-130842-wide-turn.raw",
        21_191,
        219.455,
        [
            1755, 1097, 787, 878, 1098, 4384, 2195, 4387, 2195, 2414, 1754, 787, 1752, 0,
        ],
    ),
    (
        "furuno-130842-wide-turn-port.raw",
        24_095,
        249.774,
        [
            1989, 1249, 886, 999, 1249, 4987, 2498, 4992, 2498, 2747, 1981, 886, 1935, 7,
        ],
    ),
    (
        "furuno-130842-figure8-fast.raw",
        34_466,
        357.103,
        [
            2826, 1786, 1281, 1429, 1785, 7142, 3571, 7142, 3572, 3931, 2600, 1279, 2597, 225,
        ],
    ),
];

#[test]
fn furuno_trials_n2k() {
    for (name, lines, span_s, c) in FURUNO {
        let r = read(name);
        assert_eq!(r.format, LogFormat::N2k, "{name}");
        assert_eq!(r.stats.lines, lines, "{name}");
        assert_eq!(r.stats.blank, 1, "{name}: the `# format=FAST` header");
        assert!((r.last_s - r.first_s - span_s).abs() < 1e-6, "{name}");
        let got = [
            count(&r, "n2k:25", Position),
            count(&r, "n2k:52", Position),
            count(&r, "n2k:25", CourseSpeed),
            count(&r, "n2k:52", CourseSpeed),
            count(&r, "n2k:35", SpeedThroughWater),
            count(&r, "n2k:27", RateOfTurn),
            count(&r, "n2k:52", RateOfTurn),
            r.stats.records(Attitude),
            count(&r, "n2k:52", GyroRates),
            r.stats.ignored,
            r.assembled.fixes,
            r.assembled.fixes_with_course,
            r.assembled.fixes_with_heading,
            r.assembled.positions_repeated,
        ];
        assert_eq!(got, c, "{name}");
        // Nothing else, nothing rejected, no heading PGN (yaw is in 127257).
        let total: u64 = got[..9].iter().sum();
        assert_eq!(r.stats.total_records(), total, "{name}");
        assert_eq!(r.stats.total_rejected(), 0, "{name}");
        assert_eq!(r.stats.empty, 0, "{name}");
        // The README's rates: STW 5 Hz, ROT of 27 at 20 Hz, gyro 10 Hz, COG of
        // 25 at ~3.6 Hz.
        assert!(
            (rate_hz(&r, "n2k:35", SpeedThroughWater) - 5.0).abs() < 0.05,
            "{name}"
        );
        assert!(
            (rate_hz(&r, "n2k:27", RateOfTurn) - 20.0).abs() < 0.1,
            "{name}"
        );
        assert!(
            (rate_hz(&r, "n2k:52", GyroRates) - 10.0).abs() < 0.05,
            "{name}"
        );
        assert!(
            (rate_hz(&r, "n2k:25", CourseSpeed) - 3.6).abs() < 0.1,
            "{name}"
        );
        if c[0] > 0 {
            // 25 at ~8 Hz beats 52 at 5 Hz (neither reports a fix method);
            // its COG/SOG goes with it; the heading is 52's attitude yaw.
            assert!(
                (rate_hz(&r, "n2k:25", Position) - 8.0).abs() < 0.1,
                "{name}"
            );
            assert!(
                (rate_hz(&r, "n2k:52", Position) - 5.0).abs() < 0.05,
                "{name}"
            );
            assert_eq!(
                r.assembler.sources(),
                (
                    Some(Source::N2k(25)),
                    Some(Source::N2k(25)),
                    Some(Source::N2k(52))
                ),
                "{name}"
            );
            // Once a file, 25 delivers a bunch of positions within ~60 ms,
            // two with one timestamp: the second is dropped. In the fast
            // figure-8, 25 also re-sends its previous position 0.1 s later
            // every second or two (at 4 m/s a new fix would be 0.4 m away):
            // those 225 are dropped as re-sent, not taken as a stop.
            assert_eq!(r.assembled.positions_not_after_previous, 1, "{name}");
            assert_eq!(
                r.assembled.fixes + 1 + r.assembled.positions_repeated,
                c[0],
                "{name}"
            );
            assert_eq!(r.assembled.positions_other_sources, c[1], "{name}");
        } else {
            // No position at all in these two files: no fix can be made.
            assert_eq!(r.assembler.sources().0, None, "{name}");
        }
    }
}
