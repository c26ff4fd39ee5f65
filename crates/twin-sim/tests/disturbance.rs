//! The random disturbance: its statistics in the truth record, its absence
//! when calm, its own random stream, and the hull's response to it against
//! the first-order theory the estimator's tuning rests on.

mod common;

use common::{calm, lag1_autocorrelation, local, mean, shipped, std_dev, truth_near};
use twin_core::geodesy::wrap_pi;
use twin_sim::{
    DisturbanceSpec, ManualCommand, OtterParams, Scenario, SensorEvent, SimRun, simulate,
};

/// The craft adrift (shafts stopped) for `duration_s` in the given disturbance.
fn adrift(duration_s: f64, spec: DisturbanceSpec) -> Scenario {
    let mut s = Scenario::manual_mode(
        "adrift",
        duration_s,
        vec![ManualCommand {
            time_s: 0.0,
            port_rpm: 0.0,
            starboard_rpm: 0.0,
        }],
    );
    s.disturbance = Some(spec);
    s
}

/// One component of the recorded disturbance.
fn component(run: &SimRun, i: usize) -> Vec<f64> {
    run.truth.iter().map(|t| t.disturbance_force[i]).collect()
}

#[test]
fn recorded_disturbance_has_the_configured_sigma_and_correlation() {
    let spec = DisturbanceSpec::default();
    let run = simulate(&adrift(3000.0, spec)).unwrap();
    // The truth series is at the GNSS rate, 5 Hz: lag 0.2 s.
    assert_eq!(run.truth.len(), 15_001);
    let h = run.truth[1].elapsed_s - run.truth[0].elapsed_s;
    let rho_expected = (-h / spec.correlation_s).exp();
    let xs: Vec<Vec<f64>> = (0..3).map(|i| component(&run, i)).collect();
    for (i, sigma) in spec.sigmas().into_iter().enumerate() {
        // 3000 s is 1500 correlation times: the sample standard deviation is
        // known to about sqrt(T / 2D) = 1.8 %, the mean to 3.7 % of sigma.
        let sd = std_dev(&xs[i]);
        assert!((sd / sigma - 1.0).abs() < 0.06, "{i}: sd {sd} vs {sigma}");
        assert!(
            mean(&xs[i]).abs() < 0.15 * sigma,
            "{i}: mean {}",
            mean(&xs[i])
        );
        let rho = lag1_autocorrelation(&xs[i]);
        assert!(
            (rho - rho_expected).abs() < 0.015,
            "{i}: lag-1 {rho} vs {rho_expected}"
        );
        // Stationary from the start: the first value is a draw, not zero.
        assert!(xs[i][0] != 0.0);
    }
    // The three components are independent.
    let cross = |a: &[f64], b: &[f64]| {
        let (ma, mb) = (mean(a), mean(b));
        let c: f64 = a.iter().zip(b).map(|(x, y)| (x - ma) * (y - mb)).sum();
        c / (a.len() as f64 * std_dev(a) * std_dev(b))
    };
    for (i, j) in [(0, 1), (0, 2), (1, 2)] {
        let c = cross(&xs[i], &xs[j]);
        assert!(c.abs() < 0.12, "{i}-{j}: {c}");
    }
}

#[test]
fn zero_sigma_is_bit_identical_to_no_disturbance_section() {
    for stem in ["s-manoeuvre_new-broken", "straight_original-original"] {
        let mut without = shipped(stem);
        calm(&mut without);
        let mut zero = shipped(stem);
        zero.disturbance = Some(DisturbanceSpec::calm());
        let a = simulate(&without).unwrap();
        let b = simulate(&zero).unwrap();
        assert_eq!(a, b, "{stem}");
        assert!(a.truth.iter().all(|t| t.disturbance_force == [0.0; 3]));
        // And the shipped level does move the craft.
        let c = simulate(&shipped(stem)).unwrap();
        assert_ne!(a.truth, c.truth);
    }
}

/// Each sensor's error against the truth of the same run, in event order,
/// at the instants of the truth series: GNSS north/east position and
/// velocity, heading, port and starboard shaft speeds.
fn sensor_errors(run: &SimRun) -> Vec<f64> {
    let mut out = Vec::new();
    for e in &run.events {
        let Some(t) = truth_near(run, e.time_s() - run.start_unix_s) else {
            continue;
        };
        match e {
            SensorEvent::Gnss(f) => {
                let p = local(run, f.position);
                let (sog, cog) = (f.sog_mps.unwrap(), f.cog_rad.unwrap());
                out.extend([
                    p.north_m - t.north_m,
                    p.east_m - t.east_m,
                    sog * cog.cos() - t.sog_mps * t.cog_rad.cos(),
                    sog * cog.sin() - t.sog_mps * t.cog_rad.sin(),
                ]);
            }
            SensorEvent::Heading(h) => out.push(wrap_pi(h.heading_rad - t.heading_rad)),
            SensorEvent::PropellerMeasured(p) => out.extend([
                p.port_radps - t.shaft_radps[0],
                p.starboard_radps - t.shaft_radps[1],
            ]),
            SensorEvent::PropellerCommanded(p) => out.extend([
                p.port_radps - t.shaft_cmd_radps[0],
                p.starboard_radps - t.shaft_cmd_radps[1],
            ]),
            SensorEvent::YawRate(y) => out.push(y.yaw_rate_radps - t.r_radps),
        }
    }
    out
}

#[test]
fn enabling_the_disturbance_leaves_every_sensor_noise_sequence_unchanged() {
    let mut disturbed = shipped("s-manoeuvre_new-broken");
    disturbed.sensors.heading.enabled = true;
    let mut still = disturbed.clone();
    calm(&mut still);
    let a = simulate(&still).unwrap();
    let b = simulate(&disturbed).unwrap();
    // Different trajectories...
    let gap = a
        .truth
        .iter()
        .zip(&b.truth)
        .map(|(x, y)| (x.north_m - y.north_m).hypot(x.east_m - y.east_m))
        .fold(0.0, f64::max);
    assert!(gap > 0.1, "{gap} m");
    // ...with the same noise on each sensor.
    let (ea, eb) = (sensor_errors(&a), sensor_errors(&b));
    assert_eq!(ea.len(), eb.len());
    assert!(ea.len() > 3000);
    let worst = ea
        .iter()
        .zip(&eb)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-6, "{worst}");
    // Not vacuous: the errors are noise, not zero.
    assert!(std_dev(&ea) > 0.01);
}

#[test]
fn the_realisation_depends_on_neither_the_step_nor_the_sensor_rates() {
    let base = shipped("straight_new-broken");
    let mut other = base.clone();
    other.step_s = 0.004;
    other.sensors.heading.enabled = true;
    other.sensors.heading.rate_hz = 7.0;
    other.sensors.propellers.rate_hz = 3.0;
    let a = simulate(&base).unwrap();
    let b = simulate(&other).unwrap();
    assert_eq!(a.truth.len(), b.truth.len());
    for (x, y) in a.truth.iter().zip(&b.truth) {
        assert_eq!(x.disturbance_force, y.disturbance_force);
        assert!((x.north_m - y.north_m).hypot(x.east_m - y.east_m) < 1e-6);
    }
}

#[test]
fn open_loop_surge_speed_wander_is_the_first_order_response() {
    // Fixed shaft speeds, surge disturbance only: the craft runs dead straight
    // and its surge is the first-order system M11 u' = T + X_u u + X_d.
    let spec = DisturbanceSpec {
        sway_force_sigma_n: 0.0,
        yaw_moment_sigma_nm: 0.0,
        ..DisturbanceSpec::default()
    };
    let mut s = adrift(2500.0, spec);
    s.manual.as_mut().unwrap().commands[0].port_rpm = 700.0;
    s.manual.as_mut().unwrap().commands[0].starboard_rpm = 700.0;
    let run = simulate(&s).unwrap();
    assert!(run.truth.iter().all(|t| t.v_mps == 0.0 && t.r_radps == 0.0));
    let u: Vec<f64> = run
        .truth
        .iter()
        .filter(|t| t.elapsed_s >= 30.0)
        .map(|t| t.u_mps)
        .collect();

    // Theory: u' = -a u + f with a = |X_u| / M11 and f Gauss-Markov of
    // standard deviation F / M11 and correlation time T has the stationary
    // variance (F / M11)^2 / (a (a + 1 / T)) = q / (2 a (1 + a T)), with q the
    // equivalent white acceleration density (q / 2a in the white limit).
    let p = OtterParams::default();
    let m11 = p.mass_matrix_diagonal()[0];
    let a = -p.x_u_n_per_mps / m11;
    let tc = spec.correlation_s;
    let q = spec.otter_acceleration_density()[0];
    let sigma_a = spec.surge_force_sigma_n / m11;
    assert!((q - 2.0 * sigma_a * sigma_a * tc).abs() < 1e-15);
    let expected = (q / (2.0 * a * (1.0 + a * tc))).sqrt();
    assert!(
        (expected - sigma_a / (a * (a + 1.0 / tc)).sqrt()).abs() < 1e-12,
        "{expected}"
    );
    // About 0.031 m/s for the default 3 N.
    assert!((expected - 0.0311).abs() < 5e-4, "{expected}");
    let sd = std_dev(&u);
    assert!(
        (sd / expected - 1.0).abs() < 0.15,
        "speed sd {sd} vs first-order {expected}"
    );
    // The mean is the still-water steady speed 2 k n^2 / |X_u|.
    let n = 700.0 * std::f64::consts::TAU / 60.0;
    let steady = 2.0 * p.thrust_n(n) / -p.x_u_n_per_mps;
    assert!((mean(&u) - steady).abs() < 0.01, "{} vs {steady}", mean(&u));
}

#[test]
fn acceleration_density_of_the_default_for_the_otter() {
    let spec = DisturbanceSpec::default();
    let diag = OtterParams::default().mass_matrix_diagonal();
    assert_eq!(diag, [85.5, 162.5, 42.65]);
    let q = spec.acceleration_density(diag);
    assert_eq!(q, spec.otter_acceleration_density());
    let expected = [
        2.0 * (3.0f64 / 85.5).powi(2) * 2.0,
        2.0 * (4.0f64 / 162.5).powi(2) * 2.0,
        2.0 * (0.5f64 / 42.65).powi(2) * 2.0,
    ];
    for i in 0..3 {
        assert!((q[i] - expected[i]).abs() < 1e-15, "{i}: {}", q[i]);
    }
    // The documented values.
    assert!((q[0] - 4.92e-3).abs() < 1e-5 && (q[1] - 2.42e-3).abs() < 1e-5);
    assert!((q[2] - 5.50e-4).abs() < 1e-6);
    // Calm water: no process noise.
    assert_eq!(DisturbanceSpec::calm().acceleration_density(diag), [0.0; 3]);
    // With the full mass matrix: the diagonal approximation is exact for a
    // diagonal matrix; the Otter's sway-yaw coupling adds to the yaw density
    // (the sway force is applied off the CG).
    let m = OtterParams::default().mass_matrix;
    let diag_only = nalgebra::Matrix3::from_diagonal(&nalgebra::Vector3::from(diag));
    let exact_diag = spec.acceleration_density_matrix(&diag_only);
    for i in 0..3 {
        assert!((exact_diag[(i, i)] - q[i]).abs() < 1e-15);
    }
    let coupled = spec.acceleration_density_matrix(&m);
    assert!((coupled[(0, 0)] - q[0]).abs() < 1e-15);
    assert!((coupled[(1, 1)] / q[1] - 1.0).abs() < 0.06, "{coupled}");
    assert!(coupled[(2, 2)] > 1.2 * q[2], "{coupled}");
    assert!(coupled[(1, 2)] < 0.0 && coupled[(1, 2)] == coupled[(2, 1)]);
}

/// Position error, m, of `replay` against the truth sample of the same time.
fn replay_error_m(run: &SimRun, replay: &[twin_sim::TruthSample]) -> Vec<f64> {
    replay
        .iter()
        .map(|p| {
            let t = run
                .truth
                .iter()
                .find(|t| (t.elapsed_s - p.elapsed_s).abs() < 1e-9)
                .expect("a truth sample at each replayed instant");
            (p.north_m - t.north_m).hypot(p.east_m - t.east_m)
        })
        .collect()
}

/// The replay without disturbance follows the truth where there is none (the
/// commands held between truth samples instead of changing at the control
/// rate are all that differs), and leaves it where the harbour's disturbance
/// pushes the hull: what it measures is the disturbance's own effect.
#[test]
fn the_replay_without_disturbance_follows_the_truth_only_in_calm_water() {
    let mut harbour = shipped("s-manoeuvre_new-broken");
    assert!(harbour.disturbance.is_some());
    let mut still = harbour.clone();
    calm(&mut still);
    harbour.duration_s = 160.0;
    still.duration_s = 160.0;
    let worst = |sc: &Scenario| {
        let plan = sc.validate().unwrap();
        let run = twin_sim::run_plan(&plan);
        let from = run.truth.iter().position(|t| t.elapsed_s >= 100.0).unwrap();
        let commands: Vec<_> = run.commanded_propellers().copied().collect();
        let replay = twin_sim::replay_without_disturbance(&plan, &run.truth[from..], &commands);
        assert_eq!(replay.len(), run.truth.len() - from - 1);
        replay_error_m(&run, &replay)
            .into_iter()
            .fold(0.0f64, f64::max)
    };
    let (calm_m, harbour_m) = (worst(&still), worst(&harbour));
    println!("worst replay error over 60 s: calm {calm_m:.3} m, harbour {harbour_m:.3} m");
    assert!(calm_m < 0.5, "{calm_m}");
    assert!(harbour_m > 5.0 * calm_m.max(0.1), "{harbour_m}");
}
