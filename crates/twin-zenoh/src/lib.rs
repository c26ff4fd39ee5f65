//! `twin-zenoh`: what every binary of the USV twin that opens a Zenoh
//! session shares, so that `twind`, `twin-replay` and any later tool take
//! the same flags and mean the same by them.
//!
//! # Layout
//! - [`cli`]: Zenoh's usual command-line flags (`--config`, `--mode`,
//!   `--connect`, `--listen`, `--no-multicast-scouting`) as [`ZenohArgs`],
//!   and their translation into a [`zenoh::Config`].
//! - [`limit`]: when to log a refusal (each reason first, then once a
//!   minute with the count since), shared by the binaries that take
//!   network input.
//! - [`process`]: logging set up the same way, and the `--prefix` parser.

pub mod cli;
pub mod limit;
pub mod process;

pub use cli::{Mode, ZenohArgs, ZenohConfigError};
