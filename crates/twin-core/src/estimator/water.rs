//! A kinematic vessel through water as an estimator base
//! ([`WaterKinematic`]): what `diagnose` runs on logs without propeller
//! data. It needs no vessel parameters (the antenna's position comes in
//! its sensor effects); it has no faults. A heading lost at a standstill
//! (no heading sensor, the course below the gate) is started afresh from
//! the course when the vessel moves again ([`WaterBase::reacquire`]).

use nalgebra::{SMatrix, SVector};

use super::{CourseGate, LocalFix, Term};
use crate::aekf::{Aekf, AekfConfig, AekfError, AekfState, GainSensitivity, StepReport};
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
    /// Sideways speed of the reference point per yaw rate and speed
    /// through water, s ([`WaterKinematic::sideslip_per_speed_s`]).
    pub sideslip_per_speed_s: f64,
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

/// Variance of a heading started from the course, rad^2 (half a radian:
/// the course is not the heading where the vessel drifts).
const HEADING_FROM_COURSE_VARIANCE: f64 = 0.25;

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
            gain_sensitivity: GainSensitivity::Omitted,
            gain_sensitivity_faults: [true; _],
        };
        let model = WaterKinematic {
            effects: options.effects,
            stw_scale: options.stw_scale,
            sideslip_m: options.sideslip_m,
            sideslip_per_speed_s: options.sideslip_per_speed_s,
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
                HEADING_FROM_COURSE_VARIANCE
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

    /// One step to `fix`, `dt_s` after the estimate, once the heading and
    /// yaw rate are re-acquired where they were lost
    /// ([`WaterBase::reacquire`]).
    pub fn step(
        &self,
        state: &mut AekfState<7, MEASUREMENTS, 0>,
        fix: &LocalFix,
        dt_s: f64,
    ) -> Result<StepReport<MEASUREMENTS, 0>, AekfError> {
        self.reacquire(state, fix);
        self.filter.step(state, &(), &self.measurement(fix), dt_s)
    }

    /// Starts the heading and the yaw rate afresh from `fix`, as
    /// [`WaterBase::prior`] starts them, where the heading is known less
    /// well than a heading started from the course and `fix`'s course is
    /// usable: the two states are replaced, their variances set to the
    /// prior's and their covariances with the other states dropped.
    /// Without a heading sensor, a vessel at a standstill (its course below
    /// the gate) loses its heading: the yaw rate's process noise makes it
    /// wander with a variance that grows past a whole turn. Updated from
    /// there by the first usable course, the filter's linearisation is
    /// meaningless, and where it lands depends on the smallest difference
    /// in the estimate (a GNSS latency a nanosecond longer moved a sailing
    /// yacht's likelihood by hundreds after a standstill). With a heading
    /// sensor, or underway, the heading is never known that little and
    /// nothing is changed.
    pub fn reacquire(&self, state: &mut AekfState<7, MEASUREMENTS, 0>, fix: &LocalFix) {
        if !self.gate.course_available(fix)
            || state.p[(idx::PSI, idx::PSI)] <= HEADING_FROM_COURSE_VARIANCE
        {
            return;
        }
        let fresh = self.prior(fix);
        for i in [idx::PSI, idx::R] {
            state.x[i] = fresh.x[i];
            state.p.row_mut(i).fill(0.0);
            state.p.column_mut(i).fill(0.0);
            state.p[(i, i)] = fresh.p[(i, i)];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geodesy::NorthEast;
    use rand::{Rng, SeedableRng, rngs::StdRng};
    use rand_distr::{Distribution, Normal};

    /// The diagnosis's kinematic base: its default noise, the course gated
    /// at 0.3 m/s.
    fn diagnosis_base(gnss_latency_s: f64) -> WaterBase {
        let options = WaterOptions {
            effects: SensorEffects {
                gnss_latency_s,
                ..SensorEffects::default()
            },
            stw_scale: 1.0,
            sideslip_m: 0.0,
            sideslip_per_speed_s: 0.0,
            current: Term::Free,
            process_noise: [1e-4, 1e-4, 1e-6, 1e-2, 1e-4, 1e-6, 1e-6],
            measurement_sigma: [0.5, 0.1, 0.05, 1f64.to_radians(), 0.1, 0.0087],
        };
        WaterBase::new(&options, CourseGate { min_sog_mps: 0.3 }).unwrap()
    }

    /// A yacht logged at 0.5 Hz without a heading sensor: two minutes at
    /// 1.5 m/s northward, four at a standstill (the receiver's speed a few
    /// cm/s, its course anything), then off at 1.5 m/s towards 120 deg; GNSS
    /// and log noise drawn with a fixed seed.
    fn standstill_log() -> Vec<LocalFix> {
        let mut rng = StdRng::seed_from_u64(7);
        let position_noise = Normal::new(0.0, 0.5).unwrap();
        let speed_noise = Normal::new(0.0, 0.05).unwrap();
        let course_noise = Normal::new(0.0, 0.03).unwrap();
        let (mut north, mut east) = (0.0, 0.0);
        let mut fixes = Vec::new();
        for k in 0..300 {
            let t = 2.0 * f64::from(k);
            let (speed, course) = match t {
                t if t < 120.0 => (1.5, 0.0),
                t if t < 360.0 => (0.0, 0.0),
                _ => (1.5, 120f64.to_radians()),
            };
            north += 2.0 * speed * f64::cos(course);
            east += 2.0 * speed * f64::sin(course);
            let (sog, cog) = if speed > 0.0 {
                (
                    speed + speed_noise.sample(&mut rng),
                    course + course_noise.sample(&mut rng),
                )
            } else {
                (
                    f64::abs(speed_noise.sample(&mut rng)),
                    rng.random_range(-3.1..3.1),
                )
            };
            fixes.push(LocalFix {
                time_s: t,
                position: NorthEast {
                    north_m: north + position_noise.sample(&mut rng),
                    east_m: east + position_noise.sample(&mut rng),
                },
                position_measured: true,
                sog_mps: Some(sog),
                cog_rad: Some(cog),
                heading_rad: None,
                yaw_rate_radps: None,
                stw_mps: Some((speed + speed_noise.sample(&mut rng)).max(0.0)),
            });
        }
        fixes
    }

    /// The NIS summed over the log, and the heading estimated at its end.
    fn run(base: &WaterBase, fixes: &[LocalFix]) -> (f64, f64) {
        let mut state = base.prior(&fixes[0]);
        let mut nis = 0.0;
        for pair in fixes.windows(2) {
            let dt = pair[1].time_s - pair[0].time_s;
            nis += base.step(&mut state, &pair[1], dt).unwrap().nis;
        }
        (nis, state.x[idx::PSI])
    }

    /// A standstill without a heading sensor loses the heading; where the
    /// course is usable again the heading is started afresh from it, so
    /// the filter's path after the standstill does not hang on the
    /// smallest difference of the estimate: a GNSS latency a nanosecond
    /// longer moves the log's summed NIS (about 1600) by less than 0.001.
    /// Without the re-acquisition that nanosecond moved it by about 0.01
    /// here, and a yacht's real log's likelihood by hundreds.
    #[test]
    fn a_heading_lost_at_a_standstill_is_reacquired_from_the_course() {
        let fixes = standstill_log();
        let (nis, psi) = run(&diagnosis_base(0.3), &fixes);
        let (nis_later, _) = run(&diagnosis_base(0.3 + 1e-9), &fixes);
        assert!(
            (nis - nis_later).abs() < 1e-3,
            "summed NIS {nis} and {nis_later} a nanosecond of latency apart"
        );
        let error = crate::geodesy::wrap_pi(psi - 120f64.to_radians());
        assert!(error.abs() < 0.1, "heading {psi} rad at the end");
    }

    /// Four hours of velocities without a position at 1 Hz, turning slowly
    /// in a 0.3 m/s current: the unobserved position's variance grows, and
    /// the filter stays finite and keeps the speed, heading and current.
    #[test]
    fn without_positions_the_filter_stays_well_conditioned() {
        let options = WaterOptions {
            effects: SensorEffects::default(),
            stw_scale: 1.0,
            sideslip_m: 0.0,
            sideslip_per_speed_s: 0.0,
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
