//! GNSS input from ROS 2: what a ROS 2 GNSS driver publishes (as
//! `nmea_navsat_driver` does) turned into the contract's GNSS fix.
//!
//! Three topics under `{namespace}/{vessel}/`:
//! - `fix`: `sensor_msgs/NavSatFix`, the position; each one makes a fix.
//! - `vel`: `geometry_msgs/TwistStamped`, the velocity over ground in ENU
//!   (linear x east, y north, m/s); required: a fix whose latest velocity
//!   is more than [`NavSatInput::max_gap_s`] away in time is refused.
//! - `heading`: `geometry_msgs/QuaternionStamped`, the orientation as an
//!   ENU yaw (REP 103: counter-clockwise from east; a driver that puts the
//!   compass heading in the yaw must be converted first); optional, used
//!   when within [`NavSatInput::max_gap_s`] of the fix.
//!
//! The fix's time is its header stamp (to the microsecond, the contract's
//! resolution); speed and course come from the velocity, the heading from
//! the yaw. The result is a [`GnssMessage`] that has passed the JSON
//! path's own validation ([`GnssMessage::to_fix`]), so the daemon hands it
//! to the same path as a fix on `{prefix}/{vessel}/gnss`. `hdop` and the
//! yaw rate are not taken (a NavSatFix has a covariance, not an HDOP).

use twin_core::geodesy::wrap_two_pi;

use super::cdr::CdrError;
use super::map::{heading_of_enu_yaw, seconds_of_stamp, yaw_of};
use super::msgs::{NavSatFix, QuaternionStamped, RosMessage, TwistStamped};
use crate::messages::{GnssMessage, MessageError, TimeSource};
use crate::time::format_rfc3339;

/// The topics read, under `{namespace}/{vessel}/`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum GnssTopic {
    /// `fix`: `sensor_msgs/NavSatFix`.
    Fix,
    /// `vel`: `geometry_msgs/TwistStamped`.
    Vel,
    /// `heading`: `geometry_msgs/QuaternionStamped`.
    Heading,
}

impl GnssTopic {
    /// Every topic.
    pub const ALL: [GnssTopic; 3] = [GnssTopic::Fix, GnssTopic::Vel, GnssTopic::Heading];

    /// The topic's last name.
    pub fn name(self) -> &'static str {
        match self {
            GnssTopic::Fix => "fix",
            GnssTopic::Vel => "vel",
            GnssTopic::Heading => "heading",
        }
    }

    /// `package/msg/Name` of its type.
    pub fn type_name(self) -> &'static str {
        match self {
            GnssTopic::Fix => NavSatFix::TYPE_NAME,
            GnssTopic::Vel => TwistStamped::TYPE_NAME,
            GnssTopic::Heading => QuaternionStamped::TYPE_NAME,
        }
    }

    /// Its RIHS01 type hash.
    pub fn type_hash(self) -> &'static str {
        match self {
            GnssTopic::Fix => NavSatFix::TYPE_HASH,
            GnssTopic::Vel => TwistStamped::TYPE_HASH,
            GnssTopic::Heading => QuaternionStamped::TYPE_HASH,
        }
    }
}

/// Why a ROS 2 GNSS message makes no fix.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum InputError {
    /// The payload is not the topic's message in CDR.
    #[error("bad CDR: {0}")]
    Cdr(#[from] CdrError),
    /// The fix's status says there is no fix (`status` -1).
    #[error("the receiver reports no fix")]
    NoFix,
    /// No velocity within the allowed gap of the fix.
    #[error("no velocity within {max_gap_s} s of the fix")]
    NoVelocity {
        /// The gap allowed, s.
        max_gap_s: f64,
    },
    /// The assembled fix fails the contract's validation.
    #[error("{0}")]
    Invalid(#[from] MessageError),
}

impl InputError {
    /// A short, stable name of the reason, for counting.
    pub fn reason(&self) -> &'static str {
        match self {
            InputError::Cdr(_) => "ros2_bad_cdr",
            InputError::NoFix => "ros2_no_fix",
            InputError::NoVelocity { .. } => "ros2_no_velocity",
            InputError::Invalid(e) => e.reason(),
        }
    }
}

/// One vessel's latest velocity and heading, waiting for a fix.
#[derive(Debug, Clone, Default)]
pub struct NavSatInput {
    /// How far apart in time a velocity or heading may be from the fix, s.
    pub max_gap_s: f64,
    velocity: Option<(f64, f64, f64)>,
    heading: Option<(f64, f64)>,
}

impl NavSatInput {
    /// An empty input allowing `max_gap_s` between a fix and the velocity
    /// and heading it takes.
    pub fn new(max_gap_s: f64) -> Self {
        Self {
            max_gap_s,
            ..Self::default()
        }
    }

    /// Takes one payload of `topic`; `Ok(Some(..))` when it completes a fix.
    pub fn push(
        &mut self,
        topic: GnssTopic,
        payload: &[u8],
    ) -> Result<Option<GnssMessage>, InputError> {
        match topic {
            GnssTopic::Vel => {
                let v = TwistStamped::from_cdr(payload)?;
                let t = seconds_of_stamp(v.header.stamp);
                self.velocity = Some((t, v.twist.linear.x, v.twist.linear.y));
                Ok(None)
            }
            GnssTopic::Heading => {
                let h = QuaternionStamped::from_cdr(payload)?;
                let t = seconds_of_stamp(h.header.stamp);
                self.heading = Some((t, heading_of_enu_yaw(yaw_of(&h.quaternion))));
                Ok(None)
            }
            GnssTopic::Fix => self.fix(&NavSatFix::from_cdr(payload)?).map(Some),
        }
    }

    /// The contract's fix made of `fix` and the velocity and heading held.
    pub fn fix(&self, fix: &NavSatFix) -> Result<GnssMessage, InputError> {
        if fix.status.status < 0 {
            return Err(InputError::NoFix);
        }
        let time_s = seconds_of_stamp(fix.header.stamp);
        let near = |t: f64| (t - time_s).abs() <= self.max_gap_s;
        let (east_mps, north_mps) = match self.velocity {
            Some((t, east, north)) if near(t) => (east, north),
            _ => {
                return Err(InputError::NoVelocity {
                    max_gap_s: self.max_gap_s,
                });
            }
        };
        let message = GnssMessage {
            time: format_rfc3339(time_s).map_err(MessageError::from)?,
            lat_deg: fix.latitude,
            lon_deg: fix.longitude,
            sog_mps: east_mps.hypot(north_mps),
            cog_rad: wrap_two_pi(east_mps.atan2(north_mps)),
            heading_rad: self.heading.filter(|(t, _)| near(*t)).map(|(_, h)| h),
            yaw_rate_radps: None,
            hdop: None,
            replay: false,
            time_source: TimeSource::Source,
        };
        message.to_fix()?;
        Ok(message)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ros2::map::{enu_yaw, stamp_of_seconds, yaw_quaternion};
    use crate::ros2::msgs::{Header, Point, Twist};

    fn vel(t: f64, east: f64, north: f64) -> Vec<u8> {
        TwistStamped {
            header: Header {
                stamp: stamp_of_seconds(t),
                frame_id: "gps".into(),
            },
            twist: Twist {
                linear: Point {
                    x: east,
                    y: north,
                    z: 0.0,
                },
                angular: Point::default(),
            },
        }
        .to_cdr()
    }

    fn fix(t: f64, lat: f64) -> Vec<u8> {
        NavSatFix {
            header: Header {
                stamp: stamp_of_seconds(t),
                frame_id: "gps".into(),
            },
            latitude: lat,
            longitude: 10.7,
            ..NavSatFix::default()
        }
        .to_cdr()
    }

    #[test]
    fn a_fix_takes_the_velocity_and_heading_near_it() {
        let mut input = NavSatInput::new(0.5);
        let t = 1_714_564_800.25;
        assert_eq!(input.push(GnssTopic::Vel, &vel(t, 1.0, 1.0)).unwrap(), None);
        let heading = QuaternionStamped {
            header: Header {
                stamp: stamp_of_seconds(t),
                frame_id: String::new(),
            },
            quaternion: yaw_quaternion(enu_yaw(0.7)),
        };
        input.push(GnssTopic::Heading, &heading.to_cdr()).unwrap();
        let m = input.push(GnssTopic::Fix, &fix(t, 59.9)).unwrap().unwrap();
        assert_eq!(m.time, "2024-05-01T12:00:00.250Z");
        assert_eq!(m.lat_deg, 59.9);
        assert!((m.sog_mps - 2f64.sqrt()).abs() < 1e-12);
        assert!((m.cog_rad - std::f64::consts::FRAC_PI_4).abs() < 1e-12);
        assert!((m.heading_rad.unwrap() - 0.7).abs() < 1e-12);
        // Two seconds on, the velocity and heading are too old.
        assert_eq!(
            input.push(GnssTopic::Fix, &fix(t + 2.0, 59.9)).unwrap_err(),
            InputError::NoVelocity { max_gap_s: 0.5 }
        );
    }

    #[test]
    fn bad_fixes_are_refused_with_a_reason() {
        let mut input = NavSatInput::new(0.5);
        let t = 1_714_564_800.0;
        input.push(GnssTopic::Vel, &vel(t, 0.0, 1.0)).unwrap();
        let e = input.push(GnssTopic::Fix, &fix(t, 123.0)).unwrap_err();
        assert_eq!(e.reason(), "out_of_range");
        let e = input.push(GnssTopic::Fix, &fix(t, f64::NAN)).unwrap_err();
        assert_eq!(e.reason(), "non_finite");
        let e = input
            .push(GnssTopic::Fix, b"\x00\x01\x00\x00garbage")
            .unwrap_err();
        assert_eq!(e.reason(), "ros2_bad_cdr");
        let e = input.push(GnssTopic::Vel, &[]).unwrap_err();
        assert_eq!(e.reason(), "ros2_bad_cdr");
    }
}
