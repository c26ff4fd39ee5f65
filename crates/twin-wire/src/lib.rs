//! `twin-wire`: the contract of the USV twin (messages, keys) and the log
//! formats it reads and writes.
//!
//! # Layout
//! - [`keys`]: vessel ids, topics, key expressions under a prefix, parsing a
//!   received key.
//! - [`time`]: RFC 3339 and NMEA date/time fields to and from epoch seconds.
//! - [`messages`]: the JSON input payloads (GNSS fix, actuators), their
//!   validation into `twin_core` samples, and their encoders.
//! - [`profile`]: vessel profiles (TOML): validation, and the estimator's
//!   parameters from them.
//! - [`outputs`]: the twin's output payloads (state, fault, prediction,
//!   alarm, stats).
//! - [`schema`]: the JSON Schemas of every payload, from the types.
//! - [`measurement`]: [`Record`], the typed, time-stamped SI measurement
//!   every log reader emits.
//! - [`read`]: streaming readers of NMEA 0183, canboat NMEA 2000 text and
//!   JSON lines, picked by content, with typed rejections and counts.
//! - [`mod@assemble`]: records to the estimator's inputs (fixes with course,
//!   speed and heading; paired propeller speeds), choosing sources.
//! - [`mod@write`]: NMEA 0183 sentence writers and the JSON-lines writer.
//! - [`ros2`]: the outputs and the GNSS input as ROS 2 messages in CDR, and
//!   rmw_zenoh's keys, liveliness tokens and attachment.
//! - [`mod@mcap`]: MCAP recordings of inputs and outputs (JSON channels with
//!   JSON Schemas, a Foxglove location), and their inputs read back.
//!
//! # Invariants
//! No parser panics on any input: every refusal is a typed value. Readers
//! stream in constant memory (one line and its few records at a time). All
//! numbers that leave this crate are SI (m, m/s, rad, rad/s, N) or degrees
//! of latitude/longitude, with the unit in the name. Data flows wire -> core
//! -> wire: `twin-core` never sees a serde type.

pub mod assemble;
pub mod keys;
pub mod mcap;
pub mod measurement;
pub mod messages;
pub mod outputs;
pub mod profile;
pub mod read;
pub mod ros2;
pub mod schema;
pub mod time;
pub mod write;

pub use assemble::{Assembled, AssemblerConfig, FixAssembler, SourceChoice, assemble};
pub use keys::{KeyError, KeySpace, Topic, VesselId};
pub use measurement::{Measurement, MeasurementKind, Record, Source};
pub use messages::{ActuatorCommand, MessageError, decode_actuators, decode_gnss};
pub use read::{LogFormat, LogReader, ReadOptions, ReadStats, RejectKind, RejectReason, Rejection};
