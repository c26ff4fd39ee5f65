//! The way-point autopilot: it tracks the seed's paths, passes the
//! way-points, and makes up for a weak propeller with more rpm on that side,
//! so the track hardly shows the loss (which is why the twin must read the
//! propeller speeds).

mod common;

use common::{calm, mean, shipped, truth_at, truth_mean};
use twin_sim::{InitialSpec, Scenario, Waypoint, simulate};

#[test]
fn controller_needs_more_port_rpm_for_a_port_loss() {
    let calm_water = |stem: &str| {
        let mut s = shipped(stem);
        calm(&mut s);
        simulate(&s).unwrap()
    };
    let healthy = calm_water("straight_original-original");
    let broken = calm_water("straight_new-broken");
    let ratio = |run: &twin_sim::SimRun| {
        let port: Vec<f64> = run
            .measured_propellers()
            .filter(|p| p.time_s - run.start_unix_s > 20.0)
            .map(|p| p.port_radps)
            .collect();
        let stb: Vec<f64> = run
            .measured_propellers()
            .filter(|p| p.time_s - run.start_unix_s > 20.0)
            .map(|p| p.starboard_radps)
            .collect();
        mean(&port) / mean(&stb)
    };
    // On a straight course the yaw moments balance when (1 - loss) T_p = T_s,
    // so n_p / n_s = 1 / sqrt(1 - loss).
    let expected = 1.0 / (1.0f64 - 0.18).sqrt();
    assert!(
        (ratio(&broken) - expected).abs() < 0.005,
        "{}",
        ratio(&broken)
    );
    assert!((ratio(&healthy) - 1.0).abs() < 0.002, "{}", ratio(&healthy));
    // The speed is held all the same.
    let sog = truth_mean(&broken, 20.0, |t| t.sog_mps);
    assert!((sog - 1.5).abs() < 0.005, "{sog}");
    // In the shipped files' harbour disturbance the balance holds on average
    // (the random yaw moment shifts the 40 s mean a little).
    let disturbed = simulate(&shipped("straight_new-broken")).unwrap();
    assert!(
        (ratio(&disturbed) - expected).abs() < 0.02,
        "{}",
        ratio(&disturbed)
    );
    let sog = truth_mean(&disturbed, 20.0, |t| t.sog_mps);
    assert!((sog - 1.5).abs() < 0.02, "{sog}");
}

#[test]
fn straight_line_cross_track_error_settles() {
    for (port_loss, disturbed) in [(0.0, false), (0.18, false), (0.0, true), (0.18, true)] {
        let mut s = shipped("straight_new-broken");
        if !disturbed {
            calm(&mut s);
        }
        s.propellers.port.loss = port_loss;
        // Start 10 m to starboard of the line (bearing 060) heading 030.
        s.initial = Some(InitialSpec {
            north_m: Some(-8.66),
            east_m: Some(5.0),
            heading_deg: Some(30.0),
            speed_mps: None,
        });
        let run = simulate(&s).unwrap();
        assert!((truth_at(&run, 0.0).cross_track_m.unwrap() - 10.0).abs() < 0.01);
        let worst_after = |from_s: f64| {
            run.truth
                .iter()
                .filter(|t| t.elapsed_s >= from_s)
                .map(|t| t.cross_track_m.unwrap().abs())
                .fold(0.0, f64::max)
        };
        if disturbed {
            // The harbour disturbance keeps it wandering by decimetres.
            assert!(
                worst_after(30.0) < 0.3,
                "loss {port_loss}, disturbed: {}",
                worst_after(30.0)
            );
        } else {
            assert!(
                worst_after(30.0) < 0.05,
                "loss {port_loss}: {}",
                worst_after(30.0)
            );
            assert!(
                worst_after(45.0) < 0.01,
                "loss {port_loss}: {}",
                worst_after(45.0)
            );
        }
        // Overshoot on the way in stays small.
        assert!(
            worst_after(15.0) < 1.0,
            "loss {port_loss}: {}",
            worst_after(15.0)
        );
    }
}

#[test]
fn s_manoeuvre_passes_its_waypoints() {
    for stem in ["s-manoeuvre_original-original", "s-manoeuvre_new-broken"] {
        let s = shipped(stem);
        let n_wp = s.path.as_ref().unwrap().waypoints.len();
        let run = simulate(&s).unwrap();
        let indices: Vec<usize> = run.waypoint_passes.iter().map(|p| p.index).collect();
        assert_eq!(indices, (1..n_wp).collect::<Vec<_>>(), "{stem}");
        for p in &run.waypoint_passes {
            assert!(p.within_acceptance && p.distance_m <= 5.0, "{stem}: {p:?}");
        }
        assert!(run.waypoint_passes.last().unwrap().elapsed_s < 115.0);
        // Two opposite turns: to starboard first, then to port, each near 180 deg.
        let r_max = run.truth.iter().map(|t| t.r_radps).fold(f64::MIN, f64::max);
        let r_min = run.truth.iter().map(|t| t.r_radps).fold(f64::MAX, f64::min);
        assert!(
            r_max > 3f64.to_radians() && r_min < -3f64.to_radians(),
            "{stem}"
        );
        let first_positive = run.truth.iter().position(|t| t.r_radps > 0.05).unwrap();
        let first_negative = run.truth.iter().position(|t| t.r_radps < -0.05).unwrap();
        assert!(first_positive < first_negative);
        let mid = truth_at(&run, 57.0).heading_rad.to_degrees();
        assert!(
            (mid - 180.0).abs() < 25.0,
            "{stem}: heading {mid} at the S's middle"
        );
        // On the arcs (radius 20 m) the craft turns on about that radius.
        let arc: Vec<f64> = run
            .truth
            .iter()
            .filter(|t| t.leg.is_some_and(|l| (2..=6).contains(&l)))
            .map(|t| t.sog_mps / t.r_radps)
            .collect();
        let mean_radius_m = arc.len() as f64 / arc.iter().map(|r| 1.0 / r).sum::<f64>();
        assert!(
            (mean_radius_m - 20.0).abs() < 3.0,
            "{stem}: {mean_radius_m} m"
        );
    }
}

#[test]
fn closed_loop_hides_a_port_loss_from_the_track_but_not_from_the_rpm() {
    let healthy = simulate(&shipped("s-manoeuvre_original-original")).unwrap();
    let mut lossy_scenario = shipped("s-manoeuvre_original-original");
    lossy_scenario.propellers.port.loss = 0.18;
    let lossy = simulate(&lossy_scenario).unwrap();
    let worst_m = healthy
        .truth
        .iter()
        .zip(&lossy.truth)
        .map(|(a, b)| (a.north_m - b.north_m).hypot(a.east_m - b.east_m))
        .fold(0.0, f64::max);
    // The autopilot keeps the track within half a metre of the healthy one
    // (GNSS noise is 0.3 m per axis)...
    assert!(worst_m > 0.05 && worst_m < 0.5, "{worst_m} m");
    // ...by turning the weak propeller about 10 % faster.
    let rpm_ratio = truth_mean(&lossy, 10.0, |t| t.shaft_radps[0])
        / truth_mean(&healthy, 10.0, |t| t.shaft_radps[0]);
    assert!(rpm_ratio > 1.08, "{rpm_ratio}");
}

#[test]
fn heading_autopilot_stabilises_the_directionally_unstable_hull() {
    // A 90 deg course change: the reference model turns at its rate limit,
    // and the craft settles on the new course without oscillating.
    let s = Scenario::waypoint_mode(
        "corner",
        60.0,
        1.5,
        vec![
            Waypoint::north_east(0.0, 0.0),
            Waypoint::north_east(20.0, 0.0),
            Waypoint::north_east(20.0, 100.0),
        ],
    );
    let run = simulate(&s).unwrap();
    let limit = s.control.max_turn_rate_deg_s.to_radians();
    let r_peak = run
        .truth
        .iter()
        .map(|t| t.r_radps.abs())
        .fold(0.0, f64::max);
    assert!(r_peak < 1.15 * limit, "{} deg/s", r_peak.to_degrees());
    let end = run.truth.last().unwrap();
    assert!((end.heading_rad.to_degrees() - 90.0).abs() < 0.1);
    assert!(end.r_radps.abs() < 1e-3);
}
