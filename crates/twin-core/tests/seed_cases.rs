//! The seed's simulation cases (docs/model.md section 7, thesis section 4.1)
//! reproduced with the seed's kinematic model and the adaptive EKF.
//!
//! The truth here is the seed's own kinematic model, integrated exactly as the
//! seed did (the richer Otter simulator is the truth of later tests); what these
//! tests hold is the filter's recursion, its tuning as a time constant, and its
//! anti-windup.

use nalgebra::{SMatrix, SVector, Vector2, Vector4};
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, Normal};
use twin_core::aekf::{
    Aekf, AekfConfig, AekfState, GainSensitivity, MeasurementNoiseForm, NoiseAdaptation,
};
use twin_core::geodesy::wrap_pi;
use twin_core::model::Measurement;
use twin_core::models::kinematic::{KinematicInput, KinematicModel};

/// The seed's tuning at sample interval `dt_s`: lambda = 0.995 per step,
/// Q = 0.01 I per step, R = 0.04 I, S(0) = 0.1 I.
fn seed_config(dt_s: f64) -> AekfConfig<4, 4, 2> {
    AekfConfig {
        process_noise_density: SMatrix::identity() * (0.01 / dt_s),
        measurement_noise: SMatrix::identity() * 0.04,
        forgetting_time_constant_s: -dt_s / 0.995_f64.ln(),
        fault_memory_factor: SVector::repeat(1.0),
        initial_fault_covariance: SMatrix::identity() * 0.1,
        anti_windup_ratio: 0.1,
        excitation_sigma: 0.02,
        noise_adaptation: None,
        gain_sensitivity: GainSensitivity::Omitted,
        gain_sensitivity_faults: [true; _],
    }
}

/// One truth step of the seed's model with the true faults (noise-free).
fn truth_step(x: &Vector4<f64>, u: Vector2<f64>, theta: Vector2<f64>, dt: f64) -> Vector4<f64> {
    Vector4::new(
        x[0] + dt * x[2] * x[3].cos(),
        x[1] + dt * x[2] * x[3].sin(),
        x[2] + dt * (1.0 - theta[0]) * u[0],
        wrap_pi(x[3] + dt * (1.0 - theta[1]) * u[1]),
    )
}

struct Run {
    time_s: Vec<f64>,
    theta: Vec<Vector2<f64>>,
    s_trace: Vec<f64>,
    nis: Vec<f64>,
    excited: Vec<[bool; 2]>,
    sigma: Vec<Vector2<f64>>,
}

/// Runs truth and filter together: `input(t)` and `fault(t)` give the input
/// and the true faults over [t, t+dt); `noise` the measurement noise sigmas.
fn run(
    dt: f64,
    duration_s: f64,
    config: AekfConfig<4, 4, 2>,
    x0: Vector4<f64>,
    input: impl Fn(f64) -> Vector2<f64>,
    fault: impl Fn(f64) -> Vector2<f64>,
    noise: Option<(Vector4<f64>, u64)>,
) -> Run {
    let filter = Aekf::new(KinematicModel, config).unwrap();
    // Initialised as a live twin is: from the first measurement, with its noise
    // as the initial uncertainty (the seed's P0 = I where noise is absent).
    let p0 = if noise.is_some() {
        config.measurement_noise
    } else {
        SMatrix::identity()
    };
    let mut est = AekfState::new(&config, x0, p0, Vector2::zeros());
    let mut truth = x0;
    let steps = (duration_s / dt).round() as usize;
    let mut rng = StdRng::seed_from_u64(noise.map(|n| n.1).unwrap_or(0));
    let std_normal = Normal::new(0.0, 1.0).unwrap();
    let mut out = Run {
        time_s: vec![],
        theta: vec![],
        s_trace: vec![],
        nis: vec![],
        excited: vec![],
        sigma: vec![],
    };
    for k in 0..steps {
        let t = k as f64 * dt;
        let u = input(t);
        truth = truth_step(&truth, u, fault(t), dt);
        let mut y = truth;
        if let Some((sig, _)) = noise {
            for i in 0..4 {
                y[i] += sig[i] * std_normal.sample(&mut rng);
            }
            y[3] = wrap_pi(y[3]);
        }
        let ki = KinematicInput {
            accel_mps2: u[0],
            course_rate_radps: u[1],
        };
        let rep = filter
            .step(&mut est, &ki, &Measurement::full(y), dt)
            .unwrap();
        out.time_s.push(t + dt);
        out.theta.push(est.theta);
        out.s_trace.push(est.s.trace());
        out.nis.push(rep.nis);
        out.excited.push(est.excited(config.excitation_sigma));
        out.sigma.push(est.fault_sigma());
    }
    out
}

fn case1_input(t: f64) -> Vector2<f64> {
    if t < 10.0 {
        Vector2::new(1.0, 1.0)
    } else if t < 15.0 {
        Vector2::new(2.0, 0.5)
    } else {
        Vector2::new(-0.5, 0.4)
    }
}

/// First time after which the estimate stays within `tol` of `target` for the
/// rest of `[from, until)`.
fn settled_at(r: &Run, target: Vector2<f64>, tol: f64, from: f64, until: f64) -> Option<f64> {
    let mut last_bad = from;
    for (t, th) in r.time_s.iter().zip(&r.theta) {
        if *t < from || *t >= until {
            continue;
        }
        if (th - target).amax() > tol {
            last_bad = *t;
        }
    }
    (last_bad < until - 1e-9).then_some(last_bad)
}

/// An S-manoeuvre-like input, 120 s, repeated (as the thesis repeated its
/// 120 s of real input to fill 240 s): accelerate to about 1.6 m/s, two
/// opposite turns with the speed dipping in each, decelerate.
fn s_manoeuvre_input(t: f64) -> Vector2<f64> {
    s_manoeuvre_smooth(t) + derived_input_ripple(t)
}

/// The band-limited ripple that inputs derived from 5 Hz GNSS by differencing
/// and a 1 Hz low-pass carry (thesis Fig. 4.6): a deterministic sum of
/// sinusoids between 0.05 and 1 Hz, about 0.1 m/s^2 and 0.02 rad/s RMS.
fn derived_input_ripple(t: f64) -> Vector2<f64> {
    let tau = std::f64::consts::TAU;
    let mut a = 0.0;
    let mut r = 0.0;
    for k in 1..=12 {
        let f = 0.05 + 0.08 * k as f64;
        let k = k as f64;
        a += (0.1 / 12f64.sqrt() * 2f64.sqrt()) * (tau * f * t + 1.7 * k * k).sin();
        r += (0.02 / 12f64.sqrt() * 2f64.sqrt()) * (tau * f * t + 0.9 * k * k + 1.0).sin();
    }
    Vector2::new(a, r)
}

fn s_manoeuvre_smooth(t: f64) -> Vector2<f64> {
    let t = t % 120.0;
    let tau = std::f64::consts::TAU;
    if t < 8.0 {
        Vector2::new(0.2, 0.0)
    } else if t < 10.0 {
        Vector2::zeros()
    } else if t < 110.0 {
        let ph = (t - 10.0) / 50.0;
        Vector2::new(-0.04 * (2.0 * tau * ph).sin(), 0.1 * (tau * ph).sin())
    } else {
        Vector2::new(-0.1, 0.0)
    }
}

#[test]
fn case1_converges_within_one_second_and_follows_input_changes() {
    let dt = 0.001;
    let target = Vector2::new(0.5, 0.3);
    let r = run(
        dt,
        20.0,
        seed_config(dt),
        Vector4::zeros(),
        case1_input,
        |t| if t >= 5.0 { target } else { Vector2::zeros() },
        None,
    );
    let at5 = settled_at(&r, target, 0.05, 5.0, 10.0).unwrap();
    let at2 = settled_at(&r, target, 0.02, 5.0, 10.0).unwrap();
    println!(
        "case 1: within 0.05 after {:.3} s, within 0.02 after {:.3} s",
        at5 - 5.0,
        at2 - 5.0
    );
    assert!(
        at2 - 5.0 <= 1.0,
        "within 0.02 only {:.3} s after onset",
        at2 - 5.0
    );
    // Zero fault before the onset: the estimate stays at zero (noise-free).
    for (t, th) in r.time_s.iter().zip(&r.theta) {
        if *t < 5.0 {
            assert!(th.amax() < 0.01, "t={t}: {th:?}");
        }
    }
    // It stays there while excited, through the input changes at 10 s and 15 s.
    for (t, th) in r.time_s.iter().zip(&r.theta) {
        if *t >= 5.0 + 1.0 {
            assert!((th - target).amax() <= 0.02, "t={t}: {th:?}");
        }
    }
}

/// docs/model.md section 4 quotes the authors' code form: relative error within
/// 5 % after 0.50 s and within 2 % after 0.66 s. That code adapts Q and R
/// (authors' form); with the same, our recursion gives the same timings.
#[test]
fn case1_with_the_authors_adaptation_matches_their_timings() {
    let dt = 0.001;
    let target = Vector2::new(0.5, 0.3);
    let mut config = seed_config(dt);
    config.noise_adaptation = Some(NoiseAdaptation {
        factor: 0.999,
        adapt_process_noise: true,
        measurement_noise_form: Some(MeasurementNoiseForm::AuthorsCode),
    });
    let r = run(
        dt,
        10.0,
        config,
        Vector4::zeros(),
        case1_input,
        |t| if t >= 5.0 { target } else { Vector2::zeros() },
        None,
    );
    let within_relative = |tol: f64| {
        let mut last_bad = 5.0;
        for (t, th) in r.time_s.iter().zip(&r.theta) {
            if *t >= 5.0 && ((th[0] - 0.5).abs() / 0.5 > tol || (th[1] - 0.3).abs() / 0.3 > tol) {
                last_bad = *t;
            }
        }
        last_bad - 5.0
    };
    let (t5, t2) = (within_relative(0.05), within_relative(0.02));
    println!("authors' form: within 5 % after {t5:.3} s, within 2 % after {t2:.3} s");
    assert!((t5 - 0.50).abs() < 0.02, "{t5}");
    assert!((t2 - 0.66).abs() < 0.02, "{t2}");
}

/// Case 2: the fault lasts 1000 steps ([5, 6) s) or 500 steps ([5, 5.5) s).
#[test]
fn case2_short_faults_are_tracked_and_released() {
    let dt = 0.001;
    let target = Vector2::new(0.5, 0.3);
    for end_s in [6.0, 5.5] {
        let r = run(
            dt,
            10.0,
            seed_config(dt),
            Vector4::zeros(),
            case1_input,
            |t| {
                if (5.0..end_s).contains(&t) {
                    target
                } else {
                    Vector2::zeros()
                }
            },
            None,
        );
        let at = |t: f64| r.theta[(t / dt).round() as usize - 1];
        let at_end = at(end_s);
        println!(
            "case 2 [5, {end_s}): theta at the end {:?}, 1 s later {:?}, 2 s later {:?}",
            at_end.as_slice(),
            at(end_s + 1.0).as_slice(),
            at(end_s + 2.0).as_slice()
        );
        if end_s == 6.0 {
            // 1000 steps: reaches within 0.05 before the fault ends.
            assert!((at_end - target).amax() < 0.05, "{at_end:?}");
        } else {
            // 500 steps: most of the way (the memory is 200 steps).
            assert!((at_end - target).amax() < 0.5 * target.amax(), "{at_end:?}");
            assert!(at_end[0] > 0.3 && at_end[1] > 0.15, "{at_end:?}");
        }
        // Then it returns toward 0 and gets there.
        assert!(at(end_s + 1.0).amax() < 0.05, "{:?}", at(end_s + 1.0));
        assert!(at(end_s + 2.0).amax() < 0.01, "{:?}", at(end_s + 2.0));
    }
}

/// Case 3: the input drops to zero while the estimate converges. The
/// estimate holds still during the gap, its covariance does not wind up, and
/// it converges once the input returns. Without anti-windup (the seed's
/// recursion) the covariance grows by orders of magnitude in the gap.
#[test]
fn case3_zero_input_holds_without_windup_and_resumes() {
    let dt = 0.001;
    let target = Vector2::new(0.5, 0.3);
    let gap = 5.3..8.0;
    let input = |t: f64| {
        if gap.contains(&t) {
            Vector2::zeros()
        } else {
            case1_input(t)
        }
    };
    let fault = |t: f64| if t >= 5.0 { target } else { Vector2::zeros() };
    let idx = |t: f64| (t / dt).round() as usize - 1;
    let mut without_aw = seed_config(dt);
    without_aw.anti_windup_ratio = 0.0;
    let a = run(
        dt,
        10.0,
        seed_config(dt),
        Vector4::zeros(),
        input,
        fault,
        None,
    );
    let b = run(dt, 10.0, without_aw, Vector4::zeros(), input, fault, None);

    let drift = (a.theta[idx(7.99)] - a.theta[idx(5.4)]).amax();
    let growth_aw = a.s_trace[idx(7.99)] / a.s_trace[idx(5.31)];
    let growth_seed = b.s_trace[idx(7.99)] / b.s_trace[idx(5.31)];
    println!(
        "case 3: drift in the gap {drift:.2e}; S growth in the gap: {growth_aw:.3} with anti-windup, {growth_seed:.3e} without"
    );
    assert!(drift < 1e-3, "estimate drifted by {drift} with no input");
    assert!(growth_aw < 1.02, "S grew {growth_aw}x with no input");
    assert!(
        growth_seed > 1e3,
        "the seed's recursion should wind up: {growth_seed}"
    );
    // Not yet converged when the input stopped, converged soon after it returns.
    assert!((a.theta[idx(7.99)] - target).amax() > 0.05);
    let settled = settled_at(&a, target, 0.02, 8.0, 10.0).unwrap();
    println!(
        "case 3: within 0.02 again {:.3} s after the input returns",
        settled - 8.0
    );
    assert!(settled - 8.0 < 1.0);
}

/// Why wind-up matters: with measurement noise, the wound-up covariance
/// turns the first steps after the gap into near dead-beat steps that follow
/// the noise. Noise 0.01 per component (R stays the seed's 0.04).
#[test]
fn case3_windup_throws_the_estimate_about_when_the_input_returns() {
    let dt = 0.001;
    let target = Vector2::new(0.5, 0.3);
    let gap = 5.3..8.0;
    let input = |t: f64| {
        if gap.contains(&t) {
            Vector2::zeros()
        } else {
            case1_input(t)
        }
    };
    let fault = |t: f64| if t >= 5.0 { target } else { Vector2::zeros() };
    let idx = |t: f64| (t / dt).round() as usize - 1;
    let noise = Some((Vector4::repeat(0.01), 11));
    let mut without_aw = seed_config(dt);
    without_aw.anti_windup_ratio = 0.0;
    let a = run(
        dt,
        9.0,
        seed_config(dt),
        Vector4::zeros(),
        input,
        fault,
        noise,
    );
    let b = run(dt, 9.0, without_aw, Vector4::zeros(), input, fault, noise);
    let worst = |r: &Run| {
        (idx(8.0)..idx(8.2))
            .map(|k| (r.theta[k] - target).amax())
            .fold(0.0, f64::max)
    };
    let before = |r: &Run| {
        (idx(4.5)..idx(5.0))
            .map(|k| r.theta[k].amax())
            .fold(0.0, f64::max)
    };
    println!(
        "case 3 with noise: worst error in the 0.2 s after the gap {:.3} with anti-windup, {:.3} without; worst |theta| in the 0.5 s before the onset {:.3}",
        worst(&a),
        worst(&b),
        before(&a)
    );
    assert!(worst(&b) > 2.0 * worst(&a));
}

/// Case 4 tuning: the seed's forgetting (lambda = 0.995 at 0.2 s, tau = 40 s)
/// and R; Q matched to the simulated truth, which has no process noise
/// (1e-5 per step). With the seed's Q = 0.01 per step (far more process noise
/// than the truth has), the same run converges more slowly (see below).
fn case4_config(dt: f64) -> AekfConfig<4, 4, 2> {
    let mut c = seed_config(dt);
    c.process_noise_density = SMatrix::identity() * (1e-5 / dt);
    c
}

#[test]
fn case4_s_manoeuvre_converges_by_150_s() {
    let dt = 0.2;
    let target = Vector2::new(0.1, 0.5);
    let fault = |t: f64| if t >= 25.0 { target } else { Vector2::zeros() };
    let x0 = Vector4::new(0.0, 0.0, 0.0, 0.3);
    let r = run(
        dt,
        240.0,
        case4_config(dt),
        x0,
        s_manoeuvre_input,
        fault,
        None,
    );
    let settled = settled_at(&r, target, 0.03, 25.0, 240.0).unwrap();
    println!("case 4: within 0.03 from t = {settled:.1} s");
    assert!(settled <= 150.0, "within 0.03 only from {settled} s");
    // With the seed's own Q it is slower, but it gets there within the run.
    let seed_q = run(
        dt,
        240.0,
        seed_config(dt),
        x0,
        s_manoeuvre_input,
        fault,
        None,
    );
    let settled_seed = settled_at(&seed_q, target, 0.03, 25.0, 240.0).unwrap();
    println!("case 4 with the seed's Q = 0.01 I: within 0.03 from t = {settled_seed:.1} s");
    assert!(settled_seed > settled && settled_seed < 240.0);
}

/// Zero fault with measurement noise: while the filter says the data can
/// tell (its excitation flag: the last memory window alone pins the fault to
/// 0.02), the estimate of the zero fault stays below 0.02. Two noise levels,
/// three seeds each: 0.05 m per position axis, 0.01 m/s SOG, 0.005 rad COG (a
/// differential receiver), and 0.3 m, 0.05 m/s, 0.02 rad (standalone GNSS),
/// where the filter is excited far less often: it says so rather than guess.
#[test]
fn case4_zero_fault_with_noise_hovers_at_zero_while_excited() {
    let dt = 0.2;
    for (sigma, min_excited_fraction) in [
        (Vector4::new(0.05, 0.05, 0.01, 0.005), 0.5),
        (Vector4::new(0.3, 0.3, 0.05, 0.02), 0.01),
    ] {
        let mut config = case4_config(dt);
        config.measurement_noise = SMatrix::from_diagonal(&sigma.component_mul(&sigma));
        for seed in [1, 2, 3] {
            let r = run(
                dt,
                240.0,
                config,
                Vector4::new(0.0, 0.0, 0.0, 0.3),
                s_manoeuvre_input,
                |_| Vector2::zeros(),
                Some((sigma, seed)),
            );
            let excited: Vec<usize> = (0..r.theta.len())
                .filter(|k| r.excited[*k][0] && r.excited[*k][1])
                .collect();
            let fraction = excited.len() as f64 / r.theta.len() as f64;
            let worst = excited
                .iter()
                .map(|k| r.theta[*k].amax())
                .fold(0.0, f64::max);
            let worst_overall = r.theta.iter().map(|th| th.amax()).fold(0.0, f64::max);
            println!(
                "zero fault, noise {:?}, seed {seed}: excited {:.0} % of the run, worst |theta| there {worst:.4} (anywhere: {worst_overall:.3})",
                sigma.as_slice(),
                100.0 * fraction
            );
            assert!(fraction >= min_excited_fraction, "excited only {fraction}");
            assert!(worst < 0.02, "worst {worst} while excited");
        }
    }
}
