//! `twin-replay`: publishes recorded logs over Zenoh as the contract's input
//! messages, so the daemon (and anything else that subscribes) sees a sea
//! trial as if the vessel were on the water.
//!
//! # Layout
//! - [`replay`]: [`ReplayOptions`], [`replay_log`] (a file) and
//!   [`replay_reader`] (any `BufRead` factory: bundled or generated data),
//!   [`run`] (open a session, replay, close it), the [`Progress`] reports and
//!   the final [`ReplaySummary`].
//!
//! The binary (`src/main.rs`) only parses its arguments, sets up tracing and
//! calls [`run`].
//!
//! # Invariants
//! - What is published is exactly what `twin_wire`'s `LogReader` and
//!   `FixAssembler` make of the log, in their order, encoded with
//!   `twin_wire::messages::{encode_gnss, encode_actuators}` with the original
//!   time stamps and `replay: true`. Nothing else: no resampling, no
//!   interpolation, no time shifting.
//! - The log is streamed: memory does not grow with its length.
//! - Publishers are reliable (Zenoh's default) with `CongestionControl::Block`:
//!   a slow receiver slows the replay down, it never loses messages.

pub mod replay;

pub use replay::{
    Progress, Published, Rate, RateError, ReplayError, ReplayOptions, ReplaySummary, Skipped,
    replay_log, replay_reader, run,
};
