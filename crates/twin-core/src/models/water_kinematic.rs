//! A kinematic model of any vessel moving through water, for logs without
//! propeller data (`twin diagnose` on real logs): it needs no vessel
//! parameters, and it separates the vessel's motion through the water from
//! the water's motion over ground.
//!
//! State `[north_m, east_m, heading_rad, speed_through_water_mps,
//! yaw_rate_radps, current_north_mps, current_east_mps]`; speed and yaw rate
//! wander as random walks (the vessel's own manoeuvres, whatever drives
//! them), the current is constant up to a slow random walk. The model with
//! the current held at zero (zero initial variance and zero process noise on
//! it) is the nominal one. Measurement `[north_m, east_m, sog_mps, cog_rad,
//! heading_rad, stw_mps, yaw_rate_radps]`, any of them missing, with the
//! sensor effects of [`crate::models::effects`] and a scale on the speed
//! through water; the yaw rate (a rate gyro or rate-of-turn sensor)
//! measures the state's own.
//!
//! ```text
//! north' = u cos(psi) - v sin(psi) + c_n,  east' = u sin(psi) + v cos(psi) + c_e,
//! psi' = r,  u' = r' = c' = 0 (+ noise),   v = (k + k_u u) r (sideslip, 0 nominally)
//! ```
//! The sideslip has two shapes: `k` a sway per yaw rate at any speed (a
//! hull whose hydrodynamic forces grow with speed as its centripetal force
//! does, so that its drift in a turn of a given rate does not), and `k_u`
//! a drift angle per yaw rate (`v / u = k_u r`: a hull whose damping does
//! not grow with speed, as the Otter's linear damping, drifts in
//! proportion to the centripetal force `u r`).
//! integrated over a step with the heading at the step's midpoint.

use nalgebra::{SMatrix, SVector};

use crate::geodesy::wrap_pi;
use crate::model::{Model, Observation, Transition};
use crate::models::effects::{BodyMotion, SensorEffects, body, gnss_measurement_of_body};
use crate::trig;

/// Index of each state component.
pub mod idx {
    /// North, m.
    pub const NORTH: usize = 0;
    /// East, m.
    pub const EAST: usize = 1;
    /// Heading, rad.
    pub const PSI: usize = 2;
    /// Speed through the water along the heading, m/s.
    pub const U: usize = 3;
    /// Yaw rate, rad/s.
    pub const R: usize = 4;
    /// Current, north component, m/s.
    pub const CURRENT_NORTH: usize = 5;
    /// Current, east component, m/s.
    pub const CURRENT_EAST: usize = 6;
}

/// Index of each measurement component.
pub mod meas {
    /// North, m.
    pub const NORTH: usize = 0;
    /// East, m.
    pub const EAST: usize = 1;
    /// Speed over ground, m/s.
    pub const SOG: usize = 2;
    /// Course over ground, rad.
    pub const COG: usize = 3;
    /// Heading, rad.
    pub const HEADING: usize = 4;
    /// Speed through water, m/s.
    pub const STW: usize = 5;
    /// Yaw rate from a rate gyro or rate-of-turn sensor, rad/s.
    pub const YAW_RATE: usize = 6;
}

/// Number of measurement components.
pub const MEASUREMENTS: usize = 7;

/// The model. It has no faults (`P = 0`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WaterKinematic {
    /// Effects on the GNSS and heading measurement.
    pub effects: SensorEffects,
    /// Reported speed through water divided by the true one (a log's
    /// calibration; 1 = none).
    pub stw_scale: f64,
    /// Sideways speed of the reference point per yaw rate, m/s per rad/s:
    /// in a turn a hull slides (its course through the water leaves its
    /// heading in proportion to the turn rate). 0 = none.
    pub sideslip_m: f64,
    /// Sideways speed of the reference point per yaw rate and speed
    /// through water, s (a drift angle per yaw rate: the sway is this times
    /// `u r`). 0 = none.
    pub sideslip_per_speed_s: f64,
}

impl WaterKinematic {
    /// The sway of state `x` and its derivatives in the speed through
    /// water and the yaw rate, `(v, dv/du, dv/dr)`.
    fn sway(&self, x: &SVector<f64, 7>) -> (f64, f64, f64) {
        let (u, r) = (x[idx::U], x[idx::R]);
        let per_r = self.sideslip_m + self.sideslip_per_speed_s * u;
        (per_r * r, self.sideslip_per_speed_s * r, per_r)
    }
}

impl Default for WaterKinematic {
    fn default() -> Self {
        Self {
            effects: SensorEffects::default(),
            stw_scale: 1.0,
            sideslip_m: 0.0,
            sideslip_per_speed_s: 0.0,
        }
    }
}

impl Model<7, MEASUREMENTS, 0> for WaterKinematic {
    type Input = ();

    fn transition(
        &self,
        x: &SVector<f64, 7>,
        _input: &(),
        _theta: &SVector<f64, 0>,
        dt_s: f64,
    ) -> Transition<7, 0> {
        let (psi, u, r) = (x[idx::PSI], x[idx::U], x[idx::R]);
        let (v, dv_du, dv_dr) = self.sway(x);
        let mid = psi + 0.5 * r * dt_s;
        let (s, c) = trig::sin_cos(mid);
        let mut next = *x;
        next[idx::NORTH] += dt_s * (u * c - v * s + x[idx::CURRENT_NORTH]);
        next[idx::EAST] += dt_s * (u * s + v * c + x[idx::CURRENT_EAST]);
        next[idx::PSI] = wrap_pi(psi + r * dt_s);
        // Derivatives through the midpoint heading (d mid / d psi = 1,
        // d mid / d r = dt/2) and the sideslip's sway.
        let dn_dmid = -u * s - v * c;
        let de_dmid = u * c - v * s;
        let mut f = SMatrix::<f64, 7, 7>::identity();
        f[(idx::NORTH, idx::PSI)] = dt_s * dn_dmid;
        f[(idx::NORTH, idx::U)] = dt_s * (c - dv_du * s);
        f[(idx::NORTH, idx::R)] = dt_s * (dn_dmid * 0.5 * dt_s - dv_dr * s);
        f[(idx::NORTH, idx::CURRENT_NORTH)] = dt_s;
        f[(idx::EAST, idx::PSI)] = dt_s * de_dmid;
        f[(idx::EAST, idx::U)] = dt_s * (s + dv_du * c);
        f[(idx::EAST, idx::R)] = dt_s * (de_dmid * 0.5 * dt_s + dv_dr * c);
        f[(idx::EAST, idx::CURRENT_EAST)] = dt_s;
        f[(idx::PSI, idx::R)] = dt_s;
        Transition {
            next,
            jacobian: f,
            fault_sensitivity: SMatrix::zeros(),
        }
    }

    fn observe(&self, x: &SVector<f64, 7>) -> Observation<7, MEASUREMENTS> {
        // The sideslip's sway, v = (k + k_u u) r.
        let (sway_mps, dv_du, dv_dr) = self.sway(x);
        let motion = BodyMotion {
            north_m: x[idx::NORTH],
            east_m: x[idx::EAST],
            heading_rad: x[idx::PSI],
            surge_mps: x[idx::U],
            sway_mps,
            yaw_rate_radps: x[idx::R],
            current_north_mps: x[idx::CURRENT_NORTH],
            current_east_mps: x[idx::CURRENT_EAST],
        };
        let (m, dm_db) = gnss_measurement_of_body(&motion, &self.effects);
        let mut jacobian = SMatrix::<f64, MEASUREMENTS, 7>::zeros();
        for (row, dm) in dm_db.iter().enumerate() {
            jacobian[(row, idx::NORTH)] = dm[body::NORTH];
            jacobian[(row, idx::EAST)] = dm[body::EAST];
            jacobian[(row, idx::PSI)] = dm[body::HEADING];
            jacobian[(row, idx::U)] = dm[body::SURGE] + dv_du * dm[body::SWAY];
            jacobian[(row, idx::R)] = dm[body::YAW_RATE] + dv_dr * dm[body::SWAY];
            jacobian[(row, idx::CURRENT_NORTH)] = dm[body::CURRENT_NORTH];
            jacobian[(row, idx::CURRENT_EAST)] = dm[body::CURRENT_EAST];
        }
        jacobian[(meas::STW, idx::U)] = self.stw_scale;
        jacobian[(meas::YAW_RATE, idx::R)] = self.effects.yaw_rate_scale;
        let predicted = SVector::<f64, MEASUREMENTS>::from_column_slice(&[
            m[0],
            m[1],
            m[2],
            m[3],
            m[4],
            self.stw_scale * x[idx::U],
            self.effects.yaw_rate_reading(x[idx::R]),
        ]);
        Observation {
            predicted,
            jacobian,
        }
    }

    fn measurement_angles(&self) -> [bool; MEASUREMENTS] {
        [false, false, false, true, true, false, false]
    }

    fn state_angles(&self) -> [bool; 7] {
        [false, false, true, false, false, false, false]
    }

    fn state_names(&self) -> [&'static str; 7] {
        [
            "north_m",
            "east_m",
            "heading_rad",
            "speed_through_water_mps",
            "yaw_rate_radps",
            "current_north_mps",
            "current_east_mps",
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `H` agrees with central differences of the measurement, with both
    /// sideslips and every sensor effect on.
    #[test]
    fn observation_jacobian_matches_finite_differences() {
        let m = WaterKinematic {
            effects: SensorEffects {
                antenna_m: [-1.2, 0.5],
                heading_offset_rad: -0.03,
                sog_scale: 1.02,
                gnss_latency_s: 0.25,
                yaw_rate_scale: 0.95,
                yaw_rate_bias_radps: -0.002,
            },
            stw_scale: 0.9,
            sideslip_m: 1.5,
            sideslip_per_speed_s: -0.4,
        };
        let x = SVector::<f64, 7>::from_column_slice(&[1.0, 2.0, 0.7, 2.0, 0.05, 0.2, -0.1]);
        let o = m.observe(&x);
        let eps = 1e-6;
        for j in 0..7 {
            let (mut up, mut down) = (x, x);
            up[j] += eps;
            down[j] -= eps;
            let d = (m.observe(&up).predicted - m.observe(&down).predicted) / (2.0 * eps);
            for i in 0..MEASUREMENTS {
                assert!(
                    (d[i] - o.jacobian[(i, j)]).abs() < 1e-7,
                    "H[{i},{j}]: {} analytic, {} numeric",
                    o.jacobian[(i, j)],
                    d[i]
                );
            }
        }
    }

    /// A drift that grows with speed turns the course from the heading by
    /// the same angle at every speed; one that does not, by less at a
    /// higher speed.
    #[test]
    fn the_two_drifts_bend_the_course_as_their_shapes_say() {
        let course_minus_heading = |m: &WaterKinematic, u: f64| {
            let x = SVector::<f64, 7>::from_column_slice(&[0.0, 0.0, 0.3, u, 0.1, 0.0, 0.0]);
            let o = m.observe(&x).predicted;
            wrap_pi(o[meas::COG] - o[meas::HEADING])
        };
        // At 1 and 2 m/s, a drift that grows with speed and one that does not.
        let at_two_speeds =
            |m: WaterKinematic| [1.0, 2.0].map(|u| course_minus_heading(&m, u) - (-0.04f64).atan());
        let [slow, fast] = at_two_speeds(WaterKinematic {
            sideslip_per_speed_s: -0.4,
            ..WaterKinematic::default()
        });
        assert!(slow.abs() < 1e-12 && fast.abs() < 1e-12, "{slow} {fast}");
        let [slow, fast] = at_two_speeds(WaterKinematic {
            sideslip_m: -0.4,
            ..WaterKinematic::default()
        });
        let half_the_angle = (-0.02f64).atan() - (-0.04f64).atan();
        assert!(slow.abs() < 1e-12, "{slow}");
        assert!((fast - half_the_angle).abs() < 1e-12, "{fast}");
    }

    #[test]
    fn jacobian_matches_finite_differences_and_current_moves_the_track() {
        let m = WaterKinematic {
            sideslip_m: 1.5,
            sideslip_per_speed_s: -0.4,
            ..WaterKinematic::default()
        };
        let x = SVector::<f64, 7>::from_column_slice(&[1.0, 2.0, 0.7, 2.0, 0.05, 0.2, -0.1]);
        let t = m.transition(&x, &(), &SVector::zeros(), 0.5);
        let eps = 1e-6;
        for j in 0..7 {
            let (mut xp, mut xm) = (x, x);
            xp[j] += eps;
            xm[j] -= eps;
            let d = (m.transition(&xp, &(), &SVector::zeros(), 0.5).next
                - m.transition(&xm, &(), &SVector::zeros(), 0.5).next)
                / (2.0 * eps);
            for i in 0..7 {
                assert!((d[i] - t.jacobian[(i, j)]).abs() < 1e-6, "F[{i},{j}]");
            }
        }
        // With the vessel stopped in the water, the current alone moves it.
        let m = WaterKinematic::default();
        let still = SVector::<f64, 7>::from_column_slice(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.3, 0.4]);
        let o = m.observe(&m.transition(&still, &(), &SVector::zeros(), 1.0).next);
        assert!((o.predicted[meas::SOG] - 0.5).abs() < 1e-12);
        assert!((o.predicted[meas::STW]).abs() < 1e-12);
        assert!((o.predicted[meas::NORTH] - 0.3).abs() < 1e-12);
        // A rate gyro measures the yaw rate itself.
        let o = m.observe(&x);
        assert_eq!(o.predicted[meas::YAW_RATE], x[idx::R]);
        for j in 0..7 {
            let expected = if j == idx::R { 1.0 } else { 0.0 };
            assert!((o.jacobian[(meas::YAW_RATE, j)] - expected).abs() < 1e-6);
        }
        // One reading 5 % high measures 1.05 of it.
        let high = WaterKinematic {
            effects: SensorEffects {
                yaw_rate_scale: 1.05,
                ..SensorEffects::default()
            },
            ..WaterKinematic::default()
        };
        let o = high.observe(&x);
        assert!((o.predicted[meas::YAW_RATE] - 1.05 * x[idx::R]).abs() < 1e-15);
        assert!((o.jacobian[(meas::YAW_RATE, idx::R)] - 1.05).abs() < 1e-6);
    }
}
