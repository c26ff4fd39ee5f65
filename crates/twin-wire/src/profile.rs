//! Vessel profiles: the file (TOML) that gives the twin a vessel's hull,
//! mass, damping, propellers and GNSS antenna in SI units, its validation
//! (unknown keys refused, every error naming its key, physically impossible
//! values refused) and its conversion to [`twin_core::vessel::VesselParams`].
//!
//! The Otter's profile ships in the repository (`config/profiles/otter.toml`)
//! and is compiled in as the default ([`VesselProfile::otter`]). Every key
//! is explained in docs/profiles.md. A profile is known by its name and by
//! a fingerprint of its numbers ([`VesselProfile::fingerprint`]): a
//! calibration learnt with one profile is never used with another.

use std::fmt;
use std::path::Path;

use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};
use twin_core::twin::TwinConfig;
use twin_core::vessel::VesselParams;

/// The Otter's profile, as shipped.
pub const OTTER_PROFILE_TOML: &str = include_str!("../../../config/profiles/otter.toml");

/// A profile that cannot be used: the key at fault and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ProfileError {
    /// The key, as `table.key` (or the file, when it cannot be read).
    pub key: String,
    /// What is wrong with it.
    pub reason: String,
}

impl fmt::Display for ProfileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.key, self.reason)
    }
}

impl std::error::Error for ProfileError {}

/// The hull.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HullProfile {
    /// Length of the hull (of a catamaran's pontoons), m.
    pub length_m: f64,
    /// Overall beam, m.
    pub beam_m: f64,
    /// Draft, m.
    pub draft_m: f64,
    /// Density of the water, kg/m^3.
    pub water_density_kgpm3: f64,
    /// 2D cross-flow drag coefficient of a hull section.
    pub crossflow_drag_coeff: f64,
}

/// Mass, inertia and added mass.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MassProfile {
    /// Rigid-body mass with its payload, kg.
    pub mass_kg: f64,
    /// Centre of gravity forward of the body origin, m.
    pub cg_forward_m: f64,
    /// Rigid-body yaw inertia about the body origin, kg m^2.
    pub yaw_inertia_kgm2: f64,
    /// Added mass in surge, kg (`-X_udot`).
    pub added_mass_surge_kg: f64,
    /// Added mass in sway, kg (`-Y_vdot`).
    pub added_mass_sway_kg: f64,
    /// Added inertia in yaw, kg m^2 (`-N_rdot`).
    pub added_inertia_yaw_kgm2: f64,
}

/// Damping, as positive magnitudes.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DampingProfile {
    /// Linear surge damping, N per m/s (`-X_u`).
    pub surge_n_per_mps: f64,
    /// Linear sway damping, N per m/s (`-Y_v`).
    pub sway_n_per_mps: f64,
    /// Linear yaw damping, N m per rad/s (`-N_r`).
    pub yaw_nm_per_radps: f64,
    /// Nonlinear yaw damping factor `c`, s: `N = N_r (1 + c |r|) r`.
    pub yaw_nonlinear_s: f64,
}

/// The two propellers, alike and placed symmetrically.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PropellerProfile {
    /// Distance of each propeller from the centre line, m.
    pub lateral_offset_m: f64,
    /// Thrust coefficient ahead, `T = k n |n|`, N per (rad/s)^2.
    pub thrust_coeff_ahead_n_per_radps2: f64,
    /// Thrust coefficient astern, N per (rad/s)^2.
    pub thrust_coeff_astern_n_per_radps2: f64,
    /// Highest shaft speed ahead, rad/s.
    pub max_shaft_speed_ahead_radps: f64,
    /// Highest shaft speed astern, as a positive number, rad/s.
    pub max_shaft_speed_astern_radps: f64,
    /// Time constant of the shaft speed's response, s.
    pub shaft_time_constant_s: f64,
}

/// The GNSS antenna.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GnssProfile {
    /// Antenna forward of the body origin, m.
    pub antenna_forward_m: f64,
    /// Antenna to starboard of the centre line, m.
    pub antenna_starboard_m: f64,
}

/// How well a trial pinned the profile down (written by `twin identify`):
/// the relative standard deviations of its surge damping, yaw damping,
/// thrust coefficient and mass as the twin takes them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IdentifiedProfile {
    /// Relative standard deviation of the surge damping.
    pub surge_damping_sigma: f64,
    /// Relative standard deviation of the yaw damping.
    pub yaw_damping_sigma: f64,
    /// Relative standard deviation of the thrust coefficients.
    pub thrust_sigma: f64,
    /// Relative standard deviation of the mass and inertia.
    pub mass_sigma: f64,
    /// The trial it was identified from.
    #[serde(default)]
    pub trial: String,
}

impl IdentifiedProfile {
    /// The sigmas in the twin's order.
    pub fn sigma(&self) -> [f64; 4] {
        [
            self.surge_damping_sigma,
            self.yaw_damping_sigma,
            self.thrust_sigma,
            self.mass_sigma,
        ]
    }
}

/// A vessel profile, as read from its file: parsed, not yet validated
/// (see [`VesselProfile::from_toml`], which does both).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VesselProfile {
    /// The profile's name: lower-case letters, digits, `-` and `_`.
    pub name: String,
    /// What vessel it describes.
    #[serde(default)]
    pub description: String,
    /// The hull.
    pub hull: HullProfile,
    /// Mass and inertia.
    pub mass: MassProfile,
    /// Damping.
    pub damping: DampingProfile,
    /// Propellers.
    pub propellers: PropellerProfile,
    /// GNSS antenna.
    pub gnss: GnssProfile,
    /// Present when the profile was identified from a trial of the vessel.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub identified: Option<IdentifiedProfile>,
}

/// A key's value must be finite and within `[low, high]`.
fn within(key: &str, value: f64, low: f64, high: f64, what: &str) -> Result<(), ProfileError> {
    if value.is_finite() && (low..=high).contains(&value) {
        Ok(())
    } else {
        Err(ProfileError {
            key: key.to_owned(),
            reason: format!("{value} is not {what} (between {low} and {high})"),
        })
    }
}

/// A key's value must be finite and above zero, and at most `high`.
fn positive(key: &str, value: f64, high: f64, what: &str) -> Result<(), ProfileError> {
    if value.is_finite() && value > 0.0 && value <= high {
        Ok(())
    } else {
        Err(ProfileError {
            key: key.to_owned(),
            reason: format!("{value} is not {what} (above 0, at most {high})"),
        })
    }
}

impl VesselProfile {
    /// The Otter's profile, the default.
    pub fn otter() -> Self {
        Self::from_toml(OTTER_PROFILE_TOML).expect("the shipped Otter profile is valid")
    }

    /// Parses and validates a profile.
    pub fn from_toml(text: &str) -> Result<Self, ProfileError> {
        let profile: Self = toml::from_str(text).map_err(|e| {
            let at = e
                .span()
                .map_or_else(|| "profile".to_owned(), |span| key_at(text, span.start));
            ProfileError {
                key: named_field(e.message()).map_or(at.clone(), |field| qualified(&at, field)),
                reason: e.message().to_owned(),
            }
        })?;
        profile.validate()?;
        Ok(profile)
    }

    /// Reads, parses and validates a profile file.
    pub fn from_file(path: &Path) -> Result<Self, ProfileError> {
        let text = std::fs::read_to_string(path).map_err(|e| ProfileError {
            key: path.display().to_string(),
            reason: format!("cannot read: {e}"),
        })?;
        Self::from_toml(&text)
    }

    /// The profile as TOML, every key written.
    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("a profile is plain TOML")
    }

    /// Checks that the numbers describe a vessel that can exist and that
    /// the twin can model: every error names its key.
    pub fn validate(&self) -> Result<(), ProfileError> {
        let name_ok = !self.name.is_empty()
            && self.name.len() <= 64
            && self
                .name
                .bytes()
                .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'-' || b == b'_');
        if !name_ok {
            return Err(ProfileError {
                key: "name".into(),
                reason: format!(
                    "{:?}: 1 to 64 lower-case letters, digits, '-' or '_'",
                    self.name
                ),
            });
        }
        self.validate_hull()?;
        self.validate_mass()?;
        self.validate_damping()?;
        self.validate_propellers()?;
        self.validate_gnss()?;
        if let Some(identified) = &self.identified {
            let keys = [
                "identified.surge_damping_sigma",
                "identified.yaw_damping_sigma",
                "identified.thrust_sigma",
                "identified.mass_sigma",
            ];
            for (key, sigma) in keys.into_iter().zip(identified.sigma()) {
                positive(key, sigma, 1.0, "a relative standard deviation")?;
            }
        }
        Ok(())
    }

    /// `base` (the twin's tuning) for this vessel: its parameters, and, if
    /// the profile was identified, its errors' prior from the
    /// identification.
    pub fn twin_config(&self, base: TwinConfig) -> TwinConfig {
        let twin = base.with_vessel(self.params());
        match &self.identified {
            Some(identified) => twin.with_identified_profile(identified.sigma()),
            None => twin,
        }
    }

    fn validate_hull(&self) -> Result<(), ProfileError> {
        let h = &self.hull;
        positive("hull.length_m", h.length_m, 100.0, "a hull length")?;
        positive(
            "hull.beam_m",
            h.beam_m,
            h.length_m,
            "a beam no wider than the hull is long",
        )?;
        positive("hull.draft_m", h.draft_m, h.length_m / 2.0, "a draft")?;
        within(
            "hull.water_density_kgpm3",
            h.water_density_kgpm3,
            990.0,
            1050.0,
            "the density of fresh or sea water",
        )?;
        within(
            "hull.crossflow_drag_coeff",
            h.crossflow_drag_coeff,
            0.0,
            3.0,
            "a 2D drag coefficient",
        )
    }

    fn validate_mass(&self) -> Result<(), ProfileError> {
        let m = &self.mass;
        let length = self.hull.length_m;
        positive("mass.mass_kg", m.mass_kg, 1e6, "a mass")?;
        within(
            "mass.cg_forward_m",
            m.cg_forward_m,
            -length / 2.0,
            length / 2.0,
            "a position within the hull",
        )?;
        positive(
            "mass.yaw_inertia_kgm2",
            m.yaw_inertia_kgm2,
            1e9,
            "an inertia",
        )?;
        // A hull's inertia about its origin is at least the mass's own at
        // its centre of gravity, and at most that of all the mass at the
        // ends of the hull.
        let at_ends = m.mass_kg * (length / 2.0).powi(2);
        let at_cg = m.mass_kg * m.cg_forward_m.powi(2);
        within(
            "mass.yaw_inertia_kgm2",
            m.yaw_inertia_kgm2,
            at_cg,
            at_ends,
            "an inertia this mass can have on this hull",
        )?;
        let added = [
            ("mass.added_mass_surge_kg", m.added_mass_surge_kg, m.mass_kg),
            (
                "mass.added_mass_sway_kg",
                m.added_mass_sway_kg,
                5.0 * m.mass_kg,
            ),
            (
                "mass.added_inertia_yaw_kgm2",
                m.added_inertia_yaw_kgm2,
                5.0 * m.yaw_inertia_kgm2,
            ),
        ];
        for (key, value, high) in added {
            within(key, value, 0.0, high, "an added mass for this hull")?;
        }
        if self.mass_matrix().cholesky().is_none() {
            return Err(ProfileError {
                key: "mass.yaw_inertia_kgm2".into(),
                reason: "with the sway mass and the centre of gravity it gives a mass \
                         matrix that is not positive definite"
                    .into(),
            });
        }
        Ok(())
    }

    fn validate_damping(&self) -> Result<(), ProfileError> {
        let d = &self.damping;
        positive(
            "damping.surge_n_per_mps",
            d.surge_n_per_mps,
            1e7,
            "a surge damping",
        )?;
        positive(
            "damping.sway_n_per_mps",
            d.sway_n_per_mps,
            1e7,
            "a sway damping",
        )?;
        positive(
            "damping.yaw_nm_per_radps",
            d.yaw_nm_per_radps,
            1e9,
            "a yaw damping",
        )?;
        within(
            "damping.yaw_nonlinear_s",
            d.yaw_nonlinear_s,
            0.0,
            100.0,
            "a nonlinear yaw factor",
        )
    }

    fn validate_propellers(&self) -> Result<(), ProfileError> {
        let p = &self.propellers;
        if !(p.lateral_offset_m.is_finite() && p.lateral_offset_m > 0.0) {
            return Err(ProfileError {
                key: "propellers.lateral_offset_m".into(),
                reason: format!(
                    "{}: the propellers must sit off the centre line, or their thrusts \
                     cannot turn the vessel and cannot be told apart",
                    p.lateral_offset_m
                ),
            });
        }
        positive(
            "propellers.lateral_offset_m",
            p.lateral_offset_m,
            self.hull.beam_m / 2.0,
            "a distance within half the beam",
        )?;
        positive(
            "propellers.thrust_coeff_ahead_n_per_radps2",
            p.thrust_coeff_ahead_n_per_radps2,
            1e3,
            "a thrust coefficient",
        )?;
        positive(
            "propellers.thrust_coeff_astern_n_per_radps2",
            p.thrust_coeff_astern_n_per_radps2,
            1e3,
            "a thrust coefficient",
        )?;
        positive(
            "propellers.max_shaft_speed_ahead_radps",
            p.max_shaft_speed_ahead_radps,
            1e4,
            "a shaft speed",
        )?;
        positive(
            "propellers.max_shaft_speed_astern_radps",
            p.max_shaft_speed_astern_radps,
            1e4,
            "a shaft speed",
        )?;
        positive(
            "propellers.shaft_time_constant_s",
            p.shaft_time_constant_s,
            10.0,
            "a shaft time constant",
        )
    }

    fn validate_gnss(&self) -> Result<(), ProfileError> {
        let g = &self.gnss;
        let (half_length, half_beam) = (self.hull.length_m / 2.0, self.hull.beam_m / 2.0);
        within(
            "gnss.antenna_forward_m",
            g.antenna_forward_m,
            -half_length,
            half_length,
            "a position on the hull",
        )?;
        within(
            "gnss.antenna_starboard_m",
            g.antenna_starboard_m,
            -half_beam,
            half_beam,
            "a position on the hull",
        )
    }

    /// The mass matrix with added mass, surge-sway-yaw.
    fn mass_matrix(&self) -> Matrix3<f64> {
        let m = &self.mass;
        let mxg = m.mass_kg * m.cg_forward_m;
        Matrix3::new(
            m.mass_kg + m.added_mass_surge_kg,
            0.0,
            0.0,
            0.0,
            m.mass_kg + m.added_mass_sway_kg,
            mxg,
            0.0,
            mxg,
            m.yaw_inertia_kgm2 + m.added_inertia_yaw_kgm2,
        )
    }

    /// The estimator's parameters.
    pub fn params(&self) -> VesselParams {
        let (m, d, p, h) = (&self.mass, &self.damping, &self.propellers, &self.hull);
        VesselParams {
            mass_kg: m.mass_kg,
            cg_x_m: m.cg_forward_m,
            mass_matrix: self.mass_matrix(),
            added_mass: [
                -m.added_mass_surge_kg,
                -m.added_mass_sway_kg,
                -m.added_inertia_yaw_kgm2,
            ],
            linear_damping: [-d.surge_n_per_mps, -d.sway_n_per_mps, -d.yaw_nm_per_radps],
            yaw_damping_nonlinear_s: d.yaw_nonlinear_s,
            propeller_offset_m: p.lateral_offset_m,
            thrust_coeff_ahead: p.thrust_coeff_ahead_n_per_radps2,
            thrust_coeff_astern: p.thrust_coeff_astern_n_per_radps2,
            max_shaft_speed_radps: p.max_shaft_speed_ahead_radps,
            min_shaft_speed_radps: -p.max_shaft_speed_astern_radps,
            shaft_time_constant_s: p.shaft_time_constant_s,
            length_m: h.length_m,
            beam_m: h.beam_m,
            draft_m: h.draft_m,
            water_density_kgpm3: h.water_density_kgpm3,
            crossflow_drag_coeff: h.crossflow_drag_coeff,
            antenna_m: [self.gnss.antenna_forward_m, self.gnss.antenna_starboard_m],
        }
    }

    /// This profile with the numbers of `params` (as `twin identify`
    /// writes them): the mass, inertia, added mass, damping and thrust
    /// coefficients; the hull, the propellers' places and shaft limits and
    /// the antenna are kept.
    pub fn with_params(&self, params: &VesselParams) -> Self {
        let mut p = self.clone();
        let added = params.added_mass.map(|a| -a);
        p.mass.mass_kg = params.mass_kg;
        p.mass.added_mass_surge_kg = added[0];
        p.mass.added_mass_sway_kg = added[1];
        p.mass.added_inertia_yaw_kgm2 = added[2];
        p.mass.yaw_inertia_kgm2 = params.mass_matrix[(2, 2)] - added[2];
        p.damping.surge_n_per_mps = -params.linear_damping[0];
        p.damping.sway_n_per_mps = -params.linear_damping[1];
        p.damping.yaw_nm_per_radps = -params.linear_damping[2];
        p.propellers.thrust_coeff_ahead_n_per_radps2 = params.thrust_coeff_ahead;
        p.propellers.thrust_coeff_astern_n_per_radps2 = params.thrust_coeff_astern;
        p
    }

    /// A fingerprint of the profile's numbers (not its name or
    /// description): 64-bit FNV-1a of their bits, as 16 hex digits. Two
    /// profiles with one number different differ in it.
    pub fn fingerprint(&self) -> String {
        let (h, m, d, p, g) = (
            &self.hull,
            &self.mass,
            &self.damping,
            &self.propellers,
            &self.gnss,
        );
        let numbers = [
            h.length_m,
            h.beam_m,
            h.draft_m,
            h.water_density_kgpm3,
            h.crossflow_drag_coeff,
            m.mass_kg,
            m.cg_forward_m,
            m.yaw_inertia_kgm2,
            m.added_mass_surge_kg,
            m.added_mass_sway_kg,
            m.added_inertia_yaw_kgm2,
            d.surge_n_per_mps,
            d.sway_n_per_mps,
            d.yaw_nm_per_radps,
            d.yaw_nonlinear_s,
            p.lateral_offset_m,
            p.thrust_coeff_ahead_n_per_radps2,
            p.thrust_coeff_astern_n_per_radps2,
            p.max_shaft_speed_ahead_radps,
            p.max_shaft_speed_astern_radps,
            p.shaft_time_constant_s,
            g.antenna_forward_m,
            g.antenna_starboard_m,
        ];
        let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
        for byte in numbers.iter().flat_map(|x| x.to_bits().to_le_bytes()) {
            hash ^= u64::from(byte);
            hash = hash.wrapping_mul(0x0100_0000_01b3);
        }
        format!("{hash:016x}")
    }

    /// The profile's identity as the twin's outputs and calibrations name
    /// it: `name@fingerprint`.
    pub fn identity(&self) -> String {
        format!("{}@{}", self.name, self.fingerprint())
    }
}

/// The field a serde message names (`missing field `x``, `unknown field
/// `x``), if any.
fn named_field(message: &str) -> Option<&str> {
    let rest = message
        .strip_prefix("missing field `")
        .or_else(|| message.strip_prefix("unknown field `"))?;
    rest.split('`').next()
}

/// `field` within the table of the dotted key `at` (`at` itself when it
/// already names the field).
fn qualified(at: &str, field: &str) -> String {
    if at == field || at.ends_with(&format!(".{field}")) {
        return at.to_owned();
    }
    match at.rsplit_once('.') {
        _ if at == "profile" => field.to_owned(),
        Some((table, _)) => format!("{table}.{field}"),
        None if at.contains('=') => field.to_owned(),
        None => format!("{at}.{field}"),
    }
}

/// The dotted key (`table.key`) whose line holds byte `offset` of `text`:
/// the `[table]` header on or above that line and the key on it.
fn key_at(text: &str, offset: usize) -> String {
    let before = &text[..offset.min(text.len())];
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let line_end = text[line_start..]
        .find('\n')
        .map_or(text.len(), |i| line_start + i);
    let line = text[line_start..line_end].trim();
    let table = text[..line_end]
        .lines()
        .rev()
        .map(str::trim)
        .find(|l| l.starts_with('[') && l.ends_with(']'))
        .map(|l| l.trim_matches(['[', ']']).trim().to_owned());
    let key = line
        .split_once('=')
        .map(|(k, _)| k.trim().to_owned())
        .filter(|k| !k.is_empty() && !k.starts_with('['));
    match (table, key) {
        (Some(t), Some(k)) => format!("{t}.{k}"),
        (None, Some(k)) => k,
        (Some(t), None) => t,
        (None, None) => "profile".to_owned(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Exactly: the daemon's and the tools' default twin is the one the
    /// estimator's tests and the accuracy tables run.
    #[test]
    fn the_shipped_otter_profile_is_the_estimators_default() {
        assert_eq!(VesselProfile::otter().params(), VesselParams::default());
    }

    /// `key = value` replaced in the Otter's profile text.
    fn otter_with(key: &str, value: &str) -> String {
        let mut found = false;
        let text = OTTER_PROFILE_TOML
            .lines()
            .map(|l| {
                if l.split('=').next().map(str::trim) == Some(key) {
                    found = true;
                    format!("{key} = {value}")
                } else {
                    l.to_owned()
                }
            })
            .collect::<Vec<_>>()
            .join("\n");
        assert!(found, "{key} is not in the Otter's profile");
        text
    }

    fn refusal(text: &str) -> ProfileError {
        VesselProfile::from_toml(text).expect_err("refused")
    }

    #[test]
    fn impossible_values_are_refused_naming_their_key() {
        let cases = [
            ("mass_kg", "-80.0", "mass.mass_kg"),
            ("lateral_offset_m", "0.0", "propellers.lateral_offset_m"),
            ("lateral_offset_m", "0.9", "propellers.lateral_offset_m"),
            ("surge_n_per_mps", "nan", "damping.surge_n_per_mps"),
            ("yaw_inertia_kgm2", "5000.0", "mass.yaw_inertia_kgm2"),
            ("antenna_forward_m", "3.0", "gnss.antenna_forward_m"),
            ("water_density_kgpm3", "1.2", "hull.water_density_kgpm3"),
            ("name", "\"Otter 2\"", "name"),
        ];
        for (key, value, named) in cases {
            let error = refusal(&otter_with(key, value));
            assert_eq!(error.key, named, "{key} = {value}: {error}");
        }
        let centre = refusal(&otter_with("lateral_offset_m", "0.0"));
        assert!(centre.reason.contains("centre line"), "{centre}");
    }

    #[test]
    fn unknown_and_missing_keys_are_refused_naming_the_key() {
        let unknown = refusal(&otter_with("mass_kg", "80.0\nmass_lb = 176.0"));
        assert!(unknown.reason.contains("mass_lb"), "{unknown}");
        assert_eq!(unknown.key, "mass.mass_lb");
        let missing: String = OTTER_PROFILE_TOML
            .lines()
            .filter(|l| !l.starts_with("sway_n_per_mps"))
            .collect::<Vec<_>>()
            .join("\n");
        let error = refusal(&missing);
        assert!(error.reason.contains("sway_n_per_mps"), "{error}");
        assert!(error.key.starts_with("damping"), "{error}");
    }

    #[test]
    fn a_profile_round_trips_and_its_fingerprint_follows_its_numbers() {
        let otter = VesselProfile::otter();
        let again = VesselProfile::from_toml(&otter.to_toml()).unwrap();
        assert_eq!(again, otter);
        assert_eq!(again.fingerprint(), otter.fingerprint());
        let mut renamed = otter.clone();
        renamed.name = "otter-copy".into();
        assert_eq!(renamed.fingerprint(), otter.fingerprint());
        let mut heavier = otter.clone();
        heavier.mass.mass_kg += 1e-9;
        assert_ne!(heavier.fingerprint(), otter.fingerprint());
        assert!(otter.identity().starts_with("otter@"));
        // Its own numbers change nothing.
        assert_eq!(otter.with_params(&otter.params()).params(), otter.params());
        let mut heavier_params = otter.params();
        heavier_params.mass_kg *= 2.0;
        heavier_params.mass_matrix *= 2.0;
        heavier_params.added_mass = heavier_params.added_mass.map(|a| 2.0 * a);
        let doubled = otter.with_params(&heavier_params).params();
        assert!((doubled.mass_matrix[(2, 2)] - 2.0 * 42.65).abs() < 1e-9);
        assert_eq!(doubled.mass_kg, 160.0);
    }
}
