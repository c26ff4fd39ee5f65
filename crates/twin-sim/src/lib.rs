//! `twin-sim`: the Otter simulator, the truth the twin is held against.
//!
//! It simulates the Maritime Robotics Otter USV in surge, sway and yaw with
//! its propeller dynamics, a water current and wind, random disturbances from
//! waves and gusts, the way-point autopilot of the seed's sea trials, and the
//! sensors the twin listens to (GNSS, heading, propeller speeds), all
//! deterministic for a seed.
//!
//! ```no_run
//! let text = std::fs::read_to_string("config/scenarios/s-manoeuvre_new-broken.toml").unwrap();
//! let scenario = twin_sim::Scenario::from_toml_str(&text).unwrap();
//! let run = twin_sim::simulate(&scenario).unwrap();
//! for fix in run.gnss_fixes() {
//!     println!("{} {:?}", fix.time_s, fix.position);
//! }
//! ```
//!
//! # Layout
//! - [`scenario`]: the TOML scenario a user edits, and its validation.
//! - [`sim`]: the simulation loop, [`simulate`], and its output [`SimRun`].
//! - [`otter`]: the Otter's equations of motion and parameters.
//! - [`environment`]: current and wind.
//! - [`disturbance`]: the random force and moment of waves and gusts, and
//!   (through [`DisturbanceSpec::acceleration_density`]) the process noise
//!   it amounts to for an estimator.
//! - [`guidance`]: line-of-sight guidance through way-points.
//! - [`control`]: heading and speed autopilot, thrust allocation.
//! - [`sensors`]: GNSS, heading and propeller sensors with seeded noise.
//!
//! # Invariants
//! - No dynamics code is shared with the estimator: from `twin-core` this
//!   crate uses only geodesy and the plain sample types.
//! - The same scenario (including its seed) gives bit-identical output.
//! - Every random stream (each sensor's noise, the disturbance) is its own
//!   stream of the seed: switching one on or off leaves the others as they
//!   were.
//! - Every sample is taken at its exact instant; the integration step only
//!   sets the accuracy of the trajectory between instants.
//! - Inside, everything is SI (m, s, rad, N); degrees and rpm exist only in
//!   the scenario file.

pub mod control;
pub mod disturbance;
pub mod environment;
pub mod guidance;
pub mod otter;
pub mod scenario;
pub mod sensors;
pub mod sim;

pub use guidance::WaypointPass;
pub use otter::{OtterParams, VesselScales, hoerner_cd_2d};
pub use scenario::{
    ControlSpec, CurrentSpec, DisturbanceSpec, GnssSpec, HeadingSpec, InitialSpec, LeverArm,
    ManualCommand, ManualSpec, Origin, PathSpec, Plan, PropellerSensorSpec, PropellerSpec,
    PropellersSpec, Scenario, ScenarioError, SensorsSpec, VesselSpec, Waypoint, WindSpec,
    YawRateSpec,
};
pub use sensors::{HeadingSample, SensorEvent, YawRateSample, radps_to_rpm};
pub use sim::{SimRun, TruthSample, replay_without_disturbance, run_plan, simulate};
