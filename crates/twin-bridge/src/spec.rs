//! What `--source` says: a format, a transport and its address, and
//! options, as `FORMAT:TRANSPORT[:ADDRESS][,KEY=VALUE...]`:
//!
//! | example | what |
//! |---|---|
//! | `nmea0183:udp:10110` | NMEA 0183 datagrams to port 10110, any interface (unicast or broadcast) |
//! | `nmea0183:udp:239.192.0.1:10110` | the same from a multicast group |
//! | `nmea0183:tcp:192.168.1.10:10110` | NMEA 0183 from a multiplexer's TCP server (reconnects) |
//! | `nmea0183:serial:/dev/ttyUSB0,baud=38400` | NMEA 0183 on a serial port (default 4800 baud) |
//! | `nmea0183:stdin` | NMEA 0183 on standard input |
//! | `candump:can:can0` | NMEA 2000 from a SocketCAN interface |
//! | `candump:stdin` | `candump -L can0` piped in |
//! | `ydraw:udp:1456`, `ydraw:tcp:192.168.4.1:1457` | a Yacht Devices gateway in RAW mode |
//! | `actisense:tcp:192.168.1.20:60002` | an Actisense W2K-1 in N2K ASCII |
//! | `mavlink:udp:14550` | MAVLink datagrams (ArduPilot, MAVProxy `--out`) |
//! | `mavlink:tcp:127.0.0.1:5760` | MAVLink from a TCP server (SITL, a telemetry bridge) |
//! | `mavlink:serial:/dev/ttyACM0,baud=115200` | MAVLink on the autopilot's serial port (default 57600) |
//! | `gpsd`, `gpsd:tcp:pi.local:2947` | gpsd's JSON reports (default 127.0.0.1:2947) |
//! | `gpsd:stdin` | `gpspipe -w` piped in |
//!
//! Options: `baud=N` (serial), `publish=fixes|sentences` (NMEA 0183:
//! assembled fixes on `gnss`, the default, or the checked sentences as they
//! came on `nmea`), `system=N` (MAVLink: the system to follow).

use std::fmt;
use std::net::{IpAddr, SocketAddr};
use std::path::PathBuf;
use std::str::FromStr;

/// The format of a source.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Format {
    /// NMEA 0183 sentences.
    Nmea0183,
    /// NMEA 2000 frames, candump's text or a SocketCAN interface.
    Candump,
    /// NMEA 2000 frames in Yacht Devices RAW.
    YdRaw,
    /// NMEA 2000 messages in Actisense N2K ASCII.
    Actisense,
    /// MAVLink frames.
    Mavlink,
    /// gpsd's JSON reports.
    Gpsd,
}

impl Format {
    /// The name in a source specification.
    pub fn name(self) -> &'static str {
        match self {
            Format::Nmea0183 => "nmea0183",
            Format::Candump => "candump",
            Format::YdRaw => "ydraw",
            Format::Actisense => "actisense",
            Format::Mavlink => "mavlink",
            Format::Gpsd => "gpsd",
        }
    }

    fn parse(text: &str) -> Option<Format> {
        Some(match text {
            "nmea0183" | "nmea" => Format::Nmea0183,
            "candump" | "can" | "socketcan" => Format::Candump,
            "ydraw" | "yd" => Format::YdRaw,
            "actisense" => Format::Actisense,
            "mavlink" => Format::Mavlink,
            "gpsd" => Format::Gpsd,
            _ => return None,
        })
    }

    /// Serial speed when `baud=` is not given: NMEA 0183's 4800, a
    /// telemetry radio's 57600, else 115200 (USB gateways ignore it).
    pub fn default_baud(self) -> u32 {
        match self {
            Format::Nmea0183 => 4800,
            Format::Mavlink => 57_600,
            _ => 115_200,
        }
    }
}

/// How a source is reached.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Transport {
    /// Listen for datagrams on `bind`; join `group` when it is multicast.
    Udp {
        /// The local address and port.
        bind: SocketAddr,
        /// A multicast group to join.
        group: Option<IpAddr>,
    },
    /// Connect to a TCP server, reconnecting when it closes or is away.
    Tcp {
        /// `host:port`.
        address: String,
    },
    /// A serial port, reopened when it disappears.
    Serial {
        /// The device.
        path: PathBuf,
        /// Bits per second.
        baud: u32,
    },
    /// Standard input.
    Stdin,
    /// A SocketCAN interface (Linux).
    Can {
        /// The interface name (`can0`).
        interface: String,
    },
}

impl Transport {
    /// The transport's name.
    pub fn name(&self) -> &'static str {
        match self {
            Transport::Udp { .. } => "udp",
            Transport::Tcp { .. } => "tcp",
            Transport::Serial { .. } => "serial",
            Transport::Stdin => "stdin",
            Transport::Can { .. } => "can",
        }
    }
}

/// What NMEA 0183 sources publish.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum NmeaPublish {
    /// Fixes and propeller speeds assembled here, on `gnss` and `actuators`.
    #[default]
    Fixes,
    /// The sentences that decode, as received, on `nmea` (the daemon
    /// assembles them itself).
    Sentences,
}

/// One `--source`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SourceSpec {
    /// The text given, the source's name in counts and logs.
    pub name: String,
    /// Its format.
    pub format: Format,
    /// How it is reached.
    pub transport: Transport,
    /// NMEA 0183: what is published.
    pub nmea_publish: NmeaPublish,
    /// MAVLink: the system followed.
    pub mavlink_system: Option<u8>,
}

impl fmt::Display for SourceSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.name)
    }
}

/// Why a `--source` cannot be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SpecError {
    /// The format is not one of those known.
    #[error("unknown format {0:?}: nmea0183, candump, ydraw, actisense, mavlink or gpsd")]
    Format(String),
    /// The transport is not one of those known, or not one the format
    /// comes over.
    #[error("{format} does not come over {transport:?}: use {allowed}")]
    Transport {
        /// The format.
        format: &'static str,
        /// The transport given.
        transport: String,
        /// The ones it can.
        allowed: &'static str,
    },
    /// The address does not parse.
    #[error("bad {transport} address {address:?}: {expected}")]
    Address {
        /// The transport.
        transport: &'static str,
        /// The text.
        address: String,
        /// What was expected.
        expected: &'static str,
    },
    /// An option is unknown, malformed, or does not apply.
    #[error(
        "bad option {0:?}: baud=N (serial), publish=fixes|sentences (nmea0183), system=N (mavlink)"
    )]
    Option(String),
}

fn udp(address: &str) -> Result<Transport, SpecError> {
    let bad = || SpecError::Address {
        transport: "udp",
        address: address.to_owned(),
        expected: "PORT or IP:PORT (a multicast IP is joined)",
    };
    let addr: SocketAddr = match address.parse::<u16>() {
        Ok(port) => SocketAddr::from(([0, 0, 0, 0], port)),
        Err(_) => address.parse().map_err(|_| bad())?,
    };
    if addr.ip().is_multicast() {
        let any: IpAddr = if addr.is_ipv4() {
            [0, 0, 0, 0].into()
        } else {
            std::net::Ipv6Addr::UNSPECIFIED.into()
        };
        return Ok(Transport::Udp {
            bind: SocketAddr::new(any, addr.port()),
            group: Some(addr.ip()),
        });
    }
    Ok(Transport::Udp {
        bind: addr,
        group: None,
    })
}

fn tcp(address: &str) -> Result<Transport, SpecError> {
    let ok = address
        .rsplit_once(':')
        .is_some_and(|(host, port)| !host.is_empty() && port.parse::<u16>().is_ok());
    if !ok {
        return Err(SpecError::Address {
            transport: "tcp",
            address: address.to_owned(),
            expected: "HOST:PORT",
        });
    }
    Ok(Transport::Tcp {
        address: address.to_owned(),
    })
}

impl FromStr for SourceSpec {
    type Err = SpecError;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let mut pieces = text.split(',');
        let main = pieces.next().unwrap_or("");
        let (format_text, rest) = main.split_once(':').unwrap_or((main, ""));
        let format =
            Format::parse(format_text).ok_or_else(|| SpecError::Format(format_text.to_owned()))?;
        let (transport_text, address) = rest.split_once(':').unwrap_or((rest, ""));
        let mut baud = None;
        let mut nmea_publish = NmeaPublish::Fixes;
        let mut mavlink_system = None;
        for option in pieces {
            let bad = || SpecError::Option(option.to_owned());
            let (key, value) = option.split_once('=').ok_or_else(bad)?;
            match (key, format) {
                ("baud", _) => {
                    baud = Some(
                        value
                            .parse::<u32>()
                            .ok()
                            .filter(|b| *b > 0)
                            .ok_or_else(bad)?,
                    )
                }
                ("publish", Format::Nmea0183) => {
                    nmea_publish = match value {
                        "fixes" => NmeaPublish::Fixes,
                        "sentences" => NmeaPublish::Sentences,
                        _ => return Err(bad()),
                    }
                }
                ("system", Format::Mavlink) => {
                    mavlink_system = Some(value.parse::<u8>().map_err(|_| bad())?)
                }
                _ => return Err(bad()),
            }
        }
        let allowed = match format {
            Format::Nmea0183 => "udp, tcp, serial or stdin",
            Format::Candump => "can, stdin, tcp or udp",
            Format::YdRaw => "udp, tcp, serial or stdin",
            Format::Actisense => "tcp, udp or stdin",
            Format::Mavlink => "udp, tcp, serial or stdin",
            Format::Gpsd => "tcp (default 127.0.0.1:2947) or stdin",
        };
        let wrong = || SpecError::Transport {
            format: format.name(),
            transport: transport_text.to_owned(),
            allowed,
        };
        let transport = match (format, transport_text) {
            (Format::Gpsd, "") => Transport::Tcp {
                address: "127.0.0.1:2947".to_owned(),
            },
            (Format::Gpsd, "tcp") => tcp(address)?,
            (Format::Gpsd, "stdin") if address.is_empty() => Transport::Stdin,
            (Format::Gpsd, _) => return Err(wrong()),
            (Format::Candump, "can") => {
                if address.is_empty() || address.len() > 15 {
                    return Err(SpecError::Address {
                        transport: "can",
                        address: address.to_owned(),
                        expected: "an interface name such as can0",
                    });
                }
                Transport::Can {
                    interface: address.to_owned(),
                }
            }
            (_, "can") => return Err(wrong()),
            (_, "udp") => udp(address)?,
            (_, "tcp") => tcp(address)?,
            (Format::Actisense | Format::Candump, "serial") => return Err(wrong()),
            (_, "serial") => {
                if address.is_empty() {
                    return Err(SpecError::Address {
                        transport: "serial",
                        address: String::new(),
                        expected: "a device such as /dev/ttyUSB0",
                    });
                }
                Transport::Serial {
                    path: PathBuf::from(address),
                    baud: baud.unwrap_or(format.default_baud()),
                }
            }
            (_, "stdin") if address.is_empty() => Transport::Stdin,
            _ => return Err(wrong()),
        };
        if baud.is_some() && !matches!(transport, Transport::Serial { .. }) {
            return Err(SpecError::Option(format!("baud={}", baud.unwrap_or(0))));
        }
        Ok(SourceSpec {
            name: text.to_owned(),
            format,
            transport,
            nmea_publish,
            mavlink_system,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_documented_examples_parse() {
        let s: SourceSpec = "nmea0183:udp:10110".parse().unwrap();
        assert_eq!(
            s.transport,
            Transport::Udp {
                bind: "0.0.0.0:10110".parse().unwrap(),
                group: None
            }
        );
        let s: SourceSpec = "nmea0183:udp:239.192.0.1:10110".parse().unwrap();
        assert_eq!(
            s.transport,
            Transport::Udp {
                bind: "0.0.0.0:10110".parse().unwrap(),
                group: Some("239.192.0.1".parse().unwrap())
            }
        );
        let s: SourceSpec = "nmea0183:serial:/dev/ttyUSB0,baud=38400,publish=sentences"
            .parse()
            .unwrap();
        assert_eq!(
            s.transport,
            Transport::Serial {
                path: "/dev/ttyUSB0".into(),
                baud: 38_400
            }
        );
        assert_eq!(s.nmea_publish, NmeaPublish::Sentences);
        let s: SourceSpec = "mavlink:serial:/dev/ttyACM0".parse().unwrap();
        assert_eq!(
            s.transport,
            Transport::Serial {
                path: "/dev/ttyACM0".into(),
                baud: 57_600
            }
        );
        let s: SourceSpec = "mavlink:udp:[::]:14550,system=1".parse().unwrap();
        assert_eq!(s.mavlink_system, Some(1));
        let s: SourceSpec = "gpsd".parse().unwrap();
        assert_eq!(
            s.transport,
            Transport::Tcp {
                address: "127.0.0.1:2947".into()
            }
        );
        for ok in [
            "nmea0183:tcp:192.168.1.10:10110",
            "nmea0183:stdin",
            "candump:can:can0",
            "candump:stdin",
            "ydraw:udp:1456",
            "ydraw:tcp:192.168.4.1:1457",
            "actisense:tcp:192.168.1.20:60002",
            "mavlink:tcp:127.0.0.1:5760",
            "gpsd:tcp:pi.local:2947",
        ] {
            assert!(ok.parse::<SourceSpec>().is_ok(), "{ok}");
        }
    }

    #[test]
    fn mistakes_are_named() {
        for (bad, what) in [
            ("nmea2000:udp:1", "unknown format"),
            ("nmea0183:can:can0", "does not come over"),
            ("gpsd:udp:2947", "does not come over"),
            ("nmea0183:udp:notaport", "bad udp address"),
            ("nmea0183:tcp:10110", "bad tcp address"),
            ("nmea0183:serial:", "bad serial address"),
            ("nmea0183:udp:10110,baud=4800", "bad option"),
            ("nmea0183:udp:10110,system=1", "bad option"),
            ("mavlink:udp:14550,system=300", "bad option"),
            ("nmea0183:stdin:x", "does not come over"),
        ] {
            let e = bad.parse::<SourceSpec>().unwrap_err().to_string();
            assert!(e.contains(what), "{bad}: {e}");
        }
    }
}
