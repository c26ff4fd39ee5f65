//! `twin-bench`: side-by-side performance measurements of the USV twin, as
//! PRODUCT.md's "Speed" section asks for them (medians on a shared 2-core
//! machine, printed beside its load average; never asserted in tests).
//!
//! # Layout
//! - [`rng`]: a small seeded generator, so trials are the same bit for bit.
//! - [`trial`]: the seed model's benchmark trial: generated, written as JSON,
//!   run and timed through `twin_core`'s adaptive EKF.
//! - [`numpy`]: the NumPy reference (`bench/numpy_aekf.py`): running it,
//!   reading its result, comparing estimates step by step.
//! - [`estimator`]: the `numpy` subcommand: both sides, the table.
//! - [`machine`]: load average and cores.
//!
//! The binary (`src/main.rs`) only parses the command line and calls these.

pub mod estimator;
pub mod machine;
pub mod numpy;
pub mod rng;
pub mod trial;
