//! The extended twin: the Otter's kinetic model in surge, sway and yaw,
//! driven by the measured propeller speeds. It estimates each propeller's
//! loss, and beside it what a real vessel and its sensors get wrong about
//! the model's numbers: the hull's surge and yaw damping as the profile
//! gives them, a heading sensor's offset, a rate sensor's bias, and the
//! water current (docs/model.md sections 5 and 8).
//!
//! State (10) `[north_m, east_m, psi_rad, u_mps, v_mps, r_radps,
//! current_north_mps, current_east_mps, heading_bias_rad,
//! yaw_rate_bias_radps]`; `u`, `v` are the velocities through the water in
//! the body frame; the heading bias is what the heading sensor reads minus
//! the true heading, the yaw-rate bias what the rate sensor reads minus the
//! true yaw rate. Faults (4) `theta =
//! [loss_port, loss_starboard, surge_damping, yaw_damping]`: the two losses
//! of effectiveness and the relative errors of the linear surge damping and
//! of the (linear and quadratic) yaw damping, `X_u (1 + theta_2)`,
//! `N_r (1 + theta_3)`. Measurement (6) `[north_m, east_m, sog_mps, cog_rad,
//! heading_rad, yaw_rate_radps]` (any may be missing). Input: the two shaft
//! speeds.
//!
//! ```text
//! eta'  = R(psi) [u, v] + c,   psi' = r,   c' = b' = g' = 0 (+ noise)
//! (1 + th_m) M nu' = tau(n, theta) - C(nu) nu + [X_u (1 + th_u) u, Y_v v + Y_cf, N_r (1 + th_r) (1 + 10|r|) r + N_cf]
//! tau   = [(1-th_p) T_p + (1-th_s) T_s, 0, b ((1-th_p) T_p - (1-th_s) T_s)],  T = (1 + th_k) k n|n|
//! C(nu) nu = [-m x_g r^2 - (m + a22) v r, (m + a11) u r, m x_g u r + (a22 - a11) u v]
//! heading = psi + b,  yaw rate = r + g
//! ```
//!
//! Why the damping and thrust errors are estimated with the losses: a hull
//! that is draggier than the profile, propellers that give less thrust than
//! the profile says, or both propellers having lost some, slow the vessel
//! alike on a straight run; only the yaw response to differential thrust
//! tells them apart, and only as well as the yaw damping is known; and
//! scaling the mass, the damping and the thrust together changes no motion
//! at all. With the profile's errors among the filter's unknowns,
//! the covariance of the losses carries that ambiguity instead of claiming
//! a certainty the data do not give (docs/model.md section 8). Why the
//! heading bias is a state: a heading sensor off by a few degrees, read as
//! exact, makes the model's sway and yaw balance wrong in every turn, and
//! the filter would explain it with a one-sided loss. The rate sensor's bias
//! likewise: read as exact, a gyro 0.5 deg/s off is a steady yaw moment the
//! filter can only give to one propeller (over seeds 1-8 of the trust
//! matrix with every gyro so biased, 277 of 913 healthy propellers declared
//! FAULT with the bias held at zero, none with it estimated). The heading's
//! changes, or the course's, tell it.
//!
//! Writing the kinetics in the velocity through the water is exact for a
//! constant, irrotational current (Fossen 2021, property 10.1). The cross-flow
//! drag `Y_cf, N_cf = -1/2 rho T C_D int [1, x] |v + x r| (v + x r) dx` over the
//! hull is integrated exactly (the integrand is a piecewise polynomial; see
//! [`crossflow`]).
//!
//! One filter step integrates the state with classical Runge-Kutta (4th
//! order) in sub-steps of at most [`MAX_SUBSTEP_S`] and half the fastest
//! (yaw) time constant over the step (from the yaw rate at its start and an
//! Euler guess at its end): at `h lambda = 0.5` one RK4 sub-step decays the
//! yaw mode by 0.6068 against the exact 0.6065, and a steady turn is a
//! fixed point of RK4 whatever `h`. The Jacobians are the expansion
//! `I + h A + h^2 A^2 / 2 + h^3 A^3 / 6` of `exp(h A)` with `A` taken at the
//! sub-step's midpoint (and the matching fault sensitivity), chained over the
//! sub-steps; their error is then dominated by `A` varying over the
//! sub-step (third order in `h`). The state must be accurate (the
//! fault estimate settles where the innovations average zero); the
//! Jacobians only steer the gains.

use nalgebra::{Matrix3, SMatrix, SVector, Vector2, Vector3};

use crate::geodesy::wrap_pi;
use crate::linalg::{Pattern, mul, mul_sparse_left};
use crate::model::{Model, Observation, Transition};
use crate::models::effects::{BodyMotion, SensorEffects, body, gnss_measurement_of_body};
use crate::trig;
use crate::vessel::VesselParams;

/// Longest integration sub-step, seconds.
pub const MAX_SUBSTEP_S: f64 = 0.2;

/// The smallest factor a profile error scales its part of the model by
/// (`1 + error`: the damping, the thrust coefficient, the mass). The data
/// of a vessel that is not excited (a steady turn) do not stop the errors
/// wandering along the directions they cannot tell apart; held here, the
/// model never divides by a vanishing mass nor damps with a negative
/// resistance, and an error beyond it no longer moves the model, so the
/// filter learns nothing more along it. Within the two bounds the model is
/// unchanged.
pub const MIN_PROFILE_FACTOR: f64 = 0.1;

/// The largest such factor: ten times the profile's damping, thrust or
/// mass. Errors that wander upwards without bound (a day of steady turning)
/// would otherwise make the model so stiff that its integration fails.
pub const MAX_PROFILE_FACTOR: f64 = 10.0;

/// The factor `1 + error` held within [`MIN_PROFILE_FACTOR`] and
/// [`MAX_PROFILE_FACTOR`], and its derivative with respect to the error
/// (zero where it is held; a NaN error is held at the floor).
#[inline(always)]
fn profile_factor(error: f64) -> (f64, f64) {
    let factor = 1.0 + error;
    if factor > MAX_PROFILE_FACTOR {
        (MAX_PROFILE_FACTOR, 0.0)
    } else if factor >= MIN_PROFILE_FACTOR {
        (factor, 1.0)
    } else {
        (MIN_PROFILE_FACTOR, 0.0)
    }
}

/// [`profile_factor`] of each profile error of `theta`: surge damping, yaw
/// damping, thrust coefficient, mass.
#[inline(always)]
fn profile_factors(theta: &Faults) -> [(f64, f64); 4] {
    fault::PROFILE.map(|i| profile_factor(theta[i]))
}

/// Number of states.
pub const STATES: usize = 10;
/// Number of measurement components.
pub const MEASUREMENTS: usize = 6;
/// Number of faults.
pub const FAULTS: usize = 6;

/// The state vector.
pub type State = SVector<f64, STATES>;
/// The fault vector.
pub type Faults = SVector<f64, FAULTS>;

/// Index of each component in the state vector.
pub mod idx {
    /// North position, m.
    pub const NORTH: usize = 0;
    /// East position, m.
    pub const EAST: usize = 1;
    /// Heading, rad.
    pub const PSI: usize = 2;
    /// Surge velocity through the water, m/s.
    pub const U: usize = 3;
    /// Sway velocity through the water, m/s.
    pub const V: usize = 4;
    /// Yaw rate, rad/s.
    pub const R: usize = 5;
    /// Water current, north component, m/s.
    pub const CURRENT_NORTH: usize = 6;
    /// Water current, east component, m/s.
    pub const CURRENT_EAST: usize = 7;
    /// Heading sensor minus true heading, rad.
    pub const HEADING_BIAS: usize = 8;
    /// Rate sensor's yaw rate minus the true one (a gyro's bias), rad/s.
    pub const YAW_RATE_BIAS: usize = 9;
}

/// Index of each measurement component.
pub mod meas {
    /// North position, m.
    pub const NORTH: usize = 0;
    /// East position, m.
    pub const EAST: usize = 1;
    /// Speed over ground, m/s.
    pub const SOG: usize = 2;
    /// Course over ground, rad.
    pub const COG: usize = 3;
    /// Heading, rad.
    pub const HEADING: usize = 4;
    /// Yaw rate from a rate gyro, rad/s.
    pub const YAW_RATE: usize = 5;
}

/// Index of each fault.
pub mod fault {
    /// Loss of effectiveness of the port propeller.
    pub const PORT: usize = 0;
    /// Loss of effectiveness of the starboard propeller.
    pub const STARBOARD: usize = 1;
    /// Relative error of the linear surge damping (hull resistance).
    pub const SURGE_DAMPING: usize = 2;
    /// Relative error of the yaw damping.
    pub const YAW_DAMPING: usize = 3;
    /// Relative error of both propellers' thrust coefficient.
    pub const THRUST: usize = 4;
    /// Relative error of the mass matrix (rigid body and added mass).
    pub const MASS: usize = 5;
    /// The profile's errors, in order.
    pub const PROFILE: [usize; 4] = [SURGE_DAMPING, YAW_DAMPING, THRUST, MASS];
    /// Whether each fault is one of [`PROFILE`] (a mask over the faults,
    /// such as `AekfConfig::gain_sensitivity_faults` takes).
    pub const IS_PROFILE: [bool; super::FAULTS] = {
        let mut mask = [false; super::FAULTS];
        let mut k = 0;
        while k < PROFILE.len() {
            mask[PROFILE[k]] = true;
            k += 1;
        }
        mask
    };
}

/// A pattern with `true` at the listed `(row, column)` entries.
const fn pattern<const R: usize, const C: usize>(entries: &[(usize, usize)]) -> Pattern<R, C> {
    let mut p = [[false; C]; R];
    let mut k = 0;
    while k < entries.len() {
        p[entries[k].0][entries[k].1] = true;
        k += 1;
    }
    p
}

/// The entries of the continuous Jacobian `A = d xdot / d x` that may be
/// non-zero: the kinematics (position from heading, velocities and current;
/// heading from yaw rate) and the 3 x 3 block of the kinetics. The heading
/// bias moves nothing.
const A_PATTERN: Pattern<STATES, STATES> = {
    use idx::*;
    pattern(&[
        (NORTH, PSI),
        (NORTH, U),
        (NORTH, V),
        (NORTH, CURRENT_NORTH),
        (EAST, PSI),
        (EAST, U),
        (EAST, V),
        (EAST, CURRENT_EAST),
        (PSI, R),
        (U, U),
        (U, V),
        (U, R),
        (V, U),
        (V, V),
        (V, R),
        (R, U),
        (R, V),
        (R, R),
    ])
};

/// The entries of a step's transition Jacobian `F` that may be non-zero.
/// Each sub-step's `I + h A + h^2 A^2 / 2` has this pattern, and products of
/// such matrices keep it, so `F` (their product) does too.
const F_PATTERN: Pattern<STATES, STATES> = {
    use idx::*;
    pattern(&[
        (NORTH, NORTH),
        (NORTH, PSI),
        (NORTH, U),
        (NORTH, V),
        (NORTH, R),
        (NORTH, CURRENT_NORTH),
        (EAST, EAST),
        (EAST, PSI),
        (EAST, U),
        (EAST, V),
        (EAST, R),
        (EAST, CURRENT_EAST),
        (PSI, PSI),
        (PSI, U),
        (PSI, V),
        (PSI, R),
        (U, U),
        (U, V),
        (U, R),
        (V, U),
        (V, V),
        (V, R),
        (R, U),
        (R, V),
        (R, R),
        (CURRENT_NORTH, CURRENT_NORTH),
        (CURRENT_EAST, CURRENT_EAST),
        (HEADING_BIAS, HEADING_BIAS),
        (YAW_RATE_BIAS, YAW_RATE_BIAS),
    ])
};

/// The entries of the observation Jacobian `H` that may be non-zero without
/// [`SensorEffects`]: the position from the position, the heading from the
/// heading and its bias, the yaw rate from the yaw rate, and the speed and
/// course over ground from the heading, the velocities through the water
/// and the current.
const H_PATTERN_WITHOUT_EFFECTS: Pattern<MEASUREMENTS, STATES> = {
    use idx::*;
    let velocity = [PSI, U, V, CURRENT_NORTH, CURRENT_EAST];
    let mut p = [[false; STATES]; MEASUREMENTS];
    p[meas::NORTH][NORTH] = true;
    p[meas::EAST][EAST] = true;
    p[meas::HEADING][PSI] = true;
    p[meas::HEADING][HEADING_BIAS] = true;
    p[meas::YAW_RATE][R] = true;
    p[meas::YAW_RATE][YAW_RATE_BIAS] = true;
    let mut k = 0;
    while k < velocity.len() {
        p[meas::SOG][velocity[k]] = true;
        p[meas::COG][velocity[k]] = true;
        k += 1;
    }
    p
};

/// The entries of the observation Jacobian `H` that may be non-zero, with
/// or without [`SensorEffects`]: an antenna off the body origin and a
/// latency make the position and the velocity over ground depend on
/// heading, velocities, yaw rate and current.
const H_PATTERN: Pattern<MEASUREMENTS, STATES> = {
    use idx::*;
    let velocity = [PSI, U, V, R, CURRENT_NORTH, CURRENT_EAST];
    let mut p = H_PATTERN_WITHOUT_EFFECTS;
    let mut k = 0;
    while k < velocity.len() {
        p[meas::NORTH][velocity[k]] = true;
        p[meas::EAST][velocity[k]] = true;
        p[meas::SOG][velocity[k]] = true;
        p[meas::COG][velocity[k]] = true;
        k += 1;
    }
    p
};

/// The `R x C` block at rows `r0..`, columns `c0..` of a state pattern.
const fn block<const R: usize, const C: usize>(
    full: &Pattern<STATES, STATES>,
    r0: usize,
    c0: usize,
) -> Pattern<R, C> {
    let mut p = [[false; C]; R];
    let mut i = 0;
    while i < R {
        let mut j = 0;
        while j < C {
            p[i][j] = full[r0 + i][c0 + j];
            j += 1;
        }
        i += 1;
    }
    p
}

/// `E`, the heading-to-position block of `A` (rows and columns eta): only
/// the psi column of the north and east rows.
const A_ETA_ETA: Pattern<3, 3> = block(&A_PATTERN, 0, 0);
/// `N`, the velocity-to-position block of `A` (rows eta, columns nu).
const A_ETA_NU: Pattern<3, 3> = block(&A_PATTERN, 0, 3);
/// `F` rows and columns eta: the identity and the psi column.
const F_ETA_ETA: Pattern<3, 3> = block(&F_PATTERN, 0, 0);

/// The twin's input: the two shaft speeds over the step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ShaftSpeeds {
    /// Port shaft speed, rad/s.
    pub port_radps: f64,
    /// Starboard shaft speed, rad/s.
    pub starboard_radps: f64,
}

/// The Otter's kinetic twin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OtterTwin {
    /// The vessel's parameters.
    pub params: VesselParams,
    /// Effects on the measurement (none by default).
    pub effects: SensorEffects,
    /// `M^-1`, computed once.
    mass_inverse: Matrix3<f64>,
}

impl OtterTwin {
    /// The twin of a vessel with `params`.
    pub fn new(params: VesselParams) -> Self {
        let mass_inverse = params
            .mass_matrix
            .try_inverse()
            .unwrap_or_else(Matrix3::identity);
        Self {
            params,
            effects: SensorEffects::default(),
            mass_inverse,
        }
    }

    /// The same twin with effects on its measurement.
    pub fn with_effects(mut self, effects: SensorEffects) -> Self {
        self.effects = effects;
        self
    }
}

impl Default for OtterTwin {
    fn default() -> Self {
        Self::new(VesselParams::default())
    }
}

/// Exact integrals of the cross-flow drag over the hull.
pub mod crossflow {
    /// `int_{-L/2}^{L/2} x^k |w| w dx` for `k = 0, 1` and
    /// `int x^k 2|w| dx` for `k = 0, 1, 2`, with `w = v + r x`.
    #[derive(Debug, Clone, Copy, PartialEq, Default)]
    pub struct Integrals {
        /// `int |w| w dx`.
        pub w_abs_w: f64,
        /// `int x |w| w dx`.
        pub x_w_abs_w: f64,
        /// `int 2|w| dx` (d/dv of the first).
        pub d0: f64,
        /// `int 2|w| x dx`.
        pub d1: f64,
        /// `int 2|w| x^2 dx`.
        pub d2: f64,
    }

    /// The integrals over `[-L/2, L/2]`, in closed form (below).
    #[inline]
    pub fn integrals(v: f64, r: f64, length_m: f64) -> Integrals {
        integrate::<true>(v, r, length_m)
    }

    /// The two force integrals alone (`w_abs_w`, `x_w_abs_w`; the
    /// derivative fields are left zero): what the state derivative needs.
    #[inline]
    pub fn forces(v: f64, r: f64, length_m: f64) -> Integrals {
        integrate::<false>(v, r, length_m)
    }

    /// The integrals, with the derivatives when `DERIVATIVES`. With
    /// `h = L/2`, `w_a = v - r h` and `w_b = v + r h` at the ends:
    /// - where `w` keeps the sign `s` of `v` over the hull (`|v| >= |r| h`),
    ///   `|w| w = s w^2` and every integrand is a polynomial:
    ///   `int |w| w = s (2 h v^2 + 2 r^2 h^3 / 3)`, `int x |w| w = 4 s v r h^3 / 3`,
    ///   `int 2|w| = 4 h |v|`, `int 2|w| x = 4 s r h^3 / 3`,
    ///   `int 2|w| x^2 = 4 |v| h^3 / 3`;
    /// - where it changes sign on the hull (`|v| < |r| h`, so `r != 0`), from
    ///   `d|w|^3/dx = 3 r |w| w`, `d(|w| w)/dx = 2 r |w|` and
    ///   `d(|w|^3 w)/dx = 4 r |w|^3`, integrating by parts:
    ///   `int |w| w = [|w|^3] / 3r`,
    ///   `int x |w| w = [x |w|^3] / 3r - [|w|^3 w] / 12 r^2`,
    ///   `int 2|w| = [|w| w] / r`, `int 2|w| x = ([x |w| w] - int |w| w) / r`,
    ///   `int 2|w| x^2 = ([x^2 |w| w] - 2 int x |w| w) / r`,
    ///   with `[g] = g(h) - g(-h)`. Here `|v| < |r| h` bounds every term by a
    ///   small multiple of the result's scale (`r^2 h^3`, `|r| h^4`), so the
    ///   differences lose at most a few bits of it.
    #[inline(always)]
    fn integrate<const DERIVATIVES: bool>(v: f64, r: f64, length_m: f64) -> Integrals {
        let h = 0.5 * length_m;
        let h3 = h * h * h;
        let mut out = Integrals::default();
        if v.abs() >= r.abs() * h {
            let s = if v >= 0.0 { 1.0 } else { -1.0 };
            out.w_abs_w = s * (2.0 * h * v * v + (2.0 / 3.0) * r * r * h3);
            out.x_w_abs_w = s * (4.0 / 3.0) * v * r * h3;
            if DERIVATIVES {
                out.d0 = 4.0 * h * v.abs();
                out.d1 = s * (4.0 / 3.0) * r * h3;
                out.d2 = (4.0 / 3.0) * v.abs() * h3;
            }
            return out;
        }
        let inv_r = 1.0 / r;
        let (w_a, w_b) = (v - r * h, v + r * h);
        let (abs_a, abs_b) = (w_a.abs(), w_b.abs());
        let (cube_a, cube_b) = (abs_a * abs_a * abs_a, abs_b * abs_b * abs_b);
        out.w_abs_w = (cube_b - cube_a) * (inv_r / 3.0);
        out.x_w_abs_w = h * (cube_b + cube_a) * (inv_r / 3.0)
            - (cube_b * w_b - cube_a * w_a) * (inv_r * inv_r / 12.0);
        if DERIVATIVES {
            let (sq_a, sq_b) = (abs_a * w_a, abs_b * w_b);
            out.d0 = (sq_b - sq_a) * inv_r;
            out.d1 = (h * (sq_b + sq_a) - out.w_abs_w) * inv_r;
            out.d2 = (h * h * (sq_b - sq_a) - 2.0 * out.x_w_abs_w) * inv_r;
        }
        out
    }
}

/// The continuous-time dynamics at one point: the state derivative, its
/// Jacobian `A` and the fault sensitivity `B = d xdot / d theta`.
///
/// `A` is kept as its blocks that can be non-zero (see
/// [`block_structure_holds`]): rows eta (north, east, psi) against eta, nu
/// and the constants (current and heading bias), and rows nu against nu;
/// `B` as its nu rows.
struct Derivatives {
    xdot: State,
    /// `A` rows eta, columns eta (`E`).
    a_eta_eta: Matrix3<f64>,
    /// `A` rows eta, columns nu (`N`).
    a_eta_nu: Matrix3<f64>,
    /// `A` rows eta, columns of the constants (`C`).
    a_eta_const: Matrix3<f64>,
    /// `A` rows nu, columns nu (`D`).
    a_nu_nu: Matrix3<f64>,
    /// `B` rows nu.
    b_nu: SMatrix<f64, 3, FAULTS>,
}

impl Derivatives {
    /// `A` as a full matrix.
    #[cfg(test)]
    fn a(&self) -> SMatrix<f64, STATES, STATES> {
        let mut a = SMatrix::<f64, STATES, STATES>::zeros();
        a.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.a_eta_eta);
        a.fixed_view_mut::<3, 3>(0, 3).copy_from(&self.a_eta_nu);
        a.fixed_view_mut::<3, 3>(0, 6).copy_from(&self.a_eta_const);
        a.fixed_view_mut::<3, 3>(3, 3).copy_from(&self.a_nu_nu);
        a
    }

    /// `B` as a full matrix.
    #[cfg(test)]
    fn b(&self) -> SMatrix<f64, STATES, FAULTS> {
        let mut b = SMatrix::<f64, STATES, FAULTS>::zeros();
        b.fixed_view_mut::<3, FAULTS>(3, 0).copy_from(&self.b_nu);
        b
    }
}

/// Whether `A_PATTERN` has the block structure [`SubstepJacobians`] relies
/// on. With `eta = (north, east, psi)`, `nu = (u, v, r)` and `c` the
/// constants the dynamics read (current, heading bias): `A = [[E, N, C],
/// [0, D, 0], [0, 0, 0]]`, where `E` is non-zero only in the psi column of
/// the north and east rows (so `E^2 = 0`) and `C` is zero in the psi row
/// (so `E C = 0`). The rate sensor's bias enters only the measurement: its
/// column of `A` is zero (`SubstepJacobians` keeps `C` as 3 x 3).
const fn block_structure_holds(a: &Pattern<STATES, STATES>) -> bool {
    let mut i = 0;
    while i < STATES {
        let mut j = 0;
        while j < STATES {
            let eta_row = i < 3;
            let nu_row = i >= 3 && i < 6;
            let allowed = if eta_row && j < 3 {
                j == idx::PSI && i != idx::PSI
            } else if j == idx::YAW_RATE_BIAS {
                false
            } else if eta_row && j >= 6 {
                i != idx::PSI
            } else if eta_row {
                true
            } else if nu_row {
                j >= 3 && j < 6
            } else {
                false
            };
            if a[i][j] && !allowed {
                return false;
            }
            j += 1;
        }
        i += 1;
    }
    true
}

const _: () = assert!(block_structure_holds(&A_PATTERN));

/// A step's transition Jacobian `F` and fault sensitivity `Psi`, kept as the
/// blocks that can be non-zero (the rest of `F` is the identity on the
/// constants and zero). With `A = [[E, N, C], [0, D, 0], [0, 0, 0]]` (see
/// [`block_structure_holds`]) every power of `A`, and so `exp(h A)` and every
/// product of such matrices, is `[[I + *, *, *], [0, *, 0], [0, 0, I]]`, and
/// the fault sensitivity is zero in the constants' rows. Working on these
/// 3 x 3 blocks skips the structural zeros without testing for them.
#[derive(Debug, Clone, Copy)]
struct SubstepJacobians {
    /// `F` rows eta, columns eta.
    eta_eta: Matrix3<f64>,
    /// `F` rows eta, columns nu.
    eta_nu: Matrix3<f64>,
    /// `F` rows eta, columns of the constants.
    eta_const: Matrix3<f64>,
    /// `F` rows nu, columns nu.
    nu_nu: Matrix3<f64>,
    /// `Psi` rows eta.
    fault_eta: SMatrix<f64, 3, FAULTS>,
    /// `Psi` rows nu.
    fault_nu: SMatrix<f64, 3, FAULTS>,
}

impl SubstepJacobians {
    /// `exp(h A)` and `int_0^h exp(A s) ds B` to third order in `h A`, from
    /// the derivatives `d` at one point:
    /// `F = I + hA + (hA)^2 / 2 + (hA)^3 / 6` and
    /// `Psi = h (B + hA B / 2 + (hA)^2 B / 6)`, block by block. With
    /// `E^2 = 0` and `E C = 0` the blocks of the powers are
    /// `(hA)^2 = [[0, EN + ND, 0], [0, D^2, 0], 0]` and
    /// `(hA)^3 = [[0, E(EN + ND) + N D^2, 0], [0, D^3, 0], 0]`; `B` is zero
    /// outside the nu rows. Grouped with `T = I/2 + D/6` and
    /// `G = I + D T = I + D/2 + D^2/6`:
    /// `F_nu,nu = I + D G`, `F_eta,nu = N G + E (N T)`,
    /// `Psi_nu = h G B` and `Psi_eta = h (N T + E N / 6) B`.
    #[inline(always)]
    fn exp_third_order(d: &Derivatives, h: f64) -> Self {
        let e = d.a_eta_eta * h;
        let n = d.a_eta_nu * h;
        let c = d.a_eta_const * h;
        let dd = d.a_nu_nu * h;
        let b = d.b_nu;
        // Products by E and N skip their structural zeros.
        let e_times = |m: &Matrix3<f64>| mul_sparse_left(&e, &A_ETA_ETA, m);
        let n_times = |m: &Matrix3<f64>| mul_sparse_left(&n, &A_ETA_NU, m);
        let t = Matrix3::from_fn(|i, j| if i == j { 0.5 } else { 0.0 } + dd[(i, j)] * (1.0 / 6.0));
        let g = Matrix3::identity() + mul(&dd, &t);
        let n_t = n_times(&t);
        let fault_eta_gain = n_t + e_times(&n) * (1.0 / 6.0);
        Self {
            eta_eta: Matrix3::identity() + e,
            eta_nu: n_times(&g) + e_times(&n_t),
            eta_const: c,
            nu_nu: Matrix3::identity() + mul(&dd, &g),
            fault_eta: mul(&fault_eta_gain, &b) * h,
            fault_nu: mul(&g, &b) * h,
        }
    }

    /// This step followed by `next`: `F = F_next F_self` and
    /// `Psi = F_next Psi_self + Psi_next`.
    #[inline(always)]
    fn then(&self, next: &Self) -> Self {
        let eta_eta = &next.eta_eta;
        Self {
            eta_eta: mul_sparse_left(eta_eta, &F_ETA_ETA, &self.eta_eta),
            eta_nu: mul_sparse_left(eta_eta, &F_ETA_ETA, &self.eta_nu)
                + mul(&next.eta_nu, &self.nu_nu),
            eta_const: mul_sparse_left(eta_eta, &F_ETA_ETA, &self.eta_const) + next.eta_const,
            nu_nu: mul(&next.nu_nu, &self.nu_nu),
            fault_eta: mul_sparse_left(eta_eta, &F_ETA_ETA, &self.fault_eta)
                + mul(&next.eta_nu, &self.fault_nu)
                + next.fault_eta,
            fault_nu: mul(&next.nu_nu, &self.fault_nu) + next.fault_nu,
        }
    }

    /// `F` and `Psi` as full matrices.
    #[inline(always)]
    fn to_matrices(self) -> (SMatrix<f64, STATES, STATES>, SMatrix<f64, STATES, FAULTS>) {
        let mut f = SMatrix::<f64, STATES, STATES>::identity();
        f.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.eta_eta);
        f.fixed_view_mut::<3, 3>(0, 3).copy_from(&self.eta_nu);
        f.fixed_view_mut::<3, 3>(0, 6).copy_from(&self.eta_const);
        f.fixed_view_mut::<3, 3>(3, 3).copy_from(&self.nu_nu);
        let mut psi = SMatrix::<f64, STATES, FAULTS>::zeros();
        psi.fixed_view_mut::<3, FAULTS>(0, 0)
            .copy_from(&self.fault_eta);
        psi.fixed_view_mut::<3, FAULTS>(3, 0)
            .copy_from(&self.fault_nu);
        (f, psi)
    }
}

impl OtterTwin {
    /// Propeller thrusts `[port, starboard]`, N.
    pub fn thrusts(&self, input: &ShaftSpeeds) -> Vector2<f64> {
        Vector2::new(
            self.params.thrust_n(input.port_radps),
            self.params.thrust_n(input.starboard_radps),
        )
    }

    /// The state derivative alone (three of every four evaluations in a
    /// sub-step): no Jacobians built, no cross-flow derivatives.
    fn xdot(&self, x: &State, thrust: &Vector2<f64>, theta: &Faults) -> State {
        self.derivatives::<false>(x, thrust, theta).xdot
    }

    /// The state derivative with its Jacobians.
    fn dynamics(&self, x: &State, thrust: &Vector2<f64>, theta: &Faults) -> Derivatives {
        self.derivatives::<true>(x, thrust, theta)
    }

    /// The derivatives at one point; `a` and `b` are filled only when
    /// `JACOBIANS` (left zero otherwise). Inlined into the two callers so
    /// that the unused parts are not computed.
    #[inline(always)]
    fn derivatives<const JACOBIANS: bool>(
        &self,
        x: &State,
        thrust: &Vector2<f64>,
        theta: &Faults,
    ) -> Derivatives {
        let p = &self.params;
        let (psi, u, v, r) = (x[idx::PSI], x[idx::U], x[idx::V], x[idx::R]);
        let (s, c) = trig::sin_cos(psi);
        let m = p.mass_kg;
        let mxg = m * p.cg_x_m;
        let a11 = -p.added_mass[0];
        let a22 = -p.added_mass[1];
        let [xu0, yv, nr0] = p.linear_damping;
        let [surge, yaw, thrust_scale, mass] = profile_factors(theta);
        let (xu, nr) = (xu0 * surge.0, nr0 * yaw.0);
        let k_nl = p.yaw_damping_nonlinear_s;
        let b = p.propeller_offset_m;
        let cf = 0.5 * p.water_density_kgpm3 * p.draft_m * p.crossflow_drag_coeff;
        let ints = if JACOBIANS {
            crossflow::integrals(v, r, p.length_m)
        } else {
            crossflow::forces(v, r, p.length_m)
        };

        let scale = thrust_scale.0;
        let healthy = [
            (1.0 - theta[fault::PORT]) * thrust[0],
            (1.0 - theta[fault::STARBOARD]) * thrust[1],
        ];
        let eff = [scale * healthy[0], scale * healthy[1]];
        let tau = Vector3::new(eff[0] + eff[1], 0.0, b * (eff[0] - eff[1]));
        let coriolis = Vector3::new(
            -mxg * r * r - (m + a22) * v * r,
            (m + a11) * u * r,
            mxg * u * r + (a22 - a11) * u * v,
        );
        let yaw_damping = (1.0 + k_nl * r.abs()) * r;
        let damping = Vector3::new(
            xu * u,
            yv * v - cf * ints.w_abs_w,
            nr * yaw_damping - cf * ints.x_w_abs_w,
        );
        // (1 + th_m) M nu' = g: the mass error divides the acceleration.
        let inertia = 1.0 / mass.0;
        let nu_dot = mul(&self.mass_inverse, &(tau - coriolis + damping)) * inertia;

        let mut xdot = State::zeros();
        xdot[idx::NORTH] = c * u - s * v + x[idx::CURRENT_NORTH];
        xdot[idx::EAST] = s * u + c * v + x[idx::CURRENT_EAST];
        xdot[idx::PSI] = r;
        xdot[idx::U] = nu_dot[0];
        xdot[idx::V] = nu_dot[1];
        xdot[idx::R] = nu_dot[2];

        let mut d = Derivatives {
            xdot,
            a_eta_eta: Matrix3::zeros(),
            a_eta_nu: Matrix3::zeros(),
            a_eta_const: Matrix3::zeros(),
            a_nu_nu: Matrix3::zeros(),
            b_nu: SMatrix::zeros(),
        };
        if JACOBIANS {
            // Rows north, east, psi of A; the columns of each block in
            // state order.
            d.a_eta_eta[(idx::NORTH, idx::PSI)] = -s * u - c * v;
            d.a_eta_eta[(idx::EAST, idx::PSI)] = c * u - s * v;
            d.a_eta_nu[(idx::NORTH, idx::U - 3)] = c;
            d.a_eta_nu[(idx::NORTH, idx::V - 3)] = -s;
            d.a_eta_nu[(idx::EAST, idx::U - 3)] = s;
            d.a_eta_nu[(idx::EAST, idx::V - 3)] = c;
            d.a_eta_nu[(idx::PSI, idx::R - 3)] = 1.0;
            d.a_eta_const[(idx::NORTH, idx::CURRENT_NORTH - 6)] = 1.0;
            d.a_eta_const[(idx::EAST, idx::CURRENT_EAST - 6)] = 1.0;
            // d g / d nu with g = tau - C nu + damping.
            let dg = Matrix3::new(
                xu,
                (m + a22) * r,
                2.0 * mxg * r + (m + a22) * v,
                -(m + a11) * r,
                yv - cf * ints.d0,
                -(m + a11) * u - cf * ints.d1,
                -mxg * r - (a22 - a11) * v,
                -(a22 - a11) * u - cf * ints.d1,
                nr * (1.0 + 2.0 * k_nl * r.abs()) - mxg * u - cf * ints.d2,
            );
            d.a_nu_nu = mul(&self.mass_inverse, &dg) * inertia;
            // d g / d theta.
            let dtau = SMatrix::<f64, 3, FAULTS>::new(
                -scale * thrust[0],
                -scale * thrust[1],
                xu0 * u * surge.1,
                0.0,
                (healthy[0] + healthy[1]) * thrust_scale.1,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                -b * scale * thrust[0],
                b * scale * thrust[1],
                0.0,
                nr0 * yaw_damping * yaw.1,
                b * (healthy[0] - healthy[1]) * thrust_scale.1,
                0.0,
            );
            d.b_nu = mul(&self.mass_inverse, &dtau) * inertia;
            // d nu' / d th_m = -nu' / (1 + th_m).
            d.b_nu
                .set_column(fault::MASS, &(nu_dot * (-inertia * mass.1)));
        }
        d
    }

    /// The number of RK4 sub-steps of a step of `dt_s` from `x0` (whose
    /// derivative is `xdot_start`), and the longest sub-step allowed.
    /// The nonlinear yaw damping shortens the yaw time constant to
    /// M33 / (|N_r| (1 + 2c|r|)) in a hard turn (0.14 s at 17 deg/s): keep
    /// sub-steps at half of it, and at most [`MAX_SUBSTEP_S`].
    fn substeps(&self, x0: &State, xdot_start: &State, theta: &Faults, dt_s: f64) -> (usize, f64) {
        let p = &self.params;
        let r_start = x0[idx::R];
        let r_end_euler = r_start + dt_s.min(MAX_SUBSTEP_S) * xdot_start[idx::R];
        let r_max = r_start.abs().max(r_end_euler.abs());
        let damping = -p.linear_damping[2] * profile_factor(theta[fault::YAW_DAMPING]).0;
        let inertia = p.mass_matrix[(2, 2)] * profile_factor(theta[fault::MASS]).0;
        let yaw_tau_s = inertia / (damping * (1.0 + 2.0 * p.yaw_damping_nonlinear_s * r_max));
        let max_h = MAX_SUBSTEP_S.min(0.5 * yaw_tau_s);
        let substeps = (dt_s / max_h).ceil().clamp(1.0, 1000.0) as usize;
        (substeps, max_h)
    }

    /// One filter step.
    #[inline(always)]
    fn step(
        &self,
        x0: &State,
        input: &ShaftSpeeds,
        theta: &Faults,
        dt_s: f64,
    ) -> Transition<STATES, FAULTS> {
        let thrust = self.thrusts(input);
        // The derivative at the start, also the first sub-step's k1.
        let xdot_start = self.xdot(x0, &thrust, theta);
        let (substeps, _) = self.substeps(x0, &xdot_start, theta, dt_s);
        let h = dt_s / substeps as f64;
        let mut x = *x0;
        let mut jacobians: Option<SubstepJacobians> = None;
        for substep in 0..substeps {
            // The state by classical RK4; the Jacobians of the sub-step from
            // the derivatives at its midpoint (the second RK stage), as
            // exp(h A_mid) to third order: accurate to O(h^3) (A_mid).
            let k1 = if substep == 0 {
                xdot_start
            } else {
                self.xdot(&x, &thrust, theta)
            };
            let mid = self.dynamics(&(x + k1 * (0.5 * h)), &thrust, theta);
            let sub = SubstepJacobians::exp_third_order(&mid, h);
            jacobians = Some(match jacobians {
                // F and Psi start as I and 0: the products would copy.
                None => sub,
                Some(j) => j.then(&sub),
            });
            let k2 = mid.xdot;
            let k3 = self.xdot(&(x + k2 * (0.5 * h)), &thrust, theta);
            let k4 = self.xdot(&(x + k3 * h), &thrust, theta);
            x += (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0);
        }
        x[idx::PSI] = wrap_pi(x[idx::PSI]);
        let (f, psi) = jacobians.expect("at least one sub-step").to_matrices();
        Transition {
            next: x,
            jacobian: f,
            fault_sensitivity: psi,
        }
    }

    /// The state after a step, exactly as [`Self::step`] computes it, without
    /// the Jacobians (RK4 on the state derivative alone). When `midpoint`,
    /// also the derivatives at the step's midpoint: the state after half the
    /// sub-steps when their number is even, else the middle sub-step's
    /// second RK stage (its own midpoint, which is the step's).
    #[inline(always)]
    fn propagate_state(
        &self,
        x0: &State,
        thrust: &Vector2<f64>,
        theta: &Faults,
        dt_s: f64,
        midpoint: bool,
    ) -> (State, Option<Derivatives>, f64) {
        let xdot_start = self.xdot(x0, thrust, theta);
        let (substeps, max_h) = self.substeps(x0, &xdot_start, theta, dt_s);
        let h = dt_s / substeps as f64;
        let middle = substeps / 2;
        let mut at_midpoint = None;
        let mut x = *x0;
        for substep in 0..substeps {
            let k1 = if substep == 0 {
                xdot_start
            } else if midpoint && substeps % 2 == 0 && substep == middle {
                let d = self.dynamics(&x, thrust, theta);
                let k1 = d.xdot;
                at_midpoint = Some(d);
                k1
            } else {
                self.xdot(&x, thrust, theta)
            };
            let x2 = x + k1 * (0.5 * h);
            let k2 = if midpoint && substeps % 2 == 1 && substep == middle {
                let d = self.dynamics(&x2, thrust, theta);
                let k2 = d.xdot;
                at_midpoint = Some(d);
                k2
            } else {
                self.xdot(&x2, thrust, theta)
            };
            let k3 = self.xdot(&(x + k2 * (0.5 * h)), thrust, theta);
            let k4 = self.xdot(&(x + k3 * h), thrust, theta);
            x += (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0);
        }
        x[idx::PSI] = wrap_pi(x[idx::PSI]);
        (x, at_midpoint, max_h)
    }

    /// A forecast's step: the state as [`Self::step`] (the same numbers),
    /// and the Jacobians over the whole step from `A` and `B` frozen at the
    /// step's midpoint: `F = exp(A dt)` and `Psi = int_0^dt exp(A s) ds B`,
    /// by the third-order expansion over `dt / 2^j` (no longer than a
    /// sub-step) and `j` doublings. Against the sub-step chain of `step`
    /// this drops the variation of `A` within the step (second order in
    /// `dt`, the midpoint rule): at the forecast's 1 s steps in a hard turn
    /// the difference is a fraction of a per cent (the test below), for a
    /// fifth of the derivative evaluations and products.
    #[inline(always)]
    fn forecast_step(
        &self,
        x0: &State,
        input: &ShaftSpeeds,
        theta: &Faults,
        dt_s: f64,
    ) -> Transition<STATES, FAULTS> {
        let thrust = self.thrusts(input);
        let (next, mid, max_h) = self.propagate_state(x0, &thrust, theta, dt_s, true);
        let mid = mid.expect("propagate_state evaluates the midpoint when asked");
        let mut doublings = 0;
        let mut h = dt_s;
        while h > max_h && doublings < 30 {
            h *= 0.5;
            doublings += 1;
        }
        let mut jacobians = SubstepJacobians::exp_third_order(&mid, h);
        for _ in 0..doublings {
            // int_0^2h = int_0^h + exp(A h) int_0^h; exp(2 A h) = exp(A h)^2.
            jacobians = jacobians.then(&jacobians);
        }
        let (f, psi) = jacobians.to_matrices();
        Transition {
            next,
            jacobian: f,
            fault_sensitivity: psi,
        }
    }

    /// The measurement model, with the sensors' effects, and its Jacobian.
    fn observe_state(&self, x: &State) -> Observation<STATES, MEASUREMENTS> {
        let motion = BodyMotion {
            north_m: x[idx::NORTH],
            east_m: x[idx::EAST],
            heading_rad: x[idx::PSI],
            surge_mps: x[idx::U],
            sway_mps: x[idx::V],
            yaw_rate_radps: x[idx::R],
            current_north_mps: x[idx::CURRENT_NORTH],
            current_east_mps: x[idx::CURRENT_EAST],
        };
        let (m, dm_db) = gnss_measurement_of_body(&motion, &self.effects);
        let mut jacobian = SMatrix::<f64, MEASUREMENTS, STATES>::zeros();
        for (row, dm) in dm_db.iter().enumerate() {
            jacobian[(row, idx::NORTH)] = dm[body::NORTH];
            jacobian[(row, idx::EAST)] = dm[body::EAST];
            jacobian[(row, idx::PSI)] = dm[body::HEADING];
            jacobian[(row, idx::U)] = dm[body::SURGE];
            jacobian[(row, idx::V)] = dm[body::SWAY];
            jacobian[(row, idx::R)] = dm[body::YAW_RATE];
            jacobian[(row, idx::CURRENT_NORTH)] = dm[body::CURRENT_NORTH];
            jacobian[(row, idx::CURRENT_EAST)] = dm[body::CURRENT_EAST];
        }
        jacobian[(meas::HEADING, idx::HEADING_BIAS)] = 1.0;
        jacobian[(meas::YAW_RATE, idx::R)] = self.effects.yaw_rate_scale;
        jacobian[(meas::YAW_RATE, idx::YAW_RATE_BIAS)] = 1.0;
        let predicted = SVector::<f64, MEASUREMENTS>::from([
            m[0],
            m[1],
            m[2],
            m[3],
            m[4] + x[idx::HEADING_BIAS],
            self.effects.yaw_rate_reading(x[idx::R]) + x[idx::YAW_RATE_BIAS],
        ]);
        Observation {
            predicted,
            jacobian,
        }
    }
}

const MEASUREMENT_ANGLES: [bool; MEASUREMENTS] = [false, false, false, true, true, false];
const STATE_NAMES: [&str; STATES] = [
    "north_m",
    "east_m",
    "heading_rad",
    "surge_mps",
    "sway_mps",
    "yaw_rate_radps",
    "current_north_mps",
    "current_east_mps",
    "heading_bias_rad",
    "yaw_rate_bias_radps",
];

impl Model<STATES, MEASUREMENTS, FAULTS> for OtterTwin {
    type Input = ShaftSpeeds;

    // Inlined into the filter's step, so that it runs in the step's AVX2
    // copy too (see `crate::simd`).
    #[inline(always)]
    fn transition(
        &self,
        x: &State,
        input: &ShaftSpeeds,
        theta: &Faults,
        dt_s: f64,
    ) -> Transition<STATES, FAULTS> {
        self.step(x, input, theta, dt_s)
    }

    fn propagate(&self, x: &State, input: &ShaftSpeeds, theta: &Faults, dt_s: f64) -> State {
        self.propagate_state(x, &self.thrusts(input), theta, dt_s, false)
            .0
    }

    // Inlined into the forecast, so that it runs in the forecast's AVX2
    // copy too (see `crate::simd`).
    #[inline(always)]
    fn forecast_transition(
        &self,
        x: &State,
        input: &ShaftSpeeds,
        theta: &Faults,
        dt_s: f64,
    ) -> Transition<STATES, FAULTS> {
        self.forecast_step(x, input, theta, dt_s)
    }

    fn observe(&self, x: &State) -> Observation<STATES, MEASUREMENTS> {
        self.observe_state(x)
    }

    fn measurement_angles(&self) -> [bool; MEASUREMENTS] {
        MEASUREMENT_ANGLES
    }

    fn state_angles(&self) -> [bool; STATES] {
        [
            false, false, true, false, false, false, false, false, true, false,
        ]
    }

    fn state_names(&self) -> [&'static str; STATES] {
        STATE_NAMES
    }

    const TRANSITION_PATTERN: Pattern<STATES, STATES> = F_PATTERN;

    const OBSERVATION_PATTERN: Pattern<MEASUREMENTS, STATES> = H_PATTERN;

    const SPARSER_OBSERVATION_PATTERN: Pattern<MEASUREMENTS, STATES> = H_PATTERN_WITHOUT_EFFECTS;

    fn observation_in_sparser_pattern(&self) -> bool {
        self.effects.is_neutral()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn state() -> State {
        State::from_column_slice(&[3.0, -4.0, 0.7, 1.6, 0.12, 0.08, 0.2, -0.1, 0.05, 0.004])
    }

    fn faults() -> Faults {
        Faults::from([0.2, 0.05, 0.15, -0.1, 0.12, -0.08])
    }

    #[test]
    fn the_profile_mask_marks_the_profiles_errors_and_nothing_else() {
        for i in 0..FAULTS {
            assert_eq!(
                fault::IS_PROFILE[i],
                fault::PROFILE.contains(&i),
                "fault {i}"
            );
        }
        assert!(!fault::IS_PROFILE[fault::PORT] && !fault::IS_PROFILE[fault::STARBOARD]);
    }

    #[test]
    fn crossflow_integrals_match_fine_quadrature() {
        // Both forms (sign kept, sign changing on the hull), both signs of
        // v and r, the boundary between the forms and either side of it, a
        // yaw rate too small to divide by, and still water.
        for (v, r) in [
            (0.2, 0.0),
            (0.0, 0.3),
            (0.1, -0.4),
            (-0.3, 0.05),
            (1e-9, 1e-9),
            (0.05, 0.2),
            (0.3, 0.3),
            (0.299_999, 0.3),
            (-0.300_001, 0.3),
            (-0.299_999, -0.3),
            (1.0, -2.0),
            (0.2, 1e-13),
            (0.0, 0.0),
            (-1.5, 0.7),
        ] {
            let ints = crossflow::integrals(v, r, 2.0);
            let forces = crossflow::forces(v, r, 2.0);
            assert_eq!(
                (forces.w_abs_w, forces.x_w_abs_w),
                (ints.w_abs_w, ints.x_w_abs_w)
            );
            let n = 200_000;
            let dx = 2.0 / n as f64;
            let mut fine = [0.0; 5];
            for k in 0..n {
                let x = -1.0 + (k as f64 + 0.5) * dx;
                let w: f64 = v + r * x;
                fine[0] += w.abs() * w * dx;
                fine[1] += x * w.abs() * w * dx;
                fine[2] += 2.0 * w.abs() * dx;
                fine[3] += 2.0 * w.abs() * x * dx;
                fine[4] += 2.0 * w.abs() * x * x * dx;
            }
            let exact = [ints.w_abs_w, ints.x_w_abs_w, ints.d0, ints.d1, ints.d2];
            for (i, (e, f)) in exact.iter().zip(fine).enumerate() {
                assert!((e - f).abs() < 1e-9, "v {v} r {r} integral {i}: {e} vs {f}");
            }
        }
    }

    /// Profile errors past [`MIN_PROFILE_FACTOR`]: a vessel with no mass,
    /// damping or thrust left, as an unexcited filter's errors can wander.
    fn faults_past_the_floor() -> Faults {
        Faults::from([0.2, 0.05, -1.3, -1.5, -2.0, -1.2])
    }

    /// Profile errors past [`MAX_PROFILE_FACTOR`]: the errors a day of
    /// steady turning drove upwards.
    fn faults_past_the_ceiling() -> Faults {
        Faults::from([0.2, 0.05, 9.5, 600.0, 12.0, 40.0])
    }

    /// The Jacobians, within the profile's floor and past it (where the
    /// profile errors' columns are zero: the model no longer moves with them).
    #[test]
    fn continuous_jacobians_match_finite_differences() {
        for theta in [faults(), faults_past_the_floor(), faults_past_the_ceiling()] {
            jacobians_match_finite_differences_at(&theta);
        }
    }

    /// Past the profile's bounds the model holds each factor at
    /// [`MIN_PROFILE_FACTOR`] or [`MAX_PROFILE_FACTOR`]: a second of steps
    /// stays finite, and errors further past them give the same step.
    #[test]
    fn profile_errors_past_the_bounds_leave_a_finite_model() {
        let twin = OtterTwin::default();
        let input = ShaftSpeeds {
            port_radps: 80.0,
            starboard_radps: 60.0,
        };
        for (past, further_by) in [
            (faults_past_the_floor(), -10.0),
            (faults_past_the_ceiling(), 1e6),
        ] {
            let mut further = past;
            for i in fault::PROFILE {
                further[i] += further_by;
            }
            let mut x = state();
            for _ in 0..10 {
                let step = twin.step(&x, &input, &past, 0.1);
                let same = twin.step(&x, &input, &further, 0.1);
                assert!(step.next.iter().all(|v| v.is_finite()), "{}", step.next);
                assert_eq!(step.next, same.next);
                x = step.next;
            }
            let held = twin.dynamics(&x, &Vector2::new(60.0, 45.0), &past);
            for j in fault::PROFILE {
                assert!(held.b().column(j).iter().all(|v| *v == 0.0), "column {j}");
            }
        }
    }

    fn jacobians_match_finite_differences_at(theta: &Faults) {
        let twin = OtterTwin::default();
        let thrust = Vector2::new(60.0, 45.0);
        let theta = *theta;
        let x = state();
        let d = twin.dynamics(&x, &thrust, &theta);
        let eps = 1e-6;
        for j in 0..STATES {
            let mut xp = x;
            let mut xm = x;
            xp[j] += eps;
            xm[j] -= eps;
            let num =
                (twin.xdot(&xp, &thrust, &theta) - twin.xdot(&xm, &thrust, &theta)) / (2.0 * eps);
            for i in 0..STATES {
                assert!(
                    (num[i] - d.a()[(i, j)]).abs() < 1e-5,
                    "A[{i},{j}]: {} vs {}",
                    d.a()[(i, j)],
                    num[i]
                );
            }
        }
        for j in 0..FAULTS {
            let mut tp = theta;
            tp[j] += eps;
            let num = (twin.xdot(&x, &thrust, &tp) - d.xdot) / eps;
            for i in 0..STATES {
                assert!((num[i] - d.b()[(i, j)]).abs() < 1e-5, "B[{i},{j}]");
            }
        }
    }

    /// The 3 x 3 block arithmetic of [`SubstepJacobians`] gives the dense
    /// third-order series and the dense chain rule, at a straight run, in a
    /// hard turn and reversing.
    #[test]
    fn jacobian_blocks_match_the_dense_series_and_chain() {
        let twin = OtterTwin::default();
        let thrust = Vector2::new(60.0, 45.0);
        let theta = faults();
        let mut hard_turn = state();
        hard_turn[idx::R] = 0.3;
        hard_turn[idx::V] = -0.2;
        let mut reversing = state();
        reversing[idx::U] = -0.8;
        reversing[idx::PSI] = -2.9;
        let close = |a: &[f64], b: &[f64], what: &str| {
            for (i, (x, y)) in a.iter().zip(b).enumerate() {
                assert!(
                    (x - y).abs() <= 1e-14 * (1.0 + y.abs()),
                    "{what}[{i}]: {x} vs {y}"
                );
            }
        };
        // The structure the block arithmetic relies on is checked when
        // compiling; a pattern without it (heading fed back into itself
        // through the position) is refused.
        let mut coupled = A_PATTERN;
        coupled[idx::PSI][idx::NORTH] = true;
        assert!(!block_structure_holds(&coupled));
        for x in [state(), hard_turn, reversing] {
            let d1 = twin.dynamics(&x, &thrust, &theta);
            let d2 = twin.dynamics(&(x + d1.xdot * 0.1), &thrust, &theta);
            for h in [0.05, 0.2] {
                let dense = |d: &Derivatives| {
                    let ha = d.a() * h;
                    let f = SMatrix::<f64, STATES, STATES>::identity()
                        + ha
                        + ha * ha * 0.5
                        + ha * ha * ha * (1.0 / 6.0);
                    let psi = (d.b() + ha * d.b() * 0.5 + ha * ha * d.b() * (1.0 / 6.0)) * h;
                    (f, psi)
                };
                let (f1, psi1) = dense(&d1);
                let (f2, psi2) = dense(&d2);
                let blocks1 = SubstepJacobians::exp_third_order(&d1, h);
                let blocks2 = SubstepJacobians::exp_third_order(&d2, h);
                let (f, psi) = blocks1.to_matrices();
                close(f.as_slice(), f1.as_slice(), "F");
                close(psi.as_slice(), psi1.as_slice(), "Psi");
                let (f, psi) = blocks1.then(&blocks2).to_matrices();
                close(f.as_slice(), (f2 * f1).as_slice(), "F chained");
                close(psi.as_slice(), (f2 * psi1 + psi2).as_slice(), "Psi chained");
            }
        }
    }

    /// Worst absolute difference between the step's Jacobians and central
    /// finite differences of the step itself.
    fn step_jacobian_errors(dt: f64) -> (f64, f64) {
        let x = &state();
        let twin = OtterTwin::default();
        let u = ShaftSpeeds {
            port_radps: 80.0,
            starboard_radps: 70.0,
        };
        let theta = Faults::from([0.2, 0.0, 0.0, 0.0, 0.0, 0.0]);
        let step = |x: &State, th: &Faults| Model::transition(&twin, x, &u, th, dt);
        let t = step(x, &theta);
        let eps = 1e-6;
        let (mut worst_f, mut worst_psi) = (0.0f64, 0.0f64);
        for j in 0..STATES {
            let (mut xp, mut xm) = (*x, *x);
            xp[j] += eps;
            xm[j] -= eps;
            let num = (step(&xp, &theta).next - step(&xm, &theta).next) / (2.0 * eps);
            for i in 0..STATES {
                worst_f = worst_f.max((num[i] - t.jacobian[(i, j)]).abs());
            }
        }
        for j in 0..FAULTS {
            let (mut tp, mut tm) = (theta, theta);
            tp[j] += eps;
            tm[j] -= eps;
            let num = (step(x, &tp).next - step(x, &tm).next) / (2.0 * eps);
            for i in 0..STATES {
                worst_psi = worst_psi.max((num[i] - t.fault_sensitivity[(i, j)]).abs());
            }
        }
        (worst_f, worst_psi)
    }

    /// The forecast's steps and the state-only steps give exactly the
    /// filter's next state (the diagnosis and the forecast rely on it), for
    /// steps of one and of several sub-steps, odd and even.
    #[test]
    fn forecast_and_state_only_steps_give_the_filters_state() {
        let twin = OtterTwin::default();
        let u = ShaftSpeeds {
            port_radps: 90.0,
            starboard_radps: 40.0,
        };
        let theta = Faults::from([0.1, 0.3, -0.2, 0.25, 0.2, -0.2]);
        let mut hard_turn = state();
        hard_turn[idx::R] = 0.3;
        for x in [state(), hard_turn] {
            for dt in [0.05, 0.2, 0.37, 0.6, 1.0, 2.5] {
                let filter = Model::transition(&twin, &x, &u, &theta, dt);
                let forecast = Model::forecast_transition(&twin, &x, &u, &theta, dt);
                let alone = Model::propagate(&twin, &x, &u, &theta, dt);
                assert_eq!(forecast.next, filter.next, "dt {dt}");
                assert_eq!(alone, filter.next, "dt {dt}");
            }
        }
    }

    /// The Jacobians are exp(h A_mid) to third order, with A taken at the
    /// sub-step's midpoint: their error shrinks like h^3 per sub-step (8x
    /// per halving). At the filter's 0.2 s step in a turn they are within
    /// about 1 % of the step's own derivatives.
    #[test]
    fn step_jacobians_converge_to_the_derivatives_of_the_step() {
        let (f_small, psi_small) = step_jacobian_errors(0.02);
        let (f_half, psi_half) = step_jacobian_errors(0.01);
        let (f_filter, psi_filter) = step_jacobian_errors(0.2);
        println!(
            "F error {f_small:.2e} at 0.02 s, {f_half:.2e} at 0.01 s, {f_filter:.2e} at 0.2 s; Psi {psi_small:.2e}, {psi_half:.2e}, {psi_filter:.2e}"
        );
        assert!(f_half < f_small / 6.0, "third order: {f_small} -> {f_half}");
        assert!(
            psi_half < psi_small / 6.0,
            "third order: {psi_small} -> {psi_half}"
        );
        assert!(
            f_filter < 1e-2 && psi_filter < 1e-3,
            "{f_filter} {psi_filter}"
        );
    }

    #[test]
    fn an_antenna_off_the_origin_shifts_the_fix() {
        let x = state();
        let moved = OtterTwin::default().with_effects(SensorEffects {
            antenna_m: [2.0, 0.0],
            ..Default::default()
        });
        let m = moved.observe_state(&x);
        let (s, c) = x[idx::PSI].sin_cos();
        assert!((m.predicted[meas::NORTH] - x[idx::NORTH] - 2.0 * c).abs() < 1e-12);
        assert!((m.predicted[meas::EAST] - x[idx::EAST] - 2.0 * s).abs() < 1e-12);
    }

    #[test]
    fn heading_and_yaw_rate_are_measured_with_the_sensors_bias() {
        let twin = OtterTwin::default();
        let x = state();
        let o = twin.observe_state(&x);
        assert_eq!(
            o.predicted[meas::HEADING],
            x[idx::PSI] + x[idx::HEADING_BIAS]
        );
        // The rate sensor reads the yaw rate plus its bias.
        assert_eq!(
            o.predicted[meas::YAW_RATE],
            x[idx::R] + x[idx::YAW_RATE_BIAS]
        );
        assert_eq!(o.jacobian[(meas::YAW_RATE, idx::R)], 1.0);
        assert_eq!(o.jacobian[(meas::YAW_RATE, idx::YAW_RATE_BIAS)], 1.0);
        // A rate sensor reading 4 % low measures 0.96 of the yaw rate, and
        // its row of H says so.
        let scaled = twin.with_effects(SensorEffects {
            yaw_rate_scale: 0.96,
            ..Default::default()
        });
        let o = scaled.observe_state(&x);
        let want = 0.96 * x[idx::R] + x[idx::YAW_RATE_BIAS];
        assert!((o.predicted[meas::YAW_RATE] - want).abs() < 1e-15);
        assert!((o.jacobian[(meas::YAW_RATE, idx::R)] - 0.96).abs() < 1e-6);
        assert!((o.jacobian[(meas::YAW_RATE, idx::YAW_RATE_BIAS)] - 1.0).abs() < 1e-6);
    }

    /// Without effects and with every effect on, `H` agrees with central
    /// differences of the measurement.
    #[test]
    fn observation_jacobian_matches_finite_differences() {
        let with_effects = OtterTwin::default().with_effects(SensorEffects {
            antenna_m: [0.8, -0.3],
            heading_offset_rad: 0.04,
            sog_scale: 0.97,
            gnss_latency_s: 0.4,
            yaw_rate_scale: 1.05,
            yaw_rate_bias_radps: 0.003,
        });
        let x = state();
        for twin in [OtterTwin::default(), with_effects] {
            let o = twin.observe_state(&x);
            let eps = 1e-6;
            for j in 0..STATES {
                let (mut up, mut down) = (x, x);
                up[j] += eps;
                down[j] -= eps;
                let num = (twin.observe_state(&up).predicted - twin.observe_state(&down).predicted)
                    / (2.0 * eps);
                for i in 0..MEASUREMENTS {
                    assert!(
                        (num[i] - o.jacobian[(i, j)]).abs() < 1e-7,
                        "H[{i},{j}]: {} analytic, {} numeric",
                        o.jacobian[(i, j)],
                        num[i]
                    );
                }
            }
        }
    }

    /// Every entry outside the declared patterns is exactly zero: of A, of
    /// the step's F over short and long steps (several sub-steps) in a hard
    /// turn, and of H with and without sensor effects.
    #[test]
    fn jacobians_keep_to_their_patterns() {
        let thrust = Vector2::new(60.0, 45.0);
        let theta = faults();
        let effects = SensorEffects {
            antenna_m: [0.4, -0.2],
            heading_offset_rad: 0.02,
            sog_scale: 1.03,
            gnss_latency_s: 0.15,
            yaw_rate_scale: 0.96,
            yaw_rate_bias_radps: 0.004,
        };
        let twin = OtterTwin::default();
        for (k, x) in [
            state(),
            State::from_column_slice(&[0.0, 0.0, -2.9, 2.5, -0.3, -0.4, -0.3, 0.25, -0.1, -0.006]),
        ]
        .into_iter()
        .enumerate()
        {
            let a = twin.dynamics(&x, &thrust, &theta).a();
            for dt in [0.05, 0.2, 1.0, 3.0] {
                let u = ShaftSpeeds {
                    port_radps: 90.0,
                    starboard_radps: -40.0,
                };
                let f = Model::transition(&twin, &x, &u, &theta, dt).jacobian;
                for i in 0..STATES {
                    for j in 0..STATES {
                        if !A_PATTERN[i][j] {
                            assert_eq!(a[(i, j)], 0.0, "A[{i},{j}] (state {k})");
                        }
                        if !F_PATTERN[i][j] {
                            assert_eq!(f[(i, j)], 0.0, "F[{i},{j}] at dt {dt} (state {k})");
                        }
                    }
                }
            }
            // Without effects H keeps to the sparser pattern too (and says
            // so); with them it does not, and says so.
            for t in [twin, twin.with_effects(effects)] {
                let sparser = Model::observation_in_sparser_pattern(&t);
                assert_eq!(sparser, t.effects.is_neutral());
                let h = Model::observe(&t, &x).jacobian;
                let pattern = if sparser {
                    H_PATTERN_WITHOUT_EFFECTS
                } else {
                    H_PATTERN
                };
                let mut outside_sparser = 0;
                for i in 0..MEASUREMENTS {
                    for j in 0..STATES {
                        if !pattern[i][j] {
                            assert_eq!(h[(i, j)], 0.0, "H[{i},{j}] (state {k}, {sparser})");
                        }
                        if !H_PATTERN_WITHOUT_EFFECTS[i][j] && h[(i, j)] != 0.0 {
                            outside_sparser += 1;
                        }
                    }
                }
                // The effects do reach outside the sparser pattern.
                assert_eq!(outside_sparser > 0, !sparser, "state {k}");
            }
        }
    }

    #[test]
    fn physics_sanity() {
        let twin = OtterTwin::default();
        let full = ShaftSpeeds {
            port_radps: 103.9,
            starboard_radps: 103.9,
        };
        let none = Faults::zeros();
        let mut x = State::zeros();
        for _ in 0..300 {
            x = Model::transition(&twin, &x, &full, &none, 0.2).next;
        }
        // Top speed 3.09 m/s where thrust meets linear damping.
        assert!((x[idx::U] - 3.09).abs() < 0.02, "{}", x[idx::U]);
        assert!(x[idx::V].abs() < 1e-9 && x[idx::R].abs() < 1e-9);
        // 30 % more surge damping: the top speed falls by the same factor.
        let mut draggy = x;
        let fouled = Faults::from([0.0, 0.0, 0.3, 0.0, 0.0, 0.0]);
        for _ in 0..300 {
            draggy = Model::transition(&twin, &draggy, &full, &fouled, 0.2).next;
        }
        assert!(
            (draggy[idx::U] - 3.09 / 1.3).abs() < 0.02,
            "{}",
            draggy[idx::U]
        );
        // A port loss: the bow falls off to port (negative yaw rate).
        let mut y = x;
        for _ in 0..5 {
            y = Model::transition(
                &twin,
                &y,
                &full,
                &Faults::from([0.3, 0.0, 0.0, 0.0, 0.0, 0.0]),
                0.2,
            )
            .next;
        }
        assert!(y[idx::R] < -0.05, "{}", y[idx::R]);
        // A 0.2 s step of a hard turn agrees with a fine integration to 1 mm,
        // 1 mm/s and 1 mrad.
        let u = ShaftSpeeds {
            port_radps: 90.0,
            starboard_radps: 30.0,
        };
        let one = Model::transition(&twin, &x, &u, &none, 0.2).next;
        let mut fine = x;
        for _ in 0..100 {
            fine = Model::transition(&twin, &fine, &u, &none, 0.002).next;
        }
        assert!(
            (one - fine).amax() < 1e-3,
            "{:?} vs {:?}",
            one.as_slice(),
            fine.as_slice()
        );
    }

    #[test]
    fn current_moves_the_track_not_the_water_velocity() {
        let twin = OtterTwin::default();
        let mut x = State::zeros();
        x[idx::CURRENT_EAST] = 0.3;
        let t = Model::transition(&twin, &x, &ShaftSpeeds::default(), &Faults::zeros(), 1.0);
        assert!((t.next[idx::EAST] - 0.3).abs() < 1e-12);
        let o = twin.observe_state(&t.next);
        assert!((o.predicted[meas::SOG] - 0.3).abs() < 1e-12);
        assert!((o.predicted[meas::COG] - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    }
}
