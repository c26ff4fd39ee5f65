//! Residual analysis of one filter run: bias, whiteness, consistency and the
//! signatures the innovations follow.

/// One step's innovation, normalised per component by its predicted
/// standard deviation, with the signatures it may follow.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InnovationRecord {
    /// Time, s.
    pub time_s: f64,
    /// Innovation per measurement component (0 where missing), in the
    /// measurement's units.
    pub innovation: [f64; COMPONENT_COUNT],
    /// Its predicted standard deviation per component.
    pub sigma: [f64; COMPONENT_COUNT],
    /// Which components were measured.
    pub available: [bool; COMPONENT_COUNT],
    /// Normalised innovation squared of the step, and its degrees of freedom.
    pub nis: f64,
    /// Degrees of freedom of `nis`.
    pub dof: usize,
    /// Signatures at the step: `[sin heading, cos heading, speed m/s, yaw
    /// rate rad/s, acceleration m/s^2, elapsed time s]` (from the estimate).
    pub signatures: [f64; 6],
}

/// Names of the measurement components, in record order.
pub const COMPONENTS: [&str; COMPONENT_COUNT] =
    ["north", "east", "sog", "cog", "heading", "stw", "yaw_rate"];

/// Number of measurement components a record holds.
pub const COMPONENT_COUNT: usize = 7;
/// Names of the signatures, in record order.
pub const SIGNATURES: [&str; 6] = [
    "sin_heading",
    "cos_heading",
    "speed",
    "yaw_rate",
    "acceleration",
    "time",
];

/// A component's correlation with a signature.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SignatureCorrelation {
    /// Measurement component (see [`COMPONENTS`]).
    pub component: &'static str,
    /// Signature (see [`SIGNATURES`]).
    pub signature: &'static str,
    /// Pearson correlation of the normalised innovation with it.
    pub correlation: f64,
}

/// What the residuals of one run say.
#[derive(Debug, Clone, PartialEq)]
pub struct ResidualSummary {
    /// Steps summarised.
    pub steps: usize,
    /// Mean innovation per component (measurement units).
    pub mean: [f64; COMPONENT_COUNT],
    /// Mean normalised innovation per component, in standard errors of the
    /// mean (|z| > 3: a bias).
    pub bias_z: [f64; COMPONENT_COUNT],
    /// RMS innovation per component.
    pub rms: [f64; COMPONENT_COUNT],
    /// Lag-1 autocorrelation of the normalised innovation per component
    /// (white: near 0).
    pub lag1: [f64; COMPONENT_COUNT],
    /// Mean NIS per degree of freedom (consistent: near 1).
    pub nis_per_dof: f64,
    /// Which components were measured at all.
    pub measured: [bool; COMPONENT_COUNT],
    /// The strongest correlations with signatures, largest first.
    pub signatures: Vec<SignatureCorrelation>,
}

fn pearson(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len().min(y.len());
    if n < 3 {
        return 0.0;
    }
    let (mx, my) = (
        x.iter().sum::<f64>() / n as f64,
        y.iter().sum::<f64>() / n as f64,
    );
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for i in 0..n {
        sxy += (x[i] - mx) * (y[i] - my);
        sxx += (x[i] - mx).powi(2);
        syy += (y[i] - my).powi(2);
    }
    if sxx <= 0.0 || syy <= 0.0 {
        0.0
    } else {
        sxy / (sxx * syy).sqrt()
    }
}

/// Summarises records.
pub fn summarise(records: &[InnovationRecord]) -> ResidualSummary {
    let mut mean = [0.0; COMPONENT_COUNT];
    let mut bias_z = [0.0; COMPONENT_COUNT];
    let mut rms = [0.0; COMPONENT_COUNT];
    let mut lag1 = [0.0; COMPONENT_COUNT];
    let mut measured = [false; COMPONENT_COUNT];
    let mut signatures = Vec::new();
    for c in 0..COMPONENT_COUNT {
        let vals: Vec<(usize, f64, f64)> = records
            .iter()
            .enumerate()
            .filter(|(_, r)| r.available[c] && r.sigma[c] > 0.0)
            .map(|(i, r)| (i, r.innovation[c], r.innovation[c] / r.sigma[c]))
            .collect();
        if vals.len() < 10 {
            continue;
        }
        measured[c] = true;
        let n = vals.len() as f64;
        mean[c] = vals.iter().map(|v| v.1).sum::<f64>() / n;
        rms[c] = (vals.iter().map(|v| v.1 * v.1).sum::<f64>() / n).sqrt();
        let zs: Vec<f64> = vals.iter().map(|v| v.2).collect();
        let zmean = zs.iter().sum::<f64>() / n;
        let zvar = zs.iter().map(|z| (z - zmean).powi(2)).sum::<f64>() / n;
        // Standard error of the mean, inflated for serial correlation.
        let pairs: Vec<(f64, f64)> = vals
            .windows(2)
            .filter(|w| w[1].0 == w[0].0 + 1)
            .map(|w| (w[0].2, w[1].2))
            .collect();
        let (a, b): (Vec<f64>, Vec<f64>) = pairs.into_iter().unzip();
        lag1[c] = pearson(&a, &b);
        let rho = lag1[c].clamp(0.0, 0.95);
        let effective_n = n * (1.0 - rho) / (1.0 + rho);
        bias_z[c] = zmean / (zvar.max(1e-12) / effective_n.max(1.0)).sqrt();
        for (s, name) in SIGNATURES.iter().enumerate() {
            let sig: Vec<f64> = vals.iter().map(|v| records[v.0].signatures[s]).collect();
            let corr = pearson(&zs, &sig);
            if corr.is_finite() {
                signatures.push(SignatureCorrelation {
                    component: COMPONENTS[c],
                    signature: name,
                    correlation: corr,
                });
            }
        }
    }
    signatures.sort_by(|a, b| b.correlation.abs().total_cmp(&a.correlation.abs()));
    signatures.truncate(8);
    let dof: usize = records.iter().map(|r| r.dof).sum();
    let nis: f64 = records.iter().map(|r| r.nis).sum();
    ResidualSummary {
        steps: records.len(),
        mean,
        bias_z,
        rms,
        lag1,
        nis_per_dof: if dof > 0 { nis / dof as f64 } else { f64::NAN },
        measured,
        signatures,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_biased_correlated_component_is_seen() {
        let records: Vec<InnovationRecord> = (0..500)
            .map(|k| {
                let t = k as f64 * 0.2;
                let speed = 1.0 + (0.05 * t).sin();
                let noise = ((k * 7919) % 101) as f64 / 101.0 - 0.5;
                InnovationRecord {
                    time_s: t,
                    // SOG innovation grows with speed (a scale error), north is white.
                    innovation: [
                        noise * 0.3,
                        0.0,
                        0.05 * speed + 0.01 * noise,
                        0.0,
                        0.0,
                        0.0,
                        0.0,
                    ],
                    sigma: [0.3, 0.3, 0.05, 0.02, 0.01, 0.1, 0.01],
                    available: [true, false, true, false, false, false, false],
                    nis: 2.0,
                    dof: 2,
                    signatures: [0.0, 1.0, speed, 0.0, 0.0, t],
                }
            })
            .collect();
        let s = summarise(&records);
        // Serially correlated: the standard error is inflated, still a bias.
        assert!(
            s.bias_z[2] > 3.0 && s.lag1[2] > 0.9,
            "{:?} {:?}",
            s.bias_z,
            s.lag1
        );
        assert!(s.bias_z[0].abs() < 3.0, "{:?}", s.bias_z);
        assert!(!s.measured[1]);
        let top = s.signatures[0];
        assert_eq!((top.component, top.signature), ("sog", "speed"));
        assert!(top.correlation > 0.9);
        assert!((s.nis_per_dof - 1.0).abs() < 1e-12);
    }
}
