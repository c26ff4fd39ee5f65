//! `twin analyze` over every real log of `tests/fixtures/real`, as
//! `cargo xtask real-logs` runs it: every log read to the end with the
//! counts `twin-wire` pins (`crates/twin-wire/tests/real_logs.rs`), every
//! fix used or rejected with a reason, no propeller data so no loss, the
//! README and licences skipped; and the table made from them.

use twin_cli::analyze::AnalyzeOptions;
use twin_cli::demo::workspace_root;
use twin_wire::outputs::ThrusterStatusName;

/// The counts `twin-wire` pins for each real log: (file, lines, span s,
/// reader rejections, fixes, fixes with course, fixes with heading).
const PINNED: [(&str, u64, f64, u64, u64, u64, u64); 7] = [
    ("aava-n2k.data", 21_595, 599.928, 0, 601, 596, 596),
    ("furuno-130842-accel.raw", 26_593, 338.561, 0, 0, 0, 0),
    (
        "furuno-130842-figure8-fast.raw",
        34_466,
        357.103,
        0,
        2600,
        1279,
        2597,
    ),
    (
        "furuno-130842-wide-turn-port.raw",
        24_095,
        249.774,
        0,
        1981,
        886,
        1935,
    ),
    (
        "furuno-130842-wide-turn.raw",
        21_191,
        219.455,
        0,
        1754,
        787,
        1752,
    ),
    ("furuno-130842.raw", 18_924, 240.752, 0, 0, 0, 0),
    ("plaka.log", 116_000, 14_845.0, 2, 7250, 7249, 0),
];

#[test]
fn every_real_log_runs_to_the_end_with_the_pinned_counts() {
    let logs = xtask::real_logs::analyze_dir(
        &workspace_root().join("tests/fixtures/real"),
        &AnalyzeOptions::default(),
    )
    .expect("the real logs analyse");
    let names: Vec<&str> = logs.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        PINNED.iter().map(|p| p.0).collect::<Vec<_>>(),
        "every log, README and licences skipped"
    );
    for ((name, a), (_, lines, span_s, rejected, fixes, with_course, with_heading)) in
        logs.iter().zip(PINNED)
    {
        assert_eq!(a.read.lines, lines, "{name}: read to the end");
        let span = a.span.as_ref().expect("records");
        assert!((span.duration_s - span_s).abs() < 1e-6, "{name}");
        assert_eq!(a.read.total_rejected(), rejected, "{name}");
        assert_eq!(a.assembled.fixes, fixes, "{name}");
        assert_eq!(a.assembled.fixes_with_course, with_course, "{name}");
        assert_eq!(a.assembled.fixes_with_heading, with_heading, "{name}");
        // Every assembled fix is used by the twin or rejected with a reason.
        let twin_rejected: u64 = a.rejected_by_reason.twin_fixes.values().sum();
        assert_eq!(a.samples_by_kind.fixes + twin_rejected, fixes, "{name}");
        assert_eq!(a.samples_by_kind.propellers, 0, "{name}: no engine data");
        assert_eq!(a.samples, a.samples_by_kind.fixes, "{name}");
        assert_eq!(a.rejected, rejected + twin_rejected, "{name}");
        assert!(
            !a.thrusters.observable && a.thrusters.port.loss.is_none(),
            "{name}"
        );
        assert_eq!(a.thrusters.port.status, ThrusterStatusName::NotExcited);
        if fixes > 1 {
            let q = a.quality.seed_method.as_ref().expect("filter steps");
            assert!(
                q.steps + 1 >= a.samples_by_kind.fixes - twin_rejected,
                "{name}"
            );
            assert!(q.innovation_rms.position_m.unwrap().is_finite());
            assert!(a.seed_method.input_faults.is_some());
        } else {
            assert!(
                a.quality.seed_method.is_none() && a.final_state.is_none(),
                "{name}"
            );
        }
    }
    // plaka: the 2 sentences before the first time, named.
    let plaka = &logs[6].1;
    assert_eq!(plaka.rejected_by_reason.reader.get("no_time"), Some(&2));
    assert_eq!(plaka.first_rejections[0].reason, "no_time");
    let table = xtask::real_logs::markdown_table(&logs);
    assert_eq!(table.lines().count(), 2 + 7, "{table}");
    assert!(
        table.contains("| plaka.log | nmea0183 | 4 h 07 min 25.0 s | 7250 | 2 (2 no_time) |"),
        "{table}"
    );
}
