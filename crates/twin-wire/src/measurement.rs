//! The one measurement type every log reader emits: a [`Record`] is a
//! time-stamped, typed measurement in SI units from a named [`Source`].
//!
//! Readers do the unit work (knots, degrees-and-minutes, 1e-4 rad, 0.25 rpm,
//! magnetic references) so that nothing downstream sees a wire unit. Angles
//! that are compass directions (course, heading, set) are in radians
//! clockwise from true north, wrapped to [0, 2 pi). Absent fields are `None`,
//! never a sentinel number.

use std::fmt;
use std::str::FromStr;

use twin_core::sample::{GnssFix, PropellerSpeeds, Side};

/// The largest speed over ground or through water accepted from any input,
/// m/s (about 97 kn): far above any USV, far below a corrupted field.
pub const MAX_SPEED_MPS: f64 = 50.0;

/// A two-character NMEA 0183 talker id (`GP`, `II`, ...).
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Talker([u8; 2]);

impl fmt::Debug for Talker {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Talker({:?})", self.as_str())
    }
}

impl Talker {
    /// A talker id from two ASCII upper-case letters or digits.
    pub fn new(id: [u8; 2]) -> Option<Self> {
        id.iter()
            .all(|b| b.is_ascii_uppercase() || b.is_ascii_digit())
            .then_some(Self(id))
    }

    /// `GP`, the GPS talker, used by the writers by default.
    pub const GP: Talker = Talker(*b"GP");

    /// The two characters.
    pub fn as_str(&self) -> &str {
        // Only ASCII is ever stored (see `new`).
        std::str::from_utf8(&self.0).unwrap_or("??")
    }
}

impl fmt::Display for Talker {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Where a record came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Source {
    /// An NMEA 2000 source address.
    N2k(u8),
    /// An NMEA 0183 talker id.
    Nmea(Talker),
    /// The project's own JSON messages.
    Json,
    /// A MAVLink system (its system id): `fused` is false for what its GNSS
    /// receiver reports (`GPS_RAW_INT`), true for the autopilot's own
    /// estimates (`GLOBAL_POSITION_INT`, `ATTITUDE`, `VFR_HUD`), so that the
    /// assembler's source choice tells a receiver's fix from a filtered one.
    Mavlink {
        /// The MAVLink system id.
        system: u8,
        /// The autopilot's estimate rather than the receiver's measurement.
        fused: bool,
    },
    /// A device of a gpsd daemon, numbered in the order gpsd first names it.
    Gpsd(u8),
}

impl fmt::Display for Source {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Source::N2k(address) => write!(f, "n2k:{address}"),
            Source::Nmea(talker) => write!(f, "nmea:{talker}"),
            Source::Json => f.write_str("json"),
            Source::Mavlink {
                system,
                fused: false,
            } => write!(f, "mavlink:{system}"),
            Source::Mavlink {
                system,
                fused: true,
            } => write!(f, "mavlink:{system}:ekf"),
            Source::Gpsd(device) => write!(f, "gpsd:{device}"),
        }
    }
}

/// Why a source name (`n2k:25`, `nmea:GP`, `json`, `mavlink:1`,
/// `mavlink:1:ekf`, `gpsd:0`) cannot be read.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error(
    "a source is `n2k:ADDRESS` (0-255), `nmea:TT` (talker id), `json`, `mavlink:SYSTEM`, `mavlink:SYSTEM:ekf` or `gpsd:DEVICE`"
)]
pub struct SourceParseError;

impl FromStr for Source {
    type Err = SourceParseError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        if s == "json" {
            return Ok(Source::Json);
        }
        if let Some(address) = s.strip_prefix("n2k:") {
            return address
                .parse::<u8>()
                .map(Source::N2k)
                .map_err(|_| SourceParseError);
        }
        if let Some(rest) = s.strip_prefix("mavlink:") {
            let (system, fused) = match rest.strip_suffix(":ekf") {
                Some(system) => (system, true),
                None => (rest, false),
            };
            return system
                .parse::<u8>()
                .map(|system| Source::Mavlink { system, fused })
                .map_err(|_| SourceParseError);
        }
        if let Some(device) = s.strip_prefix("gpsd:") {
            return device
                .parse::<u8>()
                .map(Source::Gpsd)
                .map_err(|_| SourceParseError);
        }
        if let Some(talker) = s.strip_prefix("nmea:") {
            let bytes: [u8; 2] = talker.as_bytes().try_into().map_err(|_| SourceParseError)?;
            return Talker::new(bytes).map(Source::Nmea).ok_or(SourceParseError);
        }
        Err(SourceParseError)
    }
}

/// How a position was fixed. The numbering of NMEA 2000 PGN 129029 "method"
/// and of the NMEA 0183 GGA quality indicator agree, so both map here.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum FixMethod {
    /// Standalone GNSS (GGA 1, 129029 method 1, mode `A`).
    Gnss,
    /// Differential GNSS / SBAS (2, mode `D`).
    Dgnss,
    /// Precise (PPS/PPP) GNSS (3, mode `P`).
    Precise,
    /// RTK with fixed integers (4, mode `R`).
    RtkFixed,
    /// RTK float (5, mode `F`).
    RtkFloat,
    /// Dead reckoning / estimated (6, mode `E`).
    DeadReckoning,
    /// Position entered by hand (7, mode `M`).
    Manual,
    /// Simulator (8, mode `S`).
    Simulated,
}

impl FixMethod {
    /// The method of a GGA quality / 129029 method number; `None` for 0 (no
    /// fix, handled by the caller as invalid) and unknown values.
    pub fn from_code(code: u64) -> Option<FixMethod> {
        Some(match code {
            1 => FixMethod::Gnss,
            2 => FixMethod::Dgnss,
            3 => FixMethod::Precise,
            4 => FixMethod::RtkFixed,
            5 => FixMethod::RtkFloat,
            6 => FixMethod::DeadReckoning,
            7 => FixMethod::Manual,
            8 => FixMethod::Simulated,
            _ => return None,
        })
    }

    /// The GGA quality / 129029 method number.
    pub fn code(self) -> u8 {
        match self {
            FixMethod::Gnss => 1,
            FixMethod::Dgnss => 2,
            FixMethod::Precise => 3,
            FixMethod::RtkFixed => 4,
            FixMethod::RtkFloat => 5,
            FixMethod::DeadReckoning => 6,
            FixMethod::Manual => 7,
            FixMethod::Simulated => 8,
        }
    }

    /// The method of an NMEA 0183 mode indicator (RMC, GLL, VTG); `None` for
    /// `N` (not valid, handled by the caller) and unknown letters.
    pub fn from_mode(mode: u8) -> Option<FixMethod> {
        Some(match mode {
            b'A' => FixMethod::Gnss,
            b'D' => FixMethod::Dgnss,
            b'P' => FixMethod::Precise,
            b'R' => FixMethod::RtkFixed,
            b'F' => FixMethod::RtkFloat,
            b'E' => FixMethod::DeadReckoning,
            b'M' => FixMethod::Manual,
            b'S' => FixMethod::Simulated,
            _ => return None,
        })
    }

    /// How good a position this method gives, higher is better; used to pick
    /// a position source. Measured fixes rank above unknown (0), estimated,
    /// manual and simulated ones below it.
    pub fn rank(method: Option<FixMethod>) -> i8 {
        match method {
            Some(FixMethod::RtkFixed) => 5,
            Some(FixMethod::RtkFloat) => 4,
            Some(FixMethod::Precise) => 3,
            Some(FixMethod::Dgnss) => 2,
            Some(FixMethod::Gnss) => 1,
            None => 0,
            Some(FixMethod::DeadReckoning) => -1,
            Some(FixMethod::Manual) => -2,
            Some(FixMethod::Simulated) => -3,
        }
    }
}

/// A propeller thrust command from the project's JSON actuator messages.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThrustCommand {
    /// Time, seconds since the Unix epoch (UTC).
    pub time_s: f64,
    /// Port propeller thrust, N (positive ahead).
    pub port_n: f64,
    /// Starboard propeller thrust, N (positive ahead).
    pub starboard_n: f64,
}

/// One measurement, in SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Measurement {
    /// A position fix of a GNSS antenna.
    Position {
        /// Latitude, degrees, positive north, within [-90, 90].
        lat_deg: f64,
        /// Longitude, degrees, positive east, within [-180, 180].
        lon_deg: f64,
        /// Horizontal dilution of precision, when given and positive.
        hdop: Option<f64>,
        /// How the fix was made, when the message says.
        method: Option<FixMethod>,
        /// Height above the WGS-84 ellipsoid, m (GGA: altitude plus geoid
        /// separation, only when both are given).
        altitude_m: Option<f64>,
    },
    /// Course and speed over ground. The course is true; a magnetic course is
    /// never converted, it is rejected (`MagneticCourse`).
    CourseSpeed {
        /// Course over ground, rad clockwise from true north, [0, 2 pi).
        cog_rad: Option<f64>,
        /// Speed over ground, m/s, within [0, MAX_SPEED_MPS].
        sog_mps: Option<f64>,
    },
    /// True heading of the bow (a magnetic heading converted with a known
    /// variation), rad clockwise from north, [0, 2 pi).
    Heading {
        /// True heading, rad.
        heading_rad: f64,
    },
    /// Rate of turn, rad/s, positive turning to starboard.
    RateOfTurn {
        /// Rate of turn, rad/s.
        radps: f64,
    },
    /// Speed through water (log / paddle wheel), m/s.
    SpeedThroughWater {
        /// Speed through water, m/s, within [0, MAX_SPEED_MPS].
        mps: f64,
    },
    /// One propeller's shaft (or engine) speed.
    PropellerSpeed {
        /// Which propeller.
        side: Side,
        /// Shaft speed, rad/s, positive ahead.
        radps: f64,
    },
    /// An instrument's own estimate of the current (PGN 130577 set & drift).
    SetDrift {
        /// Direction the current flows toward, rad clockwise from true north.
        set_rad: f64,
        /// Current speed, m/s.
        drift_mps: f64,
    },
    /// Attitude (PGN 127257); each angle is absent when not available.
    Attitude {
        /// Yaw, rad, as sent (for a satellite compass: true heading, in
        /// [-pi, pi]).
        yaw_rad: Option<f64>,
        /// Pitch, rad, bow up positive.
        pitch_rad: Option<f64>,
        /// Roll, rad, starboard down positive.
        roll_rad: Option<f64>,
    },
    /// Body angular rates (Furuno PGN 130842 "six degrees of freedom").
    GyroRates {
        /// Roll rate, rad/s.
        roll_radps: Option<f64>,
        /// Pitch rate, rad/s.
        pitch_radps: Option<f64>,
        /// Yaw rate, rad/s.
        yaw_radps: Option<f64>,
    },
    /// A complete fix from the project's JSON messages (already validated).
    GnssFix(GnssFix),
    /// Both propeller speeds from the project's JSON actuator messages.
    Propellers(PropellerSpeeds),
    /// Both propeller thrusts from the project's JSON actuator messages.
    Thrust(ThrustCommand),
}

impl Measurement {
    /// The kind of this measurement (for counting).
    pub fn kind(&self) -> MeasurementKind {
        match self {
            Measurement::Position { .. } => MeasurementKind::Position,
            Measurement::CourseSpeed { .. } => MeasurementKind::CourseSpeed,
            Measurement::Heading { .. } => MeasurementKind::Heading,
            Measurement::RateOfTurn { .. } => MeasurementKind::RateOfTurn,
            Measurement::SpeedThroughWater { .. } => MeasurementKind::SpeedThroughWater,
            Measurement::PropellerSpeed { .. } => MeasurementKind::PropellerSpeed,
            Measurement::SetDrift { .. } => MeasurementKind::SetDrift,
            Measurement::Attitude { .. } => MeasurementKind::Attitude,
            Measurement::GyroRates { .. } => MeasurementKind::GyroRates,
            Measurement::GnssFix(_) => MeasurementKind::GnssFix,
            Measurement::Propellers(_) => MeasurementKind::Propellers,
            Measurement::Thrust(_) => MeasurementKind::Thrust,
        }
    }
}

/// The kinds of [`Measurement`], without their data.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum MeasurementKind {
    /// [`Measurement::Position`].
    Position,
    /// [`Measurement::CourseSpeed`].
    CourseSpeed,
    /// [`Measurement::Heading`].
    Heading,
    /// [`Measurement::RateOfTurn`].
    RateOfTurn,
    /// [`Measurement::SpeedThroughWater`].
    SpeedThroughWater,
    /// [`Measurement::PropellerSpeed`].
    PropellerSpeed,
    /// [`Measurement::SetDrift`].
    SetDrift,
    /// [`Measurement::Attitude`].
    Attitude,
    /// [`Measurement::GyroRates`].
    GyroRates,
    /// [`Measurement::GnssFix`].
    GnssFix,
    /// [`Measurement::Propellers`].
    Propellers,
    /// [`Measurement::Thrust`].
    Thrust,
}

impl MeasurementKind {
    /// Every kind, in declaration order.
    pub const ALL: [MeasurementKind; 12] = [
        MeasurementKind::Position,
        MeasurementKind::CourseSpeed,
        MeasurementKind::Heading,
        MeasurementKind::RateOfTurn,
        MeasurementKind::SpeedThroughWater,
        MeasurementKind::PropellerSpeed,
        MeasurementKind::SetDrift,
        MeasurementKind::Attitude,
        MeasurementKind::GyroRates,
        MeasurementKind::GnssFix,
        MeasurementKind::Propellers,
        MeasurementKind::Thrust,
    ];

    /// Index into [`Self::ALL`].
    pub fn index(self) -> usize {
        self as usize
    }

    /// snake_case name, for reports.
    pub fn name(self) -> &'static str {
        match self {
            MeasurementKind::Position => "position",
            MeasurementKind::CourseSpeed => "course_speed",
            MeasurementKind::Heading => "heading",
            MeasurementKind::RateOfTurn => "rate_of_turn",
            MeasurementKind::SpeedThroughWater => "speed_through_water",
            MeasurementKind::PropellerSpeed => "propeller_speed",
            MeasurementKind::SetDrift => "set_drift",
            MeasurementKind::Attitude => "attitude",
            MeasurementKind::GyroRates => "gyro_rates",
            MeasurementKind::GnssFix => "gnss_fix",
            MeasurementKind::Propellers => "propellers",
            MeasurementKind::Thrust => "thrust",
        }
    }
}

/// A time-stamped measurement from one source.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Record {
    /// Seconds since the Unix epoch, UTC.
    pub time_s: f64,
    /// Who sent it.
    pub source: Source,
    /// What was measured.
    pub measurement: Measurement,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sources_print_and_parse() {
        for s in [
            Source::N2k(25),
            Source::Json,
            Source::Nmea(Talker::new(*b"II").unwrap()),
            Source::Mavlink {
                system: 1,
                fused: false,
            },
            Source::Mavlink {
                system: 255,
                fused: true,
            },
            Source::Gpsd(0),
        ] {
            assert_eq!(s.to_string().parse::<Source>(), Ok(s));
        }
        assert_eq!(Source::N2k(52).to_string(), "n2k:52");
        assert_eq!(
            "mavlink:1:ekf".parse::<Source>(),
            Ok(Source::Mavlink {
                system: 1,
                fused: true
            })
        );
        for bad in [
            "n2k:256",
            "n2k:",
            "nmea:gp",
            "nmea:GPS",
            "JSON",
            "",
            "mavlink:",
            "mavlink:1:",
            "mavlink:256",
            "gpsd:x",
        ] {
            assert!(bad.parse::<Source>().is_err(), "{bad}");
        }
    }

    #[test]
    fn kinds_index_their_table() {
        for (i, k) in MeasurementKind::ALL.iter().enumerate() {
            assert_eq!(k.index(), i);
        }
    }

    #[test]
    fn fix_method_codes_round_trip_and_rank() {
        for code in 1..=8 {
            assert_eq!(
                FixMethod::from_code(code).map(|m| u64::from(m.code())),
                Some(code)
            );
        }
        assert_eq!(FixMethod::from_code(0), None);
        assert_eq!(FixMethod::from_code(15), None);
        assert!(
            FixMethod::rank(Some(FixMethod::RtkFixed)) > FixMethod::rank(Some(FixMethod::Dgnss))
        );
        assert!(FixMethod::rank(Some(FixMethod::Gnss)) > FixMethod::rank(None));
        assert!(FixMethod::rank(None) > FixMethod::rank(Some(FixMethod::DeadReckoning)));
    }
}
