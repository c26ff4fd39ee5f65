//! `twin-core`: the pure estimator of the USV digital twin.
//!
//! # Layout
//! - [`geodesy`]: WGS-84 to the local flat-earth frame, angle wrapping.
//! - [`sample`]: the measurement types the twin consumes (SI units).
//!
//! # Invariants
//! This crate does no I/O, reads no clock and has no async code: time comes in
//! with every measurement, and every result is a value. It depends on neither
//! tokio, zenoh nor serde.

pub mod geodesy;
pub mod sample;
