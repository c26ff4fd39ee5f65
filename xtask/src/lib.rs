//! `xtask`: the repository's own tooling, run as `cargo xtask ...` (alias in
//! `.cargo/config.toml`). It makes the tables of the documentation and
//! regenerates them in place; nothing here ships in a product binary.
//!
//! # Layout
//! - [`trials`]: the seed's sea-trial matrix re-run in the simulator with
//!   known truth, the seed's method beside the extended twin, and the
//!   prediction comparison of the seed's Table 4.9 (`cargo xtask trials`,
//!   `cargo xtask prediction`). Its tests (`tests/trial_matrix.rs`,
//!   `tests/prediction_table.rs`, `tests/seed_flaw.rs`) hold the estimator
//!   to the project's accuracy targets.
//! - [`real_logs`]: `twin analyze` over the real logs, one table
//!   (`cargo xtask real-logs`).
//! - [`diagnose_real`]: `twin diagnose` over the real logs, with the
//!   instrument's own current where a log has one
//!   (`cargo xtask diagnose-real`).
//! - [`generated`]: every generated block of the docs, the command that
//!   makes it, and its regeneration (`cargo xtask docs`).
//! - [`SCHEMA_DIR`]: where `cargo xtask schemas` writes the payloads' JSON
//!   Schemas (`twin_wire::schema`); `twin-wire`'s `tests/schemas.rs` fails
//!   when a committed file differs from the generated one.

pub mod diagnose_real;
pub mod generated;
pub mod real_logs;
pub mod trials;

/// The payloads' JSON Schemas, relative to the repository root.
pub const SCHEMA_DIR: &str = "docs/schemas";
