//! MAVLink (v1 and v2, the ArduPilot dialect) to
//! [`Record`](crate::measurement::Record)s: what an autopilot such as
//! ArduPilot Rover on a twin-thruster boat says about its position, heading
//! and propellers, live or from a telemetry log (`.tlog`).
//!
//! # Framing
//! [`MavlinkFramer`] finds frames in any byte stream (a UDP datagram, a TCP
//! or serial stream, a `.tlog` file): a start byte (0xFE v1, 0xFD v2), the
//! length from the header, and the frame's CRC with the message's CRC_EXTRA
//! from the dialect (the `mavlink` crate). A byte that does not start a
//! frame whose CRC checks is skipped, and each run of skipped bytes is
//! reported once (`Malformed`), so a burst of noise costs one count, not one
//! per byte, and a good frame after it is found again. A `.tlog` is the same
//! with an 8-byte big-endian time stamp (microseconds since the epoch, the
//! logging ground station's clock) before each frame.
//!
//! # Messages read
//! - `GPS_RAW_INT` (the GNSS receiver, source `mavlink:S`): position when
//!   `fix_type` is 2 or more (0 and 1 are refused as not valid), fix method
//!   from the fix type (4 DGPS, 5 RTK float, 6 RTK fixed, 8 PPP), HDOP from
//!   `eph`, height above the ellipsoid from `alt_ellipsoid`; course and speed
//!   from `cog` and `vel`; a true heading from `yaw` (dual-antenna
//!   receivers; 0 means none).
//! - `GLOBAL_POSITION_INT` (the autopilot's estimate, source
//!   `mavlink:S:ekf`): position marked as estimated (so the assembler takes
//!   the receiver's fixes when there are any), course and speed from `vx`,
//!   `vy`, heading from `hdg`. (0, 0) is "no position yet": empty.
//! - `ATTITUDE` (`mavlink:S:ekf`): roll, pitch, yaw as an attitude, and
//!   the heading's rate of change from the gyro's `pitchspeed` and
//!   `yawspeed` at that roll and pitch as a rate of turn (the twin's yaw
//!   rate measurement).
//! - `VFR_HUD` (`mavlink:S:ekf`): its whole-degree heading, only while the
//!   stream has given no `ATTITUDE` (which is finer).
//! - `ESC_TELEMETRY_1_TO_4`, `_5_TO_8`, `_9_TO_12`: the shaft speed (rpm) of
//!   the port and starboard motors ([`MavlinkOptions`]: ESC n drives servo
//!   output n). ESC telemetry gives no direction: the speed takes the sign
//!   of the thrust the motor's latest servo output asks for.
//! - `SERVO_OUTPUT_RAW`: the two motors' PWM through the [`PwmThrustMap`]
//!   to a thrust command, unless the stream gives ESC rpm (then the measured
//!   shaft speeds are used and the commands only give the sign), or
//!   [`ActuatorSource`] says otherwise.
//! - `SYSTEM_TIME`: the vehicle's clock (below); counted as time only.
//!
//! Every other message is counted as ignored.
//!
//! # Systems
//! The decoder follows one system: [`MavlinkOptions::system`], or else the
//! first system that sends one of the messages above. The same messages
//! from any other system (a second vehicle on the link) are refused as
//! `OtherSystem`; other traffic (a ground station's heartbeat) is ignored.
//!
//! # Time
//! A record takes the vehicle's own clock where it can: `GPS_RAW_INT`'s
//! `time_usec` when it is a Unix time (ArduPilot sends GNSS time there);
//! boot-relative times (`time_boot_ms`, `SERVO_OUTPUT_RAW`'s wrapping
//! `time_usec`) through the offset of the latest `SYSTEM_TIME` that carried
//! a Unix time; messages without a time field, the vehicle's latest time.
//! Until the vehicle's clock is known, a record takes the time the frame
//! arrived: the `.tlog` stamp in a log, or the receive time when live
//! (`Clock::Receiver`, and the record is then receiver-stamped). The
//! switch to the vehicle's clock starts a new time line (the two clocks
//! need not agree): it is not refused as time going back.

use mavlink::Message;
pub use mavlink::dialects::ardupilotmega as dialect;
use twin_core::geodesy::{wrap_pi, wrap_two_pi};
use twin_core::sample::{RADPS_PER_RPM, Side};

use super::{Clock, Counted, Emit, LineDecoder, Monotonic, ReadOptions, RejectReason};
use crate::measurement::{FixMethod, MAX_SPEED_MPS, Measurement, Source, ThrustCommand};
use crate::messages::MAX_ABS_YAW_RATE_RADPS;
use dialect::MavMessage;

/// The rate of change of the heading (the yaw of the ZYX Euler angles),
/// rad/s, from the body's pitch and yaw rates (`pitchspeed`, `yawspeed`
/// of `ATTITUDE`, rad/s) at `roll_rad` and `pitch_rad`:
/// `(q sin(roll) + r cos(roll)) / cos(pitch)` (the kinematics of the ZYX
/// Euler angles, Fossen 2021, chapter 2).
/// On a level hull it is the yaw rate itself. A rate beyond the contract's
/// [`MAX_ABS_YAW_RATE_RADPS`] is out of range.
fn heading_rate(
    roll_rad: f64,
    pitch_rad: f64,
    pitch_rate_radps: f64,
    yaw_rate_radps: f64,
) -> Result<f64, RejectReason> {
    let (sin_roll, cos_roll) = roll_rad.sin_cos();
    let cos_pitch = pitch_rad.cos();
    let rate = (pitch_rate_radps * sin_roll + yaw_rate_radps * cos_roll) / cos_pitch;
    if !rate.is_finite() || cos_pitch.abs() < 0.1 {
        Err(RejectReason::BadField { field: "yawspeed" })
    } else if rate.abs() > MAX_ABS_YAW_RATE_RADPS {
        Err(RejectReason::OutOfRange { field: "yawspeed" })
    } else {
        Ok(rate)
    }
}

/// Start byte of a MAVLink 1 frame.
pub const MAGIC_V1: u8 = 0xFE;
/// Start byte of a MAVLink 2 frame.
pub const MAGIC_V2: u8 = 0xFD;
/// Bytes of a `.tlog` time stamp before each frame.
pub const TLOG_STAMP_BYTES: usize = 8;
/// The longest frame: v2 header, 255 payload bytes, CRC, signature.
pub const MAX_FRAME_BYTES: usize = 10 + 255 + 2 + 13;

/// The most points of a [`PwmThrustMap`].
pub const MAX_MAP_POINTS: usize = 16;

/// ArduPilot's servo function number of a skid-steering boat's left
/// throttle (`SERVOn_FUNCTION = 73`).
pub const THROTTLE_LEFT_FUNCTION: u16 = 73;
/// ... and of its right throttle (`SERVOn_FUNCTION = 74`).
pub const THROTTLE_RIGHT_FUNCTION: u16 = 74;

/// The Otter's thrust limits per propeller, N: forward ...
pub const OTTER_MAX_FORWARD_THRUST_N: f64 = 119.7;
/// ... and astern (as a positive number).
pub const OTTER_MAX_ASTERN_THRUST_N: f64 = 66.7;

/// A PWM (microseconds) -> thrust (N, positive ahead) map: linear between
/// calibration points sorted by PWM, held at the end points beyond them.
/// A PWM of 0 (no pulse: the ESC stops the motor) is no thrust; 65535 is
/// "unknown".
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PwmThrustMap {
    points: [(u16, f64); MAX_MAP_POINTS],
    len: usize,
}

/// Why a thrust map is refused.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum ThrustMapError {
    /// Fewer than 2 or more than [`MAX_MAP_POINTS`] points.
    #[error("a thrust map has 2 to {MAX_MAP_POINTS} points, not {0}")]
    PointCount(usize),
    /// PWM values not strictly increasing, or outside 1..=65534.
    #[error("PWM values must increase strictly from point to point (and lie in 1-65534)")]
    PwmOrder,
    /// A thrust that is not finite or beyond the contract's limit.
    #[error("thrust {0} N is not a finite number within the contract's limit")]
    Thrust(f64),
}

impl PwmThrustMap {
    /// A map through `points` (PWM us, thrust N).
    pub fn new(points: &[(u16, f64)]) -> Result<Self, ThrustMapError> {
        if points.len() < 2 || points.len() > MAX_MAP_POINTS {
            return Err(ThrustMapError::PointCount(points.len()));
        }
        if points.windows(2).any(|w| w[1].0 <= w[0].0)
            || points.iter().any(|p| p.0 == 0 || p.0 == u16::MAX)
        {
            return Err(ThrustMapError::PwmOrder);
        }
        if let Some(p) = points
            .iter()
            .find(|p| !p.1.is_finite() || p.1.abs() > crate::messages::MAX_ABS_THRUST_N)
        {
            return Err(ThrustMapError::Thrust(p.1));
        }
        let mut stored = [(0, 0.0); MAX_MAP_POINTS];
        stored[..points.len()].copy_from_slice(points);
        Ok(Self {
            points: stored,
            len: points.len(),
        })
    }

    /// The Otter on ArduPilot's default PWM range: 1100 us full astern
    /// (66.7 N), 1500 us stopped, 1900 us full ahead (119.7 N), linear in
    /// between. An example to calibrate, not a measurement of any boat.
    pub fn otter() -> Self {
        Self::new(&[
            (1100, -OTTER_MAX_ASTERN_THRUST_N),
            (1500, 0.0),
            (1900, OTTER_MAX_FORWARD_THRUST_N),
        ])
        .expect("the Otter's map is valid")
    }

    /// The calibration points.
    pub fn points(&self) -> &[(u16, f64)] {
        &self.points[..self.len]
    }

    /// The thrust of a PWM; `None` for 65535 (unknown).
    pub fn thrust_n(&self, pwm_us: u16) -> Option<f64> {
        if pwm_us == u16::MAX {
            return None;
        }
        if pwm_us == 0 {
            return Some(0.0);
        }
        let points = self.points();
        let first = points[0];
        let last = points[points.len() - 1];
        if pwm_us <= first.0 {
            return Some(first.1);
        }
        if pwm_us >= last.0 {
            return Some(last.1);
        }
        let i = points.partition_point(|p| p.0 <= pwm_us);
        let (a, b) = (points[i - 1], points[i]);
        let f = f64::from(pwm_us - a.0) / f64::from(b.0 - a.0);
        Some(a.1 + f * (b.1 - a.1))
    }
}

impl Default for PwmThrustMap {
    fn default() -> Self {
        Self::otter()
    }
}

/// Which actuator messages give the propellers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ActuatorSource {
    /// ESC rpm once the stream has given any, servo thrust until then.
    #[default]
    Auto,
    /// ESC telemetry rpm only.
    Rpm,
    /// Servo outputs through the thrust map only.
    Servo,
    /// Neither.
    None,
}

/// How MAVLink is read.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MavlinkOptions {
    /// The system followed; `None`: the first that sends vehicle telemetry.
    pub system: Option<u8>,
    /// The servo output (1-16) of the port (left) motor, ArduPilot's
    /// `ThrottleLeft` (function 73). ESC n drives output n.
    pub port_output: u8,
    /// The servo output (1-16) of the starboard (right) motor,
    /// `ThrottleRight` (function 74).
    pub starboard_output: u8,
    /// Which actuator messages are used.
    pub actuators: ActuatorSource,
    /// PWM -> thrust, for servo outputs.
    pub thrust_map: PwmThrustMap,
}

impl Default for MavlinkOptions {
    /// Outputs 1 (left) and 3 (right), as ArduPilot's skid-steering setup
    /// guide wires a boat; the Otter's map.
    fn default() -> Self {
        Self {
            system: None,
            port_output: 1,
            starboard_output: 3,
            actuators: ActuatorSource::Auto,
            thrust_map: PwmThrustMap::otter(),
        }
    }
}

/// One thing the framer found.
#[derive(Debug, PartialEq)]
pub enum FrameEvent<'a> {
    /// A frame whose CRC checks (with its `.tlog` stamp first, in a tlog).
    Frame(&'a [u8]),
    /// A run of bytes that are not a frame, skipped.
    Skipped {
        /// How many bytes.
        bytes: usize,
        /// Why (the first reason of the run).
        reason: RejectReason,
    },
}

/// Finds MAVLink frames in a byte stream (see the module doc).
#[derive(Debug, Clone, Default)]
pub struct MavlinkFramer {
    buf: Vec<u8>,
    start: usize,
    tlog: bool,
    skipped: usize,
    skip_reason: Option<RejectReason>,
}

const NOT_MAVLINK: RejectReason = RejectReason::Malformed {
    what: "not a MAVLink frame",
};
const BAD_CRC: RejectReason = RejectReason::Malformed {
    what: "MAVLink CRC does not check",
};

/// The length of the frame at the start of `bytes` (its start byte
/// included), once its header is there; `Err` when it cannot be one.
fn frame_len(bytes: &[u8]) -> Result<Option<usize>, ()> {
    match bytes.first() {
        Some(&MAGIC_V1) => Ok(bytes.get(1).map(|&len| 6 + usize::from(len) + 2)),
        Some(&MAGIC_V2) => match (bytes.get(1), bytes.get(2)) {
            (Some(&len), Some(&incompat)) => {
                if incompat & !0x01 != 0 {
                    return Err(());
                }
                let signature = if incompat & 0x01 != 0 { 13 } else { 0 };
                Ok(Some(10 + usize::from(len) + 2 + signature))
            }
            _ => Ok(None),
        },
        Some(_) => Err(()),
        None => Ok(None),
    }
}

/// Header fields of a whole frame.
struct Header {
    v2: bool,
    system: u8,
    message_id: u32,
    payload: std::ops::Range<usize>,
}

fn header(frame: &[u8]) -> Option<Header> {
    let len = usize::from(*frame.get(1)?);
    let (v2, header_len, system, message_id) = match frame[0] {
        MAGIC_V1 => (false, 6, *frame.get(3)?, u32::from(*frame.get(5)?)),
        MAGIC_V2 => {
            let id = frame.get(7..10)?;
            (
                true,
                10,
                *frame.get(5)?,
                u32::from(id[0]) | u32::from(id[1]) << 8 | u32::from(id[2]) << 16,
            )
        }
        _ => return None,
    };
    let payload = header_len..header_len + len;
    frame.get(payload.end..payload.end + 2)?;
    Some(Header {
        v2,
        system,
        message_id,
        payload,
    })
}

/// True when the frame's CRC matches its message's (the whole frame given).
pub fn crc_ok(frame: &[u8]) -> bool {
    let Some(h) = header(frame) else {
        return false;
    };
    let computed = mavlink::calculate_crc(
        &frame[1..h.payload.end],
        MavMessage::extra_crc(h.message_id),
    );
    let sent = u16::from_le_bytes([frame[h.payload.end], frame[h.payload.end + 1]]);
    computed == sent
}

/// A plausible `.tlog` stamp: 2001 to 2100.
fn plausible_stamp(bytes: &[u8]) -> bool {
    let Some(stamp) = bytes.get(..TLOG_STAMP_BYTES) else {
        return false;
    };
    let us = u64::from_be_bytes(stamp.try_into().unwrap_or([0; 8]));
    (1_000_000_000_000_000..4_102_444_800_000_000).contains(&us)
}

/// True when `bytes` begin like a `.tlog` (used to detect the format).
pub fn looks_like_tlog(bytes: &[u8]) -> bool {
    plausible_stamp(bytes)
        && matches!(
            bytes.get(TLOG_STAMP_BYTES),
            Some(&MAGIC_V1) | Some(&MAGIC_V2)
        )
}

impl MavlinkFramer {
    /// A framer of bare frames (`tlog` false) or of `.tlog` records.
    pub fn new(tlog: bool) -> Self {
        Self {
            tlog,
            ..Self::default()
        }
    }

    /// Adds received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        if self.start > 0 && self.start >= self.buf.len() / 2 {
            self.buf.drain(..self.start);
            self.start = 0;
        }
        self.buf.extend_from_slice(bytes);
    }

    /// Bytes held.
    pub fn buffered_bytes(&self) -> usize {
        self.buf.capacity()
    }

    fn skip(&mut self, bytes: usize, reason: RejectReason) {
        self.skipped += bytes;
        self.skip_reason.get_or_insert(reason);
        self.start += bytes;
    }

    fn take_skipped(&mut self) -> Option<FrameEvent<'_>> {
        (self.skipped > 0).then(|| FrameEvent::Skipped {
            bytes: std::mem::take(&mut self.skipped),
            reason: self.skip_reason.take().unwrap_or(NOT_MAVLINK),
        })
    }

    /// The next frame or skipped run; `None` when more bytes are needed
    /// (a frame begun may still be completed by the next bytes).
    pub fn next_event(&mut self) -> Option<FrameEvent<'_>> {
        self.event(false)
    }

    /// The same when no more bytes are coming for now (the end of a
    /// datagram, of a file): a frame begun and not complete is noise, and
    /// the bytes left at the end are reported as skipped.
    pub fn drain_event(&mut self) -> Option<FrameEvent<'_>> {
        self.event(true)
    }

    fn event(&mut self, drain: bool) -> Option<FrameEvent<'_>> {
        let prefix = if self.tlog { TLOG_STAMP_BYTES } else { 0 };
        loop {
            let rest = &self.buf[self.start..];
            if rest.len() <= prefix {
                if drain && !rest.is_empty() {
                    self.skip(rest.len(), NOT_MAVLINK);
                }
                return if drain { self.take_skipped() } else { None };
            }
            if self.tlog && !plausible_stamp(rest) {
                self.skip(1, NOT_MAVLINK);
                continue;
            }
            let frame = &rest[prefix..];
            let incomplete = match frame_len(frame) {
                Err(()) => {
                    // Jump to the next possible start byte.
                    let next = if self.tlog {
                        1
                    } else {
                        frame
                            .iter()
                            .skip(1)
                            .position(|&b| b == MAGIC_V1 || b == MAGIC_V2)
                            .map_or(frame.len(), |i| i + 1)
                    };
                    self.skip(next, NOT_MAVLINK);
                    continue;
                }
                Ok(None) => true,
                Ok(Some(len)) if frame.len() < len => true,
                Ok(Some(len)) if !crc_ok(&frame[..len]) => {
                    self.skip(1, BAD_CRC);
                    continue;
                }
                Ok(Some(_)) => false,
            };
            if incomplete {
                if drain {
                    self.skip(1, NOT_MAVLINK);
                    continue;
                }
                return None;
            }
            if self.skipped > 0 {
                return self.take_skipped();
            }
            let len = frame_len(frame).ok().flatten().unwrap_or(0);
            let begin = self.start;
            self.start += prefix + len;
            return Some(FrameEvent::Frame(&self.buf[begin..begin + prefix + len]));
        }
    }
}

/// The state of the MAVLink decoder (see the module doc).
#[derive(Debug, Clone)]
pub struct MavlinkState {
    options: ReadOptions,
    tlog: bool,
    monotonic: Monotonic,
    system: Option<u8>,
    /// Unix time minus boot time of the followed system, s.
    boot_offset_s: Option<f64>,
    /// The latest boot-relative time seen, s (to unwrap `time_usec`).
    latest_boot_s: Option<f64>,
    /// The latest vehicle-clock time given to a record.
    latest_vehicle_s: Option<f64>,
    saw_attitude: bool,
    saw_esc_rpm: bool,
    /// The latest PWM of servo outputs 1-16.
    pwm: [Option<u16>; 16],
    receive_time_s: Option<f64>,
    receiver_stamped: bool,
}

/// The MAVLink decoder.
pub type MavlinkDecoder = Counted<MavlinkState>;

/// The messages read, by id.
const GPS_RAW_INT: u32 = 24;
const SYSTEM_TIME: u32 = 2;
const ATTITUDE: u32 = 30;
const GLOBAL_POSITION_INT: u32 = 33;
const SERVO_OUTPUT_RAW: u32 = 36;
const VFR_HUD: u32 = 74;
const ESC_TELEMETRY: [u32; 3] = [11_030, 11_031, 11_032];

fn telemetry(id: u32) -> bool {
    matches!(
        id,
        GPS_RAW_INT | SYSTEM_TIME | ATTITUDE | GLOBAL_POSITION_INT | SERVO_OUTPUT_RAW | VFR_HUD
    ) || ESC_TELEMETRY.contains(&id)
}

/// A MAVLink `time_usec` that is a Unix time (after 2001) rather than a
/// time since boot.
const UNIX_US_FLOOR: u64 = 1_000_000_000_000_000;
/// `SERVO_OUTPUT_RAW.time_usec` wraps at 2^32 us.
const U32_US_WRAP_S: f64 = 4_294.967_296;

/// A record's time: where it came from.
enum When {
    /// A Unix time in microseconds.
    UnixUs(u64),
    /// Seconds since boot.
    Boot(f64),
    /// No time field.
    None,
}

impl Counted<MavlinkState> {
    /// A decoder of bare frames (`tlog` false: live streams, through a
    /// [`MavlinkFramer`]) or of `.tlog` records (stamp + frame).
    pub fn new(options: ReadOptions, tlog: bool) -> Self {
        Counted::from_state(MavlinkState {
            options,
            tlog,
            monotonic: Monotonic::default(),
            system: options.mavlink.system,
            boot_offset_s: None,
            latest_boot_s: None,
            latest_vehicle_s: None,
            saw_attitude: false,
            saw_esc_rpm: false,
            pwm: [None; 16],
            receive_time_s: None,
            receiver_stamped: false,
        })
    }

    /// The system followed, once known.
    pub fn system(&self) -> Option<u8> {
        self.state.system
    }
}

impl MavlinkState {
    /// The time of a record (see the module doc).
    fn time(&mut self, when: When, arrival_s: Option<f64>) -> Result<f64, RejectReason> {
        let vehicle = match when {
            When::UnixUs(us) if us >= UNIX_US_FLOOR => Some(us as f64 / 1e6),
            When::UnixUs(us) => self.boot_offset_s.map(|o| o + us as f64 / 1e6),
            When::Boot(boot_s) => self.boot_offset_s.map(|o| o + boot_s),
            When::None => self.boot_offset_s.and(self.latest_vehicle_s),
        };
        let time_s = match vehicle {
            Some(t) => {
                if self.latest_vehicle_s.is_none() {
                    // The first record on the vehicle's clock after records
                    // on arrival times: the clocks differ, so this is a new
                    // time line, not a jump back.
                    self.monotonic = Monotonic::default();
                }
                self.latest_vehicle_s = Some(t);
                t
            }
            None => {
                let t = arrival_s.ok_or(RejectReason::NoTime)?;
                self.receiver_stamped = !self.tlog;
                t
            }
        };
        self.monotonic
            .check(time_s, self.options.backwards_tolerance_s)?;
        Ok(time_s)
    }

    fn boot_ms(&mut self, ms: u32) -> When {
        let s = f64::from(ms) / 1e3;
        self.latest_boot_s = Some(s);
        When::Boot(s)
    }

    /// `SERVO_OUTPUT_RAW`'s 32-bit microseconds since boot, unwrapped
    /// against the latest boot time seen.
    fn boot_us32(&mut self, us: u32) -> When {
        let raw = f64::from(us) / 1e6;
        let s = match self.latest_boot_s {
            Some(latest) => raw + ((latest - raw) / U32_US_WRAP_S).round() * U32_US_WRAP_S,
            None => raw,
        };
        When::Boot(s)
    }

    #[allow(clippy::too_many_lines)] // One arm per MAVLink message read.
    fn frame(
        &mut self,
        frame: &[u8],
        arrival_s: Option<f64>,
        emit: &mut Emit<'_>,
    ) -> Result<(), RejectReason> {
        let h = header(frame).ok_or(NOT_MAVLINK)?;
        if frame.len() != frame_len(frame).ok().flatten().unwrap_or(0) {
            return Err(RejectReason::Malformed {
                what: "MAVLink frame length",
            });
        }
        if !crc_ok(frame) {
            return Err(BAD_CRC);
        }
        if !telemetry(h.message_id) {
            emit.stats.ignored += 1;
            return Ok(());
        }
        match self.system {
            Some(s) if s != h.system => {
                return Err(RejectReason::OtherSystem { system: h.system });
            }
            Some(_) => {}
            None => self.system = Some(h.system),
        }
        let version = if h.v2 {
            mavlink::MavlinkVersion::V2
        } else {
            mavlink::MavlinkVersion::V1
        };
        let message =
            MavMessage::parse(version, h.message_id, &frame[h.payload]).map_err(|_| {
                RejectReason::Malformed {
                    what: "MAVLink payload",
                }
            })?;
        let system = h.system;
        let raw = Source::Mavlink {
            system,
            fused: false,
        };
        let fused = Source::Mavlink {
            system,
            fused: true,
        };
        let mut records: [Option<(Source, Measurement)>; 3] = [None; 3];
        let when = match message {
            MavMessage::SYSTEM_TIME(m) => {
                self.boot_ms(m.time_boot_ms);
                if m.time_unix_usec >= UNIX_US_FLOOR {
                    self.boot_offset_s =
                        Some(m.time_unix_usec as f64 / 1e6 - f64::from(m.time_boot_ms) / 1e3);
                }
                emit.stats.time_only += 1;
                return Ok(());
            }
            MavMessage::GPS_RAW_INT(m) => {
                let fix = m.fix_type as u32;
                let method = match fix {
                    0 | 1 => {
                        return Err(RejectReason::NotValid {
                            what: "GPS_RAW_INT fix type",
                        });
                    }
                    4 => FixMethod::Dgnss,
                    5 => FixMethod::RtkFloat,
                    6 => FixMethod::RtkFixed,
                    8 => FixMethod::Precise,
                    _ => FixMethod::Gnss,
                };
                let (lat_deg, lon_deg) = lat_lon(m.lat, m.lon)?;
                records[0] = Some((
                    raw,
                    Measurement::Position {
                        lat_deg,
                        lon_deg,
                        hdop: (m.eph != u16::MAX && m.eph > 0).then(|| f64::from(m.eph) * 0.01),
                        method: Some(method),
                        altitude_m: (m.alt_ellipsoid != 0)
                            .then(|| f64::from(m.alt_ellipsoid) * 1e-3),
                    },
                ));
                let cog_rad = centidegrees(m.cog, "cog")?;
                let sog_mps = (m.vel != u16::MAX)
                    .then(|| speed(f64::from(m.vel) * 0.01, "vel"))
                    .transpose()?;
                if cog_rad.is_some() || sog_mps.is_some() {
                    records[1] = Some((raw, Measurement::CourseSpeed { cog_rad, sog_mps }));
                }
                if m.yaw != 0 {
                    let heading_rad = centidegrees(m.yaw, "yaw")?.unwrap_or(0.0);
                    records[2] = Some((raw, Measurement::Heading { heading_rad }));
                }
                When::UnixUs(m.time_usec)
            }
            MavMessage::GLOBAL_POSITION_INT(m) => {
                let when = self.boot_ms(m.time_boot_ms);
                if m.lat != 0 || m.lon != 0 {
                    let (lat_deg, lon_deg) = lat_lon(m.lat, m.lon)?;
                    records[0] = Some((
                        fused,
                        Measurement::Position {
                            lat_deg,
                            lon_deg,
                            hdop: None,
                            method: Some(FixMethod::DeadReckoning),
                            altitude_m: None,
                        },
                    ));
                    let (vn, ve) = (f64::from(m.vx) * 0.01, f64::from(m.vy) * 0.01);
                    let sog = speed(vn.hypot(ve), "vx, vy")?;
                    records[1] = Some((
                        fused,
                        Measurement::CourseSpeed {
                            cog_rad: (sog > 0.0).then(|| wrap_two_pi(ve.atan2(vn))),
                            sog_mps: Some(sog),
                        },
                    ));
                }
                if let Some(heading_rad) = centidegrees(m.hdg, "hdg")? {
                    records[2] = Some((fused, Measurement::Heading { heading_rad }));
                }
                when
            }
            MavMessage::ATTITUDE(m) => {
                let when = self.boot_ms(m.time_boot_ms);
                self.saw_attitude = true;
                let angle = |v: f32, field| {
                    let v = f64::from(v);
                    if v.is_finite() && v.abs() <= 2.0 * std::f64::consts::PI {
                        Ok(v)
                    } else {
                        Err(RejectReason::BadField { field })
                    }
                };
                let (roll, pitch) = (angle(m.roll, "roll")?, angle(m.pitch, "pitch")?);
                records[0] = Some((
                    fused,
                    Measurement::Attitude {
                        yaw_rad: Some(wrap_pi(angle(m.yaw, "yaw")?)),
                        pitch_rad: Some(pitch),
                        roll_rad: Some(roll),
                    },
                ));
                records[1] = Some((
                    fused,
                    Measurement::RateOfTurn {
                        radps: heading_rate(
                            roll,
                            pitch,
                            f64::from(m.pitchspeed),
                            f64::from(m.yawspeed),
                        )?,
                    },
                ));
                when
            }
            MavMessage::VFR_HUD(m) => {
                if self.saw_attitude {
                    emit.stats.ignored += 1;
                    return Ok(());
                }
                if !(0..=360).contains(&m.heading) {
                    return Err(RejectReason::OutOfRange { field: "heading" });
                }
                records[0] = Some((
                    fused,
                    Measurement::Heading {
                        heading_rad: wrap_two_pi(f64::from(m.heading).to_radians()),
                    },
                ));
                When::None
            }
            MavMessage::SERVO_OUTPUT_RAW(m) => {
                let first = usize::from(m.port) * 8;
                let values = [
                    m.servo1_raw,
                    m.servo2_raw,
                    m.servo3_raw,
                    m.servo4_raw,
                    m.servo5_raw,
                    m.servo6_raw,
                    m.servo7_raw,
                    m.servo8_raw,
                    m.servo9_raw,
                    m.servo10_raw,
                    m.servo11_raw,
                    m.servo12_raw,
                    m.servo13_raw,
                    m.servo14_raw,
                    m.servo15_raw,
                    m.servo16_raw,
                ];
                // Port 0 carries outputs 1-16 (9-16 as extensions), port 1
                // outputs 9-16 in its first eight fields.
                let count = if m.port == 0 { 16 } else { 8 };
                for (i, v) in values.iter().take(count).enumerate() {
                    if let Some(slot) = self.pwm.get_mut(first + i)
                        && (i < 8 || *v != 0)
                    {
                        *slot = Some(*v);
                    }
                }
                let mavlink = self.options.mavlink;
                let use_servo = match mavlink.actuators {
                    ActuatorSource::Servo => true,
                    ActuatorSource::Auto => !self.saw_esc_rpm,
                    ActuatorSource::Rpm | ActuatorSource::None => false,
                };
                let port = self.thrust_of(mavlink.port_output);
                let starboard = self.thrust_of(mavlink.starboard_output);
                let when = self.boot_us32(m.time_usec);
                match (use_servo, port, starboard) {
                    (true, Some(port_n), Some(starboard_n)) => {
                        let time_s = self.time(when, arrival_s)?;
                        emit.record(
                            time_s,
                            raw,
                            Measurement::Thrust(ThrustCommand {
                                time_s,
                                port_n,
                                starboard_n,
                            }),
                        );
                    }
                    (true, _, _) => emit.stats.empty += 1,
                    (false, _, _) => emit.stats.ignored += 1,
                }
                return Ok(());
            }
            MavMessage::ESC_TELEMETRY_1_TO_4(m) => self.esc(0, m.rpm, &mut records, raw),
            MavMessage::ESC_TELEMETRY_5_TO_8(m) => self.esc(4, m.rpm, &mut records, raw),
            MavMessage::ESC_TELEMETRY_9_TO_12(m) => self.esc(8, m.rpm, &mut records, raw),
            _ => {
                emit.stats.ignored += 1;
                return Ok(());
            }
        };
        if records.iter().all(Option::is_none) {
            emit.stats.empty += 1;
            return Ok(());
        }
        let time_s = self.time(when, arrival_s)?;
        for (source, measurement) in records.into_iter().flatten() {
            emit.record(time_s, source, measurement);
        }
        Ok(())
    }

    /// The thrust the latest PWM of servo output `output` (1-16) asks for.
    fn thrust_of(&self, output: u8) -> Option<f64> {
        let pwm = (*self.pwm.get(usize::from(output).checked_sub(1)?)?)?;
        self.options.mavlink.thrust_map.thrust_n(pwm)
    }

    /// Port and starboard shaft speeds from the rpm of ESCs `first + 1`
    /// to `first + 4`.
    fn esc(
        &mut self,
        first: usize,
        rpm: [u16; 4],
        records: &mut [Option<(Source, Measurement)>; 3],
        source: Source,
    ) -> When {
        let mavlink = self.options.mavlink;
        if matches!(
            mavlink.actuators,
            ActuatorSource::Servo | ActuatorSource::None
        ) {
            return When::None;
        }
        let sides = [
            (Side::Port, mavlink.port_output),
            (Side::Starboard, mavlink.starboard_output),
        ];
        for (k, (side, output)) in sides.into_iter().enumerate() {
            let Some(index) = usize::from(output).checked_sub(1 + first) else {
                continue;
            };
            let Some(&value) = rpm.get(index) else {
                continue;
            };
            self.saw_esc_rpm = true;
            let sign = if self.thrust_of(output).is_some_and(|t| t < 0.0) {
                -1.0
            } else {
                1.0
            };
            records[k] = Some((
                source,
                Measurement::PropellerSpeed {
                    side,
                    radps: sign * f64::from(value) * RADPS_PER_RPM,
                },
            ));
        }
        When::None
    }
}

fn lat_lon(lat: i32, lon: i32) -> Result<(f64, f64), RejectReason> {
    let (lat, lon) = (f64::from(lat) * 1e-7, f64::from(lon) * 1e-7);
    if lat.abs() > 90.0 {
        return Err(RejectReason::OutOfRange { field: "lat" });
    }
    if lon.abs() > 180.0 {
        return Err(RejectReason::OutOfRange { field: "lon" });
    }
    Ok((lat, lon))
}

/// A direction in centidegrees, 65535 "unknown".
fn centidegrees(value: u16, field: &'static str) -> Result<Option<f64>, RejectReason> {
    match value {
        u16::MAX => Ok(None),
        v if v > 36_000 => Err(RejectReason::OutOfRange { field }),
        v => Ok(Some(wrap_two_pi((f64::from(v) * 0.01).to_radians()))),
    }
}

fn speed(mps: f64, field: &'static str) -> Result<f64, RejectReason> {
    if mps > MAX_SPEED_MPS {
        Err(RejectReason::OutOfRange { field })
    } else {
        Ok(mps)
    }
}

impl LineDecoder for MavlinkState {
    fn line(&mut self, line: &[u8], emit: &mut Emit<'_>) -> Result<(), RejectReason> {
        let (arrival_s, frame) = if self.tlog {
            match line.split_first_chunk::<TLOG_STAMP_BYTES>() {
                Some((stamp, frame)) => (Some(u64::from_be_bytes(*stamp) as f64 / 1e6), frame),
                None => (None, &[][..]),
            }
        } else {
            let live = matches!(self.options.clock, Clock::Receiver);
            (self.receive_time_s.filter(|_| live), line)
        };
        self.frame(frame, arrival_s, emit)
    }

    fn set_receive_time(&mut self, time_s: f64) {
        self.receive_time_s = Some(time_s);
    }

    fn receiver_stamped(&self) -> bool {
        self.receiver_stamped
    }

    fn begin_line(&mut self) {
        self.receiver_stamped = false;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measurement::Record;
    use crate::read::{Decoder, Item, LogFormat, LogReader, ReadStats, RejectKind};
    use crate::write::mavlink::{frame_v2, tlog_record};
    use dialect::*;

    /// 2026-08-03T04:27:20Z.
    const T0: f64 = 1_785_731_240.0;
    /// The vehicle booted 100 s before T0.
    const BOOT_MS: u32 = 100_000;

    fn system_time(boot_ms: u32) -> MavMessage {
        MavMessage::SYSTEM_TIME(SYSTEM_TIME_DATA {
            time_unix_usec: ((T0 - 100.0) * 1e6) as u64 + u64::from(boot_ms) * 1000,
            time_boot_ms: boot_ms,
        })
    }

    fn gps(time_s: f64, fix: GpsFixType) -> MavMessage {
        MavMessage::GPS_RAW_INT(GPS_RAW_INT_DATA {
            time_usec: (time_s * 1e6) as u64,
            lat: 344_100_000,
            lon: 1_335_400_000,
            eph: 90,
            vel: 250,
            cog: 9_000,
            fix_type: fix,
            alt_ellipsoid: 40_500,
            yaw: 0,
            ..GPS_RAW_INT_DATA::default()
        })
    }

    fn attitude(boot_ms: u32, yaw: f32) -> MavMessage {
        MavMessage::ATTITUDE(ATTITUDE_DATA {
            time_boot_ms: boot_ms,
            yaw,
            pitch: 0.01,
            roll: -0.02,
            pitchspeed: 0.01,
            yawspeed: 0.05,
            ..ATTITUDE_DATA::default()
        })
    }

    fn servo(boot_ms: u32, left: u16, right: u16) -> MavMessage {
        MavMessage::SERVO_OUTPUT_RAW(SERVO_OUTPUT_RAW_DATA {
            time_usec: boot_ms * 1000,
            servo1_raw: left,
            servo3_raw: right,
            ..SERVO_OUTPUT_RAW_DATA::default()
        })
    }

    fn esc(left_rpm: u16, right_rpm: u16) -> MavMessage {
        MavMessage::ESC_TELEMETRY_1_TO_4(ESC_TELEMETRY_1_TO_4_DATA {
            rpm: [left_rpm, 0, right_rpm, 0],
            ..ESC_TELEMETRY_1_TO_4_DATA::default()
        })
    }

    /// A `.tlog` of `(arrival time, system, message)`.
    fn tlog(messages: &[(f64, u8, MavMessage)]) -> Vec<u8> {
        let mut bytes = Vec::new();
        for (i, (t, system, m)) in messages.iter().enumerate() {
            bytes.extend(tlog_record(*t, &frame_v2(*system, 1, i as u8, m)));
        }
        bytes
    }

    fn read(bytes: &[u8]) -> (Vec<Item>, ReadStats) {
        let mut reader = LogReader::open(bytes, ReadOptions::default()).unwrap();
        assert_eq!(reader.format(), LogFormat::MavlinkTlog);
        let items: Vec<Item> = reader.by_ref().collect();
        (items, reader.stats().clone())
    }

    #[test]
    fn a_tlog_gives_positions_headings_and_propellers_on_the_vehicle_clock() {
        let arrival = T0 + 0.3; // the ground station's clock, 0.3 s late
        let log = tlog(&[
            (arrival, 1, system_time(BOOT_MS)),
            (
                arrival,
                1,
                gps(T0 + 0.2, GpsFixType::GPS_FIX_TYPE_RTK_FIXED),
            ),
            (arrival, 1, attitude(BOOT_MS + 250, 3.5)),
            (arrival, 1, servo(BOOT_MS + 260, 1900, 1300)),
            (arrival, 1, esc(1200, 600)),
            (
                arrival,
                255,
                MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()),
            ),
        ]);
        let (items, stats) = read(&log);
        assert_eq!(stats.total_rejected(), 0, "{items:?}");
        assert_eq!(stats.time_only, 1);
        let records: Vec<Record> = items.into_iter().map(Result::unwrap).collect();
        let raw = Source::Mavlink {
            system: 1,
            fused: false,
        };
        // GPS_RAW_INT: position, course and speed at its own GNSS time.
        assert_eq!(records[0].source, raw);
        assert!((records[0].time_s - (T0 + 0.2)).abs() < 1e-6);
        let Measurement::Position {
            lat_deg,
            lon_deg,
            hdop,
            method,
            altitude_m,
        } = records[0].measurement
        else {
            panic!("{:?}", records[0])
        };
        assert!((lat_deg - 34.41).abs() < 1e-9 && (lon_deg - 133.54).abs() < 1e-9);
        assert_eq!(method, Some(FixMethod::RtkFixed));
        assert!((hdop.unwrap() - 0.9).abs() < 1e-12);
        assert!((altitude_m.unwrap() - 40.5).abs() < 1e-9);
        let Measurement::CourseSpeed { cog_rad, sog_mps } = records[1].measurement else {
            panic!()
        };
        assert!((cog_rad.unwrap() - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert_eq!(sog_mps, Some(2.5));
        // ATTITUDE: boot time through SYSTEM_TIME, yaw wrapped to [-pi, pi).
        assert_eq!(
            records[2].source,
            Source::Mavlink {
                system: 1,
                fused: true
            }
        );
        assert!((records[2].time_s - (T0 + 0.25)).abs() < 1e-6);
        let Measurement::Attitude { yaw_rad, .. } = records[2].measurement else {
            panic!()
        };
        assert!((yaw_rad.unwrap() - (3.5 - std::f64::consts::TAU)).abs() < 1e-6);
        // Its gyro rates as the heading's rate of change, at the same time:
        // (0.01 sin(-0.02) + 0.05 cos(-0.02)) / cos(0.01).
        assert_eq!(records[3].source, records[2].source);
        assert_eq!(records[3].time_s, records[2].time_s);
        let Measurement::RateOfTurn { radps } = records[3].measurement else {
            panic!("{:?}", records[3])
        };
        let (roll, pitch) = (f64::from(-0.02f32), f64::from(0.01f32));
        let expected =
            (f64::from(0.01f32) * roll.sin() + f64::from(0.05f32) * roll.cos()) / pitch.cos();
        assert!((radps - expected).abs() < 1e-12, "{radps} vs {expected}");
        assert!((radps - 0.049_79).abs() < 1e-4, "{radps}");
        // SERVO_OUTPUT_RAW through the Otter's map, before any ESC rpm.
        let records = &records[1..];
        let Measurement::Thrust(t) = records[3].measurement else {
            panic!("{:?}", records[3])
        };
        assert!((t.port_n - OTTER_MAX_FORWARD_THRUST_N).abs() < 1e-9);
        assert!((t.starboard_n + 0.5 * OTTER_MAX_ASTERN_THRUST_N).abs() < 1e-9);
        assert!((t.time_s - (T0 + 0.26)).abs() < 1e-6);
        // ESC rpm, signed by the servo command (starboard astern); untimed,
        // so at the vehicle's latest time.
        assert_eq!(
            records[4].measurement,
            Measurement::PropellerSpeed {
                side: Side::Port,
                radps: 1200.0 * RADPS_PER_RPM
            }
        );
        assert_eq!(
            records[5].measurement,
            Measurement::PropellerSpeed {
                side: Side::Starboard,
                radps: -600.0 * RADPS_PER_RPM
            }
        );
        assert_eq!(records[5].time_s, records[3].time_s);
        assert_eq!(records.len(), 6, "after the rate of turn");
        // The ground station's heartbeat is ignored, not refused.
        assert_eq!(stats.ignored, 1);
    }

    #[test]
    fn before_the_vehicle_clock_records_take_the_arrival_time() {
        let log = tlog(&[(T0, 1, attitude(5_000, 0.5))]);
        let (items, _) = read(&log);
        assert_eq!(items[0].as_ref().unwrap().time_s, T0);
        // Live: the receive time, and the decoder says so.
        let mut d = MavlinkDecoder::new(
            ReadOptions {
                clock: Clock::Receiver,
                ..ReadOptions::default()
            },
            false,
        );
        // The receiving computer's clock is an hour ahead of the vehicle's:
        // the switch to the vehicle's clock is a jump back, accepted.
        d.set_receive_time(T0 + 3600.0);
        let mut out = Vec::new();
        d.decode_line(&frame_v2(1, 1, 0, &attitude(5_000, 0.5)), 1, &mut out);
        assert_eq!(out[0].as_ref().unwrap().time_s, T0 + 3600.0);
        assert!(d.receiver_stamped());
        d.decode_line(&frame_v2(1, 1, 1, &system_time(5_100)), 2, &mut out);
        d.decode_line(&frame_v2(1, 1, 2, &attitude(5_200, 0.5)), 3, &mut out);
        assert!(!d.receiver_stamped());
        // Each ATTITUDE gives an attitude and a rate of turn.
        assert_eq!(out.len(), 4);
        assert_eq!(out[1].as_ref().unwrap().time_s, T0 + 3600.0);
        for record in &out[2..] {
            assert!((record.as_ref().unwrap().time_s - (T0 - 100.0 + 5.2)).abs() < 1e-6);
        }
    }

    /// A gyro rate beyond the contract's, or one that is not a number or
    /// at a pitch where the heading's rate is not defined, refuses the
    /// message with its reason.
    #[test]
    fn a_wild_gyro_rate_is_refused() {
        let wild = |yawspeed: f32, pitch: f32| {
            MavMessage::ATTITUDE(ATTITUDE_DATA {
                time_boot_ms: 5_000,
                yaw: 0.5,
                pitch,
                yawspeed,
                ..ATTITUDE_DATA::default()
            })
        };
        let log = tlog(&[
            (T0, 1, wild(5.5, 0.0)),
            (T0 + 0.1, 1, wild(f32::NAN, 0.0)),
            (T0 + 0.2, 1, wild(0.1, 1.5)),
            (T0 + 0.3, 1, wild(-0.1, 0.0)),
        ]);
        let (items, stats) = read(&log);
        assert_eq!(stats.rejected(RejectKind::OutOfRange), 1, "{items:?}");
        assert_eq!(stats.rejected(RejectKind::BadField), 2, "{items:?}");
        let good: Vec<Record> = items.into_iter().filter_map(Result::ok).collect();
        assert_eq!(good.len(), 2);
        assert_eq!(
            good[1].measurement,
            Measurement::RateOfTurn {
                radps: -0.1f32 as f64
            }
        );
    }

    #[test]
    fn a_second_system_is_refused_and_no_fix_is_not_valid() {
        let log = tlog(&[
            (T0, 1, gps(T0, GpsFixType::GPS_FIX_TYPE_3D_FIX)),
            (T0 + 0.1, 2, gps(T0 + 0.1, GpsFixType::GPS_FIX_TYPE_3D_FIX)),
            (T0 + 0.2, 1, gps(T0 + 0.2, GpsFixType::GPS_FIX_TYPE_NO_FIX)),
        ]);
        let (items, stats) = read(&log);
        assert_eq!(stats.rejected(RejectKind::OtherSystem), 1);
        assert_eq!(stats.rejected(RejectKind::NotValid), 1);
        assert_eq!(items.iter().filter(|i| i.is_ok()).count(), 2);
    }

    #[test]
    fn the_framer_skips_noise_once_per_run_and_finds_frames_split_anywhere() {
        let a = frame_v2(1, 1, 0, &attitude(1_000, 0.1));
        let b = frame_v2(1, 1, 1, &attitude(1_100, 0.2));
        let mut corrupt = b.clone();
        let last = corrupt.len() - 1;
        corrupt[last] ^= 0xFF;
        let mut stream = b"\x00\x01garbage\xFD\xFE".to_vec();
        stream.extend(&a);
        stream.extend(&corrupt);
        stream.extend(&b);
        let mut framer = MavlinkFramer::new(false);
        let mut events = Vec::new();
        // One byte at a time: a frame split anywhere is still found.
        for byte in &stream {
            framer.push(std::slice::from_ref(byte));
            while let Some(e) = framer.next_event() {
                events.push(match e {
                    FrameEvent::Frame(f) => Ok(f.to_vec()),
                    FrameEvent::Skipped { bytes, reason } => Err((bytes, reason)),
                });
            }
        }
        // The false start `\xFE` (a v1 frame of 253 bytes) waits for more.
        assert_eq!(events, vec![]);
        // Nothing more is coming: what waited is noise.
        while let Some(e) = framer.drain_event() {
            events.push(match e {
                FrameEvent::Frame(f) => Ok(f.to_vec()),
                FrameEvent::Skipped { bytes, reason } => Err((bytes, reason)),
            });
        }
        assert_eq!(events.len(), 4, "{events:?}");
        assert!(matches!(events[0], Err((11, _))));
        assert_eq!(events[1], Ok(a));
        assert!(matches!(events[2], Err((n, BAD_CRC)) if n == corrupt.len()));
        assert_eq!(events[3], Ok(b));
        assert!(framer.buffered_bytes() < 4 * MAX_FRAME_BYTES);
    }

    #[test]
    fn thrust_maps_interpolate_and_refuse_bad_points() {
        let map = PwmThrustMap::otter();
        assert_eq!(map.thrust_n(1500), Some(0.0));
        assert_eq!(map.thrust_n(1700), Some(OTTER_MAX_FORWARD_THRUST_N / 2.0));
        assert_eq!(map.thrust_n(2100), Some(OTTER_MAX_FORWARD_THRUST_N));
        assert_eq!(map.thrust_n(900), Some(-OTTER_MAX_ASTERN_THRUST_N));
        assert_eq!(map.thrust_n(0), Some(0.0));
        assert_eq!(map.thrust_n(u16::MAX), None);
        assert_eq!(
            PwmThrustMap::new(&[(1500, 0.0)]),
            Err(ThrustMapError::PointCount(1))
        );
        assert_eq!(
            PwmThrustMap::new(&[(1500, 0.0), (1500, 1.0)]),
            Err(ThrustMapError::PwmOrder)
        );
        assert!(matches!(
            PwmThrustMap::new(&[(1100, f64::NAN), (1900, 1.0)]),
            Err(ThrustMapError::Thrust(_))
        ));
    }

    #[test]
    fn random_bytes_never_panic() {
        let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
        for _ in 0..200 {
            let mut bytes = vec![MAGIC_V2];
            for _ in 0..300 {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                bytes.push(x as u8);
            }
            let mut d = MavlinkDecoder::new(ReadOptions::default(), false);
            let mut out = Vec::new();
            d.decode_line(&bytes, 1, &mut out);
            let mut framer = MavlinkFramer::new(true);
            framer.push(&bytes);
            while framer.next_event().is_some() {}
            while framer.drain_event().is_some() {}
        }
    }
}
