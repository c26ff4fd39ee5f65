#!/usr/bin/env python3
"""otter6dof: an independent 6-DOF simulator of the Otter USV, for the
hidden-effect tests of `twin diagnose` on logs from a simulator other than
the project's own (docs/accuracy.md, "Hidden effects").

What it is
==========
The Maritime Robotics Otter (a 2 m catamaran with two fixed propellers) in
six degrees of freedom, written for this project from the equations of

  T. I. Fossen (2021), Handbook of Marine Craft Hydrodynamics and Motion
  Control, 2nd ed., Wiley: the rigid-body kinetics about an arbitrary origin
  (ch. 3: M_RB = H(r_g)^T diag(m I, I_g) H(r_g), Coriolis-centripetal forces
  from the mass matrix in Kirchhoff's form), added mass (ch. 6), hydrostatic
  restoring of a surface vessel from its waterplane and metacentric heights
  (ch. 4), linear damping plus cross-flow drag by strip theory with Hoerner's
  2D coefficient (ch. 6), the current through the relative velocity
  nu_r = nu - nu_c (ch. 10, property 10.1: exact for a constant,
  irrotational current), and the kinematics eta' = J(eta) nu (ch. 2);

with the Otter's parameter values as Fossen gives them in the Otter model of
his Python Vehicle Simulator (github.com/cybergalactic/PythonVehicleSimulator,
`src/python_vehicle_simulator/vehicles/otter.py`, read as a reference for
the equations and numbers only; no code was copied, see README.md here).

Equations (body frame b at the origin CO, midships on the centre line in the
waterline; x forward, y starboard, z down; NED frame n: north, east, down;
Euler angles roll phi, pitch theta, yaw psi, zyx convention; heading psi
clockwise from north; a positive yaw rate turns the bow to starboard)

  eta = [north, east, down, phi, theta, psi]
  nu  = [u, v, w, p, q, r]        velocity over ground in b
  nu_c = [R(Theta)^T v_c, 0, 0, 0] the current in b, v_c = V_c [cos b_c, sin b_c, 0]
                                  in n (b_c: the direction it flows *toward*)
  nu_r = nu - nu_c                velocity through the water (the state here)

  [north', east', down']  = R(Theta) nu[0:3]      (= R nu_r[0:3] + v_c)
  [phi', theta', psi']    = T(Theta) nu[3:6]
  M nu_r' = tau_prop + tau_dist - C(nu_r) nu_r - D nu_r - d_yaw(r) + tau_cf(nu_r) - G eta
  C(nu) nu = [w x p1 ; v x p1 + w x p2],  [p1; p2] = M nu   (Kirchhoff; v, w: the
                                  linear and angular parts of nu; the yaw Munk moment kept)
  D = -diag(X_u, Y_v, Z_w, K_p, M_q, N_r);  d_yaw = -10 N_r |r| r   (Fossen's
                                  nonlinear yaw damping)
  tau_cf = [0, Y_cf, 0, 0, 0, N_cf],  Y_cf = -1/2 rho T C_D int |v_r + x r| (v_r + x r) dx,
                                  N_cf = the same with x under the integral, over
                                  x in [-L/2, L/2] (24-strip midpoint rule)
  G = H(r_f)^T diag(0, 0, G33, G44, G55, 0) H(r_f), r_f = [LCF, 0, 0]
  tau_prop = [T_p + T_s, 0, 0, 0, 0, b (T_p - T_s)],  T_i = (1 - loss_i) k n_i |n_i|
                                  (k ahead or astern; n_i saturated)
  n_i' = (n_cmd,i - n_i) / T_n    (shaft-speed lag)

Integration: classical Runge-Kutta (4th order), fixed step 0.05 s (the
fastest mode, heave at about 7.5 rad/s, is resolved: omega dt < 0.4), with the
commands, losses and the disturbance held over a step.

Parameters (Fossen's Otter, 25 kg payload)
------------------------------------------
  L = 2.0 m, B = 1.08 m, hull mass 55 kg at r_g = [0.2, 0, -0.2] m, payload
  25 kg at [0.05, 0, -0.35] m (combined CG [0.153, 0, -0.247] m);
  radii of gyration 0.4 B, 0.25 L, 0.25 L; pontoon beam 0.25 m, pontoon
  centre line at y = +-0.395 m, waterplane coefficient 0.75, block
  coefficient 0.4; rho = 1025 kg/m^3, g = 9.81 m/s^2; draft
  T = (m / rho) / (2 C_b B_pont L) = 0.195 m.
  Added mass (m: the hull's 55 kg; I: the inertia about the CG as otter.py
  forms it): X_udot = -0.1 m, Y_vdot = -1.5 m, Z_wdot = -m,
  K_pdot = -0.2 I_xx, M_qdot = -0.8 I_yy, N_rdot = -1.7 I_zz.
  Hydrostatics: G33 = rho g 2 A_w, G44 = rho g nabla GM_T, G55 = rho g nabla GM_L,
  GM from KB, BM_T, BM_L of the two pontoons, LCF = -0.2 m.
  Damping: X_u = -24.4 g / U_max (U_max = 6 kn), Y_v = -M22 / 1 s,
  N_r = -M66 / 1 s, Z_w, K_p, M_q from relative damping 0.3, 0.2, 0.4 at the
  heave, roll and pitch natural frequencies.
  Propellers: k = 0.02216 / 2 ahead, 0.01289 / 2 astern (N/(rad/s)^2),
  n_max = sqrt(0.5 24.4 g / k_ahead) = 103.9 rad/s, n_min = -101.7 rad/s,
  T_n = 0.1 s. Cross-flow: C_D = 1.0 (Hoerner's curve at B_pont / 2T = 0.64).
  The resulting surge-sway-yaw block of M is [[85.5, 0, 0], [0, 162.5, 12.25],
  [0, 12.25, 42.65]] (docs/model.md section 6); `--check` prints it.

  One deliberate difference from Fossen's code: there the payload's weight is
  also applied as an external force on top of a displacement that already
  carries it; here the payload is part of the craft's mass and centre of
  gravity only, so the craft floats level at eta = 0 when still.
  `--fossen-payload-force` adds Fossen's term back: the craft then sinks
  4 cm and trims about 1.7 deg by the bow, and the weight's component along
  the tilted hull pushes it ahead with about 7 N (some 7 % of the thrust at
  1.5 m/s), which the project's 3-DOF twin sees as a negative propeller loss
  of about 0.07 on both sides (not reported: a loss cannot be negative).

What is around the model (all this simulator's own)
---------------------------------------------------
  Path: a lawn-mower of seven legs of 32-44 m joined by alternating 180 deg
  turns of radius 10-16 m, about 560 m, with a speed set-point per leg
  between 1.0 and 2.0 m/s (1.2, 2.0, 1.0, 1.9, 1.1, 2.0, 1.3); 300 s are
  simulated. The speed changes matter: at one constant speed U a GNSS
  latency L and an antenna L U behind the origin move the fix alike (to
  first order, position and course), so a trial at one speed cannot tell
  them apart; with 1.3-1.8 m/s they were still tied within a few nats of
  held-out likelihood.
  Guidance: pure pursuit of a point 5 m ahead along the path (no current
  compensation). Heading: a first-order reference (time constant 1.5 s,
  turn rate limited to 15 deg/s), the yaw damping of the reference turn
  rate as feed-forward and a PID on the heading error with the reference
  turn rate as the damping target (omega_n 1 rad/s, zeta 0.9, designed on
  I = 42.65 kg m^2, N_r = -42.65 N m s). Speed: PI on the speed over ground
  with the linear surge damping as feed-forward. Allocation: T_p,s = X/2 +- N/(2 b), then
  n = sign(T) sqrt(|T| / k). The autopilot runs at 10 Hz on the true state
  and knows nothing of losses (its integrators make up for them).
  Disturbance: first-order Gauss-Markov forces in the body frame (surge
  2 N, sway 3 N, roll 1 N m, pitch 1 N m, yaw 0.5 N m; correlation 4 s);
  none with --calm.
  Sensors (each its own random stream):
    GNSS, 5 Hz: the antenna 0.5 m above the waterline on the centre line at
      midships (it swings with roll and pitch), white position noise 0.3 m per
      axis; SOG and COG from the antenna's velocity over ground plus white
      noise of 0.03 m/s per axis; HDOP 0.8.
    Heading, 5 Hz: the true yaw plus white noise of 0.5 deg, sampled when the
      logger writes the fix (at the fix's stamp) and written into its line.
    Shaft speeds, 10 Hz: the actual shaft speeds plus white noise of 1.5 rpm,
      rounded to 0.1 rpm.
    Rate gyro (with --gyro): the true yaw rate at the fix's stamp, times
      --gyro-scale (1 by default), plus --gyro-bias-deg-s (0 by default)
      and white noise of 0.2 deg/s, written into the fix's line.
  Injectable effects (any combination):
    current        speed (m/s) and the direction it flows toward (deg)
    heading_offset the heading sensor reads this much more than the truth (deg)
    sog_scale      the reported SOG is the true one times this
    latency        GNSS data (position, SOG, COG) are this much older than
                   their stamps (s); the heading is not delayed
    lever_arm      the antenna sits (x forward, y starboard) m from the origin
    loss           one propeller gives (1 - loss) of its thrust (port or starboard)
  The craft itself (--vessel otter|workboat, a named set of the scales
  below, each overridable; --mass-scale, --added-mass-scale, --surge-damping-scale,
  --sway-damping-scale, --yaw-damping-scale, --crossflow-scale,
  --thrust-scale, --size-scale, --propeller-arm-scale; 1 = Fossen's Otter):
  factors on its numbers; the size scales every length of the hull (its
  inertias by the square, its displacement by the cube), not the
  propellers' arm. The autopilot stays designed on the Otter's numbers, or
  on those of a similar hull of the given size.

How it differs from the project's simulator (crates/twin-sim)
-------------------------------------------------------------
  6 DOF here (heave, roll and pitch with hydrostatic restoring, and the
  couplings of the full 6x6 mass matrix: surge-pitch and sway-roll through
  the CG's height, roll-yaw through I_xz) against 3 DOF there; a different
  path (a lawn-mower with varying radii and speeds against a serpentine of
  equal turns at one speed; the straight leg and the steady turn on a
  circle of `--path` are common to both), different guidance (pure
  pursuit against LOS),
  heading and speed controllers of different structure, gains and rate
  (10 Hz), a different disturbance (no wind), different sensor noise
  (velocity noise of 0.03 m/s, shaft noise of 1.5 rpm rounded to 0.1 rpm,
  the heading at 5 Hz read with the fix, an antenna above the waterline)
  and NumPy's random generator. The numbers of the hull (docs/model.md section 6)
  are Fossen's in both. Nothing is shared with crates/twin-sim or
  crates/twin-core.

Output
------
  --out LOG: the project's JSON lines (crates/twin-wire/src/read/jsonl.rs),
    {"type":"gnss","time":...,"lat_deg","lon_deg","sog_mps","cog_rad","heading_rad","hdop"}
    at 5 Hz and {"type":"actuators","time":...,"rpm":{"port","starboard"}} at
    10 Hz, in time order; positions on WGS-84 through the flat-earth frame
    of docs/model.md section 2 around the origin.
  --truth TRUTH: a JSON file with the effects, the parameters and a 1 Hz
    track of the true state (never read by the diagnosis).

Usage
-----
  python3 otter6dof.py --seed 3 --effect current --current-speed-mps 0.3 \\
      --current-toward-deg 120 --out run.jsonl --truth run.truth.json
  A missing size is drawn from the ranges in EFFECT_RANGES with the seed; a
  size given names its effect without --effect.
  python3 otter6dof.py --check   prints the mass matrix and natural frequencies.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import math
import sys
from dataclasses import dataclass, field

import numpy as np

GRAVITY_MPS2 = 9.81
WATER_DENSITY_KGPM3 = 1025.0
RPM_PER_RADPS = 60.0 / (2.0 * math.pi)

# WGS-84 (docs/model.md section 2).
WGS84_A_M = 6378137.0
WGS84_F = 1.0 / 298.257223563
WGS84_E2 = 2.0 * WGS84_F - WGS84_F**2

# The payload (Fossen's otter.py): mass, kg, and position in b, m.
PAYLOAD_KG = 25.0
PAYLOAD_AT_M = (0.05, 0.0, -0.35)

# Ranges a missing effect size is drawn from (the Rust test passes its own).
EFFECT_RANGES = {
    "current": {"speed_mps": (0.1, 0.4), "toward_deg": (0.0, 360.0)},
    "heading_offset": {"offset_deg": (3.0, 10.0)},  # either sign
    "sog_scale": {"scale_error": (0.05, 0.10)},  # 1 - e or 1 + e
    "latency": {"latency_s": (0.3, 1.0)},
    "lever_arm": {"length_m": (0.5, 1.0), "bearing_deg": (0.0, 360.0)},
    "loss": {"loss": (0.15, 0.4)},  # either side
}
EFFECT_KINDS = ("none",) + tuple(EFFECT_RANGES)


# --------------------------------------------------------------------------
# Small vector helpers (plain floats: the inner loop is faster without
# NumPy's per-call overhead on 3- and 6-vectors).


def cross3(a, b):
    """The cross product a x b of two 3-sequences."""
    return (
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    )


def skew(vec) -> np.ndarray:
    """S(a) with S(a) b = a x b."""
    x, y, z = vec
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def shift_matrix(offset_m) -> np.ndarray:
    """H(r): moves generalized velocities from the origin to the point r."""
    h = np.eye(6)
    h[0:3, 3:6] = skew(offset_m).T
    return h


def rotation_zyx(phi, theta, psi):
    """R(Theta), body to NED, as a row-major 3x3 tuple of tuples."""
    cf, sf = math.cos(phi), math.sin(phi)
    ct, st = math.cos(theta), math.sin(theta)
    cp, sp = math.cos(psi), math.sin(psi)
    return (
        (cp * ct, -sp * cf + cp * st * sf, sp * sf + cp * cf * st),
        (sp * ct, cp * cf + sf * st * sp, -cp * sf + st * sp * cf),
        (-st, ct * sf, ct * cf),
    )


def mat_vec(m, x):
    """A row-major matrix (tuple of rows) times a vector."""
    return [sum(mij * xj for mij, xj in zip(row, x)) for row in m]


def mat_t_vec(m, x):
    """The transpose of a 3x3 row-major matrix times a 3-vector."""
    return [
        m[0][0] * x[0] + m[1][0] * x[1] + m[2][0] * x[2],
        m[0][1] * x[0] + m[1][1] * x[1] + m[2][1] * x[2],
        m[0][2] * x[0] + m[1][2] * x[1] + m[2][2] * x[2],
    ]


def wrap_pi(angle_rad: float) -> float:
    """An angle in [-pi, pi)."""
    return (angle_rad + math.pi) % (2.0 * math.pi) - math.pi


# --------------------------------------------------------------------------
# The Otter's parameters (Fossen 2021; values of otter.py, 25 kg payload)


@dataclass
class OtterParameters:
    """Everything the equations of motion need, in SI units."""

    length_m: float
    draft_m: float
    mass_matrix: np.ndarray  # 6x6, rigid body + added mass, at CO
    mass_inverse: tuple  # row-major tuple of tuples
    mass_rows: tuple  # M as a row-major tuple of tuples
    restoring: tuple  # G, row-major tuple of tuples
    linear_damping: tuple  # the diagonal of D (positive)
    yaw_quadratic_factor_s: float  # d_yaw = factor * D66 |r| r
    crossflow_coeff: float
    propeller_offset_m: float
    thrust_coeff_ahead: float
    thrust_coeff_astern: float
    shaft_max_radps: float
    shaft_min_radps: float
    shaft_time_constant_s: float
    natural_frequencies_radps: tuple  # heave, roll, pitch
    metacentric_heights_m: tuple  # GM_T, GM_L


@dataclass
class VesselScales:
    """Departures of the simulated craft from Fossen's Otter (1 = none): the
    vessel a twin built on the Otter's numbers is wrong about."""

    mass: float = 1.0  # rigid-body mass and inertia
    added_mass: float = 1.0  # added mass and inertia
    surge_damping: float = 1.0  # linear surge damping (hull resistance)
    sway_damping: float = 1.0  # linear sway damping
    yaw_damping: float = 1.0  # linear and quadratic yaw damping
    crossflow: float = 1.0  # cross-flow drag
    thrust: float = 1.0  # thrust coefficients, both propellers
    # Every length of the hull (geometric similarity): its length and beams,
    # the positions of the CG and payload, the radii of gyration (so the
    # inertias, rigid and added, by its square on top of the mass scales)
    # and the hydrostatics of a hull that size (its displacement by the
    # cube), not the propellers' arm. A hull s times as long wants mass and
    # added mass near s^3.
    size: float = 1.0
    # The propellers' distance from the centre line (the size leaves it).
    propeller_arm: float = 1.0


def otter_parameters(scales: VesselScales | None = None) -> OtterParameters:
    """Derives the Otter's model from Fossen's data (module docstring), with
    `scales` applied to its size, mass, added mass, damping, propeller arm
    and thrust (the `--*-scale` arguments)."""
    sc = scales or VesselScales()
    g, rho = GRAVITY_MPS2, WATER_DENSITY_KGPM3
    size = sc.size
    length, beam = 2.0 * size, 1.08 * size
    hull_kg, payload_kg = 55.0, PAYLOAD_KG
    total_kg = hull_kg + payload_kg
    def masses(size):
        """(rigid-body and added mass matrices at CO, CG) of the hull
        `size` times the Otter's, with the Otter's masses."""
        length, beam = 2.0 * size, 1.08 * size
        hull_cg = size * np.array([0.2, 0.0, -0.2])
        payload_at = size * np.array(PAYLOAD_AT_M)
        cg = (hull_kg * hull_cg + payload_kg * payload_at) / total_kg
        # Inertia about the CG as otter.py forms it: the hull's radii of
        # gyration plus the parallel-axis terms of hull and payload.
        radii = np.array([0.4 * beam, 0.25 * length, 0.25 * length])
        s_cg, s_payload = skew(cg), skew(payload_at)
        inertia = (
            hull_kg * np.diag(radii**2)
            - hull_kg * s_cg @ s_cg
            - payload_kg * s_payload @ s_payload
        )
        m_rb_cg = np.zeros((6, 6))
        m_rb_cg[0:3, 0:3] = total_kg * np.eye(3)
        m_rb_cg[3:6, 3:6] = inertia
        h_cg = shift_matrix(cg)
        added = np.diag(
            [
                0.1 * hull_kg,
                1.5 * hull_kg,
                1.0 * hull_kg,
                0.2 * inertia[0, 0],
                0.8 * inertia[1, 1],
                1.7 * inertia[2, 2],
            ]
        )
        return h_cg.T @ m_rb_cg @ h_cg, added, cg

    m_rb, added, cg = masses(size)
    pontoon_beam, pontoon_y = 0.25 * size, 0.395 * size
    waterplane_coeff, block_coeff = 0.75, 0.4
    # The displacement of a hull this size (the mass scales leave the
    # hydrostatics as they are).
    volume = total_kg * size**3 / rho
    draft = volume / (2.0 * block_coeff * pontoon_beam * length)

    mass = sc.mass * m_rb + sc.added_mass * added
    mass = 0.5 * (mass + mass.T)

    # Hydrostatics of two pontoons (Fossen 2021, ch. 4).
    pontoon_area = waterplane_coeff * length * pontoon_beam
    transverse_moment = (
        2.0
        * (1.0 / 12.0)
        * length
        * pontoon_beam**3
        * (
            6.0
            * waterplane_coeff**3
            / ((1.0 + waterplane_coeff) * (1.0 + 2.0 * waterplane_coeff))
        )
        + 2.0 * pontoon_area * pontoon_y**2
    )
    longitudinal_moment = 0.8 * 2.0 * (1.0 / 12.0) * pontoon_beam * length**3
    keel_buoyancy = (1.0 / 3.0) * (
        5.0 * draft / 2.0 - 0.5 * volume / (length * pontoon_beam)
    )
    keel_gravity = draft - cg[2]
    gm_t = keel_buoyancy + transverse_moment / volume - keel_gravity
    gm_l = keel_buoyancy + longitudinal_moment / volume - keel_gravity
    g33 = rho * g * 2.0 * pontoon_area
    g44 = rho * g * volume * gm_t
    g55 = rho * g * volume * gm_l
    flotation_centre_x = -0.2 * size
    h_f = shift_matrix([flotation_centre_x, 0.0, 0.0])
    restoring = h_f.T @ np.diag([0.0, 0.0, g33, g44, g55, 0.0]) @ h_f

    w_heave = math.sqrt(g33 / mass[2, 2])
    w_roll = math.sqrt(g44 / mass[3, 3])
    w_pitch = math.sqrt(g55 / mass[4, 4])
    max_speed = 6.0 * 0.5144
    # The time constants of sway and yaw are Fossen's for his Otter: the
    # damping derivatives come from its own (unscaled) masses, then scale.
    otter_rb, otter_added, _ = masses(1.0)
    nominal = otter_rb + otter_added
    damping = (
        sc.surge_damping * 24.4 * g / max_speed,
        sc.sway_damping * nominal[1, 1] / 1.0,
        2.0 * 0.3 * w_heave * mass[2, 2],
        2.0 * 0.2 * w_roll * mass[3, 3],
        2.0 * 0.4 * w_pitch * mass[4, 4],
        sc.yaw_damping * nominal[5, 5] / 1.0,
    )

    # Cross-flow drag: Hoerner's 2D coefficient at B / 2T of one pontoon.
    ratio = pontoon_beam / (2.0 * draft)
    assert 0.6 < ratio < 0.7, ratio
    k_ahead, k_astern = 0.02216 / 2.0, 0.01289 / 2.0
    # The shaft limits are the Otter's (from its nominal coefficients); a
    # stronger propeller gives more thrust at the same speed.
    n_max = math.sqrt(0.5 * 24.4 * g / k_ahead)
    n_min = -math.sqrt(0.5 * 13.6 * g / k_astern)

    def rows(a):
        return tuple(tuple(float(x) for x in row) for row in a)

    return OtterParameters(
        length_m=length,
        draft_m=draft,
        mass_matrix=mass,
        mass_inverse=rows(np.linalg.inv(mass)),
        mass_rows=rows(mass),
        restoring=rows(restoring),
        linear_damping=damping,
        yaw_quadratic_factor_s=10.0,
        crossflow_coeff=sc.crossflow * 1.0,
        # The propellers' arm is its own scale's (the size leaves it).
        propeller_offset_m=sc.propeller_arm * pontoon_y / size,
        thrust_coeff_ahead=sc.thrust * k_ahead,
        thrust_coeff_astern=sc.thrust * k_astern,
        shaft_max_radps=n_max,
        shaft_min_radps=n_min,
        shaft_time_constant_s=0.1,
        natural_frequencies_radps=(w_heave, w_roll, w_pitch),
        metacentric_heights_m=(gm_t, gm_l),
    )


def thrust_n(params: OtterParameters, shaft_radps: float) -> float:
    """One propeller's thrust at a shaft speed (saturated), N."""
    n = min(max(shaft_radps, params.shaft_min_radps), params.shaft_max_radps)
    k = params.thrust_coeff_ahead if n > 0.0 else params.thrust_coeff_astern
    return k * n * abs(n)


def shaft_for_thrust_radps(params: OtterParameters, thrust: float) -> float:
    """The shaft speed giving a thrust (inverse of `thrust_n`), rad/s."""
    k = params.thrust_coeff_ahead if thrust > 0.0 else params.thrust_coeff_astern
    n = math.copysign(math.sqrt(abs(thrust) / k), thrust)
    return min(max(n, params.shaft_min_radps), params.shaft_max_radps)


# --------------------------------------------------------------------------
# Equations of motion

CROSSFLOW_STRIPS = 24


@dataclass
class Inputs:
    """What is held over one integration step."""

    shaft_cmd_radps: tuple  # (port, starboard)
    thrust_factor: tuple  # 1 - loss, (port, starboard)
    disturbance: tuple  # 6 generalized forces in b
    current_ned_mps: tuple  # (north, east, down)


class OtterDynamics:
    """x = [eta (6), nu_r (6), shaft speeds (2)] and its derivative."""

    def __init__(self, params: OtterParameters, payload_force: bool = False):
        self.p = params
        # Fossen's otter.py also applies the payload's weight as an external
        # force at its position (off by default; see the module docstring).
        self.payload_weight_n = PAYLOAD_KG * GRAVITY_MPS2 if payload_force else 0.0
        half = 0.5 * params.length_m
        dx = params.length_m / CROSSFLOW_STRIPS
        self.strip_x = [-half + (i + 0.5) * dx for i in range(CROSSFLOW_STRIPS)]
        self.strip_gain = (
            0.5 * WATER_DENSITY_KGPM3 * params.draft_m * params.crossflow_coeff * dx
        )

    def crossflow(self, v_r: float, r: float):
        """Sway force and yaw moment of the cross-flow drag."""
        y_force = 0.0
        n_moment = 0.0
        for x in self.strip_x:
            w = v_r + x * r
            f = w * abs(w)
            y_force -= f
            n_moment -= x * f
        return self.strip_gain * y_force, self.strip_gain * n_moment

    def derivative(self, x, inp: Inputs):
        p = self.p
        phi, theta, psi = x[3], x[4], x[5]
        nu_r = x[6:12]
        rot = rotation_zyx(phi, theta, psi)
        # Velocity over ground: through the water plus the current.
        ground = mat_vec(rot, nu_r[0:3])
        pos_dot = [
            ground[0] + inp.current_ned_mps[0],
            ground[1] + inp.current_ned_mps[1],
            ground[2] + inp.current_ned_mps[2],
        ]
        # Euler angle rates T(Theta) omega.
        pr, qr, rr = nu_r[3], nu_r[4], nu_r[5]
        cf, sf = math.cos(phi), math.sin(phi)
        ct, tt = math.cos(theta), math.tan(theta)
        att_dot = [
            pr + sf * tt * qr + cf * tt * rr,
            cf * qr - sf * rr,
            (sf * qr + cf * rr) / ct,
        ]
        # Coriolis-centripetal forces of rigid body + added mass (Kirchhoff).
        mom = mat_vec(p.mass_rows, nu_r)
        lin, ang = nu_r[0:3], nu_r[3:6]
        c_lin = cross3(ang, mom[0:3])
        c1 = cross3(lin, mom[0:3])
        c2 = cross3(ang, mom[3:6])
        coriolis = (
            c_lin[0],
            c_lin[1],
            c_lin[2],
            c1[0] + c2[0],
            c1[1] + c2[1],
            c1[2] + c2[2],
        )
        # Restoring forces.
        restore = mat_vec(p.restoring, x[0:6])
        # Damping.
        d = p.linear_damping
        y_cf, n_cf = self.crossflow(nu_r[1], rr)
        # Propellers.
        t_port = inp.thrust_factor[0] * thrust_n(p, x[12])
        t_stb = inp.thrust_factor[1] * thrust_n(p, x[13])
        b = p.propeller_offset_m
        dist = inp.disturbance
        force = [
            t_port + t_stb - d[0] * nu_r[0],
            -d[1] * nu_r[1] + y_cf,
            -d[2] * nu_r[2],
            -d[3] * nu_r[3],
            -d[4] * nu_r[4],
            b * (t_port - t_stb)
            - d[5] * nu_r[5]
            - p.yaw_quadratic_factor_s * d[5] * abs(rr) * rr
            + n_cf,
        ]
        for i in range(6):
            force[i] += dist[i] - coriolis[i] - restore[i]
        if self.payload_weight_n:
            weight = mat_t_vec(rot, (0.0, 0.0, self.payload_weight_n))
            moment = cross3(PAYLOAD_AT_M, weight)
            for i in range(3):
                force[i] += weight[i]
                force[3 + i] += moment[i]
        acc = mat_vec(p.mass_inverse, force)
        tn = p.shaft_time_constant_s
        shaft_dot = [
            (inp.shaft_cmd_radps[0] - x[12]) / tn,
            (inp.shaft_cmd_radps[1] - x[13]) / tn,
        ]
        return pos_dot + att_dot + acc + shaft_dot


def rk4_step(dyn: OtterDynamics, x, inp: Inputs, h: float):
    """One classical Runge-Kutta step of length h."""
    k1 = dyn.derivative(x, inp)
    k2 = dyn.derivative([xi + 0.5 * h * ki for xi, ki in zip(x, k1)], inp)
    k3 = dyn.derivative([xi + 0.5 * h * ki for xi, ki in zip(x, k2)], inp)
    k4 = dyn.derivative([xi + h * ki for xi, ki in zip(x, k3)], inp)
    return [
        xi + h / 6.0 * (a + 2.0 * b2 + 2.0 * c + d4)
        for xi, a, b2, c, d4 in zip(x, k1, k2, k3, k4)
    ]


# --------------------------------------------------------------------------
# The path, guidance and autopilot (this simulator's own)


@dataclass
class PathPlan:
    """A dense polyline of the path and a speed set-point at each point."""

    north_m: np.ndarray
    east_m: np.ndarray
    speed_mps: np.ndarray
    spacing_m: float


def straight(length_m: float, speed_mps: float = 1.5, spacing_m: float = 0.25) -> PathPlan:
    """One leg due north at one speed: no turn at all."""
    steps = int(round(length_m / spacing_m))
    north = np.arange(steps + 1) * spacing_m
    return PathPlan(north, np.zeros(steps + 1), np.full(steps + 1, speed_mps), spacing_m)


def lawn_mower(spacing_m: float = 0.25) -> PathPlan:
    """Seven legs north and south, joined by 180 deg turns alternately to
    starboard and to port, with varied radii, leg lengths and speeds."""
    legs_m = [40.0, 36.0, 44.0, 32.0, 40.0, 38.0, 42.0]
    radii_m = [12.0, 16.0, 10.0, 14.0, 12.0, 16.0, 10.0]
    speeds_mps = [1.2, 2.0, 1.0, 1.9, 1.1, 2.0, 1.3]
    pts_n, pts_e, spd = [0.0], [0.0], [speeds_mps[0]]
    n, e, course = 0.0, 0.0, 0.0  # heading north first
    turn_sign = 1.0  # +1: to starboard (clockwise seen from above)
    for leg, radius, speed in zip(legs_m, radii_m, speeds_mps):
        steps = int(round(leg / spacing_m))
        for _ in range(steps):
            n += spacing_m * math.cos(course)
            e += spacing_m * math.sin(course)
            pts_n.append(n)
            pts_e.append(e)
            spd.append(speed)
        steps = int(round(math.pi * radius / spacing_m))
        dpsi = turn_sign * math.pi / steps
        n, e, course = arc(pts_n, pts_e, (n, e, course), radius, dpsi, steps)
        spd.extend([speed] * steps)
        turn_sign = -turn_sign
    return PathPlan(np.array(pts_n), np.array(pts_e), np.array(spd), spacing_m)


def arc(pts_n, pts_e, start, radius_m, dpsi, steps):
    """Appends `steps` points of an arc of `radius_m` from `start` (north,
    east, course), turning `dpsi` rad at each (each point advanced along the
    chord at the mid-course); returns where it ends."""
    n, e, course = start
    chord = 2.0 * radius_m * math.sin(0.5 * abs(dpsi))
    for _ in range(steps):
        mid = course + 0.5 * dpsi
        n += chord * math.cos(mid)
        e += chord * math.sin(mid)
        course += dpsi
        pts_n.append(n)
        pts_e.append(e)
    return n, e, course


def circles(
    length_m: float,
    radius_m: float = 20.0,
    turn_sign: float = 1.0,
    lead_in_m: float = 20.0,
    speed_mps: float = 1.5,
    spacing_m: float = 0.25,
) -> PathPlan:
    """A short leg north, then one circle of `radius_m` sailed over and over
    (to starboard for `turn_sign` +1, to port for -1) for `length_m` in all:
    a steady turn."""
    steps = int(round(lead_in_m / spacing_m))
    pts_n = [k * spacing_m for k in range(steps + 1)]
    pts_e = [0.0] * (steps + 1)
    dpsi = turn_sign * spacing_m / radius_m
    steps = int(round(length_m / spacing_m))
    arc(pts_n, pts_e, (pts_n[-1], 0.0, 0.0), radius_m, dpsi, steps)
    count = len(pts_n)
    return PathPlan(np.array(pts_n), np.array(pts_e), np.full(count, speed_mps), spacing_m)


class PurePursuit:
    """Steers toward the path point a fixed distance ahead of the closest."""

    def __init__(self, plan: PathPlan, lookahead_m: float = 5.0):
        self.plan = plan
        self.ahead = int(round(lookahead_m / plan.spacing_m))
        self.index = 0

    def command(self, north_m: float, east_m: float):
        """(desired course rad, speed set-point m/s)."""
        plan = self.plan
        last = len(plan.north_m) - 1
        window = slice(self.index, min(self.index + 120, last + 1))
        dn = plan.north_m[window] - north_m
        de = plan.east_m[window] - east_m
        self.index += int(np.argmin(dn * dn + de * de))
        target = min(self.index + self.ahead, last)
        course = math.atan2(
            plan.east_m[target] - east_m, plan.north_m[target] - north_m
        )
        return course, float(plan.speed_mps[self.index])


class Autopilot:
    """Heading PID with a rate-limited reference, speed PI, allocation.

    Designed on the Otter's yaw inertia, yaw damping and hull resistance
    (not the simulated craft's: a perturbed craft meets a controller tuned
    on the nominal one); for a hull `size` times the Otter's, on those of a
    similar hull (yaw by size^5, surge by size^3)."""

    YAW_INERTIA_KGM2 = 42.65
    YAW_DAMPING_NMS = 42.65
    SURGE_DAMPING_NSPM = 24.4 * GRAVITY_MPS2 / (6.0 * 0.5144)

    def __init__(self, params: OtterParameters, psi0: float, size: float = 1.0):
        self.p = params
        yaw, surge = size**5, size**3
        self.yaw_inertia = self.YAW_INERTIA_KGM2 * yaw
        self.yaw_damping = self.YAW_DAMPING_NMS * yaw
        self.surge_damping = self.SURGE_DAMPING_NSPM * surge
        w, zeta = 1.0, 0.9
        self.kp = self.yaw_inertia * w * w
        self.kd = 2.0 * zeta * w * self.yaw_inertia - self.yaw_damping
        self.ki = self.kp * w / 10.0
        self.ref_tau_s = 1.5
        self.ref_rate_max = math.radians(15.0)
        self.psi_ref = psi0
        self.r_ref = 0.0
        self.heading_integral = 0.0
        self.speed_kp = 120.0 * surge
        self.speed_ki = 15.0 * surge
        self.speed_integral = 0.0

    def command(self, dt_s, psi, r, sog, course_d, speed_d):
        """Shaft speed commands (port, starboard), rad/s."""
        step = wrap_pi(course_d - self.psi_ref) / self.ref_tau_s
        self.r_ref = max(-self.ref_rate_max, min(self.ref_rate_max, step))
        self.psi_ref = wrap_pi(self.psi_ref + self.r_ref * dt_s)
        err = wrap_pi(self.psi_ref - psi)
        self.heading_integral = max(-2.0, min(2.0, self.heading_integral + err * dt_s))
        yaw_moment = (
            self.yaw_damping * self.r_ref
            + self.kp * err
            + self.kd * (self.r_ref - r)
            + self.ki * self.heading_integral
        )
        speed_err = speed_d - sog
        self.speed_integral = max(
            -3.0, min(3.0, self.speed_integral + speed_err * dt_s)
        )
        surge_force = (
            self.surge_damping * speed_d
            + self.speed_kp * speed_err
            + self.speed_ki * self.speed_integral
        )
        b = self.p.propeller_offset_m
        t_port = 0.5 * surge_force + yaw_moment / (2.0 * b)
        t_stb = 0.5 * surge_force - yaw_moment / (2.0 * b)
        return (
            shaft_for_thrust_radps(self.p, t_port),
            shaft_for_thrust_radps(self.p, t_stb),
        )


# --------------------------------------------------------------------------
# Effects, sensors and the run


@dataclass
class Effects:
    """What is hidden in the log (all neutral by default)."""

    current_speed_mps: float = 0.0
    current_toward_deg: float = 0.0
    heading_offset_deg: float = 0.0
    sog_scale: float = 1.0
    latency_s: float = 0.0
    lever_arm_x_m: float = 0.0
    lever_arm_y_m: float = 0.0
    loss_port: float = 0.0
    loss_starboard: float = 0.0
    loss_onset_s: float = 0.0  # the losses act from this time on
    kinds: list = field(default_factory=list)


@dataclass
class RunConfig:
    seed: int = 1
    duration_s: float = 300.0
    step_s: float = 0.05
    control_period_s: float = 0.1
    gnss_period_s: float = 0.2
    shaft_period_s: float = 0.1
    start: dt.datetime = dt.datetime(2025, 3, 14, 8, 0, 0, tzinfo=dt.timezone.utc)
    origin_lat_deg: float = 63.4390
    origin_lon_deg: float = 10.3990
    antenna_height_m: float = 0.5
    position_sigma_m: float = 0.3
    velocity_sigma_mps: float = 0.03
    heading_sigma_deg: float = 0.5
    shaft_sigma_rpm: float = 1.5
    disturbance_sigma: tuple = (2.0, 3.0, 0.0, 1.0, 1.0, 0.5)
    disturbance_correlation_s: float = 4.0
    hdop: float = 0.8
    payload_force: bool = False
    path: str = "lawnmower"  # or "straight", "circle-starboard", "circle-port"
    gyro: bool = False  # a rate gyro's yaw rate in each fix's line
    gyro_sigma_degps: float = 0.2
    gyro_scale: float = 1.0  # reported over true: the gyro's scale error
    gyro_bias_degps: float = 0.0  # reported minus true scale x rate: its bias
    scales: VesselScales = field(default_factory=VesselScales)


def flat_to_geodetic(north_m, east_m, lat0_deg, lon0_deg):
    """Local flat-earth north/east to latitude/longitude (docs/model.md section 2)."""
    lat0 = math.radians(lat0_deg)
    s2 = math.sin(lat0) ** 2
    r_n = WGS84_A_M / math.sqrt(1.0 - WGS84_E2 * s2)
    r_m = r_n * (1.0 - WGS84_E2) / (1.0 - WGS84_E2 * s2)
    lat = lat0_deg + np.degrees(np.asarray(north_m) / r_m)
    lon = lon0_deg + np.degrees(np.asarray(east_m) / (r_n * math.cos(lat0)))
    return lat, lon


def rfc3339(start: dt.datetime, elapsed_s: float) -> str:
    """A UTC time stamp to the microsecond."""
    t = start + dt.timedelta(microseconds=round(elapsed_s * 1e6))
    return t.strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def simulate(cfg: RunConfig, fx: Effects):
    """Runs the trial; returns (log lines, truth dict)."""
    params = otter_parameters(cfg.scales)
    dyn = OtterDynamics(params, cfg.payload_force)
    if cfg.path == "straight":
        plan = straight(1.5 * cfg.duration_s + 50.0)
    elif cfg.path in ("circle-starboard", "circle-port"):
        sign = 1.0 if cfg.path == "circle-starboard" else -1.0
        plan = circles(1.5 * cfg.duration_s + 50.0, turn_sign=sign)
    else:
        plan = lawn_mower()
    guidance = PurePursuit(plan)
    seeds = np.random.SeedSequence(cfg.seed).spawn(5)
    rng_dist, rng_gnss, rng_heading, rng_shaft, rng_gyro = (
        np.random.default_rng(s) for s in seeds
    )

    beta = math.radians(fx.current_toward_deg)
    current = (
        fx.current_speed_mps * math.cos(beta),
        fx.current_speed_mps * math.sin(beta),
        0.0,
    )
    lossy = (1.0 - fx.loss_port, 1.0 - fx.loss_starboard)

    def factor_at(t_s):
        return lossy if t_s >= fx.loss_onset_s else (1.0, 1.0)

    speed0 = float(plan.speed_mps[0])
    n0 = shaft_for_thrust_radps(params, 0.5 * params.linear_damping[0] * speed0)
    x = [0.0] * 6 + [speed0, 0.0, 0.0, 0.0, 0.0, 0.0] + [n0, n0]
    pilot = Autopilot(params, 0.0, cfg.scales.size)
    cmd = (n0, n0)

    h = cfg.step_s
    steps = int(round(cfg.duration_s / h))
    per_control = int(round(cfg.control_period_s / h))
    per_gnss = int(round(cfg.gnss_period_s / h))
    per_shaft = int(round(cfg.shaft_period_s / h))
    per_truth = int(round(1.0 / h))

    # Disturbance: exact discretization of a first-order Gauss-Markov process.
    a_gm = math.exp(-h / cfg.disturbance_correlation_s)
    b_gm = math.sqrt(1.0 - a_gm * a_gm)
    sig = np.array(cfg.disturbance_sigma)
    dist_noise = rng_dist.standard_normal((steps + 1, 6))
    dist = sig * dist_noise[0]

    # Samples of the truth the sensors need: (time, state copy).
    gnss_samples = []  # (t, x, ground velocity of the antenna, antenna position)
    shaft_samples = []
    heading_truth = []  # (t, psi) at every step, for sampling at the stamps
    rate_truth = []  # r at every step
    track = []

    antenna = (fx.lever_arm_x_m, fx.lever_arm_y_m, -cfg.antenna_height_m)

    for k in range(steps + 1):
        t = k * h
        rot = rotation_zyx(x[3], x[4], x[5])
        ground_lin = mat_vec(rot, x[6:9])
        vel_n = [ground_lin[i] + current[i] for i in range(3)]
        sog = math.hypot(vel_n[0], vel_n[1])
        heading_truth.append(x[5])
        rate_truth.append(x[11])
        factor = factor_at(t)
        if k % per_control == 0:
            course_d, speed_d = guidance.command(x[0], x[1])
            cmd = pilot.command(
                cfg.control_period_s, x[5], x[11], sog, course_d, speed_d
            )
        if k % per_gnss == 0:
            # The antenna's position and velocity over ground.
            arm_n = mat_vec(rot, antenna)
            omega_x_arm = cross3(x[9:12], antenna)
            arm_vel = mat_vec(rot, omega_x_arm)
            gnss_samples.append(
                (
                    t,
                    x[0] + arm_n[0],
                    x[1] + arm_n[1],
                    vel_n[0] + arm_vel[0],
                    vel_n[1] + arm_vel[1],
                )
            )
        if k % per_shaft == 0:
            shaft_samples.append((t, x[12], x[13]))
        if k % per_truth == 0:
            track.append(
                {
                    "t_s": round(t, 3),
                    "north_m": x[0],
                    "east_m": x[1],
                    "heave_m": x[2],
                    "roll_deg": math.degrees(x[3]),
                    "pitch_deg": math.degrees(x[4]),
                    "heading_deg": math.degrees(x[5]) % 360.0,
                    "u_water_mps": x[6],
                    "v_water_mps": x[7],
                    "r_degps": math.degrees(x[11]),
                    "sog_mps": sog,
                    "shaft_rpm": [x[12] * RPM_PER_RADPS, x[13] * RPM_PER_RADPS],
                    "shaft_cmd_rpm": [cmd[0] * RPM_PER_RADPS, cmd[1] * RPM_PER_RADPS],
                    "thrust_n": [
                        factor[0] * thrust_n(params, x[12]),
                        factor[1] * thrust_n(params, x[13]),
                    ],
                    "loss": [1.0 - factor[0], 1.0 - factor[1]],
                }
            )
        if k == steps:
            break
        inp = Inputs(cmd, factor_at(t + 0.5 * h), tuple(dist), current)
        x = rk4_step(dyn, x, inp, h)
        dist = a_gm * dist + b_gm * sig * dist_noise[k + 1]

    # ---- sensors (vectorized over the samples)
    g = np.array(gnss_samples)
    count = len(g)
    pos_noise = cfg.position_sigma_m * rng_gnss.standard_normal((count, 2))
    vel_noise = cfg.velocity_sigma_mps * rng_gnss.standard_normal((count, 2))
    vn = g[:, 3] + vel_noise[:, 0]
    ve = g[:, 4] + vel_noise[:, 1]
    sog_rep = fx.sog_scale * np.hypot(vn, ve)
    cog_rep = np.mod(np.arctan2(ve, vn), 2.0 * math.pi)
    lat, lon = flat_to_geodetic(
        g[:, 1] + pos_noise[:, 0], g[:, 2] + pos_noise[:, 1],
        cfg.origin_lat_deg, cfg.origin_lon_deg,
    )
    stamps = g[:, 0] + fx.latency_s
    # The heading is read when the fix is written: the truth at the stamp.
    t_grid = np.arange(len(heading_truth)) * h
    psi_unwrapped = np.unwrap(np.array(heading_truth))
    psi_at = np.interp(stamps, t_grid, psi_unwrapped)
    heading_rep = np.mod(
        psi_at
        + math.radians(fx.heading_offset_deg)
        + math.radians(cfg.heading_sigma_deg) * rng_heading.standard_normal(count),
        2.0 * math.pi,
    )
    keep = stamps <= cfg.duration_s + 1e-9
    rate_at = np.interp(stamps, t_grid, np.array(rate_truth))
    rate_rep = (
        cfg.gyro_scale * rate_at
        + math.radians(cfg.gyro_bias_degps)
        + math.radians(cfg.gyro_sigma_degps) * rng_gyro.standard_normal(count)
    )

    s = np.array(shaft_samples)
    shaft_noise = cfg.shaft_sigma_rpm * rng_shaft.standard_normal((len(s), 2))
    rpm = np.round(s[:, 1:3] * RPM_PER_RADPS + shaft_noise, 1)

    events = []
    for i in range(count):
        if not keep[i]:
            continue
        line = {
            "type": "gnss",
            "time": rfc3339(cfg.start, stamps[i]),
            "lat_deg": float(lat[i]),
            "lon_deg": float(lon[i]),
            "sog_mps": float(sog_rep[i]),
            "cog_rad": float(cog_rep[i]),
            "heading_rad": float(heading_rep[i]),
            "hdop": cfg.hdop,
        }
        if cfg.gyro:
            line["yaw_rate_radps"] = float(rate_rep[i])
        events.append((float(stamps[i]), 0, line))
    for i in range(len(s)):
        line = {
            "type": "actuators",
            "time": rfc3339(cfg.start, s[i, 0]),
            "rpm": {"port": float(rpm[i, 0]), "starboard": float(rpm[i, 1])},
        }
        events.append((float(s[i, 0]), 1, line))
    events.sort(key=lambda ev: (ev[0], ev[1]))
    lines = [json.dumps(ev[2], separators=(",", ":")) for ev in events]

    rolls = [abs(p["roll_deg"]) for p in track]
    truth = {
        "simulator": "tests/othersim/otter6dof.py",
        "model": "Otter USV, 6 DOF (Fossen 2021; parameters of otter.py)",
        "seed": cfg.seed,
        "effects": {
            "kinds": fx.kinds or ["none"],
            "current": {
                "speed_mps": fx.current_speed_mps,
                "toward_deg": fx.current_toward_deg % 360.0,
                "north_mps": current[0],
                "east_mps": current[1],
            },
            "heading_offset_deg": fx.heading_offset_deg,
            "sog_scale": fx.sog_scale,
            "latency_s": fx.latency_s,
            "lever_arm_m": {"x_m": fx.lever_arm_x_m, "y_m": fx.lever_arm_y_m},
            "loss": {"port": fx.loss_port, "starboard": fx.loss_starboard},
            "loss_onset_s": fx.loss_onset_s,
        },
        "vessel_scales": vars(cfg.scales),
        "path": cfg.path,
        "start_time": rfc3339(cfg.start, 0.0),
        "origin": {"lat_deg": cfg.origin_lat_deg, "lon_deg": cfg.origin_lon_deg},
        "duration_s": cfg.duration_s,
        "step_s": cfg.step_s,
        "fossen_payload_force": cfg.payload_force,
        "sensors": {
            "gnss_rate_hz": 1.0 / cfg.gnss_period_s,
            "position_sigma_m": cfg.position_sigma_m,
            "velocity_sigma_mps": cfg.velocity_sigma_mps,
            "heading_sigma_deg": cfg.heading_sigma_deg,
            "shaft_rate_hz": 1.0 / cfg.shaft_period_s,
            "gyro": cfg.gyro,
            "gyro_scale": cfg.gyro_scale,
            "gyro_bias_degps": cfg.gyro_bias_degps,
            "shaft_sigma_rpm": cfg.shaft_sigma_rpm,
            "antenna_height_m": cfg.antenna_height_m,
        },
        "summary": {
            "path_index_reached": guidance.index,
            "path_points": len(plan.north_m),
            "max_abs_roll_deg": max(rolls),
            "max_abs_pitch_deg": max(abs(p["pitch_deg"]) for p in track),
            "mean_sog_mps": float(np.mean([p["sog_mps"] for p in track])),
            "gnss_lines": int(np.sum(keep)),
            "actuator_lines": len(s),
        },
        "track_1hz": track,
    }
    return lines, truth


# --------------------------------------------------------------------------
# Command line


def effects_from_args(args, rng: np.random.Generator) -> Effects:
    """The effects asked for; a missing size is drawn from EFFECT_RANGES."""
    fx = Effects()

    def pick(value, lo_hi):
        return value if value is not None else float(rng.uniform(*lo_hi))

    def sign():
        return 1.0 if rng.random() < 0.5 else -1.0

    kinds = [k for k in (args.effect or []) if k != "none"]
    # A size given names its effect even without --effect.
    implied = {
        "current": (args.current_speed_mps, args.current_toward_deg),
        "heading_offset": (args.heading_offset_deg,),
        "sog_scale": (args.sog_scale,),
        "latency": (args.latency_s,),
        "lever_arm": (args.lever_arm_x_m, args.lever_arm_y_m),
        "loss": (args.loss_side, args.loss),
    }
    for kind, values in implied.items():
        if kind not in kinds and any(v is not None for v in values):
            kinds.append(kind)
    fx.kinds = kinds
    for kind in kinds:
        ranges = EFFECT_RANGES[kind]
        if kind == "current":
            fx.current_speed_mps = pick(args.current_speed_mps, ranges["speed_mps"])
            fx.current_toward_deg = pick(args.current_toward_deg, ranges["toward_deg"])
        elif kind == "heading_offset":
            fx.heading_offset_deg = (
                args.heading_offset_deg
                if args.heading_offset_deg is not None
                else sign() * pick(None, ranges["offset_deg"])
            )
        elif kind == "sog_scale":
            fx.sog_scale = (
                args.sog_scale
                if args.sog_scale is not None
                else 1.0 + sign() * pick(None, ranges["scale_error"])
            )
        elif kind == "latency":
            fx.latency_s = pick(args.latency_s, ranges["latency_s"])
        elif kind == "lever_arm":
            if args.lever_arm_x_m is not None or args.lever_arm_y_m is not None:
                fx.lever_arm_x_m = args.lever_arm_x_m or 0.0
                fx.lever_arm_y_m = args.lever_arm_y_m or 0.0
            else:
                length = pick(None, ranges["length_m"])
                bearing = math.radians(pick(None, ranges["bearing_deg"]))
                fx.lever_arm_x_m = length * math.cos(bearing)
                fx.lever_arm_y_m = length * math.sin(bearing)
        elif kind == "loss":
            side = args.loss_side or ("port" if rng.random() < 0.5 else "starboard")
            loss = pick(args.loss, ranges["loss"])
            if side == "port":
                fx.loss_port = loss
            else:
                fx.loss_starboard = loss
    return fx


# Named craft: their scales on Fossen's Otter (the rest 1).
VESSELS = {
    "otter": {},
    # The twin-propeller workboat of config/scenarios/identify_workboat.toml:
    # twice the Otter's size (4 m), eight times its mass and added mass,
    # propellers twice as far apart and six times as strong, its own damping.
    "workboat": {
        "size": 2.0,
        "mass": 8.0,
        "added_mass": 8.0,
        "propeller_arm": 2.0,
        "thrust": 6.0,
        "surge_damping": 5.0,
        "sway_damping": 8.0,
        "yaw_damping": 24.0,
    },
}


def vessel_scales(args) -> VesselScales:
    """The craft's scales: the named vessel's, each overridden by its
    --*-scale argument where given."""
    preset = VESSELS[args.vessel]
    fields = ("mass", "added_mass", "surge_damping", "sway_damping",
              "yaw_damping", "crossflow", "thrust", "size", "propeller_arm")
    given = {
        name: getattr(args, f"{name}_scale")
        if getattr(args, f"{name}_scale") is not None
        else preset.get(name, 1.0)
        for name in fields
    }
    return VesselScales(**given)


def parse_args(argv):
    ap = argparse.ArgumentParser(
        description="An independent 6-DOF Otter USV simulator (see the module doc)."
    )
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument(
        "--effect",
        action="append",
        choices=EFFECT_KINDS,
        help="an effect to hide (repeat for several); default none",
    )
    ap.add_argument("--current-speed-mps", type=float)
    ap.add_argument("--current-toward-deg", type=float)
    ap.add_argument("--heading-offset-deg", type=float)
    ap.add_argument("--sog-scale", type=float)
    ap.add_argument("--latency-s", type=float)
    ap.add_argument("--lever-arm-x-m", type=float)
    ap.add_argument("--lever-arm-y-m", type=float)
    ap.add_argument("--loss-side", choices=("port", "starboard"))
    ap.add_argument("--loss", type=float)
    ap.add_argument("--loss-onset-s", type=float, default=0.0,
                    help="the loss acts from this time on (s)")
    ap.add_argument(
        "--path",
        choices=("lawnmower", "straight", "circle-starboard", "circle-port"),
        default="lawnmower",
        help="a lawn-mower of seven legs, one straight leg, or a steady turn "
        "on a circle of 20 m radius after a 20 m lead-in",
    )
    ap.add_argument("--shaft-rate-hz", type=float, default=10.0)
    ap.add_argument("--gyro", action="store_true",
                    help="write a rate gyro's yaw_rate_radps into each fix's line")
    ap.add_argument("--gyro-scale", type=float, default=1.0,
                    help="the gyro reads this times the true yaw rate (a scale error)")
    ap.add_argument("--gyro-bias-deg-s", type=float, default=0.0,
                    help="the gyro reads this much more than the true yaw rate (a bias), deg/s")
    ap.add_argument("--vessel", choices=tuple(VESSELS), default="otter",
                    help="the craft's scales (VESSELS); a --*-scale given overrides its own")
    for name in ("mass", "added-mass", "surge-damping", "sway-damping",
                 "yaw-damping", "crossflow", "thrust", "size", "propeller-arm"):
        ap.add_argument(f"--{name}-scale", type=float,
                        help=f"the craft's {name.replace('-', ' ')} times this")
    ap.add_argument("--duration-s", type=float, default=300.0)
    ap.add_argument("--step-s", type=float, default=0.05)
    ap.add_argument(
        "--fossen-payload-force",
        action="store_true",
        help="also apply the payload's weight as an external force, as otter.py does",
    )
    ap.add_argument(
        "--calm",
        action="store_true",
        help="no random forces of the water (the disturbance's sigmas zero)",
    )
    ap.add_argument("--out", help="the JSON-lines log to write")
    ap.add_argument("--truth", help="the truth JSON to write")
    ap.add_argument(
        "--check", action="store_true", help="print the model's numbers and exit"
    )
    return ap.parse_args(argv)


def print_check():
    p = otter_parameters()
    np.set_printoptions(precision=3, suppress=True, linewidth=120)
    print("M (6x6):")
    print(p.mass_matrix)
    print("surge-sway-yaw block:")
    print(p.mass_matrix[np.ix_([0, 1, 5], [0, 1, 5])])
    print("G (6x6):")
    print(np.array(p.restoring))
    print("linear damping diag:", np.round(p.linear_damping, 3))
    print("natural frequencies heave, roll, pitch (rad/s):",
          np.round(p.natural_frequencies_radps, 3))
    print("GM_T, GM_L (m):", np.round(p.metacentric_heights_m, 3))
    print("draft (m): %.4f" % p.draft_m)
    print("n_max, n_min (rad/s): %.2f %.2f" % (p.shaft_max_radps, p.shaft_min_radps))


def main(argv=None) -> int:
    args = parse_args(sys.argv[1:] if argv is None else argv)
    if args.check:
        print_check()
        return 0
    if not args.out:
        print("otter6dof: --out LOG is required", file=sys.stderr)
        return 2
    # The draw of missing sizes uses a stream of its own.
    draw_rng = np.random.default_rng(np.random.SeedSequence([args.seed, 0xEFFEC7]))
    fx = effects_from_args(args, draw_rng)
    fx.loss_onset_s = args.loss_onset_s
    cfg = RunConfig(
        seed=args.seed,
        duration_s=args.duration_s,
        step_s=args.step_s,
        payload_force=args.fossen_payload_force,
        path=args.path,
        gyro=args.gyro,
        gyro_scale=args.gyro_scale,
        gyro_bias_degps=args.gyro_bias_deg_s,
        shaft_period_s=1.0 / args.shaft_rate_hz,
        scales=vessel_scales(args),
    )
    if args.calm:
        cfg.disturbance_sigma = (0.0,) * 6
    lines, truth = simulate(cfg, fx)
    with open(args.out, "w", encoding="utf-8") as f:
        f.write("\n".join(lines))
        f.write("\n")
    if args.truth:
        with open(args.truth, "w", encoding="utf-8") as f:
            json.dump(truth, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
