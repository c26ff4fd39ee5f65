//! The log on one time line, in the local frame, ready for the filters.

use crate::estimator::{LocalFix, ShaftAccumulator};
use crate::geodesy::{LocalFrame, wrap_pi};
use crate::sample::{GnssFix, PropellerSpeeds};

/// One measurement of the log.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DiagEvent {
    /// A GNSS fix (with course, speed and heading where the log has them).
    Fix(GnssFix),
    /// Speed through water from a log (paddle wheel), m/s.
    SpeedThroughWater {
        /// Time, s.
        time_s: f64,
        /// Speed, m/s.
        mps: f64,
    },
    /// Propeller shaft speeds.
    Propellers(PropellerSpeeds),
}

/// One filter step: a fix with everything measured near it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    /// The fix, with the speed through water measured within half a second
    /// of it (the estimator bases mask its course below their gate's speed).
    pub fix: LocalFix,
    /// Mean propeller speeds over the interval ending at this fix
    /// `[port, starboard]`, rad/s.
    pub shafts_radps: Option<[f64; 2]>,
}

/// The prepared log.
#[derive(Debug, Clone, PartialEq)]
pub struct Prepared {
    /// The local frame (origin at the first fix).
    pub frame: LocalFrame,
    /// The steps, in time order, strictly increasing times.
    pub steps: Vec<Step>,
    /// Whether the log has propeller speeds for most of its fixes.
    pub has_propellers: bool,
    /// Whether the log has heading for most of its fixes.
    pub has_heading: bool,
    /// Whether the log has speed through water for most of its fixes.
    pub has_stw: bool,
    /// Fixes dropped: not finite, out of range, or not after the previous one.
    pub dropped: usize,
}

/// Puts the events (any order) on one time line.
pub fn prepare(events: &[DiagEvent]) -> Option<Prepared> {
    let mut events: Vec<DiagEvent> = events.to_vec();
    let time = |e: &DiagEvent| match e {
        DiagEvent::Fix(f) => f.time_s,
        DiagEvent::SpeedThroughWater { time_s, .. } => *time_s,
        DiagEvent::Propellers(p) => p.time_s,
    };
    events.sort_by(|a, b| time(a).total_cmp(&time(b)));
    let stw: Vec<(f64, f64)> = events
        .iter()
        .filter_map(|e| match e {
            DiagEvent::SpeedThroughWater { time_s, mps } if mps.is_finite() && *mps >= 0.0 => {
                Some((*time_s, *mps))
            }
            _ => None,
        })
        .collect();
    let mut frame: Option<LocalFrame> = None;
    let mut steps: Vec<Step> = Vec::new();
    let mut dropped = 0;
    let mut shafts = ShaftAccumulator::default();
    let mut stw_i = 0usize;
    for e in &events {
        match e {
            DiagEvent::Propellers(p) => {
                if p.port_radps.is_finite() && p.starboard_radps.is_finite() {
                    shafts.push(p);
                }
            }
            DiagEvent::SpeedThroughWater { .. } => {}
            DiagEvent::Fix(f) => {
                let ok = f.time_s.is_finite()
                    && f.position.is_valid()
                    && f.position.lat_deg.abs() < 89.0
                    && steps.last().is_none_or(|s| f.time_s > s.fix.time_s);
                if !ok {
                    dropped += 1;
                    continue;
                }
                let frame = *frame
                    .get_or_insert_with(|| LocalFrame::new(f.position).expect("a valid position"));
                let sog = f.sog_mps.filter(|v| v.is_finite() && *v >= 0.0);
                let cog = f.cog_rad.filter(|v| v.is_finite()).map(wrap_pi);
                while stw_i + 1 < stw.len() && stw[stw_i + 1].0 <= f.time_s {
                    stw_i += 1;
                }
                let near_stw = [stw_i, stw_i + 1]
                    .iter()
                    .filter_map(|i| stw.get(*i))
                    .filter(|(t, _)| (t - f.time_s).abs() <= 0.5)
                    .min_by(|a, b| (a.0 - f.time_s).abs().total_cmp(&(b.0 - f.time_s).abs()))
                    .map(|(_, v)| *v);
                let samples = shafts.count();
                let mean = shafts.take(f.time_s, 0.0);
                steps.push(Step {
                    fix: LocalFix {
                        time_s: f.time_s,
                        position: frame.to_local(f.position),
                        sog_mps: sog,
                        cog_rad: cog,
                        heading_rad: f.heading_rad.filter(|v| v.is_finite()).map(wrap_pi),
                        stw_mps: near_stw,
                    },
                    shafts_radps: (samples > 0)
                        .then_some(mean)
                        .flatten()
                        .map(|m| [m.port_radps, m.starboard_radps]),
                });
            }
        }
    }
    let n = steps.len();
    if n < 10 {
        return None;
    }
    let most = |k: usize| k * 2 > n;
    Some(Prepared {
        frame: frame?,
        has_propellers: most(steps.iter().filter(|s| s.shafts_radps.is_some()).count()),
        has_heading: most(steps.iter().filter(|s| s.fix.heading_rad.is_some()).count()),
        has_stw: most(steps.iter().filter(|s| s.fix.stw_mps.is_some()).count()),
        steps,
        dropped,
    })
}
