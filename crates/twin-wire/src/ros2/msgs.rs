//! The ROS 2 message types the twin speaks, as plain structs with their CDR
//! encoding ([`RosMessage::to_cdr`], [`RosMessage::from_cdr`]) and, for the
//! golden tests against PyPI `rosbags`, serde with ROS 2's own field names.
//! Definitions are those of ROS 2 Jazzy (`std_msgs`, `builtin_interfaces`,
//! `geometry_msgs`, `sensor_msgs`, `nav_msgs`, `diagnostic_msgs`); the
//! RIHS01 type hashes are the ones `rosbags` computes for them (checked by
//! `tests/tests/ros2.rs`).

use serde::{Deserialize, Serialize};

use super::cdr::{CdrError, CdrReader, CdrWriter};

/// A part of a message: written and read in field order.
pub trait CdrField: Sized {
    /// Writes the fields.
    fn write(&self, w: &mut CdrWriter);
    /// Reads the fields.
    fn read(r: &mut CdrReader<'_>) -> Result<Self, CdrError>;
}

/// A top-level message type: its ROS name and type hash, and its payload.
pub trait RosMessage: CdrField {
    /// `package/msg/Name`.
    const TYPE_NAME: &'static str;
    /// The RIHS01 type hash, as rmw_zenoh puts it in keys.
    const TYPE_HASH: &'static str;

    /// The CDR payload, encapsulation header included.
    fn to_cdr(&self) -> Vec<u8> {
        let mut w = CdrWriter::new();
        self.write(&mut w);
        w.finish()
    }

    /// Reads a whole CDR payload; bytes left over are an error.
    fn from_cdr(bytes: &[u8]) -> Result<Self, CdrError> {
        let mut r = CdrReader::new(bytes)?;
        let message = Self::read(&mut r)?;
        r.finish()?;
        Ok(message)
    }
}

/// The name rmw_zenoh gives a type in keys: `package/msg/Name` becomes
/// `package::msg::dds_::Name_`.
pub fn dds_type_name(type_name: &str) -> String {
    match type_name.rsplit_once('/') {
        Some((namespace, name)) => format!("{}::dds_::{name}_", namespace.replace('/', "::")),
        None => format!("dds_::{type_name}_"),
    }
}

/// Serde of fixed arrays longer than serde's own 32 (covariances).
mod fixed {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer, const N: usize>(v: &[f64; N], s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(v.iter())
    }

    pub fn deserialize<'de, D: Deserializer<'de>, const N: usize>(
        d: D,
    ) -> Result<[f64; N], D::Error> {
        let v = Vec::<f64>::deserialize(d)?;
        let len = v.len();
        v.try_into()
            .map_err(|_| serde::de::Error::invalid_length(len, &format!("{N} numbers").as_str()))
    }
}

/// `builtin_interfaces/msg/Time`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Time {
    /// Seconds since the Unix epoch.
    pub sec: i32,
    /// Nanoseconds, 0 to 999 999 999.
    pub nanosec: u32,
}

/// `std_msgs/msg/Header`.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Header {
    /// When.
    pub stamp: Time,
    /// The frame the data are in.
    pub frame_id: String,
}

/// `sensor_msgs/msg/NavSatStatus`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct NavSatStatus {
    /// -1 no fix, 0 fix, 1 SBAS, 2 GBAS.
    pub status: i8,
    /// Bit mask of the constellations used (1 GPS, 2 GLONASS, 4 COMPASS, 8 GALILEO).
    pub service: u16,
}

/// `sensor_msgs/msg/NavSatFix`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct NavSatFix {
    /// Time of the fix; frame of the antenna.
    pub header: Header,
    /// Fix status.
    pub status: NavSatStatus,
    /// Latitude, degrees (WGS-84), positive north.
    pub latitude: f64,
    /// Longitude, degrees, positive east.
    pub longitude: f64,
    /// Altitude above the WGS-84 ellipsoid, m (NaN when unknown).
    pub altitude: f64,
    /// East, north, up covariance, m^2, row-major.
    pub position_covariance: [f64; 9],
    /// 0 unknown, 1 approximated, 2 diagonal known, 3 known.
    pub position_covariance_type: u8,
}

/// `geometry_msgs/msg/Point`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Point {
    /// x, m.
    pub x: f64,
    /// y, m.
    pub y: f64,
    /// z, m.
    pub z: f64,
}

/// `geometry_msgs/msg/Vector3`.
pub type Vector3 = Point;

/// `geometry_msgs/msg/Quaternion`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w.
    pub w: f64,
}

impl Default for Quaternion {
    fn default() -> Self {
        Self {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }
    }
}

/// `geometry_msgs/msg/Pose`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Pose {
    /// Position, m.
    pub position: Point,
    /// Orientation.
    pub orientation: Quaternion,
}

/// `geometry_msgs/msg/PoseWithCovariance`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PoseWithCovariance {
    /// The pose.
    pub pose: Pose,
    /// x, y, z, rotation about x, y, z; row-major.
    #[serde(with = "fixed")]
    pub covariance: [f64; 36],
}

/// `geometry_msgs/msg/Twist`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Twist {
    /// Linear velocity, m/s.
    pub linear: Vector3,
    /// Angular velocity, rad/s.
    pub angular: Vector3,
}

/// `geometry_msgs/msg/TwistWithCovariance`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TwistWithCovariance {
    /// The twist.
    pub twist: Twist,
    /// Linear x, y, z, angular x, y, z; row-major.
    #[serde(with = "fixed")]
    pub covariance: [f64; 36],
}

/// `nav_msgs/msg/Odometry`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Odometry {
    /// Time; the frame of the pose.
    pub header: Header,
    /// The frame of the twist.
    pub child_frame_id: String,
    /// Pose in `header.frame_id`.
    pub pose: PoseWithCovariance,
    /// Twist in `child_frame_id`.
    pub twist: TwistWithCovariance,
}

/// `geometry_msgs/msg/PoseStamped`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct PoseStamped {
    /// Time and frame.
    pub header: Header,
    /// The pose.
    pub pose: Pose,
}

/// `nav_msgs/msg/Path`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Path {
    /// Time and frame.
    pub header: Header,
    /// The poses in order.
    pub poses: Vec<PoseStamped>,
}

/// `diagnostic_msgs/msg/KeyValue`.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct KeyValue {
    /// The key.
    pub key: String,
    /// The value.
    pub value: String,
}

/// `diagnostic_msgs/msg/DiagnosticStatus`.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct DiagnosticStatus {
    /// 0 OK, 1 WARN, 2 ERROR, 3 STALE.
    pub level: u8,
    /// What is described.
    pub name: String,
    /// A short description of the status.
    pub message: String,
    /// The hardware's id.
    pub hardware_id: String,
    /// Values.
    pub values: Vec<KeyValue>,
}

/// `diagnostic_msgs/msg/DiagnosticArray`.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct DiagnosticArray {
    /// Time.
    pub header: Header,
    /// One status per component.
    pub status: Vec<DiagnosticStatus>,
}

/// `geometry_msgs/msg/TwistStamped`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct TwistStamped {
    /// Time and frame.
    pub header: Header,
    /// The twist.
    pub twist: Twist,
}

/// `sensor_msgs/msg/Imu`: an inertial unit's orientation, angular
/// velocity and linear acceleration, in the frame of `header.frame_id`
/// (REP 103 and 145: x forward, y left, z up; a covariance whose first
/// element is -1 says the quantity is not measured).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Imu {
    /// Time and frame.
    pub header: Header,
    /// Orientation.
    pub orientation: Quaternion,
    /// Its covariance, rad^2, row-major.
    pub orientation_covariance: [f64; 9],
    /// Angular velocity, rad/s.
    pub angular_velocity: Vector3,
    /// Its covariance, (rad/s)^2, row-major.
    pub angular_velocity_covariance: [f64; 9],
    /// Linear acceleration, m/s^2.
    pub linear_acceleration: Vector3,
    /// Its covariance, (m/s^2)^2, row-major.
    pub linear_acceleration_covariance: [f64; 9],
}

/// `geometry_msgs/msg/QuaternionStamped`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct QuaternionStamped {
    /// Time and frame.
    pub header: Header,
    /// The orientation.
    pub quaternion: Quaternion,
}

impl CdrField for Time {
    fn write(&self, w: &mut CdrWriter) {
        w.i32(self.sec);
        w.u32(self.nanosec);
    }
    fn read(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            sec: r.i32("stamp.sec")?,
            nanosec: r.u32("stamp.nanosec")?,
        })
    }
}

impl CdrField for Header {
    fn write(&self, w: &mut CdrWriter) {
        self.stamp.write(w);
        w.string(&self.frame_id);
    }
    fn read(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            stamp: Time::read(r)?,
            frame_id: r.string("header.frame_id")?,
        })
    }
}

impl CdrField for NavSatStatus {
    fn write(&self, w: &mut CdrWriter) {
        w.i8(self.status);
        w.u16(self.service);
    }
    fn read(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            status: r.i8("status.status")?,
            service: r.u16("status.service")?,
        })
    }
}

impl CdrField for NavSatFix {
    fn write(&self, w: &mut CdrWriter) {
        self.header.write(w);
        self.status.write(w);
        w.f64(self.latitude);
        w.f64(self.longitude);
        w.f64(self.altitude);
        w.f64s(&self.position_covariance);
        w.u8(self.position_covariance_type);
    }
    fn read(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            header: Header::read(r)?,
            status: NavSatStatus::read(r)?,
            latitude: r.f64("latitude")?,
            longitude: r.f64("longitude")?,
            altitude: r.f64("altitude")?,
            position_covariance: r.f64s("position_covariance")?,
            position_covariance_type: r.u8("position_covariance_type")?,
        })
    }
}

impl CdrField for Point {
    fn write(&self, w: &mut CdrWriter) {
        w.f64s(&[self.x, self.y, self.z]);
    }
    fn read(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        let [x, y, z] = r.f64s("point")?;
        Ok(Self { x, y, z })
    }
}

impl CdrField for Quaternion {
    fn write(&self, w: &mut CdrWriter) {
        w.f64s(&[self.x, self.y, self.z, self.w]);
    }
    fn read(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        let [x, y, z, w] = r.f64s("quaternion")?;
        Ok(Self { x, y, z, w })
    }
}

impl CdrField for Pose {
    fn write(&self, w: &mut CdrWriter) {
        self.position.write(w);
        self.orientation.write(w);
    }
    fn read(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            position: Point::read(r)?,
            orientation: Quaternion::read(r)?,
        })
    }
}

impl CdrField for PoseWithCovariance {
    fn write(&self, w: &mut CdrWriter) {
        self.pose.write(w);
        w.f64s(&self.covariance);
    }
    fn read(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            pose: Pose::read(r)?,
            covariance: r.f64s("pose.covariance")?,
        })
    }
}

impl CdrField for Twist {
    fn write(&self, w: &mut CdrWriter) {
        self.linear.write(w);
        self.angular.write(w);
    }
    fn read(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            linear: Vector3::read(r)?,
            angular: Vector3::read(r)?,
        })
    }
}

impl CdrField for TwistWithCovariance {
    fn write(&self, w: &mut CdrWriter) {
        self.twist.write(w);
        w.f64s(&self.covariance);
    }
    fn read(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            twist: Twist::read(r)?,
            covariance: r.f64s("twist.covariance")?,
        })
    }
}

impl CdrField for Odometry {
    fn write(&self, w: &mut CdrWriter) {
        self.header.write(w);
        w.string(&self.child_frame_id);
        self.pose.write(w);
        self.twist.write(w);
    }
    fn read(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            header: Header::read(r)?,
            child_frame_id: r.string("child_frame_id")?,
            pose: PoseWithCovariance::read(r)?,
            twist: TwistWithCovariance::read(r)?,
        })
    }
}

impl CdrField for PoseStamped {
    fn write(&self, w: &mut CdrWriter) {
        self.header.write(w);
        self.pose.write(w);
    }
    fn read(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            header: Header::read(r)?,
            pose: Pose::read(r)?,
        })
    }
}

/// Smallest CDR size of a `PoseStamped` (an empty frame id), bytes.
const POSE_STAMPED_MIN_BYTES: usize = 8 + 5 + 56;
/// Smallest CDR size of a `KeyValue`, bytes.
const KEY_VALUE_MIN_BYTES: usize = 5 + 5;
/// Smallest CDR size of a `DiagnosticStatus`, bytes.
const STATUS_MIN_BYTES: usize = 1 + 3 * 5 + 4;

impl CdrField for Path {
    fn write(&self, w: &mut CdrWriter) {
        self.header.write(w);
        w.len(self.poses.len());
        for p in &self.poses {
            p.write(w);
        }
    }
    fn read(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        let header = Header::read(r)?;
        let n = r.len("poses", POSE_STAMPED_MIN_BYTES)?;
        let poses = (0..n)
            .map(|_| PoseStamped::read(r))
            .collect::<Result<_, _>>()?;
        Ok(Self { header, poses })
    }
}

impl CdrField for KeyValue {
    fn write(&self, w: &mut CdrWriter) {
        w.string(&self.key);
        w.string(&self.value);
    }
    fn read(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            key: r.string("values.key")?,
            value: r.string("values.value")?,
        })
    }
}

impl CdrField for DiagnosticStatus {
    fn write(&self, w: &mut CdrWriter) {
        w.u8(self.level);
        w.string(&self.name);
        w.string(&self.message);
        w.string(&self.hardware_id);
        w.len(self.values.len());
        for v in &self.values {
            v.write(w);
        }
    }
    fn read(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        let level = r.u8("status.level")?;
        let name = r.string("status.name")?;
        let message = r.string("status.message")?;
        let hardware_id = r.string("status.hardware_id")?;
        let n = r.len("status.values", KEY_VALUE_MIN_BYTES)?;
        let values = (0..n)
            .map(|_| KeyValue::read(r))
            .collect::<Result<_, _>>()?;
        Ok(Self {
            level,
            name,
            message,
            hardware_id,
            values,
        })
    }
}

impl CdrField for DiagnosticArray {
    fn write(&self, w: &mut CdrWriter) {
        self.header.write(w);
        w.len(self.status.len());
        for s in &self.status {
            s.write(w);
        }
    }
    fn read(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        let header = Header::read(r)?;
        let n = r.len("status", STATUS_MIN_BYTES)?;
        let status = (0..n)
            .map(|_| DiagnosticStatus::read(r))
            .collect::<Result<_, _>>()?;
        Ok(Self { header, status })
    }
}

impl CdrField for TwistStamped {
    fn write(&self, w: &mut CdrWriter) {
        self.header.write(w);
        self.twist.write(w);
    }
    fn read(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            header: Header::read(r)?,
            twist: Twist::read(r)?,
        })
    }
}

impl CdrField for QuaternionStamped {
    fn write(&self, w: &mut CdrWriter) {
        self.header.write(w);
        self.quaternion.write(w);
    }
    fn read(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            header: Header::read(r)?,
            quaternion: Quaternion::read(r)?,
        })
    }
}

impl CdrField for Imu {
    fn write(&self, w: &mut CdrWriter) {
        self.header.write(w);
        self.orientation.write(w);
        w.f64s(&self.orientation_covariance);
        self.angular_velocity.write(w);
        w.f64s(&self.angular_velocity_covariance);
        self.linear_acceleration.write(w);
        w.f64s(&self.linear_acceleration_covariance);
    }
    fn read(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            header: Header::read(r)?,
            orientation: Quaternion::read(r)?,
            orientation_covariance: r.f64s("orientation_covariance")?,
            angular_velocity: Vector3::read(r)?,
            angular_velocity_covariance: r.f64s("angular_velocity_covariance")?,
            linear_acceleration: Vector3::read(r)?,
            linear_acceleration_covariance: r.f64s("linear_acceleration_covariance")?,
        })
    }
}

impl RosMessage for Imu {
    const TYPE_NAME: &'static str = "sensor_msgs/msg/Imu";
    const TYPE_HASH: &'static str =
        "RIHS01_7d9a00ff131080897a5ec7e26e315954b8eae3353c3f995c55faf71574000b5b";
}

impl RosMessage for NavSatFix {
    const TYPE_NAME: &'static str = "sensor_msgs/msg/NavSatFix";
    const TYPE_HASH: &'static str =
        "RIHS01_62223ab3fe210a15976021da7afddc9e200dc9ec75231c1b6a557fc598a65404";
}

impl RosMessage for Odometry {
    const TYPE_NAME: &'static str = "nav_msgs/msg/Odometry";
    const TYPE_HASH: &'static str =
        "RIHS01_3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0";
}

impl RosMessage for Path {
    const TYPE_NAME: &'static str = "nav_msgs/msg/Path";
    const TYPE_HASH: &'static str =
        "RIHS01_1957a5bb3cee5da65c4e52e52b65a93df227efce4c20f8458b36e73066ca334b";
}

impl RosMessage for DiagnosticArray {
    const TYPE_NAME: &'static str = "diagnostic_msgs/msg/DiagnosticArray";
    const TYPE_HASH: &'static str =
        "RIHS01_5a8a36efb05fb25070fa0fb3810290c0e6cd4862b54a8fb975a1ee8dc55a333e";
}

impl RosMessage for TwistStamped {
    const TYPE_NAME: &'static str = "geometry_msgs/msg/TwistStamped";
    const TYPE_HASH: &'static str =
        "RIHS01_5f0fcd4f81d5d06ad9b4c4c63e3ea51b82d6ae4d0558f1d475229b1121db6f64";
}

impl RosMessage for QuaternionStamped {
    const TYPE_NAME: &'static str = "geometry_msgs/msg/QuaternionStamped";
    const TYPE_HASH: &'static str =
        "RIHS01_381add86c6c3160644d228ca342182c7fd6c7fab11c7a85ad817a9cc22dbac6e";
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dds_names_are_rmw_zenohs() {
        assert_eq!(
            dds_type_name(NavSatFix::TYPE_NAME),
            "sensor_msgs::msg::dds_::NavSatFix_"
        );
        assert_eq!(
            dds_type_name(DiagnosticArray::TYPE_NAME),
            "diagnostic_msgs::msg::dds_::DiagnosticArray_"
        );
    }

    #[test]
    fn every_prefix_of_a_message_is_refused_not_a_panic() {
        let path = Path {
            header: Header {
                stamp: Time { sec: 5, nanosec: 7 },
                frame_id: "otter/map".into(),
            },
            poses: vec![PoseStamped::default(); 3],
        };
        let bytes = path.to_cdr();
        assert_eq!(Path::from_cdr(&bytes).unwrap(), path);
        for cut in 0..bytes.len() - 1 {
            assert!(Path::from_cdr(&bytes[..cut]).is_err(), "cut at {cut}");
        }
    }
}
