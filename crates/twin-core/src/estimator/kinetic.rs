//! The extended twin as an estimator base: the Otter's kinetic model
//! ([`OtterTwin<8>`]) driven by the measured shaft speeds, estimating each
//! propeller's loss and, where asked, the water current; optionally with
//! sensor effects in its measurement (`diagnose`'s hypotheses).

use nalgebra::{SMatrix, SVector};

use super::{CourseGate, FaultPrior, LocalFix};
use crate::aekf::{Aekf, AekfConfig, AekfError, AekfState, StepReport};
use crate::model::Measurement;
use crate::models::effects::SensorEffects;
use crate::models::otter_twin::{OtterTwin, ShaftSpeeds, idx, meas};
use crate::otter::OtterParams;
use crate::sample::PropellerSpeeds;

/// The extended twin's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KineticConfig {
    /// The vessel's parameters.
    pub params: OtterParams,
    /// The filter's tuning.
    pub filter: AekfConfig<8, 5, 2>,
    /// Initial standard deviation of the water current estimate, m/s.
    pub initial_current_sigma_mps: f64,
    /// Estimate the water current (off: the current is held at zero).
    pub estimate_current: bool,
    /// Propeller data older than this stop the extended twin, s.
    pub max_propeller_age_s: f64,
    /// With the current estimated, a straight run cannot tell a loss shared by
    /// both propellers from a current along the track (both slow the vessel
    /// alike); only turning separates them. The losses count as excited only
    /// while the heading over the filter's memory has spread at least this
    /// much: `1 - |mean of (cos psi, sin psi)|`, 0.05 being about a 65 deg arc.
    pub min_heading_spread: f64,
}

impl KineticConfig {
    /// The Otter with 5 Hz GNSS (0.3 m, 0.05 m/s) and heading, if any, at
    /// 0.5 deg, in sheltered harbour water.
    ///
    /// Process noise: the kinematics are exact (tiny noise on position and
    /// heading); the velocities take the random forces of harbour water as
    /// white accelerations of density `q = M^-1 diag(2 F^2 T) M^-T` for gusts
    /// and chop of 3 N surge, 4 N sway, 0.5 N m yaw with 2 s correlation (the
    /// simulator's default disturbance, `twin_sim::DisturbanceSpec`); the
    /// current drifts slowly.
    pub fn otter() -> Self {
        let mut q = SMatrix::<f64, 8, 8>::from_diagonal(&SVector::<f64, 8>::from_column_slice(&[
            1e-6, 1e-6, 1e-7, // position and heading
            4.9e-3, 2.5e-3, 7.8e-4, // surge, sway, yaw accelerations
            1e-6, 1e-6, // current
        ]));
        // The sway-yaw mass coupling turns a sway force into a yaw acceleration too.
        q[(idx::V, idx::R)] = -7.7e-4;
        q[(idx::R, idx::V)] = -7.7e-4;
        let r = SVector::<f64, 5>::from_column_slice(&[
            0.3 * 0.3,
            0.3 * 0.3,
            0.05 * 0.05,
            0.03 * 0.03,
            0.0087 * 0.0087,
        ]);
        Self {
            params: OtterParams::default(),
            filter: AekfConfig {
                process_noise_density: q,
                measurement_noise: SMatrix::from_diagonal(&r),
                forgetting_time_constant_s: 60.0,
                initial_fault_covariance: SMatrix::identity() * 0.1,
                anti_windup_ratio: 0.1,
                excitation_sigma: 0.03,
                noise_adaptation: None,
            },
            initial_current_sigma_mps: 0.5,
            estimate_current: true,
            max_propeller_age_s: 1.0,
            min_heading_spread: 0.05,
        }
    }
}

/// How a part of the model enters a filter run: left out, estimated, or
/// held at given values.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Term<const K: usize> {
    /// Held at zero.
    Off,
    /// Estimated by the filter.
    Free,
    /// Held at these values.
    Fixed([f64; K]),
}

/// What the kinetic base estimates and how it measures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KineticOptions {
    /// Effects on the measurement (none for the live twin).
    pub effects: SensorEffects,
    /// The water current `[north, east]`, m/s.
    pub current: Term<2>,
    /// The propeller losses `[port, starboard]`.
    pub losses: Term<2>,
}

impl KineticOptions {
    /// The live twin's: no sensor effects, the losses estimated, the current
    /// estimated or held at zero.
    pub fn live(estimate_current: bool) -> Self {
        Self {
            effects: SensorEffects::default(),
            current: if estimate_current {
                Term::Free
            } else {
                Term::Off
            },
            losses: Term::Free,
        }
    }
}

/// The kinetic base.
#[derive(Debug, Clone)]
pub struct KineticBase {
    filter: Aekf<OtterTwin<8>, 8, 5, 2>,
    options: KineticOptions,
    initial_current_sigma_mps: f64,
    gate: CourseGate,
}

/// A state that is held (no variance, no noise) is given this sliver of
/// variance so that the covariance stays positive definite.
const HELD_VARIANCE: f64 = 1e-12;

impl KineticBase {
    /// The base of `config` with `options`, masking the course below
    /// `gate`'s speed. A current that is not estimated has no process noise;
    /// losses that are not estimated have no covariance (the filter then
    /// holds them).
    pub fn new(
        config: &KineticConfig,
        gate: CourseGate,
        options: KineticOptions,
    ) -> Result<Self, AekfError> {
        let mut filter = config.filter;
        if options.current != Term::Free {
            for i in [idx::CURRENT_NORTH, idx::CURRENT_EAST] {
                filter.process_noise_density[(i, i)] = 0.0;
            }
        }
        if options.losses != Term::Free {
            filter.initial_fault_covariance = SMatrix::zeros();
        }
        let model = OtterTwin::new(config.params).with_effects(options.effects);
        Ok(Self {
            filter: Aekf::new(model, filter)?,
            options,
            initial_current_sigma_mps: config.initial_current_sigma_mps,
            gate,
        })
    }

    /// The filter.
    pub fn filter(&self) -> &Aekf<OtterTwin<8>, 8, 5, 2> {
        &self.filter
    }

    /// The model.
    pub fn model(&self) -> &OtterTwin<8> {
        &self.filter.model
    }

    /// What is estimated.
    pub fn options(&self) -> &KineticOptions {
        &self.options
    }

    /// `[north, east, sog, cog, heading]`; position always, the rest where
    /// measured, the course only above the gate's speed.
    pub fn measurement(&self, fix: &LocalFix) -> Measurement<5> {
        Measurement {
            values: SVector::<f64, 5>::from_column_slice(&[
                fix.position.north_m,
                fix.position.east_m,
                fix.sog_mps.unwrap_or(0.0),
                fix.cog_rad.unwrap_or(0.0),
                fix.heading_rad.unwrap_or(0.0),
            ]),
            available: [
                true,
                true,
                fix.sog_mps.is_some(),
                self.gate.course_available(fix),
                fix.heading_rad.is_some(),
            ],
        }
    }

    /// The first estimate from a fix: position as measured; heading from the
    /// heading sensor (less its offset, if the effects have one), else the
    /// course; surge speed from the speed over ground (less its scale);
    /// sway and yaw rate zero; the current as its term says. The losses
    /// start from `restored` where given (estimate and covariance), else
    /// from none with the configured covariance, or at the values held.
    pub fn prior(&self, fix: &LocalFix, restored: Option<FaultPrior<2>>) -> AekfState<8, 5, 2> {
        let fx = &self.options.effects;
        let mut x0 = SVector::<f64, 8>::zeros();
        x0[idx::NORTH] = fix.position.north_m;
        x0[idx::EAST] = fix.position.east_m;
        x0[idx::PSI] = fix
            .heading_rad
            .map(|h| crate::geodesy::wrap_pi(h - fx.heading_offset_rad))
            .or(fix.cog_rad)
            .unwrap_or(0.0);
        x0[idx::U] = fix.sog_mps.unwrap_or(0.0) / fx.sog_scale;
        let current_variance = match self.options.current {
            Term::Free => self.initial_current_sigma_mps.powi(2),
            Term::Off => HELD_VARIANCE,
            Term::Fixed(c) => {
                x0[idx::CURRENT_NORTH] = c[0];
                x0[idx::CURRENT_EAST] = c[1];
                HELD_VARIANCE
            }
        };
        let r = &self.filter.config.measurement_noise;
        let heading_variance = if fix.heading_rad.is_some() {
            r[(meas::HEADING, meas::HEADING)]
        } else {
            0.5f64.powi(2)
        };
        // The surge speed through the water is the speed over ground less
        // the current along the track: it is as uncertain as the current.
        let p0 = SMatrix::<f64, 8, 8>::from_diagonal(&SVector::<f64, 8>::from_column_slice(&[
            r[(meas::NORTH, meas::NORTH)],
            r[(meas::EAST, meas::EAST)],
            heading_variance,
            0.3f64.powi(2) + current_variance,
            0.3f64.powi(2),
            0.1f64.powi(2),
            current_variance,
            current_variance,
        ]));
        let config = &self.filter.config;
        match (self.options.losses, restored) {
            (Term::Free, Some(r)) => {
                let mut state = AekfState::new(config, x0, p0, r.theta);
                state.s = r.covariance;
                state
            }
            (Term::Fixed(l), _) => AekfState::new(config, x0, p0, SVector::from(l)),
            _ => AekfState::new(config, x0, p0, SVector::zeros()),
        }
    }

    /// One step to `fix`, `dt_s` after the estimate, driven by `input`. A
    /// current that is off stays exactly zero.
    pub fn step(
        &self,
        state: &mut AekfState<8, 5, 2>,
        input: &ShaftSpeeds,
        fix: &LocalFix,
        dt_s: f64,
    ) -> Result<StepReport<5, 2>, AekfError> {
        let report = self
            .filter
            .step(state, input, &self.measurement(fix), dt_s)?;
        if self.options.current == Term::Off {
            state.x[idx::CURRENT_NORTH] = 0.0;
            state.x[idx::CURRENT_EAST] = 0.0;
        }
        Ok(report)
    }
}

/// The shaft-speed samples since the last fix: the kinetic base's input is
/// their mean over the interval.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ShaftAccumulator {
    sum_port: f64,
    sum_stb: f64,
    count: u32,
    last: Option<PropellerSpeeds>,
}

impl ShaftAccumulator {
    /// Adds a sample.
    pub fn push(&mut self, p: &PropellerSpeeds) {
        self.sum_port += p.port_radps;
        self.sum_stb += p.starboard_radps;
        self.count += 1;
        self.last = Some(*p);
    }

    /// Samples since the last [`Self::take`].
    pub fn count(&self) -> u32 {
        self.count
    }

    /// The mean of the samples since the last call and starts a new
    /// interval; without samples in the interval, the last sample if it is
    /// at most `max_age_s` older than `time_s`, else `None`.
    pub fn take(&mut self, time_s: f64, max_age_s: f64) -> Option<ShaftSpeeds> {
        let acc = std::mem::take(self);
        self.last = acc.last;
        if acc.count > 0 {
            Some(ShaftSpeeds {
                port_radps: acc.sum_port / acc.count as f64,
                starboard_radps: acc.sum_stb / acc.count as f64,
            })
        } else {
            acc.last
                .filter(|p| time_s - p.time_s <= max_age_s)
                .map(|p| ShaftSpeeds {
                    port_radps: p.port_radps,
                    starboard_radps: p.starboard_radps,
                })
        }
    }
}
