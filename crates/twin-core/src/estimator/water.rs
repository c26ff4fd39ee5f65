//! A kinematic vessel through water as an estimator base
//! ([`WaterKinematic`]): what `diagnose` runs on logs without propeller
//! data. It needs no vessel parameters (the antenna's position comes in
//! its sensor effects); it has no faults.

use nalgebra::{SMatrix, SVector};

use super::{CourseGate, LocalFix, Term};
use crate::aekf::{Aekf, AekfConfig, AekfError, AekfState, StepReport};
use crate::model::Measurement;
use crate::models::effects::SensorEffects;
use crate::models::water_kinematic::{MEASUREMENTS, WaterKinematic, idx, meas};

/// What the water base estimates and how it measures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WaterOptions {
    /// Effects on the GNSS and heading measurement.
    pub effects: SensorEffects,
    /// Reported speed through water divided by the true one.
    pub stw_scale: f64,
    /// Sideways speed of the reference point per yaw rate, m/s per rad/s.
    pub sideslip_m: f64,
    /// The water current `[north, east]`, m/s.
    pub current: Term<2>,
    /// Process noise density of the 7 states (per second).
    pub process_noise: [f64; 7],
    /// Measurement noise standard deviations:
    /// `[position m, SOG m/s, COG rad, heading rad, STW m/s, yaw rate rad/s]`.
    pub measurement_sigma: [f64; 6],
}

/// The water base.
#[derive(Debug, Clone)]
pub struct WaterBase {
    filter: Aekf<WaterKinematic, 7, MEASUREMENTS, 0>,
    current: Term<2>,
    gate: CourseGate,
}

/// Initial variance of an estimated current, (m/s)^2.
const CURRENT_PRIOR_VARIANCE: f64 = 0.25;

impl WaterBase {
    /// The base with `options`, masking the course below `gate`'s speed. A
    /// current that is not estimated has no process noise.
    pub fn new(options: &WaterOptions, gate: CourseGate) -> Result<Self, AekfError> {
        let [sp, ssog, scog, shead, sstw, srate] = options.measurement_sigma;
        let r = SVector::<f64, MEASUREMENTS>::from_column_slice(&[
            sp * sp,
            sp * sp,
            ssog * ssog,
            scog * scog,
            shead * shead,
            sstw * sstw,
            srate * srate,
        ]);
        let mut q = SVector::<f64, 7>::from_column_slice(&options.process_noise);
        if options.current != Term::Free {
            q[idx::CURRENT_NORTH] = 0.0;
            q[idx::CURRENT_EAST] = 0.0;
        }
        let config = AekfConfig::<7, MEASUREMENTS, 0> {
            process_noise_density: SMatrix::from_diagonal(&q),
            measurement_noise: SMatrix::from_diagonal(&r),
            forgetting_time_constant_s: 60.0,
            fault_memory_factor: SVector::repeat(1.0),
            initial_fault_covariance: SMatrix::zeros(),
            anti_windup_ratio: 0.1,
            excitation_sigma: 0.03,
            noise_adaptation: None,
        };
        let model = WaterKinematic {
            effects: options.effects,
            stw_scale: options.stw_scale,
            sideslip_m: options.sideslip_m,
        };
        Ok(Self {
            filter: Aekf::new(model, config)?,
            current: options.current,
            gate,
        })
    }

    /// The filter.
    pub fn filter(&self) -> &Aekf<WaterKinematic, 7, MEASUREMENTS, 0> {
        &self.filter
    }

    /// `[north, east, sog, cog, heading, stw, yaw rate]`, each where
    /// measured, the course only above the gate's speed.
    pub fn measurement(&self, fix: &LocalFix) -> Measurement<MEASUREMENTS> {
        let gnss = self.gate.measurement(fix, fix.stw_mps);
        let mut values = SVector::<f64, MEASUREMENTS>::zeros();
        values.fixed_rows_mut::<6>(0).copy_from(&gnss.values);
        values[meas::YAW_RATE] = fix.yaw_rate_radps.unwrap_or(0.0);
        let mut available = [false; MEASUREMENTS];
        available[..6].copy_from_slice(&gnss.available);
        available[meas::YAW_RATE] = fix.yaw_rate_radps.is_some();
        Measurement { values, available }
    }

    /// The first estimate from a fix: position as measured; heading from the
    /// sensor (less its offset), else the course; speed through water from
    /// the log (less its scale), else the speed over ground (less its
    /// scale); yaw rate from the gyro (less its scale), else zero; the
    /// current as its term says.
    pub fn prior(&self, fix: &LocalFix) -> AekfState<7, MEASUREMENTS, 0> {
        let model = &self.filter.model;
        let r = &self.filter.config.measurement_noise;
        let mut x0 = SVector::<f64, 7>::zeros();
        x0[idx::NORTH] = fix.position.north_m;
        x0[idx::EAST] = fix.position.east_m;
        x0[idx::PSI] = fix
            .heading_rad
            .map(|h| crate::geodesy::wrap_pi(h - model.effects.heading_offset_rad))
            .or(fix.cog_rad)
            .unwrap_or(0.0);
        x0[idx::U] = fix
            .stw_mps
            .map(|v| v / model.stw_scale)
            .or(fix.sog_mps.map(|s| s / model.effects.sog_scale))
            .unwrap_or(0.0);
        x0[idx::R] = fix
            .yaw_rate_radps
            .map_or(0.0, |r| model.effects.yaw_rate_of_reading(r));
        let current_variance = match self.current {
            Term::Free => CURRENT_PRIOR_VARIANCE,
            Term::Off => 1e-12,
            Term::Fixed(c) => {
                x0[idx::CURRENT_NORTH] = c[0];
                x0[idx::CURRENT_EAST] = c[1];
                1e-12
            }
        };
        let p0 = SVector::<f64, 7>::from_column_slice(&[
            r[(0, 0)],
            r[(1, 1)],
            if fix.heading_rad.is_some() {
                r[(4, 4)]
            } else {
                0.25
            },
            0.25,
            if fix.yaw_rate_radps.is_some() {
                r[(meas::YAW_RATE, meas::YAW_RATE)]
            } else {
                0.01
            },
            current_variance,
            current_variance,
        ]);
        AekfState::new(
            &self.filter.config,
            x0,
            SMatrix::from_diagonal(&p0),
            SVector::zeros(),
        )
    }

    /// One step to `fix`, `dt_s` after the estimate.
    pub fn step(
        &self,
        state: &mut AekfState<7, MEASUREMENTS, 0>,
        fix: &LocalFix,
        dt_s: f64,
    ) -> Result<StepReport<MEASUREMENTS, 0>, AekfError> {
        self.filter.step(state, &(), &self.measurement(fix), dt_s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geodesy::NorthEast;

    /// Four hours of velocities without a position at 1 Hz, turning slowly
    /// in a 0.3 m/s current: the unobserved position's variance grows, and
    /// the filter stays finite and keeps the speed, heading and current.
    #[test]
    fn without_positions_the_filter_stays_well_conditioned() {
        let options = WaterOptions {
            effects: SensorEffects::default(),
            stw_scale: 1.0,
            sideslip_m: 0.0,
            current: Term::Free,
            process_noise: [1e-4, 1e-4, 1e-6, 1e-2, 1e-4, 1e-6, 1e-6],
            measurement_sigma: [0.5, 0.1, 0.05, 1f64.to_radians(), 0.1, 0.0087],
        };
        let base = WaterBase::new(&options, CourseGate { min_sog_mps: 0.5 }).unwrap();
        let (u, current) = (2.0, [0.3, 0.0]);
        let fix_at = |t: f64| {
            let psi = crate::geodesy::wrap_pi(0.01 * t);
            let (n, e) = (u * psi.cos() + current[0], u * psi.sin() + current[1]);
            LocalFix {
                time_s: t,
                position: NorthEast {
                    north_m: 0.0,
                    east_m: 0.0,
                },
                position_measured: false,
                sog_mps: Some(n.hypot(e)),
                cog_rad: Some(e.atan2(n)),
                heading_rad: Some(psi),
                yaw_rate_radps: Some(0.01),
                stw_mps: Some(u),
            }
        };
        let first = fix_at(0.0);
        assert_eq!(
            base.measurement(&first).available,
            [false, false, true, true, true, true, true]
        );
        let mut state = base.prior(&first);
        for k in 1..=4 * 3600 {
            let report = base.step(&mut state, &fix_at(f64::from(k)), 1.0).unwrap();
            assert!(report.nis.is_finite(), "step {k}");
        }
        assert!(state.p.iter().all(|v| v.is_finite()));
        assert!(state.p[(idx::NORTH, idx::NORTH)] > 100.0, "unobserved");
        assert!((state.x[idx::U] - u).abs() < 0.05);
        assert!((state.x[idx::CURRENT_NORTH] - current[0]).abs() < 0.05);
        assert!((state.x[idx::CURRENT_EAST] - current[1]).abs() < 0.05);
    }
}
