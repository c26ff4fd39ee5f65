//! The water current and the wind the simulated Otter meets.
//!
//! The current is uniform in space and either constant or slowly varying in
//! time: its speed may oscillate sinusoidally and its direction may turn at a
//! constant rate. Its direction is where the water flows *toward*
//! (oceanographic convention). The wind is uniform; its direction is where it
//! comes *from* (meteorological convention). Both are evaluated analytically,
//! so the current's acceleration (which enters the equations of motion) is
//! exact.
//!
//! # Wind load
//! A quadratic air-drag model in the style of Fossen (2021, section 10.1) for
//! a small craft, with `gamma` the angle the relative wind comes from,
//! measured from the bow, clockwise (0 = head wind, pi/2 = from starboard),
//! `V` the relative wind speed and `q = 1/2 rho_air V^2`:
//!
//! ```text
//! X = -c_x cos(gamma)     q A_front
//! Y = -c_y sin(gamma)     q A_side
//! N = -c_n sin(2 gamma)   q A_side L
//! ```
//!
//! A head wind pushes the craft astern; a wind from starboard pushes it to
//! port; `c_n > 0` turns the bow away from a wind on the bow (the centre of
//! effort forward of midships), `c_n < 0` into it. Defaults (see
//! [`crate::scenario::WindSpec`]) are within Fossen's ranges for small
//! craft; the Otter's real windage is not published.

use std::f64::consts::TAU;

/// A uniform current, constant or slowly varying.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct CurrentModel {
    /// Mean speed, m/s.
    pub speed_mps: f64,
    /// Direction the water flows toward at t = 0, rad clockwise from north.
    pub toward_rad: f64,
    /// Rate at which the direction turns, rad/s (positive clockwise).
    pub rotation_radps: f64,
    /// Amplitude of a sinusoidal speed variation, m/s.
    pub speed_amplitude_mps: f64,
    /// Period of the speed variation, s.
    pub speed_period_s: f64,
}

impl CurrentModel {
    /// No current.
    pub fn none() -> Self {
        Self {
            speed_mps: 0.0,
            toward_rad: 0.0,
            rotation_radps: 0.0,
            speed_amplitude_mps: 0.0,
            speed_period_s: 1.0,
        }
    }

    /// Velocity (north, east) in m/s and acceleration (north, east) in m/s^2
    /// at elapsed time `t_s`.
    pub fn at(&self, t_s: f64) -> ([f64; 2], [f64; 2]) {
        let w = TAU / self.speed_period_s;
        let speed = self.speed_mps + self.speed_amplitude_mps * (w * t_s).sin();
        let speed_rate = self.speed_amplitude_mps * w * (w * t_s).cos();
        let dir = self.toward_rad + self.rotation_radps * t_s;
        let (s, c) = dir.sin_cos();
        let velocity = [speed * c, speed * s];
        let accel = [
            speed_rate * c - speed * self.rotation_radps * s,
            speed_rate * s + speed * self.rotation_radps * c,
        ];
        (velocity, accel)
    }
}

/// A uniform wind and the craft's windage.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct WindModel {
    /// True wind speed, m/s.
    pub speed_mps: f64,
    /// Direction the wind comes from, rad clockwise from north.
    pub from_rad: f64,
    /// Frontal projected area above water, m^2.
    pub frontal_area_m2: f64,
    /// Lateral projected area above water, m^2.
    pub lateral_area_m2: f64,
    /// Length for the yaw moment, m.
    pub length_m: f64,
    /// Surge coefficient `c_x`.
    pub c_x: f64,
    /// Sway coefficient `c_y`.
    pub c_y: f64,
    /// Yaw coefficient `c_n`.
    pub c_n: f64,
    /// Air density, kg/m^3.
    pub air_density_kgpm3: f64,
}

impl WindModel {
    /// Force and moment `[X, Y, N]` (N, N, N m) on a craft at heading
    /// `psi_rad` moving with body velocity over ground `u_mps`, `v_mps`.
    pub fn force(&self, psi_rad: f64, u_mps: f64, v_mps: f64) -> [f64; 3] {
        // Air velocity over ground in the body frame: it blows from `from_rad`.
        let (s, c) = (self.from_rad - psi_rad).sin_cos();
        let air_x = -self.speed_mps * c;
        let air_y = -self.speed_mps * s;
        // Air relative to the hull.
        let rel_x = air_x - u_mps;
        let rel_y = air_y - v_mps;
        let rel_speed_sq = rel_x * rel_x + rel_y * rel_y;
        if rel_speed_sq == 0.0 {
            return [0.0; 3];
        }
        // Where the relative wind comes from, relative to the bow.
        let gamma = (-rel_y).atan2(-rel_x);
        let q = 0.5 * self.air_density_kgpm3 * rel_speed_sq;
        [
            -self.c_x * gamma.cos() * q * self.frontal_area_m2,
            -self.c_y * gamma.sin() * q * self.lateral_area_m2,
            -self.c_n * (2.0 * gamma).sin() * q * self.lateral_area_m2 * self.length_m,
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wind(speed: f64, from_deg: f64) -> WindModel {
        WindModel {
            speed_mps: speed,
            from_rad: from_deg.to_radians(),
            frontal_area_m2: 0.3,
            lateral_area_m2: 0.5,
            length_m: 2.0,
            c_x: 0.6,
            c_y: 0.8,
            c_n: 0.08,
            air_density_kgpm3: 1.225,
        }
    }

    #[test]
    fn still_air_drags_a_moving_craft_back() {
        let f = wind(0.0, 0.0).force(0.3, 2.0, 0.0);
        let q = 0.5 * 1.225 * 4.0;
        assert!((f[0] + 0.6 * q * 0.3).abs() < 1e-12, "{f:?}");
        assert!(f[1].abs() < 1e-12 && f[2].abs() < 1e-12);
    }

    #[test]
    fn beam_wind_from_starboard_pushes_to_port() {
        // Heading north, wind from the east.
        let f = wind(10.0, 90.0).force(0.0, 0.0, 0.0);
        assert!(
            f[1] < 0.0 && f[0].abs() < 1e-9 && f[2].abs() < 1e-9,
            "{f:?}"
        );
        assert!((f[1] + 0.8 * 0.5 * 1.225 * 100.0 * 0.5).abs() < 1e-9);
        // Head wind: pushed astern.
        let g = wind(10.0, 45.0).force(45f64.to_radians(), 0.0, 0.0);
        assert!(g[0] < 0.0 && g[1].abs() < 1e-9, "{g:?}");
    }

    #[test]
    fn wind_on_the_starboard_bow_turns_the_bow_away_with_positive_cn() {
        let f = wind(8.0, 45.0).force(0.0, 0.0, 0.0);
        assert!(f[2] < 0.0, "{f:?}");
    }

    #[test]
    fn current_acceleration_is_the_derivative_of_its_velocity() {
        let c = CurrentModel {
            speed_mps: 0.5,
            toward_rad: 1.0,
            rotation_radps: 0.01,
            speed_amplitude_mps: 0.1,
            speed_period_s: 120.0,
        };
        let t = 37.0;
        let h = 1e-4;
        let (vp, _) = c.at(t + h);
        let (vm, _) = c.at(t - h);
        let (_, a) = c.at(t);
        for i in 0..2 {
            let fd = (vp[i] - vm[i]) / (2.0 * h);
            assert!((fd - a[i]).abs() < 1e-8, "{fd} vs {}", a[i]);
        }
        assert_eq!(CurrentModel::none().at(5.0), ([0.0, 0.0], [0.0, 0.0]));
    }
}
