//! What the hidden-effect tests on vessels unlike their profile share,
//! whichever simulator runs them: the change of the vessel drawn beside
//! the hidden effect (one of its surge damping, yaw damping or mass with
//! its added mass, by a factor of 1 ± U(0.2, 0.3)), and the bars on the
//! model-parameter findings (only the parameter changed, in its direction,
//! its size within 30 %; none on an unchanged vessel).

use rand::Rng;
use rand::rngs::StdRng;
use twin_cli::diagnose::DiagnoseReport;

use super::hidden::{Hidden, describe, judge};

/// The causes that are the vessel's own parameters.
const MODEL_CAUSES: [&str; 3] = ["surge_damping", "yaw_damping", "mass"];

/// The vessel's change in a draw: which model cause it is, and its factor.
#[derive(Debug, Clone, Copy)]
pub struct Perturbation {
    pub cause: &'static str,
    pub scale: f64,
}

/// One change of the vessel, of a random parameter, size and direction.
pub fn draw_perturbation(rng: &mut StdRng) -> Perturbation {
    let cause = MODEL_CAUSES[rng.random_range(0..3)];
    let size = rng.random_range(0.2..0.3);
    let scale = if rng.random_bool(0.5) {
        1.0 + size
    } else {
        1.0 - size
    };
    Perturbation { cause, scale }
}

/// `p` as the draw's listing shows it.
fn describe_vessel(p: Option<Perturbation>) -> String {
    p.map_or("the profile's vessel".to_string(), |p| {
        format!("{} x {:.2}", p.cause, p.scale)
    })
}

/// Judges the model-parameter findings against the perturbation; `Ok`
/// says whether the perturbation was named.
fn judge_model(p: Option<Perturbation>, r: &DiagnoseReport) -> Result<bool, String> {
    let mut named = false;
    for f in r
        .findings
        .iter()
        .filter(|f| MODEL_CAUSES.contains(&f.cause.as_str()))
    {
        let scale = f.parameters["scale"].as_f64().unwrap_or(f64::NAN);
        let Some(p) = p.filter(|p| p.cause == f.cause) else {
            return Err(format!("{} {scale:.3} named, not planted", f.cause));
        };
        let (got, want) = (scale - 1.0, p.scale - 1.0);
        if got.signum() != want.signum() || (got - want).abs() > 0.3 * want.abs() {
            return Err(format!("{} {scale:.3}, planted {:.3}", f.cause, p.scale));
        }
        named = true;
    }
    Ok(named)
}

/// The report without its model-parameter findings (judged apart).
fn without_model_causes(r: &DiagnoseReport) -> DiagnoseReport {
    let mut others = r.clone();
    others
        .findings
        .retain(|f| !MODEL_CAUSES.contains(&f.cause.as_str()));
    others
}

/// Judges a diagnosis of hidden effect `h` on a vessel changed by `p`
/// (none: the control): the effect by the hidden-effect bars, the
/// model-parameter findings by [`judge_model`]; `Ok` says whether the
/// change was named.
pub fn judge_on_vessel(
    h: Hidden,
    p: Option<Perturbation>,
    r: &DiagnoseReport,
) -> Result<bool, String> {
    judge(h, &without_model_causes(r)).and_then(|()| judge_model(p, r))
}

/// One draw on a possibly changed vessel: its index, effect, change,
/// verdict (`Ok`: whether the change was named) and what was named.
pub type Outcome = (
    usize,
    Hidden,
    Option<Perturbation>,
    Result<bool, String>,
    String,
);

/// The draws that miss the bars, by kind.
pub struct Misses {
    /// On the unchanged vessel.
    pub control: Vec<usize>,
    /// On a changed vessel.
    pub changed: Vec<usize>,
}

/// Prints each draw's verdict and a summary line starting with `label`;
/// the draws that miss the bars.
pub fn report(label: &str, results: &[Outcome]) -> Misses {
    let mut control_failures = Vec::new();
    let mut changed_failures = Vec::new();
    let (mut right, mut named_change) = (0, 0);
    for (i, h, p, verdict, summary) in results {
        println!(
            "draw {i:2}: {} on {} -> {summary}{}",
            describe(*h),
            describe_vessel(*p),
            match verdict {
                Ok(_) => String::new(),
                Err(e) => format!("   <-- misses the bars: {e}"),
            }
        );
        match (verdict, p) {
            (Ok(n), Some(_)) => {
                right += 1;
                named_change += usize::from(*n);
            }
            (Err(_), None) => control_failures.push(*i),
            (Err(_), Some(_)) => changed_failures.push(*i),
            (Ok(_), None) => {}
        }
    }
    let changed = results.iter().filter(|r| r.2.is_some()).count();
    println!(
        "{label}: control draws {} of {} meet the bars; draws on a changed vessel {right} of {changed} meet the bars, the change named in {named_change}",
        results.len() - changed - control_failures.len(),
        results.len() - changed,
    );
    Misses {
        control: control_failures,
        changed: changed_failures,
    }
}
