//! The Otter USV in surge, sway and yaw, with its two propeller shafts: the
//! equations of motion the simulator integrates.
//!
//! Written from the equations of Fossen's Otter model (MSS `otter.m`,
//! Fossen 2021, *Handbook of Marine Craft Hydrodynamics and Motion Control*)
//! with the numbers of docs/model.md section 6 (payload 25 kg). It shares no code
//! with the estimator's models in `twin-core`: this is the truth they are held
//! against.
//!
//! # Equations
//! Velocities `nu = [u, v, r]` are over ground, in the body frame (x forward,
//! y starboard, yaw positive bow to starboard). With the water current's body
//! velocity `nu_c = [u_c, v_c, 0]` and `nu_r = nu - nu_c`:
//!
//! ```text
//! M nu_r' = tau_prop + tau_wind + tau_d - C_RB(nu_r) nu_r - C_A(nu_r) nu_r + tau_damp(nu_r) + tau_crossflow(nu_r)
//! nu'     = nu_r' + nu_c',   nu_c' = R(psi)^T a_c + [r v_c, -r u_c, 0]
//! eta'    = R(psi) nu        (north, east, psi)
//! n_i'    = (sat(n_cmd_i) - n_i) / T_n
//! ```
//!
//! `nu_c'` is the time derivative of the current seen from the turning hull
//! (`a_c` is the current's acceleration in the NED frame, zero for a constant
//! current). Writing the whole equation in the relative velocity, as
//! `otter.m` does, is exact for a constant, irrotational current (then
//! `M_RB nu' + C_RB(nu) nu = M_RB nu_r' + C_RB(nu_r) nu_r`, tested below), and
//! for a slowly varying uniform current it adds the Froude-Krylov force of the
//! accelerating water (a floating hull displaces its own mass).
//!
//! - `C_RB(nu) nu = [-m r (v + x_g r), m r u, m x_g r u]`, CG `x_g` ahead of
//!   the body origin.
//! - `C_A(nu_r) nu_r = [-a22 v_r r, a11 u_r r, (a22 - a11) u_r v_r]` with
//!   `a11 = -X_udot`, `a22 = -Y_vdot`; the yaw term is the Munk moment.
//! - `tau_damp = [X_u u_r, Y_v v_r, N_r (1 + k_r |r|) r]`.
//! - Cross-flow drag by strip theory over the hull length, with Hoerner's 2D
//!   drag coefficient of one pontoon section (as `otter.m` passes one pontoon).
//! - `tau_prop = [T_p + T_s, 0, b (T_p - T_s)]`, `T_i = (1 - loss_i) k(n_i) n_i |n_i|`.
//! - `tau_wind` is the air load ([`crate::environment`]), `tau_d` the random
//!   disturbance ([`crate::disturbance`]), held constant over a step.
//!
//! The Munk moment makes the Otter directionally unstable in open loop (a
//! straight course diverges with a time constant of a few seconds at trial
//! speed); the heading autopilot stabilises it. The
//! older Python Vehicle Simulator zeroes it; `otter.m` keeps it, and so do we
//! by default ([`OtterParams::munk_moment`]).

use nalgebra::{Matrix3, SVector, Vector3};

/// Positions of the components in the simulator's state vector.
pub(crate) mod idx {
    /// North position of the body origin, m.
    pub const NORTH: usize = 0;
    /// East position of the body origin, m.
    pub const EAST: usize = 1;
    /// Heading, rad (not wrapped while integrating).
    pub const PSI: usize = 2;
    /// Surge velocity over ground, m/s.
    pub const U: usize = 3;
    /// Sway velocity over ground, m/s.
    pub const V: usize = 4;
    /// Yaw rate, rad/s.
    pub const R: usize = 5;
    /// Port shaft speed, rad/s.
    pub const N_PORT: usize = 6;
    /// Starboard shaft speed, rad/s.
    pub const N_STB: usize = 7;
}

/// The integrated state: `[north_m, east_m, psi_rad, u_mps, v_mps, r_radps,
/// n_port_radps, n_starboard_radps]` (see [`idx`]).
pub(crate) type StateVector = SVector<f64, 8>;

/// Density of sea water, kg/m^3 (`otter.m`).
pub const SEA_WATER_DENSITY_KGPM3: f64 = 1025.0;

/// The Otter's parameters. [`Default`] gives docs/model.md section 6 (hull 55 kg,
/// payload 25 kg at [0.05, 0, -0.35] m).
#[derive(Debug, Clone, PartialEq)]
pub struct OtterParams {
    /// Rigid-body mass, hull and payload, kg.
    pub mass_kg: f64,
    /// Centre of gravity ahead of the body origin (midships, centre line), m.
    pub cg_x_m: f64,
    /// Surge-sway-yaw mass matrix, rigid body plus added mass
    /// (kg, kg m, kg m^2).
    pub mass_matrix: Matrix3<f64>,
    /// Surge added mass `-X_udot`, kg.
    pub added_mass_surge_kg: f64,
    /// Sway added mass `-Y_vdot`, kg.
    pub added_mass_sway_kg: f64,
    /// Yaw added inertia `-N_rdot`, kg m^2 (already inside `mass_matrix`).
    pub added_inertia_yaw_kgm2: f64,
    /// Linear surge damping derivative `X_u` (negative), N per m/s.
    pub x_u_n_per_mps: f64,
    /// Linear sway damping derivative `Y_v` (negative), N per m/s.
    pub y_v_n_per_mps: f64,
    /// Linear yaw damping derivative `N_r` (negative), N m per rad/s.
    pub n_r_nm_per_radps: f64,
    /// Factor of the quadratic yaw damping, `N = N_r (1 + k |r|) r`, s/rad.
    pub yaw_damping_quadratic_s_per_rad: f64,
    /// Hull (pontoon) length, m.
    pub length_m: f64,
    /// Beam of one pontoon, m (the section used for cross-flow drag).
    pub pontoon_beam_m: f64,
    /// Draft, m.
    pub draft_m: f64,
    /// Water density, kg/m^3.
    pub water_density_kgpm3: f64,
    /// Number of strips of the cross-flow drag integral.
    pub crossflow_strips: usize,
    /// Whether the added-mass Munk moment `(a22 - a11) u_r v_r` acts in yaw.
    pub munk_moment: bool,
    /// Lateral distance of each propeller from the centre line, m
    /// (port at `-b`, starboard at `+b`).
    pub propeller_arm_m: f64,
    /// Thrust coefficient ahead, `T = k n^2` for `n > 0`, N/(rad/s)^2.
    pub thrust_coeff_ahead_n_per_radps2: f64,
    /// Thrust coefficient astern, `T = -k n^2` for `n < 0`, N/(rad/s)^2.
    pub thrust_coeff_astern_n_per_radps2: f64,
    /// Highest shaft speed, rad/s.
    pub shaft_max_radps: f64,
    /// Lowest (most negative) shaft speed, rad/s.
    pub shaft_min_radps: f64,
    /// Time constant of the first-order shaft response, s.
    pub shaft_time_constant_s: f64,
    /// Factor on the cross-flow drag (1 for the Otter).
    pub crossflow_scale: f64,
}

impl Default for OtterParams {
    fn default() -> Self {
        // Hull + payload 80 kg; CG (55 * 0.2 + 25 * 0.05) / 80 = 0.153125 m ahead,
        // so m x_g = 12.25 kg m. The yaw entry 42.65 is the rigid-body inertia
        // about the origin plus N_rdot = -1.7 I_z (otter.m's best-practice rule).
        let mass_kg = 80.0;
        let cg_x_m = 12.25 / 80.0;
        let mass_matrix = Matrix3::new(
            85.5, 0.0, 0.0, //
            0.0, 162.5, 12.25, //
            0.0, 12.25, 42.65,
        );
        // Draft from the displaced volume of two pontoons (block coefficient 0.4):
        // T = (m / rho) / (2 Cb B_pont L) = 0.195 m.
        let draft_m = (mass_kg / SEA_WATER_DENSITY_KGPM3) / (2.0 * 0.4 * 0.25 * 2.0);
        Self {
            mass_kg,
            cg_x_m,
            mass_matrix,
            added_mass_surge_kg: 5.5,
            added_mass_sway_kg: 82.5,
            // 1.7 I_z with otter.m's I_z = 15.102 kg m^2 (hull and payload).
            added_inertia_yaw_kgm2: 25.674,
            x_u_n_per_mps: -77.55,
            y_v_n_per_mps: -162.5,
            n_r_nm_per_radps: -42.65,
            yaw_damping_quadratic_s_per_rad: 10.0,
            length_m: 2.0,
            pontoon_beam_m: 0.25,
            draft_m,
            water_density_kgpm3: SEA_WATER_DENSITY_KGPM3,
            crossflow_strips: 20,
            munk_moment: true,
            propeller_arm_m: 0.395,
            thrust_coeff_ahead_n_per_radps2: 0.01108,
            thrust_coeff_astern_n_per_radps2: 0.006445,
            shaft_max_radps: 103.9,
            shaft_min_radps: -101.7,
            shaft_time_constant_s: 0.1,
            crossflow_scale: 1.0,
        }
    }
}

/// Scale factors on a vessel's numbers, each positive (1 = unchanged).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VesselScales {
    /// Rigid-body mass and inertia.
    pub mass: f64,
    /// Added mass and inertia.
    pub added_mass: f64,
    /// Linear surge damping.
    pub surge_damping: f64,
    /// Linear sway damping.
    pub sway_damping: f64,
    /// Linear and quadratic yaw damping.
    pub yaw_damping: f64,
    /// Cross-flow drag.
    pub crossflow_drag: f64,
    /// Thrust coefficients, ahead and astern, both propellers.
    pub thrust: f64,
    /// Every length of the hull (geometric similarity): its length, pontoon
    /// beam and draft, the centre of gravity's offset and the radii of
    /// gyration (the rigid and the added yaw inertia by its square, on top
    /// of their mass scales). A hull `s` times as long displaces `s^3`
    /// times the water at the same draft ratio: give the mass scale too.
    pub size: f64,
    /// The propellers' lateral distance from the centre line.
    pub propeller_arm: f64,
}

impl Default for VesselScales {
    fn default() -> Self {
        Self {
            mass: 1.0,
            added_mass: 1.0,
            surge_damping: 1.0,
            sway_damping: 1.0,
            yaw_damping: 1.0,
            crossflow_drag: 1.0,
            thrust: 1.0,
            size: 1.0,
            propeller_arm: 1.0,
        }
    }
}

impl OtterParams {
    /// These parameters with `scales` applied: the rigid-body mass matrix
    /// (`m`, `m x_g`, the inertia about the origin) times the mass scale and
    /// the added part times the added-mass scale, with the size scale on the
    /// lengths (`x_g` by it, the yaw inertias by its square, the hull's
    /// length, pontoon beam and draft by it); the damping derivatives, the
    /// cross-flow drag, the propellers' lateral arm and both thrust
    /// coefficients times theirs. The shaft limits are kept: a stronger
    /// propeller gives more thrust at the same speed.
    pub fn scaled(&self, scales: &VesselScales) -> Self {
        let added = Matrix3::from_diagonal(&Vector3::new(
            self.added_mass_surge_kg,
            self.added_mass_sway_kg,
            self.added_inertia_yaw_kgm2,
        ));
        let rigid = self.mass_matrix - added;
        // The rigid part's entries by their dimension of length: kg, kg m, kg m^2.
        let size = scales.size;
        let length_power = Matrix3::new(
            1.0,
            1.0,
            1.0, //
            1.0,
            1.0,
            size, //
            1.0,
            size,
            size * size,
        );
        let mut p = self.clone();
        p.mass_kg *= scales.mass;
        p.cg_x_m *= size;
        p.added_mass_surge_kg *= scales.added_mass;
        p.added_mass_sway_kg *= scales.added_mass;
        p.added_inertia_yaw_kgm2 *= scales.added_mass * size * size;
        p.mass_matrix = rigid.component_mul(&length_power) * scales.mass
            + Matrix3::from_diagonal(&Vector3::new(
                p.added_mass_surge_kg,
                p.added_mass_sway_kg,
                p.added_inertia_yaw_kgm2,
            ));
        p.length_m *= size;
        p.pontoon_beam_m *= size;
        p.draft_m *= size;
        p.x_u_n_per_mps *= scales.surge_damping;
        p.y_v_n_per_mps *= scales.sway_damping;
        p.n_r_nm_per_radps *= scales.yaw_damping;
        p.crossflow_scale *= scales.crossflow_drag;
        p.propeller_arm_m *= scales.propeller_arm;
        p.thrust_coeff_ahead_n_per_radps2 *= scales.thrust;
        p.thrust_coeff_astern_n_per_radps2 *= scales.thrust;
        p
    }

    /// Thrust of one healthy propeller at shaft speed `n_radps` (saturated to
    /// the shaft's limits), N. Positive pushes the craft ahead.
    pub fn thrust_n(&self, n_radps: f64) -> f64 {
        let n = self.saturate_shaft_radps(n_radps);
        if n >= 0.0 {
            self.thrust_coeff_ahead_n_per_radps2 * n * n
        } else {
            -self.thrust_coeff_astern_n_per_radps2 * n * n
        }
    }

    /// The shaft speed that gives `thrust_n` from a healthy propeller (the
    /// inverse of [`Self::thrust_n`]), saturated to the shaft's limits, rad/s.
    pub fn shaft_speed_for_thrust_radps(&self, thrust_n: f64) -> f64 {
        let n = if thrust_n >= 0.0 {
            (thrust_n / self.thrust_coeff_ahead_n_per_radps2).sqrt()
        } else {
            -(-thrust_n / self.thrust_coeff_astern_n_per_radps2).sqrt()
        };
        self.saturate_shaft_radps(n)
    }

    /// Clamps a shaft speed to `[shaft_min_radps, shaft_max_radps]`.
    pub fn saturate_shaft_radps(&self, n_radps: f64) -> f64 {
        n_radps.clamp(self.shaft_min_radps, self.shaft_max_radps)
    }

    /// Largest thrust ahead of one propeller, N.
    pub fn max_thrust_n(&self) -> f64 {
        self.thrust_n(self.shaft_max_radps)
    }

    /// Largest thrust astern of one propeller (negative), N.
    pub fn min_thrust_n(&self) -> f64 {
        self.thrust_n(self.shaft_min_radps)
    }

    /// The diagonal of the mass matrix `[M11 kg, M22 kg, M33 kg m^2]`
    /// (rigid body plus added mass): `[85.5, 162.5, 42.65]` by default.
    pub fn mass_matrix_diagonal(&self) -> [f64; 3] {
        [
            self.mass_matrix[(0, 0)],
            self.mass_matrix[(1, 1)],
            self.mass_matrix[(2, 2)],
        ]
    }

    /// Hoerner's 2D cross-flow drag coefficient of one pontoon section.
    pub fn crossflow_drag_coefficient(&self) -> f64 {
        hoerner_cd_2d(self.pontoon_beam_m / (2.0 * self.draft_m))
    }
}

/// Hoerner's 2D cross-flow drag coefficient of a ship section as a function
/// of `B / (2 T)`, interpolated linearly in a digitised curve (Hoerner 1965,
/// as tabulated by Leite et al. 1998, Appl. Ocean Res. 20, and used by MSS).
/// Outside the table the end values hold.
pub fn hoerner_cd_2d(beam_over_twice_draft: f64) -> f64 {
    // (B / 2T, C_D) pairs.
    const CURVE: [(f64, f64); 20] = [
        (0.0108623, 1.96608),
        (0.176606, 1.96573),
        (0.353025, 1.89756),
        (0.451863, 1.78718),
        (0.472838, 1.58374),
        (0.492877, 1.27862),
        (0.493252, 1.21082),
        (0.558473, 1.08356),
        (0.646401, 0.998631),
        (0.833589, 0.87959),
        (0.988002, 0.828415),
        (1.30807, 0.759941),
        (1.63918, 0.691442),
        (1.85998, 0.657076),
        (2.31288, 0.630693),
        (2.59998, 0.596186),
        (3.00877, 0.586846),
        (3.45075, 0.585909),
        (3.7379, 0.559877),
        (4.00309, 0.559315),
    ];
    let x = beam_over_twice_draft;
    if x <= CURVE[0].0 {
        return CURVE[0].1;
    }
    for pair in CURVE.windows(2) {
        let ((x0, y0), (x1, y1)) = (pair[0], pair[1]);
        if x <= x1 {
            return y0 + (y1 - y0) * (x - x0) / (x1 - x0);
        }
    }
    CURVE[CURVE.len() - 1].1
}

/// What drives the hull during one integration step: the shaft speed
/// commands and each propeller's loss of effectiveness (port, starboard).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Actuation {
    /// Commanded shaft speeds, rad/s (saturated inside the model).
    pub n_cmd_radps: [f64; 2],
    /// Loss of effectiveness, 0..1: effective thrust `(1 - loss) T`.
    pub loss: [f64; 2],
}

/// The water and the air around the hull at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct Surroundings {
    /// Current velocity, NED, m/s (north, east).
    pub current_ned_mps: [f64; 2],
    /// Current acceleration, NED, m/s^2 (north, east).
    pub current_accel_ned_mps2: [f64; 2],
    /// Air force and moment on the hull in the body frame (N, N, N m).
    pub wind_force: [f64; 3],
    /// Random disturbance force and moment in the body frame (N, N, N m).
    pub disturbance_force: [f64; 3],
}

/// The model with its derived constants (inverse mass matrix, cross-flow
/// coefficient) computed once.
#[derive(Debug, Clone)]
pub(crate) struct OtterModel {
    pub params: OtterParams,
    mass_inverse: Matrix3<f64>,
    crossflow_cd: f64,
}

impl OtterModel {
    /// Prepares the model. The mass matrix must be invertible (it is, for
    /// any physical parameters: symmetric positive definite).
    pub fn new(params: OtterParams) -> Self {
        let mass_inverse = params
            .mass_matrix
            .try_inverse()
            .unwrap_or_else(Matrix3::zeros);
        let crossflow_cd = params.crossflow_drag_coefficient() * params.crossflow_scale;
        Self {
            params,
            mass_inverse,
            crossflow_cd,
        }
    }

    /// Propeller force and moment `[X, Y, N]` from the shaft speeds and losses.
    pub fn propulsion(&self, shafts_radps: [f64; 2], loss: [f64; 2]) -> Vector3<f64> {
        let [t_port, t_stb] = self.effective_thrusts_n(shafts_radps, loss);
        Vector3::new(
            t_port + t_stb,
            0.0,
            self.params.propeller_arm_m * (t_port - t_stb),
        )
    }

    /// Effective thrust of each propeller, `(1 - loss) T(n)`, N.
    pub fn effective_thrusts_n(&self, shafts_radps: [f64; 2], loss: [f64; 2]) -> [f64; 2] {
        [
            (1.0 - loss[0]) * self.params.thrust_n(shafts_radps[0]),
            (1.0 - loss[1]) * self.params.thrust_n(shafts_radps[1]),
        ]
    }

    /// Rigid-body Coriolis and centripetal force `C_RB(nu) nu`.
    pub fn coriolis_rigid(&self, nu: &Vector3<f64>) -> Vector3<f64> {
        let (m, xg) = (self.params.mass_kg, self.params.cg_x_m);
        let (u, v, r) = (nu.x, nu.y, nu.z);
        Vector3::new(-m * r * (v + xg * r), m * r * u, m * xg * r * u)
    }

    /// Added-mass Coriolis force `C_A(nu_r) nu_r`, with the Munk moment if
    /// the parameters keep it.
    pub fn coriolis_added(&self, nu_r: &Vector3<f64>) -> Vector3<f64> {
        let (a11, a22) = (
            self.params.added_mass_surge_kg,
            self.params.added_mass_sway_kg,
        );
        let (u, v, r) = (nu_r.x, nu_r.y, nu_r.z);
        let munk = if self.params.munk_moment {
            (a22 - a11) * u * v
        } else {
            0.0
        };
        Vector3::new(-a22 * v * r, a11 * u * r, munk)
    }

    /// Linear damping with the quadratic yaw term, as the force the water
    /// exerts (so it opposes the motion): `[X_u u, Y_v v, N_r (1 + k|r|) r]`.
    pub fn damping_force(&self, nu_r: &Vector3<f64>) -> Vector3<f64> {
        let p = &self.params;
        Vector3::new(
            p.x_u_n_per_mps * nu_r.x,
            p.y_v_n_per_mps * nu_r.y,
            p.n_r_nm_per_radps * (1.0 + p.yaw_damping_quadratic_s_per_rad * nu_r.z.abs()) * nu_r.z,
        )
    }

    /// Cross-flow drag `[0, Y, N]` by strip theory: each strip at `x` meets
    /// the transverse flow `v_r + x r` with drag `-1/2 rho T C_D |w| w dx`.
    /// Midpoint rule over the hull length.
    pub fn crossflow_force(&self, nu_r: &Vector3<f64>) -> Vector3<f64> {
        let p = &self.params;
        let strips = p.crossflow_strips.max(1);
        let dx = p.length_m / strips as f64;
        let factor = 0.5 * p.water_density_kgpm3 * p.draft_m * self.crossflow_cd * dx;
        let (v, r) = (nu_r.y, nu_r.z);
        let (mut y_n, mut n_nm) = (0.0, 0.0);
        for i in 0..strips {
            let x = -0.5 * p.length_m + (i as f64 + 0.5) * dx;
            let w = v + x * r;
            let drag = -factor * w.abs() * w;
            y_n += drag;
            n_nm += x * drag;
        }
        Vector3::new(0.0, y_n, n_nm)
    }

    /// Body-frame current `[u_c, v_c, 0]` at heading `psi_rad`.
    pub fn body_current(psi_rad: f64, current_ned_mps: [f64; 2]) -> Vector3<f64> {
        let (s, c) = psi_rad.sin_cos();
        let [cn, ce] = current_ned_mps;
        Vector3::new(c * cn + s * ce, -s * cn + c * ce, 0.0)
    }

    /// The time derivative of the state.
    pub fn derivative(&self, x: &StateVector, act: &Actuation, env: &Surroundings) -> StateVector {
        let p = &self.params;
        let psi = x[idx::PSI];
        let (s, c) = psi.sin_cos();
        let nu = Vector3::new(x[idx::U], x[idx::V], x[idx::R]);
        let r = nu.z;

        let nu_c = Self::body_current(psi, env.current_ned_mps);
        let nu_r = nu - nu_c;
        let [an, ae] = env.current_accel_ned_mps2;
        let nu_c_dot = Vector3::new(
            c * an + s * ae + r * nu_c.y,
            -s * an + c * ae - r * nu_c.x,
            0.0,
        );

        let shafts = [x[idx::N_PORT], x[idx::N_STB]];
        let tau = self.propulsion(shafts, act.loss)
            + Vector3::from(env.wind_force)
            + Vector3::from(env.disturbance_force);
        let forces = tau - self.coriolis_rigid(&nu_r) - self.coriolis_added(&nu_r)
            + self.damping_force(&nu_r)
            + self.crossflow_force(&nu_r);
        let nu_dot = self.mass_inverse * forces + nu_c_dot;

        let mut dx = StateVector::zeros();
        dx[idx::NORTH] = c * nu.x - s * nu.y;
        dx[idx::EAST] = s * nu.x + c * nu.y;
        dx[idx::PSI] = r;
        dx[idx::U] = nu_dot.x;
        dx[idx::V] = nu_dot.y;
        dx[idx::R] = nu_dot.z;
        for (i, k) in [idx::N_PORT, idx::N_STB].into_iter().enumerate() {
            let target = p.saturate_shaft_radps(act.n_cmd_radps[i]);
            dx[k] = (target - x[k]) / p.shaft_time_constant_s;
        }
        dx
    }
}

/// One classical fourth-order Runge-Kutta step of length `h_s` from time
/// `t_s`; `f(t, x)` is the time derivative.
pub(crate) fn rk4_step<F>(f: F, t_s: f64, x: &StateVector, h_s: f64) -> StateVector
where
    F: Fn(f64, &StateVector) -> StateVector,
{
    let half = 0.5 * h_s;
    let k1 = f(t_s, x);
    let k2 = f(t_s + half, &(x + k1 * half));
    let k3 = f(t_s + half, &(x + k2 * half));
    let k4 = f(t_s + h_s, &(x + k3 * h_s));
    x + (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h_s / 6.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model() -> OtterModel {
        OtterModel::new(OtterParams::default())
    }

    fn still() -> Surroundings {
        Surroundings::default()
    }

    #[test]
    fn bollard_thrust_matches_the_otter_data() {
        let p = OtterParams::default();
        // docs/model.md section 6: 119.7 N ahead and 66.7 N astern per propeller.
        assert!(
            (p.max_thrust_n() - 119.7).abs() < 0.5,
            "{}",
            p.max_thrust_n()
        );
        assert!(
            (p.min_thrust_n() + 66.7).abs() < 0.5,
            "{}",
            p.min_thrust_n()
        );
        // Saturation: faster commands give no more thrust.
        assert_eq!(p.thrust_n(200.0), p.max_thrust_n());
        // The inverse is exact inside the limits, on both sides.
        for t in [-60.0, -1.0, 0.0, 3.0, 50.0, 119.0] {
            let n = p.shaft_speed_for_thrust_radps(t);
            assert!((p.thrust_n(n) - t).abs() < 1e-9, "{t} -> {n}");
        }
    }

    #[test]
    fn a_hull_twice_the_size_scales_lengths_and_inertias_by_their_dimensions() {
        let otter = OtterParams::default();
        let big = otter.scaled(&VesselScales {
            size: 2.0,
            mass: 8.0,
            added_mass: 8.0,
            propeller_arm: 2.0,
            ..VesselScales::default()
        });
        // kg by the mass scale, kg m by it and the size, kg m^2 by it and
        // the size squared; the added part likewise.
        let ratio = big.mass_matrix.component_div(&otter.mass_matrix);
        for (entry, want) in [((0, 0), 8.0), ((1, 1), 8.0), ((1, 2), 16.0), ((2, 2), 32.0)] {
            assert!(
                (ratio[entry] - want).abs() < 1e-12,
                "{entry:?}: {}",
                ratio[entry]
            );
        }
        assert!((big.mass_kg * big.cg_x_m - big.mass_matrix[(1, 2)]).abs() < 1e-9);
        assert!((big.added_inertia_yaw_kgm2 / otter.added_inertia_yaw_kgm2 - 32.0).abs() < 1e-12);
        assert_eq!(
            [
                big.length_m,
                big.pontoon_beam_m,
                big.draft_m,
                big.propeller_arm_m
            ],
            [
                2.0 * otter.length_m,
                2.0 * otter.pontoon_beam_m,
                2.0 * otter.draft_m,
                0.79
            ]
        );
        // The section's shape, and so its drag coefficient, is kept.
        assert_eq!(
            big.crossflow_drag_coefficient(),
            otter.crossflow_drag_coefficient()
        );
        // The propellers' arm is its own scale's, not the size's.
        let wide = otter.scaled(&VesselScales {
            size: 2.0,
            ..VesselScales::default()
        });
        assert_eq!(wide.propeller_arm_m, otter.propeller_arm_m);
    }

    #[test]
    fn mass_matrix_is_symmetric_positive_definite() {
        let m = OtterParams::default().mass_matrix;
        assert_eq!(m, m.transpose());
        assert!(m.cholesky().is_some());
        // The rigid-body coupling m x_g of the CG offset.
        let p = OtterParams::default();
        assert!((p.mass_kg * p.cg_x_m - m[(1, 2)]).abs() < 1e-12);
    }

    #[test]
    fn hoerner_coefficient_of_the_otter_pontoon() {
        let p = OtterParams::default();
        // B/2T = 0.25 / (2 * 0.195) = 0.64, between the table's 0.558 and 0.646.
        let cd = p.crossflow_drag_coefficient();
        assert!((cd - 1.005).abs() < 0.01, "{cd}");
        assert_eq!(hoerner_cd_2d(100.0), 0.559315);
        assert_eq!(hoerner_cd_2d(0.0), 1.96608);
    }

    #[test]
    fn crossflow_drag_opposes_sway_and_yaw() {
        let m = model();
        let f = m.crossflow_force(&Vector3::new(0.0, 0.5, 0.0));
        assert!(f.y < 0.0 && f.z.abs() < 1e-9, "{f}");
        // Pure sway: the integral equals 1/2 rho T C_D L v^2 exactly.
        let p = &m.params;
        let expected =
            -0.5 * p.water_density_kgpm3 * p.draft_m * m.crossflow_cd * p.length_m * 0.25;
        assert!((f.y - expected).abs() < 1e-9);
        let g = m.crossflow_force(&Vector3::new(0.0, 0.0, 0.3));
        assert!(g.z < 0.0 && g.y.abs() < 1e-9, "{g}");
    }

    #[test]
    fn coriolis_forces_do_no_work() {
        let m = model();
        for nu in [
            Vector3::new(1.5, 0.2, 0.1),
            Vector3::new(-0.4, 0.7, -0.3),
            Vector3::new(3.0, -0.1, 0.5),
        ] {
            assert!(nu.dot(&m.coriolis_rigid(&nu)).abs() < 1e-12);
            assert!(nu.dot(&m.coriolis_added(&nu)).abs() < 1e-12);
        }
    }

    #[test]
    fn relative_form_equals_absolute_rigid_body_form_for_a_constant_current() {
        // M_RB nu' + C_RB(nu) nu + M_A nu_r' + C_A(nu_r) nu_r + D(nu_r) nu_r = tau
        // is what the relative-velocity form must reduce to for a constant current.
        let m = model();
        let mut x = StateVector::zeros();
        x[idx::PSI] = 0.7;
        x[idx::U] = 1.4;
        x[idx::V] = -0.3;
        x[idx::R] = 0.25;
        x[idx::N_PORT] = 80.0;
        x[idx::N_STB] = 60.0;
        let act = Actuation {
            n_cmd_radps: [80.0, 60.0],
            loss: [0.1, 0.0],
        };
        let env = Surroundings {
            current_ned_mps: [0.3, -0.4],
            ..Surroundings::default()
        };
        let dx = m.derivative(&x, &act, &env);
        let nu = Vector3::new(x[idx::U], x[idx::V], x[idx::R]);
        let nu_dot = Vector3::new(dx[idx::U], dx[idx::V], dx[idx::R]);
        let nu_c = OtterModel::body_current(x[idx::PSI], env.current_ned_mps);
        let nu_r = nu - nu_c;
        let r = nu.z;
        let nu_c_dot = Vector3::new(r * nu_c.y, -r * nu_c.x, 0.0);
        let p = &m.params;
        let m_a = Matrix3::from_diagonal(&Vector3::new(
            p.added_mass_surge_kg,
            p.added_mass_sway_kg,
            p.added_inertia_yaw_kgm2,
        ));
        let m_rb = p.mass_matrix - m_a;
        let lhs = m_rb * nu_dot
            + m.coriolis_rigid(&nu)
            + m_a * (nu_dot - nu_c_dot)
            + m.coriolis_added(&nu_r)
            - m.damping_force(&nu_r)
            - m.crossflow_force(&nu_r);
        let tau = m.propulsion([80.0, 60.0], act.loss);
        assert!((lhs - tau).norm() < 1e-9, "{lhs} vs {tau}");
    }

    #[test]
    fn shaft_follows_a_first_order_lag_with_the_otter_time_constant() {
        let m = model();
        let act = Actuation {
            n_cmd_radps: [100.0, -50.0],
            loss: [0.0; 2],
        };
        let mut x = StateVector::zeros();
        let h = 0.001;
        for _ in 0..100 {
            x = rk4_step(|_, s| m.derivative(s, &act, &still()), 0.0, &x, h);
        }
        // After one time constant: 1 - e^-1 of the step.
        let frac = 1.0 - (-1.0f64).exp();
        assert!(
            (x[idx::N_PORT] - 100.0 * frac).abs() < 1e-6,
            "{}",
            x[idx::N_PORT]
        );
        assert!((x[idx::N_STB] + 50.0 * frac).abs() < 1e-6);
    }

    #[test]
    fn energy_balance_holds_under_rk4() {
        // d/dt (1/2 nu^T M nu) = nu^T (tau + drag): the Coriolis terms do no work.
        // Integrating the power along an RK4 trajectory must give the energy change.
        let m = model();
        let act = Actuation {
            n_cmd_radps: [95.0, 40.0],
            loss: [0.0; 2],
        };
        let energy = |x: &StateVector| {
            let nu = Vector3::new(x[idx::U], x[idx::V], x[idx::R]);
            0.5 * nu.dot(&(m.params.mass_matrix * nu))
        };
        let power = |x: &StateVector| {
            let nu = Vector3::new(x[idx::U], x[idx::V], x[idx::R]);
            let f = m.propulsion([x[idx::N_PORT], x[idx::N_STB]], act.loss)
                + m.damping_force(&nu)
                + m.crossflow_force(&nu);
            nu.dot(&f)
        };
        let mut x = StateVector::zeros();
        x[idx::U] = 1.0;
        let h = 0.002;
        let e0 = energy(&x);
        let mut work = 0.0;
        let mut p_prev = power(&x);
        for _ in 0..10_000 {
            x = rk4_step(|_, s| m.derivative(s, &act, &still()), 0.0, &x, h);
            let p_now = power(&x);
            work += 0.5 * (p_prev + p_now) * h;
            p_prev = p_now;
        }
        let e1 = energy(&x);
        assert!(x[idx::R].abs() > 0.1, "the craft should be turning: {x}");
        let err = (e1 - e0 - work).abs();
        assert!(
            err < 1e-4 * (e1.abs() + work.abs()),
            "dE {} vs work {work}",
            e1 - e0
        );
    }

    #[test]
    fn coasting_craft_loses_energy_monotonically() {
        let m = model();
        let act = Actuation {
            n_cmd_radps: [0.0; 2],
            loss: [0.0; 2],
        };
        let mut x = StateVector::zeros();
        x[idx::U] = 2.0;
        x[idx::V] = 0.3;
        x[idx::R] = 0.4;
        let energy = |x: &StateVector| {
            let nu = Vector3::new(x[idx::U], x[idx::V], x[idx::R]);
            0.5 * nu.dot(&(m.params.mass_matrix * nu))
        };
        let mut e = energy(&x);
        for _ in 0..2000 {
            x = rk4_step(|_, s| m.derivative(s, &act, &still()), 0.0, &x, 0.01);
            let e_next = energy(&x);
            assert!(e_next <= e + 1e-12, "{e_next} > {e}");
            e = e_next;
        }
        assert!(e < 1e-3, "{e}");
    }

    /// The estimator's model (`twin_core::models::otter_twin`) and this
    /// one describe the same Otter: at the profile's parameters their
    /// accelerations agree over the velocities and shaft speeds the trials
    /// sail, ahead, astern, turning both ways and saturated. What they do
    /// differently is the cross-flow drag (here Hoerner's coefficient over
    /// strips, there a coefficient of 1 integrated exactly), well inside
    /// the bound. A change to the physics of one and not the other fails
    /// here: the hidden-effect tests read a difference of the two models as
    /// an effect in the water.
    #[test]
    fn the_twins_model_has_the_same_accelerations() {
        use twin_core::model::Model;
        use twin_core::models::otter_twin::{Faults, OtterTwin, ShaftSpeeds, State, idx as twin};
        let sim = model();
        let estimator = OtterTwin::default();
        let dt_s = 1e-6;
        let mut worst = [0.0_f64; 3];
        for u in [-0.5, 0.0, 0.8, 1.5, 2.5] {
            for v in [-0.3, 0.0, 0.2] {
                for r in [-0.3, 0.0, 0.15, 0.4] {
                    for shafts in [
                        [0.0, 0.0],
                        [60.0, 60.0],
                        [90.0, 40.0],
                        [40.0, 90.0],
                        [-50.0, 60.0],
                        [-80.0, -80.0],
                        [500.0, 500.0],
                    ] {
                        let mut xs = StateVector::zeros();
                        (xs[idx::U], xs[idx::V], xs[idx::R]) = (u, v, r);
                        (xs[idx::N_PORT], xs[idx::N_STB]) = (shafts[0], shafts[1]);
                        let act = Actuation {
                            n_cmd_radps: shafts,
                            loss: [0.0; 2],
                        };
                        let simulated = sim.derivative(&xs, &act, &still());
                        let mut xt = State::zeros();
                        (xt[twin::U], xt[twin::V], xt[twin::R]) = (u, v, r);
                        let input = ShaftSpeeds {
                            port_radps: shafts[0],
                            starboard_radps: shafts[1],
                        };
                        let next = estimator.propagate(&xt, &input, &Faults::zeros(), dt_s);
                        for (k, (i, j)) in [(idx::U, twin::U), (idx::V, twin::V), (idx::R, twin::R)]
                            .into_iter()
                            .enumerate()
                        {
                            let estimated = (next[j] - xt[j]) / dt_s;
                            worst[k] = worst[k].max((estimated - simulated[i]).abs());
                        }
                    }
                }
            }
        }
        // Surge, sway (m/s^2) and yaw (rad/s^2): accelerations of the order
        // of 1 over this grid.
        assert!(worst.iter().all(|w| *w < 2e-3), "{worst:?}");
    }
}
