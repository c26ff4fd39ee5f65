//! `twin-cli`: the library behind the `twin` command.
//!
//! # Layout
//! - [`trials`]: the seed's sea-trial matrix re-run in the simulator with
//!   known truth: the seed's method beside the extended twin.

pub mod trials;
