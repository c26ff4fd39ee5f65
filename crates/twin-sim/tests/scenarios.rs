//! Scenario files: the shipped ones load and say what their names say, bad
//! ones are rejected with the offending key named, and a scenario survives a
//! round trip through TOML.

mod common;

use common::{scenario_dir, shipped};
use twin_core::geodesy::NorthEast;
use twin_sim::{DisturbanceSpec, Scenario, ScenarioError, Waypoint, simulate};

#[test]
fn shipped_scenarios_are_the_seed_trial_matrix() {
    let mut stems: Vec<String> = std::fs::read_dir(scenario_dir())
        .unwrap()
        .filter_map(|e| {
            let path = e.unwrap().path();
            (path.extension()? == "toml").then(|| path.file_stem()?.to_str().map(str::to_string))?
        })
        .collect();
    stems.sort();
    let mut expected = Vec::new();
    for path in ["s-manoeuvre", "straight"] {
        for set in ["new-broken", "new-new", "new-original", "original-original"] {
            expected.push(format!("{path}_{set}"));
        }
    }
    // Besides the matrix: the demo's trial, the base of the diagnose
    // tests, the identification trial and the trial its profile is judged
    // on (docs/identification.md). Each must still load; a new file has to
    // be added here on purpose.
    let extras = [
        "demo_broken-port",
        "diagnose_base",
        "identify_heavy-otter",
        "identify_heavy-otter_port-loss",
        "identify_workboat",
        "identify_workboat_port-loss",
    ];
    for extra in extras {
        let s = shipped(extra);
        assert_eq!(s.name, extra);
        assert!(s.duration_s > 0.0, "{extra}");
    }
    let matrix: Vec<String> = stems
        .iter()
        .filter(|s| !extras.contains(&s.as_str()))
        .cloned()
        .collect();
    assert_eq!(matrix, expected);
    assert_eq!(stems.len(), expected.len() + extras.len());
    for stem in &matrix {
        let s = shipped(stem);
        assert_eq!(&s.name, stem);
        let (path, set) = stem.split_once('_').unwrap();
        assert_eq!(s.duration_s, if path == "straight" { 60.0 } else { 120.0 });
        // The set reads starboard-port, as in the thesis tables.
        let (stb, port) = set.split_once('-').unwrap();
        assert_eq!(s.propellers.starboard.label, stb);
        assert_eq!(s.propellers.port.label, port);
        let port_loss = if port == "broken" { 0.18 } else { 0.0 };
        assert_eq!(s.propellers.port.loss, port_loss, "{stem}");
        assert_eq!(s.propellers.starboard.loss, 0.0);
        assert_eq!(s.sensors.gnss.rate_hz, 5.0);
        // Harbour water, spelled out in every file.
        assert_eq!(s.disturbance, Some(DisturbanceSpec::default()), "{stem}");
    }
}

fn key_of(err: ScenarioError) -> String {
    match err {
        ScenarioError::Invalid { key, .. } => key,
        other => panic!("expected a validation error, got {other}"),
    }
}

const MINIMAL: &str = r#"
duration_s = 10.0
[path]
speed_mps = 1.5
waypoints = [{ north_m = 0.0, east_m = 0.0 }, { north_m = 50.0, east_m = 0.0 }]
"#;

#[test]
fn a_minimal_scenario_takes_every_default() {
    let s = Scenario::from_toml_str(MINIMAL).unwrap();
    assert_eq!(s.origin.lat_deg, 62.47);
    assert_eq!(s.step_s, 0.01);
    assert_eq!(s.sensors.gnss.position_sigma_m, 0.3);
    assert!(!s.sensors.heading.enabled);
    // No section, no disturbance; an empty section, the harbour default.
    assert_eq!(s.disturbance, None);
    let empty = Scenario::from_toml_str(&format!("{MINIMAL}\n[disturbance]\n")).unwrap();
    assert_eq!(empty.disturbance, Some(DisturbanceSpec::default()));
    let run = simulate(&s).unwrap();
    assert_eq!(run.start_unix_s, 1_653_040_800.0);
}

#[test]
fn toml_errors_name_the_key() {
    let typo = format!("{MINIMAL}\n[sensors.gnss]\nposition_sigma = 0.3\n");
    let msg = Scenario::from_toml_str(&typo).unwrap_err().to_string();
    assert!(msg.contains("position_sigma"), "{msg}");

    let wrong_type = MINIMAL.replace("duration_s = 10.0", "duration_s = \"ten\"");
    let msg = Scenario::from_toml_str(&wrong_type)
        .unwrap_err()
        .to_string();
    assert!(msg.contains("duration_s"), "{msg}");

    let typo = format!("{MINIMAL}\n[disturbance]\nsurge_sigma_n = 3.0\n");
    let msg = Scenario::from_toml_str(&typo).unwrap_err().to_string();
    assert!(msg.contains("surge_sigma_n"), "{msg}");

    let missing = MINIMAL.replace("duration_s = 10.0", "");
    let msg = Scenario::from_toml_str(&missing).unwrap_err().to_string();
    assert!(msg.contains("duration_s"), "{msg}");
}

#[test]
fn validation_errors_name_the_key() {
    let cases = [
        (
            "[sensors.gnss]\nposition_sigma_m = -1.0",
            "sensors.gnss.position_sigma_m",
        ),
        ("[propellers.port]\nloss = 1.5", "propellers.port.loss"),
        ("[control]\nrate_hz = 0.0", "control.rate_hz"),
        (
            "[current]\nspeed_mps = 0.2\ntoward_deg = 10.0\nspeed_amplitude_mps = 0.5",
            "current.speed_amplitude_mps",
        ),
        (
            "[manual]\ncommands = [{ time_s = 0.0, port_rpm = 1.0, starboard_rpm = 1.0 }]",
            "manual",
        ),
        (
            "[disturbance]\nsurge_force_sigma_n = -1.0",
            "disturbance.surge_force_sigma_n",
        ),
        (
            "[disturbance]\nsway_force_sigma_n = inf",
            "disturbance.sway_force_sigma_n",
        ),
        (
            "[disturbance]\nyaw_moment_sigma_nm = nan",
            "disturbance.yaw_moment_sigma_nm",
        ),
        (
            "[disturbance]\ncorrelation_s = 0.0",
            "disturbance.correlation_s",
        ),
        (
            "[disturbance]\ncorrelation_s = 0.05",
            "disturbance.correlation_s",
        ),
    ];
    for (extra, key) in cases {
        let text = format!("{MINIMAL}\n{extra}\n");
        assert_eq!(
            key_of(Scenario::from_toml_str(&text).unwrap_err()),
            key,
            "{extra}"
        );
    }
    let bad_wp = MINIMAL.replace(
        "{ north_m = 50.0, east_m = 0.0 }",
        "{ north_m = 50.0, lat_deg = 62.0, lon_deg = 6.0 }",
    );
    assert_eq!(
        key_of(Scenario::from_toml_str(&bad_wp).unwrap_err()),
        "path.waypoints[1]"
    );
    let local_time = format!("start_time = 2022-05-20T10:00:00\n{MINIMAL}");
    assert_eq!(
        key_of(Scenario::from_toml_str(&local_time).unwrap_err()),
        "start_time"
    );
    let no_path = "duration_s = 5.0\n";
    assert_eq!(
        key_of(Scenario::from_toml_str(no_path).unwrap_err()),
        "path"
    );
}

#[test]
fn lat_lon_waypoints_are_the_same_path() {
    let s = shipped("straight_new-broken");
    let frame = s.validate().unwrap().frame();
    let mut geo = s.clone();
    for wp in &mut geo.path.as_mut().unwrap().waypoints {
        let ll = frame.to_geodetic(NorthEast {
            north_m: wp.north_m.unwrap(),
            east_m: wp.east_m.unwrap(),
        });
        *wp = Waypoint {
            lat_deg: Some(ll.lat_deg),
            lon_deg: Some(ll.lon_deg),
            ..Waypoint::default()
        };
    }
    let a = simulate(&s).unwrap();
    let b = simulate(&geo).unwrap();
    let last = (a.truth.last().unwrap(), b.truth.last().unwrap());
    assert!((last.0.north_m - last.1.north_m).abs() < 1e-6);
    assert!((last.0.east_m - last.1.east_m).abs() < 1e-6);
}

#[test]
fn scenarios_round_trip_through_toml() {
    for stem in ["s-manoeuvre_new-broken", "straight_original-original"] {
        let mut s = shipped(stem);
        s.sensors.gnss.lever_arm.x_m = 0.4;
        s.sensors.heading.enabled = true;
        s.current = Some(twin_sim::CurrentSpec {
            speed_mps: 0.2,
            toward_deg: 135.0,
            rotation_deg_s: 0.01,
            speed_amplitude_mps: 0.05,
            speed_period_s: 300.0,
        });
        let text = s.to_toml_string().unwrap();
        let back = Scenario::from_toml_str(&text).unwrap();
        assert_eq!(back, s, "{text}");
    }
}

#[test]
fn the_readme_example_is_a_valid_scenario_with_the_documented_defaults() {
    let readme = std::fs::read_to_string(scenario_dir().join("README.md")).unwrap();
    let start = readme.find("```toml\n").unwrap() + "```toml\n".len();
    let end = start + readme[start..].find("```").unwrap();
    let s = Scenario::from_toml_str(&readme[start..end]).unwrap();
    // The example spells out every default of the sections it shares with a
    // minimal scenario.
    let minimal = Scenario::from_toml_str(MINIMAL).unwrap();
    assert_eq!(s.control, minimal.control);
    assert_eq!(s.propellers, minimal.propellers);
    assert_eq!(s.sensors, minimal.sensors);
    assert_eq!(
        (s.seed, s.step_s, s.origin),
        (minimal.seed, minimal.step_s, minimal.origin)
    );
    assert_eq!(s.start_time, minimal.start_time);
    assert_eq!(s.disturbance, Some(DisturbanceSpec::default()));
    assert!(simulate(&s).is_ok());
}
