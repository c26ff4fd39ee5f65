//! The faults' sensitivity `Upsilon` with the gain's part
//! (`AekfConfig::gain_sensitivity`) is the derivative of the state estimate
//! with respect to the faults: the extended twin's filter, its faults held
//! (no fault covariance), run twice over the same measurements with one
//! fault moved either way, differs by `Upsilon` times the move; through
//! the covariance alone, where the measurement model is linear; and a fault
//! left out of the gain's part (`AekfConfig::gain_sensitivity_faults`)
//! keeps step 7's column as published.

use nalgebra::{SMatrix, SVector};
use twin_core::aekf::{Aekf, AekfState, GainSensitivity};
use twin_core::estimator::KineticConfig;
use twin_core::model::{Measurement, Model};
use twin_core::models::otter_twin::{FAULTS, MEASUREMENTS, OtterTwin, STATES, ShaftSpeeds, fault};

/// Standard deviations of the simulated measurements: position (m), speed
/// over ground (m/s), course, heading (rad), yaw rate (rad/s).
const NOISE: [f64; MEASUREMENTS] = [0.3, 0.3, 0.05, 0.03, 0.0087, 0.0087];

/// The fix interval, s.
const DT_S: f64 = 0.2;

/// Where the run, and the filter, start: at the origin, heading north at
/// 1.4 m/s through still water.
fn start() -> SVector<f64, STATES> {
    let mut x = SVector::<f64, STATES>::zeros();
    x[3] = 1.4;
    x
}

/// A weaving run of 80 s at 5 Hz: the Otter with healthy propellers and
/// its own profile, its shaft speeds swinging 15 rad/s either side of 70,
/// measured with Gaussian noise from a fixed-seed generator; the speed and
/// course over ground only `with_velocity`.
fn weaving_run(with_velocity: bool) -> Vec<(ShaftSpeeds, Measurement<MEASUREMENTS>)> {
    let model = OtterTwin::default();
    let mut x = start();
    let mut seed: u64 = 12345;
    let mut gaussian = || {
        // Irwin-Hall: twelve uniforms less six.
        let mut sum = 0.0;
        for _ in 0..12 {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            sum += (seed >> 11) as f64 / (1u64 << 53) as f64;
        }
        sum - 6.0
    };
    (0..400)
        .map(|k| {
            let t_s = f64::from(k) * DT_S;
            let swing = 15.0 * (t_s / 10.0).sin();
            let input = ShaftSpeeds {
                port_radps: 70.0 + swing,
                starboard_radps: 70.0 - swing,
            };
            x = model.propagate(&x, &input, &SVector::zeros(), DT_S);
            let mut values = model.observe(&x).predicted;
            for (v, sigma) in values.iter_mut().zip(NOISE) {
                *v += sigma * gaussian();
            }
            let mut available = [true; MEASUREMENTS];
            available[2] = with_velocity;
            available[3] = with_velocity;
            let y = Measurement { values, available };
            (input, y)
        })
        .collect()
}

/// Every fault carries the gain's part.
const ALL_FAULTS: [bool; FAULTS] = [true; FAULTS];

/// The filter's estimate after `run` with the faults held at `theta`, the
/// gain's part on the `faults` marked.
fn estimate(
    run: &[(ShaftSpeeds, Measurement<MEASUREMENTS>)],
    theta: SVector<f64, FAULTS>,
    gain_sensitivity: GainSensitivity,
    faults: [bool; FAULTS],
) -> AekfState<STATES, MEASUREMENTS, FAULTS> {
    let mut config = KineticConfig::otter().filter;
    config.initial_fault_covariance = SMatrix::zeros();
    config.gain_sensitivity = gain_sensitivity;
    config.gain_sensitivity_faults = faults;
    let filter = Aekf::new(OtterTwin::default(), config).expect("a valid filter");
    let p0 = SMatrix::from_diagonal(&SVector::from([
        1.0, 1.0, 0.01, 0.1, 0.01, 0.01, 0.01, 0.01, 0.001, 0.0001,
    ]));
    let mut state = AekfState::new(&config, start(), p0, theta);
    for (input, y) in run {
        filter
            .step(&mut state, input, y, DT_S)
            .expect("the step succeeds");
    }
    state
}

/// The faults the runs are held at.
fn held_faults() -> SVector<f64, FAULTS> {
    SVector::from([0.1, 0.05, 0.1, 0.05, -0.05, 0.1])
}

/// The largest relative difference, over the `faults` marked, between
/// `Upsilon` and the central difference of the estimate, the gain's part
/// on those faults.
fn worst_relative_error(
    gain_sensitivity: GainSensitivity,
    with_velocity: bool,
    faults: [bool; FAULTS],
) -> f64 {
    let run = weaving_run(with_velocity);
    let theta = held_faults();
    let at = estimate(&run, theta, gain_sensitivity, faults);
    let step = 1e-5;
    (0..FAULTS)
        .filter(|&i| faults[i])
        .map(|i| {
            let (mut up, mut down) = (theta, theta);
            up[i] += step;
            down[i] -= step;
            let numeric = (estimate(&run, up, gain_sensitivity, faults).x
                - estimate(&run, down, gain_sensitivity, faults).x)
                / (2.0 * step);
            (numeric - at.upsilon.column(i)).norm() / numeric.norm()
        })
        .fold(0.0, f64::max)
}

#[test]
fn upsilon_with_the_gains_part_is_the_estimates_derivative() {
    // Without the gain's part the same comparison is 21 % off.
    let worst = worst_relative_error(GainSensitivity::Exact, true, ALL_FAULTS);
    assert!(worst < 0.05, "Upsilon is {worst:.3} off the derivative");
}

#[test]
fn through_the_covariance_it_is_the_derivative_where_h_is_constant() {
    // Positions, heading and yaw rate: a measurement Jacobian that does
    // not depend on the state, where the covariance carries all of the
    // gain's dependence (without it, 62 % off).
    let worst = worst_relative_error(GainSensitivity::ThroughCovariance, false, ALL_FAULTS);
    assert!(worst < 0.05, "Upsilon is {worst:.3} off the derivative");
}

#[test]
fn a_fault_left_out_keeps_the_published_column_and_the_others_stay_exact() {
    // The gain's part on the profile's errors alone: their columns are
    // still the derivative, and the losses' columns are step 7's as
    // published, to the bit.
    let profile_only = fault::IS_PROFILE;
    let worst = worst_relative_error(GainSensitivity::Exact, true, profile_only);
    assert!(worst < 0.05, "Upsilon is {worst:.3} off the derivative");
    let run = weaving_run(true);
    let with = estimate(&run, held_faults(), GainSensitivity::Exact, profile_only);
    let without = estimate(&run, held_faults(), GainSensitivity::Omitted, ALL_FAULTS);
    for i in [fault::PORT, fault::STARBOARD] {
        assert_eq!(
            with.upsilon.column(i),
            without.upsilon.column(i),
            "fault {i}"
        );
        assert_eq!(
            with.covariance_sensitivity[i],
            SMatrix::<f64, STATES, STATES>::zeros(),
            "fault {i}"
        );
    }
    for i in fault::PROFILE {
        assert_ne!(
            with.upsilon.column(i),
            without.upsilon.column(i),
            "fault {i}"
        );
    }
}
