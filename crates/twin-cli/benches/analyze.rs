//! `cargo bench -p twin-cli --bench analyze`: `twin analyze` (the library
//! call behind it, without printing) on the 4-hour real log
//! `tests/fixtures/real/plaka.log` (NMEA 0183, 116 000 lines, 7250 fixes),
//! and on the 5-minute demo trial with propeller speeds (the extended twin).
//! The target: a 4-hour log in well under a second.

use std::hint::black_box;
use std::path::PathBuf;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use twin_cli::analyze::{AnalyzeOptions, analyze_path};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn bench_analyze(c: &mut Criterion) {
    let mut group = c.benchmark_group("analyze");
    group.sample_size(20);
    group.measurement_time(Duration::from_secs(10));
    let options = AnalyzeOptions::default();
    for (name, path) in [
        (
            "plaka_4h_nmea0183",
            root().join("tests/fixtures/real/plaka.log"),
        ),
        (
            "demo_5min_jsonl_extended_twin",
            root().join(twin_cli::demo::LOG),
        ),
    ] {
        group.bench_function(name, |b| {
            b.iter(|| {
                let a = analyze_path(black_box(&path), &options).expect("the log analyses");
                black_box(a.samples)
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench_analyze);
criterion_main!(benches);
