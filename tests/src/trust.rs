//! The trust matrix: simulated trials whose truth is not the twin's model,
//! and the measures a controller acting on `twin/fault` needs: no healthy
//! propeller ever declared FAULT, a real loss declared on its own side and
//! soon, no flapping, and published standard deviations that cover the
//! error at their stated rate.
//!
//! # What a draw is
//! Every draw perturbs the simulated vessel itself, besides the effect it
//! plants: its rigid-body mass and inertia, added mass, linear surge, sway
//! and yaw damping (the quadratic yaw term with it), cross-flow drag and
//! both propellers' thrust coefficients are each multiplied by `1 +- U(0.2,
//! 0.3)` with a random sign (the same thrust factor on both sides: a
//! difference between the sides is, for any observer, a loss). One draw in
//! six is a control left unperturbed. On top of that a draw belongs to one
//! [`Class`] and samples the shaft speeds at the GNSS rate (5 Hz) or at
//! 20 Hz, and carries a rate gyro or not. Both of the project's simulators
//! run the draws: `twin-sim` (3 DOF) and `tests/othersim/otter6dof.py` (6
//! DOF, independent code).
//!
//! # How a draw is judged (fixed before any draw was run)
//! The log goes through the same reader and assembler as `twin analyze`
//! into a [`VesselTwin`]. Per propeller:
//! - **false FAULT**: status FAULT at any time while that propeller's true
//!   loss is zero (a healthy propeller, or a propeller before its loss
//!   starts);
//! - **missed**: a loss of at least [`MUST_DETECT_LOSS`] not declared FAULT
//!   within [`DETECT_WITHIN_S`] of its onset (of the start, for a loss
//!   present from the start, where the twin has [`COLD_START_S`] more);
//! - **late onset**: for a loss that starts mid-trial, the reported onset
//!   more than [`DETECT_WITHIN_S`] from the true one (a loss present from
//!   the start began before the twin's first fix);
//! - **flapping**: more status changes (among nominal, suspect, fault; the
//!   first decision after `not_excited` is not a change) than real changes
//!   of the truth, one for a loss present from the start;
//! - **coverage**: at each whole second from [`COVERAGE_FROM_S`] on, whether
//!   `|loss - true loss| <= 2 sigma`;
//! - **bands**: forecasts through the logged shaft speeds started every
//!   [`BAND_EVERY_S`] from [`COVERAGE_FROM_S`]; whether the true position is
//!   within two published standard deviations per axis at 10, 30 and 60 s.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::io::{BufReader, Cursor};
use std::process::Command;

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use twin_cli::simulate::write_jsonl;
use twin_core::decision::{DecisionConfig, ThrusterStatus};
use twin_core::geodesy::{LatLon, LocalFrame, NorthEast};
use twin_core::models::otter_twin::{ShaftSpeeds, fault, idx};
use twin_core::sample::PropellerSpeeds;
use twin_core::twin::{FaultReport, TwinConfig, VesselTwin};
use twin_sim::{CurrentSpec, LeverArm, Scenario, VesselSpec, Waypoint};
use twin_wire::{Assembled, AssemblerConfig, FixAssembler, LogReader, ReadOptions};

/// A loss at least this large must be declared FAULT.
pub const MUST_DETECT_LOSS: f64 = 0.15;
/// ... within this long of its onset, s.
pub const DETECT_WITHIN_S: f64 = 30.0;
/// A loss present from the start has this much longer: the twin starts
/// cold, s.
pub const COLD_START_S: f64 = 30.0;
/// Coverage and bands are sampled from this time on, s.
pub const COVERAGE_FROM_S: f64 = 60.0;
/// A forecast is started this often, s.
pub const BAND_EVERY_S: f64 = 30.0;
/// The forecast horizons judged, s.
pub const HORIZONS_S: [f64; 3] = [10.0, 30.0, 60.0];
/// The detection goal a controller would like (not a bar of the matrix):
/// a loss of at least this much that starts while the twin watches a
/// manoeuvring vessel ...
pub const GOAL_LOSS: f64 = 0.2;
/// ... declared FAULT within this long of its onset, s.
pub const GOAL_WITHIN_S: f64 = 15.0;

/// Which simulator makes the log.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Simulator {
    /// `twin-sim`, the project's 3-DOF Otter.
    Own,
    /// `tests/othersim/otter6dof.py`, the independent 6-DOF Otter.
    Other,
}

impl Simulator {
    /// Short name for tables.
    pub fn name(self) -> &'static str {
        match self {
            Simulator::Own => "twin-sim",
            Simulator::Other => "othersim",
        }
    }
}

/// What a draw plants besides the perturbed vessel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Class {
    /// Healthy propellers, manoeuvring.
    Healthy,
    /// One propeller with a loss from the start, manoeuvring.
    Loss,
    /// One propeller's loss starting mid-trial, manoeuvring.
    LateLoss,
    /// A heading sensor off by 3-8 deg, healthy propellers.
    HeadingOffset,
    /// A heading sensor off by 3-8 deg and a loss.
    HeadingOffsetLoss,
    /// Hull drag 20-40 % higher than the vessel's own (fouling), healthy.
    Fouling,
    /// A straight run, healthy.
    Straight,
    /// A straight run with a loss.
    StraightLoss,
    /// GNSS data 0.1-0.5 s older than their stamps, and a loss in half.
    Latency,
    /// The antenna up to 1 m from the reference point, and a loss in half.
    LeverArm,
    /// A current of 0.1-0.4 m/s and a loss.
    CurrentLoss,
    /// A steady turn on a circle of 20 m radius, healthy.
    SteadyTurn,
    /// A steady turn with a loss.
    SteadyTurnLoss,
}

impl Class {
    /// Every class, in table order.
    pub const ALL: [Class; 13] = [
        Class::Healthy,
        Class::Loss,
        Class::LateLoss,
        Class::HeadingOffset,
        Class::HeadingOffsetLoss,
        Class::Fouling,
        Class::Straight,
        Class::StraightLoss,
        Class::Latency,
        Class::LeverArm,
        Class::CurrentLoss,
        Class::SteadyTurn,
        Class::SteadyTurnLoss,
    ];

    /// snake_case name.
    pub fn name(self) -> &'static str {
        match self {
            Class::Healthy => "healthy",
            Class::Loss => "loss",
            Class::LateLoss => "late_loss",
            Class::HeadingOffset => "heading_offset",
            Class::HeadingOffsetLoss => "heading_offset+loss",
            Class::Fouling => "fouling",
            Class::Straight => "straight",
            Class::StraightLoss => "straight+loss",
            Class::Latency => "latency",
            Class::LeverArm => "lever_arm",
            Class::CurrentLoss => "current+loss",
            Class::SteadyTurn => "steady_turn",
            Class::SteadyTurnLoss => "steady_turn+loss",
        }
    }

    fn straight(self) -> bool {
        matches!(self, Class::Straight | Class::StraightLoss)
    }

    fn steady_turn(self) -> bool {
        matches!(self, Class::SteadyTurn | Class::SteadyTurnLoss)
    }
}

/// Factors on the simulated vessel's numbers (1 = the Otter).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Perturbation {
    /// Rigid-body mass and inertia.
    pub mass: f64,
    /// Added mass and inertia.
    pub added_mass: f64,
    /// Linear surge damping.
    pub surge_damping: f64,
    /// Linear sway damping.
    pub sway_damping: f64,
    /// Linear and quadratic yaw damping.
    pub yaw_damping: f64,
    /// Cross-flow drag.
    pub crossflow: f64,
    /// Thrust coefficients, both propellers.
    pub thrust: f64,
}

impl Perturbation {
    /// None: the Otter itself.
    pub const NONE: Perturbation = Perturbation {
        mass: 1.0,
        added_mass: 1.0,
        surge_damping: 1.0,
        sway_damping: 1.0,
        yaw_damping: 1.0,
        crossflow: 1.0,
        thrust: 1.0,
    };

    /// Each factor `1 +- U(0.2, 0.3)`, random sign.
    fn draw(rng: &mut StdRng) -> Self {
        let mut f = || {
            let size = rng.random_range(0.2..0.3);
            if rng.random_bool(0.5) {
                1.0 + size
            } else {
                1.0 - size
            }
        };
        Perturbation {
            mass: f(),
            added_mass: f(),
            surge_damping: f(),
            sway_damping: f(),
            yaw_damping: f(),
            crossflow: f(),
            thrust: f(),
        }
    }
}

/// One trial of the matrix.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Draw {
    /// Its number in the matrix.
    pub index: usize,
    /// Which simulator.
    pub simulator: Simulator,
    /// What it plants.
    pub class: Class,
    /// The simulator's noise seed.
    pub seed: u64,
    /// The vessel's departure from the Otter ([`Perturbation::NONE`] for a
    /// control draw).
    pub vessel: Perturbation,
    /// The true loss `[port, starboard]` once it acts.
    pub loss: [f64; 2],
    /// When it starts acting, s from the start.
    pub onset_s: f64,
    /// Heading sensor minus true heading, deg.
    pub heading_offset_deg: f64,
    /// GNSS latency, s.
    pub latency_s: f64,
    /// Antenna position `[forward, starboard]`, m.
    pub lever_arm_m: [f64; 2],
    /// Current `(speed m/s, toward deg)`.
    pub current: Option<(f64, f64)>,
    /// Shaft-speed sampling rate, Hz.
    pub shaft_rate_hz: f64,
    /// Whether a rate gyro's yaw rate rides on the fixes.
    pub gyro: bool,
    /// The rate gyro's bias (reported minus true), deg/s; none in the
    /// matrix's own draws.
    pub gyro_bias_deg_s: f64,
    /// Length of the trial, s.
    pub duration_s: f64,
    /// The direction of a steady turn: +1 to starboard, -1 to port.
    pub turn_sign: f64,
    /// Whether the water's random forces are off (the matrix's own draws
    /// have them): what the disturbance of the moment writes into an
    /// estimate is then told from what the vessel's difference from its
    /// profile writes.
    pub calm_water: bool,
    /// The project's simulator's sensor noise (GNSS position and
    /// velocity, heading, shaft speeds, rate gyro) times this; 1 in the
    /// matrix's own draws, and the independent simulator keeps its own
    /// whatever it is. What an estimate keeps on the vessel's own profile
    /// in calm water and loses as the noise goes is the estimator's doing,
    /// not the model's (docs/known-issues.md, "The filter's profile errors
    /// run on the vessel's own profile").
    pub sensor_noise_scale: f64,
}

impl Draw {
    /// The true loss of both propellers at `elapsed_s`.
    pub fn loss_at(&self, elapsed_s: f64) -> [f64; 2] {
        if elapsed_s >= self.onset_s {
            self.loss
        } else {
            [0.0, 0.0]
        }
    }

    /// The independent simulator's `--path` for this draw.
    fn other_path(&self) -> &'static str {
        if self.class.straight() {
            "straight"
        } else if !self.class.steady_turn() {
            "lawnmower"
        } else if self.turn_sign > 0.0 {
            "circle-starboard"
        } else {
            "circle-port"
        }
    }

    /// Whether the vessel is the Otter itself.
    pub fn is_control(&self) -> bool {
        self.vessel == Perturbation::NONE
    }

    /// A one-line description.
    pub fn describe(&self) -> String {
        let mut s = format!(
            "#{} {} {} seed {}",
            self.index,
            self.simulator.name(),
            self.class.name(),
            self.seed
        );
        if self.loss != [0.0, 0.0] {
            let _ = write!(
                s,
                ", loss [{:.2}, {:.2}] from {:.0} s",
                self.loss[0], self.loss[1], self.onset_s
            );
        }
        if self.heading_offset_deg != 0.0 {
            let _ = write!(s, ", heading offset {:.1} deg", self.heading_offset_deg);
        }
        if self.latency_s != 0.0 {
            let _ = write!(s, ", latency {:.2} s", self.latency_s);
        }
        if self.lever_arm_m != [0.0, 0.0] {
            let _ = write!(
                s,
                ", antenna ({:.2}, {:.2}) m",
                self.lever_arm_m[0], self.lever_arm_m[1]
            );
        }
        if let Some((v, d)) = self.current {
            let _ = write!(s, ", current {v:.2} m/s toward {d:.0} deg");
        }
        if self.class.steady_turn() {
            s.push_str(if self.turn_sign > 0.0 {
                ", turning to starboard"
            } else {
                ", turning to port"
            });
        }
        let v = &self.vessel;
        if self.is_control() {
            s.push_str(", vessel: the Otter");
        } else {
            let _ = write!(
                s,
                ", vessel: mass {:.2} added {:.2} damping u {:.2} v {:.2} r {:.2} crossflow {:.2} thrust {:.2}",
                v.mass,
                v.added_mass,
                v.surge_damping,
                v.sway_damping,
                v.yaw_damping,
                v.crossflow,
                v.thrust
            );
        }
        let _ = write!(
            s,
            ", shafts {} Hz{}",
            self.shaft_rate_hz,
            if !self.gyro {
                String::new()
            } else if self.gyro_bias_deg_s == 0.0 {
                ", gyro".to_string()
            } else {
                format!(", gyro biased {:+.2} deg/s", self.gyro_bias_deg_s)
            }
        );
        if self.calm_water {
            s.push_str(", calm water");
        }
        if self.sensor_noise_scale != 1.0 && self.simulator == Simulator::Own {
            let _ = write!(s, ", sensor noise x{}", self.sensor_noise_scale);
        }
        s
    }
}

/// The matrix's seed, as the docs' tables and the CI test run it.
pub const MATRIX_SEED: u64 = 20_261_125;
/// Its draws on `twin-sim`: four per class.
pub const MATRIX_OWN_DRAWS: usize = 4 * Class::ALL.len();
/// Its draws on the independent simulator: two per class.
pub const MATRIX_OTHER_DRAWS: usize = 2 * Class::ALL.len();

/// The matrix's draws: `own` on `twin-sim`, then `other` on the
/// independent simulator (numbered after them), from `seed`.
pub fn matrix_draws(own: usize, other: usize, seed: u64) -> Vec<Draw> {
    let mut all = draws(Simulator::Own, own, seed);
    let mut others = draws(Simulator::Other, other, seed ^ 0x0A11_0C8E);
    for d in &mut others {
        d.index += own;
    }
    all.extend(others);
    all
}

/// `count` draws on `simulator` from `seed`: the classes in blocks of
/// [`Class::ALL`], each block in a random order; one draw in six a control.
pub fn draws(simulator: Simulator, count: usize, seed: u64) -> Vec<Draw> {
    let mut rng = StdRng::seed_from_u64(seed);
    let mut classes = Vec::with_capacity(count);
    while classes.len() < count {
        let mut block = Class::ALL.to_vec();
        for i in (1..block.len()).rev() {
            block.swap(i, rng.random_range(0..=i));
        }
        classes.extend(block);
    }
    classes
        .into_iter()
        .take(count)
        .enumerate()
        .map(|(index, class)| draw(&mut rng, simulator, index, class))
        .collect()
}

fn draw(rng: &mut StdRng, simulator: Simulator, index: usize, class: Class) -> Draw {
    let sign = |rng: &mut StdRng| if rng.random_bool(0.5) { 1.0 } else { -1.0 };
    let control = index % 6 == 5;
    let mut vessel = if control {
        Perturbation::NONE
    } else {
        Perturbation::draw(rng)
    };
    let one_loss = |rng: &mut StdRng| {
        let size = rng.random_range(0.15..0.40);
        if rng.random_bool(0.5) {
            [size, 0.0]
        } else {
            [0.0, size]
        }
    };
    let mut d = Draw {
        index,
        simulator,
        class,
        seed: rng.random_range(1..1_000_000),
        vessel,
        loss: [0.0, 0.0],
        onset_s: 0.0,
        heading_offset_deg: 0.0,
        latency_s: 0.0,
        lever_arm_m: [0.0, 0.0],
        current: None,
        shaft_rate_hz: if rng.random_bool(0.5) { 5.0 } else { 20.0 },
        gyro: rng.random_bool(0.5),
        gyro_bias_deg_s: 0.0,
        duration_s: if class.straight() { 180.0 } else { 300.0 },
        turn_sign: 1.0,
        calm_water: false,
        sensor_noise_scale: 1.0,
    };
    match class {
        Class::Healthy | Class::Straight => {}
        Class::Loss | Class::StraightLoss => d.loss = one_loss(rng),
        Class::SteadyTurn => d.turn_sign = sign(rng),
        Class::SteadyTurnLoss => {
            d.turn_sign = sign(rng);
            d.loss = one_loss(rng);
        }
        Class::LateLoss => {
            d.loss = one_loss(rng);
            d.onset_s = rng.random_range(90.0..180.0);
        }
        Class::HeadingOffset => d.heading_offset_deg = sign(rng) * rng.random_range(3.0..8.0),
        Class::HeadingOffsetLoss => {
            d.heading_offset_deg = sign(rng) * rng.random_range(3.0..8.0);
            d.loss = one_loss(rng);
        }
        Class::Fouling => {
            vessel.surge_damping = rng.random_range(1.2..1.4);
            d.vessel = vessel;
        }
        Class::Latency => {
            d.latency_s = rng.random_range(0.1..0.5);
            if rng.random_bool(0.5) {
                d.loss = one_loss(rng);
            }
        }
        Class::LeverArm => {
            d.lever_arm_m = [rng.random_range(-1.0..1.0), rng.random_range(-0.5..0.5)];
            if rng.random_bool(0.5) {
                d.loss = one_loss(rng);
            }
        }
        Class::CurrentLoss => {
            d.current = Some((rng.random_range(0.1..0.4), rng.random_range(0.0..360.0)));
            d.loss = one_loss(rng);
        }
    }
    d
}

/// A simulated trial: its log (the project's JSON lines) and the true
/// position of the body origin over time.
pub struct Trial {
    /// The log.
    pub log: Vec<u8>,
    /// `(elapsed s, position)` of the body origin.
    pub track: Vec<(f64, LatLon)>,
    /// Unix time of the trial's start, s.
    pub start_s: f64,
}

/// Runs `draw`'s simulator. The independent simulator needs `python3` with
/// NumPy; `Err` says why it could not run.
pub fn simulate(draw: &Draw) -> Result<Trial, String> {
    match draw.simulator {
        Simulator::Own => Ok(simulate_own(draw)),
        Simulator::Other => simulate_other(draw),
    }
}

/// A lawn-mower of six legs of 40 m joined by 180 deg turns of radius 12 m
/// alternately to starboard and to port (or one straight leg, or a 20 m
/// leg north then a circle of 20 m radius sailed over and over), at
/// 1.5 m/s.
fn own_scenario(draw: &Draw) -> Scenario {
    let wp = |north_m: f64, east_m: f64| Waypoint {
        north_m: Some(north_m),
        east_m: Some(east_m),
        lat_deg: None,
        lon_deg: None,
    };
    let waypoints = if draw.class.straight() {
        vec![wp(0.0, 0.0), wp(600.0, 0.0)]
    } else if draw.class.steady_turn() {
        // Points every 10 deg of the circle, whose centre is 20 m abeam of
        // the lead-in's end on the side of the turn; enough laps for the
        // trial.
        let radius = 20.0;
        let laps = (1.5 * draw.duration_s / (2.0 * std::f64::consts::PI * radius)).ceil() + 1.0;
        let mut w = vec![wp(0.0, 0.0)];
        for k in 0..(36.0 * laps) as usize {
            let a = (k as f64) * 10f64.to_radians();
            w.push(wp(
                20.0 + radius * a.sin(),
                draw.turn_sign * radius * (1.0 - a.cos()),
            ));
        }
        w
    } else {
        let radius = 12.0;
        let mut w = vec![wp(0.0, 0.0)];
        for leg in 0..8 {
            let east = 2.0 * radius * f64::from(leg);
            // North on even legs, south on odd ones; each ends in a half
            // circle east to the next leg, so the turns alternate between
            // starboard and port.
            let (end, bulge) = if leg % 2 == 0 {
                (40.0, 1.0)
            } else {
                (0.0, -1.0)
            };
            w.push(wp(end, east));
            for k in 1..4 {
                let a = std::f64::consts::PI * f64::from(k) / 4.0;
                w.push(wp(
                    end + bulge * radius * a.sin(),
                    east + radius - radius * a.cos(),
                ));
            }
            w.push(wp(end, east + 2.0 * radius));
        }
        w
    };
    with_draw(
        draw,
        Scenario::waypoint_mode(draw.class.name(), draw.duration_s, 1.5, waypoints),
    )
}

/// `sc` (its manoeuvres) with what `draw` plants: the vessel, its losses,
/// the water, the sensors as installed, the noise seed.
fn with_draw(draw: &Draw, mut sc: Scenario) -> Scenario {
    sc.seed = draw.seed;
    sc.propellers.port.loss = draw.loss[0];
    sc.propellers.starboard.loss = draw.loss[1];
    sc.propellers.port.onset_s = draw.onset_s;
    sc.propellers.starboard.onset_s = draw.onset_s;
    sc.disturbance = Some(if draw.calm_water {
        twin_sim::DisturbanceSpec::calm()
    } else {
        twin_sim::DisturbanceSpec::default()
    });
    sc.sensors.heading.enabled = true;
    sc.sensors.heading.offset_deg = draw.heading_offset_deg;
    let noise = draw.sensor_noise_scale;
    sc.sensors.gnss.position_sigma_m *= noise;
    sc.sensors.gnss.sog_sigma_mps *= noise;
    sc.sensors.heading.sigma_deg *= noise;
    sc.sensors.propellers.sigma_rpm *= noise;
    sc.sensors.yaw_rate.sigma_deg_s *= noise;
    sc.sensors.gnss.latency_s = -draw.latency_s;
    sc.sensors.gnss.lever_arm = LeverArm {
        x_m: draw.lever_arm_m[0],
        y_m: draw.lever_arm_m[1],
    };
    sc.sensors.propellers.rate_hz = draw.shaft_rate_hz;
    sc.sensors.yaw_rate.enabled = draw.gyro;
    sc.sensors.yaw_rate.bias_deg_s = draw.gyro_bias_deg_s;
    if let Some((speed_mps, toward_deg)) = draw.current {
        sc.current = Some(CurrentSpec {
            speed_mps,
            toward_deg,
            rotation_deg_s: 0.0,
            speed_amplitude_mps: 0.0,
            speed_period_s: 600.0,
        });
    }
    let v = &draw.vessel;
    sc.vessel = (!draw.is_control()).then_some(VesselSpec {
        mass_scale: v.mass,
        added_mass_scale: v.added_mass,
        surge_damping_scale: v.surge_damping,
        sway_damping_scale: v.sway_damping,
        yaw_damping_scale: v.yaw_damping,
        crossflow_drag_scale: v.crossflow,
        thrust_scale: v.thrust,
        ..VesselSpec::default()
    });
    sc
}

fn simulate_own(draw: &Draw) -> Trial {
    simulate_scenario(&own_scenario(draw))
}

/// `twin-sim`'s trial of `sc`.
fn simulate_scenario(sc: &Scenario) -> Trial {
    let run = twin_sim::simulate(sc).expect("a valid scenario");
    let mut log = Vec::new();
    write_jsonl(&run, &mut log).expect("writing to memory");
    Trial {
        log,
        track: run
            .truth
            .iter()
            .map(|t| (t.elapsed_s, t.position))
            .collect(),
        start_s: run.start_unix_s,
    }
}

/// The independent simulator.
pub const OTHER_SIMULATOR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/othersim/otter6dof.py");

fn simulate_other(draw: &Draw) -> Result<Trial, String> {
    let dir =
        std::env::temp_dir().join(format!("twin-trust-{}-{}", std::process::id(), draw.index));
    std::fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
    let log = dir.join("run.jsonl");
    let truth = dir.join("run.truth.json");
    let mut cmd = Command::new("python3");
    let v = &draw.vessel;
    cmd.arg(OTHER_SIMULATOR)
        .args(["--seed", &draw.seed.to_string()])
        .args(["--duration-s", &draw.duration_s.to_string()])
        .args(["--shaft-rate-hz", &draw.shaft_rate_hz.to_string()])
        .args(["--path", draw.other_path()])
        .args(["--mass-scale", &v.mass.to_string()])
        .args(["--added-mass-scale", &v.added_mass.to_string()])
        .args(["--surge-damping-scale", &v.surge_damping.to_string()])
        .args(["--sway-damping-scale", &v.sway_damping.to_string()])
        .args(["--yaw-damping-scale", &v.yaw_damping.to_string()])
        .args(["--crossflow-scale", &v.crossflow.to_string()])
        .args(["--thrust-scale", &v.thrust.to_string()]);
    if draw.gyro {
        cmd.arg("--gyro");
        cmd.arg(format!("--gyro-bias-deg-s={}", draw.gyro_bias_deg_s));
    }
    if draw.calm_water {
        cmd.arg("--calm");
    }
    if draw.heading_offset_deg != 0.0 {
        cmd.arg(format!("--heading-offset-deg={}", draw.heading_offset_deg));
    }
    if draw.latency_s != 0.0 {
        cmd.args(["--latency-s", &draw.latency_s.to_string()]);
    }
    if draw.lever_arm_m != [0.0, 0.0] {
        cmd.arg(format!("--lever-arm-x-m={}", draw.lever_arm_m[0]))
            .arg(format!("--lever-arm-y-m={}", draw.lever_arm_m[1]));
    }
    if let Some((speed, toward)) = draw.current {
        cmd.args(["--current-speed-mps", &speed.to_string()])
            .args(["--current-toward-deg", &toward.to_string()]);
    }
    for (i, side) in ["port", "starboard"].iter().enumerate() {
        if draw.loss[i] > 0.0 {
            cmd.args(["--loss-side", side])
                .args(["--loss", &draw.loss[i].to_string()])
                .args(["--loss-onset-s", &draw.onset_s.to_string()]);
        }
    }
    cmd.arg("--out").arg(&log).arg("--truth").arg(&truth);
    let out = cmd
        .output()
        .map_err(|e| format!("python3 cannot be run: {e}"))?;
    if !out.status.success() {
        return Err(format!(
            "{} failed: {}",
            OTHER_SIMULATOR,
            String::from_utf8_lossy(&out.stderr)
        ));
    }
    let log_bytes = std::fs::read(&log).map_err(|e| e.to_string())?;
    let truth_json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&truth).map_err(|e| e.to_string())?)
            .map_err(|e| e.to_string())?;
    let _ = std::fs::remove_dir_all(&dir);
    let origin = LatLon {
        lat_deg: truth_json["origin"]["lat_deg"].as_f64().unwrap_or(0.0),
        lon_deg: truth_json["origin"]["lon_deg"].as_f64().unwrap_or(0.0),
    };
    let frame = LocalFrame::new(origin).map_err(|e| format!("{e:?}"))?;
    let start_s =
        twin_wire::time::parse_rfc3339(truth_json["start_time"].as_str().unwrap_or_default())
            .map_err(|e| e.to_string())?;
    let track = truth_json["track_1hz"]
        .as_array()
        .map(|points| {
            points
                .iter()
                .map(|p| {
                    (
                        p["t_s"].as_f64().unwrap_or(0.0),
                        frame.to_geodetic(NorthEast {
                            north_m: p["north_m"].as_f64().unwrap_or(0.0),
                            east_m: p["east_m"].as_f64().unwrap_or(0.0),
                        }),
                    )
                })
                .collect()
        })
        .unwrap_or_default();
    Ok(Trial {
        log: log_bytes,
        track,
        start_s,
    })
}

/// Why Python with NumPy cannot run the independent simulator, if it cannot.
pub fn other_simulator_unavailable() -> Option<String> {
    match Command::new("python3")
        .args(["-c", "import numpy"])
        .output()
    {
        Err(e) => Some(format!("python3 cannot be run: {e}")),
        Ok(out) if !out.status.success() => Some(
            "python3 has no NumPy: run `python3 -m pip install -r tests/requirements.txt`"
                .to_string(),
        ),
        Ok(_) => None,
    }
}

/// The fault picture at one time.
#[derive(Debug, Clone, Copy)]
pub struct Sample {
    /// Time since the start of the trial, s.
    pub elapsed_s: f64,
    /// What the twin published.
    pub report: FaultReport,
    /// What the extended twin's filter holds beside what it publishes,
    /// where it runs: what a trace shows beside the losses.
    pub filter: Option<FilterView>,
}

/// The extended twin's filter at one fix, as a trace shows it.
#[derive(Debug, Clone, Copy)]
pub struct FilterView {
    /// The water current `[north, east]`, m/s.
    pub current_mps: [f64; 2],
    /// The heading sensor's offset, rad.
    pub heading_offset_rad: f64,
    /// The filter's own losses `[port, starboard]` with their standard
    /// deviations, before the publication widens their common part and
    /// refers them to the stronger propeller
    /// (`KineticBase::losses` in `twin_core::estimator`).
    pub losses: [(f64, f64); 2],
}

/// One forecast position against the truth.
#[derive(Debug, Clone, Copy)]
pub struct BandCheck {
    /// Horizon, s.
    pub horizon_s: f64,
    /// `|error| / sigma` per axis (north, east).
    pub normalised_error: [f64; 2],
}

/// What the twin published over a trial.
pub struct Record {
    /// The fault report after each accepted fix.
    pub samples: Vec<Sample>,
    /// The forecast checks.
    pub bands: Vec<BandCheck>,
}

/// `trial`'s log read and assembled as `twin analyze` reads it: the
/// fixes and shaft speeds in time order.
pub fn assembled(trial: &Trial) -> Vec<Assembled> {
    let reader = LogReader::open(
        BufReader::new(Cursor::new(&trial.log)),
        ReadOptions::default(),
    )
    .expect("the simulated log opens");
    let mut assembler = FixAssembler::new(AssemblerConfig::default());
    let mut items = Vec::new();
    // The simulators write only well-formed records; a refused one would
    // be the reader's to count, as in `twin analyze`.
    for record in reader.flatten() {
        assembler.push(record, &mut items);
    }
    assembler.finish(&mut items);
    items
}

/// Reads `trial`'s log as `twin analyze` does and runs a twin with `config`
/// over it.
pub fn run(trial: &Trial, config: TwinConfig) -> Record {
    let items = assembled(trial);
    let shafts: Vec<PropellerSpeeds> = items
        .iter()
        .filter_map(|i| match i {
            Assembled::Propellers(p) => Some(*p),
            _ => None,
        })
        .collect();
    let mut twin = VesselTwin::new(config).expect("a valid configuration");
    let mut samples = Vec::new();
    let mut bands = Vec::new();
    let mut next_band_s = COVERAGE_FROM_S;
    for item in &items {
        match item {
            Assembled::Propellers(p) => {
                let _ = twin.on_propellers(p);
            }
            Assembled::Fix(fix) => {
                let Ok(out) = twin.on_gnss(fix) else { continue };
                let elapsed_s = fix.time_s - trial.start_s;
                let filter = twin.kinetic_state().map(|k| FilterView {
                    current_mps: [k.x[idx::CURRENT_NORTH], k.x[idx::CURRENT_EAST]],
                    heading_offset_rad: k.x[idx::HEADING_BIAS],
                    losses: [fault::PORT, fault::STARBOARD]
                        .map(|i| (k.theta[i], k.s[(i, i)].max(0.0).sqrt())),
                });
                samples.push(Sample {
                    elapsed_s,
                    report: out.faults,
                    filter,
                });
                if elapsed_s >= next_band_s && twin.kinetic_active() {
                    next_band_s += BAND_EVERY_S;
                    bands.extend(band_checks(&twin, fix.time_s, &shafts, trial));
                }
            }
            Assembled::Thrust(_) => {}
        }
    }
    Record { samples, bands }
}

/// Forecasts from the twin's estimate at `t0_s` through the logged shaft
/// speeds (their mean over each second) and checks the true position at
/// each horizon.
fn band_checks(
    twin: &VesselTwin,
    t0_s: f64,
    shafts: &[PropellerSpeeds],
    trial: &Trial,
) -> Vec<BandCheck> {
    let longest = HORIZONS_S[HORIZONS_S.len() - 1];
    let inputs: Vec<(f64, ShaftSpeeds)> = (0..longest as usize)
        .map(|k| {
            let (a, b) = (t0_s + k as f64, t0_s + k as f64 + 1.0);
            let within: Vec<&PropellerSpeeds> = shafts
                .iter()
                .filter(|p| p.time_s > a && p.time_s <= b)
                .collect();
            let n = within.len().max(1) as f64;
            let mean =
                |f: fn(&PropellerSpeeds) -> f64| within.iter().map(|p| f(p)).sum::<f64>() / n;
            (
                1.0,
                ShaftSpeeds {
                    port_radps: mean(|p| p.port_radps),
                    starboard_radps: mean(|p| p.starboard_radps),
                },
            )
        })
        .collect();
    let Some(frame) = twin.frame().copied() else {
        return Vec::new();
    };
    let points = twin.forecast_kinetic(inputs);
    let mut checks = Vec::new();
    for h in HORIZONS_S {
        let Some(p) = points.iter().find(|p| (p.time_s - (t0_s + h)).abs() < 1e-6) else {
            continue;
        };
        let target = t0_s + h - trial.start_s;
        let Some(truth) = true_position(&trial.track, target) else {
            continue;
        };
        let t = frame.to_local(truth);
        checks.push(BandCheck {
            horizon_s: h,
            normalised_error: [
                (p.local.north_m - t.north_m).abs() / p.position_sigma_m[0].max(1e-9),
                (p.local.east_m - t.east_m).abs() / p.position_sigma_m[1].max(1e-9),
            ],
        });
    }
    checks
}

/// The true position at `elapsed_s`, interpolated linearly in the track.
fn true_position(track: &[(f64, LatLon)], elapsed_s: f64) -> Option<LatLon> {
    let i = track.partition_point(|(t, _)| *t < elapsed_s);
    if i == 0 || i >= track.len() {
        return None;
    }
    let ((t0, a), (t1, b)) = (track[i - 1], track[i]);
    let w = (elapsed_s - t0) / (t1 - t0);
    Some(LatLon {
        lat_deg: a.lat_deg + w * (b.lat_deg - a.lat_deg),
        lon_deg: a.lon_deg + w * (b.lon_deg - a.lon_deg),
    })
}

/// How one propeller of one draw fared.
#[derive(Debug, Clone, Default)]
pub struct SideScore {
    /// Declared FAULT while healthy.
    pub false_fault: bool,
    /// The propeller lost at least [`MUST_DETECT_LOSS`].
    pub must_detect: bool,
    /// A loss to detect, not declared in time.
    pub missed: bool,
    /// Time from onset to FAULT, s (losses to detect that were detected).
    pub delay_s: Option<f64>,
    /// Reported onset minus true onset, s.
    pub onset_error_s: Option<f64>,
    /// Status changes beyond the truth's.
    pub extra_changes: usize,
    /// Coverage samples: how many, how many covered.
    pub coverage: (usize, usize),
    /// The same for the loss relative to the other propeller, where the
    /// twin calls it excited.
    pub relative_coverage: (usize, usize),
    /// The last published loss and its sigma.
    pub final_loss: f64,
    /// The last published sigma.
    pub final_sigma: f64,
    /// The last status.
    pub final_status: Option<ThrusterStatus>,
    /// Seconds of healthy operation seen (for false FAULTs per hour).
    pub healthy_s: f64,
    /// FAULT declarations while healthy.
    pub false_declarations: usize,
    /// Whether the twin published a profile mismatch that had lasted
    /// [`DecisionConfig::mismatch_withdraw_s`] or longer.
    pub long_mismatch: bool,
    /// Whether it called this propeller `nominal` then (the contract
    /// withdraws a `nominal` by that time).
    pub nominal_under_mismatch: bool,
}

/// How one draw fared.
#[derive(Debug, Clone)]
pub struct DrawScore {
    /// Port and starboard.
    pub sides: [SideScore; 2],
    /// The forecast checks.
    pub bands: Vec<BandCheck>,
    /// The estimator's profile errors against the vessel's perturbation
    /// (surge damping, yaw damping, thrust coefficient: `factor - 1`): per
    /// error, (samples, samples within two of its standard deviations),
    /// every second from [`COVERAGE_FROM_S`].
    pub profile_coverage: [(usize, usize); 3],
}

impl DrawScore {
    /// What went wrong, if anything, in words.
    pub fn failures(&self) -> Vec<String> {
        let mut out = Vec::new();
        for (i, s) in self.sides.iter().enumerate() {
            let side = ["port", "starboard"][i];
            if s.false_fault {
                out.push(format!("{side}: FAULT while healthy"));
            }
            if s.missed {
                out.push(format!("{side}: loss not declared FAULT in time"));
            }
            if s.must_detect && s.final_status == Some(ThrusterStatus::Nominal) {
                out.push(format!("{side}: loss ends called nominal"));
            }
            if s.nominal_under_mismatch {
                out.push(format!("{side}: called nominal through a profile mismatch"));
            }
            if s.onset_error_s.is_some_and(|e| e.abs() > DETECT_WITHIN_S) {
                out.push(format!(
                    "{side}: onset off by {:.0} s",
                    s.onset_error_s.unwrap_or_default()
                ));
            }
            if s.extra_changes > 0 {
                out.push(format!(
                    "{side}: {} status changes too many",
                    s.extra_changes
                ));
            }
        }
        out
    }
}

/// Judges a record of `draw` (module doc).
pub fn score(draw: &Draw, record: &Record) -> DrawScore {
    let sides = std::array::from_fn(|i| score_side(draw, record, i));
    DrawScore {
        sides,
        bands: record.bands.clone(),
        profile_coverage: profile_coverage(draw, record),
    }
}

/// [`DrawScore::profile_coverage`].
fn profile_coverage(draw: &Draw, record: &Record) -> [(usize, usize); 3] {
    let v = &draw.vessel;
    let truth = [v.surge_damping - 1.0, v.yaw_damping - 1.0, v.thrust - 1.0];
    let mut out = [(0, 0); 3];
    let mut next_s = COVERAGE_FROM_S;
    for sample in &record.samples {
        let Some(errors) = sample.report.profile_errors else {
            continue;
        };
        if sample.elapsed_s < next_s {
            continue;
        }
        next_s = sample.elapsed_s.floor() + 1.0;
        for (k, (n, within)) in out.iter_mut().enumerate() {
            let (estimate, sigma) = errors[k];
            *n += 1;
            *within += usize::from((estimate - truth[k]).abs() <= 2.0 * sigma);
        }
    }
    out
}

fn score_side(draw: &Draw, record: &Record, i: usize) -> SideScore {
    let mut s = SideScore::default();
    let true_loss = draw.loss[i];
    let to_detect = true_loss >= MUST_DETECT_LOSS;
    s.must_detect = to_detect;
    let deadline_s = if draw.onset_s > 0.0 {
        draw.onset_s + DETECT_WITHIN_S
    } else {
        COLD_START_S + DETECT_WITHIN_S
    };
    let mut last_status: Option<ThrusterStatus> = None;
    let mut changes = 0usize;
    let mut was_fault = false;
    let mut last_t: Option<f64> = None;
    let mut next_coverage_s = COVERAGE_FROM_S;
    let mut mismatch_since_s: Option<f64> = None;
    let withdraw_s = DecisionConfig::default().mismatch_withdraw_s;
    for sample in &record.samples {
        let t = sample.elapsed_s;
        let th = sample.report.thrusters[i];
        let truth = draw.loss_at(t)[i];
        let status = th.decision.status;
        mismatch_since_s = sample
            .report
            .profile_mismatch
            .map(|_| mismatch_since_s.unwrap_or(t));
        // A fix later than the withdrawal, so that the sampling of the
        // record cannot make a legal status look late.
        if mismatch_since_s.is_some_and(|since| t - since > withdraw_s + 1.0) {
            s.long_mismatch = true;
            s.nominal_under_mismatch |= status == ThrusterStatus::Nominal;
        }
        if let Some(prev) = last_t
            && truth == 0.0
        {
            s.healthy_s += t - prev;
        }
        last_t = Some(t);
        if status == ThrusterStatus::Fault && truth == 0.0 {
            s.false_fault = true;
            if !was_fault {
                s.false_declarations += 1;
            }
        }
        if status == ThrusterStatus::Fault && !was_fault && to_detect && truth > 0.0 {
            let reference = draw.onset_s;
            if s.delay_s.is_none() {
                s.delay_s = Some(t - reference);
                s.onset_error_s =
                    th.decision
                        .onset_time_s
                        .filter(|_| draw.onset_s > 0.0)
                        .map(|o| {
                            // Onsets are message times; the trial started at
                            // the sample's time minus its elapsed time.
                            o - (sample.report.time_s - t) - draw.onset_s
                        });
            }
        }
        was_fault = status == ThrusterStatus::Fault;
        if status != ThrusterStatus::NotExcited {
            if let Some(prev) = last_status
                && prev != status
            {
                changes += 1;
            }
            last_status = Some(status);
        }
        if t >= next_coverage_s && th.loss.is_finite() && th.sigma.is_finite() {
            next_coverage_s = t.floor() + 1.0;
            s.coverage.0 += 1;
            s.coverage.1 += usize::from((th.loss - truth).abs() <= 2.0 * th.sigma);
            if th.relative_excited && th.relative_sigma.is_finite() {
                let other = draw.loss_at(t)[1 - i];
                let true_relative = 1.0 - (1.0 - truth) / (1.0 - other);
                s.relative_coverage.0 += 1;
                s.relative_coverage.1 += usize::from(
                    (th.relative_loss - true_relative).abs() <= 2.0 * th.relative_sigma,
                );
            }
        }
        s.final_loss = th.loss;
        s.final_sigma = th.sigma;
        s.final_status = Some(status);
    }
    if to_detect {
        s.missed = s.delay_s.is_none_or(|d| draw.onset_s + d > deadline_s);
    }
    let allowed = usize::from(true_loss > 0.0);
    s.extra_changes = changes.saturating_sub(allowed);
    s
}

/// The matrix over many draws.
#[derive(Debug, Clone, Default)]
pub struct Matrix {
    /// Per `(simulator, class)`: the draws and their scores.
    pub cells: BTreeMap<(Simulator, Class), Vec<(Draw, DrawScore)>>,
}

impl Matrix {
    /// Adds a judged draw.
    pub fn add(&mut self, draw: Draw, score: DrawScore) {
        self.cells
            .entry((draw.simulator, draw.class))
            .or_default()
            .push((draw, score));
    }

    fn all(&self) -> impl Iterator<Item = &(Draw, DrawScore)> {
        self.cells.values().flatten()
    }

    /// The losses of at least [`GOAL_LOSS`] that start mid-trial on a
    /// manoeuvring vessel (neither a straight run nor a steady turn), and
    /// how many of them are declared FAULT within [`GOAL_WITHIN_S`] of
    /// their onset: `(declared in time, losses)`.
    pub fn goal_detections(&self) -> (usize, usize) {
        self.sides()
            .filter(|(d, i, _)| {
                d.loss[*i] >= GOAL_LOSS
                    && d.onset_s > 0.0
                    && !d.class.straight()
                    && !d.class.steady_turn()
            })
            .fold((0, 0), |(k, n), (_, _, x)| {
                (
                    k + usize::from(x.delay_s.is_some_and(|t| t <= GOAL_WITHIN_S)),
                    n + 1,
                )
            })
    }

    fn sides(&self) -> impl Iterator<Item = (&Draw, usize, &SideScore)> {
        self.all()
            .flat_map(|(d, s)| s.sides.iter().enumerate().map(move |(i, x)| (d, i, x)))
    }

    /// Propellers that lost at least [`MUST_DETECT_LOSS`] and end their
    /// trial with another status than FAULT.
    pub fn losses_not_ending_fault(&self) -> usize {
        self.final_statuses_of_losses()
            .filter(|s| *s != Some(ThrusterStatus::Fault))
            .count()
    }

    /// Propellers that lost at least [`MUST_DETECT_LOSS`] and end their
    /// trial declared FAULT.
    pub fn losses_ending_fault(&self) -> usize {
        self.final_statuses_of_losses()
            .filter(|s| *s == Some(ThrusterStatus::Fault))
            .count()
    }

    fn final_statuses_of_losses(&self) -> impl Iterator<Item = Option<ThrusterStatus>> {
        self.sides()
            .filter(|(d, i, _)| d.loss[*i] >= MUST_DETECT_LOSS)
            .map(|(_, _, s)| s.final_status)
    }

    /// Propellers that lost at least [`MUST_DETECT_LOSS`].
    pub fn losses_to_detect(&self) -> usize {
        self.final_statuses_of_losses().count()
    }

    /// Propellers that lost at least [`MUST_DETECT_LOSS`] and end their
    /// trial called nominal: a loss the twin vouches is not there.
    pub fn losses_ending_nominal(&self) -> usize {
        self.final_statuses_of_losses()
            .filter(|s| *s == Some(ThrusterStatus::Nominal))
            .count()
    }

    /// Propellers called `nominal` after a profile mismatch had lasted
    /// [`DecisionConfig::mismatch_withdraw_s`] (the contract withdraws
    /// it), and propellers that went through such a mismatch at all.
    pub fn nominal_under_mismatch(&self) -> (usize, usize) {
        self.sides().fold((0, 0), |(n, all), (_, _, s)| {
            (
                n + usize::from(s.nominal_under_mismatch),
                all + usize::from(s.long_mismatch),
            )
        })
    }

    /// Propellers that lost nothing over their trial.
    pub fn healthy_propellers(&self) -> usize {
        self.sides().filter(|(d, i, _)| d.loss[*i] == 0.0).count()
    }

    /// Propellers that lost nothing and end their trial `not_excited`: a
    /// health the twin does not vouch for.
    pub fn healthy_ending_not_excited(&self) -> usize {
        self.sides()
            .filter(|(d, i, s)| {
                d.loss[*i] == 0.0 && s.final_status == Some(ThrusterStatus::NotExcited)
            })
            .count()
    }

    /// Draws judged.
    pub fn draws(&self) -> usize {
        self.all().count()
    }

    /// Healthy propellers declared FAULT (any time), wrong side included.
    pub fn false_faults(&self) -> usize {
        self.sides().filter(|(_, _, s)| s.false_fault).count()
    }

    /// Losses to detect that were not declared in time.
    pub fn missed(&self) -> usize {
        self.sides().filter(|(_, _, s)| s.missed).count()
    }

    /// Propellers with more status changes than the truth had.
    pub fn flapping(&self) -> usize {
        self.sides().filter(|(_, _, s)| s.extra_changes > 0).count()
    }

    /// Reported onsets more than [`DETECT_WITHIN_S`] from the truth.
    pub fn late_onsets(&self) -> usize {
        self.sides()
            .filter(|(_, _, s)| s.onset_error_s.is_some_and(|e| e.abs() > DETECT_WITHIN_S))
            .count()
    }

    /// Share of samples with `|loss - truth| <= 2 sigma`.
    pub fn sigma_coverage(&self) -> f64 {
        let (n, k) = self.sides().fold((0, 0), |(n, k), (_, _, s)| {
            (n + s.coverage.0, k + s.coverage.1)
        });
        k as f64 / n.max(1) as f64
    }

    /// Share of samples with `|relative loss - truth| <= 2 sigma`, where
    /// the relative loss is excited.
    pub fn relative_sigma_coverage(&self) -> f64 {
        let (n, k) = self.sides().fold((0, 0), |(n, k), (_, _, s)| {
            (n + s.relative_coverage.0, k + s.relative_coverage.1)
        });
        k as f64 / n.max(1) as f64
    }

    /// Per profile error (surge damping, yaw damping, thrust coefficient),
    /// the share of samples within two of its standard deviations of the
    /// drawn perturbation ([`DrawScore::profile_coverage`]).
    pub fn profile_error_coverage(&self) -> [f64; 3] {
        std::array::from_fn(|k| {
            let (n, w) = self.all().fold((0, 0), |(n, w), (_, s)| {
                (n + s.profile_coverage[k].0, w + s.profile_coverage[k].1)
            });
            w as f64 / n.max(1) as f64
        })
    }

    /// Share of (check, axis) within two sigmas at `horizon_s`.
    pub fn band_coverage(&self, horizon_s: f64) -> f64 {
        let (n, k) = self
            .all()
            .flat_map(|(_, s)| s.bands.iter())
            .filter(|b| b.horizon_s == horizon_s)
            .fold((0, 0), |(n, k), b| {
                (
                    n + 2,
                    k + b.normalised_error.iter().filter(|e| **e <= 2.0).count(),
                )
            });
        k as f64 / n.max(1) as f64
    }

    /// FAULT declarations on healthy propellers per hour of healthy
    /// operation.
    pub fn false_faults_per_hour(&self) -> f64 {
        let (n, s) = self.sides().fold((0, 0.0), |(n, t), (_, _, x)| {
            (n + x.false_declarations, t + x.healthy_s)
        });
        n as f64 / (s / 3600.0).max(1e-9)
    }

    /// Every draw that failed a bar, with why.
    pub fn failures(&self) -> Vec<String> {
        self.all()
            .filter_map(|(d, s)| {
                let f = s.failures();
                (!f.is_empty()).then(|| format!("{}: {}", d.describe(), f.join("; ")))
            })
            .collect()
    }

    /// The tables, as markdown.
    pub fn report(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(
            out,
            "| simulator | class | draws | false FAULT | missed | flapping | sigma coverage | detection delay median / max (s) | median abs error (loss) |"
        );
        let _ = writeln!(out, "|---|---|---:|---:|---:|---:|---:|---|---:|");
        for ((sim, class), cell) in &self.cells {
            let sides = cell
                .iter()
                .flat_map(|(d, s)| s.sides.iter().enumerate().map(move |(i, x)| (d, i, x)));
            let (mut ff, mut miss, mut flap, mut cov) = (0, 0, 0, (0, 0));
            let mut delays = Vec::new();
            let mut errors = Vec::new();
            for (d, i, x) in sides {
                ff += usize::from(x.false_fault);
                miss += usize::from(x.missed);
                flap += usize::from(x.extra_changes > 0);
                cov.0 += x.coverage.0;
                cov.1 += x.coverage.1;
                delays.extend(x.delay_s);
                if x.final_loss.is_finite() {
                    errors.push((x.final_loss - d.loss[i]).abs());
                }
            }
            let _ = writeln!(
                out,
                "| {} | {} | {} | {} | {} | {} | {:.2} | {} | {} |",
                sim.name(),
                class.name(),
                cell.len(),
                ff,
                miss,
                flap,
                cov.1 as f64 / cov.0.max(1) as f64,
                if delays.is_empty() {
                    "-".to_string()
                } else {
                    format!("{:.1} / {:.1}", median(&mut delays), max(&delays))
                },
                if errors.is_empty() {
                    "-".to_string()
                } else {
                    format!("{:.3}", median(&mut errors))
                },
            );
        }
        let _ = writeln!(out);
        let _ = writeln!(out, "Final status per propeller (rows: the truth):");
        let _ = writeln!(out);
        let _ = writeln!(out, "| truth | not_excited | nominal | suspect | fault |");
        let _ = writeln!(out, "|---|---:|---:|---:|---:|");
        for (label, lossy) in [("healthy", false), ("loss >= 0.15", true)] {
            let mut counts = [0usize; 4];
            for (d, i, x) in self.sides() {
                if (d.loss[i] >= MUST_DETECT_LOSS) != lossy {
                    continue;
                }
                let k = match x.final_status {
                    Some(ThrusterStatus::Nominal) => 1,
                    Some(ThrusterStatus::Suspect) => 2,
                    Some(ThrusterStatus::Fault) => 3,
                    _ => 0,
                };
                counts[k] += 1;
            }
            let _ = writeln!(
                out,
                "| {label} | {} | {} | {} | {} |",
                counts[0], counts[1], counts[2], counts[3]
            );
        }
        let _ = writeln!(out);
        self.write_summary(&mut out);
        out
    }

    /// The report's closing lines: coverages, counts, the detection goal
    /// and the profile errors' coverage.
    fn write_summary(&self, out: &mut String) {
        let (nominal_under_mismatch, through_mismatch) = self.nominal_under_mismatch();
        let _ = writeln!(
            out,
            "sigma coverage (|loss - truth| <= 2 sigma) {:.3}, of the relative loss {:.3}; forecast band coverage (2 sigma per axis) at {}; false FAULTs per hour of healthy operation {:.2}; false FAULT {}, missed {}, flapping {}, late onset {}; called nominal {:.0} s into a profile mismatch {} (of {} propellers through one)",
            self.sigma_coverage(),
            self.relative_sigma_coverage(),
            HORIZONS_S
                .iter()
                .map(|h| format!("{h:.0} s {:.3}", self.band_coverage(*h)))
                .collect::<Vec<_>>()
                .join(", "),
            self.false_faults_per_hour(),
            self.false_faults(),
            self.missed(),
            self.flapping(),
            self.late_onsets(),
            DecisionConfig::default().mismatch_withdraw_s,
            nominal_under_mismatch,
            through_mismatch,
        );
        let (in_time, goal_losses) = self.goal_detections();
        let _ = writeln!(
            out,
            "losses of {:.0} % or more starting mid-trial on a manoeuvring vessel declared FAULT within {GOAL_WITHIN_S:.0} s of their onset (a goal, not a bar): {in_time} of {goal_losses}",
            100.0 * GOAL_LOSS
        );
        let [du, dr, dk] = self.profile_error_coverage();
        let _ = writeln!(
            out,
            "the estimator's profile errors (not published on twin/fault) within 2 sigma of the vessel's drawn factor - 1: surge damping {du:.3}, yaw damping {dr:.3}, thrust coefficient {dk:.3}"
        );
    }
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn max(v: &[f64]) -> f64 {
    v.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
}

/// Runs and judges `draws` on `threads` threads with the twin's `config`.
pub fn run_matrix(draws: &[Draw], config: TwinConfig, threads: usize) -> Result<Matrix, String> {
    run_matrix_with(draws, threads, |_| Ok(config))
}

/// The twin's `config` with the GNSS antenna where `draw` put it, as a
/// profile that states the antenna's position (`gnss.antenna_forward_m`,
/// `gnss.antenna_starboard_m`) gives it.
pub fn with_known_antenna(config: TwinConfig, draw: &Draw) -> TwinConfig {
    let mut config = config;
    config.kinetic.params.antenna_m = draw.lever_arm_m;
    config
}

/// The identification trial of `draw`'s vessel: the same hull, propellers
/// and sensors as installed (the antenna's place, the heading sensor's
/// offset, the GNSS latency, the shaft-speed sampling, the gyro), sailed
/// healthy in still water on another day (another noise seed). On
/// `twin-sim` its manoeuvres are those of the shipped identification
/// trial ([`IDENTIFICATION_SCENARIO`]: steps of thrust, turns both ways, a
/// zig-zag); the independent simulator sails its lawn-mower.
pub fn identification_draw(draw: &Draw) -> Draw {
    Draw {
        class: Class::Healthy,
        seed: draw.seed ^ 0x005e_ed1d,
        loss: [0.0, 0.0],
        onset_s: 0.0,
        current: None,
        turn_sign: 1.0,
        ..*draw
    }
}

/// The shipped identification trial whose manoeuvres `twin-sim`'s
/// identification trials sail (docs/identification.md).
pub const IDENTIFICATION_SCENARIO: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../config/scenarios/identify_heavy-otter.toml"
);

/// [`IDENTIFICATION_SCENARIO`], read once.
fn identification_scenario() -> Result<Scenario, String> {
    static SHIPPED: std::sync::OnceLock<Result<Scenario, String>> = std::sync::OnceLock::new();
    SHIPPED
        .get_or_init(|| {
            let text = std::fs::read_to_string(IDENTIFICATION_SCENARIO)
                .map_err(|e| format!("{IDENTIFICATION_SCENARIO}: {e}"))?;
            Scenario::from_toml_str(&text).map_err(|e| format!("{IDENTIFICATION_SCENARIO}: {e}"))
        })
        .clone()
}

/// The twin's `config` on the profile `twin identify` gives from the
/// identification trial of `draw`'s vessel ([`identification_draw`]),
/// starting from the Otter's with the antenna where `config` puts it:
/// what an operator who ran that trial first would sail with
/// (docs/identification.md).
pub fn with_identified_profile(config: TwinConfig, draw: &Draw) -> Result<TwinConfig, String> {
    let (start, trial) = healthy_trial(&config, draw)?;
    let report = twin_cli::identify::identify_reader(
        Cursor::new(&trial.log),
        std::path::Path::new("identification-trial.jsonl"),
        twin_wire::assemble::SourceChoice::Best,
        &start,
        "identified",
        &twin_core::diagnose::IdentifyConfig::default(),
    )
    .map_err(|e| format!("{}: {e}", draw.describe()))?;
    Ok(report.identified.twin_config(config))
}

/// The Otter's profile with the antenna where `config` puts it, and the
/// healthy trial of `draw`'s vessel ([`identification_draw`]) on the
/// simulator of `draw`.
fn healthy_trial(
    config: &TwinConfig,
    draw: &Draw,
) -> Result<(twin_wire::profile::VesselProfile, Trial), String> {
    let healthy = identification_draw(draw);
    let mut start = twin_wire::profile::VesselProfile::otter();
    [start.gnss.antenna_forward_m, start.gnss.antenna_starboard_m] =
        config.kinetic.params.antenna_m;
    let trial = match draw.simulator {
        Simulator::Own => simulate_scenario(&with_draw(&healthy, identification_scenario()?)),
        Simulator::Other => simulate_other(&healthy)?,
    };
    Ok((start, trial))
}

/// The name the healthy trial's log is diagnosed under.
pub const HEALTHY_TRIAL_LOG: &str = "healthy-trial.jsonl";

/// `twin diagnose` of the same healthy trial of `draw`'s vessel as
/// [`with_identified_profile`] sails, on the Otter's profile with the
/// antenna where `config` puts it: that profile, and the report.
pub fn diagnose_healthy_trial(
    config: &TwinConfig,
    draw: &Draw,
) -> Result<
    (
        twin_wire::profile::VesselProfile,
        twin_cli::diagnose::DiagnoseReport,
    ),
    String,
> {
    let (start, trial) = healthy_trial(config, draw)?;
    let log = twin_cli::diagnose::load(
        Cursor::new(&trial.log),
        std::path::Path::new(HEALTHY_TRIAL_LOG),
        twin_wire::assemble::SourceChoice::Best,
    )
    .map_err(|e| format!("{}: {e}", draw.describe()))?;
    let report = twin_cli::diagnose::diagnose_loaded(
        HEALTHY_TRIAL_LOG,
        &log,
        &twin_core::diagnose::DiagnoseConfig::default(),
        &start,
    )
    .map_err(|e| format!("{}: {e}", draw.describe()))?;
    Ok((start, report))
}

/// The profile `twin diagnose --out` writes from [`diagnose_healthy_trial`]:
/// the antenna's position and the hull's scales the diagnosis finds,
/// carried into the starting profile
/// (`twin_cli::diagnose::profile_with_findings`), with what was carried and
/// what not.
pub fn diagnosed_profile(
    config: &TwinConfig,
    draw: &Draw,
) -> Result<twin_cli::diagnose::DiagnosedProfile, String> {
    let (start, report) = diagnose_healthy_trial(config, draw)?;
    let diagnosed = twin_cli::diagnose::profile_with_findings(
        &start,
        &report.findings,
        HEALTHY_TRIAL_LOG,
        "diagnosed",
    );
    diagnosed
        .profile
        .validate()
        .map_err(|e| format!("{}: {e}", draw.describe()))?;
    Ok(diagnosed)
}

/// [`run_matrix`] with the twin's configuration chosen per draw by
/// `config_of` (e.g. [`with_known_antenna`], [`with_identified_profile`]).
pub fn run_matrix_with(
    draws: &[Draw],
    threads: usize,
    config_of: impl Fn(&Draw) -> Result<TwinConfig, String> + Sync,
) -> Result<Matrix, String> {
    let next = std::sync::atomic::AtomicUsize::new(0);
    let results = std::sync::Mutex::new(Vec::new());
    let error = std::sync::Mutex::new(None::<String>);
    std::thread::scope(|s| {
        for _ in 0..threads.max(1) {
            s.spawn(|| {
                loop {
                    let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    let Some(draw) = draws.get(i) else { break };
                    match simulate(draw).and_then(|trial| Ok((trial, config_of(draw)?))) {
                        Ok((trial, config)) => {
                            let record = run(&trial, config);
                            let sc = score(draw, &record);
                            if let Ok(mut r) = results.lock() {
                                r.push((*draw, sc));
                            }
                        }
                        Err(e) => {
                            if let Ok(mut slot) = error.lock() {
                                slot.get_or_insert(e);
                            }
                        }
                    }
                }
            });
        }
    });
    if let Some(e) = error.into_inner().ok().flatten() {
        return Err(e);
    }
    let mut matrix = Matrix::default();
    let mut results = results.into_inner().unwrap_or_default();
    results.sort_by_key(|(d, _)| d.index);
    for (d, s) in results {
        matrix.add(d, s);
    }
    Ok(matrix)
}
