//! `identify`: a vessel profile's parameters from a trial of the healthy
//! vessel, with their uncertainty, what the trial could not excite, and the
//! gain on the part of the trial the fit never saw.
//!
//! # Method
//! The profile's surge damping, yaw damping, mass (with its inertia and
//! added mass, as one scale) and yaw inertia (rigid and added, a further
//! scale on it: the radius of gyration) are searched for the largest likelihood of
//! the training part of the trial (the first `1 - holdout_fraction` of it)
//! under the extended twin: both propellers healthy (losses held at zero),
//! the current and the heading sensor's offset estimated (as the live twin
//! estimates them), the velocities' process noise that of the water
//! alone, so that a wrong profile shows in the innovations. The search runs
//! on the logarithm of each scale, one parameter at a time (a grid, then
//! two parabolic steps), in rounds until no scale moves by more than
//! `tolerance`; each parameter's uncertainty is the likelihood's curvature
//! (the inverse of the Hessian's diagonal block, so that two parameters the
//! trial cannot tell apart are both reported as uncertain).
//!
//! **The force scale.** Positions and shaft speeds say how the vessel
//! accelerates and turns for a shaft speed, never how many newtons that
//! takes: scaling the mass, the damping and the thrust together changes no
//! motion. The thrust coefficient is therefore held at the starting
//! profile's (a propeller's data sheet, or a bollard pull) and the mass and
//! damping identified relative to it; the loss of a propeller is relative
//! to that baseline either way.
//!
//! **Not excited.** A parameter whose standard deviation after the trial
//! is above `identifiable_sigma` is reported as not identifiable from this
//! trial (a straight run at one speed cannot give the mass, a run without
//! turns cannot give the yaw damping) and keeps its starting value; the
//! yaw inertia then follows the mass (the starting profile's radius of
//! gyration is kept). The yaw's time constant is about a second, a few
//! GNSS fixes, and a trial often leaves it so.
//!
//! **Judged on held-out data.** The starting and the identified profile are
//! each run, with their errors held at zero, over the whole trial; the
//! held-out part's log-likelihood per step and position prediction errors
//! are compared.

use super::fit::{DiagnoseConfig, Hypothesis, minimise_1d};
use super::pass::{PassOptions, kinetic_pass};
use super::prepare::Prepared;
use crate::estimator::{KineticConfig, Term};
use crate::twin::TwinConfig;
use crate::vessel::VesselParams;

/// The parameters `identify` estimates: the twin's order of the profile's
/// errors (its mass-and-inertia error is the mass here), then the yaw
/// inertia on its own, because a starting profile's inertia is a rule of
/// thumb more often than its mass is.
pub const IDENTIFIED_PARAMETERS: [&str; 5] = [
    "surge damping",
    "yaw damping",
    "thrust coefficients",
    "mass",
    "yaw inertia",
];

/// The index of the thrust coefficients in [`IDENTIFIED_PARAMETERS`].
const THRUST: usize = 2;
/// The index of the mass.
const MASS: usize = 3;
/// The index of the yaw inertia.
const YAW_INERTIA: usize = 4;

/// How an identification runs.
#[derive(Debug, Clone, PartialEq)]
pub struct IdentifyConfig {
    /// Held-out fraction, horizons and the rest of the judging.
    pub diagnose: DiagnoseConfig,
    /// A parameter is identified when the trial pins its relative error
    /// to this standard deviation or better.
    pub identifiable_sigma: f64,
    /// Rounds stop when no scale moves by more than this (relative).
    pub tolerance: f64,
    /// The most rounds.
    pub max_rounds: usize,
}

impl Default for IdentifyConfig {
    fn default() -> Self {
        Self {
            diagnose: DiagnoseConfig::default(),
            identifiable_sigma: 0.05,
            tolerance: 0.005,
            max_rounds: 8,
        }
    }
}

/// One parameter's identification.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParameterEstimate {
    /// What it is ([`IDENTIFIED_PARAMETERS`]).
    pub name: &'static str,
    /// The identified value over the starting profile's.
    pub scale: f64,
    /// Standard deviation of its logarithm after the trial (about the
    /// relative standard deviation).
    pub sigma: f64,
    /// Whether the trial pinned it down (else it keeps its starting value).
    pub identified: bool,
    /// Held at the starting profile's by construction (the force scale).
    pub held: bool,
    /// What it keeps when the trial does not pin it down.
    pub fallback: Fallback,
}

/// What a parameter the trial did not pin down keeps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fallback {
    /// The starting profile's value.
    StartingProfile,
    /// The starting profile's value times the identified mass scale (the
    /// yaw inertia: the starting profile's radius of gyration).
    FollowsTheMass,
}

/// How well a profile predicts the held-out part of the trial.
#[derive(Debug, Clone, PartialEq)]
pub struct HeldOut {
    /// Negative log-likelihood per held-out step.
    pub nll_per_step: f64,
    /// Position prediction RMSE per horizon: `(horizon s, m)`.
    pub rmse_m: Vec<(f64, f64)>,
}

/// What an identification found.
#[derive(Debug, Clone, PartialEq)]
pub struct Identification {
    /// The identified parameters (the starting ones where not identified).
    pub params: VesselParams,
    /// Each parameter.
    pub estimates: [ParameterEstimate; 5],
    /// The relative standard deviations to give the twin of the identified
    /// profile ([`KineticConfig::profile_sigma`]), in its order: its
    /// mass-and-inertia error takes the larger of the mass's and the yaw
    /// inertia's.
    pub profile_sigma: [f64; 4],
    /// Rounds run.
    pub rounds: usize,
    /// The starting profile on the held-out part.
    pub before: HeldOut,
    /// The identified profile on the held-out part.
    pub after: HeldOut,
    /// Steps in the training and the held-out part.
    pub training_steps: usize,
    /// Held-out steps.
    pub heldout_steps: usize,
}

/// The smallest relative standard deviation given to the twin for an
/// identified parameter: what one trial in one sea state can promise (the
/// likelihood's curvature knows nothing of what the model itself lacks).
const MIN_IDENTIFIED_SIGMA: f64 = 0.05;

/// The searched parameters' indices in [`IDENTIFIED_PARAMETERS`].
const SEARCHED: [usize; 4] = [0, 1, 3, 4];
/// How many parameters are searched.
const N_SEARCHED: usize = SEARCHED.len();

/// `start` with the scales of [`IDENTIFIED_PARAMETERS`] applied, the yaw
/// inertia's on top of the mass's (which scales the whole mass matrix).
fn scaled_params(start: &VesselParams, scales: [f64; 5]) -> VesselParams {
    start
        .scaled([scales[0], scales[1], scales[2], scales[MASS]])
        .with_yaw_inertia_scaled(scales[YAW_INERTIA])
}

/// The twin `params` describes, taken as exact, with the water's process
/// noise alone.
fn exact_twin(base: &DiagnoseConfig, params: VesselParams) -> DiagnoseConfig {
    DiagnoseConfig {
        twin: TwinConfig {
            kinetic: KineticConfig {
                estimate_current: base.twin.kinetic.estimate_current,
                ..KineticConfig::for_vessel(params, 1.0)
            },
            ..base.twin
        },
        ..base.clone()
    }
}

/// The healthy twin's hypothesis: the current, the heading sensor's
/// offset and the rate sensor's bias estimated (as the live twin estimates
/// them: held at zero, a 6 deg offset was fitted into the hull, the mass
/// 20 % high), no loss.
fn healthy() -> Hypothesis {
    Hypothesis {
        current: Term::Free,
        loss: Term::Fixed([0.0, 0.0]),
        heading_bias: Term::Free,
        yaw_rate_bias: Term::Free,
        ..Hypothesis::nominal()
    }
}

/// Negative log-likelihood of the training part under `params`.
fn training_nll(prep: &Prepared, base: &DiagnoseConfig, params: VesselParams, split: usize) -> f64 {
    let config = exact_twin(base, params);
    let out = kinetic_pass(
        prep,
        &healthy(),
        PassOptions {
            split,
            train_only: true,
            record: false,
            config: &config,
        },
    );
    if out.failed || !out.nll_train.is_finite() {
        f64::INFINITY
    } else {
        out.nll_train
    }
}

/// The first held-out step of `prep` under `config`.
fn split_of(prep: &Prepared, config: &DiagnoseConfig) -> usize {
    let n = prep.steps.len();
    ((n as f64) * (1.0 - config.holdout_fraction)).round() as usize
}

/// `params` judged on the held-out part: the twin with the current
/// estimated, the propellers healthy and the profile taken as exact.
fn held_out(prep: &Prepared, base: &DiagnoseConfig, params: VesselParams) -> HeldOut {
    let config = exact_twin(base, params);
    let out = kinetic_pass(
        prep,
        &healthy(),
        PassOptions {
            split: split_of(prep, &config),
            train_only: false,
            record: false,
            config: &config,
        },
    );
    HeldOut {
        nll_per_step: if out.failed || out.steps_test == 0 {
            f64::INFINITY
        } else {
            out.nll_test / out.steps_test as f64
        },
        rmse_m: out.rmse(),
    }
}

/// Farthest a scale is searched from the starting profile's: a factor of 4.
const MAX_LOG_SCALE: f64 = 1.386_294_361_119_890_6;
/// Grid points of a one-parameter search.
const GRID: usize = 16;
/// Step of the finite differences of the likelihood's curvature, in the
/// logarithm of a scale.
const CURVATURE_STEP: f64 = 0.02;

/// The standard deviations of the log-scales from the likelihood's Hessian
/// over the `active` slots at `log_scales` (the square roots of its
/// inverse's diagonal; infinite where the Hessian is not positive definite,
/// zero for a slot held).
fn marginal_sigma(
    nll: &dyn Fn([f64; N_SEARCHED]) -> f64,
    log_scales: [f64; N_SEARCHED],
    active: &[usize],
) -> [f64; N_SEARCHED] {
    let h = CURVATURE_STEP;
    let at = |pairs: &[(usize, f64)]| {
        let mut x = log_scales;
        for (slot, d) in pairs {
            x[*slot] += d;
        }
        nll(x)
    };
    let f0 = at(&[]);
    let n = active.len();
    let mut hessian = nalgebra::DMatrix::<f64>::zeros(n, n);
    for (i, &a) in active.iter().enumerate() {
        hessian[(i, i)] = (at(&[(a, h)]) - 2.0 * f0 + at(&[(a, -h)])) / (h * h);
        for (j, &b) in active.iter().enumerate().take(i) {
            let v = (at(&[(a, h), (b, h)]) - at(&[(a, h), (b, -h)]) - at(&[(a, -h), (b, h)])
                + at(&[(a, -h), (b, -h)]))
                / (4.0 * h * h);
            hessian[(i, j)] = v;
            hessian[(j, i)] = v;
        }
    }
    let mut sigma = [0.0; N_SEARCHED];
    match hessian.cholesky() {
        Some(c) => {
            let inverse = c.inverse();
            for (i, &a) in active.iter().enumerate() {
                sigma[a] = inverse[(i, i)].max(0.0).sqrt();
            }
        }
        None => {
            for &a in active {
                sigma[a] = f64::INFINITY;
            }
        }
    }
    sigma
}

/// The largest likelihood over the `active` slots, from `log_scales`, one
/// slot at a time in rounds with a narrowing window; the optimum and the
/// rounds run.
fn search(
    nll: &dyn Fn([f64; N_SEARCHED]) -> f64,
    mut log_scales: [f64; N_SEARCHED],
    active: &[usize],
    config: &IdentifyConfig,
) -> ([f64; N_SEARCHED], usize) {
    let mut rounds = 0;
    while rounds < config.max_rounds {
        rounds += 1;
        let mut largest_move: f64 = 0.0;
        for &slot in active {
            let along = |x: f64| {
                let mut s = log_scales;
                s[slot] = x;
                nll(s)
            };
            // Each round searches a narrower window about the last value.
            let half = MAX_LOG_SCALE / rounds as f64;
            let lo = (log_scales[slot] - half).max(-MAX_LOG_SCALE);
            let hi = (log_scales[slot] + half).min(MAX_LOG_SCALE);
            let (best, _) = minimise_1d(&along, lo, hi, GRID);
            if along(best) <= along(log_scales[slot]) {
                largest_move = largest_move.max((best - log_scales[slot]).abs());
                log_scales[slot] = best;
            }
        }
        if largest_move < config.tolerance && rounds > 1 {
            break;
        }
    }
    (log_scales, rounds)
}

/// The searched slots without the yaw inertia's own factor.
const WITH_INERTIA_FOLLOWING_THE_MASS: [usize; 3] = [0, 1, 2];
/// Every searched slot.
const ALL_SEARCHED: [usize; 4] = [0, 1, 2, 3];

/// Identifies the profile of the vessel of `prep` (a trial of it healthy,
/// with propeller speeds), starting from `start`. `None` when the trial has
/// no propeller speeds or the twin cannot run on it.
///
/// First with the yaw inertia following the mass (the starting profile's
/// radius of gyration), then with its own factor free from there; that
/// factor is kept only where the trial pins it down, and else the first
/// fit is the answer, with its own uncertainties.
pub fn identify(
    prep: &Prepared,
    start: &VesselParams,
    config: &IdentifyConfig,
) -> Option<Identification> {
    if !prep.has_propellers || prep.steps.len() < 10 {
        return None;
    }
    let split = split_of(prep, &config.diagnose);
    let params_of = |log_scales: [f64; N_SEARCHED]| {
        let mut scales = [1.0; 5];
        for (slot, k) in SEARCHED.iter().enumerate() {
            scales[*k] = log_scales[slot].exp();
        }
        scaled_params(start, scales)
    };
    let nll = |log_scales: [f64; N_SEARCHED]| {
        training_nll(prep, &config.diagnose, params_of(log_scales), split)
    };
    if !nll([0.0; N_SEARCHED]).is_finite() {
        return None;
    }
    let (tied, tied_rounds) = search(
        &nll,
        [0.0; N_SEARCHED],
        &WITH_INERTIA_FOLLOWING_THE_MASS,
        config,
    );
    let (free, free_rounds) = search(&nll, tied, &ALL_SEARCHED, config);
    let free_sigma = marginal_sigma(&nll, free, &ALL_SEARCHED);
    let inertia_slot = N_SEARCHED - 1;
    let (log_scales, sigma_log) = if free_sigma[inertia_slot] <= config.identifiable_sigma {
        (free, free_sigma)
    } else {
        let mut sigma = marginal_sigma(&nll, tied, &WITH_INERTIA_FOLLOWING_THE_MASS);
        sigma[inertia_slot] = free_sigma[inertia_slot];
        // Reported (not used): the free fit's own factor.
        let mut reported = tied;
        reported[inertia_slot] = free[inertia_slot];
        (reported, sigma)
    };
    let rounds = tied_rounds + free_rounds;
    let mut scale = [1.0; 5];
    let mut sigma = [0.0; 5];
    for (slot, k) in SEARCHED.iter().enumerate() {
        scale[*k] = log_scales[slot].exp();
        sigma[*k] = sigma_log[slot];
    }
    let estimates: [ParameterEstimate; 5] = std::array::from_fn(|k| ParameterEstimate {
        name: IDENTIFIED_PARAMETERS[k],
        // The yaw inertia's over the starting profile's, the mass's with it.
        scale: if k == YAW_INERTIA {
            scale[MASS] * scale[YAW_INERTIA]
        } else {
            scale[k]
        },
        sigma: sigma[k],
        identified: k != THRUST && sigma[k] <= config.identifiable_sigma,
        held: k == THRUST,
        fallback: if k == YAW_INERTIA {
            Fallback::FollowsTheMass
        } else {
            Fallback::StartingProfile
        },
    });
    // What the trial did not pin down keeps its starting value (the yaw
    // inertia's own factor 1: it follows the mass).
    let kept: [f64; 5] = std::array::from_fn(|k| {
        if estimates[k].identified {
            scale[k]
        } else {
            1.0
        }
    });
    let params = scaled_params(start, kept);
    let given = |e: &ParameterEstimate| match e {
        e if e.held => MIN_IDENTIFIED_SIGMA,
        e if e.identified => e.sigma.max(MIN_IDENTIFIED_SIGMA),
        // Not identified: an uncalibrated profile's.
        _ => KineticConfig::UNIDENTIFIED_PROFILE_SIGMA,
    };
    // The twin's mass-and-inertia error stands for both: the larger.
    let profile_sigma = [
        given(&estimates[0]),
        given(&estimates[1]),
        given(&estimates[2]),
        given(&estimates[3]).max(given(&estimates[4])),
    ];
    Some(Identification {
        params,
        estimates,
        profile_sigma,
        rounds,
        before: held_out(prep, &config.diagnose, *start),
        after: held_out(prep, &config.diagnose, params),
        training_steps: split,
        heldout_steps: prep.steps.len().saturating_sub(split),
    })
}
