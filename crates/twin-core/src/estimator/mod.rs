//! The estimator bases: one type per base model, owning everything between
//! a measurement and the adaptive filter, so that the live twin
//! ([`crate::twin::VesselTwin`]), `diagnose` and the benchmarks run the same
//! code for the same data.
//!
//! Each base owns
//! - its **prior** from a first fix (state, covariance, faults);
//! - its **measurement** from a fix: which components are available, the
//!   course masked below the speed at which it means something
//!   ([`CourseGate`], from the twin's gating settings);
//! - its **input** from the samples accumulated since the previous fix;
//! - its **step** through [`crate::aekf::Aekf`].
//!
//! The bases:
//! - [`SeedBase`]: the seed's kinematic model, its inputs derived from GNSS
//!   (docs/model.md section 3);
//! - [`KineticBase`]: the Otter's kinetic twin driven by the measured shaft
//!   speeds, with per-propeller losses, the water current and optional
//!   sensor effects (docs/model.md section 5);
//! - [`WaterBase`]: a kinematic vessel through water, for logs without
//!   propeller data (`diagnose` only).

mod kinetic;
pub(crate) mod seed;
mod water;

pub use kinetic::{
    KineticBase, KineticConfig, KineticFilter, KineticOptions, KineticReport, KineticState,
    LossReading, ShaftAccumulator, Term,
};
pub use seed::{SeedBase, SeedConfig, SeedInputs};
pub use water::{WaterBase, WaterOptions};

use crate::geodesy::{LocalFrame, NorthEast, wrap_pi};
use crate::sample::GnssFix;

/// One fix in the local frame, with everything measured at it: what every
/// base builds its measurement from. Angles are wrapped to [-pi, pi).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalFix {
    /// Time, s.
    pub time_s: f64,
    /// Antenna position in the local frame (the frame's origin when not
    /// measured).
    pub position: NorthEast,
    /// Whether the position was measured: false on a log without positions,
    /// whose velocities alone are diagnosed.
    pub position_measured: bool,
    /// Speed over ground, m/s.
    pub sog_mps: Option<f64>,
    /// Course over ground, rad (not yet gated by speed: see [`CourseGate`]).
    pub cog_rad: Option<f64>,
    /// Heading, rad.
    pub heading_rad: Option<f64>,
    /// Yaw rate from a rate gyro, rad/s.
    pub yaw_rate_radps: Option<f64>,
    /// Speed through water, m/s.
    pub stw_mps: Option<f64>,
}

impl LocalFix {
    /// A GNSS fix in `frame` (no speed through water).
    pub fn from_gnss(fix: &GnssFix, frame: &LocalFrame) -> Self {
        Self::at(fix, frame.to_local(fix.position))
    }

    /// A GNSS fix whose position in the local frame is `position`.
    pub fn at(fix: &GnssFix, position: NorthEast) -> Self {
        Self {
            time_s: fix.time_s,
            position,
            position_measured: true,
            sog_mps: fix.sog_mps,
            cog_rad: fix.cog_rad.map(wrap_pi),
            heading_rad: fix.heading_rad.map(wrap_pi),
            yaw_rate_radps: fix.yaw_rate_radps,
            stw_mps: None,
        }
    }
}

/// Below a speed over ground the reported course is noise: the bases mask it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CourseGate {
    /// Slowest speed over ground at which the course is used, m/s.
    pub min_sog_mps: f64,
}

impl CourseGate {
    /// Whether `fix`'s course is measured and meaningful.
    pub fn course_available(&self, fix: &LocalFix) -> bool {
        fix.cog_rad.is_some() && fix.sog_mps.is_some_and(|s| s >= self.min_sog_mps)
    }

    /// `[north, east, sog, cog, heading, extra]` from `fix`: each where
    /// measured, the course only above the gate's
    /// speed; `extra` is the base's own sixth measurement (the yaw rate,
    /// the speed through water), where the fix has it.
    pub fn measurement(&self, fix: &LocalFix, extra: Option<f64>) -> crate::model::Measurement<6> {
        crate::model::Measurement {
            values: nalgebra::SVector::<f64, 6>::from([
                fix.position.north_m,
                fix.position.east_m,
                fix.sog_mps.unwrap_or(0.0),
                fix.cog_rad.unwrap_or(0.0),
                fix.heading_rad.unwrap_or(0.0),
                extra.unwrap_or(0.0),
            ]),
            available: [
                fix.position_measured,
                fix.position_measured,
                fix.sog_mps.is_some(),
                self.course_available(fix),
                fix.heading_rad.is_some(),
                extra.is_some(),
            ],
        }
    }
}

/// What an estimator learnt about a vessel, to start a new estimate from:
/// the faults with their covariance and anti-windup memory, and for the
/// extended twin the surroundings it had estimated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Learnt<const P: usize> {
    /// The fault estimate.
    pub theta: nalgebra::SVector<f64, P>,
    /// Its covariance.
    pub covariance: nalgebra::SMatrix<f64, P, P>,
    /// The information held per fault (the anti-windup memory).
    pub held_information: nalgebra::SVector<f64, P>,
    /// The water current, the heading sensor's offset and the rate sensor's
    /// bias.
    pub surroundings: Option<Surroundings>,
}

/// What the extended twin learnt of the water and of its heading and rate
/// sensors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Surroundings {
    /// Water current `[north, east]`, m/s.
    pub current_mps: [f64; 2],
    /// Heading sensor minus true heading, rad.
    pub heading_bias_rad: f64,
    /// Covariance of `[current north, current east, heading bias]`.
    pub covariance: [[f64; 3]; 3],
    /// The rate sensor's bias, where the twin estimated it (`None` where it
    /// was held, or in a calibration saved before it was kept).
    pub yaw_rate_bias: Option<RateSensorBias>,
}

/// A rate sensor's bias as the extended twin learnt it: what it reads when
/// the vessel does not turn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RateSensorBias {
    /// The bias, rad/s.
    pub radps: f64,
    /// Its variance, (rad/s)^2 (its covariance with the other surroundings
    /// is not kept).
    pub variance: f64,
}
