//! The model trait every vessel model implements for the adaptive EKF.
//!
//! A model is affine in its fault parameters `theta` over one step:
//!
//! ```text
//! x(k+1) = g(x(k), u(k), theta) ~ g(x, u, theta_old) + Psi (theta - theta_old)
//! y(k+1) = h(x(k+1)) + v
//! ```
//!
//! For the seed's kinematic model this is exact (`Psi = -B diag(u)`); for the
//! kinetic models it is the linearisation the filter needs. The filter asks a
//! model for one [`Transition`] per step (the predicted state, its Jacobian and
//! the fault sensitivity `Psi`, all at the same linearisation point) and one
//! [`Observation`] (predicted measurement and its Jacobian). Nothing else: the
//! filter holds no model state and a model holds no filter state, so the same
//! filter runs the seed's model and the extended twins unchanged.

use nalgebra::{SMatrix, SVector};

pub use crate::linalg::{Pattern, dense};

/// What one step of a model predicts, with the derivatives the filter needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transition<const N: usize, const P: usize> {
    /// The predicted next state `g(x, u, theta)` (angles wrapped).
    pub next: SVector<f64, N>,
    /// `d next / d x` at the linearisation point (the `F` of docs/model.md section 4).
    pub jacobian: SMatrix<f64, N, N>,
    /// `d next / d theta`: the fault sensitivity `Psi`.
    pub fault_sensitivity: SMatrix<f64, N, P>,
}

/// A predicted measurement and its Jacobian.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation<const N: usize, const M: usize> {
    /// `h(x)`.
    pub predicted: SVector<f64, M>,
    /// `d h / d x` (the `C` of docs/model.md section 4).
    pub jacobian: SMatrix<f64, M, N>,
}

/// A measurement vector of which some components may be missing this step
/// (a fix without course, a heading sensor that dropped out, a course that is
/// meaningless because the vessel is stopped).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measurement<const M: usize> {
    /// Measured values; components that are not available are ignored.
    pub values: SVector<f64, M>,
    /// Which components are available.
    pub available: [bool; M],
}

impl<const M: usize> Measurement<M> {
    /// A measurement with every component available.
    pub fn full(values: SVector<f64, M>) -> Self {
        Self {
            values,
            available: [true; M],
        }
    }

    /// Number of available components (the degrees of freedom of its NIS).
    pub fn dof(&self) -> usize {
        self.available.iter().filter(|a| **a).count()
    }
}

/// A vessel model: state dimension `N`, measurement dimension `M`, number of
/// fault parameters `P`.
pub trait Model<const N: usize, const M: usize, const P: usize> {
    /// What drives the model over one step (accelerations, propeller speeds...).
    type Input: Copy + std::fmt::Debug;

    /// One step of length `dt_s` from `x` under `input`, with fault parameters
    /// `theta`, and the derivatives at that point.
    fn transition(
        &self,
        x: &SVector<f64, N>,
        input: &Self::Input,
        theta: &SVector<f64, P>,
        dt_s: f64,
    ) -> Transition<N, P>;

    /// The next state alone, without the derivatives: what a forecast of
    /// states needs (the diagnosis's held-out forecasts). Equal to
    /// `transition(..).next`, which the default computes; a model whose
    /// derivatives are dear skips them.
    fn propagate(
        &self,
        x: &SVector<f64, N>,
        input: &Self::Input,
        theta: &SVector<f64, P>,
        dt_s: f64,
    ) -> SVector<f64, N> {
        self.transition(x, input, theta, dt_s).next
    }

    /// The transition a forecast's covariance is propagated with: the same
    /// next state as [`Model::transition`], and derivatives that may be a
    /// coarser approximation over the step (a forecast's uncertainty band
    /// needs them to a fraction of a per cent over its 1 s steps, not to the
    /// filter's precision). The default is `transition`.
    fn forecast_transition(
        &self,
        x: &SVector<f64, N>,
        input: &Self::Input,
        theta: &SVector<f64, P>,
        dt_s: f64,
    ) -> Transition<N, P> {
        self.transition(x, input, theta, dt_s)
    }

    /// The measurement the model expects in state `x`.
    fn observe(&self, x: &SVector<f64, N>) -> Observation<N, M>;

    /// Which measurement components are angles (their innovations are wrapped
    /// to [-pi, pi)).
    fn measurement_angles(&self) -> [bool; M];

    /// Which state components are angles (wrapped to [-pi, pi) after updates).
    fn state_angles(&self) -> [bool; N];

    /// Short names of the state components, with units, for reports.
    fn state_names(&self) -> [&'static str; N];

    /// Entries of the transition Jacobian `F` that may be non-zero. The filter
    /// skips the others; a model whose `F` is sparse says so here (a wrong
    /// pattern gives wrong results, which the models' tests check).
    const TRANSITION_PATTERN: Pattern<N, N> = dense();

    /// Entries of the observation Jacobian `H` that may be non-zero.
    const OBSERVATION_PATTERN: Pattern<M, N> = dense();

    /// A sparser pattern that `H` keeps to on some instances of the model
    /// (the Otter twin's without sensor effects), where
    /// [`Model::observation_in_sparser_pattern`] says so; the filter then
    /// skips its zeros too. Defaults to [`Model::OBSERVATION_PATTERN`].
    const SPARSER_OBSERVATION_PATTERN: Pattern<M, N> = Self::OBSERVATION_PATTERN;

    /// Whether this instance's `H` keeps to
    /// [`Model::SPARSER_OBSERVATION_PATTERN`] (a wrong answer gives wrong
    /// results, which the models' tests check). Defaults to `false`.
    fn observation_in_sparser_pattern(&self) -> bool {
        false
    }
}
