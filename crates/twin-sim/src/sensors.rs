//! The simulated sensors: GNSS (position, SOG, COG), a heading sensor (HDT)
//! and the propeller shaft speeds, each with its own seeded random stream so
//! the output is the same for the same seed, and switching one sensor on or
//! off leaves the others' noise unchanged.
//!
//! # GNSS
//! The antenna sits at a lever arm `(x, y)` from the body origin (forward,
//! starboard), so its position is `p + R(psi) [x, y]` and its velocity
//! `v + R(psi) [-r y, r x]`. Position noise is added per axis (north, east),
//! white or first-order Gauss-Markov ("slowly correlated") with a stationary
//! standard deviation equal to the configured sigma. Velocity noise of
//! standard deviation `sog_sigma_mps` is added to each of the north and east
//! velocity components, and SOG and COG are computed from that noisy vector:
//! SOG noise then has the configured sigma and COG noise is about
//! `sog_sigma / SOG` rad, growing without bound as the craft stops, which is
//! why COG is not reported below `cog_min_sog_mps`. A SOG scale error
//! multiplies the reported SOG.
//!
//! A fix is stamped with the simulation's start time plus the true time of
//! its sample minus `latency_s`: a positive latency stamps a fix earlier than
//! the moment it describes, a negative one later (data older than its stamp,
//! the usual receiver delay). Fixes come out in stamp order with the other
//! events.

use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, StandardNormal};
use twin_core::geodesy::{LocalFrame, NorthEast, course_of, wrap_two_pi};
use twin_core::sample::{GnssFix, PropellerSpeeds, RADPS_PER_RPM};

/// One heading measurement (e.g. an NMEA HDT sentence).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeadingSample {
    /// Time stamp, seconds since the Unix epoch (UTC).
    pub time_s: f64,
    /// Reported true heading, rad clockwise from north, in [0, 2 pi).
    pub heading_rad: f64,
}

/// One output of the simulated sensors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SensorEvent {
    /// A GNSS fix (`heading_rad` is always `None`: heading comes separately).
    Gnss(GnssFix),
    /// A heading measurement.
    Heading(HeadingSample),
    /// Measured shaft speeds: the actual speeds plus noise.
    PropellerMeasured(PropellerSpeeds),
    /// Shaft speeds the autopilot commanded (no noise).
    PropellerCommanded(PropellerSpeeds),
    /// A rate gyro's yaw rate.
    YawRate(YawRateSample),
}

/// One yaw-rate measurement (a rate gyro, NMEA 0183 `ROT`, NMEA 2000 PGN
/// 127251).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct YawRateSample {
    /// Time stamp, seconds since the Unix epoch (UTC).
    pub time_s: f64,
    /// Reported yaw rate, rad/s (positive: bow to starboard).
    pub yaw_rate_radps: f64,
}

impl SensorEvent {
    /// The event's time stamp, seconds since the Unix epoch.
    pub fn time_s(&self) -> f64 {
        match self {
            SensorEvent::Gnss(f) => f.time_s,
            SensorEvent::Heading(h) => h.time_s,
            SensorEvent::PropellerMeasured(p) | SensorEvent::PropellerCommanded(p) => p.time_s,
            SensorEvent::YawRate(y) => y.time_s,
        }
    }
}

/// Converts a shaft speed to revolutions per minute.
pub fn radps_to_rpm(n_radps: f64) -> f64 {
    n_radps / RADPS_PER_RPM
}

/// Kinematic truth of the body origin the sensors sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct BodyMotion {
    pub north_m: f64,
    pub east_m: f64,
    pub psi_rad: f64,
    pub u_mps: f64,
    pub v_mps: f64,
    pub r_radps: f64,
}

impl BodyMotion {
    /// Position and velocity (north, east) of a point at body `(x, y)`.
    pub fn point(&self, x_m: f64, y_m: f64) -> ([f64; 2], [f64; 2]) {
        let (s, c) = self.psi_rad.sin_cos();
        let pos = [
            self.north_m + c * x_m - s * y_m,
            self.east_m + s * x_m + c * y_m,
        ];
        // Body velocity of the point: [u - r y, v + r x].
        let bu = self.u_mps - self.r_radps * y_m;
        let bv = self.v_mps + self.r_radps * x_m;
        let vel = [c * bu - s * bv, s * bu + c * bv];
        (pos, vel)
    }
}

/// Validated GNSS settings, SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct GnssSettings {
    pub period_s: f64,
    pub position_sigma_m: f64,
    pub position_correlation_s: f64,
    pub sog_sigma_mps: f64,
    pub cog_min_sog_mps: f64,
    pub latency_s: f64,
    pub lever_arm_m: [f64; 2],
    pub sog_scale: f64,
    pub hdop: Option<f64>,
}

/// Streams of the seeded generator, one per sensor.
pub(crate) const STREAM_GNSS: u64 = 0x9E37_79B9_7F4A_7C15;
pub(crate) const STREAM_HEADING: u64 = 0xC2B2_AE3D_27D4_EB4F;
pub(crate) const STREAM_PROPELLERS: u64 = 0x1656_67B1_9E37_79F9;
pub(crate) const STREAM_YAW_RATE: u64 = 0x27D4_EB2F_1656_67C5;

fn stream(seed: u64, salt: u64) -> StdRng {
    StdRng::seed_from_u64(seed ^ salt)
}

fn gaussian(rng: &mut StdRng) -> f64 {
    StandardNormal.sample(rng)
}

/// The GNSS receiver.
#[derive(Debug, Clone)]
pub(crate) struct GnssSensor {
    settings: GnssSettings,
    rng: StdRng,
    /// Correlated position error (north, east), m; `None` before the first fix.
    position_error_m: Option<[f64; 2]>,
}

impl GnssSensor {
    pub fn new(settings: GnssSettings, seed: u64) -> Self {
        Self {
            settings,
            rng: stream(seed, STREAM_GNSS),
            position_error_m: None,
        }
    }

    fn next_position_error(&mut self) -> [f64; 2] {
        let sigma = self.settings.position_sigma_m;
        let fresh = [
            sigma * gaussian(&mut self.rng),
            sigma * gaussian(&mut self.rng),
        ];
        let tau = self.settings.position_correlation_s;
        let error = match self.position_error_m {
            Some(prev) if tau > 0.0 => {
                // First-order Gauss-Markov, stationary standard deviation sigma.
                let a = (-self.settings.period_s / tau).exp();
                let b = (1.0 - a * a).sqrt();
                [a * prev[0] + b * fresh[0], a * prev[1] + b * fresh[1]]
            }
            _ => fresh,
        };
        self.position_error_m = Some(error);
        error
    }

    /// A fix of the craft as it is at elapsed time `elapsed_s`.
    pub fn sample(
        &mut self,
        elapsed_s: f64,
        start_unix_s: f64,
        body: &BodyMotion,
        frame: &LocalFrame,
    ) -> GnssFix {
        let s = self.settings;
        let (pos, vel) = body.point(s.lever_arm_m[0], s.lever_arm_m[1]);
        let err = self.next_position_error();
        let position = frame.to_geodetic(NorthEast {
            north_m: pos[0] + err[0],
            east_m: pos[1] + err[1],
        });
        let vn = vel[0] + s.sog_sigma_mps * gaussian(&mut self.rng);
        let ve = vel[1] + s.sog_sigma_mps * gaussian(&mut self.rng);
        let speed = vn.hypot(ve);
        let cog = (speed >= s.cog_min_sog_mps).then(|| course_of(vn, ve));
        GnssFix {
            time_s: start_unix_s + elapsed_s - s.latency_s,
            position,
            sog_mps: Some(s.sog_scale * speed),
            cog_rad: cog,
            heading_rad: None,
            yaw_rate_radps: None,
            hdop: s.hdop,
        }
    }
}

/// Validated heading-sensor settings, SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct HeadingSettings {
    pub period_s: f64,
    pub sigma_rad: f64,
    pub offset_rad: f64,
}

/// A heading sensor with white noise and a constant offset.
#[derive(Debug, Clone)]
pub(crate) struct HeadingSensor {
    settings: HeadingSettings,
    rng: StdRng,
}

impl HeadingSensor {
    pub fn new(settings: HeadingSettings, seed: u64) -> Self {
        Self {
            settings,
            rng: stream(seed, STREAM_HEADING),
        }
    }

    pub fn sample(&mut self, elapsed_s: f64, start_unix_s: f64, psi_rad: f64) -> HeadingSample {
        let noise = self.settings.sigma_rad * gaussian(&mut self.rng);
        HeadingSample {
            time_s: start_unix_s + elapsed_s,
            heading_rad: wrap_two_pi(psi_rad + self.settings.offset_rad + noise),
        }
    }
}

/// Validated propeller-sensor settings, SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct PropellerSettings {
    pub period_s: f64,
    pub sigma_radps: f64,
}

/// Tachometers on both shafts, with white noise.
#[derive(Debug, Clone)]
pub(crate) struct PropellerSensor {
    settings: PropellerSettings,
    rng: StdRng,
}

impl PropellerSensor {
    pub fn new(settings: PropellerSettings, seed: u64) -> Self {
        Self {
            settings,
            rng: stream(seed, STREAM_PROPELLERS),
        }
    }

    pub fn sample(
        &mut self,
        elapsed_s: f64,
        start_unix_s: f64,
        shafts_radps: [f64; 2],
    ) -> PropellerSpeeds {
        let sigma = self.settings.sigma_radps;
        PropellerSpeeds {
            time_s: start_unix_s + elapsed_s,
            port_radps: shafts_radps[0] + sigma * gaussian(&mut self.rng),
            starboard_radps: shafts_radps[1] + sigma * gaussian(&mut self.rng),
        }
    }
}

/// Validated rate-gyro settings, SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct YawRateSettings {
    pub period_s: f64,
    pub sigma_radps: f64,
    pub bias_radps: f64,
    pub scale: f64,
}

/// A rate gyro with a scale factor, white noise and a constant bias.
#[derive(Debug, Clone)]
pub(crate) struct YawRateSensor {
    settings: YawRateSettings,
    rng: StdRng,
}

impl YawRateSensor {
    pub fn new(settings: YawRateSettings, seed: u64) -> Self {
        Self {
            settings,
            rng: stream(seed, STREAM_YAW_RATE),
        }
    }

    pub fn sample(&mut self, elapsed_s: f64, start_unix_s: f64, r_radps: f64) -> YawRateSample {
        let noise = self.settings.sigma_radps * gaussian(&mut self.rng);
        YawRateSample {
            time_s: start_unix_s + elapsed_s,
            yaw_rate_radps: self.settings.scale * r_radps + self.settings.bias_radps + noise,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lever_arm_point_moves_with_the_turning_hull() {
        let body = BodyMotion {
            north_m: 10.0,
            east_m: 20.0,
            psi_rad: std::f64::consts::FRAC_PI_2,
            u_mps: 1.0,
            v_mps: 0.0,
            r_radps: 0.5,
        };
        // Heading east: 1 m forward is 1 m east; 1 m to starboard is 1 m south.
        let (pos, vel) = body.point(1.0, 1.0);
        assert!((pos[0] - 9.0).abs() < 1e-12 && (pos[1] - 21.0).abs() < 1e-12);
        // Body velocity of the point: [u - r y, v + r x] = [0.5, 0.5]
        // -> east 0.5, south 0.5.
        assert!(
            (vel[0] + 0.5).abs() < 1e-12 && (vel[1] - 0.5).abs() < 1e-12,
            "{vel:?}"
        );
    }

    #[test]
    fn rpm_conversion() {
        assert!((radps_to_rpm(103.9) - 992.2).abs() < 0.1);
    }
}
