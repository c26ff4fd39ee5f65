//! `cargo xtask diagnose-real` over the real logs of `tests/fixtures/real`:
//! every log gets a row; on `aava-n2k.data` the current the twin names
//! agrees with the instrument's own set and drift (PGN 130577, an
//! independent estimate the diagnosis never reads) within 0.1 m/s as a
//! vector; the 4-hour `plaka.log`, which the nominal model explains, gets no
//! finding; the two logs without position records are diagnosed from their
//! velocities (one step per COG/SOG message, no cause that needs positions);
//! the logs' measured yaw rates make the Furuno diagnoses better than the
//! same logs without them.

use std::path::Path;

use twin_core::diagnose::DiagnoseConfig;
use xtask::diagnose_real::{
    LogOutcome, diagnose_dir, extended_forecast_rmse_m, instrument_comparison, markdown,
    without_yaw_rates, yaw_rate_comparison, yaw_rate_markdown,
};

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
    the_measured_yaw_rate_improves_the_furuno_diagnoses(&dir, &logs, &config);

    let md = markdown(&logs);
    for name in names {
        assert!(md.contains(&format!("| {name} |")), "{name} has a row");
    }
    assert!(md.contains("PGN 130577"));
}

/// What the measured yaw rate buys on the Furuno logs with positions
/// (their rate of turn, PGN 127251, and gyro rates, PGN 130842, as
/// recorded, against the same logs with those records removed): the model
/// the findings extend forecasts the held-out positions better at 15 and
/// 30 s, and the mirrored wide turns get the same physical explanation (a
/// hull that slides in its turns, sideways speed against yaw rate of one
/// sign), not a heading sensor's offset in one log that the other does
/// not show.
fn the_measured_yaw_rate_improves_the_furuno_diagnoses(
    dir: &Path,
    logs: &[(String, LogOutcome)],
    config: &DiagnoseConfig,
) {
    let comparisons = yaw_rate_comparison(dir, logs, config).unwrap();
    let compared: Vec<&str> = comparisons.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(
        compared,
        vec![
            "furuno-130842-figure8-fast.raw",
            "furuno-130842-wide-turn-port.raw",
            "furuno-130842-wide-turn.raw",
        ]
    );
    for c in &comparisons {
        assert!(!c.without.measured.yaw_rate, "{}", c.name);
        for horizon_s in [15.0, 30.0] {
            let (with, without) = (
                extended_forecast_rmse_m(&c.with, horizon_s),
                extended_forecast_rmse_m(&c.without, horizon_s),
            );
            assert!(
                with < without,
                "{}: {horizon_s} s forecast RMSE {with:.2} m with the yaw rate, {without:.2} m without",
                c.name
            );
        }
    }
    let sideslip = |name: &str| {
        let r = &comparisons.iter().find(|c| c.name == name).unwrap().with;
        let first = &r.findings[0];
        assert_eq!(first.cause, "sideslip", "{name}: {:?}", r.findings);
        first.parameters["lateral_mps_per_radps"]
            .as_f64()
            .expect("a number")
    };
    let (port, starboard) = (
        sideslip("furuno-130842-wide-turn-port.raw"),
        sideslip("furuno-130842-wide-turn.raw"),
    );
    assert_eq!(port.signum(), starboard.signum(), "{port} and {starboard}");
    assert!(yaw_rate_markdown(&comparisons).contains("| records removed |"));
}

#[test]
fn a_log_without_its_yaw_rates_keeps_every_other_record() {
    let text = "2026-08-03T05:05:27.966Z,2,127251,27,255,8,00,f2,74,fa,ff,ff,ff,ff\n\
                2026-08-03T05:05:27.970Z,2,129025,25,255,8,00,00,00,00,00,00,00,00\n\
                2026-08-03T05:05:27.980Z,3,130842,52,255,29,71,98,00,00,00,00,00,00\n\
                $TIROT,-12.5,A*1E\n\
                $HEHDT,91.5,T*2C\n";
    let kept = without_yaw_rates(text);
    assert_eq!(kept.lines().count(), 2, "{kept}");
    assert!(kept.contains(",129025,") && kept.contains("$HEHDT"));
}
