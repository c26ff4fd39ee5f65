//! How well an estimator's model explains a log: innovation statistics in
//! constant memory, and the chi-square consistency test of the normalised
//! innovation squared (NIS).
//!
//! For a consistent filter each step's NIS is chi-square distributed with
//! as many degrees of freedom as measured components, so over a run:
//! - the mean NIS per degree of freedom, `sum NIS / sum dof`, is near 1; the
//!   two-sided 95 % band for it is `[chi2_0.025(D), chi2_0.975(D)] / D` with
//!   `D = sum dof` (Bar-Shalom, Li, Kirubarajan 2001, section 5.4), which
//!   narrows as the run grows: a long log must fit its noise model well;
//! - about 5 % of the steps exceed their own 95 % quantile `chi2_0.95(dof)`.
//!
//! Quantiles: exact values for 1-5 degrees of freedom, the Wilson-Hilferty
//! approximation above (within 1 % from 6 on).

use serde::Serialize;

/// The standard normal quantile at 0.975.
const Z_0975: f64 = 1.959_963_984_540_054;
/// The standard normal quantile at 0.95.
const Z_095: f64 = 1.644_853_626_951_472_6;

/// Chi-square quantiles for 1-5 degrees of freedom at 0.025, 0.95, 0.975.
const CHI2_TABLE: [[f64; 3]; 5] = [
    [0.000_982_069, 3.841_459, 5.023_886],
    [0.050_635_62, 5.991_465, 7.377_759],
    [0.215_795_3, 7.814_728, 9.348_404],
    [0.484_418_6, 9.487_729, 11.143_287],
    [0.831_211_6, 11.070_498, 12.832_502],
];

/// Which quantile of the chi-square distribution.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quantile {
    /// 2.5 %.
    P025,
    /// 95 %.
    P95,
    /// 97.5 %.
    P975,
}

/// The chi-square quantile with `dof` degrees of freedom (`dof` >= 1).
pub fn chi2_quantile(dof: u64, q: Quantile) -> f64 {
    let column = match q {
        Quantile::P025 => 0,
        Quantile::P95 => 1,
        Quantile::P975 => 2,
    };
    if (1..=5).contains(&dof) {
        return CHI2_TABLE[dof as usize - 1][column];
    }
    let z = match q {
        Quantile::P025 => -Z_0975,
        Quantile::P95 => Z_095,
        Quantile::P975 => Z_0975,
    };
    let k = dof.max(1) as f64;
    let a = 2.0 / (9.0 * k);
    k * (1.0 - a + z * a.sqrt()).powi(3).max(0.0)
}

/// The names of the innovation components, in [`twin_core::twin::StepOutput`]
/// order.
pub const COMPONENTS: [&str; 6] = [
    "north_m",
    "east_m",
    "sog_mps",
    "cog_rad",
    "heading_rad",
    "yaw_rate_radps",
];

/// Running innovation and NIS statistics of one estimator.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct QualityAccumulator {
    steps: u64,
    sum_sq: [f64; 6],
    count: [u64; 6],
    sum_nis: f64,
    sum_dof: u64,
    above_95: u64,
    max_nis_per_dof: f64,
}

impl QualityAccumulator {
    /// Takes one step's innovation (components marked available), its NIS
    /// and degrees of freedom.
    pub fn push(&mut self, innovation: &[f64; 6], available: &[bool; 6], nis: f64, dof: usize) {
        if dof == 0 || !nis.is_finite() {
            return;
        }
        self.steps += 1;
        for i in 0..6 {
            if available[i] && innovation[i].is_finite() {
                self.sum_sq[i] += innovation[i] * innovation[i];
                self.count[i] += 1;
            }
        }
        self.sum_nis += nis;
        self.sum_dof += dof as u64;
        if nis > chi2_quantile(dof as u64, Quantile::P95) {
            self.above_95 += 1;
        }
        self.max_nis_per_dof = self.max_nis_per_dof.max(nis / dof as f64);
    }

    /// Steps taken into account.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// The summary, `None` with no step.
    pub fn summary(&self) -> Option<Quality> {
        if self.steps == 0 {
            return None;
        }
        let rms =
            |i: usize| (self.count[i] > 0).then(|| (self.sum_sq[i] / self.count[i] as f64).sqrt());
        let d = self.sum_dof;
        let band = [
            chi2_quantile(d, Quantile::P025) / d as f64,
            chi2_quantile(d, Quantile::P975) / d as f64,
        ];
        let per_dof = self.sum_nis / d as f64;
        let position = match (rms(0), rms(1)) {
            (Some(n), Some(e)) => Some((n * n + e * e).sqrt()),
            _ => None,
        };
        Some(Quality {
            steps: self.steps,
            innovation_rms: InnovationRms {
                north_m: rms(0),
                east_m: rms(1),
                position_m: position,
                sog_mps: rms(2),
                cog_rad: rms(3),
                heading_rad: rms(4),
                yaw_rate_radps: rms(5),
            },
            measured: self.count,
            mean_nis: self.sum_nis / self.steps as f64,
            mean_dof: d as f64 / self.steps as f64,
            mean_nis_per_dof: per_dof,
            nis_band_95: band,
            nis_within_band: (band[0]..=band[1]).contains(&per_dof),
            fraction_above_95: self.above_95 as f64 / self.steps as f64,
            max_nis_per_dof: self.max_nis_per_dof,
        })
    }
}

/// Root-mean-square innovation per component (`null` when never measured).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct InnovationRms {
    /// North, m.
    pub north_m: Option<f64>,
    /// East, m.
    pub east_m: Option<f64>,
    /// Horizontal position, `sqrt(north^2 + east^2)`, m.
    pub position_m: Option<f64>,
    /// Speed over ground, m/s.
    pub sog_mps: Option<f64>,
    /// Course over ground, rad.
    pub cog_rad: Option<f64>,
    /// Heading, rad.
    pub heading_rad: Option<f64>,
    /// Yaw rate, rad/s.
    pub yaw_rate_radps: Option<f64>,
}

/// The consistency of one estimator over a log.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Quality {
    /// Filter steps judged (initialisations are not steps).
    pub steps: u64,
    /// Innovation RMS per component.
    pub innovation_rms: InnovationRms,
    /// Steps in which each component (`north`, `east`, `sog`, `cog`,
    /// `heading`) was measured.
    pub measured: [u64; 6],
    /// Mean NIS per step.
    pub mean_nis: f64,
    /// Mean degrees of freedom per step.
    pub mean_dof: f64,
    /// `sum NIS / sum dof`: 1 for a consistent filter.
    pub mean_nis_per_dof: f64,
    /// The two-sided 95 % band of `mean_nis_per_dof` for a consistent filter.
    pub nis_band_95: [f64; 2],
    /// Whether `mean_nis_per_dof` lies in the band.
    pub nis_within_band: bool,
    /// Fraction of steps whose NIS exceeds its 95 % quantile (0.05 expected).
    pub fraction_above_95: f64,
    /// The largest single-step NIS per degree of freedom.
    pub max_nis_per_dof: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_match_tables() {
        // Exact for small dof; Wilson-Hilferty within 1 % beyond.
        assert_eq!(chi2_quantile(2, Quantile::P95), 5.991_465);
        let exact_10 = [3.246_973, 18.307_038, 20.483_177];
        for (q, exact) in [Quantile::P025, Quantile::P95, Quantile::P975]
            .into_iter()
            .zip(exact_10)
        {
            let wh = chi2_quantile(10, q);
            assert!((wh - exact).abs() / exact < 0.01, "{q:?}: {wh} vs {exact}");
        }
        // dof 1000, 97.5 %: 1089.531.
        assert!((chi2_quantile(1000, Quantile::P975) - 1089.531).abs() < 0.1);
    }

    #[test]
    fn a_consistent_filter_is_in_the_band() {
        // Innovations of a filter that matches its noise: NIS per dof = 1
        // on average; deterministic "noise" with the right second moment.
        let mut acc = QualityAccumulator::default();
        for k in 0..4000 {
            let z = [1.0, -1.0, 1.0, -1.0][k % 4];
            let nis = 2.0 * (1.0 + 0.3 * z);
            acc.push(
                &[0.3 * z, -0.3 * z, 0.0, 0.0, 0.0, 0.0],
                &[true, true, false, false, false, false],
                nis,
                2,
            );
        }
        let q = acc.summary().unwrap();
        assert!((q.mean_nis_per_dof - 1.0).abs() < 1e-12);
        assert!(q.nis_within_band);
        assert!((q.innovation_rms.north_m.unwrap() - 0.3).abs() < 1e-12);
        assert_eq!(q.innovation_rms.sog_mps, None);
        assert_eq!(q.measured, [4000, 4000, 0, 0, 0, 0]);
        assert!(q.nis_band_95[0] < 1.0 && q.nis_band_95[1] > 1.0);
        // Twice the NIS is far outside for so many steps.
        let mut bad = QualityAccumulator::default();
        for _ in 0..4000 {
            bad.push(&[0.0; 6], &[true; 6], 10.0, 5);
        }
        assert!(!bad.summary().unwrap().nis_within_band);
        assert_eq!(QualityAccumulator::default().summary(), None);
    }
}
