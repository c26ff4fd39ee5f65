//! A deterministic trial of the seed's kinematic model for the estimator
//! benchmarks: generated from a seed, written to and read from a JSON file that
//! the NumPy reference (`bench/numpy_aekf.py`) reads too, and run through
//! `twin_core`'s filter, recorded or timed.
//!
//! The trial is built to exercise every branch of the filter's step: a
//! turning, accelerating vessel whose course crosses +-pi many times (angle
//! wrapping), a zero-input stretch in every 200 s (anti-windup holds `S`),
//! faults that switch on and change, a jittered sample interval (lambda is
//! derived from dt each step), and measurements with missing components
//! (course, position, all, or all but course) whose values are a wild
//! sentinel that must be ignored.

use std::hint::black_box;
use std::time::Instant;

use nalgebra::{SMatrix, SVector, Vector2, Vector4};
use serde::{Deserialize, Serialize};
use twin_core::aekf::{
    Aekf, AekfConfig, AekfError, AekfState, GainSensitivity, MeasurementNoiseForm, NoiseAdaptation,
};
use twin_core::geodesy::wrap_pi;
use twin_core::model::Measurement;
use twin_core::models::kinematic::{KinematicInput, KinematicModel};

use crate::rng::SplitMix64;
use crate::workloads::StepCode;

/// The `format` tag of trial files this crate writes and reads.
pub const TRIAL_FORMAT: &str = "twin-bench/aekf-trial/v1";

/// The value written for a measurement component that is not available: far
/// off, so an implementation that used it would disagree at once.
pub const MISSING_SENTINEL: f64 = 1.0e6;

/// The seed model's filter as the benchmark runs it.
pub type SeedFilter = Aekf<KinematicModel, 4, 4, 2>;

/// The seed model's estimate.
pub type SeedState = AekfState<4, 4, 2>;

/// Which Q/R adaptation the trial's filter runs with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum Adaptation {
    /// No adaptation (the default tuning).
    Off,
    /// Q and R adapted, R in the seed authors' form (prior innovation).
    AuthorsCode,
    /// Q and R adapted, R from the post-fit residual (Akhlaghi et al.).
    PostFitResidual,
}

/// What to generate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrialSpec {
    /// Number of filter steps.
    pub steps: usize,
    /// Nominal sample interval, seconds (each step is jittered by +-2.5 %).
    pub dt_s: f64,
    /// Seed of the noise, jitter and dropouts.
    pub seed: u64,
    /// The filter's noise adaptation.
    pub adaptation: Adaptation,
}

impl Default for TrialSpec {
    /// 3,000 steps at 5 Hz (600 s), seed 1, no adaptation.
    fn default() -> Self {
        Self {
            steps: 3000,
            dt_s: 0.2,
            seed: 1,
            adaptation: Adaptation::Off,
        }
    }
}

/// The filter's tuning as written in a trial file (matrices row by row).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ConfigFile {
    /// `Q_c`, per second.
    pub process_noise_density: [[f64; 4]; 4],
    /// `R`.
    pub measurement_noise: [[f64; 4]; 4],
    /// `tau` of `lambda = exp(-dt/tau)`, seconds.
    pub forgetting_time_constant_s: f64,
    /// `S(0)`.
    pub initial_fault_covariance: [[f64; 2]; 2],
    /// Anti-windup ratio (0 = the seed's plain forgetting).
    pub anti_windup_ratio: f64,
    /// Excitation threshold (not used by the step itself).
    pub excitation_sigma: f64,
    /// Q/R adaptation, or none.
    pub noise_adaptation: Option<AdaptationFile>,
}

/// Q/R adaptation as written in a trial file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AdaptationFile {
    /// Memory factor `a` per step.
    pub factor: f64,
    /// Whether Q is adapted.
    pub adapt_process_noise: bool,
    /// `"authors_code"`, `"post_fit_residual"`, or none (R not adapted).
    pub measurement_noise_form: Option<String>,
}

/// The initial estimate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InitialFile {
    /// `xhat(0)`: `[north_m, east_m, sog_mps, course_rad]`.
    pub x: [f64; 4],
    /// `P(0)`.
    pub p: [[f64; 4]; 4],
    /// `thetahat(0)`.
    pub theta: [f64; 2],
}

/// The per-step data, one entry per step in each vector.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StepsFile {
    /// Time since the previous estimate, seconds.
    pub dt_s: Vec<f64>,
    /// `[accel_mps2, course_rate_radps]` over the step.
    pub input: Vec<[f64; 2]>,
    /// Measured `[north_m, east_m, sog_mps, course_rad]` at the end of the step
    /// ([`MISSING_SENTINEL`] where not available).
    pub y: Vec<[f64; 4]>,
    /// Which measurement components are available.
    pub available: Vec<[bool; 4]>,
    /// The true faults over the step (for reference; the filter does not see them).
    pub true_theta: Vec<[f64; 2]>,
}

/// A whole trial: what both implementations read.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrialFile {
    /// [`TRIAL_FORMAT`].
    pub format: String,
    /// `"kinematic"`: the seed's model.
    pub model: String,
    /// How it was generated, for the record.
    pub description: String,
    /// The filter's tuning.
    pub config: ConfigFile,
    /// The initial estimate.
    pub initial: InitialFile,
    /// The steps.
    pub steps: StepsFile,
}

/// One step ready for the filter.
#[derive(Debug, Clone, Copy)]
pub struct PreparedStep {
    /// The input over the step.
    pub input: KinematicInput,
    /// The measurement at its end.
    pub y: Measurement<4>,
    /// Its length, seconds.
    pub dt_s: f64,
}

/// A trial turned into the filter, its initial estimate and its steps.
#[derive(Debug, Clone)]
pub struct Prepared {
    /// The filter.
    pub filter: SeedFilter,
    /// The initial estimate.
    pub start: SeedState,
    /// The steps.
    pub steps: Vec<PreparedStep>,
}

/// Per-step estimates of a run (after each step; a refused step repeats the
/// previous estimate and has no NIS).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Estimates {
    /// `thetahat` after each step.
    pub theta: Vec<[f64; 2]>,
    /// `xhat` after each step.
    pub x: Vec<[f64; 4]>,
    /// The step's NIS, or none if the step was refused.
    pub nis: Vec<Option<f64>>,
}

/// Median and minimum of repeated timings of a whole trial, per step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Timing {
    /// Median over the repeats, nanoseconds per step.
    pub ns_per_step_median: f64,
    /// Fastest repeat, nanoseconds per step.
    pub ns_per_step_min: f64,
    /// Number of timed repeats.
    pub repeats: usize,
}

fn rows<const R: usize, const C: usize>(m: &SMatrix<f64, R, C>) -> [[f64; C]; R] {
    std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)]))
}

fn from_rows<const R: usize, const C: usize>(a: &[[f64; C]; R]) -> SMatrix<f64, R, C> {
    SMatrix::from_fn(|i, j| a[i][j])
}

/// The input at time `t_s`: a slow steady turn with two superposed course-rate
/// oscillations (so the course crosses +-pi again and again), a zero-mean
/// acceleration that keeps the speed between about 1 and 2 m/s, and a
/// 15 s straight run at constant speed (no input at all) in every 200 s.
pub fn input_at(t_s: f64) -> [f64; 2] {
    if (60.0..75.0).contains(&(t_s % 200.0)) {
        return [0.0, 0.0];
    }
    let tau = std::f64::consts::TAU;
    let a = 0.05 * (tau * t_s / 47.0).sin() + 0.02 * (tau * t_s / 13.0 + 1.0).sin();
    let r = 0.02 + 0.08 * (tau * t_s / 60.0).sin() + 0.03 * (tau * t_s / 7.3 + 0.5).sin();
    [a, r]
}

/// The true faults over the step starting at `t_s`: none for 20 s, then
/// `[0.2, 0.4]`, then `[0.1, 0.5]` from 300 s.
pub fn true_theta_at(t_s: f64) -> [f64; 2] {
    if t_s < 20.0 {
        [0.0, 0.0]
    } else if t_s < 300.0 {
        [0.2, 0.4]
    } else {
        [0.1, 0.5]
    }
}

/// Measurement noise standard deviations: standalone GNSS (0.3 m per axis,
/// 0.05 m/s, 0.02 rad).
pub const NOISE_SIGMA: [f64; 4] = [0.3, 0.3, 0.05, 0.02];

/// Generates the trial: the truth integrated with the seed's model and the true
/// faults, noisy measurements with dropouts, and the filter's tuning.
pub fn generate(spec: &TrialSpec) -> TrialFile {
    let mut rng = SplitMix64::new(spec.seed);
    let sigma = Vector4::from(NOISE_SIGMA);
    let r = SMatrix::<f64, 4, 4>::from_diagonal(&sigma.component_mul(&sigma));
    let noise_adaptation = match spec.adaptation {
        Adaptation::Off => None,
        Adaptation::AuthorsCode => Some(AdaptationFile {
            factor: 0.999,
            adapt_process_noise: true,
            measurement_noise_form: Some("authors_code".into()),
        }),
        Adaptation::PostFitResidual => Some(AdaptationFile {
            factor: 0.999,
            adapt_process_noise: true,
            measurement_noise_form: Some("post_fit_residual".into()),
        }),
    };
    let config = ConfigFile {
        process_noise_density: rows(&SMatrix::<f64, 4, 4>::from_diagonal(&Vector4::new(
            0.01, 0.01, 0.001, 0.0005,
        ))),
        measurement_noise: rows(&r),
        forgetting_time_constant_s: 40.0,
        initial_fault_covariance: rows(&(SMatrix::<f64, 2, 2>::identity() * 0.1)),
        anti_windup_ratio: 0.1,
        excitation_sigma: 0.02,
        noise_adaptation,
    };

    let mut truth = [0.0, 0.0, 1.5, 2.9];
    let measure = |x: &[f64; 4], rng: &mut SplitMix64| -> [f64; 4] {
        let mut y: [f64; 4] = std::array::from_fn(|i| x[i] + NOISE_SIGMA[i] * rng.normal());
        y[3] = wrap_pi(y[3]);
        y
    };
    let y0 = measure(&truth, &mut rng);
    let initial = InitialFile {
        x: y0,
        p: rows(&r),
        theta: [0.0, 0.0],
    };

    let n = spec.steps;
    let mut steps = StepsFile {
        dt_s: Vec::with_capacity(n),
        input: Vec::with_capacity(n),
        y: Vec::with_capacity(n),
        available: Vec::with_capacity(n),
        true_theta: Vec::with_capacity(n),
    };
    let mut t = 0.0;
    for _ in 0..n {
        let dt = spec.dt_s * (1.0 + 0.05 * (rng.uniform() - 0.5));
        let u = input_at(t);
        let th = true_theta_at(t);
        let x = truth;
        truth = [
            x[0] + dt * x[2] * x[3].cos(),
            x[1] + dt * x[2] * x[3].sin(),
            x[2] + dt * (1.0 - th[0]) * u[0],
            wrap_pi(x[3] + dt * (1.0 - th[1]) * u[1]),
        ];
        let mut y = measure(&truth, &mut rng);
        let p = rng.uniform();
        let available = if p < 0.03 {
            [true, true, true, false] // no course
        } else if p < 0.05 {
            [false, false, true, true] // no position
        } else if p < 0.06 {
            [false; 4] // nothing at all
        } else if p < 0.065 {
            [false, false, false, true] // course only
        } else {
            [true; 4]
        };
        for i in 0..4 {
            if !available[i] {
                y[i] = MISSING_SENTINEL;
            }
        }
        steps.dt_s.push(dt);
        steps.input.push(u);
        steps.y.push(y);
        steps.available.push(available);
        steps.true_theta.push(th);
        t += dt;
    }

    TrialFile {
        format: TRIAL_FORMAT.into(),
        model: "kinematic".into(),
        description: format!(
            "seed kinematic model, {} steps at {} Hz nominal (dt jittered +-2.5 %), seed {}, \
             noise sigma {:?}, noise adaptation {:?}",
            spec.steps,
            1.0 / spec.dt_s,
            spec.seed,
            NOISE_SIGMA,
            spec.adaptation
        ),
        config,
        initial,
        steps,
    }
}

impl TrialFile {
    /// Checks the file and builds the filter, its start and its steps.
    pub fn prepare(&self) -> anyhow::Result<Prepared> {
        anyhow::ensure!(
            self.format == TRIAL_FORMAT,
            "trial format {:?}, expected {TRIAL_FORMAT:?}",
            self.format
        );
        anyhow::ensure!(
            self.model == "kinematic",
            "model {:?}: only the seed's kinematic model is supported",
            self.model
        );
        let s = &self.steps;
        let n = s.dt_s.len();
        anyhow::ensure!(
            s.input.len() == n && s.y.len() == n && s.available.len() == n,
            "per-step vectors differ in length"
        );
        let c = &self.config;
        let noise_adaptation = match &c.noise_adaptation {
            None => None,
            Some(a) => Some(NoiseAdaptation {
                factor: a.factor,
                adapt_process_noise: a.adapt_process_noise,
                measurement_noise_form: match a.measurement_noise_form.as_deref() {
                    None => None,
                    Some("authors_code") => Some(MeasurementNoiseForm::AuthorsCode),
                    Some("post_fit_residual") => Some(MeasurementNoiseForm::PostFitResidual),
                    Some(other) => anyhow::bail!("unknown measurement_noise_form {other:?}"),
                },
            }),
        };
        let config = AekfConfig {
            process_noise_density: from_rows(&c.process_noise_density),
            measurement_noise: from_rows(&c.measurement_noise),
            forgetting_time_constant_s: c.forgetting_time_constant_s,
            fault_memory_factor: SVector::repeat(1.0),
            initial_fault_covariance: from_rows(&c.initial_fault_covariance),
            anti_windup_ratio: c.anti_windup_ratio,
            excitation_sigma: c.excitation_sigma,
            noise_adaptation,
            gain_sensitivity: GainSensitivity::Omitted,
            gain_sensitivity_faults: [true; _],
        };
        let filter = Aekf::new(KinematicModel, config)?;
        let start = AekfState::new(
            &config,
            SVector::from(self.initial.x),
            from_rows(&self.initial.p),
            Vector2::from(self.initial.theta),
        );
        let steps = (0..n)
            .map(|k| PreparedStep {
                input: KinematicInput {
                    accel_mps2: s.input[k][0],
                    course_rate_radps: s.input[k][1],
                },
                y: Measurement {
                    values: SVector::from(s.y[k]),
                    available: s.available[k],
                },
                dt_s: s.dt_s[k],
            })
            .collect();
        Ok(Prepared {
            filter,
            start,
            steps,
        })
    }

    /// Number of steps with at least one measurement component missing.
    pub fn masked_steps(&self) -> usize {
        self.steps
            .available
            .iter()
            .filter(|a| a.iter().any(|v| !v))
            .count()
    }

    /// Duration of the trial, seconds.
    pub fn duration_s(&self) -> f64 {
        self.steps.dt_s.iter().sum()
    }
}

impl Prepared {
    /// Runs the trial once, recording the estimate after every step. A refused
    /// step leaves the estimate as it was, as a live twin would.
    pub fn run_recorded(&self) -> Estimates {
        let mut est = self.start;
        let mut out = Estimates {
            theta: Vec::with_capacity(self.steps.len()),
            x: Vec::with_capacity(self.steps.len()),
            nis: Vec::with_capacity(self.steps.len()),
        };
        for s in &self.steps {
            let nis = self
                .filter
                .step(&mut est, &s.input, &s.y, s.dt_s)
                .ok()
                .map(|r| r.nis);
            out.theta.push(est.theta.into());
            out.x.push(est.x.into());
            out.nis.push(nis);
        }
        out
    }

    /// Runs the whole trial once through `black_box` (what is timed).
    pub fn run_once(&self) -> SeedState {
        self.run_once_in(StepCode::Dispatched)
    }

    /// Runs the whole trial once in the given copy of the step's code.
    #[inline(never)]
    pub fn run_once_in(&self, code: StepCode) -> SeedState {
        let mut est = self.start;
        for s in &self.steps {
            let (input, y, dt_s) = (black_box(&s.input), black_box(&s.y), black_box(s.dt_s));
            let r: Result<_, AekfError> = match code {
                StepCode::Dispatched => self.filter.step(black_box(&mut est), input, y, dt_s),
                StepCode::Baseline => {
                    self.filter
                        .step_baseline(black_box(&mut est), input, y, dt_s)
                }
            };
            // By reference: the report stays where the step wrote it (by
            // value, `black_box` would copy its 200 bytes once more and time
            // the copy too).
            black_box(&r);
        }
        black_box(est)
    }

    /// Times the step's two copies side by side: `repeats` runs of the whole
    /// trial in each, alternating (after one warm-up run of each).
    pub fn time_both_copies(&self, repeats: usize) -> [Timing; 2] {
        crate::workloads::per_item_both_copies(self.steps.len(), repeats, |code| {
            black_box(self.run_once_in(code));
        })
    }

    /// Times `repeats` runs of the whole trial (after one warm-up run).
    pub fn time(&self, repeats: usize) -> Timing {
        let repeats = repeats.max(1);
        black_box(self.run_once());
        let mut ns: Vec<f64> = (0..repeats)
            .map(|_| {
                let t0 = Instant::now();
                black_box(self.run_once());
                t0.elapsed().as_nanos() as f64
            })
            .collect();
        ns.sort_by(f64::total_cmp);
        let per_step = self.steps.len().max(1) as f64;
        let median = if repeats % 2 == 1 {
            ns[repeats / 2]
        } else {
            0.5 * (ns[repeats / 2 - 1] + ns[repeats / 2])
        };
        Timing {
            ns_per_step_median: median / per_step,
            ns_per_step_min: ns[0] / per_step,
            repeats,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The default trial exercises what it is meant to: masking of every
    /// kind, course wrap-arounds, zero input, faults, varying dt; and every
    /// step of it is accepted by the filter.
    #[test]
    fn default_trial_covers_the_branches() {
        let trial = generate(&TrialSpec::default());
        let s = &trial.steps;
        assert_eq!(s.dt_s.len(), 3000);
        assert!(trial.masked_steps() > 100, "{}", trial.masked_steps());
        assert!(s.available.iter().any(|a| a.iter().all(|v| !v)));
        assert!(s.available.contains(&[false, false, false, true]));
        let crossings =
            s.y.windows(2)
                .zip(s.available.windows(2))
                .filter(|(y, a)| a[0][3] && a[1][3] && (y[1][3] - y[0][3]).abs() > 3.0)
                .count();
        assert!(crossings >= 4, "course crosses +-pi only {crossings} times");
        assert!(s.input.iter().filter(|u| **u == [0.0, 0.0]).count() > 100);
        assert!(s.true_theta.iter().any(|t| t[0] > 0.0 && t[1] > 0.0));
        let (lo, hi) = s
            .dt_s
            .iter()
            .fold((f64::MAX, f64::MIN), |(lo, hi), d| (lo.min(*d), hi.max(*d)));
        assert!(lo < 0.199 && hi > 0.201);
        let run = trial.prepare().unwrap().run_recorded();
        assert!(run.nis.iter().all(|n| n.is_some()), "a step was refused");
        // The filter finds the fault it is meant to find.
        let th = run.theta[1400];
        assert!(
            (th[0] - 0.2).abs() < 0.1 && (th[1] - 0.4).abs() < 0.1,
            "{th:?}"
        );
    }

    /// Written and read back, the trial prepares the same filter and steps
    /// (floats compared to the last bit or one unit in the last place:
    /// serde_json's default parser may be one ULP off; Python's is exact).
    #[test]
    fn trial_file_round_trips_through_json() {
        let trial = generate(&TrialSpec {
            steps: 50,
            adaptation: Adaptation::PostFitResidual,
            ..TrialSpec::default()
        });
        let text = serde_json::to_string(&trial).unwrap();
        let back: TrialFile = serde_json::from_str(&text).unwrap();
        assert_eq!(back.config.noise_adaptation, trial.config.noise_adaptation);
        assert_eq!(back.steps.available, trial.steps.available);
        let close = |a: f64, b: f64| (a - b).abs() <= 2.3e-16 * a.abs().max(b.abs());
        for (a, b) in back
            .steps
            .y
            .iter()
            .flatten()
            .zip(trial.steps.y.iter().flatten())
        {
            assert!(close(*a, *b), "{a} {b}");
        }
        for (a, b) in back.steps.dt_s.iter().zip(&trial.steps.dt_s) {
            assert!(close(*a, *b), "{a} {b}");
        }
        back.prepare().unwrap();
    }
}
