//! The twin's outputs as standard ROS 2 messages, so that a controller
//! needs no package of the twin's to read them:
//!
//! | twin output | ROS 2 message | topic under `{namespace}/{vessel}/twin/` |
//! |---|---|---|
//! | `twin/state` | `nav_msgs/Odometry` | `odometry` |
//! | `twin/state` | `sensor_msgs/NavSatFix` (the estimated position) | `fix` |
//! | `twin/fault` | `diagnostic_msgs/DiagnosticArray` | `fault` |
//! | `twin/prediction` | `nav_msgs/Path` | `prediction` |
//!
//! Frames (REP 103 and REP 105). The twin works in NED (north, east, down;
//! angles clockwise from north); ROS in ENU for the world-fixed frame and
//! FLU (forward, left, up) for the body. The world frame
//! `{vessel}/map` is ENU with its origin at the twin's local origin (the
//! `north_m`, `east_m` of `twin/state`): x = east, y = north, z = up (0). A
//! yaw is ENU: counter-clockwise from east, `yaw = pi/2 - heading`. The
//! body frame `{vessel}/base_link` is FLU, so a velocity to starboard is a
//! negative y and a turn to starboard a negative yaw rate.
//!
//! Unknowns: the twin estimates no altitude (`NaN`), no roll or pitch and
//! no yaw rate; their variances are [`UNKNOWN_VARIANCE`] (a large number,
//! as REP 145 advises for what a message must carry but is not measured).
//! The orientation is the heading where the twin has one, else the course
//! (a boat's track with no sideslip); its variance is the course's only in
//! that second case, [`UNKNOWN_VARIANCE`] otherwise (the twin publishes no
//! heading deviation).
//!
//! Faults: one `DiagnosticStatus` per propeller, named
//! `{vessel}/thruster/port` and `.../starboard`, and one for both,
//! `{vessel}/thrusters`. `level`: OK for `nominal` and `not_excited` (no
//! evidence of a loss; the `excited` value says whether the data could
//! tell), WARN for `suspect`, ERROR for `fault`. The values repeat the
//! JSON fault's fields as text: numbers in the shortest form that reads
//! back to the same double, `nan` for an unknown number, `true`/`false`,
//! an empty onset when there is none.

use std::f64::consts::FRAC_PI_2;

use twin_core::geodesy::{wrap_pi, wrap_two_pi};

use super::msgs::{
    DiagnosticArray, DiagnosticStatus, Header, KeyValue, NavSatFix, NavSatStatus, Odometry, Path,
    Point, Pose, PoseStamped, PoseWithCovariance, Quaternion, Time, Twist, TwistWithCovariance,
};
use crate::outputs::{
    FaultMessage, PredictionMessage, StateMessage, ThrusterMessage, ThrusterStatusName,
};
use crate::time::parse_rfc3339;

/// The variance given to what the twin does not estimate.
pub const UNKNOWN_VARIANCE: f64 = 1.0e6;

/// `DiagnosticStatus` levels.
pub mod level {
    /// OK.
    pub const OK: u8 = 0;
    /// WARN.
    pub const WARN: u8 = 1;
    /// ERROR.
    pub const ERROR: u8 = 2;
}

/// `NavSatFix.position_covariance_type`: the diagonal is known.
pub const COVARIANCE_TYPE_DIAGONAL_KNOWN: u8 = 2;

/// The frames of one vessel.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Frames {
    /// The world-fixed ENU frame, `{vessel}/map`.
    pub map: String,
    /// The body FLU frame, `{vessel}/base_link`.
    pub base_link: String,
}

impl Frames {
    /// The frames of `vessel`.
    pub fn of(vessel: &str) -> Self {
        Self {
            map: format!("{vessel}/map"),
            base_link: format!("{vessel}/base_link"),
        }
    }
}

/// A time of the contract (RFC 3339, microseconds) as a ROS stamp; the
/// zero stamp for a time that does not parse or does not fit.
pub fn stamp_of(time: &str) -> Time {
    parse_rfc3339(time).map_or(Time::default(), stamp_of_seconds)
}

/// Seconds since the Unix epoch as a ROS stamp, to the microsecond (the
/// contract's resolution); the zero stamp when it does not fit.
pub fn stamp_of_seconds(time_s: f64) -> Time {
    let whole = time_s.floor();
    let mut micros = ((time_s - whole) * 1e6).round() as u32;
    let mut sec = whole;
    if micros >= 1_000_000 {
        micros -= 1_000_000;
        sec += 1.0;
    }
    if !(0.0..=f64::from(i32::MAX)).contains(&sec) {
        return Time::default();
    }
    Time {
        sec: sec as i32,
        nanosec: micros * 1000,
    }
}

/// A stamp as seconds since the Unix epoch.
pub fn seconds_of_stamp(t: Time) -> f64 {
    f64::from(t.sec) + f64::from(t.nanosec) * 1e-9
}

/// The ENU yaw of a NED heading or course.
pub fn enu_yaw(heading_rad: f64) -> f64 {
    wrap_pi(FRAC_PI_2 - heading_rad)
}

/// The NED heading, in [0, 2 pi), of an ENU yaw.
pub fn heading_of_enu_yaw(yaw_rad: f64) -> f64 {
    wrap_two_pi(FRAC_PI_2 - yaw_rad)
}

/// A rotation about z by `yaw_rad`.
pub fn yaw_quaternion(yaw_rad: f64) -> Quaternion {
    let half = 0.5 * yaw_rad;
    Quaternion {
        x: 0.0,
        y: 0.0,
        z: half.sin(),
        w: half.cos(),
    }
}

/// The yaw of an orientation (its rotation about z).
pub fn yaw_of(q: &Quaternion) -> f64 {
    (2.0 * (q.w * q.z + q.x * q.y)).atan2(1.0 - 2.0 * (q.y * q.y + q.z * q.z))
}

fn diagonal6(d: [f64; 6]) -> [f64; 36] {
    let mut m = [0.0; 36];
    for (i, v) in d.into_iter().enumerate() {
        m[i * 7] = v;
    }
    m
}

/// `twin/state` as `nav_msgs/Odometry`: pose in `{vessel}/map` (ENU),
/// twist in `{vessel}/base_link` (FLU).
pub fn odometry(state: &StateMessage, frames: &Frames) -> Odometry {
    let u = UNKNOWN_VARIANCE;
    let heading = state.heading_rad.unwrap_or(state.cog_rad);
    let yaw_variance = match state.heading_rad {
        Some(_) => u,
        None => state.sigma.cog_rad.powi(2),
    };
    // The course relative to the bow: the velocity's direction in the body.
    let drift = state.cog_rad - heading;
    let sideways_sigma_mps = state.sog_mps * state.sigma.cog_rad;
    Odometry {
        header: Header {
            stamp: stamp_of(&state.time),
            frame_id: frames.map.clone(),
        },
        child_frame_id: frames.base_link.clone(),
        pose: PoseWithCovariance {
            pose: Pose {
                position: Point {
                    x: state.east_m,
                    y: state.north_m,
                    z: 0.0,
                },
                orientation: yaw_quaternion(enu_yaw(heading)),
            },
            covariance: diagonal6([
                state.sigma.east_m.powi(2),
                state.sigma.north_m.powi(2),
                u,
                u,
                u,
                yaw_variance,
            ]),
        },
        twist: TwistWithCovariance {
            twist: Twist {
                linear: Point {
                    x: state.sog_mps * drift.cos(),
                    y: -state.sog_mps * drift.sin(),
                    z: 0.0,
                },
                angular: Point::default(),
            },
            covariance: diagonal6([
                state.sigma.sog_mps.powi(2),
                sideways_sigma_mps.powi(2),
                u,
                u,
                u,
                u,
            ]),
        },
    }
}

/// `twin/state`'s position as `sensor_msgs/NavSatFix`.
pub fn estimated_fix(state: &StateMessage, frames: &Frames) -> NavSatFix {
    let mut covariance = [0.0; 9];
    covariance[0] = state.sigma.east_m.powi(2);
    covariance[4] = state.sigma.north_m.powi(2);
    covariance[8] = UNKNOWN_VARIANCE;
    NavSatFix {
        header: Header {
            stamp: stamp_of(&state.time),
            frame_id: frames.base_link.clone(),
        },
        status: NavSatStatus {
            status: 0,
            service: 0,
        },
        latitude: state.lat_deg,
        longitude: state.lon_deg,
        altitude: f64::NAN,
        position_covariance: covariance,
        position_covariance_type: COVARIANCE_TYPE_DIAGONAL_KNOWN,
    }
}

/// A thruster status as written in the JSON payloads.
pub fn status_name(s: ThrusterStatusName) -> &'static str {
    match s {
        ThrusterStatusName::NotExcited => "not_excited",
        ThrusterStatusName::Nominal => "nominal",
        ThrusterStatusName::Suspect => "suspect",
        ThrusterStatusName::Fault => "fault",
    }
}

/// The `DiagnosticStatus` level of a thruster status.
pub fn level_of(s: ThrusterStatusName) -> u8 {
    match s {
        ThrusterStatusName::NotExcited | ThrusterStatusName::Nominal => level::OK,
        ThrusterStatusName::Suspect => level::WARN,
        ThrusterStatusName::Fault => level::ERROR,
    }
}

/// A number as a diagnostic value: the shortest text that reads back to
/// the same double; `nan` for none.
pub fn number_text(v: Option<f64>) -> String {
    match v {
        Some(v) if v.is_finite() => format!("{v}"),
        _ => "nan".to_string(),
    }
}

fn kv(key: &str, value: String) -> KeyValue {
    KeyValue {
        key: key.to_string(),
        value,
    }
}

fn thruster_status(vessel: &str, side: &str, t: &ThrusterMessage) -> DiagnosticStatus {
    DiagnosticStatus {
        level: level_of(t.status),
        name: format!("{vessel}/thruster/{side}"),
        message: status_name(t.status).to_string(),
        hardware_id: vessel.to_string(),
        values: vec![
            kv("loss", number_text(t.loss)),
            kv("sigma", number_text(t.sigma)),
            kv("loss_raw", number_text(t.loss_raw)),
            kv("excited", t.excited.to_string()),
            kv("status", status_name(t.status).to_string()),
            kv("onset", t.onset.clone().unwrap_or_default()),
        ],
    }
}

/// `twin/fault` as `diagnostic_msgs/DiagnosticArray` (see the module doc).
pub fn fault_diagnostics(fault: &FaultMessage) -> DiagnosticArray {
    let vessel = fault.vessel.as_str();
    let ratio = fault.effectiveness_ratio;
    let model = match fault.model {
        crate::outputs::ModelName::Kinetic => "kinetic",
        crate::outputs::ModelName::SeedMethod => "seed_method",
    };
    let both = DiagnosticStatus {
        level: level_of(fault.status),
        name: format!("{vessel}/thrusters"),
        message: status_name(fault.status).to_string(),
        hardware_id: vessel.to_string(),
        values: vec![
            kv("status", status_name(fault.status).to_string()),
            kv("excited", fault.excited.to_string()),
            kv("effectiveness_ratio", number_text(ratio.map(|r| r.value))),
            kv(
                "effectiveness_ratio_sigma",
                number_text(ratio.map(|r| r.sigma)),
            ),
            kv("onset", fault.onset.clone().unwrap_or_default()),
            kv("model", model.to_string()),
            kv("replay", fault.replay.to_string()),
            kv(
                "profile_mismatch",
                fault
                    .profile_mismatch
                    .map(|m| m.to_string())
                    .unwrap_or_default(),
            ),
        ],
    };
    DiagnosticArray {
        header: Header {
            stamp: stamp_of(&fault.time),
            frame_id: String::new(),
        },
        status: vec![
            thruster_status(vessel, "port", &fault.thrusters.port),
            thruster_status(vessel, "starboard", &fault.thrusters.starboard),
            both,
        ],
    }
}

/// `twin/prediction` as `nav_msgs/Path` in `{vessel}/map`: each point's
/// time, position and course (as the orientation).
pub fn prediction_path(prediction: &PredictionMessage, frames: &Frames) -> Path {
    Path {
        header: Header {
            stamp: stamp_of(&prediction.start),
            frame_id: frames.map.clone(),
        },
        poses: prediction
            .points
            .iter()
            .map(|p| PoseStamped {
                header: Header {
                    stamp: stamp_of(&p.time),
                    frame_id: frames.map.clone(),
                },
                pose: Pose {
                    position: Point {
                        x: p.east_m,
                        y: p.north_m,
                        z: 0.0,
                    },
                    orientation: yaw_quaternion(enu_yaw(p.cog_rad)),
                },
            })
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stamps_keep_the_microsecond_and_carry() {
        let t = stamp_of("2024-05-01T12:00:00.123456Z");
        assert_eq!(t.nanosec, 123_456_000);
        assert_eq!(
            crate::time::format_rfc3339(seconds_of_stamp(t)).unwrap(),
            "2024-05-01T12:00:00.123456Z"
        );
        assert_eq!(
            stamp_of_seconds(9.999_999_9),
            Time {
                sec: 10,
                nanosec: 0
            }
        );
        assert_eq!(stamp_of("not a time"), Time::default());
    }

    #[test]
    fn a_heading_east_is_yaw_zero_and_north_is_a_quarter_turn() {
        assert!(enu_yaw(FRAC_PI_2).abs() < 1e-15);
        assert!((enu_yaw(0.0) - FRAC_PI_2).abs() < 1e-15);
        for h in [0.1, 1.0, 3.0, 4.0, 6.2] {
            let back = heading_of_enu_yaw(yaw_of(&yaw_quaternion(enu_yaw(h))));
            assert!((back - h).abs() < 1e-12, "{h} -> {back}");
        }
    }

    /// The vessels' status says why the comparison of the propellers is
    /// withheld, and says nothing while the profile describes the vessel.
    #[test]
    fn the_thrusters_status_carries_the_profile_mismatch() {
        let thruster = crate::outputs::ThrusterMessage {
            loss: Some(0.2),
            sigma: Some(0.35),
            loss_raw: Some(0.2),
            excited: false,
            status: ThrusterStatusName::NotExcited,
            onset: None,
        };
        let mut fault = FaultMessage {
            vessel: "v".into(),
            time: "2026-01-01T00:00:00Z".into(),
            thrusters: crate::outputs::Thrusters {
                port: thruster.clone(),
                starboard: thruster,
            },
            status: ThrusterStatusName::NotExcited,
            excited: false,
            onset: None,
            model: crate::outputs::ModelName::Kinetic,
            effectiveness_ratio: None,
            seed_input_faults: [0.0, 0.0],
            replay: false,
            profile_mismatch: None,
        };
        let mismatch_of = |f: &FaultMessage| {
            let d = fault_diagnostics(f);
            let both = d.status.last().unwrap();
            both.values
                .iter()
                .find(|v| v.key == "profile_mismatch")
                .map(|v| v.value.clone())
                .unwrap()
        };
        assert_eq!(mismatch_of(&fault), "");
        fault.profile_mismatch = Some(crate::outputs::ProfileMismatchMessage {
            yaw_damping_error: 1.24,
            yaw_damping_bound: 0.75,
            mass_error: 0.06,
            mass_bound: 0.75,
            thrust_error: -0.12,
            thrust_bound: 0.62,
            nis_per_dof: 0.66,
            max_nis_per_dof: 2.0,
        });
        assert_eq!(
            mismatch_of(&fault),
            "yaw damping error +1.24, at most +-0.75; mass error +0.06, at most +-0.75; thrust coefficient error -0.12, at most +-0.62; NIS per dof over the last minute 0.66, at most 2.0"
        );
    }

    #[test]
    fn numbers_read_back_exactly() {
        for v in [0.1, 1.0 / 3.0, 1e-7, 123456.789] {
            assert_eq!(number_text(Some(v)).parse::<f64>().unwrap(), v);
        }
        assert_eq!(number_text(None), "nan");
        assert_eq!(number_text(Some(f64::INFINITY)), "nan");
    }
}
