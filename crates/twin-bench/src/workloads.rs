//! The workloads that the `core` measurements and the criterion benches
//! share, so both time the same things: simulated trials (`twin-sim`) as the
//! twin receives them, the extended twin's filter steps recorded from a
//! trial, the real logs of `tests/fixtures/real`, and a synthetic 4-hour log.

use std::fmt::Write as _;
use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use twin_core::estimator::{
    CourseGate, KineticBase, KineticOptions, KineticState, LocalFix, ShaftAccumulator,
};
use twin_core::model::Measurement;
use twin_core::models::otter_twin::{MEASUREMENTS, ShaftSpeeds, meas};
use twin_core::sample::{GnssFix, PropellerSpeeds};
use twin_core::twin::{TwinConfig, VesselTwin};
use twin_sim::{Scenario, SensorEvent, SimRun};

use crate::trial::Timing;

/// The workspace root (for `config/`, `data/` and `tests/fixtures/`).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .components()
        .collect()
}

/// A scenario file of `config/scenarios/` (name without `.toml`).
pub fn scenario(name: &str) -> anyhow::Result<Scenario> {
    let path = workspace_root().join(format!("config/scenarios/{name}.toml"));
    let text =
        std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
    Scenario::from_toml_str(&text).with_context(|| format!("scenario {}", path.display()))
}

/// Simulates a scenario file of `config/scenarios/`.
pub fn simulate(name: &str) -> anyhow::Result<SimRun> {
    twin_sim::simulate(&scenario(name)?).with_context(|| format!("simulating {name}"))
}

/// What the twin is fed, in time order.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TwinInput {
    /// A GNSS fix (with the heading sensor's sample joined, as in the logs).
    Fix(GnssFix),
    /// Measured shaft speeds.
    Propellers(PropellerSpeeds),
}

/// A simulated trial as the twin receives it: the GNSS fixes with the
/// heading joined (as `twin simulate` writes them) and the measured shaft
/// speeds, in time order.
pub fn twin_inputs(run: &SimRun) -> Vec<TwinInput> {
    let mut fixes = twin_cli::simulate::fixes_as_logged(run).into_iter();
    run.events
        .iter()
        .filter_map(|e| match e {
            SensorEvent::Gnss(_) => fixes.next().map(TwinInput::Fix),
            SensorEvent::PropellerMeasured(p) => Some(TwinInput::Propellers(*p)),
            _ => None,
        })
        .collect()
}

/// Number of GNSS fixes among `inputs`.
pub fn fix_count(inputs: &[TwinInput]) -> usize {
    inputs
        .iter()
        .filter(|i| matches!(i, TwinInput::Fix(_)))
        .count()
}

/// Feeds `inputs` to a fresh twin with `config` (rejections ignored) and
/// returns it.
pub fn run_twin(inputs: &[TwinInput], config: TwinConfig) -> VesselTwin {
    let mut twin = VesselTwin::new(config).expect("the default configuration is valid");
    feed(&mut twin, inputs);
    twin
}

/// Feeds `inputs` to `twin`, ignoring rejections.
#[inline(never)]
pub fn feed(twin: &mut VesselTwin, inputs: &[TwinInput]) {
    for input in inputs {
        match input {
            TwinInput::Fix(f) => {
                let _ = black_box(twin.on_gnss(black_box(f)));
            }
            TwinInput::Propellers(p) => {
                let _ = black_box(twin.on_propellers(black_box(p)));
            }
        }
    }
}

/// The extended twin's filter (`OtterTwin`: 10 states, 6 measurements, 6
/// faults) as `VesselTwin` runs it.
pub use twin_core::estimator::KineticFilter;

/// One step of the extended twin's filter.
#[derive(Debug, Clone, Copy)]
pub struct KineticStep {
    /// Mean shaft speeds since the previous fix.
    pub input: ShaftSpeeds,
    /// The fix as the filter's measurement.
    pub y: Measurement<MEASUREMENTS>,
    /// The course's variance for the fix's speed, rad², which the twin's
    /// base sets before the step (`KineticBase::course_variance`).
    pub course_variance: f64,
    /// Time since the previous fix, s.
    pub dt_s: f64,
}

/// The extended twin's filter steps of a trial, recorded as `VesselTwin`
/// takes them, to be replayed through the bare filter.
#[derive(Debug, Clone)]
pub struct KineticSteps {
    /// The filter, configured as the twin's.
    pub filter: KineticFilter,
    /// The estimate before the first recorded step.
    pub start: KineticState,
    /// The steps.
    pub steps: Vec<KineticStep>,
    /// The twin's own estimate after the last step (to check a replay).
    pub twin_end: KineticState,
}

/// Records the extended twin's filter steps over `inputs` with `config`:
/// runs a `VesselTwin` and, beside it, takes each step's input (the mean of
/// the shaft speeds since the previous fix) and measurement from the same
/// estimator base as the twin. Requires a trial with shaft speeds, current
/// estimated and no restarts (a simulated trial).
pub fn kinetic_steps(inputs: &[TwinInput], config: TwinConfig) -> anyhow::Result<KineticSteps> {
    anyhow::ensure!(
        config.kinetic.estimate_current,
        "recording needs the current estimated (the twin zeroes it otherwise)"
    );
    let gate = CourseGate {
        min_sog_mps: config.gating.min_sog_for_course_mps,
    };
    let base = KineticBase::new(
        &config.kinetic,
        gate,
        KineticOptions::live(true, config.kinetic.estimate_yaw_rate_bias),
    )
    .map_err(|e| anyhow::anyhow!("the extended twin's filter: {e}"))?;
    let mut twin = VesselTwin::new(config).map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut start = None;
    let mut steps = Vec::new();
    let mut shafts = ShaftAccumulator::default();
    let mut last_fix_s: Option<f64> = None;
    for input in inputs {
        match input {
            TwinInput::Propellers(p) => {
                if twin.on_propellers(p).is_ok() {
                    shafts.push(p);
                }
            }
            TwinInput::Fix(fix) => {
                let before = twin.kinetic_state().copied();
                let samples = shafts.count();
                if twin.on_gnss(fix).is_err() {
                    continue;
                }
                let mean = shafts.take(fix.time_s, 0.0).filter(|_| samples > 0);
                let (Some(before), Some(u), Some(t0), Some(frame)) =
                    (before, mean, last_fix_s, twin.frame().copied())
                else {
                    last_fix_s = Some(fix.time_s);
                    continue;
                };
                last_fix_s = Some(fix.time_s);
                start.get_or_insert(before);
                let local = LocalFix::from_gnss(fix, &frame);
                steps.push(KineticStep {
                    input: u,
                    y: base.measurement(&local),
                    course_variance: base.course_variance(&local),
                    dt_s: fix.time_s - t0,
                });
            }
        }
    }
    let start = start.context("no extended-twin step in the trial (no shaft speeds?)")?;
    let twin_end = *twin
        .kinetic_state()
        .context("the extended twin is not running at the end of the trial")?;
    Ok(KineticSteps {
        filter: base.filter().clone(),
        start,
        steps,
        twin_end,
    })
}

impl KineticSteps {
    /// Replays every step once through the filter from the start; the
    /// estimate at the end.
    pub fn run_once(&self) -> KineticState {
        self.run_once_in(StepCode::Dispatched)
    }

    /// [`Self::run_once`] in the given copy of the step's code.
    #[inline(never)]
    pub fn run_once_in(&self, code: StepCode) -> KineticState {
        let mut est = self.start;
        for s in &self.steps {
            let (input, y, dt_s) = (black_box(&s.input), black_box(&s.y), black_box(s.dt_s));
            est.measurement_noise[(meas::COG, meas::COG)] = black_box(s.course_variance);
            let r = match code {
                StepCode::Dispatched => self.filter.step(black_box(&mut est), input, y, dt_s),
                StepCode::Baseline => {
                    self.filter
                        .step_baseline(black_box(&mut est), input, y, dt_s)
                }
            };
            black_box(&r);
        }
        black_box(est)
    }

    /// Times `repeats` replays (after one warm-up), per step.
    pub fn time(&self, repeats: usize) -> Timing {
        per_item(self.steps.len(), repeats, || {
            black_box(self.run_once());
        })
    }

    /// Times the step's two copies side by side, alternating replays.
    pub fn time_both_copies(&self, repeats: usize) -> [Timing; 2] {
        per_item_both_copies(self.steps.len(), repeats, |code| {
            black_box(self.run_once_in(code));
        })
    }
}

/// Which compiled copy of the filter's step a benchmark runs
/// (`twin_core::simd`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StepCode {
    /// `Aekf::step`: the AVX2 copy where the processor has AVX2.
    Dispatched,
    /// `Aekf::step_baseline`: the baseline x86-64 code everywhere.
    Baseline,
}

/// Times `work` in both copies of the step's code, `repeats` runs each,
/// alternating so that both see the same state of a shared machine;
/// `[dispatched, baseline]`.
pub fn per_item_both_copies(
    items: usize,
    repeats: usize,
    mut work: impl FnMut(StepCode),
) -> [Timing; 2] {
    let codes = [StepCode::Dispatched, StepCode::Baseline];
    let mut ns = [Vec::new(), Vec::new()];
    for _ in 0..=repeats.max(1) {
        for (code, times) in codes.iter().zip(ns.iter_mut()) {
            let t0 = Instant::now();
            work(*code);
            times.push(t0.elapsed().as_nanos() as f64);
        }
    }
    ns.map(|mut times| {
        times.remove(0); // the warm-up run
        timing_of(&mut times, items)
    })
}

/// Times `repeats` runs of `work` (after one warm-up run) and gives the
/// median and the fastest per item, `items` items per run.
pub fn per_item(items: usize, repeats: usize, mut work: impl FnMut()) -> Timing {
    let repeats = repeats.max(1);
    work();
    let mut ns: Vec<f64> = (0..repeats)
        .map(|_| {
            let t0 = Instant::now();
            work();
            t0.elapsed().as_nanos() as f64
        })
        .collect();
    timing_of(&mut ns, items)
}

/// Median and fastest of whole-run times `ns` (sorted in place), per item.
fn timing_of(ns: &mut [f64], items: usize) -> Timing {
    let items = items.max(1) as f64;
    Timing {
        ns_per_step_median: median(ns) / items,
        ns_per_step_min: ns[0] / items,
        repeats: ns.len(),
    }
}

/// The median of `values` (sorted in place; NaN last). 0 for none.
pub fn median(values: &mut [f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    values.sort_by(f64::total_cmp);
    let n = values.len();
    if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    }
}

/// A real log of `tests/fixtures/real` (file name).
pub fn real_log(name: &str) -> PathBuf {
    workspace_root().join("tests/fixtures/real").join(name)
}

/// The bundled demo trial's log (JSON lines, 5 min, GNSS 5 Hz with
/// heading, shaft speeds 10 Hz).
pub fn demo_log() -> PathBuf {
    workspace_root().join(twin_cli::demo::LOG)
}

/// The logs parsed per format: (format, file).
pub fn parse_logs() -> Vec<(&'static str, PathBuf)> {
    vec![
        ("JSON lines (contract)", demo_log()),
        ("NMEA 0183", real_log("plaka.log")),
        ("NMEA 2000, canboat plain", real_log("aava-n2k.data")),
        (
            "NMEA 2000, canboat FAST",
            real_log("furuno-130842-figure8-fast.raw"),
        ),
    ]
}

/// Reads a whole log from memory through `twin-wire`'s reader (format
/// picked by content); the number of records and of rejections.
#[inline(never)]
pub fn parse_all(bytes: &[u8]) -> (u64, u64) {
    let options = twin_wire::read::ReadOptions::default();
    let Ok(reader) = twin_wire::read::LogReader::open(bytes, options) else {
        return (0, 0);
    };
    let (mut records, mut rejected) = (0, 0);
    for item in reader {
        match black_box(item) {
            Ok(_) => records += 1,
            Err(_) => rejected += 1,
        }
    }
    (records, rejected)
}

/// Duration of the synthetic long log, s (4 h).
pub const LONG_LOG_S: f64 = 4.0 * 3600.0;

/// A scenario of `duration_s` seconds: the Otter on a serpentine of 180 deg
/// turns (radius 20 m, as in the demo trial) going east for as long as it
/// takes, port propeller 20 % down, GNSS 5 Hz with heading, shaft speeds
/// 10 Hz, harbour disturbance and a weak current.
pub fn serpentine_scenario(duration_s: f64) -> anyhow::Result<Scenario> {
    // Each turn: 63 m of arc plus 20 m of straight; 1.5 m/s.
    let turns = (duration_s * 1.5 / 80.0).ceil() as usize + 2;
    let mut waypoints = String::from("  { north_m = 0.0, east_m = 0.0 },\n");
    for k in 0..turns {
        let centre_east = 20.0 + 40.0 * k as f64;
        let side = if k % 2 == 0 { 1.0 } else { -1.0 };
        // The first point of a turn is the last of the one before.
        for step in (if k == 0 { 0 } else { 1 })..=6 {
            let a = std::f64::consts::PI * f64::from(step) / 6.0;
            let north = 25.0 + side * 20.0 * a.sin();
            let east = centre_east - 20.0 * a.cos();
            let _ = writeln!(
                waypoints,
                "  {{ north_m = {north:.2}, east_m = {east:.2} }},"
            );
        }
    }
    let text = format!(
        r#"name = "serpentine-long"
description = "twin-bench: a long serpentine for the offline-analysis benchmark"
duration_s = {duration_s}
seed = 7
start_time = 2024-06-01T10:00:00Z
step_s = 0.02
[origin]
lat_deg = 62.47
lon_deg = 6.15
[path]
speed_mps = 1.5
waypoints = [
{waypoints}]
[propellers.port]
loss = 0.2
[current]
speed_mps = 0.1
toward_deg = 120.0
[disturbance]
[sensors.gnss]
rate_hz = 5.0
[sensors.propellers]
rate_hz = 10.0
[sensors.heading]
enabled = true
rate_hz = 5.0
"#
    );
    Scenario::from_toml_str(&text).context("the serpentine scenario")
}

/// Writes a simulated log of `duration_s` seconds (JSON lines) to `path`;
/// its size in bytes and the number of fixes.
pub fn write_long_log(path: &Path, duration_s: f64) -> anyhow::Result<(u64, usize)> {
    let run = twin_sim::simulate(&serpentine_scenario(duration_s)?)?;
    let file =
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
    let summary = twin_cli::simulate::write_jsonl(&run, std::io::BufWriter::new(file))
        .map_err(|e| anyhow::anyhow!("writing {}: {e}", path.display()))?;
    let size = std::fs::metadata(path)?.len();
    Ok((size, summary.fixes))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Replaying the recorded steps through the bare filter gives the twin's
    /// own estimate, bit for bit, in both copies of the step's code: the
    /// benchmark times what the twin does, and its side-by-side row compares
    /// two copies that compute the same thing.
    #[test]
    fn recorded_kinetic_steps_replay_to_the_twins_estimate() {
        let run = simulate("s-manoeuvre_new-broken").unwrap();
        let inputs = twin_inputs(&run);
        let k = kinetic_steps(&inputs, TwinConfig::default()).unwrap();
        assert!(k.steps.len() > 500, "{} steps", k.steps.len());
        assert_eq!(k.run_once(), k.twin_end);
        assert_eq!(k.run_once_in(StepCode::Baseline), k.twin_end);
    }

    #[test]
    fn every_log_parses_to_records() {
        for (format, path) in parse_logs() {
            let bytes = std::fs::read(&path).unwrap();
            let (records, _) = parse_all(&bytes);
            assert!(records > 1000, "{format}: {records} records");
        }
    }

    #[test]
    fn the_serpentine_is_a_valid_scenario() {
        let s = serpentine_scenario(600.0).unwrap();
        assert_eq!(s.duration_s, 600.0);
    }
}
