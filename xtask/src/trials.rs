//! The seed's sea-trial matrix, re-run in the project's Otter simulator with
//! known truth, and the prediction comparison of the seed's Table 4.9.
//!
//! The seed ran four propeller sets over two paths (a 60 s straight line and
//! a 120 s S-manoeuvre) at Alesund with 5 Hz GNSS. Here each cell is a
//! simulated trial (`twin-sim`, the truth) on the same paths, plus losses of
//! 10-40 % on either side, three noise seeds each, optionally in a current.
//! Every cell is judged by three estimators run over the same data:
//! - the seed's method (GNSS-derived inputs, kinematic AEKF, step 4);
//! - the extended twin (propeller speeds, kinetic AEKF, water current);
//! - the extended twin without its current state.

use twin_core::decision::ThrusterStatus;
use twin_core::geodesy::{LocalFrame, wrap_pi};
use twin_core::models::kinematic::KinematicInput;
use twin_core::models::otter_twin::ShaftSpeeds;
use twin_core::sample::PropellerSpeeds;
use twin_core::twin::{FaultSource, TwinConfig, VesselTwin};
use twin_sim::{CurrentSpec, Scenario, SensorEvent, SimRun};

/// The two paths of the seed's trials.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TrialPath {
    /// Path 1: a 60 s straight line.
    Straight,
    /// Path 2: a 120 s S-manoeuvre.
    SManoeuvre,
}

impl TrialPath {
    /// Both paths.
    pub const BOTH: [TrialPath; 2] = [TrialPath::Straight, TrialPath::SManoeuvre];

    /// Name as in the scenario files.
    pub fn name(self) -> &'static str {
        match self {
            TrialPath::Straight => "straight",
            TrialPath::SManoeuvre => "s-manoeuvre",
        }
    }

    /// The scenario file this path comes from (the healthy set; losses and
    /// currents are set per cell).
    fn base_scenario(self) -> &'static str {
        match self {
            TrialPath::Straight => include_str!("../../config/scenarios/straight_new-new.toml"),
            TrialPath::SManoeuvre => {
                include_str!("../../config/scenarios/s-manoeuvre_new-new.toml")
            }
        }
    }
}

/// A propeller set: what is fitted and the true loss of each propeller.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PropellerSet {
    /// Name, starboard first as in the thesis tables (e.g. `new/broken`).
    pub name: &'static str,
    /// True loss of the port propeller.
    pub port_loss: f64,
    /// True loss of the starboard propeller.
    pub starboard_loss: f64,
}

impl PropellerSet {
    /// The true losses `[port, starboard]`.
    pub fn losses(&self) -> [f64; 2] {
        [self.port_loss, self.starboard_loss]
    }
}

/// The seed's four propeller sets; the broken port propeller's loss is a
/// chosen value (the seed's own estimate, 18 %). "Original" and "new" are
/// taken as healthy: the replica's true efficiency was never measured.
pub fn seed_sets(broken_loss: f64) -> Vec<PropellerSet> {
    vec![
        PropellerSet {
            name: "original/original",
            port_loss: 0.0,
            starboard_loss: 0.0,
        },
        PropellerSet {
            name: "new/original",
            port_loss: 0.0,
            starboard_loss: 0.0,
        },
        PropellerSet {
            name: "new/new",
            port_loss: 0.0,
            starboard_loss: 0.0,
        },
        PropellerSet {
            name: "new/broken",
            port_loss: broken_loss,
            starboard_loss: 0.0,
        },
    ]
}

/// Losses of 10, 20, 30 and 40 % on the port, then the starboard propeller.
pub fn loss_sets() -> Vec<PropellerSet> {
    const PORT: [&str; 4] = [
        "healthy/port-10",
        "healthy/port-20",
        "healthy/port-30",
        "healthy/port-40",
    ];
    const STB: [&str; 4] = [
        "stb-10/healthy",
        "stb-20/healthy",
        "stb-30/healthy",
        "stb-40/healthy",
    ];
    let mut v = Vec::new();
    for (i, l) in [0.1, 0.2, 0.3, 0.4].into_iter().enumerate() {
        v.push(PropellerSet {
            name: PORT[i],
            port_loss: l,
            starboard_loss: 0.0,
        });
    }
    for (i, l) in [0.1, 0.2, 0.3, 0.4].into_iter().enumerate() {
        v.push(PropellerSet {
            name: STB[i],
            port_loss: 0.0,
            starboard_loss: l,
        });
    }
    v
}

/// A water current.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Current {
    /// Speed, m/s.
    pub speed_mps: f64,
    /// Direction the water flows toward, degrees true.
    pub toward_deg: f64,
}

/// One cell of the matrix.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cell {
    /// The path.
    pub path: TrialPath,
    /// The propellers.
    pub set: PropellerSet,
    /// The current, if any.
    pub current: Option<Current>,
    /// The noise seed.
    pub seed: u64,
}

/// The matrix: the seed's sets and the loss sets, both paths, `seeds` noise
/// seeds each; with `current_mps > 0` each seed gets a current of that speed
/// toward 047, 167 and 287 deg (cycling).
pub fn matrix(seeds: u64, current_mps: f64) -> Vec<Cell> {
    let mut sets = seed_sets(0.18);
    sets.extend(loss_sets());
    let mut cells = Vec::new();
    for path in TrialPath::BOTH {
        for set in &sets {
            for seed in 0..seeds {
                let current = (current_mps > 0.0).then(|| Current {
                    speed_mps: current_mps,
                    toward_deg: [47.0, 167.0, 287.0][(seed % 3) as usize],
                });
                cells.push(Cell {
                    path,
                    set: *set,
                    current,
                    seed: 1000 + seed,
                });
            }
        }
    }
    cells
}

/// The scenario of a cell.
pub fn scenario(cell: &Cell) -> Scenario {
    let mut sc = Scenario::from_toml_str(cell.path.base_scenario())
        .expect("the bundled scenario files parse");
    sc.name = format!("{}_{}", cell.path.name(), cell.set.name);
    sc.seed = cell.seed;
    sc.propellers.port.loss = cell.set.port_loss;
    sc.propellers.starboard.loss = cell.set.starboard_loss;
    sc.current = cell.current.map(|c| CurrentSpec {
        speed_mps: c.speed_mps,
        toward_deg: c.toward_deg,
        rotation_deg_s: 0.0,
        speed_amplitude_mps: 0.0,
        speed_period_s: 600.0,
    });
    sc
}

/// What an estimator concluded about one cell.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExtendedResult {
    /// Final loss estimates `[port, starboard]`.
    pub loss: [f64; 2],
    /// Their standard deviations.
    pub sigma: [f64; 2],
    /// Whether each was excited at the end.
    pub excited: [bool; 2],
    /// The decision about each at the end.
    pub status: [ThrusterStatus; 2],
    /// The port/starboard effectiveness ratio and its standard deviation.
    pub effectiveness_ratio: (f64, f64),
}

impl ExtendedResult {
    /// The side(s) the twin names: those with a suspect or fault status.
    pub fn named(&self) -> [bool; 2] {
        self.status.map(|s| s >= ThrusterStatus::Suspect)
    }
}

/// The seed's method over one cell.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SeedResult {
    /// Final input faults `[theta_a, theta_r]`.
    pub input_faults: [f64; 2],
    /// Peak per-thruster value of step 4 over the run `[port, starboard]`
    /// (the seed reported peaks).
    pub thruster_peak: [f64; 2],
    /// Correlation of the step-4 values (magnitudes, both sides pooled) with
    /// the magnitude of the true yaw rate: do the "faults" follow the turns?
    pub turn_correlation: f64,
    /// Correlation of the same with the error of the derived inputs (derived
    /// minus true acceleration and course rate, scaled by 0.1 m/s^2 and
    /// 0.05 rad/s): do they follow the input derivation's noise and lag?
    pub input_error_correlation: f64,
}

/// Everything measured on one cell.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CellResult {
    /// The cell.
    pub cell: Cell,
    /// The extended twin with its current state.
    pub extended: ExtendedResult,
    /// The extended twin without a current state.
    pub without_current: ExtendedResult,
    /// The seed's method.
    pub seed_method: SeedResult,
}

/// The seed method at one fix: its derived input and its step-4 values.
struct SeedStep {
    time_s: f64,
    input: KinematicInput,
    loss: [Option<f64>; 2],
}

fn feed(run: &SimRun, config: TwinConfig, with_propellers: bool) -> (VesselTwin, Vec<SeedStep>) {
    let mut twin = VesselTwin::new(config).expect("valid default configuration");
    let mut seed_series = Vec::new();
    for event in &run.events {
        match event {
            SensorEvent::Gnss(fix) if twin.on_gnss(fix).is_ok() => {
                seed_series.push(SeedStep {
                    time_s: fix.time_s,
                    input: twin.seed_last_input(),
                    loss: twin.seed_thruster_loss(),
                });
            }
            SensorEvent::PropellerMeasured(p) if with_propellers => {
                let _ = twin.on_propellers(p);
            }
            _ => {}
        }
    }
    (twin, seed_series)
}

fn extended_result(twin: &VesselTwin) -> ExtendedResult {
    let f = twin.fault_report(0.0);
    assert_eq!(f.source, FaultSource::Kinetic, "propeller data were fed");
    ExtendedResult {
        loss: f.thrusters.map(|t| t.loss),
        sigma: f.thrusters.map(|t| t.sigma),
        excited: f.thrusters.map(|t| t.excited),
        status: f.thrusters.map(|t| t.decision.status),
        effectiveness_ratio: f.effectiveness_ratio(),
    }
}

/// How well a twin identified from a trial of the trials' vessel knows its
/// profile (relative standard deviations of surge damping, yaw damping,
/// thrust coefficient and mass): the simulated vessel is the profile's
/// Otter, so these tables are of a twin whose profile is right. The trust
/// matrix (`tests/src/trust.rs`) runs vessels that differ from the profile,
/// with the default, unidentified one.
pub const IDENTIFIED_PROFILE_SIGMA: [f64; 4] = [0.01; 4];

/// The twin the trials run: its profile identified
/// ([`IDENTIFIED_PROFILE_SIGMA`]).
pub fn trials_twin() -> TwinConfig {
    TwinConfig::identified(IDENTIFIED_PROFILE_SIGMA)
}

/// Runs one cell through the simulator and the three estimators.
pub fn run_cell(cell: &Cell) -> CellResult {
    let run = twin_sim::simulate(&scenario(cell)).expect("the cell's scenario is valid");
    let (twin, _) = feed(&run, trials_twin(), true);
    let mut no_current = trials_twin();
    no_current.kinetic.estimate_current = false;
    let (twin_nc, _) = feed(&run, no_current, true);
    let (seed_twin, series) = feed(&run, TwinConfig::default(), false);

    let mut peak = [0.0f64; 2];
    let (mut turn, mut input_error, mut value) = (Vec::new(), Vec::new(), Vec::new());
    let mut previous: Option<&twin_sim::TruthSample> = None;
    for step in &series {
        let truth = run.truth.iter().min_by(|a, b| {
            (a.time_s - step.time_s)
                .abs()
                .total_cmp(&(b.time_s - step.time_s).abs())
        });
        let (Some(tr), Some(prev)) = (truth, previous) else {
            previous = truth;
            continue;
        };
        let dt = tr.time_s - prev.time_s;
        let true_accel = (tr.sog_mps - prev.sog_mps) / dt;
        let true_course_rate = wrap_pi(tr.cog_rad - prev.cog_rad) / dt;
        let err = ((step.input.accel_mps2 - true_accel) / 0.1).abs()
            + ((step.input.course_rate_radps - true_course_rate) / 0.05).abs();
        for (peak, loss) in peak.iter_mut().zip(step.loss) {
            if let Some(l) = loss {
                *peak = peak.max(l);
                turn.push(tr.r_radps.abs());
                input_error.push(err);
                value.push(l.abs());
            }
        }
        previous = Some(tr);
    }
    let theta = seed_twin
        .seed_state()
        .map(|s| [s.theta[0], s.theta[1]])
        .unwrap_or([f64::NAN; 2]);
    CellResult {
        cell: *cell,
        extended: extended_result(&twin),
        without_current: extended_result(&twin_nc),
        seed_method: SeedResult {
            input_faults: theta,
            thruster_peak: peak,
            turn_correlation: correlation(&turn, &value),
            input_error_correlation: correlation(&input_error, &value),
        },
    }
}

/// Pearson correlation (NaN for fewer than 3 points or no spread).
pub fn correlation(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len().min(y.len());
    if n < 3 {
        return f64::NAN;
    }
    let mx = x[..n].iter().sum::<f64>() / n as f64;
    let my = y[..n].iter().sum::<f64>() / n as f64;
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for i in 0..n {
        sxy += (x[i] - mx) * (y[i] - my);
        sxx += (x[i] - mx).powi(2);
        syy += (y[i] - my).powi(2);
    }
    sxy / (sxx * syy).sqrt()
}

/// Prediction after calibration, as the seed's Table 4.9: calibrate on the
/// first half of the broken-port S-manoeuvre, then predict the second half
/// open loop from the recorded inputs (derived inputs for the seed's model,
/// measured propeller speeds for the extended twin), and compare with the
/// truth. RMSE per state `[north, east, speed, course]`, in metres, m/s and
/// radians, and as a percentage of the true state's range over the window
/// (the seed does not say what its percentages are of; the range is the
/// strictest reading).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PredictionComparison {
    /// Horizon, s.
    pub horizon_s: f64,
    /// Seed's method: RMSE per state.
    pub seed_rmse: [f64; 4],
    /// Seed's method: RMSE as % of the range.
    pub seed_rmse_pct: [f64; 4],
    /// Extended twin: RMSE per state.
    pub extended_rmse: [f64; 4],
    /// Extended twin: RMSE as % of the range.
    pub extended_rmse_pct: [f64; 4],
    /// Extended twin: the position error at the horizon in units of the
    /// forecast's own standard deviation, `[north, east]`.
    pub extended_final_error_sigmas: [f64; 2],
    /// Seed's method with its derived input held at the split (what it
    /// could forecast live, without the track ahead): RMSE per state.
    pub seed_held_rmse: [f64; 4],
    /// Extended twin with the shaft speeds of the last interval before the
    /// split held (its live forecast, as `twin/prediction` publishes it):
    /// RMSE per state.
    pub extended_held_rmse: [f64; 4],
    /// The simulator's own vessel from the true state at the split, on the
    /// recorded commands, in water with no disturbance ahead
    /// ([`twin_sim::replay_without_disturbance`]): RMSE per state.
    pub replay_rmse: [f64; 4],
}

/// The seed's published Table 4.9 (RMSE %, x, y, U, psi).
pub const SEED_TABLE_4_9_PCT: [f64; 4] = [0.35, 9.01, 3.5, 2.61];

/// The recorded inputs a forecast from the split runs through, one per GNSS
/// interval after the twins' last fix, and the inputs a live forecast
/// would hold instead.
struct HorizonInputs {
    /// Measured shaft speeds, the mean over each interval.
    kinetic: Vec<(f64, ShaftSpeeds)>,
    /// The seed method's inputs, derived from the fixes over the horizon.
    seed: Vec<(f64, KinematicInput)>,
    /// The mean measured shaft speeds over the last interval before the
    /// split.
    shafts_at_split: ShaftSpeeds,
    /// The seed method's last derived input before the split.
    seed_input_at_split: KinematicInput,
}

impl HorizonInputs {
    /// The inputs of `run` after the twins' last fix `t_start` (at or
    /// before `t_split`).
    fn recorded(run: &SimRun, t_split: f64, t_start: f64) -> Self {
        let props: Vec<_> = run.measured_propellers().copied().collect();
        let mut deriver = twin_core::inputs::InputDeriver::new(TwinConfig::default().seed.inputs)
            .expect("valid derivation");
        // Prime the derivation with the fixes before the split so its
        // low-pass is in steady state, as it is in the calibrated twin.
        let mut seed_input_at_split = KinematicInput::default();
        for f in run.gnss_fixes().filter(|f| f.time_s <= t_split) {
            if let (Some(s), Some(c)) = (f.sog_mps, f.cog_rad)
                && let Some(u) = deriver.push(f.time_s, s, wrap_pi(c))
            {
                seed_input_at_split = u;
            }
        }
        let mut out = Self {
            kinetic: Vec::new(),
            seed: Vec::new(),
            shafts_at_split: ShaftSpeeds::default(),
            seed_input_at_split,
        };
        let mut t_prev = t_start;
        for f in run.gnss_fixes().filter(|f| f.time_s > t_split) {
            if out.kinetic.is_empty() {
                let interval_s = f.time_s - t_start;
                out.shafts_at_split = mean_shaft_speeds(&props, t_start - interval_s, t_start);
            }
            out.kinetic.push((
                f.time_s - t_prev,
                mean_shaft_speeds(&props, t_prev, f.time_s),
            ));
            let u = match (f.sog_mps, f.cog_rad) {
                (Some(s), Some(c)) => deriver.push(f.time_s, s, wrap_pi(c)).unwrap_or_default(),
                _ => KinematicInput::default(),
            };
            out.seed.push((f.time_s - t_prev, u));
            t_prev = f.time_s;
        }
        out
    }
}

/// The broken-port S-manoeuvre's plan and run with noise seed `seed`, in
/// the scenario's harbour water or (`calm_water`) with no random
/// disturbance.
fn broken_port_run(seed: u64, calm_water: bool) -> (twin_sim::Plan, SimRun) {
    let cell = Cell {
        path: TrialPath::SManoeuvre,
        set: seed_sets(0.18)[3],
        current: None,
        seed,
    };
    let mut sc = scenario(&cell);
    if calm_water {
        sc.disturbance = None;
    }
    let plan = sc.validate().expect("valid scenario");
    let run = twin_sim::run_plan(&plan);
    (plan, run)
}

/// One sensor event into the extended twin (fixes and shaft speeds) and
/// the seed method's (fixes).
fn feed_both(event: &SensorEvent, kinetic: &mut VesselTwin, seed_twin: &mut VesselTwin) {
    match event {
        SensorEvent::Gnss(fix) => {
            let _ = kinetic.on_gnss(fix);
            let _ = seed_twin.on_gnss(fix);
        }
        SensorEvent::PropellerMeasured(p) => {
            let _ = kinetic.on_propellers(p);
        }
        _ => {}
    }
}

/// Runs the prediction comparison on the broken-port S-manoeuvre with
/// noise seed `seed` and a horizon of `horizon_s` at the end of the run, in
/// the scenario's harbour water or (`calm_water`) with no random disturbance.
pub fn prediction_comparison(seed: u64, horizon_s: f64, calm_water: bool) -> PredictionComparison {
    let (plan, run) = broken_port_run(seed, calm_water);
    let t_end = run.truth.last().map(|t| t.time_s).unwrap_or(0.0);
    let t_split = t_end - horizon_s;

    // Calibrate both twins on the data before the split.
    let mut kinetic = VesselTwin::new(trials_twin()).expect("valid config");
    let mut seed_twin = VesselTwin::new(TwinConfig::default()).expect("valid config");
    for event in run.events.iter().filter(|e| e.time_s() <= t_split) {
        feed_both(event, &mut kinetic, &mut seed_twin);
    }
    let t_start = seed_twin
        .state_report()
        .map(|s| s.time_s)
        .unwrap_or(t_split);
    let inputs = HorizonInputs::recorded(&run, t_split, t_start);
    let held = |n: usize| std::iter::repeat_n(inputs.shafts_at_split, n);
    let kinetic_held_inputs: Vec<_> = inputs
        .kinetic
        .iter()
        .map(|(dt, _)| *dt)
        .zip(held(inputs.kinetic.len()))
        .collect();
    let seed_held_inputs: Vec<_> = inputs
        .seed
        .iter()
        .map(|(dt, _)| (*dt, inputs.seed_input_at_split))
        .collect();
    let kin_held_points = kinetic.forecast_kinetic(kinetic_held_inputs);
    let kin_points = kinetic.forecast_kinetic(inputs.kinetic);
    let seed_points = seed_twin.forecast_seed(inputs.seed);
    let seed_held_points = seed_twin.forecast_seed(seed_held_inputs);
    // Forecasts are compared with the truth in the simulator's frame (the
    // twins' frames start at their first, noisy, fix).
    let sim_frame = LocalFrame::new(run.origin).expect("valid origin");
    let in_sim_frame = |points: &[twin_core::twin::ForecastPoint]| -> Vec<[f64; 5]> {
        points
            .iter()
            .map(|p| {
                let local = sim_frame.to_local(p.position);
                [p.time_s, local.north_m, local.east_m, p.sog_mps, p.cog_rad]
            })
            .collect()
    };
    let split_index = run
        .truth
        .iter()
        .position(|t| t.time_s >= t_start - 1e-6)
        .unwrap_or(run.truth.len());
    let commands: Vec<_> = run.commanded_propellers().copied().collect();
    let replay: Vec<[f64; 5]> =
        twin_sim::replay_without_disturbance(&plan, &run.truth[split_index..], &commands)
            .iter()
            .map(|t| [t.time_s, t.north_m, t.east_m, t.sog_mps, t.cog_rad])
            .collect();

    let (seed_rmse, seed_rmse_pct) = score(&in_sim_frame(&seed_points), &run);
    let (extended_rmse, extended_rmse_pct) = score(&in_sim_frame(&kin_points), &run);
    let (seed_held_rmse, _) = score(&in_sim_frame(&seed_held_points), &run);
    let (extended_held_rmse, _) = score(&in_sim_frame(&kin_held_points), &run);
    let (replay_rmse, _) = score(&replay, &run);
    let extended_final_error_sigmas = kin_points
        .last()
        .and_then(|p| {
            let tr = run
                .truth
                .iter()
                .find(|t| (t.time_s - p.time_s).abs() < 1e-6)?;
            let local = sim_frame.to_local(p.position);
            Some([
                (local.north_m - tr.north_m).abs() / p.position_sigma_m[0],
                (local.east_m - tr.east_m).abs() / p.position_sigma_m[1],
            ])
        })
        .unwrap_or([f64::NAN; 2]);
    PredictionComparison {
        horizon_s,
        seed_rmse,
        seed_rmse_pct,
        extended_rmse,
        extended_rmse_pct,
        extended_final_error_sigmas,
        seed_held_rmse,
        extended_held_rmse,
        replay_rmse,
    }
}

/// The live forecasts (`VesselTwin::forecast`: each twin's input held at
/// its last value, as `twin/prediction` publishes them) of the broken-port
/// S-manoeuvre from many splits of one run: one every `every_s` from
/// `first_s` to the run's end less `horizon_s`, each twin calibrated on
/// the data before it.
fn live_forecast_errors(
    seed: u64,
    horizon_s: f64,
    calm_water: bool,
    first_s: f64,
    every_s: f64,
) -> LiveForecastErrors {
    let (_, run) = broken_port_run(seed, calm_water);
    let t_first = run.truth.first().map(|t| t.time_s).unwrap_or(0.0);
    let t_end = run.truth.last().map(|t| t.time_s).unwrap_or(0.0);
    let sim_frame = LocalFrame::new(run.origin).expect("valid origin");
    let mut kinetic = VesselTwin::new(trials_twin()).expect("valid config");
    let mut seed_twin = VesselTwin::new(TwinConfig::default()).expect("valid config");
    let (mut sq, mut n) = ([0.0; 2], [0usize; 2]);
    let mut score = |twin: &VesselTwin, k: usize| {
        for p in twin.forecast(horizon_s, 0.2) {
            let i = run.truth.partition_point(|t| t.time_s < p.time_s - 1e-3);
            let Some(tr) = run
                .truth
                .get(i)
                .filter(|t| (t.time_s - p.time_s).abs() < 1e-3)
            else {
                continue;
            };
            let local = sim_frame.to_local(p.position);
            sq[k] += (local.north_m - tr.north_m).powi(2) + (local.east_m - tr.east_m).powi(2);
            n[k] += 1;
        }
    };
    // Times are the run's clock (Unix seconds); splits count from its start.
    let mut next_split_s = t_first + first_s;
    let mut splits = 0;
    for event in &run.events {
        while event.time_s() > next_split_s && next_split_s + horizon_s <= t_end {
            score(&seed_twin, 0);
            score(&kinetic, 1);
            splits += 1;
            next_split_s += every_s;
        }
        feed_both(event, &mut kinetic, &mut seed_twin);
    }
    LiveForecastErrors {
        sum_sq_m2: sq,
        points: n,
        forecasts: splits,
    }
}

/// The horizontal position errors of live forecasts, `[seed method,
/// extended twin]`.
#[derive(Debug, Clone, Copy, Default)]
struct LiveForecastErrors {
    /// Sums of the squared errors over the forecast points, m^2.
    sum_sq_m2: [f64; 2],
    /// How many points each sum holds.
    points: [usize; 2],
    /// How many forecasts were started.
    forecasts: usize,
}

/// The live forecasts' horizontal position RMSE, `[seed method, extended
/// twin]` in m, over noise seeds `seeds` (splits every [`LIVE_EVERY_S`]
/// from [`LIVE_FIRST_S`], see [`live_forecast_errors`]), and how many
/// forecasts that is.
pub fn live_forecast_rmse(seeds: &[u64], horizon_s: f64, calm_water: bool) -> ([f64; 2], usize) {
    let mut all = LiveForecastErrors::default();
    for &seed in seeds {
        let e = live_forecast_errors(seed, horizon_s, calm_water, LIVE_FIRST_S, LIVE_EVERY_S);
        for k in 0..2 {
            all.sum_sq_m2[k] += e.sum_sq_m2[k];
            all.points[k] += e.points[k];
        }
        all.forecasts += e.forecasts;
    }
    let rmse = std::array::from_fn(|k| (all.sum_sq_m2[k] / all.points[k].max(1) as f64).sqrt());
    (rmse, all.forecasts)
}

/// RMSE of forecast `points` (`[time s, north m, east m, speed m/s, course
/// rad]`, in the simulator's frame) against the truth of `run` per state
/// `[north, east, speed, course]`, and as % of the true state's range over
/// them.
fn score(points: &[[f64; 5]], run: &SimRun) -> ([f64; 4], [f64; 4]) {
    let mut sq = [0.0f64; 4];
    let mut lo = [f64::MAX; 4];
    let mut hi = [f64::MIN; 4];
    let mut n = 0.0f64;
    let mut course_unwrapped = None::<f64>;
    for &[time_s, north_m, east_m, sog_mps, cog_rad] in points {
        let Some(tr) = run.truth.iter().find(|t| (t.time_s - time_s).abs() < 1e-6) else {
            continue;
        };
        let c = match course_unwrapped {
            None => tr.cog_rad,
            Some(prev) => prev + wrap_pi(tr.cog_rad - prev),
        };
        course_unwrapped = Some(c);
        let truth = [tr.north_m, tr.east_m, tr.sog_mps, c];
        let err = [
            north_m - tr.north_m,
            east_m - tr.east_m,
            sog_mps - tr.sog_mps,
            wrap_pi(cog_rad - tr.cog_rad),
        ];
        for i in 0..4 {
            sq[i] += err[i] * err[i];
            lo[i] = lo[i].min(truth[i]);
            hi[i] = hi[i].max(truth[i]);
        }
        n += 1.0;
    }
    let rmse = sq.map(|s| (s / n.max(1.0)).sqrt());
    let pct = std::array::from_fn(|i| 100.0 * rmse[i] / (hi[i] - lo[i]).max(1e-9));
    (rmse, pct)
}

/// The mean of the measured shaft speeds in `(from_s, to_s]` (zero where
/// there are none): the recorded input of one GNSS interval.
fn mean_shaft_speeds(props: &[PropellerSpeeds], from_s: f64, to_s: f64) -> ShaftSpeeds {
    let in_interval: Vec<_> = props
        .iter()
        .filter(|p| p.time_s > from_s && p.time_s <= to_s)
        .collect();
    let n = in_interval.len().max(1) as f64;
    ShaftSpeeds {
        port_radps: in_interval.iter().map(|p| p.port_radps).sum::<f64>() / n,
        starboard_radps: in_interval.iter().map(|p| p.starboard_radps).sum::<f64>() / n,
    }
}

/// Coverage of the extended twin's forecast bands on a simulated run: the
/// twin is calibrated up to each split time, then forecasts open loop through
/// the recorded propeller speeds to the end of the run; every forecast point's
/// north and east errors are compared with its standard deviations.
/// Returns (within 1 sigma, within 2 sigma, components judged).
pub fn forecast_coverage(
    cell: &Cell,
    config: TwinConfig,
    splits_s: &[f64],
) -> (usize, usize, usize) {
    let run = twin_sim::simulate(&scenario(cell)).expect("valid scenario");
    let sim_frame = LocalFrame::new(run.origin).expect("valid origin");
    let props: Vec<_> = run.measured_propellers().copied().collect();
    let (mut w1, mut w2, mut n) = (0, 0, 0);
    for split in splits_s {
        let t_split = run.start_unix_s + split;
        let mut twin = VesselTwin::new(config).expect("valid config");
        for event in run.events.iter().filter(|e| e.time_s() <= t_split) {
            match event {
                SensorEvent::Gnss(fix) => {
                    let _ = twin.on_gnss(fix);
                }
                SensorEvent::PropellerMeasured(p) => {
                    let _ = twin.on_propellers(p);
                }
                _ => {}
            }
        }
        let Some(mut t_prev) = twin.state_report().map(|s| s.time_s) else {
            continue;
        };
        let mut inputs = Vec::new();
        for f in run.gnss_fixes().filter(|f| f.time_s > t_split) {
            inputs.push((
                f.time_s - t_prev,
                mean_shaft_speeds(&props, t_prev, f.time_s),
            ));
            t_prev = f.time_s;
        }
        for p in twin.forecast_kinetic(inputs) {
            let Some(tr) = run
                .truth
                .iter()
                .find(|t| (t.time_s - p.time_s).abs() < 1e-6)
            else {
                continue;
            };
            let local = sim_frame.to_local(p.position);
            for (err, sigma) in [
                (local.north_m - tr.north_m, p.position_sigma_m[0]),
                (local.east_m - tr.east_m, p.position_sigma_m[1]),
            ] {
                w1 += usize::from(err.abs() <= sigma);
                w2 += usize::from(err.abs() <= 2.0 * sigma);
                n += 1;
            }
        }
    }
    (w1, w2, n)
}

/// The seed's published Table 4.8: peak per-thruster faults `[starboard,
/// port]` ("RT", "LT") for each propeller set (starboard/port names), straight
/// line then S-manoeuvre.
pub const SEED_TABLE_4_8: [(&str, [f64; 2], [f64; 2]); 4] = [
    ("original/original", [0.0, 0.0], [0.02, 0.01]),
    ("new/original", [0.0, 0.0], [0.02, 0.01]),
    ("new/new", [0.0, 0.0], [0.01, 0.07]),
    ("new/broken", [0.0, 0.0], [0.01, 0.18]),
];

fn mean_over<'a>(
    rs: impl Iterator<Item = &'a CellResult>,
    f: impl Fn(&CellResult) -> [f64; 2],
) -> [f64; 2] {
    let mut sum = [0.0; 2];
    let mut n = 0.0;
    for r in rs {
        let v = f(r);
        sum[0] += v[0];
        sum[1] += v[1];
        n += 1.0;
    }
    [sum[0] / n, sum[1] / n]
}

/// The seed's published peak for a propeller set on a path, `[port,
/// starboard]`, as text; `-` for the sets the seed did not run.
fn published_peak(path: TrialPath, set: &str) -> String {
    SEED_TABLE_4_8
        .iter()
        .find(|(n, _, _)| *n == set)
        .map(|(_, straight, s_man)| {
            let v = if path == TrialPath::Straight {
                straight
            } else {
                s_man
            };
            format!("[{:.2}, {:.2}]", v[1], v[0])
        })
        .unwrap_or_else(|| "-".to_string())
}

/// The largest error over the cells of `path` of the estimate `f` picks.
fn worst_error(rs: &[CellResult], path: TrialPath, f: impl Fn(&CellResult) -> [f64; 2]) -> f64 {
    rs.iter()
        .filter(|r| r.cell.path == path)
        .map(|r| {
            let t = r.cell.set.losses();
            let e = f(r);
            (e[0] - t[0]).abs().max((e[1] - t[1]).abs())
        })
        .fold(0.0f64, f64::max)
}

/// One row of the matrix table: a path and a propeller set, means over the
/// noise seeds, in still water and in the 0.3 m/s current.
fn matrix_row(
    path: TrialPath,
    set: &PropellerSet,
    still: &[CellResult],
    current: &[CellResult],
) -> Option<String> {
    let pick = |rs: &[CellResult]| -> Vec<CellResult> {
        rs.iter()
            .filter(|r| r.cell.path == path && r.cell.set.name == set.name)
            .copied()
            .collect()
    };
    let s = pick(still);
    let c = pick(current);
    let first = s.first()?;
    let pair = |v: [f64; 2], decimals: usize| format!("[{:.decimals$}, {:.decimals$}]", v[0], v[1]);
    let status: Vec<&str> = first.extended.status.iter().map(|st| st.name()).collect();
    Some(format!(
        "| {} | {} | {} | {} | {} | {} | {} +- {} | {} | {} | {} |",
        path.name(),
        set.name,
        pair(set.losses(), 2),
        published_peak(path, set.name),
        pair(mean_over(s.iter(), |r| r.seed_method.thruster_peak), 2),
        pair(mean_over(s.iter(), |r| r.seed_method.input_faults), 2),
        pair(mean_over(s.iter(), |r| r.extended.loss), 3),
        pair(mean_over(s.iter(), |r| r.extended.sigma), 3),
        status.join("/"),
        pair(mean_over(c.iter(), |r| r.without_current.loss), 3),
        pair(mean_over(c.iter(), |r| r.extended.loss), 3),
    ))
}

/// The sea-trial matrix as markdown tables (`cargo xtask trials`): every
/// cell (means over `seeds` noise seeds) with the seed's published peak, the
/// seed's method and the extended twin, in still water and in a 0.3 m/s
/// current; then the worst error over the S-manoeuvre cells.
pub fn matrix_markdown(seeds: u64) -> String {
    use std::fmt::Write;
    let mut out = String::new();
    let still = matrix(seeds, 0.0).iter().map(run_cell).collect::<Vec<_>>();
    let current = matrix(seeds, 0.3).iter().map(run_cell).collect::<Vec<_>>();
    let sets: Vec<PropellerSet> = seed_sets(0.18).into_iter().chain(loss_sets()).collect();
    let _ = writeln!(
        out,
        "| path | set (stb/port) | true loss | seed published peak | seed method peak (step 4) | seed method input faults [a, r] | extended twin | status | without current state, 0.3 m/s current | extended twin, 0.3 m/s current |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|---|---|---|---|");
    for path in TrialPath::BOTH {
        for set in &sets {
            if let Some(row) = matrix_row(path, set, &still, &current) {
                let _ = writeln!(out, "{row}");
            }
        }
    }
    let _ = writeln!(out);
    let _ = writeln!(out, "| S-manoeuvres, every cell and seed | worst error |");
    let _ = writeln!(out, "|---|---:|");
    let p = TrialPath::SManoeuvre;
    for (what, worst) in [
        (
            "extended twin, still water",
            worst_error(&still, p, |r| r.extended.loss),
        ),
        (
            "extended twin, 0.3 m/s current",
            worst_error(&current, p, |r| r.extended.loss),
        ),
        (
            "extended twin without its current state, 0.3 m/s current",
            worst_error(&current, p, |r| r.without_current.loss),
        ),
    ] {
        let _ = writeln!(out, "| {what} | {worst:.3} |");
    }
    out
}

/// Prediction after calibration as the seed's Table 4.9, as markdown
/// (`cargo xtask prediction`): RMSE over each horizon, means over `seeds`
/// noise seeds, in calm and in harbour water; then the horizontal position
/// RMSE (per seed, then the mean) of every forecast, beside what each
/// knows of what lies ahead.
pub fn prediction_markdown(seeds: u64) -> String {
    use std::fmt::Write;
    let mut rows = Vec::new();
    for calm in [true, false] {
        for horizon in [10.0, 30.0, 60.0] {
            let (mut mean, mut horizontal) = ([[0.0; 4]; 5], [0.0; 5]);
            for seed in 0..seeds {
                let p = prediction_comparison(1000 + seed, horizon, calm);
                let runs = [
                    p.seed_rmse,
                    p.extended_rmse,
                    p.replay_rmse,
                    p.seed_held_rmse,
                    p.extended_held_rmse,
                ];
                for ((m, h), r) in mean.iter_mut().zip(&mut horizontal).zip(runs) {
                    for i in 0..4 {
                        m[i] += r[i] / seeds as f64;
                    }
                    *h += r[0].hypot(r[1]) / seeds as f64;
                }
            }
            rows.push((
                if calm { "calm" } else { "harbour" },
                horizon,
                mean,
                horizontal,
            ));
        }
    }
    let mut out = String::new();
    let _ = writeln!(
        out,
        "| water | horizon | seed method RMSE [north m, east m, SOG m/s, COG rad] | extended twin RMSE |"
    );
    let _ = writeln!(out, "|---|---|---|---|");
    for (water, horizon, [s, e, ..], _) in &rows {
        let _ = writeln!(
            out,
            "| {water} | {horizon:.0} s | [{:.2}, {:.2}, {:.3}, {:.3}] | [{:.2}, {:.2}, {:.3}, {:.3}] |",
            s[0], s[1], s[2], s[3], e[0], e[1], e[2], e[3]
        );
    }
    let _ = writeln!(out);
    let _ = writeln!(
        out,
        "| water | horizon | seed method, inputs derived from the track ahead | extended twin, recorded shaft speeds | the simulated vessel itself, recorded commands, no disturbance ahead | seed method, input held | extended twin, shaft speeds held (live) |"
    );
    let _ = writeln!(out, "|---|---|---:|---:|---:|---:|---:|");
    for (water, horizon, _, [s, e, r, sh, eh]) in &rows {
        let _ = writeln!(
            out,
            "| {water} | {horizon:.0} s | {s:.2} | {e:.2} | {r:.2} | {sh:.2} | {eh:.2} |"
        );
    }
    let _ = writeln!(out);
    let _ = writeln!(
        out,
        "| water | horizon | forecasts (splits every {LIVE_EVERY_S:.0} s from {LIVE_FIRST_S:.0} s) | seed method, input held | extended twin, shaft speeds held (live) |"
    );
    let _ = writeln!(out, "|---|---|---:|---:|---:|");
    for calm in [true, false] {
        for horizon in [10.0, 30.0, 60.0] {
            let noise_seeds: Vec<u64> = (0..seeds).map(|k| 1000 + k).collect();
            let ([seed_m, twin_m], forecasts) = live_forecast_rmse(&noise_seeds, horizon, calm);
            let _ = writeln!(
                out,
                "| {} | {horizon:.0} s | {forecasts} | {seed_m:.2} | {twin_m:.2} |",
                if calm { "calm" } else { "harbour" },
            );
        }
    }
    out
}

/// The first split of the live forecasts' table, s: the twins have 40 s
/// of the manoeuvre, its first turns, behind them.
const LIVE_FIRST_S: f64 = 40.0;
/// How often a live forecast starts in that table, s.
const LIVE_EVERY_S: f64 = 5.0;
