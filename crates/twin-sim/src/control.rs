//! The Otter's autopilot as simulated: a heading controller (reference model
//! plus PID), a speed controller (feed-forward plus PI), and the allocation of
//! the surge force and yaw moment they ask for to the two propeller speeds.
//!
//! The controllers see the true state (a perfect navigation system) and know
//! nothing of propeller losses: their integral actions are what make up for a
//! weak propeller, as on the real craft. Gains come from pole placement on the
//! nominal surge and yaw dynamics `m x' + d x = tau` of the Otter (the design
//! numbers below), with bandwidths from the scenario.
//!
//! The reference model is a critically damped second-order filter of the
//! guidance's heading with limits on the turn rate and the angular
//! acceleration, so a way-point switch gives a smooth turn.

use twin_core::geodesy::wrap_pi;

use crate::otter::OtterParams;

/// Yaw inertia including added inertia the heading design uses, kg m^2.
const DESIGN_YAW_INERTIA_KGM2: f64 = 42.65;
/// Linear yaw damping the heading design uses, N m s/rad.
const DESIGN_YAW_DAMPING_NMS: f64 = 42.65;
/// Surge mass including added mass the speed design uses, kg.
const DESIGN_SURGE_MASS_KG: f64 = 85.5;
/// Linear surge damping the speed design uses (feed-forward), N s/m.
const DESIGN_SURGE_DAMPING_NSPM: f64 = 77.55;

/// Tuning of the autopilot (validated scenario values, SI units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct AutopilotTuning {
    /// Closed-loop natural frequency of the heading loop, rad/s.
    pub heading_bandwidth_radps: f64,
    /// Natural frequency of the heading reference model, rad/s.
    pub reference_bandwidth_radps: f64,
    /// Largest turn rate the reference model asks for, rad/s.
    pub max_turn_rate_radps: f64,
    /// Largest angular acceleration of the reference model, rad/s^2.
    pub max_turn_accel_radps2: f64,
    /// Closed-loop natural frequency of the speed loop, rad/s.
    pub speed_bandwidth_radps: f64,
}

/// Heading reference model and PID with feed-forward.
#[derive(Debug, Clone)]
pub(crate) struct HeadingAutopilot {
    tuning: AutopilotTuning,
    kp_nm_per_rad: f64,
    kd_nms_per_rad: f64,
    ki_nm_per_rads: f64,
    /// Reference heading, rad.
    pub psi_ref_rad: f64,
    /// Reference turn rate, rad/s.
    pub r_ref_radps: f64,
    accel_ref_radps2: f64,
    integral_rad_s: f64,
}

impl HeadingAutopilot {
    /// An autopilot whose reference starts at `psi_rad`, turning at `r_radps`.
    pub fn new(tuning: AutopilotTuning, psi_rad: f64, r_radps: f64) -> Self {
        let w = tuning.heading_bandwidth_radps;
        let zeta = 0.9;
        let m = DESIGN_YAW_INERTIA_KGM2;
        Self {
            tuning,
            kp_nm_per_rad: m * w * w,
            kd_nms_per_rad: 2.0 * zeta * w * m,
            ki_nm_per_rads: m * w * w * w / 10.0,
            psi_ref_rad: psi_rad,
            r_ref_radps: r_radps.clamp(-tuning.max_turn_rate_radps, tuning.max_turn_rate_radps),
            accel_ref_radps2: 0.0,
            integral_rad_s: 0.0,
        }
    }

    /// Advances the reference model toward `psi_cmd_rad` over `h_s`.
    fn advance_reference(&mut self, psi_cmd_rad: f64, h_s: f64) {
        const SUBSTEPS: usize = 10;
        let dt = h_s / SUBSTEPS as f64;
        let w = self.tuning.reference_bandwidth_radps;
        let r_max = self.tuning.max_turn_rate_radps;
        let a_max = self.tuning.max_turn_accel_radps2;
        for _ in 0..SUBSTEPS {
            let error = wrap_pi(psi_cmd_rad - self.psi_ref_rad);
            let accel = (w * w * error - 2.0 * w * self.r_ref_radps).clamp(-a_max, a_max);
            let rate = (self.r_ref_radps + accel * dt).clamp(-r_max, r_max);
            self.accel_ref_radps2 = (rate - self.r_ref_radps) / dt;
            self.r_ref_radps = rate;
            self.psi_ref_rad = wrap_pi(self.psi_ref_rad + rate * dt);
        }
    }

    /// The yaw moment to ask for, N m. `hold_integral` freezes the integral
    /// (anti-windup while the propellers are saturated).
    pub fn update(
        &mut self,
        psi_cmd_rad: f64,
        psi_rad: f64,
        r_radps: f64,
        h_s: f64,
        hold_integral: bool,
    ) -> f64 {
        self.advance_reference(psi_cmd_rad, h_s);
        let error = wrap_pi(psi_rad - self.psi_ref_rad);
        let rate_error = r_radps - self.r_ref_radps;
        if !hold_integral {
            self.integral_rad_s += error * h_s;
        }
        let r_ref = self.r_ref_radps;
        let feed_forward = DESIGN_YAW_INERTIA_KGM2 * self.accel_ref_radps2
            + DESIGN_YAW_DAMPING_NMS * r_ref * (1.0 + 10.0 * r_ref.abs());
        feed_forward
            - self.kp_nm_per_rad * error
            - self.kd_nms_per_rad * rate_error
            - self.ki_nm_per_rads * self.integral_rad_s
    }
}

/// Speed over ground: damping feed-forward plus PI.
#[derive(Debug, Clone)]
pub(crate) struct SpeedController {
    kp_n_per_mps: f64,
    ki_n_per_m: f64,
    integral_m: f64,
}

impl SpeedController {
    /// A speed controller with the given closed-loop bandwidth.
    pub fn new(bandwidth_radps: f64) -> Self {
        let w = bandwidth_radps;
        let m = DESIGN_SURGE_MASS_KG;
        Self {
            kp_n_per_mps: (2.0 * w * m - DESIGN_SURGE_DAMPING_NSPM).max(0.5 * w * m),
            ki_n_per_m: m * w * w,
            integral_m: 0.0,
        }
    }

    /// The surge force to ask for, N.
    pub fn update(
        &mut self,
        desired_mps: f64,
        speed_mps: f64,
        h_s: f64,
        hold_integral: bool,
    ) -> f64 {
        let error = desired_mps - speed_mps;
        if !hold_integral {
            self.integral_m += error * h_s;
        }
        DESIGN_SURGE_DAMPING_NSPM * desired_mps
            + self.kp_n_per_mps * error
            + self.ki_n_per_m * self.integral_m
    }
}

/// Shaft speed commands for a surge force and yaw moment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Allocation {
    /// Commanded shaft speeds (port, starboard), rad/s.
    pub n_cmd_radps: [f64; 2],
    /// True if the request could not be met within the thrust limits.
    pub saturated: bool,
}

/// Splits `[X, N]` into the two thrusts, `T_p = X/2 + N/(2b)`,
/// `T_s = X/2 - N/(2b)`, within the thrust limits with the yaw moment first
/// (the surge force gives way), and inverts the thrust model to shaft speeds.
pub(crate) fn allocate(params: &OtterParams, surge_n: f64, yaw_nm: f64) -> Allocation {
    let (t_min, t_max) = (params.min_thrust_n(), params.max_thrust_n());
    let b = params.propeller_arm_m;
    let wanted_diff = yaw_nm / b;
    let diff = wanted_diff.clamp(t_min - t_max, t_max - t_min);
    let wanted_mean = 0.5 * surge_n;
    let mean = wanted_mean.clamp(t_min + 0.5 * diff.abs(), t_max - 0.5 * diff.abs());
    let t_port = mean + 0.5 * diff;
    let t_stb = mean - 0.5 * diff;
    let saturated = diff != wanted_diff || mean != wanted_mean;
    Allocation {
        n_cmd_radps: [
            params.shaft_speed_for_thrust_radps(t_port),
            params.shaft_speed_for_thrust_radps(t_stb),
        ],
        saturated,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn allocation_inverts_the_thrust_model() {
        let p = OtterParams::default();
        let a = allocate(&p, 100.0, 8.0);
        assert!(!a.saturated);
        let t = [p.thrust_n(a.n_cmd_radps[0]), p.thrust_n(a.n_cmd_radps[1])];
        assert!((t[0] + t[1] - 100.0).abs() < 1e-9);
        assert!((p.propeller_arm_m * (t[0] - t[1]) - 8.0).abs() < 1e-9);
        // Port thrust turns the bow to starboard: a positive moment needs more port.
        assert!(a.n_cmd_radps[0] > a.n_cmd_radps[1]);
    }

    #[test]
    fn allocation_keeps_the_yaw_moment_when_saturated() {
        let p = OtterParams::default();
        let a = allocate(&p, 400.0, -10.0);
        assert!(a.saturated);
        let t = [p.thrust_n(a.n_cmd_radps[0]), p.thrust_n(a.n_cmd_radps[1])];
        assert!((p.propeller_arm_m * (t[0] - t[1]) + 10.0).abs() < 1e-9);
        assert!((t[1] - p.max_thrust_n()).abs() < 1e-9);
    }

    #[test]
    fn reference_model_respects_its_rate_limit() {
        let tuning = AutopilotTuning {
            heading_bandwidth_radps: 1.2,
            reference_bandwidth_radps: 0.6,
            max_turn_rate_radps: 10f64.to_radians(),
            max_turn_accel_radps2: 5f64.to_radians(),
            speed_bandwidth_radps: 0.5,
        };
        let mut ap = HeadingAutopilot::new(tuning, 0.0, 0.0);
        let mut peak: f64 = 0.0;
        for _ in 0..300 {
            ap.update(2.0, 0.0, 0.0, 0.1, true);
            peak = peak.max(ap.r_ref_radps.abs());
        }
        assert!(peak <= tuning.max_turn_rate_radps + 1e-12);
        assert!(peak > 0.99 * tuning.max_turn_rate_radps);
        assert!((ap.psi_ref_rad - 2.0).abs() < 1e-3, "{}", ap.psi_ref_rad);
    }
}
