//! The seed's kinematic model (docs/model.md section 3): state
//! `[north_m, east_m, sog_mps, course_rad]`, input `[a, r]` (acceleration along
//! the track, m/s^2, and course rate, rad/s), faults `theta = [theta_a,
//! theta_r]`, a loss of effectiveness on each input. All four states are
//! measured (position from lat/lon, speed and course over ground).
//!
//! ```text
//! next = [n + dt U cos chi, e + dt U sin chi, U + dt (1 - theta_a) a, chi + dt (1 - theta_r) r]
//! Psi  = -B diag(u),  B = dt [[0,0],[0,0],[1,0],[0,1]]
//! ```
//! Euler discretisation as in the seed (ERRATA 1: the thesis' eq. 3.12 drops
//! the previous position and `dt`; the paper's eq. 10 has it right).

use nalgebra::{SMatrix, SVector, Vector2, Vector4};

use crate::geodesy::wrap_pi;
use crate::linalg::{Pattern, diagonal};
use crate::model::{Model, Observation, Transition};
use crate::trig;

/// State `[north_m, east_m, sog_mps, course_rad]`.
pub type KinematicState = Vector4<f64>;

/// The seed's inputs: acceleration along the track and course rate.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct KinematicInput {
    /// Rate of change of speed over ground, m/s^2.
    pub accel_mps2: f64,
    /// Rate of change of course over ground, rad/s.
    pub course_rate_radps: f64,
}

impl KinematicInput {
    /// As the vector `[a, r]`.
    pub fn as_vector(&self) -> Vector2<f64> {
        Vector2::new(self.accel_mps2, self.course_rate_radps)
    }
}

/// The seed's kinematic model. Stateless.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct KinematicModel;

impl Model<4, 4, 2> for KinematicModel {
    type Input = KinematicInput;

    // Inlined into the filter's step (a different crate's generic code):
    // the Jacobians' constant entries then fold into the products.
    #[inline]
    fn transition(
        &self,
        x: &SVector<f64, 4>,
        input: &KinematicInput,
        theta: &SVector<f64, 2>,
        dt_s: f64,
    ) -> Transition<4, 2> {
        let (speed, course) = (x[2], x[3]);
        let (sin_c, cos_c) = trig::sin_cos(course);
        let a = input.accel_mps2;
        let r = input.course_rate_radps;
        let next = Vector4::new(
            x[0] + dt_s * speed * cos_c,
            x[1] + dt_s * speed * sin_c,
            speed + dt_s * (1.0 - theta[0]) * a,
            wrap_pi(course + dt_s * (1.0 - theta[1]) * r),
        );
        #[rustfmt::skip]
        let jacobian = SMatrix::<f64, 4, 4>::new(
            1.0, 0.0, dt_s * cos_c, -dt_s * speed * sin_c,
            0.0, 1.0, dt_s * sin_c,  dt_s * speed * cos_c,
            0.0, 0.0, 1.0, 0.0,
            0.0, 0.0, 0.0, 1.0,
        );
        #[rustfmt::skip]
        let fault_sensitivity = SMatrix::<f64, 4, 2>::new(
            0.0, 0.0,
            0.0, 0.0,
            -dt_s * a, 0.0,
            0.0, -dt_s * r,
        );
        Transition {
            next,
            jacobian,
            fault_sensitivity,
        }
    }

    #[inline]
    fn observe(&self, x: &SVector<f64, 4>) -> Observation<4, 4> {
        Observation {
            predicted: *x,
            jacobian: SMatrix::identity(),
        }
    }

    fn measurement_angles(&self) -> [bool; 4] {
        [false, false, false, true]
    }

    fn state_angles(&self) -> [bool; 4] {
        [false, false, false, true]
    }

    fn state_names(&self) -> [&'static str; 4] {
        ["north_m", "east_m", "sog_mps", "course_rad"]
    }

    const TRANSITION_PATTERN: Pattern<4, 4> = [
        [true, false, true, true],
        [false, true, true, true],
        [false, false, true, false],
        [false, false, false, true],
    ];

    const OBSERVATION_PATTERN: Pattern<4, 4> = diagonal();
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Jacobian and Psi agree with central finite differences.
    #[test]
    fn derivatives_match_finite_differences() {
        let m = KinematicModel;
        let x = Vector4::new(3.0, -2.0, 1.7, 2.5);
        let u = KinematicInput {
            accel_mps2: 0.3,
            course_rate_radps: -0.2,
        };
        let th = Vector2::new(0.2, 0.4);
        let dt = 0.2;
        let tr = m.transition(&x, &u, &th, dt);
        let eps = 1e-6;
        for j in 0..4 {
            let mut xp = x;
            let mut xm = x;
            xp[j] += eps;
            xm[j] -= eps;
            let d = (m.transition(&xp, &u, &th, dt).next - m.transition(&xm, &u, &th, dt).next)
                / (2.0 * eps);
            for i in 0..4 {
                assert!((d[i] - tr.jacobian[(i, j)]).abs() < 1e-6, "F[{i},{j}]");
            }
        }
        for i in 0..4 {
            for j in 0..4 {
                if !KinematicModel::TRANSITION_PATTERN[i][j] {
                    assert_eq!(tr.jacobian[(i, j)], 0.0, "F[{i},{j}] outside its pattern");
                }
                if !KinematicModel::OBSERVATION_PATTERN[i][j] {
                    assert_eq!(m.observe(&x).jacobian[(i, j)], 0.0);
                }
            }
        }
        for j in 0..2 {
            let mut tp = th;
            tp[j] += eps;
            let d = (m.transition(&x, &u, &tp, dt).next - tr.next) / eps;
            for i in 0..4 {
                assert!(
                    (d[i] - tr.fault_sensitivity[(i, j)]).abs() < 1e-6,
                    "Psi[{i},{j}]"
                );
            }
        }
    }

    /// Regression for ERRATA 1: the step keeps the previous position.
    #[test]
    fn step_keeps_position_and_integrates_velocity() {
        let m = KinematicModel;
        let x = Vector4::new(10.0, 20.0, 2.0, std::f64::consts::FRAC_PI_2);
        let tr = m.transition(&x, &KinematicInput::default(), &Vector2::zeros(), 0.5);
        assert!((tr.next[0] - 10.0).abs() < 1e-12);
        assert!((tr.next[1] - 21.0).abs() < 1e-12);
    }
}
