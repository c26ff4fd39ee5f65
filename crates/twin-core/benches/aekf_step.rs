//! Criterion benchmarks of the estimator: one adaptive-EKF step of the seed's
//! kinematic model (target: under 250 ns median), and a whole 120 s trial at
//! 5 Hz offline; and the step in the baseline x86-64 code beside its AVX2
//! copy. Run with `cargo bench -p twin-core`.

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::{SMatrix, SVector, Vector2, Vector4};
use std::hint::black_box;
use twin_core::aekf::{Aekf, AekfConfig, AekfError, AekfState, GainSensitivity, StepReport};
use twin_core::model::Measurement;
use twin_core::models::kinematic::{KinematicInput, KinematicModel};

fn seed_config() -> AekfConfig<4, 4, 2> {
    AekfConfig {
        process_noise_density: SMatrix::identity() * 0.05,
        measurement_noise: SMatrix::identity() * 0.04,
        forgetting_time_constant_s: 40.0,
        fault_memory_factor: SVector::repeat(1.0),
        initial_fault_covariance: SMatrix::identity() * 0.1,
        anti_windup_ratio: 0.1,
        excitation_sigma: 0.02,
        noise_adaptation: None,
        gain_sensitivity: GainSensitivity::Omitted,
        gain_sensitivity_faults: [true; _],
    }
}

/// 600 steps of a turning, accelerating vessel (inputs and measurements
/// precomputed so the benchmark times the filter only).
fn trial() -> Vec<(KinematicInput, Measurement<4>)> {
    let dt = 0.2;
    let mut x = Vector4::new(0.0, 0.0, 1.5, 0.0);
    (0..600)
        .map(|k| {
            let t = k as f64 * dt;
            let u = KinematicInput {
                accel_mps2: 0.05 * (0.3 * t).sin(),
                course_rate_radps: 0.1 * (0.1 * t).sin(),
            };
            x = Vector4::new(
                x[0] + dt * x[2] * x[3].cos(),
                x[1] + dt * x[2] * x[3].sin(),
                x[2] + dt * 0.9 * u.accel_mps2,
                x[3] + dt * 0.8 * u.course_rate_radps,
            );
            (u, Measurement::full(x))
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let config = seed_config();
    let filter = Aekf::new(KinematicModel, config).unwrap();
    let data = trial();
    let start = AekfState::new(
        &config,
        Vector4::new(0.0, 0.0, 1.5, 0.0),
        SMatrix::identity(),
        Vector2::zeros(),
    );

    type SeedFilter = Aekf<KinematicModel, 4, 4, 2>;
    type SeedStep = fn(
        &SeedFilter,
        &mut AekfState<4, 4, 2>,
        &KinematicInput,
        &Measurement<4>,
        f64,
    ) -> Result<StepReport<4, 2>, AekfError>;
    // The step as the twin runs it (the AVX2 copy where the processor has
    // it), then the same step in the baseline x86-64 code
    // (`twin_core::simd`), one beside the other.
    let steps: [(&str, SeedStep); 2] = [
        ("aekf_step_seed_model", SeedFilter::step),
        (
            "aekf_step_seed_model_baseline_code",
            SeedFilter::step_baseline,
        ),
    ];
    for (name, step) in steps {
        c.bench_function(name, |b| {
            let mut est = start;
            let mut k = 0usize;
            b.iter(|| {
                let (u, y) = &data[k % data.len()];
                if k.is_multiple_of(data.len()) {
                    est = start;
                }
                k += 1;
                black_box(step(&filter, &mut est, black_box(u), black_box(y), 0.2).unwrap());
            });
        });
    }

    c.bench_function("trial_120s_seed_model", |b| {
        b.iter(|| {
            let mut est = start;
            for (u, y) in &data {
                filter.step(&mut est, u, y, 0.2).unwrap();
            }
            black_box(est.theta)
        });
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
