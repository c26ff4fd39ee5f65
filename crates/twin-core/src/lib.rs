//! `twin-core`: the pure estimator of the USV digital twin.
//!
//! # Layout
//! - [`geodesy`]: WGS-84 to the local flat-earth frame, angle wrapping.
//! - [`sample`]: the measurement types the twin consumes (SI units).
//! - [`model`]: the [`model::Model`] trait every vessel model implements.
//! - [`models`]: the seed's kinematic model and the extended kinetic twins.
//! - [`inputs`]: the seed's inputs derived from GNSS (differences, low-pass).
//! - [`vessel`]: a vessel's parameters (the Otter by default) and the seed's thrust split (step 4).
//! - [`linalg`]: small Cholesky factorisation and solves for the filter.
//! - [`simd`]: which vector width this processor runs the filter's step at.
//! - [`trig`]: the sine and cosine of a heading, inlined (the models' hot path).
//! - [`aekf`]: the adaptive extended Kalman filter, generic over the model.
//! - [`estimator`]: the estimator bases (prior, measurement from a fix,
//!   input, step), one type per base model, shared by the live twin,
//!   `diagnose` and the benchmarks.
//! - [`predict`]: open-loop forecasts with their uncertainty.
//! - [`decision`]: nominal / suspect / fault per thruster, with hysteresis.
//! - [`diagnose`]: what the model gets wrong on a log, the cause, the gain.
//! - [`twin`]: one vessel's twin, fed measurement by measurement (what the
//!   daemon and `twin analyze` both run).
//!
//! # Invariants
//! This crate does no I/O, reads no clock and has no async code: time comes in
//! with every measurement, and every result is a value. It depends on neither
//! tokio, zenoh nor serde.

pub mod aekf;
pub mod decision;
pub mod diagnose;
pub mod estimator;
pub mod geodesy;
pub mod inputs;
mod linalg;
pub mod model;
pub mod models;
pub mod predict;
pub mod sample;
mod simd;
mod trig;
pub mod twin;
pub mod vessel;

pub use simd::avx2_available;
