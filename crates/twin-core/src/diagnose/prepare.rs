//! The log on one time line, in the local frame, ready for the filters.

use crate::estimator::{LocalFix, ShaftAccumulator};
use crate::geodesy::{LocalFrame, NorthEast, wrap_pi};
use crate::sample::{GnssFix, PropellerSpeeds};

/// One measurement of the log.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DiagEvent {
    /// A GNSS fix (with course, speed and heading where the log has them).
    Fix(GnssFix),
    /// Course, speed, heading and yaw rate at an instant of a log without
    /// positions (its position is not read). Used only when the log has no
    /// [`DiagEvent::Fix`]: the velocities alone are then diagnosed.
    Velocity(GnssFix),
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

impl DiagEvent {
    /// Its time, s.
    pub fn time_s(&self) -> f64 {
        match self {
            DiagEvent::Fix(f) | DiagEvent::Velocity(f) => f.time_s,
            DiagEvent::SpeedThroughWater { time_s, .. } => *time_s,
            DiagEvent::Propellers(p) => p.time_s,
        }
    }
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
    /// The local frame (origin at the first fix); `None` when the log has
    /// no positions.
    pub frame: Option<LocalFrame>,
    /// The steps, in time order, strictly increasing times.
    pub steps: Vec<Step>,
    /// Whether the steps have measured positions: false for a log without
    /// position records, whose steps are its course/speed instants.
    pub has_position: bool,
    /// Whether the log has propeller speeds for most of its fixes.
    pub has_propellers: bool,
    /// Whether the log has heading for most of its fixes.
    pub has_heading: bool,
    /// Whether the log has speed through water for most of its fixes.
    pub has_stw: bool,
    /// Whether the log has a yaw rate (a rate gyro, a rate of turn) for
    /// most of its fixes.
    pub has_yaw_rate: bool,
    /// Fixes dropped: not finite, out of range, or not after the previous one.
    pub dropped: usize,
    /// The mean speed over ground of the fixes at [`UNDER_WAY_MPS`] or
    /// faster ([`UNDER_WAY_MPS`] where there are none), m/s: the speed at
    /// which a sideslip that grows with speed is reported.
    pub under_way_speed_mps: f64,
}

/// The speed over ground from which a vessel counts as under way, m/s.
pub const UNDER_WAY_MPS: f64 = 0.3;

/// The speed through water nearest a time, within half a second: a cursor
/// over the time-ordered speeds.
struct StwJoin {
    stw: Vec<(f64, f64)>,
    i: usize,
}

impl StwJoin {
    fn new(events: &[DiagEvent]) -> Self {
        let stw = events
            .iter()
            .filter_map(|e| match e {
                DiagEvent::SpeedThroughWater { time_s, mps } if mps.is_finite() && *mps >= 0.0 => {
                    Some((*time_s, *mps))
                }
                _ => None,
            })
            .collect();
        Self { stw, i: 0 }
    }

    /// The speed nearest `time_s` (times asked in increasing order).
    fn near(&mut self, time_s: f64) -> Option<f64> {
        let stw = &self.stw;
        while self.i + 1 < stw.len() && stw[self.i + 1].0 <= time_s {
            self.i += 1;
        }
        [self.i, self.i + 1]
            .iter()
            .filter_map(|i| stw.get(*i))
            .filter(|(t, _)| (t - time_s).abs() <= 0.5)
            .min_by(|a, b| (a.0 - time_s).abs().total_cmp(&(b.0 - time_s).abs()))
            .map(|(_, v)| *v)
    }
}

/// Puts the events (any order) on one time line. A log without any
/// [`DiagEvent::Fix`] is put on the time line of its
/// [`DiagEvent::Velocity`] instants, positions not measured.
pub fn prepare(events: &[DiagEvent]) -> Option<Prepared> {
    let mut events: Vec<DiagEvent> = events.to_vec();
    events.sort_by(|a, b| a.time_s().total_cmp(&b.time_s()));
    let has_position = events.iter().any(|e| matches!(e, DiagEvent::Fix(_)));
    let mut stw = StwJoin::new(&events);
    let mut frame: Option<LocalFrame> = None;
    let mut steps: Vec<Step> = Vec::new();
    let mut dropped = 0;
    let mut shafts = ShaftAccumulator::default();
    for e in &events {
        let (f, position) = match e {
            DiagEvent::Propellers(p) => {
                if p.port_radps.is_finite() && p.starboard_radps.is_finite() {
                    shafts.push(p);
                }
                continue;
            }
            DiagEvent::SpeedThroughWater { .. } => continue,
            DiagEvent::Velocity(_) if has_position => continue,
            DiagEvent::Velocity(f) => (f, None),
            DiagEvent::Fix(f) => (f, Some(f.position)),
        };
        let ok = f.time_s.is_finite()
            && position.is_none_or(|p| p.is_valid() && p.lat_deg.abs() < 89.0)
            && steps.last().is_none_or(|s| f.time_s > s.fix.time_s);
        if !ok {
            dropped += 1;
            continue;
        }
        let local = position.map(|p| {
            frame
                .get_or_insert_with(|| LocalFrame::new(p).expect("a valid position"))
                .to_local(p)
        });
        let samples = shafts.count();
        let mean = shafts.take(f.time_s, 0.0);
        steps.push(Step {
            fix: LocalFix {
                time_s: f.time_s,
                position: local.unwrap_or(NorthEast {
                    north_m: 0.0,
                    east_m: 0.0,
                }),
                position_measured: local.is_some(),
                sog_mps: f.sog_mps.filter(|v| v.is_finite() && *v >= 0.0),
                cog_rad: f.cog_rad.filter(|v| v.is_finite()).map(wrap_pi),
                heading_rad: f.heading_rad.filter(|v| v.is_finite()).map(wrap_pi),
                yaw_rate_radps: f.yaw_rate_radps.filter(|v| v.is_finite()),
                stw_mps: stw.near(f.time_s),
            },
            shafts_radps: (samples > 0)
                .then_some(mean)
                .flatten()
                .map(|m| [m.port_radps, m.starboard_radps]),
        });
    }
    let n = steps.len();
    if n < 10 {
        return None;
    }
    let most = |k: usize| k * 2 > n;
    let under_way: Vec<f64> = steps
        .iter()
        .filter_map(|s| s.fix.sog_mps)
        .filter(|v| *v >= UNDER_WAY_MPS)
        .collect();
    let under_way_speed_mps = if under_way.is_empty() {
        UNDER_WAY_MPS
    } else {
        under_way.iter().sum::<f64>() / under_way.len() as f64
    };
    Some(Prepared {
        frame,
        has_position,
        has_propellers: most(steps.iter().filter(|s| s.shafts_radps.is_some()).count()),
        has_heading: most(steps.iter().filter(|s| s.fix.heading_rad.is_some()).count()),
        has_stw: most(steps.iter().filter(|s| s.fix.stw_mps.is_some()).count()),
        has_yaw_rate: most(
            steps
                .iter()
                .filter(|s| s.fix.yaw_rate_radps.is_some())
                .count(),
        ),
        steps,
        dropped,
        under_way_speed_mps,
    })
}
