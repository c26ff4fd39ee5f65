//! Log and sentence writers: NMEA 0183 sentences (RMC, GGA, VTG, HDT, RPM,
//! ZDA) for the simulator, the project's JSON lines for the replay tool,
//! NMEA 2000 in the raw gateway layouts and MAVLink frames and `.tlog`
//! records for tests and benchmarks.
//!
//! Everything written reads back through [`crate::read`] to the same values
//! within the written precision (tests check the round trip).

pub mod jsonl;
pub mod mavlink;
pub mod n2k_raw;
pub mod nmea0183;

pub use jsonl::JsonlWriter;
pub use nmea0183::NmeaWriter;

use crate::messages::MessageError;
use crate::time::TimeError;

/// Why a value cannot be written.
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    /// A number is NaN or infinite.
    #[error("{field} is not finite")]
    NotFinite {
        /// The field.
        field: &'static str,
    },
    /// A number is outside what the sentence can carry (|lat| > 90, negative
    /// speed, more than 20 000 rpm...).
    #[error("{field} out of range")]
    OutOfRange {
        /// The field.
        field: &'static str,
    },
    /// The time cannot be written (not finite, outside years 0-9999).
    #[error("bad time: {0}")]
    Time(#[from] TimeError),
    /// The JSON message would not be valid.
    #[error("invalid message: {0}")]
    Message(#[from] MessageError),
    /// Writing to the output failed.
    #[error("write failed: {0}")]
    Io(#[from] std::io::Error),
}
