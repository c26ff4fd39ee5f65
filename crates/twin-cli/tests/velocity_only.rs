//! `twin diagnose` on a log without positions: the simulator writes the
//! hidden-effect base trial as NMEA 0183, its position sentences (GGA, RMC)
//! are removed, and the diagnosis reads what is left (course and speed over
//! ground in VTG, heading in HDT, and with or without the shaft speeds in
//! RPM). A hidden current of 0.3 m/s must be named within 20 % as a vector;
//! the same log without the current names nothing (on the kinematic water
//! base, nothing but the simulated hull's real sideslip, at its true size);
//! neither names a cause that needs positions.

use std::io::Cursor;
use std::path::Path;

use twin_cli::diagnose::{DiagnoseReport, diagnose_loaded, load};
use twin_cli::simulate::{OutputFormat, simulate_to_bytes};
use twin_core::diagnose::{DiagEvent, DiagnoseConfig};
use twin_sim::{CurrentSpec, Scenario};
use twin_wire::SourceChoice;
use twin_wire::profile::VesselProfile;

const CURRENT_MPS: f64 = 0.3;
const CURRENT_TOWARD_DEG: f64 = 60.0;

fn scenario(current: bool) -> Scenario {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../config/scenarios/diagnose_base.toml"
    );
    let mut sc = Scenario::from_toml_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    sc.seed = 7;
    if current {
        sc.current = Some(CurrentSpec {
            speed_mps: CURRENT_MPS,
            toward_deg: CURRENT_TOWARD_DEG,
            rotation_deg_s: 0.0,
            speed_amplitude_mps: 0.0,
            speed_period_s: 600.0,
        });
    }
    sc
}

/// The scenario's NMEA 0183 log without the sentences in `drop` (by
/// sentence type: `GGA`, `RMC`, `RPM`).
fn log_without(sc: &Scenario, drop: &[&str]) -> Vec<u8> {
    let (bytes, _) = simulate_to_bytes(sc, OutputFormat::Nmea).unwrap();
    let text = String::from_utf8(bytes).unwrap();
    let kept: Vec<&str> = text
        .lines()
        .filter(|l| !drop.iter().any(|d| l.get(3..6) == Some(*d)))
        .collect();
    assert!(
        kept.len() < text.lines().count(),
        "the sentences to drop were in the log"
    );
    (kept.join("\r\n") + "\r\n").into_bytes()
}

fn diagnose_bytes(bytes: Vec<u8>, name: &str) -> DiagnoseReport {
    let log = load(Cursor::new(bytes), Path::new(name), SourceChoice::Best).unwrap();
    assert!(
        !log.events.iter().any(|e| matches!(e, DiagEvent::Fix(_))),
        "no fix with a position is left"
    );
    let velocities = log
        .events
        .iter()
        .filter(|e| matches!(e, DiagEvent::Velocity(_)))
        .count();
    // 5 Hz course/speed for 300 s.
    assert!((1400..=1510).contains(&velocities), "{velocities} instants");
    diagnose_loaded(
        name,
        &log,
        &DiagnoseConfig {
            threads: 2,
            ..DiagnoseConfig::default()
        },
        &VesselProfile::otter(),
    )
    .unwrap()
}

fn summary(r: &DiagnoseReport) -> String {
    r.findings
        .iter()
        .map(|f| format!("{} {:?}", f.cause, f.parameters))
        .collect::<Vec<_>>()
        .join("; ")
}

fn check_velocity_only(r: &DiagnoseReport) {
    assert!(!r.measured.position);
    assert!(r.measured.heading);
    assert!(r.steps > 1400, "{} steps", r.steps);
    for f in &r.findings {
        assert!(
            !["gnss_latency", "lever_arm"].contains(&f.cause.as_str()),
            "{} needs positions",
            f.cause
        );
        assert!(f.gain.prediction_rmse_m.is_empty(), "no forecast RMSE");
    }
    for c in &r.rejected {
        assert!(
            !["gnss_latency", "lever_arm"].contains(&c.cause),
            "{} was tried",
            c.cause
        );
    }
    // Neither position component was measured.
    assert!(!r.nominal.measured[0] && !r.nominal.measured[1]);
    let json = serde_json::to_string(r).unwrap();
    assert!(json.contains("\"position\":false"));
    assert!(!json.contains("NaN"));
}

fn check_current_named(r: &DiagnoseReport) {
    let f = r
        .findings
        .iter()
        .find(|f| f.cause == "current")
        .unwrap_or_else(|| panic!("no current named: {}", summary(r)));
    let get = |k: &str| f.parameters[k].as_f64().unwrap();
    let (north, east) = (get("north_mps"), get("east_mps"));
    let toward = CURRENT_TOWARD_DEG.to_radians();
    let error = (north - CURRENT_MPS * toward.cos()).hypot(east - CURRENT_MPS * toward.sin());
    assert!(
        error <= 0.2 * CURRENT_MPS,
        "current ({north:.3}, {east:.3}) m/s is {error:.3} m/s from the truth: {}",
        summary(r)
    );
}

/// The simulated hull's own sideslip: the least-squares slope of its true
/// sway speed through the water over its yaw rate, m/s per rad/s; or, for
/// a sway that grows with speed (`with_speed`), over its yaw rate times its
/// surge speed through the water, times its mean speed over ground where it
/// is under way (the speed `sideslip_with_speed` is reported at).
fn true_sideslip(sc: &Scenario, with_speed: bool) -> f64 {
    let truth = twin_sim::simulate(sc).unwrap().truth;
    let x = |t: &twin_sim::TruthSample| {
        if with_speed {
            t.r_radps * t.u_water_mps
        } else {
            t.r_radps
        }
    };
    let (vx, xx) = truth.iter().fold((0.0, 0.0), |(vx, xx), t| {
        (vx + t.v_water_mps * x(t), xx + x(t) * x(t))
    });
    let under_way: Vec<f64> = truth
        .iter()
        .map(|t| t.sog_mps)
        .filter(|v| *v >= twin_core::diagnose::UNDER_WAY_MPS)
        .collect();
    let speed_mps = under_way.iter().sum::<f64>() / under_way.len() as f64;
    if with_speed {
        vx / xx * speed_mps
    } else {
        vx / xx
    }
}

/// Besides the current (if any), the water base may name only the hull's
/// drift, which the simulated hull really has (it slides in its turns), of
/// either shape: then at the size of the truth's in that shape within 25 %.
fn check_only_the_hulls_sideslip(r: &DiagnoseReport, sc: &Scenario) {
    for f in r.findings.iter().filter(|f| f.cause != "current") {
        let with_speed = match f.cause.as_str() {
            "sideslip" => false,
            "sideslip_with_speed" => true,
            other => panic!("{other} named: {}", summary(r)),
        };
        let k = f.parameters["lateral_mps_per_radps"].as_f64().unwrap();
        let truth = true_sideslip(sc, with_speed);
        assert!(
            (k - truth).abs() <= 0.25 * truth.abs(),
            "{} {k:.3}, the hull's {truth:.3} m/s per rad/s",
            f.cause
        );
    }
}

#[test]
fn a_current_is_named_from_velocities_alone_on_the_water_base() {
    let drop = ["GGA", "RMC", "RPM"];
    let with_current = scenario(true);
    let r = diagnose_bytes(log_without(&with_current, &drop), "current-water");
    println!("with a current: {}", summary(&r));
    assert_eq!(r.base_model, "water");
    check_velocity_only(&r);
    check_current_named(&r);
    check_only_the_hulls_sideslip(&r, &with_current);
    let clean_scenario = scenario(false);
    let clean = diagnose_bytes(log_without(&clean_scenario, &drop), "clean-water");
    println!("clean: {}", summary(&clean));
    check_velocity_only(&clean);
    assert!(
        clean.findings.iter().all(|f| f.cause != "current"),
        "{}",
        summary(&clean)
    );
    check_only_the_hulls_sideslip(&clean, &clean_scenario);
}

#[test]
fn a_current_is_named_from_velocities_alone_on_the_kinetic_base() {
    let drop = ["GGA", "RMC"];
    let r = diagnose_bytes(log_without(&scenario(true), &drop), "current-kinetic");
    println!("with a current: {}", summary(&r));
    assert_eq!(r.base_model, "kinetic");
    check_velocity_only(&r);
    check_current_named(&r);
    let clean = diagnose_bytes(log_without(&scenario(false), &drop), "clean-kinetic");
    println!("clean: {}", summary(&clean));
    check_velocity_only(&clean);
    assert!(clean.findings.is_empty(), "{}", summary(&clean));
}
