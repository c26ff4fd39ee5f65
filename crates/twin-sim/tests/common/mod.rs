//! Helpers shared by the integration tests: loading the shipped scenarios,
//! silencing sensors, looking up the truth, and simple statistics.

#![allow(dead_code)]

use std::path::PathBuf;

use twin_core::geodesy::{LatLon, LocalFrame, NorthEast};
use twin_sim::{Scenario, SimRun, TruthSample, Waypoint};

/// The shipped scenario directory, `config/scenarios`.
pub fn scenario_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/scenarios")
}

/// Loads a shipped scenario by file stem.
pub fn shipped(stem: &str) -> Scenario {
    let path = scenario_dir().join(format!("{stem}.toml"));
    Scenario::from_path(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Sets every sensor noise to zero.
pub fn silence(s: &mut Scenario) {
    s.sensors.gnss.position_sigma_m = 0.0;
    s.sensors.gnss.sog_sigma_mps = 0.0;
    s.sensors.heading.sigma_deg = 0.0;
    s.sensors.propellers.sigma_rpm = 0.0;
}

/// Removes the random disturbance: calm water.
pub fn calm(s: &mut Scenario) {
    s.disturbance = None;
}

/// A straight way-point path north from the origin.
pub fn northward(duration_s: f64, speed_mps: f64, length_m: f64) -> Scenario {
    Scenario::waypoint_mode(
        "northward",
        duration_s,
        speed_mps,
        vec![
            Waypoint::north_east(0.0, 0.0),
            Waypoint::north_east(length_m, 0.0),
        ],
    )
}

/// The truth sample at an elapsed time (the series is at exact instants).
pub fn truth_at(run: &SimRun, elapsed_s: f64) -> &TruthSample {
    truth_near(run, elapsed_s).unwrap_or_else(|| panic!("no truth at {elapsed_s} s"))
}

/// The truth sample at an elapsed time, if the series has one there (to
/// 1e-6 s: a unix time stamp less the start holds the elapsed time to
/// about 1e-7 s).
pub fn truth_near(run: &SimRun, elapsed_s: f64) -> Option<&TruthSample> {
    run.truth
        .iter()
        .find(|t| (t.elapsed_s - elapsed_s).abs() < 1e-6)
}

/// The run's local frame.
pub fn frame(run: &SimRun) -> LocalFrame {
    LocalFrame::new(run.origin).unwrap()
}

/// A geodetic position in the run's local frame.
pub fn local(run: &SimRun, p: LatLon) -> NorthEast {
    frame(run).to_local(p)
}

/// Mean of a sample.
pub fn mean(xs: &[f64]) -> f64 {
    xs.iter().sum::<f64>() / xs.len() as f64
}

/// Sample standard deviation.
pub fn std_dev(xs: &[f64]) -> f64 {
    let m = mean(xs);
    (xs.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (xs.len() - 1) as f64).sqrt()
}

/// Lag-1 autocorrelation.
pub fn lag1_autocorrelation(xs: &[f64]) -> f64 {
    let m = mean(xs);
    let num: f64 = xs.windows(2).map(|w| (w[0] - m) * (w[1] - m)).sum();
    let den: f64 = xs.iter().map(|x| (x - m).powi(2)).sum();
    num / den
}

/// Mean of a per-sample quantity over the truth samples after `from_s`.
pub fn truth_mean(run: &SimRun, from_s: f64, f: impl Fn(&TruthSample) -> f64) -> f64 {
    let xs: Vec<f64> = run
        .truth
        .iter()
        .filter(|t| t.elapsed_s >= from_s)
        .map(f)
        .collect();
    mean(&xs)
}
