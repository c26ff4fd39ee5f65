//! Criterion benchmarks of what `twin-bench core` measures beyond
//! `twin-core`'s own `aekf_step` bench: one AEKF step of the extended model
//! (target: under 1 us), the forecast rollout (60 s at 1 s), the whole twin
//! over a 120 s trial, and parsing per format with `Throughput::Bytes` (MB/s).
//! Run with `cargo bench -p twin-bench --bench core`.

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use twin_bench::workloads;
use twin_core::twin::TwinConfig;

fn bench_estimator(c: &mut Criterion) {
    let config = TwinConfig::default();
    let demo = workloads::simulate("demo_broken-port").expect("the demo scenario");
    let inputs = workloads::twin_inputs(&demo);
    let kinetic = workloads::kinetic_steps(&inputs, config).expect("extended-twin steps");

    c.bench_function("aekf_step_extended_model", |b| {
        let mut est = kinetic.start;
        let mut k = 0usize;
        b.iter(|| {
            if k == kinetic.steps.len() {
                est = kinetic.start;
                k = 0;
            }
            let s = &kinetic.steps[k];
            k += 1;
            let r = kinetic
                .filter
                .step(&mut est, black_box(&s.input), black_box(&s.y), s.dt_s);
            black_box(&r);
        });
    });

    let twin = workloads::run_twin(&inputs, config);
    c.bench_function("forecast_60s_extended_twin", |b| {
        b.iter(|| black_box(twin.forecast(black_box(60.0), 1.0)))
    });

    let s_run = workloads::simulate("s-manoeuvre_new-broken").expect("the S-manoeuvre");
    let s_inputs = workloads::twin_inputs(&s_run);
    c.bench_function("trial_120s_whole_twin", |b| {
        b.iter(|| black_box(workloads::run_twin(&s_inputs, config)))
    });
}

fn bench_parsing(c: &mut Criterion) {
    let mut group = c.benchmark_group("parse");
    group.measurement_time(Duration::from_secs(5));
    group.sample_size(20);
    for (format, path) in workloads::parse_logs() {
        let bytes = std::fs::read(&path).expect("the log");
        group.throughput(Throughput::Bytes(bytes.len() as u64));
        group.bench_function(format, |b| {
            b.iter(|| black_box(workloads::parse_all(black_box(&bytes))))
        });
    }
    group.finish();
}

criterion_group!(benches, bench_estimator, bench_parsing);
criterion_main!(benches);
