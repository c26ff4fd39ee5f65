//! The seed's inputs derived from GNSS (docs/model.md section 3): acceleration
//! along the track `a = dU/dt` and course rate `r = dchi/dt` by finite
//! differences of SOG and COG over irregular time steps (course differences
//! wrapped), followed by a causal low-pass.
//!
//! Two alignments of the difference (see [`DifferenceAlignment`]) and two
//! low-passes (see [`LowPass`]), each with the lag it adds:
//! - the difference `(U(k+1) - U(k)) / dt` is the mean slope over the
//!   interval, i.e. the derivative half an interval earlier than its newest
//!   sample; aligned forward (the thesis) it drives exactly the interval it
//!   was measured over and adds no lag to the filter; aligned backward (the
//!   paper) it drives the next interval and so lags by one sample interval;
//! - the Butterworth low-pass of order `n` and cut-off `fc` delays slow
//!   signals by its DC group delay `1 / (wc sin(pi / 2n))` with the
//!   pre-warped `wc = 2 fs tan(pi fc / fs)`: 0.445 s for the thesis' 5th
//!   order at 1 Hz and 5 Hz (computed from the designed coefficients by
//!   [`Butterworth::group_delay_at_dc_s`]);
//! - the first-order lag with time constant `T` delays slow signals by `T`.
//!
//! All of these run causally, one sample at a time, as a live daemon must.

use std::f64::consts::PI;

use crate::geodesy::angle_diff;
use crate::models::kinematic::KinematicInput;

/// Which interval a difference drives.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DifferenceAlignment {
    /// `u(k) = (y(k+1) - y(k)) / dt`: the thesis' forward difference. It is
    /// available when `y(k+1)` arrives, which is when the filter consumes it,
    /// so it is causal here and adds no lag.
    #[default]
    Forward,
    /// `u(k) = (y(k) - y(k-1)) / dt'`: the paper's backward difference, one
    /// sample interval older.
    Backward,
}

/// The low-pass applied to the raw differences.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LowPass {
    /// No filtering.
    None,
    /// A Butterworth low-pass designed for a nominal sample rate (the thesis:
    /// order 5, 1 Hz at 5 Hz). Irregular intervals are treated as nominal.
    Butterworth {
        /// Filter order, 1 to 8.
        order: usize,
        /// Cut-off frequency, Hz; below half the sample rate.
        cutoff_hz: f64,
        /// The nominal sample rate, Hz.
        sample_rate_hz: f64,
    },
    /// A first-order lag with output saturation (the paper), exact for
    /// irregular intervals: `y += (1 - exp(-dt/T)) (x - y)`, then clamped.
    FirstOrderLag {
        /// Time constant, seconds.
        time_constant_s: f64,
        /// Saturation of the acceleration output, m/s^2.
        max_accel_mps2: f64,
        /// Saturation of the course-rate output, rad/s.
        max_course_rate_radps: f64,
    },
}

/// Why an input-derivation configuration is unusable.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum InputConfigError {
    /// The Butterworth order is outside 1..=8.
    #[error("Butterworth order {0} is outside 1..=8")]
    BadOrder(usize),
    /// The cut-off is not below the Nyquist frequency, or not positive.
    #[error(
        "cut-off {cutoff_hz} Hz must be positive and below half the sample rate {sample_rate_hz} Hz"
    )]
    BadCutoff {
        /// The requested cut-off, Hz.
        cutoff_hz: f64,
        /// The nominal sample rate, Hz.
        sample_rate_hz: f64,
    },
    /// A time constant or saturation is not positive.
    #[error("time constant and saturation limits must be positive")]
    BadLag,
}

/// One second-order section in transposed direct form II.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct Biquad {
    b: [f64; 3],
    a: [f64; 2],
    z: [f64; 2],
}

impl Biquad {
    fn step(&mut self, x: f64) -> f64 {
        let y = self.b[0] * x + self.z[0];
        self.z[0] = self.b[1] * x - self.a[0] * y + self.z[1];
        self.z[1] = self.b[2] * x - self.a[1] * y;
        y
    }

    /// Group delay at DC, in samples: `d(-phase)/d omega` at 0 for
    /// `(b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2)`.
    fn group_delay_at_dc_samples(&self) -> f64 {
        let num = (self.b[1] + 2.0 * self.b[2]) / (self.b[0] + self.b[1] + self.b[2]);
        let den = (self.a[0] + 2.0 * self.a[1]) / (1.0 + self.a[0] + self.a[1]);
        num - den
    }
}

/// The most second-order sections a filter of order 1 to 8 needs.
const MAX_SECTIONS: usize = 4;

/// A digital Butterworth low-pass as a cascade of second-order sections,
/// designed by the bilinear transform with pre-warping.
///
/// The sections are held inline (no heap), so copying a filter, as every
/// copy of the twin does (a forecast's, for one), does not allocate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Butterworth {
    /// The first `section_count` are the filter; the rest stay at their
    /// default and are never used.
    sections: [Biquad; MAX_SECTIONS],
    section_count: usize,
    sample_rate_hz: f64,
    primed: bool,
}

impl Butterworth {
    /// Designs the filter.
    pub fn new(
        order: usize,
        cutoff_hz: f64,
        sample_rate_hz: f64,
    ) -> Result<Self, InputConfigError> {
        if !(1..=8).contains(&order) {
            return Err(InputConfigError::BadOrder(order));
        }
        if !(cutoff_hz > 0.0 && sample_rate_hz > 0.0 && cutoff_hz < 0.5 * sample_rate_hz) {
            return Err(InputConfigError::BadCutoff {
                cutoff_hz,
                sample_rate_hz,
            });
        }
        // Pre-warped analogue cut-off, with the bilinear constant k = 2 fs
        // folded in: w = tan(pi fc / fs).
        let w = (PI * cutoff_hz / sample_rate_hz).tan();
        let mut sections = [Biquad::default(); MAX_SECTIONS];
        let mut section_count = 0;
        // Conjugate pole pairs of the normalised prototype: s^2 + 2 sin(phi) s + 1
        // with phi = (2k+1) pi / (2n), k < n/2.
        for k in 0..order / 2 {
            let phi = (2 * k + 1) as f64 * PI / (2 * order) as f64;
            let alpha = 2.0 * phi.sin();
            // H(s) = w^2 / (s^2 + alpha w s + w^2) with s = (1 - z^-1)/(1 + z^-1).
            let d = 1.0 + alpha * w + w * w;
            let g = w * w / d;
            sections[section_count] = Biquad {
                b: [g, 2.0 * g, g],
                a: [2.0 * (w * w - 1.0) / d, (1.0 - alpha * w + w * w) / d],
                z: [0.0; 2],
            };
            section_count += 1;
        }
        if order % 2 == 1 {
            // Real pole: H(s) = w / (s + w).
            let d = 1.0 + w;
            sections[section_count] = Biquad {
                b: [w / d, w / d, 0.0],
                a: [(w - 1.0) / d, 0.0],
                z: [0.0; 2],
            };
            section_count += 1;
        }
        Ok(Self {
            sections,
            section_count,
            sample_rate_hz,
            primed: false,
        })
    }

    /// Filters one sample. The first sample initialises the state to its
    /// steady state for that value, so a filter started mid-manoeuvre does
    /// not ring.
    pub fn step(&mut self, x: f64) -> f64 {
        if !self.primed {
            self.primed = true;
            for s in self.sections[..self.section_count].iter_mut() {
                // Steady state of TDF-II for a constant input x with unit DC gain.
                s.z[1] = s.b[2] * x - s.a[1] * x;
                s.z[0] = s.b[1] * x - s.a[0] * x + s.z[1];
            }
        }
        self.sections[..self.section_count]
            .iter_mut()
            .fold(x, |v, s| s.step(v))
    }

    /// The delay of slow signals through the filter, seconds.
    pub fn group_delay_at_dc_s(&self) -> f64 {
        self.sections[..self.section_count]
            .iter()
            .map(Biquad::group_delay_at_dc_samples)
            .sum::<f64>()
            / self.sample_rate_hz
    }

    /// Gain at DC (1 for a low-pass; exposed for tests).
    pub fn dc_gain(&self) -> f64 {
        self.sections[..self.section_count]
            .iter()
            .map(|s| (s.b[0] + s.b[1] + s.b[2]) / (1.0 + s.a[0] + s.a[1]))
            .product()
    }

    /// Magnitude of the frequency response at `freq_hz`.
    pub fn gain_at(&self, freq_hz: f64) -> f64 {
        let w = 2.0 * PI * freq_hz / self.sample_rate_hz;
        let (c1, s1) = (w.cos(), -w.sin());
        let (c2, s2) = ((2.0 * w).cos(), -(2.0 * w).sin());
        self.sections[..self.section_count]
            .iter()
            .map(|s| {
                let nr = s.b[0] + s.b[1] * c1 + s.b[2] * c2;
                let ni = s.b[1] * s1 + s.b[2] * s2;
                let dr = 1.0 + s.a[0] * c1 + s.a[1] * c2;
                let di = s.a[0] * s1 + s.a[1] * s2;
                (nr.hypot(ni)) / (dr.hypot(di))
            })
            .product()
    }
}

#[derive(Debug, Clone, PartialEq)]
#[expect(
    clippy::large_enum_variant,
    reason = "one per deriver; a box would put an allocation on every copy of the twin"
)]
enum Smoother {
    None,
    /// Inline, like the filters' sections: a copy does not allocate.
    Butterworth([Butterworth; 2]),
    Lag {
        time_constant_s: f64,
        limits: [f64; 2],
        state: Option<[f64; 2]>,
    },
}

/// Configuration of the derivation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InputDerivationConfig {
    /// Which interval a difference drives.
    pub alignment: DifferenceAlignment,
    /// The low-pass on the raw differences.
    pub low_pass: LowPass,
    /// Below this SOG the course is meaningless (a stopped vessel's COG is
    /// noise), so the course rate is taken as 0. m/s.
    pub min_speed_for_course_mps: f64,
}

impl InputDerivationConfig {
    /// The thesis' choice: forward difference, 5th-order Butterworth at
    /// 1 Hz for 5 Hz GNSS.
    pub fn thesis() -> Self {
        Self {
            alignment: DifferenceAlignment::Forward,
            low_pass: LowPass::Butterworth {
                order: 5,
                cutoff_hz: 1.0,
                sample_rate_hz: 5.0,
            },
            min_speed_for_course_mps: 0.3,
        }
    }

    /// The delay this configuration adds to slow signals, seconds, at the
    /// given sample interval (one interval for the backward alignment, plus
    /// the low-pass's delay).
    pub fn lag_s(&self, sample_interval_s: f64) -> f64 {
        let align = match self.alignment {
            DifferenceAlignment::Forward => 0.0,
            DifferenceAlignment::Backward => sample_interval_s,
        };
        let filter = match self.low_pass {
            LowPass::None => 0.0,
            LowPass::Butterworth {
                order,
                cutoff_hz,
                sample_rate_hz,
            } => Butterworth::new(order, cutoff_hz, sample_rate_hz)
                .map(|b| b.group_delay_at_dc_s())
                .unwrap_or(f64::NAN),
            LowPass::FirstOrderLag {
                time_constant_s, ..
            } => time_constant_s,
        };
        align + filter
    }
}

/// Derives the seed's inputs from a stream of (time, SOG, COG) samples.
#[derive(Debug, Clone, PartialEq)]
pub struct InputDeriver {
    config: InputDerivationConfig,
    smoother: Smoother,
    last: Option<(f64, f64, f64)>,
    previous_raw: Option<KinematicInput>,
}

impl InputDeriver {
    /// A deriver with `config`, checked.
    pub fn new(config: InputDerivationConfig) -> Result<Self, InputConfigError> {
        let smoother = match config.low_pass {
            LowPass::None => Smoother::None,
            LowPass::Butterworth {
                order,
                cutoff_hz,
                sample_rate_hz,
            } => {
                let filter = Butterworth::new(order, cutoff_hz, sample_rate_hz)?;
                Smoother::Butterworth([filter; 2])
            }
            LowPass::FirstOrderLag {
                time_constant_s,
                max_accel_mps2,
                max_course_rate_radps,
            } => {
                if !(time_constant_s > 0.0 && max_accel_mps2 > 0.0 && max_course_rate_radps > 0.0) {
                    return Err(InputConfigError::BadLag);
                }
                Smoother::Lag {
                    time_constant_s,
                    limits: [max_accel_mps2, max_course_rate_radps],
                    state: None,
                }
            }
        };
        Ok(Self {
            config,
            smoother,
            last: None,
            previous_raw: None,
        })
    }

    /// Consumes the next sample (time in seconds, SOG in m/s, COG in rad) and
    /// returns the input for the interval that ends at it, or `None` for the
    /// first sample or a sample that does not advance time.
    pub fn push(&mut self, time_s: f64, sog_mps: f64, cog_rad: f64) -> Option<KinematicInput> {
        let Some((t0, u0, c0)) = self.last else {
            self.last = Some((time_s, sog_mps, cog_rad));
            return None;
        };
        let dt = time_s - t0;
        if dt.is_nan() || dt <= 0.0 || !sog_mps.is_finite() || !cog_rad.is_finite() {
            return None;
        }
        self.last = Some((time_s, sog_mps, cog_rad));
        let slow = sog_mps.min(u0) < self.config.min_speed_for_course_mps;
        let raw = KinematicInput {
            accel_mps2: (sog_mps - u0) / dt,
            course_rate_radps: if slow {
                0.0
            } else {
                angle_diff(cog_rad, c0) / dt
            },
        };
        let aligned = match self.config.alignment {
            DifferenceAlignment::Forward => raw,
            DifferenceAlignment::Backward => self.previous_raw.replace(raw).unwrap_or_default(),
        };
        Some(self.smooth(aligned, dt))
    }

    fn smooth(&mut self, raw: KinematicInput, dt: f64) -> KinematicInput {
        match &mut self.smoother {
            Smoother::None => raw,
            Smoother::Butterworth(filters) => KinematicInput {
                accel_mps2: filters[0].step(raw.accel_mps2),
                course_rate_radps: filters[1].step(raw.course_rate_radps),
            },
            Smoother::Lag {
                time_constant_s,
                limits,
                state,
            } => {
                let x = [raw.accel_mps2, raw.course_rate_radps];
                let gain = 1.0 - (-dt / *time_constant_s).exp();
                let y = match state {
                    None => x,
                    Some(prev) => [
                        prev[0] + gain * (x[0] - prev[0]),
                        prev[1] + gain * (x[1] - prev[1]),
                    ],
                };
                let y = [
                    y[0].clamp(-limits[0], limits[0]),
                    y[1].clamp(-limits[1], limits[1]),
                ];
                *state = Some(y);
                KinematicInput {
                    accel_mps2: y[0],
                    course_rate_radps: y[1],
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn butterworth_has_unit_dc_gain_and_minus_3_db_at_cutoff() {
        for order in 1..=8 {
            let f = Butterworth::new(order, 1.0, 5.0).unwrap();
            assert!((f.dc_gain() - 1.0).abs() < 1e-12, "order {order}");
            assert!(
                (f.gain_at(1.0) - 0.5f64.sqrt()).abs() < 1e-9,
                "order {order}: {}",
                f.gain_at(1.0)
            );
            // Monotone roll-off: at 2 Hz the 5th order is down by more than 30 dB
            // (the digital filter has a zero at Nyquist, so it beats the analogue one).
            if order == 5 {
                assert!(f.gain_at(2.0) < 0.03, "{}", f.gain_at(2.0));
            }
        }
    }

    #[test]
    fn butterworth_delay_matches_the_analogue_formula() {
        // Analogue DC group delay: 1 / (wc sin(pi / 2n)). Near DC the bilinear
        // transform is the identity on frequency, so the digital filter has
        // the delay of its pre-warped prototype, wc = 2 fs tan(pi fc / fs).
        let f = Butterworth::new(5, 1.0, 5.0).unwrap();
        let prewarped = 2.0 * 5.0 * (PI / 5.0).tan();
        let analogue = 1.0 / (prewarped * (PI / 10.0).sin());
        let digital = f.group_delay_at_dc_s();
        assert!((digital - analogue).abs() < 1e-9, "{digital} vs {analogue}");
        assert!((digital - 0.445).abs() < 0.001, "{digital}");
        // And a slow ramp through the filter is delayed by exactly that much.
        let mut g = Butterworth::new(5, 1.0, 5.0).unwrap();
        let mut last = 0.0;
        for k in 0..500 {
            last = g.step(k as f64 * 0.2 * 0.1);
        }
        let t_end = 499.0 * 0.2;
        let delay = t_end - last / 0.1;
        assert!(
            (delay - digital).abs() < 1e-6,
            "ramp delay {delay} vs {digital}"
        );
    }

    #[test]
    fn forward_difference_recovers_constant_rates_with_wrapping() {
        let mut d = InputDeriver::new(InputDerivationConfig {
            alignment: DifferenceAlignment::Forward,
            low_pass: LowPass::None,
            min_speed_for_course_mps: 0.3,
        })
        .unwrap();
        // Irregular steps; the course crosses north (2 pi -> 0).
        let times = [0.0f64, 0.2, 0.35, 0.6, 0.8, 1.3];
        let mut out = vec![];
        for t in times {
            let sog = 1.0 + 0.5 * t;
            let cog = (6.2 + 0.1 * t).rem_euclid(std::f64::consts::TAU);
            out.extend(d.push(t, sog, cog));
        }
        assert_eq!(out.len(), times.len() - 1);
        for u in out {
            assert!((u.accel_mps2 - 0.5).abs() < 1e-9);
            assert!(
                (u.course_rate_radps - 0.1).abs() < 1e-9,
                "{}",
                u.course_rate_radps
            );
        }
    }

    #[test]
    fn backward_alignment_is_one_interval_late() {
        let cfg = |alignment| InputDerivationConfig {
            alignment,
            low_pass: LowPass::None,
            min_speed_for_course_mps: 0.3,
        };
        let mut fwd = InputDeriver::new(cfg(DifferenceAlignment::Forward)).unwrap();
        let mut bwd = InputDeriver::new(cfg(DifferenceAlignment::Backward)).unwrap();
        let sog = [1.0, 1.0, 2.0, 2.0, 2.0];
        let f: Vec<_> = sog
            .iter()
            .enumerate()
            .filter_map(|(k, s)| fwd.push(k as f64, *s, 0.0))
            .collect();
        let b: Vec<_> = sog
            .iter()
            .enumerate()
            .filter_map(|(k, s)| bwd.push(k as f64, *s, 0.0))
            .collect();
        assert_eq!(
            f.iter().map(|u| u.accel_mps2).collect::<Vec<_>>(),
            vec![0.0, 1.0, 0.0, 0.0]
        );
        assert_eq!(
            b.iter().map(|u| u.accel_mps2).collect::<Vec<_>>(),
            vec![0.0, 0.0, 1.0, 0.0]
        );
        assert_eq!(
            InputDerivationConfig::thesis().lag_s(0.2),
            InputDerivationConfig {
                alignment: DifferenceAlignment::Forward,
                ..InputDerivationConfig::thesis()
            }
            .lag_s(0.2)
        );
        assert!((cfg(DifferenceAlignment::Backward).lag_s(0.2) - 0.2).abs() < 1e-12);
    }

    #[test]
    fn course_rate_is_zero_when_stopped_and_lag_saturates() {
        let mut d = InputDeriver::new(InputDerivationConfig {
            alignment: DifferenceAlignment::Forward,
            low_pass: LowPass::FirstOrderLag {
                time_constant_s: 0.5,
                max_accel_mps2: 0.2,
                max_course_rate_radps: 0.1,
            },
            min_speed_for_course_mps: 0.3,
        })
        .unwrap();
        d.push(0.0, 0.1, 0.0);
        let u = d.push(0.2, 0.1, 3.0).unwrap();
        assert_eq!(u.course_rate_radps, 0.0);
        let u = d.push(0.4, 5.0, 3.0).unwrap();
        assert_eq!(u.accel_mps2, 0.2, "saturated");
        assert!(
            InputDeriver::new(InputDerivationConfig {
                low_pass: LowPass::Butterworth {
                    order: 5,
                    cutoff_hz: 3.0,
                    sample_rate_hz: 5.0
                },
                ..InputDerivationConfig::thesis()
            })
            .is_err()
        );
    }
}
