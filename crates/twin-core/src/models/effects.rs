//! Sensor-side effects a model's measurement can include: where the GNSS
//! antenna sits, a heading sensor's offset, a scale error of the reported
//! speed over ground, GNSS latency, and a scale error and a bias of the rate
//! sensor's yaw rate. They are the measurement half of
//! `twin diagnose`'s catalogue of causes (the other half, the water current
//! and the propellers' losses, are states and faults of the models).
//!
//! All effects default to none, and then the models use their exact
//! analytic Jacobians. With effects the measurement is
//!
//! ```text
//! position = p + R(psi) a - L v            (antenna a in the body frame, latency L)
//! velocity = v + R(psi) (r x a)            (the antenna swings with the yaw rate)
//! SOG      = s |velocity|                  (scale s)
//! COG      = atan2(velocity) - L r         (the course L seconds ago)
//! heading  = psi + d                       (offset d)
//! yaw rate = g r + b                       (rate sensor's scale g, bias b)
//! ```
//!
//! to first order in `L`, and its Jacobian is taken numerically (central
//! differences): these runs are offline and a few.

/// Effects on the measurement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorEffects {
    /// GNSS antenna position in the body frame, `[forward, starboard]`, m.
    pub antenna_m: [f64; 2],
    /// Heading sensor reading minus the true heading, rad.
    pub heading_offset_rad: f64,
    /// Reported speed over ground divided by the true one.
    pub sog_scale: f64,
    /// GNSS data describe the vessel this long before their time stamps, s.
    pub gnss_latency_s: f64,
    /// The rate sensor's yaw rate divided by the true one (a gyro's scale
    /// factor error, or a rate of turn damped by its sensor).
    pub yaw_rate_scale: f64,
    /// The rate sensor's reading at rest, rad/s (a gyro's bias, a rate of
    /// turn's zero offset).
    pub yaw_rate_bias_radps: f64,
}

impl Default for SensorEffects {
    fn default() -> Self {
        Self {
            antenna_m: [0.0, 0.0],
            heading_offset_rad: 0.0,
            sog_scale: 1.0,
            gnss_latency_s: 0.0,
            yaw_rate_scale: 1.0,
            yaw_rate_bias_radps: 0.0,
        }
    }
}

impl SensorEffects {
    /// True when there is no effect (the models then use analytic Jacobians).
    pub fn is_neutral(&self) -> bool {
        *self == Self::default()
    }

    /// What the rate sensor reads at the true yaw rate `yaw_rate_radps`.
    pub fn yaw_rate_reading(&self, yaw_rate_radps: f64) -> f64 {
        self.yaw_rate_scale * yaw_rate_radps + self.yaw_rate_bias_radps
    }

    /// The true yaw rate that makes the rate sensor read `reading_radps`.
    pub fn yaw_rate_of_reading(&self, reading_radps: f64) -> f64 {
        (reading_radps - self.yaw_rate_bias_radps) / self.yaw_rate_scale
    }
}

/// What a measurement depends on, at the body origin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Kinematics {
    /// North, m.
    pub north_m: f64,
    /// East, m.
    pub east_m: f64,
    /// Heading, rad.
    pub heading_rad: f64,
    /// Yaw rate, rad/s.
    pub yaw_rate_radps: f64,
    /// Velocity over ground, north, m/s.
    pub ground_north_mps: f64,
    /// Velocity over ground, east, m/s.
    pub ground_east_mps: f64,
}

/// The measurement `[north, east, SOG, COG, heading]` of `k` with `fx`.
pub fn gnss_measurement(k: &Kinematics, fx: &SensorEffects) -> [f64; 5] {
    let (s, c) = crate::trig::sin_cos(k.heading_rad);
    let [ax, ay] = fx.antenna_m;
    // Antenna offset and its velocity from the yaw rate, in north/east.
    let off_n = c * ax - s * ay;
    let off_e = s * ax + c * ay;
    let r = k.yaw_rate_radps;
    let (bx, by) = (-r * ay, r * ax);
    let vn = k.ground_north_mps + c * bx - s * by;
    let ve = k.ground_east_mps + s * bx + c * by;
    let l = fx.gnss_latency_s;
    [
        k.north_m + off_n - l * vn,
        k.east_m + off_e - l * ve,
        fx.sog_scale * vn.hypot(ve),
        ve.atan2(vn) - l * r,
        k.heading_rad + fx.heading_offset_rad,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn k() -> Kinematics {
        Kinematics {
            north_m: 10.0,
            east_m: 5.0,
            heading_rad: std::f64::consts::FRAC_PI_2,
            yaw_rate_radps: 0.1,
            ground_north_mps: 0.0,
            ground_east_mps: 2.0,
        }
    }

    #[test]
    fn neutral_effects_measure_the_state_itself() {
        let m = gnss_measurement(&k(), &SensorEffects::default());
        assert_eq!(m[0], 10.0);
        assert_eq!(m[1], 5.0);
        assert!((m[2] - 2.0).abs() < 1e-12);
        assert!((m[3] - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    }

    #[test]
    fn each_effect_does_what_it_says() {
        // Heading east: an antenna 1 m forward is 1 m east; 1 m to starboard is
        // 1 m south. Turning to starboard at 0.1 rad/s, the forward antenna
        // moves 0.1 m/s to starboard (south).
        let fx = SensorEffects {
            antenna_m: [1.0, 0.0],
            ..Default::default()
        };
        let m = gnss_measurement(&k(), &fx);
        assert!((m[1] - 6.0).abs() < 1e-12 && (m[0] - 10.0).abs() < 1e-12);
        assert!((m[2] - (2.0f64.powi(2) + 0.1f64.powi(2)).sqrt()).abs() < 1e-12);
        assert!(
            m[3] > std::f64::consts::FRAC_PI_2,
            "course swings to starboard: {}",
            m[3]
        );
        let fx = SensorEffects {
            antenna_m: [0.0, 1.0],
            ..Default::default()
        };
        assert!((gnss_measurement(&k(), &fx)[0] - 9.0).abs() < 1e-12);
        // Latency: the fix is where the vessel was 0.5 s ago, 1 m back west.
        let fx = SensorEffects {
            gnss_latency_s: 0.5,
            ..Default::default()
        };
        let m = gnss_measurement(&k(), &fx);
        assert!((m[1] - 4.0).abs() < 1e-12);
        assert!((m[3] - (std::f64::consts::FRAC_PI_2 - 0.05)).abs() < 1e-12);
        let fx = SensorEffects {
            sog_scale: 1.05,
            heading_offset_rad: 0.1,
            ..Default::default()
        };
        let m = gnss_measurement(&k(), &fx);
        assert!(
            (m[2] - 2.1).abs() < 1e-12 && (m[4] - std::f64::consts::FRAC_PI_2 - 0.1).abs() < 1e-12
        );
        assert!(!fx.is_neutral() && SensorEffects::default().is_neutral());
    }

    #[test]
    fn the_rate_sensors_reading_is_scaled_and_biased_and_inverts() {
        let fx = SensorEffects {
            yaw_rate_scale: 0.96,
            yaw_rate_bias_radps: 0.01,
            ..Default::default()
        };
        assert!((fx.yaw_rate_reading(0.1) - 0.106).abs() < 1e-15);
        assert!((fx.yaw_rate_of_reading(fx.yaw_rate_reading(-0.2)) + 0.2).abs() < 1e-15);
        assert_eq!(SensorEffects::default().yaw_rate_reading(0.1), 0.1);
        assert!(!fx.is_neutral());
    }
}
