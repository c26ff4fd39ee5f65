//! Zenoh's usual command-line flags, shared by `twind` and `twin-replay`
//! (docs/contracts.md, command-line conventions), and their translation into a
//! [`zenoh::Config`].
//!
//! The translation starts from the `--config` file (Zenoh's own JSON5
//! format, loaded with [`zenoh::Config::from_file`]) or from
//! [`zenoh::Config::default`], then applies each flag with
//! [`zenoh::Config::insert_json5`], so a flag given on the command line wins
//! over the file:
//!
//! | flag | config key |
//! |---|---|
//! | `--mode M` | `mode` |
//! | `--connect E` (repeatable) | `connect/endpoints` (replaces the file's list) |
//! | `--listen E` (repeatable) | `listen/endpoints` (replaces the file's list) |
//! | `--no-multicast-scouting` | `scouting/multicast/enabled = false` |
//!
//! Zenoh's configuration fields are unstable API; `insert_json5` is the
//! stable way to set them. Every error names the flag and the value at fault.

use std::fmt;
use std::path::PathBuf;
use std::str::FromStr;

use zenoh::config::EndPoint;

/// The role of the Zenoh session (`--mode`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, clap::ValueEnum)]
pub enum Mode {
    /// Talks to other peers directly and through routers (Zenoh's default).
    Peer,
    /// Talks through exactly one router or peer; reconnects when it is lost.
    Client,
    /// Routes for clients and peers.
    Router,
}

impl Mode {
    /// The name Zenoh's configuration uses.
    pub fn as_str(self) -> &'static str {
        match self {
            Mode::Peer => "peer",
            Mode::Client => "client",
            Mode::Router => "router",
        }
    }
}

impl fmt::Display for Mode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Zenoh's usual flags. Flatten it into a binary's arguments with
/// `#[command(flatten)]`; build one by hand in tests and embedders (every
/// field is public and `Default` is "no flags").
#[derive(Debug, Clone, Default, PartialEq, Eq, clap::Args)]
#[command(next_help_heading = "Zenoh")]
pub struct ZenohArgs {
    /// A Zenoh configuration file (JSON5, Zenoh's own format); the flags
    /// below override what it says.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// The session's mode [Zenoh's default: peer].
    #[arg(long, value_enum, value_name = "MODE")]
    pub mode: Option<Mode>,
    /// An endpoint to connect to, e.g. tcp/127.0.0.1:7447 (repeatable).
    #[arg(long, value_name = "ENDPOINT", value_parser = parse_endpoint)]
    pub connect: Vec<String>,
    /// An endpoint to listen on, e.g. tcp/0.0.0.0:7447 (repeatable).
    #[arg(long, value_name = "ENDPOINT", value_parser = parse_endpoint)]
    pub listen: Vec<String>,
    /// Do not discover peers and routers by UDP multicast.
    #[arg(long)]
    pub no_multicast_scouting: bool,
}

/// Why the flags do not make a Zenoh configuration.
#[derive(Debug, thiserror::Error)]
pub enum ZenohConfigError {
    /// `--config FILE` cannot be read or is not a valid Zenoh configuration.
    #[error("--config {path:?}: cannot load the Zenoh configuration")]
    ConfigFile {
        /// The file given.
        path: PathBuf,
        /// Zenoh's reason.
        #[source]
        source: zenoh::Error,
    },
    /// A `--connect` or `--listen` value is not a Zenoh endpoint
    /// (`<protocol>/<address>[?<metadata>][#<config>]`).
    #[error("{flag} {value:?} is not a Zenoh endpoint")]
    BadEndpoint {
        /// The flag, with its dashes.
        flag: &'static str,
        /// The value given.
        value: String,
        /// Zenoh's reason.
        #[source]
        source: zenoh::Error,
    },
    /// Zenoh refused the setting a flag translates to.
    #[error("{flag} {value}: Zenoh refused {key} = {json}")]
    Rejected {
        /// The flag, with its dashes.
        flag: &'static str,
        /// The value given on the command line.
        value: String,
        /// The configuration key set.
        key: &'static str,
        /// The JSON5 value inserted.
        json: String,
        /// Zenoh's reason.
        #[source]
        source: zenoh::Error,
    },
}

/// Checks that `text` is a Zenoh endpoint; the clap value parser of
/// `--connect` and `--listen` (so a bad one is refused while parsing).
pub fn parse_endpoint(text: &str) -> Result<String, String> {
    EndPoint::from_str(text)
        .map(|_| text.to_owned())
        .map_err(|e| e.to_string())
}

impl ZenohArgs {
    /// The Zenoh configuration these flags describe (see the module doc).
    pub fn to_config(&self) -> Result<zenoh::Config, ZenohConfigError> {
        let mut config = match &self.config {
            Some(path) => {
                zenoh::Config::from_file(path).map_err(|source| ZenohConfigError::ConfigFile {
                    path: path.clone(),
                    source,
                })?
            }
            None => zenoh::Config::default(),
        };
        if let Some(mode) = self.mode {
            insert(
                &mut config,
                "--mode",
                mode.as_str(),
                "mode",
                json_string(mode.as_str()),
            )?;
        }
        for (flag, key, endpoints) in [
            ("--connect", "connect/endpoints", &self.connect),
            ("--listen", "listen/endpoints", &self.listen),
        ] {
            if endpoints.is_empty() {
                continue;
            }
            for value in endpoints {
                EndPoint::from_str(value).map_err(|e| ZenohConfigError::BadEndpoint {
                    flag,
                    value: value.clone(),
                    source: e,
                })?;
            }
            let json = serde_json::Value::from(endpoints.clone()).to_string();
            insert(&mut config, flag, &endpoints.join(" "), key, json)?;
        }
        if self.no_multicast_scouting {
            insert(
                &mut config,
                "--no-multicast-scouting",
                "true",
                "scouting/multicast/enabled",
                "false".to_owned(),
            )?;
        }
        Ok(config)
    }
}

impl TryFrom<&ZenohArgs> for zenoh::Config {
    type Error = ZenohConfigError;

    fn try_from(args: &ZenohArgs) -> Result<Self, Self::Error> {
        args.to_config()
    }
}

fn json_string(text: &str) -> String {
    serde_json::Value::from(text).to_string()
}

fn insert(
    config: &mut zenoh::Config,
    flag: &'static str,
    value: &str,
    key: &'static str,
    json: String,
) -> Result<(), ZenohConfigError> {
    config
        .insert_json5(key, &json)
        .map_err(|source| ZenohConfigError::Rejected {
            flag,
            value: value.to_owned(),
            key,
            json,
            source,
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Debug, clap::Parser)]
    struct Cli {
        #[command(flatten)]
        zenoh: ZenohArgs,
    }

    fn parse(args: &[&str]) -> Result<ZenohArgs, clap::Error> {
        Cli::try_parse_from(std::iter::once("prog").chain(args.iter().copied())).map(|c| c.zenoh)
    }

    #[test]
    fn no_flags_is_zenohs_default() {
        let args = parse(&[]).unwrap();
        assert_eq!(args, ZenohArgs::default());
        let config = args.to_config().unwrap();
        assert_eq!(
            config.get_json("scouting/multicast/enabled").unwrap(),
            zenoh::Config::default()
                .get_json("scouting/multicast/enabled")
                .unwrap()
        );
    }

    #[test]
    fn flags_land_in_the_config() {
        let args = parse(&[
            "--mode",
            "client",
            "--connect",
            "tcp/127.0.0.1:7447",
            "--connect",
            "tcp/10.0.0.1:7447",
            "--listen",
            "tcp/127.0.0.1:0",
            "--no-multicast-scouting",
        ])
        .unwrap();
        let config = args.to_config().unwrap();
        assert_eq!(config.get_json("mode").unwrap(), r#""client""#);
        assert_eq!(
            config.get_json("connect/endpoints").unwrap(),
            r#"["tcp/127.0.0.1:7447","tcp/10.0.0.1:7447"]"#
        );
        assert_eq!(
            config.get_json("listen/endpoints").unwrap(),
            r#"["tcp/127.0.0.1:0"]"#
        );
        assert_eq!(
            config.get_json("scouting/multicast/enabled").unwrap(),
            "false"
        );
    }

    #[test]
    fn flags_override_the_file() {
        let dir = std::env::temp_dir().join(format!("twin-replay-cli-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("zenoh.json5");
        std::fs::write(
            &file,
            r#"{ mode: "router", connect: { endpoints: ["tcp/192.0.2.1:7447"] },
                 scouting: { multicast: { enabled: false } } }"#,
        )
        .unwrap();
        let from_file = ZenohArgs {
            config: Some(file.clone()),
            ..ZenohArgs::default()
        }
        .to_config()
        .unwrap();
        assert_eq!(from_file.get_json("mode").unwrap(), r#""router""#);
        assert_eq!(
            from_file.get_json("scouting/multicast/enabled").unwrap(),
            "false"
        );
        let overridden = ZenohArgs {
            config: Some(file.clone()),
            mode: Some(Mode::Peer),
            connect: vec!["tcp/127.0.0.1:7447".into()],
            ..ZenohArgs::default()
        }
        .to_config()
        .unwrap();
        assert_eq!(overridden.get_json("mode").unwrap(), r#""peer""#);
        assert_eq!(
            overridden.get_json("connect/endpoints").unwrap(),
            r#"["tcp/127.0.0.1:7447"]"#
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn errors_name_the_flag_and_the_value() {
        let e = parse(&["--connect", "localhost:7447"]).unwrap_err();
        let text = e.to_string();
        assert!(
            text.contains("--connect") && text.contains("localhost:7447"),
            "{text}"
        );
        assert!(parse(&["--mode", "server"]).is_err());

        let e = ZenohArgs {
            listen: vec!["nonsense".into()],
            ..ZenohArgs::default()
        }
        .to_config()
        .unwrap_err();
        assert!(
            matches!(&e, ZenohConfigError::BadEndpoint { flag: "--listen", value, .. } if value == "nonsense"),
            "{e:?}"
        );
        assert!(e.to_string().contains("--listen \"nonsense\""), "{e}");

        let missing = PathBuf::from("/nonexistent/zenoh.json5");
        let e = ZenohArgs {
            config: Some(missing.clone()),
            ..ZenohArgs::default()
        }
        .to_config()
        .unwrap_err();
        assert!(
            matches!(&e, ZenohConfigError::ConfigFile { path, .. } if *path == missing),
            "{e:?}"
        );
        assert!(e.to_string().contains("/nonexistent/zenoh.json5"), "{e}");
    }
}
