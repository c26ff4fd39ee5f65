//! A twin-propeller vessel's parameters, the numbers of its profile
//! (`twin_wire::profile` reads them from a file; docs/profiles.md), with
//! the Otter's as the default (docs/model.md section 6, from Fossen's
//! `otter.m` and the Python Vehicle Simulator with a 25 kg payload); and
//! the seed's step 4:
//! from faults on the kinematic inputs to a fault per thruster (docs/model.md
//! section 5), done with the correct thrust split.
//!
//! Numbers only live here; the simulator (`twin-sim`) keeps its own copy of
//! the physics so that the truth never shares code with the estimator.

use nalgebra::{Matrix3, Vector2};

use crate::sample::Side;

/// A twin-propeller vessel's parameters in surge, sway and yaw.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VesselParams {
    /// Rigid-body mass, hull and payload, kg.
    pub mass_kg: f64,
    /// Longitudinal position of the centre of gravity from the origin, m.
    pub cg_x_m: f64,
    /// Mass matrix including added mass, surge-sway-yaw block (kg, kg m, kg m^2).
    pub mass_matrix: Matrix3<f64>,
    /// Added mass coefficients `[X_udot, Y_vdot, N_rdot]` (negative).
    pub added_mass: [f64; 3],
    /// Linear damping `[X_u, Y_v, N_r]` (negative): N s/m, N s/m, N m s.
    pub linear_damping: [f64; 3],
    /// Nonlinear yaw damping factor `c` in `N = N_r (1 + c |r|) r`.
    pub yaw_damping_nonlinear_s: f64,
    /// Lateral distance of each propeller from the centre line, m.
    pub propeller_offset_m: f64,
    /// Thrust coefficient ahead, `T = k n |n|`, N / (rad/s)^2.
    pub thrust_coeff_ahead: f64,
    /// Thrust coefficient astern, N / (rad/s)^2.
    pub thrust_coeff_astern: f64,
    /// Maximum shaft speed ahead, rad/s.
    pub max_shaft_speed_radps: f64,
    /// Maximum shaft speed astern (negative), rad/s.
    pub min_shaft_speed_radps: f64,
    /// Time constant of the shaft speed response, s.
    pub shaft_time_constant_s: f64,
    /// Hull (pontoon) length, m.
    pub length_m: f64,
    /// Hull beam (overall, across both pontoons), m: with `length_m`, the
    /// rectangle the GNSS antenna can be on.
    pub beam_m: f64,
    /// Draft, m: the displaced volume of two pontoons with block
    /// coefficient 0.4 and beam 0.25 m, `(m / rho) / (2 0.4 0.25 L)`.
    pub draft_m: f64,
    /// Density of sea water, kg/m^3.
    pub water_density_kgpm3: f64,
    /// 2D cross-flow drag coefficient of a pontoon section (Hoerner's curve
    /// at `B / 2T = 0.25 / 0.39`: about 1.0).
    pub crossflow_drag_coeff: f64,
    /// The GNSS antenna's position in the body frame `[forward, starboard]`
    /// from the body origin, m.
    pub antenna_m: [f64; 2],
}

impl Default for VesselParams {
    /// The Otter with a 25 kg payload (docs/model.md section 6).
    fn default() -> Self {
        let yaw_inertia_total = 42.65;
        Self {
            mass_kg: 80.0,
            cg_x_m: 12.25 / 80.0,
            mass_matrix: Matrix3::new(
                85.5,
                0.0,
                0.0, //
                0.0,
                162.5,
                12.25, //
                0.0,
                12.25,
                yaw_inertia_total,
            ),
            // N_rdot = -1.7 I_z with M66 = I_z - N_rdot = 2.7 I_z.
            added_mass: [-5.5, -82.5, -1.7 * yaw_inertia_total / 2.7],
            linear_damping: [-24.4 * 9.81 / (6.0 * 0.5144), -162.5, -42.65],
            yaw_damping_nonlinear_s: 10.0,
            propeller_offset_m: 0.395,
            thrust_coeff_ahead: 0.01108,
            thrust_coeff_astern: 0.006445,
            max_shaft_speed_radps: 103.9,
            min_shaft_speed_radps: -101.7,
            shaft_time_constant_s: 0.1,
            length_m: 2.0,
            beam_m: 1.08,
            draft_m: (80.0 / 1025.0) / (2.0 * 0.4 * 0.25 * 2.0),
            water_density_kgpm3: 1025.0,
            crossflow_drag_coeff: 1.0,
            antenna_m: [0.0, 0.0],
        }
    }
}

impl VesselParams {
    /// These parameters with the scales `[surge damping, yaw damping,
    /// thrust coefficients, mass]` applied (the mass scale applies to the
    /// rigid-body mass and inertia and to the added mass alike).
    pub fn scaled(&self, scales: [f64; 4]) -> Self {
        let mut p = *self;
        p.linear_damping[0] *= scales[0];
        p.linear_damping[2] *= scales[1];
        p.thrust_coeff_ahead *= scales[2];
        p.thrust_coeff_astern *= scales[2];
        p.mass_kg *= scales[3];
        p.mass_matrix *= scales[3];
        for a in &mut p.added_mass {
            *a *= scales[3];
        }
        p
    }

    /// These parameters with the yaw inertia, rigid and added, times
    /// `scale` (the mass and the surge and sway added mass kept).
    pub fn with_yaw_inertia_scaled(&self, scale: f64) -> Self {
        let mut p = *self;
        p.mass_matrix[(2, 2)] *= scale;
        p.added_mass[2] *= scale;
        p
    }

    /// Thrust of one propeller at shaft speed `n_radps` (saturated to the
    /// shaft's limits), N: `k n |n|` with the ahead or astern coefficient.
    pub fn thrust_n(&self, n_radps: f64) -> f64 {
        let n = n_radps.clamp(self.min_shaft_speed_radps, self.max_shaft_speed_radps);
        let k = if n >= 0.0 {
            self.thrust_coeff_ahead
        } else {
            self.thrust_coeff_astern
        };
        k * n * n.abs()
    }

    /// The shaft speed that gives thrust `thrust_n` (the inverse of
    /// [`Self::thrust_n`] within the shaft's limits), rad/s: how a thrust
    /// command drives a twin whose input is shaft speed.
    pub fn shaft_speed_for_thrust_radps(&self, thrust_n: f64) -> f64 {
        let n = if thrust_n >= 0.0 {
            (thrust_n / self.thrust_coeff_ahead).sqrt()
        } else {
            -(-thrust_n / self.thrust_coeff_astern).sqrt()
        };
        n.clamp(self.min_shaft_speed_radps, self.max_shaft_speed_radps)
    }

    /// Splits a surge force and a yaw moment between the two propellers:
    /// `X = T_port + T_stb`, `N = b (T_port - T_stb)` (the port propeller
    /// sits at `y = -b`, and positive yaw turns the bow to starboard), so
    /// `T_port = X/2 + N/(2b)`, `T_stb = X/2 - N/(2b)`. Returns `[port, stb]`, N.
    pub fn split_thrust(&self, surge_force_n: f64, yaw_moment_nm: f64) -> Vector2<f64> {
        let half_x = 0.5 * surge_force_n;
        let half_n_over_b = 0.5 * yaw_moment_nm / self.propeller_offset_m;
        Vector2::new(half_x + half_n_over_b, half_x - half_n_over_b)
    }

    /// The surge force and yaw moment that produce `[u_dot, r_dot]` at surge
    /// speed `u` and yaw rate `r` with no sway (the seed's reduced 2-DOF
    /// kinetic model, thesis eq. 3.14, with this crate's parameters):
    /// `X = M11 u_dot - m x_g r^2 - X_u u`,
    /// `N = M33 r_dot + m x_g u r - N_r (1 + c |r|) r`.
    pub fn surge_yaw_forces(&self, u_mps: f64, r_radps: f64, u_dot: f64, r_dot: f64) -> (f64, f64) {
        let mxg = self.mass_kg * self.cg_x_m;
        let x = self.mass_matrix[(0, 0)] * u_dot
            - mxg * r_radps * r_radps
            - self.linear_damping[0] * u_mps;
        let n = self.mass_matrix[(2, 2)] * r_dot + mxg * u_mps * r_radps
            - self.linear_damping[2]
                * (1.0 + self.yaw_damping_nonlinear_s * r_radps.abs())
                * r_radps;
        (x, n)
    }
}

/// The seed's step 4 at one instant: what each thruster would have to lose
/// for the accelerations to shrink by the input faults.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThrusterFaults {
    /// Thrust each propeller must give for the measured accelerations, N, `[port, stb]`.
    pub thrust_n: Vector2<f64>,
    /// Thrust for the accelerations scaled by `(1 - theta)`, N.
    pub faulty_thrust_n: Vector2<f64>,
    /// `1 - T_faulty / T` per thruster, or `None` where `|T|` is below the
    /// guard and the ratio means nothing.
    pub loss: [Option<f64>; 2],
}

impl ThrusterFaults {
    /// The loss of one side.
    pub fn loss_of(&self, side: Side) -> Option<f64> {
        self.loss[side.index()]
    }
}

/// The seed's step 4: input faults `theta = [theta_a, theta_r]` to per-thruster
/// losses through the reduced kinetic model, at surge speed `u`, yaw rate `r`
/// and accelerations `u_dot`, `r_dot`. `min_thrust_n` guards the ratio.
pub fn seed_thruster_faults(
    params: &VesselParams,
    u_mps: f64,
    r_radps: f64,
    u_dot: f64,
    r_dot: f64,
    theta: Vector2<f64>,
    min_thrust_n: f64,
) -> ThrusterFaults {
    let (x, n) = params.surge_yaw_forces(u_mps, r_radps, u_dot, r_dot);
    let (xf, nf) = params.surge_yaw_forces(
        u_mps,
        r_radps,
        (1.0 - theta[0]) * u_dot,
        (1.0 - theta[1]) * r_dot,
    );
    let thrust = params.split_thrust(x, n);
    let faulty = params.split_thrust(xf, nf);
    let loss = std::array::from_fn(|i| {
        (thrust[i].abs() >= min_thrust_n).then(|| 1.0 - faulty[i] / thrust[i])
    });
    ThrusterFaults {
        thrust_n: thrust,
        faulty_thrust_n: faulty,
        loss,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parameters_match_model_md() {
        let p = VesselParams::default();
        assert!(
            (p.linear_damping[0] + 77.55).abs() < 0.05,
            "{}",
            p.linear_damping[0]
        );
        // Maximum thrust per propeller: 119.7 N ahead, 66.7 N astern.
        assert!((p.thrust_n(1e3) - 119.6).abs() < 0.3, "{}", p.thrust_n(1e3));
        assert!(
            (p.thrust_n(-1e3) + 66.66).abs() < 0.3,
            "{}",
            p.thrust_n(-1e3)
        );
        // Top speed where full thrust meets linear surge damping: about 3.09 m/s.
        let top = 2.0 * p.thrust_n(p.max_shaft_speed_radps) / -p.linear_damping[0];
        assert!((top - 3.09).abs() < 0.02, "{top}");
        assert!((p.added_mass[2] + 26.85).abs() < 0.01);
        for n in [-90.0, -10.0, 0.0, 35.0, 100.0] {
            assert!((p.shaft_speed_for_thrust_radps(p.thrust_n(n)) - n).abs() < 1e-9);
        }
    }

    #[test]
    fn thrust_split_inverts_the_force_model_in_consistent_units() {
        // Regression for ERRATA 7: the authors inverted [[1, b], [1, -b]],
        // mixing newtons with newton-metres and the yaw sign.
        let p = VesselParams::default();
        let (tp, ts) = (80.0, 30.0);
        let x = tp + ts;
        let n = p.propeller_offset_m * (tp - ts);
        let t = p.split_thrust(x, n);
        assert!((t[0] - tp).abs() < 1e-12 && (t[1] - ts).abs() < 1e-12);
        // More port thrust turns the bow to starboard (positive yaw moment).
        assert!(n > 0.0);
    }

    #[test]
    fn input_faults_map_to_the_thruster_that_does_the_work() {
        let p = VesselParams::default();
        // Accelerating straight: both thrusters share; a surge-input fault hits both alike.
        let f = seed_thruster_faults(&p, 1.5, 0.0, 0.3, 0.0, Vector2::new(0.2, 0.0), 5.0);
        let (lp, ls) = (f.loss[0].unwrap(), f.loss[1].unwrap());
        assert!((lp - ls).abs() < 1e-12 && lp > 0.0 && lp < 0.2, "{lp} {ls}");
        // Spinning up a starboard turn (r_dot > 0 needs port thrust): a yaw-input
        // fault is a port loss, with starboard pushing less and gaining.
        let f = seed_thruster_faults(&p, 1.5, 0.05, 0.0, 0.2, Vector2::new(0.0, 0.3), 5.0);
        assert!(
            f.loss[0].unwrap() > 0.0 && f.loss[1].unwrap() < 0.0,
            "{f:?}"
        );
        // Where a thruster's thrust is near zero the ratio is refused.
        let f = seed_thruster_faults(&p, 0.0, 0.0, 0.0, 0.0, Vector2::new(0.2, 0.2), 5.0);
        assert_eq!(f.loss, [None, None]);
    }
}
