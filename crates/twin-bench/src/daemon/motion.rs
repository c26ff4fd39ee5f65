//! How the benchmark's fleet moves: every vessel is an Otter in a steady
//! turn at constant shaft speeds, each on its own circle (centres on a
//! 200 m grid) and at its own phase, so that the GNSS fixes and the shaft
//! speeds it publishes agree with each other as they would on the water.
//!
//! The steady turn is not made up: [`Circle::from_simulator`] runs the
//! project's Otter simulator (`twin-sim`, calm water) at constant shaft
//! speeds, picks the mean shaft speed that gives the wanted speed over ground
//! (bisection), and reads off the steady speed, yaw rate and drift angle.
//! The fleet then follows that circle analytically, with GNSS-like noise
//! added per fix.

use twin_core::geodesy::{LatLon, LocalFrame, NorthEast, wrap_two_pi};
use twin_core::sample::{GnssFix, PropellerSpeeds, RADPS_PER_RPM};

use crate::rng::SplitMix64;

/// Port shaft speed over starboard shaft speed in the turn (a turn to
/// starboard).
const PORT_OVER_STARBOARD: f64 = 1.06;

/// The origin of the fleet's frame: off Alesund, where the seed's trials ran.
pub const ORIGIN: LatLon = LatLon {
    lat_deg: 62.47,
    lon_deg: 6.15,
};

/// A steady turn of the Otter at constant shaft speeds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Circle {
    /// Speed over ground, m/s.
    pub speed_mps: f64,
    /// Yaw rate (and rate of turn of the course), rad/s; positive to
    /// starboard.
    pub yaw_rate_radps: f64,
    /// Heading minus course over ground (minus the drift angle), rad.
    pub heading_minus_course_rad: f64,
    /// Shaft speeds, rpm: port, starboard.
    pub rpm: [f64; 2],
}

impl Circle {
    /// Radius of the circle, m.
    pub fn radius_m(&self) -> f64 {
        self.speed_mps / self.yaw_rate_radps.abs()
    }

    /// Simulates the Otter (calm water, no current) at constant shaft
    /// speeds with port/starboard = 1.06 and finds the mean shaft speed that
    /// gives `speed_mps` over ground in the steady turn.
    pub fn from_simulator(speed_mps: f64) -> anyhow::Result<Self> {
        anyhow::ensure!(
            speed_mps > 0.2 && speed_mps < 4.0,
            "a speed the Otter can hold"
        );
        let (mut lo, mut hi) = (100.0, 900.0);
        let mut best = steady_turn(0.5 * (lo + hi))?;
        for _ in 0..24 {
            let mid = 0.5 * (lo + hi);
            best = steady_turn(mid)?;
            if best.speed_mps < speed_mps {
                lo = mid;
            } else {
                hi = mid;
            }
            if (best.speed_mps - speed_mps).abs() < 1e-3 {
                break;
            }
        }
        anyhow::ensure!(
            (best.speed_mps - speed_mps).abs() < 0.05,
            "the simulated Otter does not reach {speed_mps} m/s (got {:.2})",
            best.speed_mps
        );
        Ok(best)
    }
}

/// The steady turn at mean shaft speed `mean_rpm`: 90 s simulated, the
/// last 30 s averaged.
fn steady_turn(mean_rpm: f64) -> anyhow::Result<Circle> {
    let starboard = 2.0 * mean_rpm / (1.0 + PORT_OVER_STARBOARD);
    let port = PORT_OVER_STARBOARD * starboard;
    let text = format!(
        "name = \"bench-steady-turn\"\n\
         duration_s = 90.0\n\
         [manual]\n\
         commands = [{{ time_s = 0.0, port_rpm = {port}, starboard_rpm = {starboard} }}]\n\
         [initial]\n\
         speed_mps = 1.0\n"
    );
    let scenario = twin_sim::Scenario::from_toml_str(&text)?;
    let run = twin_sim::simulate(&scenario)?;
    let last = run
        .truth
        .last()
        .ok_or_else(|| anyhow::anyhow!("the simulation gave no truth"))?;
    let tail: Vec<_> = run
        .truth
        .iter()
        .filter(|t| t.elapsed_s >= last.elapsed_s - 30.0)
        .collect();
    let n = tail.len().max(1) as f64;
    let speed_mps = tail.iter().map(|t| t.sog_mps).sum::<f64>() / n;
    let yaw_rate_radps = tail.iter().map(|t| t.r_radps).sum::<f64>() / n;
    let drift = tail
        .iter()
        .map(|t| twin_core::geodesy::wrap_pi(t.heading_rad - t.cog_rad))
        .sum::<f64>()
        / n;
    Ok(Circle {
        speed_mps,
        yaw_rate_radps,
        heading_minus_course_rad: drift,
        rpm: [port, starboard],
    })
}

/// The fleet: `n` vessels on copies of one circle.
#[derive(Debug, Clone)]
pub struct Fleet {
    circle: Circle,
    frame: LocalFrame,
    n: usize,
}

/// GNSS noise of the published fixes (one sigma), as the simulator's
/// default receiver.
const POSITION_SIGMA_M: f64 = 0.3;
const SOG_SIGMA_MPS: f64 = 0.05;
const COG_SIGMA_RAD: f64 = 0.02;
const HEADING_SIGMA_RAD: f64 = 0.5 * std::f64::consts::PI / 180.0;
const RPM_SIGMA: f64 = 2.0;
/// Grid spacing of the circles' centres, m.
const SPACING_M: f64 = 200.0;

impl Fleet {
    /// `n` vessels on `circle`.
    pub fn new(circle: Circle, n: usize) -> anyhow::Result<Self> {
        Ok(Self {
            circle,
            frame: LocalFrame::new(ORIGIN)?,
            n: n.max(1),
        })
    }

    /// The circle every vessel follows.
    pub fn circle(&self) -> &Circle {
        &self.circle
    }

    /// Vessel `v`'s fix at `time_s` (Unix time), `elapsed_s` after the start,
    /// with noise drawn from `rng`.
    pub fn fix(&self, v: usize, time_s: f64, elapsed_s: f64, rng: &mut SplitMix64) -> GnssFix {
        let c = &self.circle;
        let side = (self.n as f64).sqrt().ceil() as usize;
        let centre_n = (v / side) as f64 * SPACING_M;
        let centre_e = (v % side) as f64 * SPACING_M;
        // Course chi(t) = phase + r t; the position that moves at speed U
        // along chi on a circle of radius U / r about the centre.
        let phase = std::f64::consts::TAU * v as f64 / self.n as f64;
        let chi = phase + c.yaw_rate_radps * elapsed_s;
        let radius = c.speed_mps / c.yaw_rate_radps;
        let (s, co) = chi.sin_cos();
        let ne = NorthEast {
            north_m: centre_n + radius * s + POSITION_SIGMA_M * rng.normal(),
            east_m: centre_e - radius * co + POSITION_SIGMA_M * rng.normal(),
        };
        GnssFix {
            time_s,
            position: self.frame.to_geodetic(ne),
            sog_mps: Some((c.speed_mps + SOG_SIGMA_MPS * rng.normal()).max(0.0)),
            cog_rad: Some(wrap_two_pi(chi + COG_SIGMA_RAD * rng.normal())),
            heading_rad: Some(wrap_two_pi(
                chi + c.heading_minus_course_rad + HEADING_SIGMA_RAD * rng.normal(),
            )),
            yaw_rate_radps: None,
            hdop: Some(0.9),
        }
    }

    /// Vessel `v`'s measured shaft speeds at `time_s`.
    pub fn shafts(&self, time_s: f64, rng: &mut SplitMix64) -> PropellerSpeeds {
        let [port, starboard] = self.circle.rpm;
        PropellerSpeeds {
            time_s,
            port_radps: (port + RPM_SIGMA * rng.normal()) * RADPS_PER_RPM,
            starboard_radps: (starboard + RPM_SIGMA * rng.normal()) * RADPS_PER_RPM,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_simulated_otter_turns_steadily_at_the_wanted_speed() {
        let c = Circle::from_simulator(1.5).unwrap();
        assert!((c.speed_mps - 1.5).abs() < 0.01, "{c:?}");
        assert!(c.yaw_rate_radps > 0.0, "a turn to starboard: {c:?}");
        assert!(c.radius_m() > 5.0 && c.radius_m() < 500.0, "{c:?}");
        assert!(c.rpm[0] > c.rpm[1], "{c:?}");
    }

    #[test]
    fn consecutive_fixes_move_at_the_circle_speed() {
        let c = Circle {
            speed_mps: 1.5,
            yaw_rate_radps: 0.05,
            heading_minus_course_rad: 0.0,
            rpm: [600.0, 520.0],
        };
        let fleet = Fleet::new(c, 100).unwrap();
        let frame = LocalFrame::new(ORIGIN).unwrap();
        // Noise-free positions: a zero-sigma draw is not possible, so
        // average the noise out over many draws.
        let mut rng = SplitMix64::new(1);
        let mean = |t: f64, rng: &mut SplitMix64| {
            let (mut n, mut e) = (0.0, 0.0);
            for _ in 0..2000 {
                let p = frame.to_local(fleet.fix(7, 0.0, t, rng).position);
                n += p.north_m;
                e += p.east_m;
            }
            (n / 2000.0, e / 2000.0)
        };
        let a = mean(10.0, &mut rng);
        let b = mean(11.0, &mut rng);
        let d = ((a.0 - b.0).powi(2) + (a.1 - b.1).powi(2)).sqrt();
        assert!((d - 1.5).abs() < 0.05, "{d}");
    }
}
