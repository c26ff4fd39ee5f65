//! The MAVLink side of a boat, from a TOML file (`--mavlink-config`): which
//! servo outputs drive the port and starboard motors, which actuator
//! messages to use, and the PWM -> thrust map. An example for the Otter is
//! `config/mavlink-otter.toml`:
//!
//! ```toml
//! port_output = 1          # SERVO1_FUNCTION = 73 (ThrottleLeft)
//! starboard_output = 3     # SERVO3_FUNCTION = 74 (ThrottleRight)
//! actuators = "auto"       # auto | rpm | servo | none
//! thrust_map = [[1100, -66.7], [1500, 0.0], [1900, 119.7]]  # [PWM us, thrust N]
//! ```
//!
//! Every key is optional; what is left out keeps its default
//! (`twin_wire::read::MavlinkOptions::default`).

use std::path::Path;

use serde::Deserialize;
use twin_wire::read::MavlinkOptions;
use twin_wire::read::mavlink::{ActuatorSource, PwmThrustMap, ThrustMapError};

/// The file's keys.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    port_output: Option<u8>,
    starboard_output: Option<u8>,
    actuators: Option<String>,
    thrust_map: Option<Vec<(u16, f64)>>,
    system: Option<u8>,
}

/// Why the file is refused; every message names the key.
#[derive(Debug, thiserror::Error)]
pub enum MavlinkConfigError {
    /// The file cannot be read.
    #[error("cannot read {path}: {source}")]
    Read {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// Not TOML, or an unknown key, or a value of the wrong type.
    #[error("{path}: {source}")]
    Toml {
        /// The file.
        path: String,
        /// Why.
        source: toml::de::Error,
    },
    /// An output number outside 1-16, or both motors on one output.
    #[error("{key} = {value}: a servo output is 1 to 16, one per motor")]
    Output {
        /// The key.
        key: &'static str,
        /// The value.
        value: u8,
    },
    /// `actuators` is not one of its words.
    #[error("actuators = {0:?}: auto, rpm, servo or none")]
    Actuators(String),
    /// `thrust_map` is refused.
    #[error("thrust_map: {0}")]
    Map(#[from] ThrustMapError),
}

/// Reads a MAVLink configuration from TOML text.
pub fn parse(text: &str, path: &str) -> Result<MavlinkOptions, MavlinkConfigError> {
    let file: File = toml::from_str(text).map_err(|source| MavlinkConfigError::Toml {
        path: path.to_owned(),
        source,
    })?;
    let mut options = MavlinkOptions::default();
    for (key, value, slot) in [
        ("port_output", file.port_output, &mut options.port_output),
        (
            "starboard_output",
            file.starboard_output,
            &mut options.starboard_output,
        ),
    ] {
        if let Some(v) = value {
            if !(1..=16).contains(&v) {
                return Err(MavlinkConfigError::Output { key, value: v });
            }
            *slot = v;
        }
    }
    if options.port_output == options.starboard_output {
        return Err(MavlinkConfigError::Output {
            key: "starboard_output",
            value: options.starboard_output,
        });
    }
    if let Some(a) = file.actuators {
        options.actuators = match a.as_str() {
            "auto" => ActuatorSource::Auto,
            "rpm" => ActuatorSource::Rpm,
            "servo" => ActuatorSource::Servo,
            "none" => ActuatorSource::None,
            _ => return Err(MavlinkConfigError::Actuators(a)),
        };
    }
    if let Some(points) = file.thrust_map {
        options.thrust_map = PwmThrustMap::new(&points)?;
    }
    options.system = file.system;
    Ok(options)
}

/// Reads a MAVLink configuration file.
pub fn load(path: &Path) -> Result<MavlinkOptions, MavlinkConfigError> {
    let name = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|source| MavlinkConfigError::Read {
        path: name.clone(),
        source,
    })?;
    parse(&text, &name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_otter_example_is_the_default() {
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../config/mavlink-otter.toml"
        ))
        .unwrap();
        let options = parse(&text, "mavlink-otter.toml").unwrap();
        assert_eq!(options, MavlinkOptions::default());
        assert_eq!(parse("", "empty").unwrap(), MavlinkOptions::default());
    }

    #[test]
    fn a_boat_of_its_own_and_mistakes() {
        let o = parse(
            "port_output = 2\nstarboard_output = 4\nactuators = \"servo\"\nthrust_map = [[1000, -20.0], [1500, 0.0], [2000, 40.0]]\n",
            "t",
        )
        .unwrap();
        assert_eq!((o.port_output, o.starboard_output), (2, 4));
        assert_eq!(o.actuators, ActuatorSource::Servo);
        assert_eq!(o.thrust_map.thrust_n(2000), Some(40.0));
        for (bad, what) in [
            ("port_output = 0", "port_output = 0"),
            ("port_output = 3", "starboard_output = 3"),
            ("actuators = \"esc\"", "actuators"),
            ("thrust_map = [[1500, 0.0]]", "thrust_map"),
            ("thrust_map = [[1900, 0.0], [1100, 1.0]]", "thrust_map"),
            ("trust_map = []", "unknown field"),
        ] {
            let e = parse(bad, "t").unwrap_err().to_string();
            assert!(e.contains(what), "{bad}: {e}");
        }
    }
}
