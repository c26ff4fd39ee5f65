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

pub use kinetic::{KineticBase, KineticConfig, KineticOptions, ShaftAccumulator, Term};
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
    /// Antenna position in the local frame.
    pub position: NorthEast,
    /// Speed over ground, m/s.
    pub sog_mps: Option<f64>,
    /// Course over ground, rad (not yet gated by speed: see [`CourseGate`]).
    pub cog_rad: Option<f64>,
    /// Heading, rad.
    pub heading_rad: Option<f64>,
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
            sog_mps: fix.sog_mps,
            cog_rad: fix.cog_rad.map(wrap_pi),
            heading_rad: fix.heading_rad.map(wrap_pi),
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
}

/// A fault prior restored from a calibration: the estimate and its
/// covariance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FaultPrior<const P: usize> {
    /// The fault estimate.
    pub theta: nalgebra::SVector<f64, P>,
    /// Its covariance.
    pub covariance: nalgebra::SMatrix<f64, P, P>,
}
