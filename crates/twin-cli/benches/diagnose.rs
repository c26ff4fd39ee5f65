//! `cargo bench -p twin-cli --bench diagnose`: the whole `twin diagnose`
//! catalogue (nominal residuals, every cause fitted and judged on held-out
//! data, greedy rounds) on a 5-minute 5 Hz log. Target: under 2 s.
//!
//! Cases: the bundled demo trial (5 min, 5 Hz GNSS + heading, 10 Hz shaft
//! speeds: the kinetic base, the heavier one), on one thread and on two
//! (this machine class has two cores); the diagnose tests' base trial on a
//! hull 28 % heavier than the profile's, in a current of 0.2 m/s (two
//! findings, the mass's size fitted again with the process noise's levels:
//! the heaviest path), on one thread; and a real 6-minute log without
//! propeller data (`furuno-130842-figure8-fast.raw`, 2600 fixes: the water
//! base). The log is read once; only the diagnosis is timed.

use std::fs::File;
use std::hint::black_box;
use std::io::{BufReader, Cursor};
use std::path::Path;
use std::path::PathBuf;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use twin_cli::diagnose::{LoadedLog, diagnose_loaded, load};
use twin_cli::simulate::{OutputFormat, simulate_to_bytes};
use twin_core::diagnose::DiagnoseConfig;
use twin_sim::{CurrentSpec, Scenario, VesselSpec};
use twin_wire::SourceChoice;
use twin_wire::profile::VesselProfile;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn read(path: &PathBuf) -> LoadedLog {
    let file = File::open(path).expect("the log opens");
    load(BufReader::new(file), path, SourceChoice::Best).expect("the log reads")
}

/// The diagnose tests' base trial on a hull 28 % heavier (its added mass
/// too) in a current of 0.2 m/s toward 300 deg.
fn heavier_hull_in_a_current() -> LoadedLog {
    let path = root().join("config/scenarios/diagnose_base.toml");
    let text = std::fs::read_to_string(&path).expect("the base trial reads");
    let mut sc = Scenario::from_toml_str(&text).expect("the base trial parses");
    sc.vessel = Some(VesselSpec {
        mass_scale: 1.28,
        added_mass_scale: 1.28,
        ..VesselSpec::default()
    });
    sc.current = Some(CurrentSpec {
        speed_mps: 0.2,
        toward_deg: 300.0,
        rotation_deg_s: 0.0,
        speed_amplitude_mps: 0.0,
        speed_period_s: 600.0,
    });
    let (bytes, _) = simulate_to_bytes(&sc, OutputFormat::JsonLines).expect("it simulates");
    load(Cursor::new(bytes), Path::new("heavier"), SourceChoice::Best).expect("the log reads")
}

fn bench_diagnose(c: &mut Criterion) {
    let mut group = c.benchmark_group("diagnose");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(20));
    let demo = read(&root().join(twin_cli::demo::LOG));
    let furuno = read(&root().join("tests/fixtures/real/furuno-130842-figure8-fast.raw"));
    let heavier = heavier_hull_in_a_current();
    for (name, log, threads) in [
        ("demo_5min_5hz_kinetic_1_thread", &demo, 1),
        ("demo_5min_5hz_kinetic_2_threads", &demo, 2),
        (
            "heavier_hull_current_5min_5hz_kinetic_1_thread",
            &heavier,
            1,
        ),
        ("furuno_6min_7hz_water_2_threads", &furuno, 2),
    ] {
        let config = DiagnoseConfig {
            threads,
            ..DiagnoseConfig::default()
        };
        group.bench_function(name, |b| {
            b.iter(|| {
                let r = diagnose_loaded(name, black_box(log), &config, &VesselProfile::otter())
                    .expect("diagnosable");
                black_box(r.findings.len())
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench_diagnose);
criterion_main!(benches);
