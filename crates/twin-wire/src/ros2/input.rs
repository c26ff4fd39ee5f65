//! GNSS input from ROS 2: what a ROS 2 GNSS driver publishes (as
//! `nmea_navsat_driver` does) turned into the contract's GNSS fix.
//!
//! Four topics under `{namespace}/{vessel}/`:
//! - `fix`: `sensor_msgs/NavSatFix`, the position; each one makes a fix.
//! - `vel`: `geometry_msgs/TwistStamped`, the velocity over ground in ENU
//!   (linear x east, y north, m/s); required: a fix whose latest velocity
//!   is more than [`NavSatInput::max_gap_s`] away in time is refused.
//! - `heading`: `geometry_msgs/QuaternionStamped`, the orientation as an
//!   ENU yaw (REP 103: counter-clockwise from east; a driver that puts the
//!   compass heading in the yaw must be converted first); optional, used
//!   when within [`NavSatInput::max_gap_s`] of the fix.
//! - `imu`: `sensor_msgs/Imu`, its angular velocity about z as the yaw
//!   rate (REP 103 and 145: the body frame's z points up, so a turn to
//!   starboard is a negative z rate; the contract's yaw rate is positive to
//!   starboard, so it is the z rate's opposite); optional, used when within
//!   [`NavSatInput::max_gap_s`] of the fix. An IMU whose angular velocity
//!   covariance starts with -1 (REP 145: not measured) gives none; one that
//!   is not finite or beyond the contract's
//!   [`MAX_ABS_YAW_RATE_RADPS`] is refused. Its orientation and
//!   acceleration are not used.
//!
//! The fix's time is its header stamp (to the microsecond, the contract's
//! resolution); speed and course come from the velocity, the heading from
//! the yaw. The result is a [`GnssMessage`] that has passed the JSON
//! path's own validation ([`GnssMessage::to_fix`]), so the daemon hands it
//! to the same path as a fix on `{prefix}/{vessel}/gnss`. `hdop` is not
//! taken (a NavSatFix has a covariance, not an HDOP).

use twin_core::geodesy::wrap_two_pi;

use super::cdr::CdrError;
use super::map::{heading_of_enu_yaw, seconds_of_stamp, yaw_of};
use super::msgs::{Imu, NavSatFix, QuaternionStamped, RosMessage, TwistStamped};
use crate::messages::{GnssMessage, MAX_ABS_YAW_RATE_RADPS, MessageError, TimeSource};
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
    /// `imu`: `sensor_msgs/Imu`.
    Imu,
}

impl GnssTopic {
    /// Every topic.
    pub const ALL: [GnssTopic; 4] = [
        GnssTopic::Fix,
        GnssTopic::Vel,
        GnssTopic::Heading,
        GnssTopic::Imu,
    ];

    /// The topic's last name.
    pub fn name(self) -> &'static str {
        match self {
            GnssTopic::Fix => "fix",
            GnssTopic::Vel => "vel",
            GnssTopic::Heading => "heading",
            GnssTopic::Imu => "imu",
        }
    }

    /// `package/msg/Name` of its type.
    pub fn type_name(self) -> &'static str {
        match self {
            GnssTopic::Fix => NavSatFix::TYPE_NAME,
            GnssTopic::Vel => TwistStamped::TYPE_NAME,
            GnssTopic::Heading => QuaternionStamped::TYPE_NAME,
            GnssTopic::Imu => Imu::TYPE_NAME,
        }
    }

    /// Its RIHS01 type hash.
    pub fn type_hash(self) -> &'static str {
        match self {
            GnssTopic::Fix => NavSatFix::TYPE_HASH,
            GnssTopic::Vel => TwistStamped::TYPE_HASH,
            GnssTopic::Heading => QuaternionStamped::TYPE_HASH,
            GnssTopic::Imu => Imu::TYPE_HASH,
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

/// One vessel's latest velocity, heading and yaw rate, waiting for a fix.
#[derive(Debug, Clone, Default)]
pub struct NavSatInput {
    /// How far apart in time a velocity, heading or yaw rate may be from
    /// the fix, s.
    pub max_gap_s: f64,
    velocity: Option<(f64, f64, f64)>,
    heading: Option<(f64, f64)>,
    yaw_rate: Option<(f64, f64)>,
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
            GnssTopic::Imu => {
                let imu = Imu::from_cdr(payload)?;
                if imu.angular_velocity_covariance[0] == -1.0 {
                    return Ok(None);
                }
                let radps = -imu.angular_velocity.z;
                if !radps.is_finite() {
                    return Err(MessageError::NotFinite {
                        field: "angular_velocity.z",
                    }
                    .into());
                }
                if radps.abs() > MAX_ABS_YAW_RATE_RADPS {
                    return Err(MessageError::OutOfRange {
                        field: "angular_velocity.z",
                    }
                    .into());
                }
                self.yaw_rate = Some((seconds_of_stamp(imu.header.stamp), radps));
                Ok(None)
            }
            GnssTopic::Fix => self.fix(&NavSatFix::from_cdr(payload)?).map(Some),
        }
    }

    /// The contract's fix made of `fix` and the velocity, heading and yaw
    /// rate held.
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
            yaw_rate_radps: self.yaw_rate.filter(|(t, _)| near(*t)).map(|(_, r)| r),
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

    /// An IMU's message at `t` turning at `z_radps` about its z axis (up).
    fn imu(t: f64, z_radps: f64, covariance0: f64) -> Vec<u8> {
        let mut angular_velocity_covariance = [0.0; 9];
        angular_velocity_covariance[0] = covariance0;
        Imu {
            header: Header {
                stamp: stamp_of_seconds(t),
                frame_id: "base_link".into(),
            },
            orientation: yaw_quaternion(0.3),
            orientation_covariance: [0.0; 9],
            angular_velocity: Point {
                x: 0.01,
                y: -0.02,
                z: z_radps,
            },
            angular_velocity_covariance,
            linear_acceleration: Point {
                x: 0.1,
                y: 0.0,
                z: 9.81,
            },
            linear_acceleration_covariance: [0.0; 9],
        }
        .to_cdr()
    }

    #[test]
    fn a_fix_takes_the_imu_yaw_rate_near_it_turned_to_starboard_positive() {
        let mut input = NavSatInput::new(0.5);
        let t = 1_714_564_800.0;
        input.push(GnssTopic::Vel, &vel(t, 0.0, 2.0)).unwrap();
        // Turning to port: counter-clockwise seen from above, +z in REP 103.
        assert_eq!(
            input
                .push(GnssTopic::Imu, &imu(t - 0.1, 0.05, 1e-6))
                .unwrap(),
            None
        );
        let m = input.push(GnssTopic::Fix, &fix(t, 59.9)).unwrap().unwrap();
        assert_eq!(m.yaw_rate_radps, Some(-0.05));
        assert!(m.to_fix().unwrap().yaw_rate_radps == Some(-0.05));
        // A rate the IMU says it does not measure is not taken; the one
        // held is, while near the fix.
        assert_eq!(
            input.push(GnssTopic::Imu, &imu(t, 0.2, -1.0)).unwrap(),
            None
        );
        input.push(GnssTopic::Vel, &vel(t + 0.3, 0.0, 2.0)).unwrap();
        let m = input
            .push(GnssTopic::Fix, &fix(t + 0.3, 59.9))
            .unwrap()
            .unwrap();
        assert_eq!(m.yaw_rate_radps, Some(-0.05));
        // Too old for a fix a second later: the fix has no yaw rate.
        input.push(GnssTopic::Vel, &vel(t + 1.0, 0.0, 2.0)).unwrap();
        let m = input
            .push(GnssTopic::Fix, &fix(t + 1.0, 59.9))
            .unwrap()
            .unwrap();
        assert_eq!(m.yaw_rate_radps, None);
        // Wild and undefined rates are refused with their reasons.
        let e = input.push(GnssTopic::Imu, &imu(t, 6.0, 0.0)).unwrap_err();
        assert_eq!(e.reason(), "out_of_range");
        let e = input
            .push(GnssTopic::Imu, &imu(t, f64::NAN, 0.0))
            .unwrap_err();
        assert_eq!(e.reason(), "non_finite");
        let e = input
            .push(GnssTopic::Imu, &imu(t, 0.1, 0.0)[..40])
            .unwrap_err();
        assert_eq!(e.reason(), "ros2_bad_cdr");
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
