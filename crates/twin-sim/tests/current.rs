//! Water current: it separates course from heading and speed over ground
//! from speed through the water, by exactly the current.

mod common;

use common::{northward, truth_at};
use twin_sim::{CurrentSpec, simulate};

fn current(speed_mps: f64, toward_deg: f64) -> CurrentSpec {
    CurrentSpec {
        speed_mps,
        toward_deg,
        rotation_deg_s: 0.0,
        speed_amplitude_mps: 0.0,
        speed_period_s: 600.0,
    }
}

#[test]
fn cross_current_makes_the_craft_crab() {
    let mut s = northward(150.0, 1.5, 500.0);
    s.current = Some(current(0.5, 90.0));
    s.control.ilos_gain = 0.4;
    let run = simulate(&s).unwrap();
    let end = run.truth.last().unwrap();
    // Over ground it goes up the line...
    assert!(
        end.cog_rad
            .to_degrees()
            .min(360.0 - end.cog_rad.to_degrees())
            < 0.05
    );
    assert!(end.cross_track_m.unwrap().abs() < 0.01);
    assert!((end.sog_mps - 1.5).abs() < 0.005);
    // ...heading into the current by the crab angle atan(V_c / SOG),
    let crab_deg = (0.5f64 / 1.5).atan().to_degrees();
    let heading_deg = end.heading_rad.to_degrees() - 360.0;
    assert!(
        (heading_deg + crab_deg).abs() < 0.1,
        "{heading_deg} vs -{crab_deg}"
    );
    // through the water at sqrt(SOG^2 + V_c^2), with no sideslip in the water.
    assert!((end.speed_through_water_mps() - 1.5f64.hypot(0.5)).abs() < 0.005);
    assert!(end.v_water_mps.abs() < 1e-3);
    // Ground velocity = water velocity + current, at every sample.
    for t in &run.truth {
        let (s, c) = t.heading_rad.sin_cos();
        let water = [
            c * t.u_water_mps - s * t.v_water_mps,
            s * t.u_water_mps + c * t.v_water_mps,
        ];
        let ground = [t.sog_mps * t.cog_rad.cos(), t.sog_mps * t.cog_rad.sin()];
        for i in 0..2 {
            assert!((ground[i] - water[i] - t.current_ned_mps[i]).abs() < 1e-9);
        }
    }
}

#[test]
fn plain_los_leaves_the_cross_track_offset_of_its_lookahead() {
    // Without the integral, LOS holds the crab angle atan(e / Delta), so the
    // craft settles downstream of the line by Delta V_c / SOG.
    let mut s = northward(120.0, 1.5, 500.0);
    s.current = Some(current(0.5, 90.0));
    s.control.ilos_gain = 0.0;
    let run = simulate(&s).unwrap();
    let expected_m = s.control.lookahead_m * 0.5 / 1.5;
    let end = run.truth.last().unwrap();
    assert!(
        (end.cross_track_m.unwrap() - expected_m).abs() < 0.02,
        "{:?}",
        end.cross_track_m
    );
}

#[test]
fn following_current_adds_to_the_speed_through_water() {
    let mut s = northward(60.0, 1.5, 500.0);
    s.current = Some(current(0.3, 0.0));
    let run = simulate(&s).unwrap();
    let end = truth_at(&run, 60.0);
    assert!((end.sog_mps - 1.5).abs() < 0.005);
    assert!((end.sog_mps - end.speed_through_water_mps() - 0.3).abs() < 1e-3);
    assert!(end.heading_rad.min(std::f64::consts::TAU - end.heading_rad) < 1e-4);
    // Less water speed, less thrust: the shafts turn slower than in still water.
    let still = simulate(&northward(60.0, 1.5, 500.0)).unwrap();
    assert!(end.shaft_radps[0] < truth_at(&still, 60.0).shaft_radps[0] * 0.92);
}

#[test]
fn slowly_varying_current_turns_and_pulses_as_configured() {
    let mut s = northward(100.0, 1.5, 500.0);
    s.current = Some(CurrentSpec {
        speed_mps: 0.4,
        toward_deg: 45.0,
        rotation_deg_s: 0.5,
        speed_amplitude_mps: 0.1,
        speed_period_s: 200.0,
    });
    s.control.ilos_gain = 0.4;
    let run = simulate(&s).unwrap();
    for t in run.truth.iter().step_by(50) {
        let [n, e] = t.current_ned_mps;
        let dir = e.atan2(n).to_degrees().rem_euclid(360.0);
        let expected_dir = (45.0 + 0.5 * t.elapsed_s).rem_euclid(360.0);
        let speed = 0.4 + 0.1 * (std::f64::consts::TAU * t.elapsed_s / 200.0).sin();
        assert!((dir - expected_dir).abs() < 1e-9, "{dir} vs {expected_dir}");
        assert!((n.hypot(e) - speed).abs() < 1e-12);
    }
    // The autopilot copes: still on the line at the end.
    assert!(run.truth.last().unwrap().cross_track_m.unwrap().abs() < 0.5);
}
