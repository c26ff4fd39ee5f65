//! ROS 2 messages of the twin, in CDR, for rmw_zenoh: a ROS 2 node on
//! rmw_zenoh subscribes to the twin's fault, state and prediction, and
//! publishes GNSS input to it, with no bridge between them. Pure: no Zenoh
//! calls here (the daemon's `twind::ros2` makes them).
//!
//! - [`cdr`]: the little-endian CDR writer and reader.
//! - [`msgs`]: the standard message types used, their CDR and type hashes.
//! - [`rmw`]: rmw_zenoh's keys, liveliness tokens and attachment.
//! - [`map`]: the twin's outputs as ROS 2 messages (frames, units,
//!   unknowns; see its doc).
//! - [`input`]: `sensor_msgs/NavSatFix` with velocity, heading and an
//!   IMU's yaw rate as the contract's GNSS fix.

pub mod cdr;
pub mod input;
pub mod map;
pub mod msgs;
pub mod rmw;
