//! The simulation loop: integrates the Otter with RK4, runs the autopilot at
//! its rate, samples the sensors and the truth, and collects everything into
//! a [`SimRun`].
//!
//! Time is driven by a schedule of exact instants (`k / rate` for each of the
//! control loop, the truth series and every sensor, plus the onsets of losses
//! and manual commands), so every sample is taken at its true time whatever
//! the integration step: between two instants the integrator takes equal
//! steps no longer than `step_s`. Over one step the commanded shaft speeds,
//! the losses and the random disturbance are held; the current and the wind
//! are evaluated at each RK4 stage. The disturbance is updated on a clock of
//! its own (every twentieth of its correlation time, see
//! [`crate::disturbance`]) whose ticks are scheduled instants, so its
//! realisation depends neither on the step nor on the sensors' rates.

use twin_core::geodesy::{LatLon, NorthEast, course_of, wrap_two_pi};
use twin_core::sample::{GnssFix, PropellerSpeeds};

use crate::control::{HeadingAutopilot, SpeedController, allocate};
use crate::disturbance::DisturbanceProcess;
use crate::guidance::{LineOfSight, WaypointPass};
use crate::otter::{Actuation, OtterModel, StateVector, Surroundings, idx, rk4_step};
use crate::scenario::{Drive, Plan, Scenario, ScenarioError};
use crate::sensors::{
    BodyMotion, GnssSensor, HeadingSample, HeadingSensor, PropellerSensor, SensorEvent,
    YawRateSensor, radps_to_rpm,
};

/// Two instants closer than this are the same instant, s.
const SAME_INSTANT_S: f64 = 1e-9;

/// Rate of the truth series when GNSS is off, Hz.
const DEFAULT_TRUTH_RATE_HZ: f64 = 5.0;

/// The true state of the craft at one instant (body origin: midships on the
/// centre line).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthSample {
    /// Time, seconds since the Unix epoch.
    pub time_s: f64,
    /// Time since the trial's start, s.
    pub elapsed_s: f64,
    /// Position of the body origin.
    pub position: LatLon,
    /// North of the frame's origin, m.
    pub north_m: f64,
    /// East of the frame's origin, m.
    pub east_m: f64,
    /// Heading, rad clockwise from north, in [0, 2 pi).
    pub heading_rad: f64,
    /// Surge velocity over ground, m/s.
    pub u_mps: f64,
    /// Sway velocity over ground, m/s.
    pub v_mps: f64,
    /// Yaw rate, rad/s (positive: bow to starboard).
    pub r_radps: f64,
    /// Speed over ground of the body origin, m/s.
    pub sog_mps: f64,
    /// Course over ground of the body origin, rad in [0, 2 pi).
    pub cog_rad: f64,
    /// Surge velocity through the water, m/s.
    pub u_water_mps: f64,
    /// Sway velocity through the water, m/s.
    pub v_water_mps: f64,
    /// Actual shaft speeds (port, starboard), rad/s.
    pub shaft_radps: [f64; 2],
    /// Commanded shaft speeds (port, starboard), rad/s.
    pub shaft_cmd_radps: [f64; 2],
    /// Effective thrust of each propeller, `(1 - loss) T`, N.
    pub thrust_n: [f64; 2],
    /// Loss of effectiveness of each propeller, 0..1.
    pub loss: [f64; 2],
    /// Water current (north, east), m/s.
    pub current_ned_mps: [f64; 2],
    /// Random disturbance on the hull, body frame: surge force (N), sway
    /// force (N), yaw moment (N m); held from this instant over the next
    /// integration step. Zero without a `[disturbance]` section.
    pub disturbance_force: [f64; 3],
    /// Cross-track error from the active leg, m, positive to starboard
    /// (way-point mode only).
    pub cross_track_m: Option<f64>,
    /// Index of the way-point the active leg starts from (way-point mode only).
    pub leg: Option<usize>,
}

impl TruthSample {
    /// Actual shaft speeds (port, starboard), rpm.
    pub fn shaft_rpm(&self) -> [f64; 2] {
        self.shaft_radps.map(radps_to_rpm)
    }

    /// Speed through the water, m/s.
    pub fn speed_through_water_mps(&self) -> f64 {
        self.u_water_mps.hypot(self.v_water_mps)
    }
}

/// Everything one simulated trial produced.
#[derive(Debug, Clone, PartialEq)]
pub struct SimRun {
    /// The scenario's name.
    pub name: String,
    /// Unix time of the start, s.
    pub start_unix_s: f64,
    /// Origin of the local frame.
    pub origin: LatLon,
    /// Sensor outputs in time-stamp order.
    pub events: Vec<SensorEvent>,
    /// The true state at the GNSS rate (true sample times, no latency).
    pub truth: Vec<TruthSample>,
    /// Way-points reached, in order (way-point mode).
    pub waypoint_passes: Vec<WaypointPass>,
}

impl SimRun {
    /// The GNSS fixes, in stamp order.
    pub fn gnss_fixes(&self) -> impl Iterator<Item = &GnssFix> {
        self.events.iter().filter_map(|e| match e {
            SensorEvent::Gnss(f) => Some(f),
            _ => None,
        })
    }

    /// The heading measurements, in time order.
    pub fn headings(&self) -> impl Iterator<Item = &HeadingSample> {
        self.events.iter().filter_map(|e| match e {
            SensorEvent::Heading(h) => Some(h),
            _ => None,
        })
    }

    /// The measured shaft speeds, in time order.
    pub fn measured_propellers(&self) -> impl Iterator<Item = &PropellerSpeeds> {
        self.events.iter().filter_map(|e| match e {
            SensorEvent::PropellerMeasured(p) => Some(p),
            _ => None,
        })
    }

    /// The commanded shaft speeds, in time order.
    pub fn commanded_propellers(&self) -> impl Iterator<Item = &PropellerSpeeds> {
        self.events.iter().filter_map(|e| match e {
            SensorEvent::PropellerCommanded(p) => Some(p),
            _ => None,
        })
    }
}

/// Validates the scenario and runs it.
pub fn simulate(scenario: &Scenario) -> Result<SimRun, ScenarioError> {
    let plan = scenario.validate()?;
    Ok(run_plan(&plan))
}

/// A periodic instant: due at `next * period_s`.
#[derive(Debug, Clone, Copy)]
struct Ticker {
    period_s: f64,
    next: u64,
}

impl Ticker {
    fn new(period_s: f64) -> Self {
        Self { period_s, next: 0 }
    }

    fn due_s(&self) -> f64 {
        self.next as f64 * self.period_s
    }

    /// True (and advanced) if due at `t_s`.
    fn fire(&mut self, t_s: f64) -> bool {
        if self.due_s() <= t_s + SAME_INSTANT_S {
            self.next += 1;
            true
        } else {
            false
        }
    }
}

/// The autopilot in way-point mode.
struct Autopilot {
    los: LineOfSight,
    heading: HeadingAutopilot,
    speed: SpeedController,
    speed_mps: f64,
    saturated: bool,
}

/// Runs a validated plan: at each instant something happens (a control
/// tick, a sample, a disturbance update, a loss onset or a manual command),
/// control, record, then integrate to the next such instant.
pub fn run_plan(plan: &Plan) -> SimRun {
    let mut run = Run::new(plan);
    let mut t = 0.0_f64;
    loop {
        let body = body_motion(&run.x);
        let disturbance_force = run.disturbance_at(t);
        run.control(t, &body);
        run.record(t, &body, disturbance_force);
        if t >= plan.duration_s - SAME_INSTANT_S {
            break;
        }
        let t_next = run.next_instant(t);
        run.integrate(t, t_next, disturbance_force);
        t = t_next;
    }
    run.finish()
}

/// A run in progress: the vessel's state, its controller, the clocks of
/// everything periodic, and what has been recorded.
struct Run<'a> {
    plan: &'a Plan,
    model: OtterModel,
    x: StateVector,
    n_cmd: [f64; 2],
    autopilot: Option<Autopilot>,
    /// Loss onsets and manual command changes, in order.
    breakpoints: Vec<f64>,
    control_clock: Ticker,
    truth_clock: Ticker,
    gnss: Option<(GnssSensor, Ticker)>,
    heading: Option<(HeadingSensor, Ticker)>,
    props: Option<(PropellerSensor, Ticker)>,
    gyro: Option<(YawRateSensor, Ticker)>,
    disturbance: Option<(DisturbanceProcess, Ticker)>,
    events: Vec<SensorEvent>,
    truth: Vec<TruthSample>,
    passes: Vec<WaypointPass>,
}

impl<'a> Run<'a> {
    fn new(plan: &'a Plan) -> Self {
        let model = OtterModel::new(plan.vessel.clone());
        // Initial state: at speed in still water, shafts turning to hold it.
        let [north0, east0, psi0, speed0] = plan.initial;
        let hold_thrust_n = -model.params.x_u_n_per_mps * speed0 / 2.0;
        let n0 = model.params.shaft_speed_for_thrust_radps(hold_thrust_n);
        let x = StateVector::from_column_slice(&[north0, east0, psi0, speed0, 0.0, 0.0, n0, n0]);
        let autopilot = match &plan.drive {
            Drive::Waypoints {
                waypoints,
                speed_mps,
            } => Some(Autopilot {
                los: LineOfSight::new(
                    waypoints.clone(),
                    plan.lookahead_m,
                    plan.acceptance_radius_m,
                    plan.ilos_gain,
                ),
                heading: HeadingAutopilot::new(plan.tuning, psi0, 0.0),
                speed: SpeedController::new(plan.tuning.speed_bandwidth_radps),
                speed_mps: *speed_mps,
                saturated: false,
            }),
            Drive::Manual(_) => None,
        };
        let mut breakpoints: Vec<f64> = plan.losses.iter().map(|l| l.onset_s).collect();
        if let Drive::Manual(cmds) = &plan.drive {
            breakpoints.extend(cmds.iter().map(|(t, _)| *t));
        }
        breakpoints.retain(|t| *t > 0.0 && *t < plan.duration_s);
        breakpoints.sort_by(f64::total_cmp);
        let truth_period = plan
            .gnss
            .map_or(1.0 / DEFAULT_TRUTH_RATE_HZ, |g| g.period_s);
        Self {
            plan,
            model,
            x,
            n_cmd: [n0, n0],
            autopilot,
            breakpoints,
            control_clock: Ticker::new(plan.control_period_s),
            truth_clock: Ticker::new(truth_period),
            gnss: plan
                .gnss
                .map(|s| (GnssSensor::new(s, plan.seed), Ticker::new(s.period_s))),
            heading: plan
                .heading
                .map(|s| (HeadingSensor::new(s, plan.seed), Ticker::new(s.period_s))),
            props: plan
                .propellers
                .map(|s| (PropellerSensor::new(s, plan.seed), Ticker::new(s.period_s))),
            gyro: plan
                .yaw_rate
                .map(|s| (YawRateSensor::new(s, plan.seed), Ticker::new(s.period_s))),
            disturbance: plan.disturbance.map(|s| {
                (
                    DisturbanceProcess::new(s, plan.seed),
                    Ticker::new(s.update_period_s()),
                )
            }),
            events: Vec::new(),
            truth: Vec::new(),
            passes: Vec::new(),
        }
    }

    fn loss_at(&self, t_s: f64) -> [f64; 2] {
        [self.plan.losses[0].at(t_s), self.plan.losses[1].at(t_s)]
    }

    /// The manual shaft-speed command in force at `t_s`.
    fn manual_at(&self, t_s: f64) -> [f64; 2] {
        match &self.plan.drive {
            Drive::Manual(cmds) => cmds
                .iter()
                .rev()
                .find(|(from, _)| *from <= t_s + SAME_INSTANT_S)
                .map_or([0.0, 0.0], |(_, n)| *n),
            Drive::Waypoints { .. } => [0.0, 0.0],
        }
    }

    /// The random disturbance's force at `t`, advanced when due.
    fn disturbance_at(&mut self, t: f64) -> [f64; 3] {
        if let Some((process, clock)) = self.disturbance.as_mut()
            && clock.fire(t)
        {
            process.advance_to(t);
        }
        self.disturbance
            .as_ref()
            .map_or([0.0; 3], |(p, _)| p.value())
    }

    /// The shaft-speed commands at `t`: the autopilot at its control ticks,
    /// or the manual command in force.
    fn control(&mut self, t: f64, body: &BodyMotion) {
        let plan = self.plan;
        let params = &self.model.params;
        if self.control_clock.fire(t)
            && let Some(ap) = self.autopilot.as_mut()
        {
            let h = plan.control_period_s;
            let los = ap
                .los
                .update(t, body.north_m, body.east_m, h, &mut self.passes);
            let yaw_nm = ap.heading.update(
                los.heading_cmd_rad,
                body.psi_rad,
                body.r_radps,
                h,
                ap.saturated,
            );
            let speed = body.u_mps.hypot(body.v_mps).copysign(body.u_mps);
            let surge_n = ap.speed.update(ap.speed_mps, speed, h, ap.saturated);
            let alloc = allocate(params, surge_n, yaw_nm);
            ap.saturated = alloc.saturated;
            self.n_cmd = alloc.n_cmd_radps;
        }
        if self.autopilot.is_none() {
            // Manual commands change at their own instants, not only at control ticks.
            self.n_cmd = self.manual_at(t).map(|n| params.saturate_shaft_radps(n));
        }
    }

    /// The truth and every sensor sample due at `t`.
    fn record(&mut self, t: f64, body: &BodyMotion, disturbance_force: [f64; 3]) {
        let plan = self.plan;
        let start = plan.start_unix_s;
        if self.truth_clock.fire(t) {
            let act = Actuation {
                n_cmd_radps: self.n_cmd,
                loss: self.loss_at(t),
            };
            self.truth.push(truth_sample(
                plan,
                &self.model,
                &self.x,
                t,
                &act,
                disturbance_force,
                self.autopilot.as_ref().map(|ap| &ap.los),
            ));
        }
        if let Some((sensor, clock)) = self.gnss.as_mut()
            && clock.fire(t)
        {
            self.events.push(SensorEvent::Gnss(sensor.sample(
                t,
                start,
                body,
                &plan.frame,
            )));
        }
        if let Some((sensor, clock)) = self.heading.as_mut()
            && clock.fire(t)
        {
            self.events
                .push(SensorEvent::Heading(sensor.sample(t, start, body.psi_rad)));
        }
        if let Some((sensor, clock)) = self.props.as_mut()
            && clock.fire(t)
        {
            let shafts = [self.x[idx::N_PORT], self.x[idx::N_STB]];
            self.events.push(SensorEvent::PropellerMeasured(
                sensor.sample(t, start, shafts),
            ));
            self.events
                .push(SensorEvent::PropellerCommanded(PropellerSpeeds {
                    time_s: start + t,
                    port_radps: self.n_cmd[0],
                    starboard_radps: self.n_cmd[1],
                }));
        }
        if let Some((sensor, clock)) = self.gyro.as_mut()
            && clock.fire(t)
        {
            self.events
                .push(SensorEvent::YawRate(sensor.sample(t, start, body.r_radps)));
        }
    }

    /// The next instant after `t` at which something happens.
    fn next_instant(&self, t: f64) -> f64 {
        let mut t_next = self
            .plan
            .duration_s
            .min(self.control_clock.due_s())
            .min(self.truth_clock.due_s());
        for due in [
            self.gnss.as_ref().map(|(_, c)| c.due_s()),
            self.heading.as_ref().map(|(_, c)| c.due_s()),
            self.props.as_ref().map(|(_, c)| c.due_s()),
            self.gyro.as_ref().map(|(_, c)| c.due_s()),
            self.disturbance.as_ref().map(|(_, c)| c.due_s()),
            self.breakpoints
                .iter()
                .copied()
                .find(|b| *b > t + SAME_INSTANT_S),
        ]
        .into_iter()
        .flatten()
        {
            t_next = t_next.min(due);
        }
        t_next
    }

    /// Integrates the state from `t` to `t_next` ([`integrate_held`]).
    fn integrate(&mut self, t: f64, t_next: f64, disturbance_force: [f64; 3]) {
        self.x = integrate_held(
            self.plan,
            &self.model,
            &self.x,
            (t, t_next),
            self.n_cmd,
            |ts| self.loss_at(ts),
            disturbance_force,
        );
    }

    fn finish(self) -> SimRun {
        let mut events = self.events;
        events.sort_by(|a, b| a.time_s().total_cmp(&b.time_s()));
        SimRun {
            name: self.plan.name.clone(),
            start_unix_s: self.plan.start_unix_s,
            origin: self.plan.frame.origin(),
            events,
            truth: self.truth,
            waypoint_passes: self.passes,
        }
    }
}

/// `x` integrated over `span` (elapsed s, from, to) with RK4 in equal steps
/// of at most the plan's step: the shaft speed commands `n_cmd_radps` and
/// the random disturbance held, the losses at each step's midpoint, the
/// plan's current and wind at each stage.
fn integrate_held(
    plan: &Plan,
    model: &OtterModel,
    x: &StateVector,
    (t, t_next): (f64, f64),
    n_cmd_radps: [f64; 2],
    loss_at: impl Fn(f64) -> [f64; 2],
    disturbance_force: [f64; 3],
) -> StateVector {
    let steps = (((t_next - t) / plan.step_s) - 1e-9).ceil().max(1.0);
    let h = (t_next - t) / steps;
    let mut x = *x;
    for k in 0..steps as usize {
        let t0 = t + k as f64 * h;
        let act = Actuation {
            n_cmd_radps,
            loss: loss_at(t0 + 0.5 * h),
        };
        x = rk4_step(
            |ts, xs| {
                let (current, accel) = plan.current.at(ts);
                let wind_force = plan
                    .wind
                    .map_or([0.0; 3], |w| w.force(xs[idx::PSI], xs[idx::U], xs[idx::V]));
                let env = Surroundings {
                    current_ned_mps: current,
                    current_accel_ned_mps2: accel,
                    wind_force,
                    disturbance_force,
                };
                model.derivative(xs, &act, &env)
            },
            t0,
            &x,
            h,
        );
    }
    x
}

/// The plan's vessel driven open loop from the true state of `truth[0]` by
/// the recorded shaft speed `commands` (each held until the next; the
/// trial's `PropellerCommanded` events, at the control rate when the
/// propellers are logged at it) and the losses of `truth`, in the plan's
/// current and wind but with none of its random disturbance: one sample for
/// each later instant of `truth`.
///
/// Run on a trial's own truth from a split onwards, this is what the
/// vessel itself would have done on the same commands had the water ahead
/// been calm: its distance from the truth is what the disturbance to come
/// makes unknowable to any forecast from the commands (docs/accuracy.md,
/// "Prediction after calibration").
pub fn replay_without_disturbance(
    plan: &Plan,
    truth: &[TruthSample],
    commands: &[PropellerSpeeds],
) -> Vec<TruthSample> {
    let Some(first) = truth.first() else {
        return Vec::new();
    };
    let model = OtterModel::new(plan.vessel.clone());
    let mut x = StateVector::from_column_slice(&[
        first.north_m,
        first.east_m,
        first.heading_rad,
        first.u_mps,
        first.v_mps,
        first.r_radps,
        first.shaft_radps[0],
        first.shaft_radps[1],
    ]);
    let elapsed = |c: &PropellerSpeeds| c.time_s - plan.start_unix_s;
    // The command in force: the last one at or before the time reached
    // (`next` is the first not yet in force).
    let mut n_cmd = first.shaft_cmd_radps;
    let mut next = 0;
    let take_until = |t_s: f64, next: &mut usize, n_cmd: &mut [f64; 2]| {
        while let Some(c) = commands.get(*next)
            && elapsed(c) <= t_s + SAME_INSTANT_S
        {
            *n_cmd = [c.port_radps, c.starboard_radps];
            *next += 1;
        }
    };
    let mut out = Vec::with_capacity(truth.len().saturating_sub(1));
    for pair in truth.windows(2) {
        let (from, to) = (&pair[0], &pair[1]);
        // Integrate piecewise between the command changes inside the span.
        let mut t = from.elapsed_s;
        take_until(t, &mut next, &mut n_cmd);
        loop {
            let change = commands
                .get(next)
                .map(elapsed)
                .filter(|c| *c < to.elapsed_s - SAME_INSTANT_S);
            let t_next = change.unwrap_or(to.elapsed_s);
            x = integrate_held(
                plan,
                &model,
                &x,
                (t, t_next),
                n_cmd,
                |_| from.loss,
                [0.0; 3],
            );
            t = t_next;
            if change.is_none() {
                break;
            }
            take_until(t, &mut next, &mut n_cmd);
        }
        let act = Actuation {
            n_cmd_radps: n_cmd,
            loss: from.loss,
        };
        out.push(truth_sample(
            plan,
            &model,
            &x,
            to.elapsed_s,
            &act,
            [0.0; 3],
            None,
        ));
    }
    out
}

fn body_motion(x: &StateVector) -> BodyMotion {
    BodyMotion {
        north_m: x[idx::NORTH],
        east_m: x[idx::EAST],
        psi_rad: x[idx::PSI],
        u_mps: x[idx::U],
        v_mps: x[idx::V],
        r_radps: x[idx::R],
    }
}

fn truth_sample(
    plan: &Plan,
    model: &OtterModel,
    x: &StateVector,
    t_s: f64,
    act: &Actuation,
    disturbance_force: [f64; 3],
    los: Option<&LineOfSight>,
) -> TruthSample {
    let body = body_motion(x);
    let (s, c) = body.psi_rad.sin_cos();
    let vn = c * body.u_mps - s * body.v_mps;
    let ve = s * body.u_mps + c * body.v_mps;
    let (current, _) = plan.current.at(t_s);
    let nu_c = OtterModel::body_current(body.psi_rad, current);
    let shafts = [x[idx::N_PORT], x[idx::N_STB]];
    TruthSample {
        time_s: plan.start_unix_s + t_s,
        elapsed_s: t_s,
        position: plan.frame.to_geodetic(NorthEast {
            north_m: body.north_m,
            east_m: body.east_m,
        }),
        north_m: body.north_m,
        east_m: body.east_m,
        heading_rad: wrap_two_pi(body.psi_rad),
        u_mps: body.u_mps,
        v_mps: body.v_mps,
        r_radps: body.r_radps,
        sog_mps: vn.hypot(ve),
        cog_rad: course_of(vn, ve),
        u_water_mps: body.u_mps - nu_c.x,
        v_water_mps: body.v_mps - nu_c.y,
        shaft_radps: shafts,
        shaft_cmd_radps: act.n_cmd_radps,
        thrust_n: model.effective_thrusts_n(shafts, act.loss),
        loss: act.loss,
        current_ned_mps: current,
        disturbance_force,
        cross_track_m: los.map(|l| l.cross_track_m(body.north_m, body.east_m)),
        leg: los.map(LineOfSight::leg),
    }
}
