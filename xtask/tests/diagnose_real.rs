//! `cargo xtask diagnose-real` over the real logs of `tests/fixtures/real`:
//! every log gets a row; on `aava-n2k.data` the current the twin names
//! agrees with the instrument's own set and drift (PGN 130577, an
//! independent estimate the diagnosis never reads) within 0.1 m/s as a
//! vector; the 4-hour `plaka.log`, which the nominal model explains, gets no
//! finding; the two logs without position records are diagnosed from their
//! velocities (one step per COG/SOG message, no cause that needs positions).

use std::path::Path;

use twin_core::diagnose::DiagnoseConfig;
use xtask::diagnose_real::{LogOutcome, diagnose_dir, instrument_comparison, markdown};

#[test]
fn the_real_logs_are_diagnosed_and_the_current_matches_the_instrument() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/real");
    let config = DiagnoseConfig {
        threads: 2,
        ..DiagnoseConfig::default()
    };
    let logs = diagnose_dir(&dir, &config).unwrap();
    let names: Vec<&str> = logs.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        vec![
            "aava-n2k.data",
            "furuno-130842-accel.raw",
            "furuno-130842-figure8-fast.raw",
            "furuno-130842-wide-turn-port.raw",
            "furuno-130842-wide-turn.raw",
            "furuno-130842.raw",
            "plaka.log"
        ],
        "README and licences are skipped, every log is taken"
    );
    let report = |name: &str| match &logs.iter().find(|(n, _)| n == name).unwrap().1 {
        LogOutcome::Diagnosed(r) => r.clone(),
        LogOutcome::TooFewFixes => panic!("{name} not diagnosed"),
    };
    let aava = report("aava-n2k.data");
    assert_eq!(aava.findings[0].cause, "current");
    let (_, _, difference_mps, _) = instrument_comparison(&aava).expect("both currents");
    assert!(
        difference_mps < 0.1,
        "{difference_mps} m/s from the instrument"
    );
    assert!(report("plaka.log").findings.is_empty());
    for name in ["furuno-130842.raw", "furuno-130842-accel.raw"] {
        let r = report(name);
        // One step per COG/SOG message (PGN 129026), counted in the text.
        let text = std::fs::read_to_string(dir.join(name)).unwrap();
        let courses = text.lines().filter(|l| l.contains(",129026,")).count();
        assert!(courses > 800, "{name}: {courses} COG/SOG messages");
        assert!(
            r.steps <= courses && r.steps * 100 >= courses * 98,
            "{name}: {} steps from {courses} COG/SOG messages",
            r.steps
        );
        assert_eq!(r.base_model, "water", "{name}");
        assert!(!r.measured.position, "{name}");
        assert!(
            r.measured.heading && r.measured.speed_through_water,
            "{name}"
        );
        let tried = r
            .findings
            .iter()
            .map(|f| f.cause.as_str())
            .chain(r.rejected.iter().map(|c| c.cause));
        for cause in tried {
            assert!(
                !["gnss_latency", "lever_arm"].contains(&cause),
                "{name}: {cause} needs positions"
            );
        }
        assert!(
            r.findings
                .iter()
                .all(|f| f.gain.prediction_rmse_m.is_empty()),
            "{name}: no forecast without positions"
        );
    }
    for (name, outcome) in &logs {
        if let LogOutcome::Diagnosed(r) = outcome {
            assert!(
                !serde_json::to_string(r).unwrap().contains("NaN"),
                "{name}: JSON has no NaN"
            );
        }
    }
    let md = markdown(&logs);
    for name in names {
        assert!(md.contains(&format!("| {name} |")), "{name} has a row");
    }
    assert!(md.contains("PGN 130577"));
}
