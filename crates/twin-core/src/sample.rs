//! The measurements the twin consumes, in SI units, as plain values.
//!
//! These are the estimator's own input types. Wire formats (JSON payloads,
//! NMEA 0183, NMEA 2000) are converted into them by `twin-wire`; nothing here
//! knows about serde or text.

use crate::geodesy::LatLon;

/// One GNSS fix: position, and where the receiver gives them, speed and course
/// over ground, heading (from a dual-antenna receiver or a compass), the yaw
/// rate (from a rate gyro) and HDOP.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GnssFix {
    /// Time of the fix, seconds since the Unix epoch (UTC), from the message.
    pub time_s: f64,
    /// Antenna position.
    pub position: LatLon,
    /// Speed over ground, m/s.
    pub sog_mps: Option<f64>,
    /// Course over ground, radians clockwise from true north.
    pub cog_rad: Option<f64>,
    /// True heading of the bow, radians clockwise from true north.
    pub heading_rad: Option<f64>,
    /// Yaw rate from a rate gyro or rate-of-turn sensor joined to the fix,
    /// rad/s, positive turning the bow to starboard.
    pub yaw_rate_radps: Option<f64>,
    /// Horizontal dilution of precision, if the receiver reports it.
    pub hdop: Option<f64>,
}

/// Which propeller of a twin-propeller vessel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Side {
    /// Left, looking forward (y = -b in the body frame).
    Port,
    /// Right, looking forward (y = +b in the body frame).
    Starboard,
}

impl Side {
    /// Both sides, port first (the order of every two-vector in the crate).
    pub const BOTH: [Side; 2] = [Side::Port, Side::Starboard];

    /// Index in two-vectors: port 0, starboard 1.
    pub fn index(self) -> usize {
        match self {
            Side::Port => 0,
            Side::Starboard => 1,
        }
    }

    /// Lower-case name, as used in payloads: `port` or `starboard`.
    pub fn name(self) -> &'static str {
        match self {
            Side::Port => "port",
            Side::Starboard => "starboard",
        }
    }
}

/// Propeller shaft speeds of both propellers at one time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PropellerSpeeds {
    /// Time, seconds since the Unix epoch (UTC), from the message.
    pub time_s: f64,
    /// Port shaft speed, rad/s (positive ahead).
    pub port_radps: f64,
    /// Starboard shaft speed, rad/s (positive ahead).
    pub starboard_radps: f64,
}

/// Revolutions per minute to radians per second.
pub const RADPS_PER_RPM: f64 = std::f64::consts::TAU / 60.0;
