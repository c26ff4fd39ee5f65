//! `twin-bench`: side-by-side performance measurements of the USV twin, as
//! the project's speed targets ask for them (docs/performance.md) (medians on a shared 2-core
//! machine, printed beside its load average; never asserted in tests).
//!
//! # Layout
//! - [`rng`]: a small seeded generator, so trials are the same bit for bit.
//! - [`trial`]: the seed model's benchmark trial: generated, written as JSON,
//!   run and timed through `twin_core`'s adaptive EKF.
//! - [`numpy`]: the NumPy reference (`bench/numpy_aekf.py`): running it,
//!   reading its result, comparing estimates step by step.
//! - [`estimator`]: the `numpy` subcommand: both sides, the table.
//! - [`workloads`]: what `core` and the criterion benches time: simulated
//!   trials, the extended twin's recorded filter steps, the logs.
//! - [`core`]: the `core` subcommand: estimator and offline path, one table
//!   with the targets.
//! - [`daemon`]: the `daemon` subcommand: twind under load against raw
//!   Zenoh on loopback (throughput, latency, CPU, RSS, scaling, maximum
//!   sustained rate), one table with the targets; `daemon::cold_start`,
//!   the `cold-start` subcommand: a whole fleet starting at once.
//! - [`soak`]: the `soak` subcommand: a fleet through the daemon for a day
//!   of vessel time (memory, counts, drift, covariances).
//! - [`machine`]: load average, cores, processor.
//!
//! The binary (`src/main.rs`) only parses the command line and calls these.

pub mod core;
pub mod daemon;
pub mod estimator;
pub mod machine;
pub mod numpy;
pub mod rng;
pub mod soak;
pub mod trial;
pub mod workloads;
