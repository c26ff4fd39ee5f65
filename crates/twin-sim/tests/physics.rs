//! The simulated Otter against what is known of the real one: top speed,
//! bollard thrust, shaft lag, turning, the effect of a propeller loss without
//! an autopilot, wind drift, and the integrator's accuracy.

mod common;

use common::{shipped, silence, truth_at};
use twin_sim::{InitialSpec, ManualCommand, Scenario, WindSpec, simulate};

fn manual(duration_s: f64, port_rpm: f64, starboard_rpm: f64) -> Scenario {
    Scenario::manual_mode(
        "manual",
        duration_s,
        vec![ManualCommand {
            time_s: 0.0,
            port_rpm,
            starboard_rpm,
        }],
    )
}

#[test]
fn top_speed_at_full_shaft_speed_is_the_otters_u_max() {
    // X_u was calibrated so that 2 x 119.7 N holds U_max = 6 kn = 3.09 m/s.
    let run = simulate(&manual(80.0, 1000.0, 1000.0)).unwrap();
    let end = run.truth.last().unwrap();
    assert!(
        (end.sog_mps - 3.09).abs() < 0.02 * 3.09,
        "top speed {} m/s",
        end.sog_mps
    );
    assert!(end.r_radps.abs() < 1e-9 && end.v_mps.abs() < 1e-9);
    // The 1000 rpm command saturates at n_max = 103.9 rad/s (992 rpm), where
    // each propeller gives its bollard thrust of about 119.7 N.
    for i in 0..2 {
        assert!(
            (end.shaft_radps[i] - 103.9).abs() < 1e-6,
            "{:?}",
            end.shaft_radps
        );
        assert!((end.thrust_n[i] - 119.7).abs() < 0.5, "{:?}", end.thrust_n);
    }
}

#[test]
fn shaft_speed_lags_a_step_command_by_one_time_constant() {
    let mut s = Scenario::manual_mode(
        "step",
        2.0,
        vec![ManualCommand {
            time_s: 1.0,
            port_rpm: 600.0,
            starboard_rpm: -300.0,
        }],
    );
    silence(&mut s);
    let run = simulate(&s).unwrap();
    let at = |elapsed: f64| {
        run.measured_propellers()
            .find(|p| (p.time_s - run.start_unix_s - elapsed).abs() < 1e-6)
            .copied()
            .unwrap()
    };
    let rpm = twin_sim::radps_to_rpm;
    assert_eq!(rpm(at(1.0).port_radps), 0.0);
    // One time constant (0.1 s) after the step: 1 - 1/e of the way.
    let frac = 1.0 - (-1.0f64).exp();
    assert!(
        (rpm(at(1.1).port_radps) - 600.0 * frac).abs() < 0.05,
        "{}",
        rpm(at(1.1).port_radps)
    );
    assert!((rpm(at(1.1).starboard_radps) + 300.0 * frac).abs() < 0.05);
    let frac5 = 1.0 - (-5.0f64).exp();
    assert!((rpm(at(1.5).port_radps) - 600.0 * frac5).abs() < 0.05);
    // The command itself is reported without lag.
    let cmd = run
        .commanded_propellers()
        .find(|p| (p.time_s - run.start_unix_s - 1.0).abs() < 1e-6)
        .unwrap();
    assert!((rpm(cmd.port_radps) - 600.0).abs() < 1e-9);
}

#[test]
fn port_loss_turns_the_uncontrolled_craft_to_port() {
    let mut healthy = manual(20.0, 700.0, 700.0);
    healthy.initial = Some(InitialSpec {
        speed_mps: Some(1.5),
        ..InitialSpec::default()
    });
    let mut lossy = healthy.clone();
    lossy.propellers.port.loss = 0.18;
    lossy.propellers.port.onset_s = 5.0;
    let a = simulate(&healthy).unwrap();
    let b = simulate(&lossy).unwrap();
    // Before the onset the two are the same craft.
    assert_eq!(truth_at(&a, 5.0).north_m, truth_at(&b, 5.0).north_m);
    // Healthy and symmetric: dead straight.
    for t in &a.truth {
        assert!(t.r_radps.abs() < 1e-12 && t.east_m.abs() < 1e-9);
    }
    // Port weak: the starboard propeller pushes the bow to port (r < 0).
    let later = truth_at(&b, 8.0);
    assert!(later.r_radps < -0.01, "r = {}", later.r_radps);
    assert!(
        truth_at(&b, 10.0).east_m < -0.2,
        "{}",
        truth_at(&b, 10.0).east_m
    );
    assert!(b.truth.iter().all(|t| t.r_radps <= 1e-12));
}

#[test]
fn tightest_turn_at_trial_speed_is_a_few_metres() {
    // Full port shaft speed, starboard chosen (by bisection) so the steady
    // speed over ground is the trials' 1.5 m/s: the tightest steady turn to
    // starboard at that speed.
    let steady = |stb_rpm: f64| {
        let mut s = manual(60.0, 1000.0, stb_rpm);
        s.initial = Some(InitialSpec {
            speed_mps: Some(1.5),
            ..InitialSpec::default()
        });
        let run = simulate(&s).unwrap();
        let end = *run.truth.last().unwrap();
        (end.sog_mps, end.r_radps)
    };
    let (mut lo, mut hi) = (-600.0, 600.0);
    for _ in 0..30 {
        let mid = 0.5 * (lo + hi);
        if steady(mid).0 < 1.5 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let (sog, r) = steady(0.5 * (lo + hi));
    let radius_m = sog / r;
    assert!((sog - 1.5).abs() < 0.01);
    assert!(r > 0.0, "full port thrust turns to starboard");
    // About 2.5 hull lengths: tighter than the S-manoeuvre's 20 m arcs.
    assert!((3.0..8.0).contains(&radius_m), "radius {radius_m} m");
}

#[test]
fn a_head_wind_drives_the_craft_astern_until_water_drag_balances_it() {
    let mut s = manual(120.0, 0.0, 0.0);
    s.wind = Some(WindSpec {
        speed_mps: 10.0,
        from_deg: 0.0,
        frontal_area_m2: 0.3,
        lateral_area_m2: 0.5,
        c_x: 0.6,
        c_y: 0.8,
        c_n: 0.08,
        air_density_kgpm3: 1.225,
    });
    let run = simulate(&s).unwrap();
    let end = run.truth.last().unwrap();
    // Balance: c_x 1/2 rho_air (10 + u)^2 A_front = -X_u (-u), u < 0.
    let k = 0.6 * 0.5 * 1.225 * 0.3;
    let mut u: f64 = 0.0;
    for _ in 0..50 {
        u = -k * (10.0 + u).powi(2) / 77.55;
    }
    assert!(
        (end.u_mps - u).abs() < 1e-3 * u.abs() + 1e-6,
        "{} vs {u}",
        end.u_mps
    );
    assert!(end.north_m < 0.0 && end.heading_rad == 0.0);
}

#[test]
fn halving_the_step_changes_the_trajectory_negligibly() {
    let base = shipped("s-manoeuvre_new-broken");
    let mut half = base.clone();
    half.step_s = base.step_s / 2.0;
    let a = simulate(&base).unwrap();
    let b = simulate(&half).unwrap();
    assert_eq!(a.truth.len(), b.truth.len());
    let worst_m = a
        .truth
        .iter()
        .zip(&b.truth)
        .map(|(x, y)| (x.north_m - y.north_m).hypot(x.east_m - y.east_m))
        .fold(0.0, f64::max);
    // RK4's error falls as h^4: at 0.01 s it is far below a millimetre.
    assert!(worst_m < 1e-6, "{worst_m} m");
    // And the samples are at the same instants whatever the step.
    assert_eq!(a.truth[123].elapsed_s, b.truth[123].elapsed_s);
}
