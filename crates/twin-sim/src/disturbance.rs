//! Random disturbances: the unmodelled, irregular push of waves, boat wakes,
//! reflections off the quays and wind gusts on the hull, as a force in surge
//! and sway and a moment in yaw, each a first-order Gauss-Markov process.
//!
//! # Model
//! Each component `d` (surge force `X_d`, sway force `Y_d`, yaw moment `N_d`,
//! body frame, at the body origin) is an Ornstein-Uhlenbeck process with
//! stationary standard deviation `sigma` and correlation time `T`:
//!
//! ```text
//! d' = -d / T + sigma sqrt(2 / T) w(t),     E[d(t) d(t + tau)] = sigma^2 e^{-|tau| / T}
//! ```
//!
//! with `w` unit white noise, the three components independent. It enters the
//! equations of motion next to the propeller and wind loads
//! (`tau = tau_prop + tau_wind + tau_d`).
//!
//! # Integration
//! The disturbance is held constant over every integration step, so each RK4
//! step integrates a smooth right-hand side, and is updated between steps
//! with the exact discretisation of the process over the elapsed time `h`:
//!
//! ```text
//! d <- d e^{-h/T} + sigma sqrt(1 - e^{-2h/T}) n,    n ~ N(0, 1)
//! ```
//!
//! which keeps the variance at `sigma^2` and the correlation at `e^{-h/T}`
//! whatever `h`. The first value is drawn from the stationary distribution,
//! so the statistics hold from the trial's start.
//!
//! Updates happen on a clock of their own, every `T / 20`
//! ([`UPDATES_PER_CORRELATION_TIME`]), whose instants the simulation loop
//! adds to its schedule, so every integration step lies between two updates.
//! The realisation therefore depends on the seed and the `[disturbance]`
//! section only: not on `step_s` (halving the step still changes the
//! trajectory only by the integrator's error) nor on which sensors are on.
//! Holding the force for `T / 20` loses nothing the hull can feel: the
//! process's spectrum is down by a factor of about 4000 at the hold's
//! Nyquist frequency `10 / T`, and the low-frequency density of the held
//! process is `2 sigma^2 T` to within 0.02 %. With the default `T = 2 s` the
//! updates are at 10 Hz, on the autopilot's own instants.
//!
//! # Random stream
//! The process draws from a stream of the scenario's seed salted apart from
//! the sensors' streams, so switching the disturbance on or off leaves every
//! sensor's noise sequence as it was (the truth it is added to changes, of
//! course). Three numbers are drawn per update even when a component's sigma
//! is zero, so setting one component to zero leaves the others' realisations
//! unchanged.
//!
//! # For an estimator
//! At frequencies well below `1 / (2 pi T)` a Gauss-Markov force looks like
//! white noise of two-sided spectral density `2 sigma^2 T` (the integral of its
//! autocorrelation). On a body of (added-)mass `m` that is a white
//! acceleration of density `q = 2 (sigma / m)^2 T`: the continuous-time process
//! noise intensity of a velocity state (`E[w(t) w(s)] = q delta(t - s)`, a
//! discrete step `dt` adds about `q dt` to the velocity variance). See
//! [`crate::DisturbanceSpec::acceleration_density`].

use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, StandardNormal};

/// Salt of the disturbance's random stream (the sensors use others).
const STREAM_DISTURBANCE: u64 = 0x2545_F491_4F6C_DD1D;

/// Updates of the disturbance per correlation time: it is held for `T / 20`.
pub const UPDATES_PER_CORRELATION_TIME: f64 = 20.0;

/// Validated disturbance settings, SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct DisturbanceSettings {
    /// Stationary standard deviations `[X N, Y N, N N m]`.
    pub sigma: [f64; 3],
    /// Correlation time, s (positive).
    pub correlation_s: f64,
}

impl DisturbanceSettings {
    /// Time between updates, s.
    pub fn update_period_s(&self) -> f64 {
        self.correlation_s / UPDATES_PER_CORRELATION_TIME
    }
}

/// The disturbance force and moment as they evolve over a run.
#[derive(Debug, Clone)]
pub(crate) struct DisturbanceProcess {
    settings: DisturbanceSettings,
    rng: StdRng,
    /// Current value `[X, Y, N]` and the elapsed time it belongs to; `None`
    /// before the first update.
    state: Option<([f64; 3], f64)>,
}

impl DisturbanceProcess {
    pub fn new(settings: DisturbanceSettings, seed: u64) -> Self {
        Self {
            settings,
            rng: StdRng::seed_from_u64(seed ^ STREAM_DISTURBANCE),
            state: None,
        }
    }

    /// Moves the process to elapsed time `t_s` (exactly, over whatever time
    /// has passed since the last update; the first call draws from the
    /// stationary distribution) and returns its value there.
    pub fn advance_to(&mut self, t_s: f64) -> [f64; 3] {
        let fresh: [f64; 3] = std::array::from_fn(|_| StandardNormal.sample(&mut self.rng));
        let sigma = self.settings.sigma;
        let value = match self.state {
            None => std::array::from_fn(|i| sigma[i] * fresh[i]),
            Some((prev, prev_t_s)) => {
                let a = (-(t_s - prev_t_s).max(0.0) / self.settings.correlation_s).exp();
                let b = (1.0 - a * a).sqrt();
                std::array::from_fn(|i| a * prev[i] + b * sigma[i] * fresh[i])
            }
        };
        self.state = Some((value, t_s));
        value
    }

    /// The value held now (zero before the first update), `[X N, Y N, N N m]`.
    pub fn value(&self) -> [f64; 3] {
        self.state.map_or([0.0; 3], |(v, _)| v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings() -> DisturbanceSettings {
        DisturbanceSettings {
            sigma: [3.0, 0.0, 0.5],
            correlation_s: 0.5,
        }
    }

    #[test]
    fn stationary_variance_and_correlation_hold_for_any_step() {
        // Alternate two step lengths: the exact update keeps sigma and gives
        // the correlation e^{-h/T} of each step.
        let mut p = DisturbanceProcess::new(settings(), 7);
        let (mut t, mut xs, mut pairs_short, mut pairs_long) = (0.0, Vec::new(), 0.0, 0.0);
        let mut prev = p.advance_to(t)[0];
        xs.push(prev);
        let n = 200_000;
        for k in 0..n {
            let h = if k % 2 == 0 { 0.01 } else { 0.3 };
            t += h;
            let x = p.advance_to(t)[0];
            if k % 2 == 0 {
                pairs_short += prev * x;
            } else {
                pairs_long += prev * x;
            }
            prev = x;
            xs.push(x);
        }
        let var = xs.iter().map(|x| x * x).sum::<f64>() / xs.len() as f64;
        assert!((var.sqrt() / 3.0 - 1.0).abs() < 0.02, "{}", var.sqrt());
        let rho_short = pairs_short / (n / 2) as f64 / var;
        let rho_long = pairs_long / (n / 2) as f64 / var;
        assert!((rho_short - (-0.02f64).exp()).abs() < 0.01, "{rho_short}");
        assert!((rho_long - (-0.6f64).exp()).abs() < 0.01, "{rho_long}");
        // A zero sigma keeps its component at zero.
        assert_eq!(p.value()[1], 0.0);
    }

    #[test]
    fn the_stream_is_apart_from_every_sensors_stream() {
        use crate::sensors::{STREAM_GNSS, STREAM_HEADING, STREAM_PROPELLERS};
        for salt in [STREAM_GNSS, STREAM_HEADING, STREAM_PROPELLERS] {
            assert_ne!(STREAM_DISTURBANCE, salt);
        }
    }

    #[test]
    fn one_components_sigma_does_not_change_the_others() {
        let mut a = DisturbanceProcess::new(settings(), 3);
        let mut other = settings();
        other.sigma[0] = 0.0;
        let mut b = DisturbanceProcess::new(other, 3);
        for k in 0..100 {
            let t = f64::from(k) * 0.01;
            assert_eq!(a.advance_to(t)[2], b.advance_to(t)[2]);
        }
        assert_eq!(b.value()[0], 0.0);
    }
}
