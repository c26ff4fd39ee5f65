//! `cargo bench -p twin-cli --bench identify`: `twin identify` on a
//! 10-minute 5 Hz trial (the identification trial of
//! `config/scenarios/identify_heavy-otter.toml`, run for 10 minutes: steps
//! of thrust, turns both ways, a zig-zag). Target: under 10 s. The log is
//! simulated and read once; only the identification is timed.

use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use twin_cli::demo::workspace_root;
use twin_cli::diagnose::load;
use twin_cli::simulate::{OutputFormat, simulate_to_bytes};
use twin_core::diagnose::{IdentifyConfig, identify, prepare};
use twin_core::vessel::VesselParams;
use twin_sim::Scenario;
use twin_wire::SourceChoice;

fn bench_identify(c: &mut Criterion) {
    let path = workspace_root().join("config/scenarios/identify_heavy-otter.toml");
    let mut scenario = Scenario::from_path(&path).expect("the identification scenario");
    scenario.duration_s = 600.0;
    let (bytes, _) = simulate_to_bytes(&scenario, OutputFormat::Nmea).expect("simulated");
    let log = load(&bytes[..], Path::new("trial.nmea"), SourceChoice::Best).expect("read");
    let prep = prepare(&log.events).expect("prepared");
    let config = IdentifyConfig::default();
    let start = VesselParams::default();
    let mut group = c.benchmark_group("identify");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(60));
    group.bench_function("trial_10min_5hz", |b| {
        b.iter(|| {
            let found = identify(black_box(&prep), &start, &config).expect("identified");
            black_box(found.rounds)
        })
    });
    group.finish();
}

criterion_group!(benches, bench_identify);
criterion_main!(benches);
