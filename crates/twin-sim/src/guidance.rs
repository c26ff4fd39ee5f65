//! Way-point guidance: line-of-sight (LOS) steering along the straight legs
//! between way-points, as in the Otter's way-point mode.
//!
//! On the leg from way-point `k` to `k + 1` with direction `pi_k`, the
//! cross-track error `e` (positive when the craft is to starboard of the leg)
//! and a lookahead distance `Delta` give the desired heading
//!
//! ```text
//! psi_d = pi_k - atan((e + kappa y_int) / Delta)
//! y_int' = Delta e / (Delta^2 + (e + kappa y_int)^2)
//! ```
//!
//! With `kappa = 0` this is plain LOS; `kappa > 0` is integral LOS (Borhaug,
//! Pavlov and Pettersen 2008), whose integral learns the crab angle a cross
//! current needs, so the cross-track error goes to zero. The integral restarts
//! on each leg, because the crab angle depends on the leg's direction.
//!
//! The next way-point becomes active when the craft is inside its circle of
//! acceptance, or (a guard against circling a missed way-point) when the
//! along-track distance passes the leg's end. After the last way-point the
//! craft keeps following the extension of the last leg.

/// A way-point that became the one behind the craft.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WaypointPass {
    /// Index of the way-point in the scenario's list.
    pub index: usize,
    /// Elapsed simulation time, s.
    pub elapsed_s: f64,
    /// Distance from the craft to the way-point at that moment, m.
    pub distance_m: f64,
    /// True if the craft was inside the circle of acceptance; false if it
    /// was switched because it had passed the leg's end.
    pub within_acceptance: bool,
}

/// What the guidance asks for, and where the craft is relative to the leg.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct LosOutput {
    /// Desired heading, rad.
    pub heading_cmd_rad: f64,
    /// Cross-track error, m, positive to starboard of the leg.
    pub cross_track_m: f64,
    /// Index of the way-point the active leg starts from.
    pub leg: usize,
}

/// LOS guidance through a list of way-points (north, east in metres).
#[derive(Debug, Clone)]
pub(crate) struct LineOfSight {
    waypoints: Vec<[f64; 2]>,
    lookahead_m: f64,
    acceptance_radius_m: f64,
    integral_gain: f64,
    leg: usize,
    drift_integral_m: f64,
    finished: bool,
}

impl LineOfSight {
    /// Guidance along `waypoints` (at least two, consecutive ones distinct).
    pub fn new(
        waypoints: Vec<[f64; 2]>,
        lookahead_m: f64,
        acceptance_radius_m: f64,
        integral_gain: f64,
    ) -> Self {
        Self {
            waypoints,
            lookahead_m,
            acceptance_radius_m,
            integral_gain,
            leg: 0,
            drift_integral_m: 0.0,
            finished: false,
        }
    }

    /// Direction of the leg from way-point `k` to `k + 1`, rad.
    pub fn leg_direction_rad(&self, k: usize) -> f64 {
        let [n0, e0] = self.waypoints[k];
        let [n1, e1] = self.waypoints[k + 1];
        (e1 - e0).atan2(n1 - n0)
    }

    /// Along-track and cross-track position of (north, east) on leg `k`, m.
    fn leg_coordinates(&self, k: usize, north_m: f64, east_m: f64) -> (f64, f64, f64) {
        let [n0, e0] = self.waypoints[k];
        let [n1, e1] = self.waypoints[k + 1];
        let length = (n1 - n0).hypot(e1 - e0);
        let (s, c) = self.leg_direction_rad(k).sin_cos();
        let (dn, de) = (north_m - n0, east_m - e0);
        let along = dn * c + de * s;
        let cross = -dn * s + de * c;
        (along, cross, length)
    }

    /// Index of the way-point the active leg starts from.
    pub fn leg(&self) -> usize {
        self.leg
    }

    /// Cross-track error of (north, east) from the active leg, m, positive
    /// to starboard of the leg.
    pub fn cross_track_m(&self, north_m: f64, east_m: f64) -> f64 {
        self.leg_coordinates(self.leg, north_m, east_m).1
    }

    /// Advances the active leg if the craft has reached its end, recording
    /// each way-point passed, then computes the desired heading. `dt_s` is
    /// the time since the last call (for the drift integral).
    pub fn update(
        &mut self,
        elapsed_s: f64,
        north_m: f64,
        east_m: f64,
        dt_s: f64,
        passes: &mut Vec<WaypointPass>,
    ) -> LosOutput {
        let last_leg = self.waypoints.len() - 2;
        loop {
            if self.finished {
                break;
            }
            let [nt, et] = self.waypoints[self.leg + 1];
            let distance = (north_m - nt).hypot(east_m - et);
            let (along, _, length) = self.leg_coordinates(self.leg, north_m, east_m);
            let inside = distance <= self.acceptance_radius_m;
            if !(inside || along >= length) {
                break;
            }
            passes.push(WaypointPass {
                index: self.leg + 1,
                elapsed_s,
                distance_m: distance,
                within_acceptance: inside,
            });
            if self.leg == last_leg {
                self.finished = true;
            } else {
                self.leg += 1;
                self.drift_integral_m = 0.0;
            }
        }

        let (_, cross, _) = self.leg_coordinates(self.leg, north_m, east_m);
        let delta = self.lookahead_m;
        let shifted = cross + self.integral_gain * self.drift_integral_m;
        if self.integral_gain > 0.0 {
            self.drift_integral_m += dt_s * delta * cross / (delta * delta + shifted * shifted);
        }
        LosOutput {
            heading_cmd_rad: self.leg_direction_rad(self.leg) - (shifted / delta).atan(),
            cross_track_m: cross,
            leg: self.leg,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steers_back_toward_the_leg() {
        // Leg due north; craft 5 m east of it: steer west of north.
        let mut los = LineOfSight::new(vec![[0.0, 0.0], [100.0, 0.0]], 5.0, 3.0, 0.0);
        let mut passes = Vec::new();
        let out = los.update(0.0, 10.0, 5.0, 0.1, &mut passes);
        assert!((out.cross_track_m - 5.0).abs() < 1e-12);
        assert!((out.heading_cmd_rad + std::f64::consts::FRAC_PI_4).abs() < 1e-12);
        let out = los.update(0.0, 10.0, -5.0, 0.1, &mut passes);
        assert!((out.heading_cmd_rad - std::f64::consts::FRAC_PI_4).abs() < 1e-12);
        assert!(passes.is_empty());
    }

    #[test]
    fn switches_inside_the_circle_and_after_passing_the_leg_end() {
        let wps = vec![[0.0, 0.0], [50.0, 0.0], [50.0, 50.0], [0.0, 50.0]];
        let mut los = LineOfSight::new(wps, 5.0, 3.0, 0.0);
        let mut passes = Vec::new();
        let out = los.update(1.0, 48.0, 0.5, 0.1, &mut passes);
        assert_eq!(out.leg, 1);
        assert_eq!(passes.len(), 1);
        assert!(passes[0].within_acceptance && passes[0].index == 1);
        // Missed the second way-point's circle but went past the leg's end.
        let out = los.update(2.0, 44.0, 55.0, 0.1, &mut passes);
        assert_eq!(out.leg, 2);
        assert!(!passes[1].within_acceptance);
        // The last way-point: the leg stays, the pass is recorded once.
        los.update(3.0, 1.0, 50.0, 0.1, &mut passes);
        los.update(4.0, -5.0, 50.0, 0.1, &mut passes);
        assert_eq!(passes.len(), 3);
        assert_eq!(passes[2].index, 3);
    }

    #[test]
    fn integral_los_shifts_the_heading_against_a_steady_offset() {
        let mut los = LineOfSight::new(vec![[0.0, 0.0], [1000.0, 0.0]], 5.0, 3.0, 0.1);
        let mut passes = Vec::new();
        let first = los.update(0.0, 0.0, 1.0, 0.1, &mut passes).heading_cmd_rad;
        let mut later = first;
        for _ in 0..100 {
            later = los.update(0.0, 0.0, 1.0, 0.1, &mut passes).heading_cmd_rad;
        }
        assert!(later < first, "{later} vs {first}");
    }
}
