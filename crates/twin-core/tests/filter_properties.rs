//! Properties of the adaptive EKF that hold whatever the case: consistency
//! with its own noise model (NIS), unbiased noise adaptation, independence of
//! the sample interval, symmetric positive definite covariances over a million
//! steps, and errors as values for everything else.

use nalgebra::{SMatrix, SVector, Vector2, Vector4};
use proptest::prelude::*;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use twin_core::aekf::{
    Aekf, AekfConfig, AekfError, AekfState, GainSensitivity, MeasurementNoiseForm, NoiseAdaptation,
};
use twin_core::geodesy::wrap_pi;
use twin_core::model::Measurement;
use twin_core::models::kinematic::{KinematicInput, KinematicModel};

fn config(q_density: Vector4<f64>, r_sigma: Vector4<f64>, tau_s: f64) -> AekfConfig<4, 4, 2> {
    AekfConfig {
        process_noise_density: SMatrix::from_diagonal(&q_density),
        measurement_noise: SMatrix::from_diagonal(&r_sigma.component_mul(&r_sigma)),
        forgetting_time_constant_s: tau_s,
        fault_memory_factor: SVector::repeat(1.0),
        initial_fault_covariance: SMatrix::identity() * 0.1,
        anti_windup_ratio: 0.1,
        excitation_sigma: 0.02,
        noise_adaptation: None,
        gain_sensitivity: GainSensitivity::Omitted,
        gain_sensitivity_faults: [true; _],
    }
}

/// A smooth manoeuvring input: speed changes and turns both ways.
fn manoeuvre(t: f64) -> Vector2<f64> {
    Vector2::new(
        0.15 * (0.21 * t).sin(),
        0.08 * (0.13 * t).sin() + 0.03 * (0.57 * t).cos(),
    )
}

/// The truth of the kinematic model driven by `input`, with process noise of
/// density `q_density` (so the filter's model is exactly right) and faults
/// `theta`, measured with noise `r_sigma`. Returns (dt, input, measurement)
/// per step, and the truths.
#[allow(clippy::type_complexity)]
fn simulate(
    dt: f64,
    duration_s: f64,
    q_density: Vector4<f64>,
    r_sigma: Vector4<f64>,
    theta: Vector2<f64>,
    seed: u64,
) -> (Vec<(KinematicInput, Vector4<f64>)>, Vec<Vector4<f64>>) {
    let mut rng = StdRng::seed_from_u64(seed);
    let n01 = Normal::new(0.0, 1.0).unwrap();
    let mut x = Vector4::new(0.0, 0.0, 1.5, 0.2);
    let mut steps = vec![];
    let mut truths = vec![];
    for k in 0..(duration_s / dt).round() as usize {
        let u = manoeuvre(k as f64 * dt);
        let w = Vector4::from_fn(|i, _| (q_density[i] * dt).sqrt() * n01.sample(&mut rng));
        x = Vector4::new(
            x[0] + dt * x[2] * x[3].cos(),
            x[1] + dt * x[2] * x[3].sin(),
            x[2] + dt * (1.0 - theta[0]) * u[0],
            x[3] + dt * (1.0 - theta[1]) * u[1],
        ) + w;
        x[3] = wrap_pi(x[3]);
        let mut y = x + Vector4::from_fn(|i, _| r_sigma[i] * n01.sample(&mut rng));
        y[3] = wrap_pi(y[3]);
        steps.push((
            KinematicInput {
                accel_mps2: u[0],
                course_rate_radps: u[1],
            },
            y,
        ));
        truths.push(x);
    }
    (steps, truths)
}

/// Chi-square quantile by the Wilson-Hilferty approximation (accurate to a
/// fraction of a percent for the thousands of degrees of freedom used here).
fn chi2_quantile(dof: f64, z: f64) -> f64 {
    let a = 2.0 / (9.0 * dof);
    dof * (1.0 - a + z * a.sqrt()).powi(3)
}

#[test]
fn nis_is_consistent_with_the_stated_noise() {
    let dt = 0.2;
    let q = Vector4::new(0.01, 0.01, 0.002, 0.0005);
    let r = Vector4::new(0.5, 0.5, 0.05, 0.02);
    let theta = Vector2::new(0.2, 0.1);
    let cfg = config(q, r, 60.0);
    let filter = Aekf::new(KinematicModel, cfg).unwrap();
    for seed in [1, 2, 3] {
        let (steps, _) = simulate(dt, 600.0, q, r, theta, seed);
        let mut est = AekfState::new(&cfg, steps[0].1, cfg.measurement_noise, Vector2::zeros());
        let mut nis = vec![];
        for (u, y) in &steps[1..] {
            let rep = filter
                .step(&mut est, u, &Measurement::full(*y), dt)
                .unwrap();
            nis.push(rep.nis);
        }
        // Skip the first two memory windows while the fault estimate converges.
        let tail = &nis[600..];
        let n = tail.len() as f64;
        let mean = tail.iter().sum::<f64>() / n;
        let (lo, hi) = (
            chi2_quantile(4.0 * n, -1.96) / n,
            chi2_quantile(4.0 * n, 1.96) / n,
        );
        println!(
            "seed {seed}: average NIS {mean:.3} over {n} steps; 95 % band [{lo:.3}, {hi:.3}]; theta {:?}",
            est.theta.as_slice()
        );
        assert!(
            mean > lo && mean < hi,
            "average NIS {mean} outside [{lo}, {hi}]"
        );
        assert!((est.theta - theta).amax() < 0.1);
    }
}

#[test]
fn nis_detects_a_filter_that_understates_its_noise() {
    // The same check fails when the filter believes the noise is half what it
    // is: the consistency test has teeth.
    let dt = 0.2;
    let q = Vector4::new(0.01, 0.01, 0.002, 0.0005);
    let r = Vector4::new(0.5, 0.5, 0.05, 0.02);
    let cfg = config(q, r * 0.5, 60.0);
    let filter = Aekf::new(KinematicModel, cfg).unwrap();
    let (steps, _) = simulate(dt, 600.0, q, r, Vector2::zeros(), 1);
    let mut est = AekfState::new(&cfg, steps[0].1, cfg.measurement_noise, Vector2::zeros());
    let mut nis = vec![];
    for (u, y) in &steps[1..] {
        nis.push(
            filter
                .step(&mut est, u, &Measurement::full(*y), dt)
                .unwrap()
                .nis,
        );
    }
    let tail = &nis[600..];
    let n = tail.len() as f64;
    let mean = tail.iter().sum::<f64>() / n;
    assert!(
        mean > chi2_quantile(4.0 * n, 1.96) / n,
        "average NIS {mean}"
    );
}

#[test]
fn measurement_noise_adaptation_post_fit_is_unbiased_and_the_authors_form_is_not() {
    let dt = 0.2;
    let q = Vector4::new(0.01, 0.01, 0.002, 0.0005);
    let r_true = Vector4::new(0.5, 0.5, 0.05, 0.02);
    let (steps, _) = simulate(dt, 2000.0, q, r_true, Vector2::zeros(), 5);
    let mut results = vec![];
    for form in [
        MeasurementNoiseForm::PostFitResidual,
        MeasurementNoiseForm::AuthorsCode,
    ] {
        // Start from a wrong R (4x the true variance) and let it adapt.
        let mut cfg = config(q, r_true * 2.0, 60.0);
        cfg.noise_adaptation = Some(NoiseAdaptation {
            factor: 0.995,
            adapt_process_noise: false,
            measurement_noise_form: Some(form),
        });
        let filter = Aekf::new(KinematicModel, cfg).unwrap();
        let mut est = AekfState::new(&cfg, steps[0].1, cfg.measurement_noise, Vector2::zeros());
        let mut r_sum = Vector4::zeros();
        let mut count = 0.0;
        for (k, (u, y)) in steps[1..].iter().enumerate() {
            filter
                .step(&mut est, u, &Measurement::full(*y), dt)
                .unwrap();
            assert!(nalgebra::Cholesky::new(est.measurement_noise).is_some());
            if k > 3000 {
                r_sum += est.measurement_noise.diagonal();
                count += 1.0;
            }
        }
        let ratio = (r_sum / count).component_div(&r_true.component_mul(&r_true));
        println!("{form:?}: adapted R / true R = {:.3?}", ratio.as_slice());
        results.push(ratio);
    }
    // Post-fit form: within 15 % of the true variance on every component.
    assert!(
        results[0].iter().all(|x| (x - 1.0).abs() < 0.15),
        "{:?}",
        results[0]
    );
    // The authors' form overestimates every component (it converges to R + 2 H P- H^T).
    assert!(results[1].iter().all(|x| *x > 1.15), "{:?}", results[1]);
}

#[test]
fn process_noise_adaptation_keeps_q_symmetric_positive_definite_and_tracks_it() {
    let dt = 0.2;
    let q_true = Vector4::new(0.04, 0.04, 0.004, 0.001);
    let r = Vector4::new(0.3, 0.3, 0.05, 0.02);
    let (steps, _) = simulate(dt, 2000.0, q_true, r, Vector2::zeros(), 9);
    // Start with Q 100x too small.
    let mut cfg = config(q_true * 0.01, r, 60.0);
    cfg.noise_adaptation = Some(NoiseAdaptation {
        factor: 0.995,
        adapt_process_noise: true,
        measurement_noise_form: None,
    });
    let filter = Aekf::new(KinematicModel, cfg).unwrap();
    let mut est = AekfState::new(&cfg, steps[0].1, cfg.measurement_noise, Vector2::zeros());
    let mut trace_sum = 0.0;
    let mut count = 0.0;
    for (k, (u, y)) in steps[1..].iter().enumerate() {
        filter
            .step(&mut est, u, &Measurement::full(*y), dt)
            .unwrap();
        let qd = est.process_noise_density;
        assert!((qd - qd.transpose()).amax() < 1e-12);
        assert!(
            nalgebra::Cholesky::new(qd).is_some(),
            "Q not SPD at step {k}"
        );
        if k > 3000 {
            trace_sum += qd.trace();
            count += 1.0;
        }
    }
    let ratio = trace_sum / count / q_true.sum();
    println!("adapted trace(Q) / true trace(Q) = {ratio:.3}");
    // It grows from 1 % of the truth to the right order of magnitude.
    assert!(ratio > 0.3 && ratio < 3.0, "{ratio}");
}

/// The same physical run sampled at different rates converges in the same
/// number of seconds: the filter's tuning is in seconds, not in steps.
#[test]
fn convergence_time_does_not_depend_on_the_sample_interval() {
    let theta = Vector2::new(0.3, 0.2);
    let mut times = vec![];
    for dt in [0.05, 0.1, 0.2, 0.5] {
        let q = Vector4::new(1e-4, 1e-4, 1e-5, 1e-6);
        let r = Vector4::new(0.02, 0.02, 0.005, 0.002);
        let cfg = config(q, r, 20.0);
        let filter = Aekf::new(KinematicModel, cfg).unwrap();
        let (steps, _) = simulate(dt, 200.0, Vector4::zeros(), Vector4::zeros(), theta, 1);
        let mut est = AekfState::new(&cfg, steps[0].1, cfg.measurement_noise, Vector2::zeros());
        let mut last_bad = 0.0;
        for (k, (u, y)) in steps[1..].iter().enumerate() {
            filter
                .step(&mut est, u, &Measurement::full(*y), dt)
                .unwrap();
            if (est.theta - theta).amax() > 0.02 {
                last_bad = (k + 2) as f64 * dt;
            }
        }
        println!("dt = {dt} s: within 0.02 from {last_bad:.1} s");
        times.push(last_bad);
    }
    let (lo, hi) = times
        .iter()
        .fold((f64::MAX, 0.0f64), |(lo, hi), t| (lo.min(*t), hi.max(*t)));
    assert!(hi < 150.0, "{times:?}");
    assert!(
        hi - lo < 0.25 * hi,
        "convergence times differ too much: {times:?}"
    );
}

#[test]
fn bad_steps_are_errors_and_leave_the_estimate_unchanged() {
    let cfg = config(Vector4::repeat(0.01), Vector4::repeat(0.2), 40.0);
    let filter = Aekf::new(KinematicModel, cfg).unwrap();
    let mut est = AekfState::new(
        &cfg,
        Vector4::new(0.0, 0.0, 1.0, 0.0),
        SMatrix::identity(),
        Vector2::zeros(),
    );
    let u = KinematicInput {
        accel_mps2: 0.1,
        course_rate_radps: 0.05,
    };
    let good = Measurement::full(Vector4::new(0.2, 0.0, 1.0, 0.0));
    filter.step(&mut est, &u, &good, 0.2).unwrap();
    let before = est;
    for dt in [0.0, -0.2, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            filter.step(&mut est, &u, &good, dt),
            Err(AekfError::InvalidTimeStep { .. })
        ));
    }
    let nan = Measurement::full(Vector4::new(f64::NAN, 0.0, 1.0, 0.0));
    assert!(matches!(
        filter.step(&mut est, &u, &nan, 0.2),
        Err(AekfError::NonFinite { .. })
    ));
    let bad_input = KinematicInput {
        accel_mps2: f64::INFINITY,
        course_rate_radps: 0.0,
    };
    assert!(filter.step(&mut est, &bad_input, &good, 0.2).is_err());
    assert_eq!(est, before);
    // A NaN in a component marked missing is ignored, not an error.
    let mut partial = nan;
    partial.available[0] = false;
    assert!(filter.step(&mut est, &u, &partial, 0.2).is_ok());
    // Unusable configurations are refused up front.
    let mut c = cfg;
    c.measurement_noise[(0, 0)] = -1.0;
    assert!(matches!(
        Aekf::new(KinematicModel, c),
        Err(AekfError::NotPositiveDefinite { .. })
    ));
    let mut c = cfg;
    c.forgetting_time_constant_s = 0.0;
    assert!(Aekf::new(KinematicModel, c).is_err());
    // A process noise that is not finite, even symmetric, is refused: the
    // step checks the noise covariances only when adaptation changes them.
    for bad in [f64::NAN, f64::INFINITY] {
        let mut c = cfg;
        c.process_noise_density[(1, 1)] = bad;
        assert!(matches!(
            Aekf::new(KinematicModel, c),
            Err(AekfError::InvalidConfig(_))
        ));
    }
}

#[test]
fn missing_components_are_ignored_exactly() {
    // A step with course marked missing equals a step where the course
    // measurement happens to equal the prediction with infinite noise.
    let cfg = config(Vector4::repeat(0.01), Vector4::repeat(0.2), 40.0);
    let filter = Aekf::new(KinematicModel, cfg).unwrap();
    let start = AekfState::new(
        &cfg,
        Vector4::new(0.0, 0.0, 1.0, 0.3),
        SMatrix::identity(),
        Vector2::zeros(),
    );
    let u = KinematicInput {
        accel_mps2: 0.1,
        course_rate_radps: 0.05,
    };
    let mut masked = Measurement::full(Vector4::new(0.3, 0.1, 1.1, 99.0));
    masked.available[3] = false;
    let mut a = start;
    let ra = filter.step(&mut a, &u, &masked, 0.2).unwrap();
    assert_eq!(ra.dof, 3);
    assert_eq!(ra.innovation[3], 0.0);
    let mut c2 = cfg;
    c2.measurement_noise[(3, 3)] = 1e12;
    let filter2 = Aekf::new(KinematicModel, c2).unwrap();
    let mut b = AekfState::new(&c2, start.x, start.p, start.theta);
    let pred = KinematicModel;
    let tr = twin_core::model::Model::transition(&pred, &start.x, &u, &start.theta, 0.2);
    let mut full = masked;
    full.available[3] = true;
    full.values[3] = tr.next[3];
    filter2.step(&mut b, &u, &full, 0.2).unwrap();
    assert!((a.x - b.x).amax() < 1e-6, "{:?} vs {:?}", a.x, b.x);
    assert!((a.p - b.p).amax() < 1e-6);
}

/// A million steps with random excitation, random gaps and random faults:
/// every covariance stays symmetric positive definite and every number finite.
#[test]
fn covariances_stay_spd_over_a_million_steps() {
    let mut rng = StdRng::seed_from_u64(2024);
    let mut cfg = config(
        Vector4::new(0.01, 0.01, 0.001, 0.001),
        Vector4::new(0.5, 0.5, 0.05, 0.02),
        30.0,
    );
    cfg.noise_adaptation = Some(NoiseAdaptation {
        factor: 0.999,
        adapt_process_noise: true,
        measurement_noise_form: Some(MeasurementNoiseForm::PostFitResidual),
    });
    let filter = Aekf::new(KinematicModel, cfg).unwrap();
    let mut est = AekfState::new(
        &cfg,
        Vector4::new(0.0, 0.0, 1.0, 0.0),
        SMatrix::identity(),
        Vector2::zeros(),
    );
    let mut x = est.x;
    let n01 = Normal::new(0.0, 1.0).unwrap();
    let mut u = Vector2::zeros();
    for k in 0..1_000_000u32 {
        if k % 500 == 0 {
            // New input regime: sometimes zero (no excitation), sometimes large.
            u = match rng.random_range(0..4) {
                0 => Vector2::zeros(),
                1 => Vector2::new(rng.random_range(-0.5..0.5), 0.0),
                _ => Vector2::new(rng.random_range(-0.5..0.5), rng.random_range(-0.3..0.3)),
            };
        }
        let dt = [0.05, 0.2, 1.0][rng.random_range(0..3)];
        x = Vector4::new(
            x[0] + dt * x[2] * x[3].cos(),
            x[1] + dt * x[2] * x[3].sin(),
            (x[2] + dt * 0.8 * u[0]).clamp(-5.0, 5.0),
            wrap_pi(x[3] + dt * 0.7 * u[1]),
        );
        let mut y = Measurement::full(x + Vector4::from_fn(|_, _| 0.1 * n01.sample(&mut rng)));
        if rng.random_bool(0.05) {
            y.available[rng.random_range(0..4)] = false;
        }
        let ki = KinematicInput {
            accel_mps2: u[0],
            course_rate_radps: u[1],
        };
        filter.step(&mut est, &ki, &y, dt).unwrap();
        if k % 997 == 0 {
            assert!(est.is_sane());
            let p = est.p;
            assert!(
                (p - p.transpose()).amax() <= 1e-9 * p.amax(),
                "P asymmetric at {k}"
            );
            assert!(nalgebra::Cholesky::new(p).is_some(), "P not SPD at {k}");
            assert!((est.s - est.s.transpose()).amax() <= 1e-9 * est.s.amax());
            assert!(nalgebra::Cholesky::new(est.s).is_some(), "S not SPD at {k}");
            assert!(nalgebra::Cholesky::new(est.measurement_noise).is_some());
        }
    }
    assert!(est.is_sane());
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// Whatever the inputs and measurements, a step either fails with an
    /// error (estimate untouched) or leaves a finite, sane estimate.
    #[test]
    fn no_nan_ever_leaves_the_filter(
        values in proptest::collection::vec(
            (prop_oneof![Just(f64::NAN), Just(f64::INFINITY), Just(-1e308), Just(0.0), -1e6f64..1e6],
             -1e3f64..1e3, -1e3f64..1e3, -10f64..10.0, prop_oneof![Just(0.0), Just(-1.0), 1e-6f64..100.0],
             any::<[bool; 4]>()),
            1..200),
    ) {
        let cfg = config(Vector4::repeat(0.01), Vector4::repeat(0.3), 20.0);
        let filter = Aekf::new(KinematicModel, cfg).unwrap();
        let mut est = AekfState::new(&cfg, Vector4::zeros(), SMatrix::identity(), Vector2::zeros());
        for (v0, v1, a, r, dt, avail) in values {
            let y = Measurement { values: Vector4::new(v0, v1, a.abs(), r), available: avail };
            let u = KinematicInput { accel_mps2: a, course_rate_radps: r };
            let before = est;
            match filter.step(&mut est, &u, &y, dt) {
                Ok(rep) => {
                    prop_assert!(est.is_sane());
                    prop_assert!(rep.nis.is_finite());
                }
                Err(_) => prop_assert_eq!(est, before),
            }
        }
    }
}
