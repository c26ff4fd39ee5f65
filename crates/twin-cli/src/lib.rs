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
//! - [`real_logs`]: `twin report real-logs`: analyze over the real logs, as a
//!   markdown table.
//! - [`diagnose_real`]: `twin report diagnose-real`: diagnose over the real
//!   logs, as markdown, with the instrument's own current where there is one.
//! - [`demo`]: the bundled demo trial (`data/demo/`) and how it is made.
//! - [`trials`]: the seed's sea-trial matrix re-run in the simulator with
//!   known truth: the seed's method beside the extended twin
//!   (`twin report trials`).

pub mod analyze;
pub mod demo;
pub mod diagnose;
pub mod diagnose_real;
pub mod plots;
pub mod quality;
pub mod real_logs;
pub mod simulate;
pub mod svg;
pub mod trials;
pub mod truth;
