//! The adaptive extended Kalman filter (docs/model.md section 4; Zhang 2018,
//! Skriver-Helck-Hasan 2019): joint estimation of a vessel's state and of a
//! loss of effectiveness `theta` on its inputs.
//!
//! The filter is generic over state (`N`), measurement (`M`) and fault (`P`)
//! dimensions with static sizes, takes its model as a [`Model`], and holds no
//! hidden state: the estimate ([`AekfState`]) goes in by reference and is
//! replaced only when a step succeeds, so a failed step leaves it exactly as it
//! was. Every failure is an [`AekfError`], never a panic.
//!
//! # The recursion (one step, consuming `y(k+1)` and the input `u(k)`)
//! Steps 1-13 of docs/model.md section 4, with these deliberate differences, each
//! documented where it is coded:
//! - the covariance update uses the Joseph form;
//! - forgetting is configured as a time constant and `lambda = exp(-dt/tau)`
//!   is derived per step, so the filter's memory in seconds does not depend on
//!   the sample rate;
//! - process noise is a density (per second): `Q_k = Q_c dt`;
//! - anti-windup: forgetting is applied per fault component and only as fast
//!   as new information about that component arrives (see [`forgetting_factors`]);
//!   with no excitation `S` holds instead of growing like `lambda^-k`;
//! - measurement components may be missing (masked), exactly: a masked
//!   component has a zero row in `H` and a zero innovation;
//! - the measurement model may be nonlinear (`H` is its Jacobian at the
//!   predicted state), and angle innovations are wrapped;
//! - optionally ([`AekfConfig::gain_sensitivity`]), step 7 adds the Kalman
//!   gain's own dependence on the faults, `(dK/dtheta) ytilde`, carrying
//!   the state covariance's derivative `dP/dtheta` from step to step
//!   (Ljung 1979's modification of the extended Kalman filter as a
//!   parameter estimator): with [`GainSensitivity::Exact`] `Upsilon` is
//!   then the derivative of the state estimate with respect to the
//!   faults, where step 7 alone leaves the gain out of it.
//!
//! Computed, not changed: `Sigma` is factorised once per step as `L D L^T`
//! (no square roots) and every solve with it reuses the factor; steps 8-10
//! go through the push-through identity, a `P x P` inverse in place of
//! factorising the `M x M` `Lambda^-1` (see the step's comments); the Joseph
//! form is regrouped to reuse `H P-` (`joseph_update`); where the model
//! says its `H` keeps to a sparser pattern
//! ([`Model::observation_in_sparser_pattern`]), the update runs in a copy of
//! its code that skips those zeros. All give the recursion's numbers to
//! rounding (`twin-bench numpy` holds them to the NumPy reference, which
//! codes the steps as written).

use nalgebra::{SMatrix, SVector};

use crate::linalg::{
    Pattern, cholesky, inverse_small, ldl, mirror_lower, mul, mul_sparse_left, mul_t, mul_t_sparse,
    mul_tn, sym_mul_t_sparse,
};

use crate::geodesy::wrap_pi;
use crate::model::{Measurement, Model, Observation};

/// Optional adaptation of Q and R from the innovations (the seed authors'
/// code; Akhlaghi, Zhou and Huang 2017).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseAdaptation {
    /// Memory factor `a` per step, in (0, 1): 0.999 in the authors' code.
    pub factor: f64,
    /// Adapt the process noise: `Q <- a Q + (1-a) K ytilde ytilde^T K^T`.
    pub adapt_process_noise: bool,
    /// Adapt the measurement noise, in the given form.
    pub measurement_noise_form: Option<MeasurementNoiseForm>,
}

/// How R is adapted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MeasurementNoiseForm {
    /// Akhlaghi et al. 2017: `R <- a R + (1-a)(eps eps^T + H P+ H^T)` with the
    /// post-fit residual `eps = y - h(x+)`. Unbiased: `E[eps eps^T] = R - H P+ H^T`.
    PostFitResidual,
    /// The seed authors' code (docs/model.md section 4):
    /// `R <- a R + (1-a)(ytilde ytilde^T + H P- H^T)` with the prior innovation.
    /// Since `E[ytilde ytilde^T] = H P- H^T + R`, this converges to
    /// `R + 2 H P- H^T`: biased upward. Kept to reproduce the seed.
    AuthorsCode,
}

/// Tuning of the filter. All fields are in SI units and independent of the
/// sample interval.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AekfConfig<const N: usize, const M: usize, const P: usize> {
    /// Process noise density `Q_c` (per second): `Q_k = Q_c dt`.
    pub process_noise_density: SMatrix<f64, N, N>,
    /// Measurement noise covariance `R` (per measurement, not per second).
    pub measurement_noise: SMatrix<f64, M, M>,
    /// Time constant of the fault estimator's memory, seconds:
    /// `lambda = exp(-dt / tau)`. The seed's `lambda = 0.995` is `tau = 40 s` at
    /// `dt = 0.2 s` and `tau = 0.2 s` at `dt = 1 ms`.
    pub forgetting_time_constant_s: f64,
    /// Per fault component, a factor on that time constant: 1 forgets at the
    /// configured rate; a larger factor remembers longer (a parameter that
    /// changes slowly, such as a hull's drag, beside losses that can change
    /// at any time); infinity never forgets.
    pub fault_memory_factor: SVector<f64, P>,
    /// Initial fault covariance `S(0)` (the seed: `0.1 I`); zero freezes the
    /// faults at their initial values.
    pub initial_fault_covariance: SMatrix<f64, P, P>,
    /// Anti-windup: a fault component forgets at the full rate while the
    /// information it receives per step is at least this fraction of the
    /// steady-state rate for what it holds, and proportionally slower below
    /// (see [`forgetting_factors`]). 0 turns it off and reproduces the seed's
    /// recursion exactly, wind-up included; 0.1 is a good default.
    pub anti_windup_ratio: f64,
    /// A fault component counts as excited while the data of the last memory
    /// window alone would pin it down to this standard deviation or better.
    pub excitation_sigma: f64,
    /// Optional Q/R adaptation.
    pub noise_adaptation: Option<NoiseAdaptation>,
    /// How much of the Kalman gain's dependence on the faults their
    /// sensitivity `Upsilon` carries (the module's docs;
    /// [`GainSensitivity::Omitted`] is the seed's recursion).
    pub gain_sensitivity: GainSensitivity,
    /// The faults whose sensitivity carries the gain's part where
    /// [`Self::gain_sensitivity`] asks for it; the others' columns of
    /// `Upsilon` are step 7's as published, and cost nothing.
    pub gain_sensitivity_faults: [bool; P],
}

/// The Kalman gain's part in the faults' sensitivity `Upsilon` (step 7).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum GainSensitivity {
    /// Step 7 as published: `Upsilon = (I - K H)(F Upsilon + Psi)`, the
    /// gain read as if it did not depend on the faults.
    #[default]
    Omitted,
    /// The gain's dependence through the propagated covariance
    /// (`dP-/dtheta` from the transition Jacobian's change along the
    /// faults), not through the point where the measurement model is
    /// linearised: exact where `H` does not depend on the state. One
    /// transition per fault it is on
    /// ([`AekfConfig::gain_sensitivity_faults`]) per step, besides the
    /// products.
    ThroughCovariance,
    /// Both: `Upsilon` is the derivative of the state estimate with
    /// respect to the faults it is on. A transition and a measurement
    /// model per such fault per step, besides the products.
    Exact,
}

/// The estimate the filter carries from step to step. Plain data: clone it to
/// fork a filter, store it to persist a calibration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AekfState<const N: usize, const M: usize, const P: usize> {
    /// State estimate `xhat(k|k)`.
    pub x: SVector<f64, N>,
    /// State covariance `P(k|k)`.
    pub p: SMatrix<f64, N, N>,
    /// Sensitivity of the state estimate to the fault estimate, `Upsilon`.
    pub upsilon: SMatrix<f64, N, P>,
    /// Fault covariance `S` (the uncertainty of `theta`).
    pub s: SMatrix<f64, P, P>,
    /// Fault estimate `thetahat`.
    pub theta: SVector<f64, P>,
    /// Current process noise density (adapted if adaptation is on).
    pub process_noise_density: SMatrix<f64, N, N>,
    /// Current measurement noise (adapted if adaptation is on).
    pub measurement_noise: SMatrix<f64, M, M>,
    /// Information about each fault component gathered within the memory
    /// window and held while unexcited: drives the anti-windup.
    pub held_information: SVector<f64, P>,
    /// Information about the faults from the last memory window (always
    /// forgetting), as a matrix: drives the excitation flags, in any
    /// direction of the faults (one component, or a difference of two).
    pub recent_information: SMatrix<f64, P, P>,
    /// Steps taken.
    pub steps: u64,
    /// The derivative of `p` with respect to each fault, `dP/dtheta_i`,
    /// where [`AekfConfig::gain_sensitivity`] carries it; zeros otherwise.
    pub covariance_sensitivity: [SMatrix<f64, N, N>; P],
}

impl<const N: usize, const M: usize, const P: usize> AekfState<N, M, P> {
    /// A fresh estimate at `x0` with covariance `p0`, faults `theta0`, and the
    /// noise and fault covariances of `config`.
    pub fn new(
        config: &AekfConfig<N, M, P>,
        x0: SVector<f64, N>,
        p0: SMatrix<f64, N, N>,
        theta0: SVector<f64, P>,
    ) -> Self {
        Self {
            x: x0,
            p: p0,
            upsilon: SMatrix::zeros(),
            s: config.initial_fault_covariance,
            theta: theta0,
            process_noise_density: config.process_noise_density,
            measurement_noise: config.measurement_noise,
            held_information: SVector::zeros(),
            recent_information: SMatrix::zeros(),
            steps: 0,
            covariance_sensitivity: [SMatrix::zeros(); P],
        }
    }

    /// Standard deviation of each fault estimate, `sqrt(diag S)`.
    pub fn fault_sigma(&self) -> SVector<f64, P> {
        self.s.diagonal().map(|v| v.max(0.0).sqrt())
    }

    /// Whether each fault component is excited: the data of the last memory
    /// window alone pin it down to `excitation_sigma` or better (its own
    /// information, as if the other faults were known).
    pub fn excited(&self, excitation_sigma: f64) -> [bool; P] {
        let needed = 1.0 / (excitation_sigma * excitation_sigma);
        std::array::from_fn(|i| self.recent_information[(i, i)] >= needed)
    }

    /// The information of the last memory window about the combination
    /// `direction^T theta` with the other directions unknown:
    /// `1 / (d^T I^-1 d)`, with `I` the recent information regularised by
    /// `prior_information` (the information a prior gives each component,
    /// so that directions the data never saw do not make `I` singular).
    pub fn recent_information_along(
        &self,
        direction: &SVector<f64, P>,
        prior_information: &SVector<f64, P>,
    ) -> f64 {
        let regularised = self.recent_information + SMatrix::from_diagonal(prior_information);
        match crate::linalg::solve_general(&regularised, direction) {
            Some(v) => {
                let quad = direction.dot(&v);
                if quad > 0.0 { 1.0 / quad } else { 0.0 }
            }
            None => 0.0,
        }
    }

    /// True if every number is finite, the state covariance has a positive
    /// diagonal and the fault covariance a non-negative one (zero when the
    /// faults are frozen).
    pub fn is_sane(&self) -> bool {
        let all_finite = poison(&self.x)
            + poison(&self.p)
            + poison(&self.s)
            + poison(&self.theta)
            + poison(&self.upsilon)
            + poison(&self.held_information)
            + poison(&self.recent_information)
            + poison(&self.process_noise_density)
            + poison(&self.measurement_noise)
            + self.covariance_sensitivity.iter().map(poison).sum::<f64>()
            == 0.0;
        let mut diagonals_ok = true;
        for i in 0..N {
            diagonals_ok &= self.p[(i, i)] > 0.0;
        }
        for i in 0..P {
            diagonals_ok &= self.s[(i, i)] >= 0.0;
        }
        all_finite & diagonals_ok
    }
}

/// 0 if every entry of `m` is finite, NaN otherwise: `v * 0` is 0 for a
/// finite `v` and NaN for NaN and the infinities. Sums in two independent
/// lanes without branches, so that the check (on the filter's every step)
/// is a handful of vector instructions rather than a loop of tests.
#[inline(always)]
fn poison<const R: usize, const C: usize>(m: &SMatrix<f64, R, C>) -> f64 {
    let values = m.as_slice();
    let mut lanes = [0.0f64; 2];
    let mut pairs = values.chunks_exact(2);
    for pair in pairs.by_ref() {
        lanes[0] += pair[0] * 0.0;
        lanes[1] += pair[1] * 0.0;
    }
    for v in pairs.remainder() {
        lanes[0] += v * 0.0;
    }
    lanes[0] + lanes[1]
}

/// What one step saw, for consistency checks and residual analysis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepReport<const M: usize, const P: usize> {
    /// Innovation `ytilde = y - h(xbar)` (angles wrapped, missing components 0).
    pub innovation: SVector<f64, M>,
    /// Innovation covariance of the state part, `Sigma = H P- H^T + R`.
    pub innovation_covariance: SMatrix<f64, M, M>,
    /// Normalised innovation squared `ytilde^T Sigma^-1 ytilde` over the
    /// available components.
    pub nis: f64,
    /// Number of available measurement components (degrees of freedom of `nis`).
    pub dof: usize,
    /// Per-component forgetting factor applied this step (1 = no forgetting).
    pub forgetting: SVector<f64, P>,
}

/// Why a step was refused. The estimate is unchanged after any of these.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum AekfError {
    /// The time step is not a positive finite number of seconds.
    #[error("time step {dt_s} s is not positive and finite")]
    InvalidTimeStep {
        /// The rejected step, seconds.
        dt_s: f64,
    },
    /// A measurement or input value is NaN or infinite.
    #[error("non-finite value in the {what}")]
    NonFinite {
        /// Which quantity held the non-finite value.
        what: &'static str,
    },
    /// A matrix that must be symmetric positive definite is not.
    #[error("{which} is not positive definite")]
    NotPositiveDefinite {
        /// Which matrix failed its Cholesky factorisation.
        which: &'static str,
    },
    /// The step produced a non-finite or non-positive covariance.
    #[error("the step produced an unusable estimate ({what})")]
    Diverged {
        /// What went wrong.
        what: &'static str,
    },
    /// The configuration is unusable.
    #[error("invalid configuration: {0}")]
    InvalidConfig(&'static str),
}

/// The filter's prediction (steps 1 and 2), handed to its update.
struct Prediction<const N: usize, const P: usize> {
    /// The forgetting factor of the step.
    lambda: f64,
    /// `F`, the transition Jacobian.
    f: SMatrix<f64, N, N>,
    /// `Psi`, the fault sensitivity.
    psi: SMatrix<f64, N, P>,
    /// The predicted state.
    x_bar: SVector<f64, N>,
    /// The process noise of the step, `Q_c dt`.
    q_step: SMatrix<f64, N, N>,
    /// The predicted covariance `P-`.
    p_prior: SMatrix<f64, N, N>,
    /// `dP-/dtheta_i`, where [`AekfConfig::gain_sensitivity`] asks for it.
    p_prior_sensitivity: Option<[SMatrix<f64, N, N>; P]>,
}

/// The step of the finite differences along each fault in
/// [`AekfConfig::gain_sensitivity`]'s terms: the fault moved by it, the
/// state by its sensitivity times it.
const SENSITIVITY_STEP: f64 = 1e-6;

/// What the gain's part of step 7 reads from the update.
struct GainTerms<'a, const N: usize, const M: usize, const P: usize> {
    /// The predicted state `x-`.
    x_bar: &'a SVector<f64, N>,
    /// `H` at the predicted state, as the model gives it.
    observed_jacobian: &'a SMatrix<f64, M, N>,
    /// `H` with the missing components' rows zero.
    h: &'a SMatrix<f64, M, N>,
    /// The Kalman gain.
    k: &'a SMatrix<f64, N, M>,
    /// `P-`.
    p_prior: &'a SMatrix<f64, N, N>,
    /// `H P-`.
    h_p: &'a SMatrix<f64, M, N>,
    /// The structural zeros of `H` (and of its change along the faults).
    h_pattern: &'a Pattern<M, N>,
    /// `F Upsilon + Psi`: the predicted state's sensitivity to the faults.
    f_ups_psi: &'a SMatrix<f64, N, P>,
    /// The innovation.
    innovation: &'a SVector<f64, M>,
    /// Which measurement components are available.
    available: &'a [bool; M],
}

/// The filter: a model and its tuning. Stateless; see [`AekfState`].
#[derive(Debug, Clone)]
pub struct Aekf<Mdl, const N: usize, const M: usize, const P: usize> {
    /// The vessel model.
    pub model: Mdl,
    /// The tuning.
    pub config: AekfConfig<N, M, P>,
}

impl<Mdl, const N: usize, const M: usize, const P: usize> Aekf<Mdl, N, M, P>
where
    Mdl: Model<N, M, P>,
{
    /// A filter for `model` with `config`, checked: the time constant must be
    /// positive, the noise and initial fault covariances positive definite.
    pub fn new(model: Mdl, config: AekfConfig<N, M, P>) -> Result<Self, AekfError> {
        if config.forgetting_time_constant_s.is_nan() || config.forgetting_time_constant_s <= 0.0 {
            return Err(AekfError::InvalidConfig(
                "forgetting_time_constant_s must be positive",
            ));
        }
        if config
            .fault_memory_factor
            .iter()
            .any(|f| f.is_nan() || *f <= 0.0)
        {
            return Err(AekfError::InvalidConfig(
                "fault_memory_factor must be positive",
            ));
        }
        if !(config.anti_windup_ratio >= 0.0 && config.anti_windup_ratio <= 1.0) {
            return Err(AekfError::InvalidConfig(
                "anti_windup_ratio must be in [0, 1]",
            ));
        }
        if config.excitation_sigma.is_nan() || config.excitation_sigma <= 0.0 {
            return Err(AekfError::InvalidConfig(
                "excitation_sigma must be positive",
            ));
        }
        if let Some(a) = config.noise_adaptation
            && !(a.factor > 0.0 && a.factor < 1.0)
        {
            return Err(AekfError::InvalidConfig(
                "noise adaptation factor must be in (0, 1)",
            ));
        }
        if cholesky(&config.measurement_noise).is_none() {
            return Err(AekfError::NotPositiveDefinite {
                which: "measurement noise R",
            });
        }
        // A fault whose row and column of S(0) are zero is held at its
        // initial value (S(0) = 0: a model that estimates no faults, the
        // nominal model of `diagnose`); the others' block must be positive
        // definite.
        if !held_block_positive_definite(&config.initial_fault_covariance) {
            return Err(AekfError::NotPositiveDefinite {
                which: "initial fault covariance S(0)",
            });
        }
        // Written so that NaN and the infinities fail too.
        let q = &config.process_noise_density;
        let q_finite = q.iter().all(|v| v.is_finite());
        if !q_finite || q.diagonal().iter().any(|v| *v < 0.0) || (q - q.transpose()).amax() > 1e-12
        {
            return Err(AekfError::InvalidConfig(
                "process noise density must be finite and symmetric with a non-negative diagonal",
            ));
        }
        Ok(Self { model, config })
    }

    /// The per-step forgetting factor for a step of `dt_s` seconds.
    pub fn lambda(&self, dt_s: f64) -> f64 {
        (-dt_s / self.config.forgetting_time_constant_s).exp()
    }

    /// One step: consume the measurement `y` taken `dt_s` after the current
    /// estimate, with `input` the input that drove the vessel over that
    /// interval. On success the estimate is replaced; on error it is untouched.
    ///
    /// On an x86-64 processor with AVX2 and FMA (most made since 2013-2015;
    /// not some low-end Pentium, Celeron and Atom parts) the step runs in a
    /// copy of its code compiled for 256-bit vectors, chosen at run time;
    /// elsewhere in the baseline build. Both copies compute the same
    /// numbers bit for bit: Rust neither reorders nor fuses floating-point
    /// operations, whatever the vector width (see [`crate::simd`]).
    pub fn step(
        &self,
        state: &mut AekfState<N, M, P>,
        input: &Mdl::Input,
        y: &Measurement<M>,
        dt_s: f64,
    ) -> Result<StepReport<M, P>, AekfError> {
        #[cfg(target_arch = "x86_64")]
        if crate::simd::avx2_available() {
            // SAFETY: `step_avx2` requires AVX2 and FMA, and the processor
            // running this code has both (checked on the line above).
            #[allow(unsafe_code)]
            return unsafe { self.step_avx2(state, input, y, dt_s) };
        }
        self.step_baseline(state, input, y, dt_s)
    }

    /// [`Self::step`] compiled for AVX2 (the same source, inlined here).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn step_avx2(
        &self,
        state: &mut AekfState<N, M, P>,
        input: &Mdl::Input,
        y: &Measurement<M>,
        dt_s: f64,
    ) -> Result<StepReport<M, P>, AekfError> {
        self.step_baseline(state, input, y, dt_s)
    }

    /// [`Self::step`] in the baseline code, whatever the processor: the same
    /// numbers, for benchmarks that time the AVX2 copy against it side by
    /// side (`twin-bench core`) and for tests. Use [`Self::step`] otherwise.
    #[inline(always)]
    pub fn step_baseline(
        &self,
        state: &mut AekfState<N, M, P>,
        input: &Mdl::Input,
        y: &Measurement<M>,
        dt_s: f64,
    ) -> Result<StepReport<M, P>, AekfError> {
        if !(dt_s > 0.0 && dt_s.is_finite()) {
            return Err(AekfError::InvalidTimeStep { dt_s });
        }
        if (0..M).any(|i| y.available[i] && !y.values[i].is_finite()) {
            return Err(AekfError::NonFinite {
                what: "measurement",
            });
        }
        let lambda = self.lambda(dt_s);

        // Steps 1 and 11 (first half): predicted state, F and Psi at xhat(k|k).
        let tr = self.model.transition(&state.x, input, &state.theta, dt_s);
        if tr.next.iter().any(|v| !v.is_finite()) {
            return Err(AekfError::NonFinite {
                what: "predicted state (check the input)",
            });
        }
        let f = tr.jacobian;
        debug_assert!(
            crate::linalg::within_pattern(&f, &Mdl::TRANSITION_PATTERN),
            "the model's transition Jacobian has entries outside its TRANSITION_PATTERN"
        );
        let psi = tr.fault_sensitivity;
        let x_bar = tr.next;

        // Step 2.
        let q_step = state.process_noise_density * dt_s;
        let f_pattern = &Mdl::TRANSITION_PATTERN;
        let p_prior =
            sym_mul_t_sparse(&mul_sparse_left(&f, f_pattern, &state.p), &f, f_pattern) + q_step;

        // The measurement model at the predicted state, and the update. Where
        // this instance of the model keeps its `H` to the sparser pattern,
        // the update runs in a copy of its code with that pattern folded in,
        // so that its products by `H` skip those zeros too.
        let obs = self.model.observe(&x_bar);
        let p_prior_sensitivity = (self.config.gain_sensitivity != GainSensitivity::Omitted)
            .then(|| self.prior_covariance_sensitivity(state, input, &f, dt_s));
        let prediction = Prediction {
            lambda,
            f,
            psi,
            x_bar,
            q_step,
            p_prior,
            p_prior_sensitivity,
        };
        if self.model.observation_in_sparser_pattern() {
            self.update(
                state,
                y,
                dt_s,
                &prediction,
                &obs,
                &Mdl::SPARSER_OBSERVATION_PATTERN,
            )
        } else {
            self.update(state, y, dt_s, &prediction, &obs, &Mdl::OBSERVATION_PATTERN)
        }
    }

    /// `dP-/dtheta_i = dF P F^T + F P dF^T + F (dP/dtheta_i) F^T` for each
    /// fault, with `dF` the change of the transition Jacobian along the
    /// fault and the state estimate's sensitivity to it (`x + e Upsilon_i`,
    /// `theta + e e_i`), by a finite difference of the model.
    fn prior_covariance_sensitivity(
        &self,
        state: &AekfState<N, M, P>,
        input: &Mdl::Input,
        f: &SMatrix<f64, N, N>,
        dt_s: f64,
    ) -> [SMatrix<f64, N, N>; P] {
        let f_pattern = &Mdl::TRANSITION_PATTERN;
        let p_ft = mul_t_sparse(&state.p, f, f_pattern);
        std::array::from_fn(|i| {
            if !self.config.gain_sensitivity_faults[i] {
                return SMatrix::zeros();
            }
            let mut theta = state.theta;
            theta[i] += SENSITIVITY_STEP;
            let x = state.x + state.upsilon.column(i) * SENSITIVITY_STEP;
            let moved = self.model.transition(&x, input, &theta, dt_s).jacobian;
            // Both Jacobians keep to the pattern, and so does their difference.
            let df = (moved - f) / SENSITIVITY_STEP;
            let spread = mul_sparse_left(&df, f_pattern, &p_ft);
            let f_dp = mul_sparse_left(f, f_pattern, &state.covariance_sensitivity[i]);
            // Exactly symmetric: a sum of a matrix and its transpose, and a
            // mirrored product.
            spread + spread.transpose() + sym_mul_t_sparse(&f_dp, f, f_pattern)
        })
    }

    /// The gain's part of step 7 (Ljung 1979), for each fault: with
    /// `dH` the measurement Jacobian's change along the predicted state's
    /// sensitivity `F Upsilon + Psi` (a finite difference of the model, the
    /// missing components' rows zero; zero for
    /// [`GainSensitivity::ThroughCovariance`]),
    /// `dK = [(I - K H) dP- H^T + (I - K H) P- dH^T - K dH P- H^T] Sigma^-1`
    /// is added to `Upsilon` times the innovation, and
    /// `dP = dP- - dK H P- - K dH P- - K H dP-` is returned for the next
    /// step.
    fn gain_sensitivity_step(
        &self,
        gain: &GainTerms<'_, N, M, P>,
        sigma_chol: &crate::linalg::Ldl<M>,
        dp_prior: &[SMatrix<f64, N, N>; P],
        upsilon: &mut SMatrix<f64, N, P>,
    ) -> [SMatrix<f64, N, N>; P] {
        let h_pattern = gain.h_pattern;
        let exact = self.config.gain_sensitivity == GainSensitivity::Exact;
        // (I - K H) P-, for the exact form's dH term.
        let i_kh_p = exact.then(|| gain.p_prior - mul(gain.k, gain.h_p));
        std::array::from_fn(|i| {
            if !self.config.gain_sensitivity_faults[i] {
                return SMatrix::zeros();
            }
            // (I - K H) dP-, the part both forms share.
            let i_kh_dp =
                dp_prior[i] - mul(gain.k, &mul_sparse_left(gain.h, h_pattern, &dp_prior[i]));
            let mut before_sigma = mul_t_sparse(&i_kh_dp, gain.h, h_pattern);
            let mut k_dh_p = SMatrix::<f64, N, N>::zeros();
            if let Some(i_kh_p) = &i_kh_p {
                let moved = gain.x_bar + gain.f_ups_psi.column(i) * SENSITIVITY_STEP;
                let mut dh = (self.model.observe(&moved).jacobian - gain.observed_jacobian)
                    / SENSITIVITY_STEP;
                for (m, available) in gain.available.iter().enumerate() {
                    if !available {
                        dh.set_row(m, &SMatrix::<f64, 1, N>::zeros());
                    }
                }
                k_dh_p = mul(gain.k, &mul_sparse_left(&dh, h_pattern, gain.p_prior));
                before_sigma +=
                    mul_t_sparse(i_kh_p, &dh, h_pattern) - mul_t_sparse(&k_dh_p, gain.h, h_pattern);
            }
            // dK = before_sigma Sigma^-1, Sigma symmetric: (Sigma^-1 before_sigma^T)^T.
            let dk = sigma_chol.solve(&before_sigma.transpose()).transpose();
            upsilon.set_column(i, &(upsilon.column(i) + dk * gain.innovation));
            let dp = i_kh_dp - mul(&dk, gain.h_p) - k_dh_p;
            (dp + dp.transpose()) * 0.5
        })
    }

    /// Steps 3-13 of [`Self::step_baseline`], from its prediction and the
    /// measurement model at the predicted state, whose Jacobian keeps to
    /// `h_pattern`. On success the estimate is replaced; on error it is
    /// untouched.
    #[inline(always)]
    #[allow(clippy::too_many_lines)] // Steps 3-13 in order, as docs/model.md section 4 numbers them.
    fn update(
        &self,
        state: &mut AekfState<N, M, P>,
        y: &Measurement<M>,
        dt_s: f64,
        prediction: &Prediction<N, P>,
        obs: &Observation<N, M>,
        h_pattern: &Pattern<M, N>,
    ) -> Result<StepReport<M, P>, AekfError> {
        let Prediction {
            lambda,
            ref f,
            ref psi,
            x_bar,
            q_step,
            p_prior,
            ref p_prior_sensitivity,
        } = *prediction;
        let f_pattern = &Mdl::TRANSITION_PATTERN;
        // The measurement model at the predicted state, with missing
        // components masked.
        let mut h = obs.jacobian;
        debug_assert!(
            crate::linalg::within_pattern(&h, h_pattern),
            "the model's observation Jacobian has entries outside its pattern"
        );
        let mut r = state.measurement_noise;
        let angles = self.model.measurement_angles();
        let mut innovation = SVector::<f64, M>::zeros();
        for i in 0..M {
            if y.available[i] {
                let d = y.values[i] - obs.predicted[i];
                innovation[i] = if angles[i] { wrap_pi(d) } else { d };
            } else {
                h.set_row(i, &nalgebra::SMatrix::<f64, 1, N>::zeros());
                let keep = r[(i, i)];
                r.set_row(i, &nalgebra::SMatrix::<f64, 1, M>::zeros());
                r.set_column(i, &SVector::<f64, M>::zeros());
                r[(i, i)] = if keep > 0.0 { keep } else { 1.0 };
            }
        }

        // Steps 3-5 (Joseph form). Sigma is factorised once; every solve
        // with it below reuses the factor.
        let h_p = mul_sparse_left(&h, h_pattern, &p_prior);
        let sigma = sym_mul_t_sparse(&h_p, &h, h_pattern) + r;
        let sigma_chol = ldl(&sigma).ok_or(AekfError::NotPositiveDefinite {
            which: "innovation covariance Sigma",
        })?;
        // The report is built here, where its parts are ready, so that it
        // can be written where the caller receives it rather than copied
        // there at the end.
        let mut report = StepReport {
            innovation,
            innovation_covariance: sigma,
            nis: 0.0,
            dof: y.dof(),
            forgetting: SVector::repeat(1.0),
        };
        let k = sigma_chol.solve(&h_p).transpose();
        // K R K^T: R is diagonal unless adaptation filled it in.
        let k_r = if is_diagonal(&r) {
            SMatrix::<f64, N, M>::from_fn(|i, j| k[(i, j)] * r[(j, j)])
        } else {
            mul(&k, &r)
        };
        let p_post = joseph_update(&p_prior, &h, h_pattern, &h_p, &k, &k_r);

        // Steps 6-7, sharing F Upsilon_old + Psi; with Omega = H (F
        // Upsilon_old + Psi) at hand, (I - K H)(F Upsilon_old + Psi) is
        // that minus K Omega.
        let f_ups_psi = mul_sparse_left(f, f_pattern, &state.upsilon) + psi;
        let omega = mul_sparse_left(&h, h_pattern, &f_ups_psi);
        let mut upsilon = f_ups_psi - mul(&k, &omega);
        // Where the gain's part is off, the (zero) derivatives are neither
        // copied nor checked nor written back.
        let covariance_sensitivity = p_prior_sensitivity.as_ref().map(|dp_prior| {
            let gain = GainTerms {
                x_bar: &x_bar,
                observed_jacobian: &obs.jacobian,
                h: &h,
                k: &k,
                p_prior: &p_prior,
                h_p: &h_p,
                h_pattern,
                f_ups_psi: &f_ups_psi,
                innovation: &innovation,
                available: &y.available,
            };
            self.gain_sensitivity_step(&gain, &sigma_chol, dp_prior, &mut upsilon)
        });

        // Forgetting, per fault component (anti-windup), then steps 8-10 in the
        // equivalent form with the forgotten S_f = D^-1/2 S D^-1/2.
        let sigma_inv_omega = sigma_chol.solve(&omega);
        let info_gain = mul_tn(&omega, &sigma_inv_omega);
        let lambdas = SVector::<f64, P>::from_fn(|i, _| {
            let factor = self.config.fault_memory_factor[i];
            if factor == 1.0 {
                lambda
            } else {
                (-dt_s / (self.config.forgetting_time_constant_s * factor)).exp()
            }
        });
        let forgetting = forgetting_factors(
            &lambdas,
            &info_gain.diagonal(),
            &state.held_information,
            self.config.anti_windup_ratio,
        );
        // S_f[i][j] = S[i][j] / sqrt(f_i f_j): a division on the diagonal,
        // one square root per pair off it.
        let mut s_forgot = state.s;
        for i in 0..P {
            for j in 0..P {
                s_forgot[(i, j)] /= if i == j {
                    forgetting[i]
                } else {
                    (forgetting[i] * forgetting[j]).sqrt()
                };
            }
        }
        // Steps 8-10 through the push-through identity, with the information
        // G = Omega^T Sigma^-1 Omega already at hand:
        //   Gamma = S_f Omega^T (Sigma + Omega S_f Omega^T)^-1
        //         = S_f (I + G S_f)^-1 (Sigma^-1 Omega)^T,
        //   S     = S_f - Gamma Omega S_f = S_f (I + G S_f)^-1,
        // a P x P solve instead of factorising the M x M Lambda^-1. I + G S_f
        // is invertible for any positive semi-definite S_f (the eigenvalues
        // of G S_f are non-negative), so it fails only on a broken S.
        let gain_matrix = SMatrix::<f64, P, P>::identity() + mul(&info_gain, &s_forgot);
        let gain_inv = inverse_small(&gain_matrix).ok_or(AekfError::NotPositiveDefinite {
            which: "fault gain matrix I + G S",
        })?;
        let s_post_full = mul(&s_forgot, &gain_inv);
        let gamma = mul_t(&s_post_full, &sigma_inv_omega);
        let s_post = (s_post_full + s_post_full.transpose()) * 0.5;

        // Steps 11-13.
        let d_theta = mul(&gamma, &innovation);
        let theta = state.theta + d_theta;
        let mut x_post = x_bar + mul(&k, &innovation) + mul(&upsilon, &d_theta);
        for (i, is_angle) in self.model.state_angles().iter().enumerate() {
            if *is_angle {
                x_post[i] = wrap_pi(x_post[i]);
            }
        }

        let nis = sigma_chol.quadratic_form(&innovation);
        if !nis.is_finite() {
            return Err(AekfError::Diverged {
                what: "innovation too large to represent",
            });
        }
        let held_information =
            forgetting.component_mul(&state.held_information) + info_gain.diagonal();
        let recent_information = state.recent_information * lambda + info_gain;

        // Optional noise adaptation, for use from the next step.
        // (None: unchanged, and then neither copied nor written back.)
        let mut q_density: Option<SMatrix<f64, N, N>> = None;
        let mut r_next: Option<SMatrix<f64, M, M>> = None;
        if let Some(adapt) = self.config.noise_adaptation {
            let a = adapt.factor;
            if adapt.adapt_process_noise {
                let ki = k * innovation;
                let q_new = q_step * a + (ki * ki.transpose()) * (1.0 - a);
                q_density = Some((q_new + q_new.transpose()) * (0.5 / dt_s));
            }
            if let Some(form) = adapt.measurement_noise_form {
                let (resid, spread) = match form {
                    MeasurementNoiseForm::PostFitResidual => {
                        let post = self.model.observe(&x_post).predicted;
                        let mut eps = SVector::<f64, M>::zeros();
                        for i in 0..M {
                            if y.available[i] {
                                let d = y.values[i] - post[i];
                                eps[i] = if angles[i] { wrap_pi(d) } else { d };
                            }
                        }
                        (eps, h * p_post * h.transpose())
                    }
                    MeasurementNoiseForm::AuthorsCode => (innovation, h * p_prior * h.transpose()),
                };
                let sample = resid * resid.transpose() + spread;
                let mut r_new = state.measurement_noise;
                // Only the available block learns; missing rows keep their value.
                for i in 0..M {
                    for j in 0..M {
                        if y.available[i] && y.available[j] {
                            r_new[(i, j)] = a * r_new[(i, j)] + (1.0 - a) * sample[(i, j)];
                        }
                    }
                }
                r_new = (r_new + r_new.transpose()) * 0.5;
                if cholesky(&r_new).is_none() {
                    r_new = state.measurement_noise;
                }
                r_next = Some(r_new);
            }
        }

        // The checks of `AekfState::is_sane` on the new values, before any is
        // stored; then the fields are written in place (no second copy of
        // the whole estimate). The noise covariances are checked only when
        // adaptation changed them: unchanged, they are the values checked
        // when they were set (or the configuration's, checked by `new`).
        let mut diagonals_ok = true;
        for i in 0..N {
            diagonals_ok &= p_post[(i, i)] > 0.0;
        }
        for i in 0..P {
            diagonals_ok &= s_post[(i, i)] >= 0.0;
        }
        let all_finite = poison(&x_post)
            + poison(&p_post)
            + poison(&s_post)
            + poison(&theta)
            + poison(&upsilon)
            + covariance_sensitivity
                .as_ref()
                .map_or(0.0, |d| d.iter().map(poison).sum::<f64>())
            + poison(&held_information)
            + poison(&recent_information)
            + q_density.as_ref().map_or(0.0, poison)
            + r_next.as_ref().map_or(0.0, poison)
            == 0.0;
        if !(all_finite && diagonals_ok) {
            return Err(AekfError::Diverged {
                what: "non-finite value or non-positive variance",
            });
        }
        state.x = x_post;
        state.p = p_post;
        state.upsilon = upsilon;
        if let Some(d) = covariance_sensitivity {
            state.covariance_sensitivity = d;
        }
        state.s = s_post;
        state.theta = theta;
        if let Some(q) = q_density {
            state.process_noise_density = q;
        }
        if let Some(r) = r_next {
            state.measurement_noise = r;
        }
        state.held_information = held_information;
        state.recent_information = recent_information;
        state.steps += 1;
        report.nis = nis;
        report.forgetting = forgetting;
        Ok(report)
    }
}

/// The Joseph form of the covariance update (docs/model.md section 4, step 5),
/// `P+ = (I - K H) P- (I - K H)^T + K R K^T`, for any gain `K`, given
/// `H P-` (`h_p`) and `K R` (`k_r`), where `H` keeps to `h_pattern`.
///
/// Computed as `B - (B H^T - K R) K^T` with `B = (I - K H) P- = P- - K (H P-)`:
/// the same polynomial in `K`, so it keeps the Joseph form's property that an
/// error in the gain changes `P+` only to second order, in about half the
/// multiplications of the literal form (`H P-` is already at hand from the
/// gain). With the optimal gain the bracket is zero in exact arithmetic and
/// holds what rounding left of the gain's error. The lower triangle is
/// mirrored, so the result is exactly symmetric.
#[inline(always)]
fn joseph_update<const N: usize, const M: usize>(
    p_prior: &SMatrix<f64, N, N>,
    h: &SMatrix<f64, M, N>,
    h_pattern: &Pattern<M, N>,
    h_p: &SMatrix<f64, M, N>,
    k: &SMatrix<f64, N, M>,
    k_r: &SMatrix<f64, N, M>,
) -> SMatrix<f64, N, N> {
    let b = p_prior - mul(k, h_p);
    let bracket = mul_t_sparse(&b, h, h_pattern) - k_r;
    let mut p_post = b - mul_t(&bracket, k);
    mirror_lower(&mut p_post);
    p_post
}

/// Whether `s` is positive definite on the components with a non-zero
/// diagonal and exactly zero in the rows and columns of the others.
fn held_block_positive_definite<const P: usize>(s: &SMatrix<f64, P, P>) -> bool {
    let free: [bool; P] = std::array::from_fn(|i| s[(i, i)] != 0.0);
    for i in 0..P {
        for j in 0..P {
            if (!free[i] || !free[j]) && s[(i, j)] != 0.0 {
                return false;
            }
        }
    }
    // The free block, with the held components replaced by ones on the
    // diagonal (which leaves its definiteness as it is).
    let block = SMatrix::<f64, P, P>::from_fn(|i, j| match (free[i], free[j]) {
        (true, true) => s[(i, j)],
        _ if i == j => 1.0,
        _ => 0.0,
    });
    cholesky(&block).is_some()
}

fn is_diagonal<const M: usize>(r: &SMatrix<f64, M, M>) -> bool {
    (0..M).all(|i| (0..M).all(|j| i == j || r[(i, j)] == 0.0))
}

/// Per-component forgetting factors with anti-windup.
///
/// The seed forgets every component by `lambda` each step. Where a component
/// receives no information (zero input) that makes its `S` grow like
/// `lambda^-k` (wind-up), and the next excitation then throws the estimate
/// about. Here a component forgets in proportion to the information it
/// receives, relative to what it holds: with the ratio
/// `e = gain / ((1 - lambda) held)` (1 under steady excitation) and the
/// configured `ratio_min`, `lambda_i = 1 - (1 - lambda) min(1, e / ratio_min)`.
/// At or above `ratio_min` this is the seed's `lambda`; with no information
/// `lambda_i = 1` and `S` holds; in between, the held information decays only
/// slowly (linearly, by `gain (1/ratio_min - 1)` per step), so weak excitation
/// cannot wind `S` up quickly. `ratio_min = 0` disables it.
pub fn forgetting_factors<const P: usize>(
    lambdas: &SVector<f64, P>,
    info_gain: &SVector<f64, P>,
    held_information: &SVector<f64, P>,
    ratio_min: f64,
) -> SVector<f64, P> {
    SVector::from_fn(|i, _| {
        let lambda = lambdas[i];
        if ratio_min <= 0.0 {
            return lambda;
        }
        let gain = info_gain[i].max(0.0);
        let held = held_information[i];
        // e / ratio_min, with one division.
        let excitation = if held > 0.0 {
            gain / ((1.0 - lambda) * held * ratio_min)
        } else if gain > 0.0 {
            1.0
        } else {
            0.0
        };
        1.0 - (1.0 - lambda) * excitation.min(1.0)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::kinematic::{KinematicInput, KinematicModel};
    use crate::models::otter_twin::{FAULTS, MEASUREMENTS, OtterTwin, STATES, ShaftSpeeds, meas};
    use crate::twin::TwinConfig;
    use nalgebra::{Vector2, Vector4};

    /// The regrouped Joseph form is the literal one for any gain, not only
    /// the optimal gain (where the two forms of the update agree anyway):
    /// the gain here is the optimal one plus a large error.
    #[test]
    fn the_joseph_update_is_the_literal_form_for_any_gain() {
        let g = SMatrix::<f64, 6, 6>::from_fn(|i, j| ((i * 7 + j * 3) % 5) as f64 * 0.3 - 0.4);
        let p_prior = g * g.transpose() + SMatrix::<f64, 6, 6>::identity() * 0.5;
        let mut pattern = [[true; 6]; 3];
        pattern[0][4] = false;
        pattern[2][1] = false;
        let h = SMatrix::<f64, 3, 6>::from_fn(|i, j| {
            if pattern[i][j] {
                ((i * 5 + j * 2) % 7) as f64 * 0.25 - 0.6
            } else {
                0.0
            }
        });
        let r = SMatrix::<f64, 3, 3>::from_diagonal(&nalgebra::Vector3::new(0.2, 0.05, 0.4));
        let optimal =
            p_prior * h.transpose() * (h * p_prior * h.transpose() + r).try_inverse().unwrap();
        let k =
            optimal + SMatrix::<f64, 6, 3>::from_fn(|i, j| ((i + 2 * j) % 3) as f64 * 0.2 - 0.15);
        let ikh = SMatrix::<f64, 6, 6>::identity() - k * h;
        let literal = ikh * p_prior * ikh.transpose() + k * r * k.transpose();
        let regrouped = joseph_update(&p_prior, &h, &pattern, &(h * p_prior), &k, &(k * r));
        assert!(
            (regrouped - literal).amax() < 1e-12 * literal.amax(),
            "{regrouped} vs {literal}"
        );
        assert_eq!(regrouped, regrouped.transpose());
        // The gain error shows: this is not the short form P- - K H P-.
        let short = p_prior - k * h * p_prior;
        assert!((short - literal).amax() > 0.01 * literal.amax());
    }

    /// Runs `steps` through [`Aekf::step`] (the AVX2 copy where the processor
    /// has AVX2) and through the baseline code, and requires every estimate
    /// and report to agree bit for bit. Returns how many steps succeeded.
    fn same_bits_both_ways<Mdl: Model<N, M, P>, const N: usize, const M: usize, const P: usize>(
        filter: &Aekf<Mdl, N, M, P>,
        start: AekfState<N, M, P>,
        steps: &[(Mdl::Input, Measurement<M>)],
        dt_s: f64,
    ) -> usize {
        let mut dispatched = start;
        let mut baseline = start;
        let mut succeeded = 0;
        for (k, (u, y)) in steps.iter().enumerate() {
            let a = filter.step(&mut dispatched, u, y, dt_s);
            let b = filter.step_baseline(&mut baseline, u, y, dt_s);
            // Debug formatting prints every f64 exactly (shortest round trip),
            // and tells NaN, -0.0 and 0.0 apart, unlike `==`.
            assert_eq!(format!("{a:?}"), format!("{b:?}"), "report at step {k}");
            assert_eq!(
                format!("{dispatched:?}"),
                format!("{baseline:?}"),
                "estimate at step {k}"
            );
            succeeded += usize::from(a.is_ok());
        }
        succeeded
    }

    /// The step's AVX2 copy and its baseline copy give the same bits, for the
    /// seed's model and the extended twin (whose transition is inlined into
    /// both). On a processor without AVX2 both calls run the baseline, and
    /// the test says so rather than passing silently.
    #[test]
    fn both_copies_of_the_step_give_the_same_bits() {
        if !crate::simd::avx2_available() {
            eprintln!("no AVX2 here: both calls run the baseline code");
        }
        let seed = TwinConfig::default().seed.filter;
        let filter = Aekf::new(KinematicModel, seed).unwrap();
        let start = AekfState::new(
            &seed,
            Vector4::new(0.0, 0.0, 1.5, 0.0),
            SMatrix::identity(),
            Vector2::zeros(),
        );
        let dt = 0.2;
        let mut x = Vector4::new(0.0, 0.0, 1.5, 0.0);
        let seed_steps: Vec<_> = (0..400)
            .map(|k| {
                let t = k as f64 * dt;
                let u = KinematicInput {
                    accel_mps2: 0.05 * (0.3 * t).sin(),
                    course_rate_radps: 0.3 * (0.1 * t).sin(),
                };
                x = Vector4::new(
                    x[0] + dt * x[2] * x[3].cos(),
                    x[1] + dt * x[2] * x[3].sin(),
                    x[2] + dt * 0.9 * u.accel_mps2,
                    wrap_pi(x[3] + dt * 0.7 * u.course_rate_radps),
                );
                let mut y = Measurement::full(x + Vector4::repeat(0.01 * (1.7 * t).sin()));
                // Some fixes without course, as when the vessel stops.
                y.available[3] = k % 7 != 3;
                (u, y)
            })
            .collect();
        assert_eq!(same_bits_both_ways(&filter, start, &seed_steps, dt), 400);

        let (filter, start, kinetic_steps) = otter_trial();
        assert_eq!(
            same_bits_both_ways(&filter, start, &kinetic_steps, 0.2),
            300
        );
    }
    /// The extended twin's filter, a start and 300 steps of 0.2 s: full
    /// ahead, then a hard turn to port and one to starboard, with the port
    /// propeller at 70 % and the heading in one fix of three.
    #[allow(clippy::type_complexity)]
    fn otter_trial() -> (
        Aekf<OtterTwin, STATES, MEASUREMENTS, FAULTS>,
        AekfState<STATES, MEASUREMENTS, FAULTS>,
        Vec<(ShaftSpeeds, Measurement<MEASUREMENTS>)>,
    ) {
        let kinetic = TwinConfig::default().kinetic;
        let model = OtterTwin::new(kinetic.params);
        let filter = Aekf::new(model, kinetic.filter).unwrap();
        let mut x0 = SVector::<f64, STATES>::zeros();
        x0[3] = 1.0;
        let start = AekfState::new(
            &kinetic.filter,
            x0,
            SMatrix::identity() * 0.1,
            SVector::zeros(),
        );
        let dt = 0.2;
        let mut truth = x0;
        let kinetic_steps: Vec<_> = (0..300)
            .map(|k| {
                let t = k as f64 * dt;
                // Full ahead, then a hard turn to port and one to starboard,
                // with the port propeller at 70 %.
                let turn = (0.05 * t).sin();
                let u = ShaftSpeeds {
                    port_radps: 100.0 * (1.0 - 0.6 * turn.max(0.0)),
                    starboard_radps: 100.0 * (1.0 + 0.6 * turn.min(0.0)),
                };
                truth = model
                    .transition(
                        &truth,
                        &u,
                        &SVector::from([0.3, 0.0, 0.0, 0.0, 0.0, 0.0]),
                        dt,
                    )
                    .next;
                let observed = model.observe(&truth).predicted;
                let mut y = Measurement::full(observed);
                y.available[meas::HEADING] = k % 3 == 0;
                (u, y)
            })
            .collect();
        (filter, start, kinetic_steps)
    }

    /// The Otter twin's `H` without sensor effects keeps to the sparser
    /// pattern, and the update that skips its zeros gives the same bits as
    /// the update with the full pattern (the same model, made to say it
    /// does not keep to the sparser one).
    #[test]
    fn the_sparser_observation_pattern_changes_no_number() {
        struct FullPattern(OtterTwin);
        impl Model<STATES, MEASUREMENTS, FAULTS> for FullPattern {
            type Input = ShaftSpeeds;
            fn transition(
                &self,
                x: &SVector<f64, STATES>,
                input: &ShaftSpeeds,
                theta: &SVector<f64, FAULTS>,
                dt_s: f64,
            ) -> crate::model::Transition<STATES, FAULTS> {
                self.0.transition(x, input, theta, dt_s)
            }
            fn observe(&self, x: &SVector<f64, STATES>) -> Observation<STATES, MEASUREMENTS> {
                self.0.observe(x)
            }
            fn measurement_angles(&self) -> [bool; MEASUREMENTS] {
                self.0.measurement_angles()
            }
            fn state_angles(&self) -> [bool; STATES] {
                self.0.state_angles()
            }
            fn state_names(&self) -> [&'static str; STATES] {
                self.0.state_names()
            }
            const TRANSITION_PATTERN: Pattern<STATES, STATES> =
                <OtterTwin as Model<STATES, MEASUREMENTS, FAULTS>>::TRANSITION_PATTERN;
            const OBSERVATION_PATTERN: Pattern<MEASUREMENTS, STATES> =
                <OtterTwin as Model<STATES, MEASUREMENTS, FAULTS>>::OBSERVATION_PATTERN;
        }
        let (filter, start, steps) = otter_trial();
        assert!(filter.model.observation_in_sparser_pattern());
        let full = Aekf::new(FullPattern(filter.model), filter.config).unwrap();
        assert!(!full.model.observation_in_sparser_pattern());
        let (mut sparser_state, mut full_state) = (start, start);
        for (u, y) in &steps {
            let a = filter.step(&mut sparser_state, u, y, 0.2).unwrap();
            let b = full.step(&mut full_state, u, y, 0.2).unwrap();
            assert_eq!(a, b);
            assert_eq!(sparser_state, full_state);
        }
        assert_eq!(sparser_state.steps, 300);
    }
}
