//! WGS-84 geodesy for the twin: latitude/longitude to a local flat-earth
//! North-East frame and back (docs/model.md section 2), and angle helpers.
//!
//! The flat-earth approximation is the one of Fossen's `llh2flat`: north uses
//! the meridian radius of curvature `R_M`, east uses the prime-vertical radius
//! `R_N` scaled by `cos(lat0)`. Both radii are evaluated once, at the origin, so
//! the map is linear in (lat, lon); errors grow with the square of the distance
//! from the origin (about 1 m at 10 km), far below GNSS noise over a trial.

use std::f64::consts::{PI, TAU};

/// WGS-84 semi-major (equatorial) axis, metres.
pub const WGS84_A_M: f64 = 6_378_137.0;
/// WGS-84 flattening.
pub const WGS84_F: f64 = 1.0 / 298.257_223_563;
/// WGS-84 first eccentricity squared, `e^2 = 2f - f^2`.
pub const WGS84_E2: f64 = 2.0 * WGS84_F - WGS84_F * WGS84_F;

/// A position in the local flat-earth frame, metres from the origin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NorthEast {
    /// Metres north of the origin.
    pub north_m: f64,
    /// Metres east of the origin.
    pub east_m: f64,
}

/// A geodetic position on the WGS-84 ellipsoid, in degrees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LatLon {
    /// Latitude, degrees, positive north.
    pub lat_deg: f64,
    /// Longitude, degrees, positive east.
    pub lon_deg: f64,
}

impl LatLon {
    /// True when both coordinates are finite and inside their ranges
    /// (|lat| <= 90, |lon| <= 180).
    pub fn is_valid(&self) -> bool {
        self.lat_deg.is_finite()
            && self.lon_deg.is_finite()
            && self.lat_deg.abs() <= 90.0
            && self.lon_deg.abs() <= 180.0
    }
}

/// A local flat-earth frame tangent at an origin. Cheap to copy; the radii of
/// curvature are computed once at construction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalFrame {
    origin: LatLon,
    /// Meridian radius of curvature at the origin, metres per radian of latitude.
    meridian_radius_m: f64,
    /// `R_N cos(lat0)`: metres per radian of longitude at the origin.
    parallel_radius_m: f64,
}

/// Why a local frame cannot be made at an origin.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum FrameError {
    /// The origin is not a finite latitude/longitude inside its range.
    #[error("origin {lat_deg}, {lon_deg} is not a valid latitude/longitude")]
    InvalidOrigin {
        /// The rejected latitude, degrees.
        lat_deg: f64,
        /// The rejected longitude, degrees.
        lon_deg: f64,
    },
    /// The origin is within 0.01 degrees of a pole, where east is undefined.
    #[error("origin latitude {lat_deg} is too close to a pole for a flat-earth frame")]
    NearPole {
        /// The rejected latitude, degrees.
        lat_deg: f64,
    },
}

impl LocalFrame {
    /// A frame with its origin at `origin`.
    pub fn new(origin: LatLon) -> Result<Self, FrameError> {
        if !origin.is_valid() {
            return Err(FrameError::InvalidOrigin {
                lat_deg: origin.lat_deg,
                lon_deg: origin.lon_deg,
            });
        }
        if origin.lat_deg.abs() > 89.99 {
            return Err(FrameError::NearPole {
                lat_deg: origin.lat_deg,
            });
        }
        let lat0 = origin.lat_deg.to_radians();
        let sin2 = lat0.sin().powi(2);
        let denom = 1.0 - WGS84_E2 * sin2;
        let prime_vertical_radius_m = WGS84_A_M / denom.sqrt();
        let meridian_radius_m = prime_vertical_radius_m * (1.0 - WGS84_E2) / denom;
        Ok(Self {
            origin,
            meridian_radius_m,
            parallel_radius_m: prime_vertical_radius_m * lat0.cos(),
        })
    }

    /// The origin of the frame.
    pub fn origin(&self) -> LatLon {
        self.origin
    }

    /// Meridian radius of curvature `R_M` at the origin, metres.
    pub fn meridian_radius_m(&self) -> f64 {
        self.meridian_radius_m
    }

    /// `R_N cos(lat0)` at the origin, metres.
    pub fn parallel_radius_m(&self) -> f64 {
        self.parallel_radius_m
    }

    /// Geodetic to local north/east. Longitude differences are wrapped, so a
    /// frame near the antimeridian works on both sides of it.
    pub fn to_local(&self, p: LatLon) -> NorthEast {
        let dlat_rad = (p.lat_deg - self.origin.lat_deg).to_radians();
        let dlon_rad = wrap_pi((p.lon_deg - self.origin.lon_deg).to_radians());
        NorthEast {
            north_m: dlat_rad * self.meridian_radius_m,
            east_m: dlon_rad * self.parallel_radius_m,
        }
    }

    /// Local north/east back to geodetic: the exact inverse of [`Self::to_local`]
    /// (longitude wrapped to [-180, 180)).
    pub fn to_geodetic(&self, p: NorthEast) -> LatLon {
        let lat_deg = self.origin.lat_deg + (p.north_m / self.meridian_radius_m).to_degrees();
        let lon_rad = self.origin.lon_deg.to_radians() + p.east_m / self.parallel_radius_m;
        LatLon {
            lat_deg,
            lon_deg: wrap_pi(lon_rad).to_degrees(),
        }
    }
}

/// Wraps an angle to [-pi, pi) ("smallest signed angle", Fossen's `ssa`).
/// Non-finite input comes back unchanged (NaN stays NaN).
#[inline]
pub fn wrap_pi(angle_rad: f64) -> f64 {
    // Fast path: the filter wraps angles that are at most a turn out of range.
    if (-PI..PI).contains(&angle_rad) {
        return angle_rad;
    }
    if (PI..3.0 * PI).contains(&angle_rad) {
        let w = angle_rad - TAU;
        if w < PI {
            return w.max(-PI);
        }
    } else if (-3.0 * PI..-PI).contains(&angle_rad) {
        let w = angle_rad + TAU;
        if w >= -PI {
            return if w < PI { w } else { -PI };
        }
    }
    if !angle_rad.is_finite() {
        return angle_rad;
    }
    let wrapped = (angle_rad + PI).rem_euclid(TAU) - PI;
    // rem_euclid can return TAU itself for tiny negative inputs after rounding.
    if wrapped >= PI {
        wrapped - TAU
    } else {
        wrapped
    }
}

/// Wraps an angle to [0, 2 pi), the range of a compass course or heading.
pub fn wrap_two_pi(angle_rad: f64) -> f64 {
    if !angle_rad.is_finite() {
        return angle_rad;
    }
    let wrapped = angle_rad.rem_euclid(TAU);
    if wrapped >= TAU { 0.0 } else { wrapped }
}

/// The signed difference `to - from` between two angles, wrapped to [-pi, pi).
pub fn angle_diff(to_rad: f64, from_rad: f64) -> f64 {
    wrap_pi(to_rad - from_rad)
}

/// Course over ground (radians clockwise from north, in [0, 2 pi)) of a
/// velocity given as north/east components. Returns 0 for a zero vector.
pub fn course_of(north_mps: f64, east_mps: f64) -> f64 {
    wrap_two_pi(east_mps.atan2(north_mps))
}

/// Compass degrees (clockwise from north) to radians in [0, 2 pi).
pub fn compass_deg_to_rad(deg: f64) -> f64 {
    wrap_two_pi(deg.to_radians())
}

/// Radians to compass degrees in [0, 360).
pub fn rad_to_compass_deg(rad: f64) -> f64 {
    let deg = wrap_two_pi(rad).to_degrees();
    if deg >= 360.0 { 0.0 } else { deg }
}

/// Knots to metres per second (1 kn = 1852 m / 3600 s exactly).
pub const MPS_PER_KNOT: f64 = 1852.0 / 3600.0;

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn radii_match_hand_computation_at_60_north() {
        // R_N = a / sqrt(1 - e^2 sin^2 60deg); R_M = R_N (1-e^2)/(1 - e^2 sin^2).
        let f = LocalFrame::new(LatLon {
            lat_deg: 60.0,
            lon_deg: 24.0,
        })
        .unwrap();
        let s2 = 0.75_f64;
        let rn = 6_378_137.0 / (1.0 - 0.006_694_379_990_14 * s2).sqrt();
        let rm = rn * (1.0 - 0.006_694_379_990_14) / (1.0 - 0.006_694_379_990_14 * s2);
        assert!(
            (f.meridian_radius_m() - rm).abs() < 1e-3,
            "{}",
            f.meridian_radius_m()
        );
        assert!((f.parallel_radius_m() - rn * 0.5).abs() < 1e-3);
        // Published value: R_M at 60 deg is about 6 383 453.9 m, R_N about 6 394 209.2 m.
        assert!((rm - 6_383_453.857).abs() < 1.0, "{rm}");
        assert!((rn - 6_394_209.174).abs() < 1.0, "{rn}");
    }

    #[test]
    fn one_arcminute_of_latitude_is_about_a_nautical_mile() {
        let f = LocalFrame::new(LatLon {
            lat_deg: 45.0,
            lon_deg: 0.0,
        })
        .unwrap();
        let p = f.to_local(LatLon {
            lat_deg: 45.0 + 1.0 / 60.0,
            lon_deg: 0.0,
        });
        // Meridian arc per arcminute at 45 deg: 1852.2 m (the nautical mile's definition point).
        assert!((p.north_m - 1852.2).abs() < 1.0, "{}", p.north_m);
        assert_eq!(p.east_m, 0.0);
        let q = f.to_local(LatLon {
            lat_deg: 45.0,
            lon_deg: 1.0 / 60.0,
        });
        // East: R_N cos 45 per radian -> about 1313.5 m per arcminute.
        assert!((q.east_m - 1313.5).abs() < 1.0, "{}", q.east_m);
        assert_eq!(q.north_m, 0.0);
    }

    #[test]
    fn north_is_latitude_and_east_is_longitude() {
        // Regression for the thesis' swapped axes (ERRATA 3).
        let f = LocalFrame::new(LatLon {
            lat_deg: 62.47,
            lon_deg: 6.15,
        })
        .unwrap();
        let p = f.to_local(LatLon {
            lat_deg: 62.471,
            lon_deg: 6.15,
        });
        assert!(p.north_m > 100.0 && p.east_m.abs() < 1e-9);
    }

    #[test]
    fn wrap_edges() {
        assert_eq!(wrap_pi(PI), -PI);
        assert_eq!(wrap_pi(-PI), -PI);
        assert!((wrap_pi(3.0 * PI) + PI).abs() < 1e-12);
        assert!((wrap_pi(-0.1) + 0.1).abs() < 1e-15);
        assert!(wrap_pi(f64::NAN).is_nan());
        assert_eq!(wrap_two_pi(-0.0), 0.0);
        assert!((wrap_two_pi(-0.5) - (TAU - 0.5)).abs() < 1e-12);
        assert!((angle_diff(0.1, TAU - 0.1) - 0.2).abs() < 1e-12);
        assert!((course_of(0.0, 1.0) - PI / 2.0).abs() < 1e-12);
        assert!((course_of(0.0, -1.0) - 1.5 * PI).abs() < 1e-12);
        assert_eq!(rad_to_compass_deg(TAU), 0.0);
    }

    #[test]
    fn frames_near_poles_and_bad_origins_are_errors() {
        assert!(
            LocalFrame::new(LatLon {
                lat_deg: 89.999,
                lon_deg: 0.0
            })
            .is_err()
        );
        assert!(
            LocalFrame::new(LatLon {
                lat_deg: f64::NAN,
                lon_deg: 0.0
            })
            .is_err()
        );
        assert!(
            LocalFrame::new(LatLon {
                lat_deg: 10.0,
                lon_deg: 181.0
            })
            .is_err()
        );
    }

    proptest! {
        #[test]
        fn geodetic_local_round_trip(
            lat0 in -80.0f64..80.0, lon0 in -180.0f64..180.0,
            north in -20_000.0f64..20_000.0, east in -20_000.0f64..20_000.0,
        ) {
            let f = LocalFrame::new(LatLon { lat_deg: lat0, lon_deg: lon0 }).unwrap();
            let ll = f.to_geodetic(NorthEast { north_m: north, east_m: east });
            prop_assert!(ll.is_valid());
            let back = f.to_local(ll);
            prop_assert!((back.north_m - north).abs() < 1e-6, "{} vs {}", back.north_m, north);
            prop_assert!((back.east_m - east).abs() < 1e-6, "{} vs {}", back.east_m, east);
        }

        #[test]
        fn local_distance_matches_haversine_within_small_error(
            lat0 in -70.0f64..70.0, lon0 in -179.0f64..179.0,
            north in -2_000.0f64..2_000.0, east in -2_000.0f64..2_000.0,
        ) {
            // Oracle: the great-circle distance on a sphere of the local mean radius.
            let f = LocalFrame::new(LatLon { lat_deg: lat0, lon_deg: lon0 }).unwrap();
            let ll = f.to_geodetic(NorthEast { north_m: north, east_m: east });
            let (p1, p2) = (lat0.to_radians(), ll.lat_deg.to_radians());
            let dl = (ll.lon_deg - lon0).to_radians();
            let h = ((p2 - p1) / 2.0).sin().powi(2) + p1.cos() * p2.cos() * (dl / 2.0).sin().powi(2);
            let radius = (f.meridian_radius_m() * f.parallel_radius_m() / p1.cos()).sqrt();
            let d_sphere = 2.0 * radius * h.sqrt().asin();
            let d_flat = north.hypot(east);
            // Over 2.8 km the flat-earth and spherical distances agree to ~0.5 %
            // (the sphere uses one mean radius where the ellipsoid has two).
            prop_assert!((d_sphere - d_flat).abs() <= 0.005 * d_flat + 0.05, "{} vs {}", d_sphere, d_flat);
        }

        #[test]
        fn wrap_pi_range_and_equivalence(a in -1e6f64..1e6) {
            let w = wrap_pi(a);
            prop_assert!((-PI..PI).contains(&w));
            prop_assert!(((a - w) / TAU - ((a - w) / TAU).round()).abs() < 1e-6);
            let c = wrap_two_pi(a);
            prop_assert!((0.0..TAU).contains(&c));
        }
    }
}
