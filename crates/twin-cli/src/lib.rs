//! `twin-cli`: the library behind the `twin` command. `main.rs` only parses
//! the command line and calls these modules.
//!
//! # Layout
//! - [`simulate`]: `twin simulate`: a scenario through the Otter simulator to
//!   an NMEA 0183 or JSON-lines log (and a truth file, [`truth`]).
//! - [`analyze`]: `twin analyze`: a log through the reader, the assembler and
//!   the vessel twin, streaming; the human summary and the JSON report
//!   (schema in the module doc), with [`quality`] (innovations, NIS) and
//!   [`plots`] (SVG figures drawn with [`svg`]).
//! - [`diagnose`]: `twin diagnose`: what the model gets wrong on a log, the
//!   cause, the gain on held-out data (text, JSON, SVG).
//! - [`demo`]: the bundled demo trial (`data/demo/`) and how it is made.
//!
//! The tables of the documentation (the sea-trial matrix, the real logs)
//! are made by `cargo xtask`, which uses this library; the `twin` binary
//! carries only what its users run.

pub mod analyze;
pub mod demo;
pub mod diagnose;
pub mod identify;
pub mod plots;
pub mod quality;
pub mod simulate;
pub mod svg;
pub mod truth;
