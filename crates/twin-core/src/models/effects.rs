//! Sensor-side effects a model's measurement can include: where the GNSS
//! antenna sits, a heading sensor's offset, a scale error of the reported
//! speed over ground, GNSS latency, and a scale error and a bias of the rate
//! sensor's yaw rate. They are the measurement half of
//! `twin diagnose`'s catalogue of causes (the other half, the water current
//! and the propellers' losses, are states and faults of the models).
//!
//! All effects default to none (the measurement is then the state's own
//! position, speed, course and heading). With effects the measurement is
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
//! to first order in `L`. [`gnss_measurement_linearised`] gives it with
//! its Jacobian with respect to the [`Kinematics`], analytically, with
//! effects or without; [`gnss_measurement_of_body`] chains that through
//! the ground velocity to a hull's [`BodyMotion`] (position, heading,
//! velocities through the water, yaw rate, current), and each model maps
//! its columns onto its own states. Forward differences would take eleven
//! evaluations of the measurement a step, about a fifth of a diagnosis
//! with a rate gyro.

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
    /// True when there is no effect (the observation Jacobian then keeps to
    /// the sparser pattern of a measurement without effects).
    pub fn is_neutral(&self) -> bool {
        *self == Self::default()
    }

    /// These effects with their antenna offset (a lever arm, as diagnose
    /// searches it) taken from the profile's antenna at `profile_antenna_m`
    /// `[forward, starboard]`, m: the antenna the model measures at.
    pub fn with_antenna_from(mut self, profile_antenna_m: [f64; 2]) -> Self {
        for (arm, profile) in self.antenna_m.iter_mut().zip(profile_antenna_m) {
            *arm += profile;
        }
        self
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
    gnss_measurement_linearised(k, fx).0
}

/// The columns of [`gnss_measurement_linearised`]'s Jacobian: the
/// [`Kinematics`] fields in their declared order.
pub mod kin {
    /// [`super::Kinematics::north_m`].
    pub const NORTH: usize = 0;
    /// [`super::Kinematics::east_m`].
    pub const EAST: usize = 1;
    /// [`super::Kinematics::heading_rad`].
    pub const HEADING: usize = 2;
    /// [`super::Kinematics::yaw_rate_radps`].
    pub const YAW_RATE: usize = 3;
    /// [`super::Kinematics::ground_north_mps`].
    pub const GROUND_NORTH: usize = 4;
    /// [`super::Kinematics::ground_east_mps`].
    pub const GROUND_EAST: usize = 5;
}

/// Below this speed over ground, m/s, the derivatives of the speed and
/// course are taken as at this speed: the course of a vessel at rest has no
/// derivative.
pub const MIN_SOG_FOR_DERIVATIVES_MPS: f64 = 1e-3;

/// [`gnss_measurement`] and its Jacobian with respect to `k`'s fields
/// (rows the five measurements, columns [`kin`]).
///
/// With the antenna's offset `o = R(psi) a` (north `o_n`, east `o_e`), the
/// antenna's velocity is `v_n = g_n - r o_e`, `v_e = g_e + r o_n`, and
/// `d o_n / d psi = -o_e`, `d o_e / d psi = o_n`: every derivative follows
/// from these and the chain rule.
#[inline]
pub fn gnss_measurement_linearised(
    k: &Kinematics,
    fx: &SensorEffects,
) -> ([f64; 5], [[f64; 6]; 5]) {
    use kin::*;
    let (s, c) = crate::trig::sin_cos(k.heading_rad);
    let [ax, ay] = fx.antenna_m;
    let off_n = c * ax - s * ay;
    let off_e = s * ax + c * ay;
    let r = k.yaw_rate_radps;
    let vn = k.ground_north_mps - r * off_e;
    let ve = k.ground_east_mps + r * off_n;
    let l = fx.gnss_latency_s;
    // Speeds are far from overflow: no need of `hypot`'s scaling.
    let sog = (vn * vn + ve * ve).sqrt();
    let measured = [
        k.north_m + off_n - l * vn,
        k.east_m + off_e - l * ve,
        fx.sog_scale * sog,
        ve.atan2(vn) - l * r,
        k.heading_rad + fx.heading_offset_rad,
    ];
    let safe = sog.max(MIN_SOG_FOR_DERIVATIVES_MPS);
    // The speed and course against the antenna's velocity ...
    let (sog_vn, sog_ve) = (fx.sog_scale * vn / safe, fx.sog_scale * ve / safe);
    let (cog_vn, cog_ve) = (-ve / (safe * safe), vn / (safe * safe));
    // ... and the antenna's velocity against heading and yaw rate (against
    // the ground velocity: the identity).
    let (dvn_dpsi, dve_dpsi) = (-r * off_n, -r * off_e);
    let (dvn_dr, dve_dr) = (-off_e, off_n);
    let mut jacobian = [[0.0; 6]; 5];
    jacobian[0][NORTH] = 1.0;
    jacobian[0][HEADING] = -off_e - l * dvn_dpsi;
    jacobian[0][YAW_RATE] = -l * dvn_dr;
    jacobian[0][GROUND_NORTH] = -l;
    jacobian[1][EAST] = 1.0;
    jacobian[1][HEADING] = off_n - l * dve_dpsi;
    jacobian[1][YAW_RATE] = -l * dve_dr;
    jacobian[1][GROUND_EAST] = -l;
    jacobian[2][HEADING] = sog_vn * dvn_dpsi + sog_ve * dve_dpsi;
    jacobian[2][YAW_RATE] = sog_vn * dvn_dr + sog_ve * dve_dr;
    jacobian[2][GROUND_NORTH] = sog_vn;
    jacobian[2][GROUND_EAST] = sog_ve;
    jacobian[3][HEADING] = cog_vn * dvn_dpsi + cog_ve * dve_dpsi;
    jacobian[3][YAW_RATE] = cog_vn * dvn_dr + cog_ve * dve_dr - l;
    jacobian[3][GROUND_NORTH] = cog_vn;
    jacobian[3][GROUND_EAST] = cog_ve;
    jacobian[4][HEADING] = 1.0;
    (measured, jacobian)
}

/// A hull's motion as the models' states hold it: the body origin's
/// position, the heading, the velocities through the water in the body
/// frame, the yaw rate and the current over the ground.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyMotion {
    /// North, m.
    pub north_m: f64,
    /// East, m.
    pub east_m: f64,
    /// Heading, rad.
    pub heading_rad: f64,
    /// Surge velocity through the water, m/s.
    pub surge_mps: f64,
    /// Sway velocity through the water, m/s.
    pub sway_mps: f64,
    /// Yaw rate, rad/s.
    pub yaw_rate_radps: f64,
    /// Current over the ground, north, m/s.
    pub current_north_mps: f64,
    /// Current over the ground, east, m/s.
    pub current_east_mps: f64,
}

/// The columns of [`gnss_measurement_of_body`]'s Jacobian: the
/// [`BodyMotion`] fields in their declared order.
pub mod body {
    /// [`super::BodyMotion::north_m`].
    pub const NORTH: usize = 0;
    /// [`super::BodyMotion::east_m`].
    pub const EAST: usize = 1;
    /// [`super::BodyMotion::heading_rad`].
    pub const HEADING: usize = 2;
    /// [`super::BodyMotion::surge_mps`].
    pub const SURGE: usize = 3;
    /// [`super::BodyMotion::sway_mps`].
    pub const SWAY: usize = 4;
    /// [`super::BodyMotion::yaw_rate_radps`].
    pub const YAW_RATE: usize = 5;
    /// [`super::BodyMotion::current_north_mps`].
    pub const CURRENT_NORTH: usize = 6;
    /// [`super::BodyMotion::current_east_mps`].
    pub const CURRENT_EAST: usize = 7;
}

/// [`gnss_measurement_linearised`] of a hull's motion, its Jacobian chained
/// through the ground velocity `g = R(psi) [u, v] + current` (rows the five
/// measurements, columns [`body`]). Each model maps the columns onto its
/// states: the kinetic model holds every field as a state, the water
/// model's sway is its sideslip times the yaw rate.
#[inline]
pub fn gnss_measurement_of_body(b: &BodyMotion, fx: &SensorEffects) -> ([f64; 5], [[f64; 8]; 5]) {
    let (s, c) = crate::trig::sin_cos(b.heading_rad);
    let (u, v) = (b.surge_mps, b.sway_mps);
    let k = Kinematics {
        north_m: b.north_m,
        east_m: b.east_m,
        heading_rad: b.heading_rad,
        yaw_rate_radps: b.yaw_rate_radps,
        ground_north_mps: c * u - s * v + b.current_north_mps,
        ground_east_mps: s * u + c * v + b.current_east_mps,
    };
    let (m, dm_dk) = gnss_measurement_linearised(&k, fx);
    let dgn_dpsi = -s * u - c * v;
    let dge_dpsi = c * u - s * v;
    let mut jacobian = [[0.0; 8]; 5];
    for (row, dm) in jacobian.iter_mut().zip(dm_dk.iter()) {
        let (dgn, dge) = (dm[kin::GROUND_NORTH], dm[kin::GROUND_EAST]);
        row[body::NORTH] = dm[kin::NORTH];
        row[body::EAST] = dm[kin::EAST];
        row[body::HEADING] = dm[kin::HEADING] + dgn * dgn_dpsi + dge * dge_dpsi;
        row[body::SURGE] = dgn * c + dge * s;
        row[body::SWAY] = dge * c - dgn * s;
        row[body::YAW_RATE] = dm[kin::YAW_RATE];
        row[body::CURRENT_NORTH] = dgn;
        row[body::CURRENT_EAST] = dge;
    }
    (m, jacobian)
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

    /// The analytic Jacobian agrees with central differences of
    /// [`gnss_measurement`] with every effect on, turning and straight,
    /// and its measurement is [`gnss_measurement`]'s.
    #[test]
    fn the_linearised_measurement_matches_central_differences() {
        let fx = SensorEffects {
            antenna_m: [0.7, -0.4],
            heading_offset_rad: 0.05,
            sog_scale: 1.03,
            gnss_latency_s: 0.3,
            yaw_rate_scale: 0.97,
            yaw_rate_bias_radps: 0.002,
        };
        for (heading_rad, yaw_rate_radps) in [(0.3, 0.12), (-2.9, -0.05), (1.2, 0.0)] {
            let base = Kinematics {
                heading_rad,
                yaw_rate_radps,
                ground_north_mps: 1.1,
                ground_east_mps: -0.6,
                ..k()
            };
            let (_, jac) = gnss_measurement_linearised(&base, &fx);
            fn field(k: &mut Kinematics, j: usize) -> &mut f64 {
                match j {
                    kin::NORTH => &mut k.north_m,
                    kin::EAST => &mut k.east_m,
                    kin::HEADING => &mut k.heading_rad,
                    kin::YAW_RATE => &mut k.yaw_rate_radps,
                    kin::GROUND_NORTH => &mut k.ground_north_mps,
                    _ => &mut k.ground_east_mps,
                }
            }
            let h = 1e-6;
            for j in 0..6 {
                let (mut up, mut down) = (base, base);
                *field(&mut up, j) += h;
                *field(&mut down, j) -= h;
                let (mu, md) = (gnss_measurement(&up, &fx), gnss_measurement(&down, &fx));
                for (i, row) in jac.iter().enumerate() {
                    let numeric = (mu[i] - md[i]) / (2.0 * h);
                    assert!(
                        (numeric - row[j]).abs() < 1e-7,
                        "d m{i} / d k{j}: {} analytic, {numeric} numeric",
                        row[j]
                    );
                }
            }
        }
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
