//! What the hidden-effect tests on the project's simulator share: the
//! base trial, the seeded draw of one hidden effect, its planting in the
//! scenario, and the diagnosis of the simulated log (read as a user's log
//! would be; the truth is never an input).
//!
//! With `TWIN_KEEP_DRAWS=DIR` in the environment, each simulated log is
//! also written to `DIR/{name}.jsonl`, so that a draw can be run again
//! with `twin diagnose` (or timed) as a user's log.

use std::io::Cursor;
use std::path::Path;

use rand::Rng;
use rand::rngs::StdRng;
use twin_cli::diagnose::{DiagnoseReport, diagnose_loaded, load};
use twin_cli::simulate::{OutputFormat, simulate_to_bytes};
use twin_core::diagnose::DiagnoseConfig;
use twin_sim::{CurrentSpec, Scenario};
use twin_wire::SourceChoice;
use twin_wire::profile::VesselProfile;

use super::hidden::Hidden;

pub fn base() -> Scenario {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../config/scenarios/diagnose_base.toml"
    );
    Scenario::from_toml_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

pub fn draw(rng: &mut StdRng) -> Hidden {
    let sign = |rng: &mut StdRng| if rng.random_bool(0.5) { 1.0 } else { -1.0 };
    match rng.random_range(0..6) {
        0 => Hidden::Nothing,
        1 => Hidden::Current {
            speed_mps: rng.random_range(0.1..0.5),
            toward_deg: rng.random_range(0.0..360.0),
        },
        2 => Hidden::HeadingOffset {
            offset_deg: sign(rng) * rng.random_range(2.0..10.0),
        },
        3 => Hidden::SogScale {
            scale: 1.0 + sign(rng) * rng.random_range(0.02..0.08),
        },
        4 => Hidden::Latency {
            latency_s: rng.random_range(0.2..1.0),
        },
        _ => Hidden::Loss {
            port: rng.random_bool(0.5),
            loss: rng.random_range(0.1..0.4),
        },
    }
}

pub fn apply(sc: &mut Scenario, h: Hidden) {
    match h {
        Hidden::Nothing => {}
        Hidden::Current {
            speed_mps,
            toward_deg,
        } => {
            sc.current = Some(CurrentSpec {
                speed_mps,
                toward_deg,
                rotation_deg_s: 0.0,
                speed_amplitude_mps: 0.0,
                speed_period_s: 600.0,
            })
        }
        Hidden::HeadingOffset { offset_deg } => sc.sensors.heading.offset_deg = offset_deg,
        Hidden::SogScale { scale } => sc.sensors.gnss.sog_scale = scale,
        // The simulator stamps a fix with its true time minus `latency_s`:
        // data older than their stamps is a negative value there.
        Hidden::Latency { latency_s } => sc.sensors.gnss.latency_s = -latency_s,
        Hidden::Loss { port: true, loss } => sc.propellers.port.loss = loss,
        Hidden::Loss { port: false, loss } => sc.propellers.starboard.loss = loss,
        Hidden::YawRateScale { scale } => {
            sc.sensors.yaw_rate.enabled = true;
            sc.sensors.yaw_rate.scale = scale;
        }
        Hidden::YawRateBias { bias_deg_s } => {
            sc.sensors.yaw_rate.enabled = true;
            sc.sensors.yaw_rate.bias_deg_s = bias_deg_s;
        }
    }
}

/// The diagnosis of `sc`'s simulated log, read as a user's log under
/// `name` (also its file's name under `TWIN_KEEP_DRAWS`).
pub fn diagnose_scenario(sc: &Scenario, name: &str) -> DiagnoseReport {
    diagnose_scenario_on(sc, name, &VesselProfile::otter())
}

/// [`diagnose_scenario`] on the vessel profile `profile`.
pub fn diagnose_scenario_on(sc: &Scenario, name: &str, profile: &VesselProfile) -> DiagnoseReport {
    let (bytes, _) = simulate_to_bytes(sc, OutputFormat::JsonLines).unwrap();
    if let Some(dir) = std::env::var_os("TWIN_KEEP_DRAWS") {
        let path = Path::new(&dir).join(format!("{name}.jsonl"));
        std::fs::write(&path, &bytes).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    }
    let log = load(Cursor::new(bytes), Path::new(name), SourceChoice::Best).unwrap();
    diagnose_loaded(name, &log, &DiagnoseConfig::default(), profile).unwrap()
}

/// `f` over the items on two threads (the machine has two cores), the
/// results in the items' order.
pub fn on_two_threads<T: Sync, R: Send>(items: &[T], f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    std::thread::scope(|s| {
        let handles: Vec<_> = items
            .chunks(items.len().div_ceil(2).max(1))
            .map(|chunk| s.spawn(|| chunk.iter().map(&f).collect::<Vec<R>>()))
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap())
            .collect()
    })
}
