//! The simulated sensors: determinism, noise statistics against the
//! configured sigmas, and the latency, lever-arm, SOG-scale and heading-offset
//! options doing what they say.

mod common;

use common::{
    calm, lag1_autocorrelation, local, mean, shipped, silence, std_dev, truth_at, truth_near,
};
use twin_core::geodesy::{angle_diff, wrap_pi};
use twin_sim::{LeverArm, ManualCommand, Scenario, SensorEvent, SimRun, simulate};

/// A long straight run at trial speed for statistics.
fn long_straight(duration_s: f64) -> Scenario {
    let mut s = shipped("straight_original-original");
    s.duration_s = duration_s;
    s
}

/// Pairs each GNSS fix with the truth at the instant it describes.
fn fixes_with_truth(
    run: &SimRun,
    latency_s: f64,
) -> Vec<(twin_core::sample::GnssFix, twin_sim::TruthSample)> {
    run.gnss_fixes()
        .map(|f| (*f, *truth_at(run, f.time_s - run.start_unix_s + latency_s)))
        .collect()
}

#[test]
fn same_seed_same_output_other_seed_other_noise() {
    let s = shipped("s-manoeuvre_new-broken");
    let a = simulate(&s).unwrap();
    let b = simulate(&s).unwrap();
    assert_eq!(a, b);
    let mut other = s.clone();
    other.seed += 1;
    let c = simulate(&other).unwrap();
    let differing = a
        .gnss_fixes()
        .zip(c.gnss_fixes())
        .filter(|(x, y)| x.position != y.position)
        .count();
    assert_eq!(differing, a.gnss_fixes().count());
    // The disturbance is seeded too, so the truth differs...
    assert!(
        a.truth
            .iter()
            .zip(&c.truth)
            .all(|(x, y)| x.disturbance_force != y.disturbance_force)
    );
    // ...but in calm water it does not (the autopilot sees the truth).
    let (mut calm_a, mut calm_c) = (s.clone(), other.clone());
    calm(&mut calm_a);
    calm(&mut calm_c);
    assert_eq!(
        simulate(&calm_a).unwrap().truth,
        simulate(&calm_c).unwrap().truth
    );
    // Switching the heading sensor on leaves the GNSS noise as it was.
    let mut with_heading = s.clone();
    with_heading.sensors.heading.enabled = true;
    let d = simulate(&with_heading).unwrap();
    assert!(a.gnss_fixes().eq(d.gnss_fixes()));
    assert_eq!(d.headings().count(), 601);
}

#[test]
fn events_are_in_time_order_at_their_rates() {
    let run = simulate(&shipped("straight_new-broken")).unwrap();
    assert!(
        run.events
            .windows(2)
            .all(|w| w[0].time_s() <= w[1].time_s())
    );
    // 60 s at 5 Hz and at 10 Hz, both ends included.
    assert_eq!(run.gnss_fixes().count(), 301);
    assert_eq!(run.measured_propellers().count(), 601);
    assert_eq!(run.commanded_propellers().count(), 601);
    assert_eq!(run.truth.len(), 301);
    let first = run.gnss_fixes().next().unwrap();
    assert_eq!(first.time_s, run.start_unix_s);
    assert_eq!(run.start_unix_s, 1_653_040_800.0 + 30.0 * 60.0);
}

#[test]
fn gnss_noise_matches_the_configured_sigmas() {
    let run = simulate(&long_straight(400.0)).unwrap();
    let pairs = fixes_with_truth(&run, 0.0);
    let (mut dn, mut de, mut dsog, mut dcog) = (vec![], vec![], vec![], vec![]);
    for (fix, truth) in &pairs {
        let p = local(&run, fix.position);
        dn.push(p.north_m - truth.north_m);
        de.push(p.east_m - truth.east_m);
        dsog.push(fix.sog_mps.unwrap() - truth.sog_mps);
        dcog.push(angle_diff(fix.cog_rad.unwrap(), truth.cog_rad));
    }
    assert_eq!(pairs.len(), 2001);
    // 2001 samples: the standard deviation is known to about 1.6 %.
    for (name, xs, sigma) in [
        ("north", &dn, 0.3),
        ("east", &de, 0.3),
        ("sog", &dsog, 0.05),
        ("cog", &dcog, 0.05 / 1.5),
    ] {
        let sd = std_dev(xs);
        assert!(
            (sd / sigma - 1.0).abs() < 0.07,
            "{name}: sd {sd} vs {sigma}"
        );
        assert!(
            mean(xs).abs() < 4.0 * sigma / (xs.len() as f64).sqrt(),
            "{name} biased"
        );
        assert!(
            lag1_autocorrelation(xs).abs() < 0.1,
            "{name} should be white"
        );
    }
}

#[test]
fn correlated_position_noise_keeps_its_sigma() {
    let mut s = long_straight(1200.0);
    s.sensors.gnss.position_correlation_s = 5.0;
    let run = simulate(&s).unwrap();
    let dn: Vec<f64> = fixes_with_truth(&run, 0.0)
        .iter()
        .map(|(f, t)| local(&run, f.position).north_m - t.north_m)
        .collect();
    // Gauss-Markov: lag-1 correlation exp(-0.2 / 5) = 0.961.
    let rho = lag1_autocorrelation(&dn);
    assert!((rho - (-0.2f64 / 5.0).exp()).abs() < 0.015, "{rho}");
    // Only about 120 independent samples: a looser bound on sigma.
    let sd = std_dev(&dn);
    assert!((sd / 0.3 - 1.0).abs() < 0.2, "{sd}");
}

#[test]
fn heading_and_propeller_noise_match_the_configured_sigmas() {
    let mut s = long_straight(300.0);
    s.sensors.heading.enabled = true;
    s.sensors.heading.sigma_deg = 0.8;
    s.sensors.heading.offset_deg = 2.5;
    s.sensors.propellers.sigma_rpm = 3.0;
    let run = simulate(&s).unwrap();
    let dh: Vec<f64> = run
        .headings()
        .map(|h| {
            let t = truth_at(&run, h.time_s - run.start_unix_s);
            wrap_pi(h.heading_rad - t.heading_rad).to_degrees()
        })
        .collect();
    assert!((std_dev(&dh) / 0.8 - 1.0).abs() < 0.08, "{}", std_dev(&dh));
    assert!((mean(&dh) - 2.5).abs() < 0.1, "offset {}", mean(&dh));
    // Propeller noise: measured minus actual, at the truth instants.
    let dp: Vec<f64> = run
        .measured_propellers()
        .filter_map(|p| {
            let elapsed = p.time_s - run.start_unix_s;
            run.truth
                .iter()
                .find(|t| (t.elapsed_s - elapsed).abs() < 1e-6)
                .map(|t| twin_sim::radps_to_rpm(p.port_radps - t.shaft_radps[0]))
        })
        .collect();
    assert_eq!(dp.len(), 1501);
    assert!((std_dev(&dp) / 3.0 - 1.0).abs() < 0.08, "{}", std_dev(&dp));
}

#[test]
fn latency_stamps_each_fix_earlier_than_the_state_it_describes() {
    for latency_s in [0.35, -0.5] {
        let mut s = shipped("s-manoeuvre_new-broken");
        silence(&mut s);
        s.sensors.gnss.latency_s = latency_s;
        let run = simulate(&s).unwrap();
        let pairs = fixes_with_truth(&run, latency_s);
        assert_eq!(pairs.len(), 601);
        for (fix, truth) in &pairs {
            let p = local(&run, fix.position);
            assert!((p.north_m - truth.north_m).abs() < 1e-6);
            assert!((p.east_m - truth.east_m).abs() < 1e-6);
            assert!((fix.sog_mps.unwrap() - truth.sog_mps).abs() < 1e-12);
        }
        let first = run.gnss_fixes().next().unwrap();
        assert!((first.time_s - (run.start_unix_s - latency_s)).abs() < 1e-6);
    }
}

#[test]
fn lever_arm_moves_the_reported_position_and_velocity_with_the_hull() {
    let mut s = shipped("s-manoeuvre_new-broken");
    silence(&mut s);
    s.sensors.gnss.lever_arm = LeverArm {
        x_m: 0.6,
        y_m: -0.3,
    };
    let run = simulate(&s).unwrap();
    let mut sog_gap: f64 = 0.0;
    for (fix, t) in fixes_with_truth(&run, 0.0) {
        let p = local(&run, fix.position);
        let (sn, cs) = t.heading_rad.sin_cos();
        // Body (0.6, -0.3) rotated by the heading.
        let expected = [0.6 * cs + 0.3 * sn, 0.6 * sn - 0.3 * cs];
        assert!((p.north_m - t.north_m - expected[0]).abs() < 1e-6);
        assert!((p.east_m - t.east_m - expected[1]).abs() < 1e-6);
        // The antenna's velocity: body [u - r y, v + r x].
        let (bu, bv) = (t.u_mps + 0.3 * t.r_radps, t.v_mps + 0.6 * t.r_radps);
        assert!((fix.sog_mps.unwrap() - bu.hypot(bv)).abs() < 1e-9);
        sog_gap = sog_gap.max((fix.sog_mps.unwrap() - t.sog_mps).abs());
    }
    // In the turns the antenna's speed differs from the origin's.
    assert!(sog_gap > 0.02, "{sog_gap}");
}

/// A rate gyro reads `scale x true + bias`, exactly without noise.
#[test]
fn a_rate_gyro_reads_its_scale_and_bias() {
    let mut s = Scenario::manual_mode(
        "turning",
        30.0,
        vec![ManualCommand {
            time_s: 2.0,
            port_rpm: 900.0,
            starboard_rpm: 300.0,
        }],
    );
    silence(&mut s);
    s.sensors.yaw_rate.enabled = true;
    s.sensors.yaw_rate.sigma_deg_s = 0.0;
    s.sensors.yaw_rate.scale = 0.95;
    s.sensors.yaw_rate.bias_deg_s = 0.1;
    let run = simulate(&s).unwrap();
    let mut turning = 0;
    for e in &run.events {
        let SensorEvent::YawRate(y) = e else { continue };
        // At the truth's instants.
        let Some(t) = truth_near(&run, y.time_s - run.start_unix_s) else {
            continue;
        };
        let want = 0.95 * t.r_radps + 0.1f64.to_radians();
        assert!((y.yaw_rate_radps - want).abs() < 1e-12, "{y:?} {t:?}");
        turning += usize::from(t.r_radps.abs() > 0.1);
    }
    assert!(turning > 50, "the hull turns: {turning} samples");
    s.sensors.yaw_rate.scale = 0.0;
    assert!(simulate(&s).is_err(), "a scale must be positive");
}

#[test]
fn sog_scale_and_cog_cut_off() {
    let mut s = Scenario::manual_mode(
        "start",
        30.0,
        vec![ManualCommand {
            time_s: 5.0,
            port_rpm: 600.0,
            starboard_rpm: 600.0,
        }],
    );
    silence(&mut s);
    s.sensors.gnss.sog_scale = 1.04;
    let run = simulate(&s).unwrap();
    for (fix, t) in fixes_with_truth(&run, 0.0) {
        assert!((fix.sog_mps.unwrap() - 1.04 * t.sog_mps).abs() < 1e-12);
        // COG is withheld while the craft is (nearly) stopped.
        assert_eq!(fix.cog_rad.is_some(), t.sog_mps >= 0.2, "{t:?}");
    }
    assert!(run.gnss_fixes().any(|f| f.cog_rad.is_none()));
    assert!(run.gnss_fixes().any(|f| f.cog_rad.is_some()));
    assert!(
        run.events
            .iter()
            .all(|e| !matches!(e, SensorEvent::Heading(_)))
    );
}
