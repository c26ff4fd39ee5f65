//! Zenoh key expressions of the contract (docs/contracts.md): vessel ids, the topic
//! of each key, building keys under a configurable prefix and parsing a
//! received key back into (vessel, topic).
//!
//! A vessel id is one key chunk made of ASCII letters, digits, `-` and `_`,
//! 1 to 64 characters. Everything else (`/`, `*`, `$`, spaces, non-ASCII,
//! empty, too long) is rejected: the id is put into key expressions, so a
//! `*` or a `/` in it would widen a subscription or address another key.

use std::fmt;
use std::str::FromStr;

/// The default key prefix.
pub const DEFAULT_PREFIX: &str = "asv";

/// The verbatim chunk under the prefix that holds the daemons' own keys
/// ([`KeySpace::daemon_stats`]).
pub const DAEMON_CHUNK: &str = "@twind";

/// The longest vessel id accepted, in characters.
pub const MAX_VESSEL_ID_LEN: usize = 64;

/// Why a vessel id, a prefix or a received key is rejected.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum KeyError {
    /// The vessel id is empty.
    #[error("vessel id is empty")]
    EmptyVesselId,
    /// The vessel id is longer than [`MAX_VESSEL_ID_LEN`] characters.
    #[error("vessel id is {len} characters long, at most {MAX_VESSEL_ID_LEN} are allowed")]
    VesselIdTooLong {
        /// Its length in bytes.
        len: usize,
    },
    /// The vessel id has a character other than a letter, digit, `-` or `_`.
    #[error("vessel id has a forbidden character {ch:?} at byte {index}")]
    VesselIdBadChar {
        /// The first forbidden character.
        ch: char,
        /// Its byte index in the id.
        index: usize,
    },
    /// The prefix is empty, has an empty chunk (`a//b`, a leading or trailing
    /// `/`) or a character outside letters, digits, `-`, `_` and `.`
    /// (wildcards and `$` are not allowed in a prefix).
    #[error("invalid key prefix")]
    BadPrefix,
    /// The received key does not start with this key space's prefix followed
    /// by `/`.
    #[error("key does not start with the prefix")]
    WrongPrefix,
    /// The received key has no topic after the vessel id.
    #[error("key has no topic after the vessel id")]
    MissingTopic,
    /// The part after the vessel id is not one of the contract's topics.
    #[error("unknown topic")]
    UnknownTopic,
}

/// A validated vessel id (see the module doc for the rule).
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct VesselId(String);

impl VesselId {
    /// Validates `id` as a vessel id.
    pub fn new(id: &str) -> Result<Self, KeyError> {
        validate_vessel_id(id)?;
        Ok(Self(id.to_owned()))
    }

    /// The id as text.
    pub fn as_str(&self) -> &str {
        &self.0
    }
}

/// Checks the vessel id rule without allocating.
pub fn validate_vessel_id(id: &str) -> Result<(), KeyError> {
    if id.is_empty() {
        return Err(KeyError::EmptyVesselId);
    }
    if let Some((index, ch)) = id
        .char_indices()
        .find(|(_, c)| !(c.is_ascii_alphanumeric() || *c == '-' || *c == '_'))
    {
        return Err(KeyError::VesselIdBadChar { ch, index });
    }
    if id.len() > MAX_VESSEL_ID_LEN {
        return Err(KeyError::VesselIdTooLong { len: id.len() });
    }
    Ok(())
}

impl FromStr for VesselId {
    type Err = KeyError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::new(s)
    }
}

impl fmt::Display for VesselId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl AsRef<str> for VesselId {
    fn as_ref(&self) -> &str {
        &self.0
    }
}

/// The topic of a key: what comes after `{prefix}/{vessel}/`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Topic {
    /// `gnss`: JSON GNSS fixes in.
    Gnss,
    /// `nmea`: raw NMEA 0183 text in.
    Nmea,
    /// `actuators`: JSON propeller commands in.
    Actuators,
    /// `twin/state`: the estimated state out (also a queryable).
    TwinState,
    /// `twin/fault`: thruster fault estimates out.
    TwinFault,
    /// `twin/prediction`: the predicted track out.
    TwinPrediction,
    /// `twin/alarm`: alarms out, on change only.
    TwinAlarm,
    /// `twin/alive`: the liveliness token of a running twin.
    TwinAlive,
    /// `twin/stats`: the twin's counters (samples, rejections) out.
    TwinStats,
    /// `twin/finding`: model-error findings (cause, parameters, gain) out.
    TwinFinding,
}

impl Topic {
    /// Every topic, inputs first.
    pub const ALL: [Topic; 10] = [
        Topic::Gnss,
        Topic::Nmea,
        Topic::Actuators,
        Topic::TwinState,
        Topic::TwinFault,
        Topic::TwinPrediction,
        Topic::TwinAlarm,
        Topic::TwinAlive,
        Topic::TwinStats,
        Topic::TwinFinding,
    ];

    /// The key suffix after the vessel id, e.g. `twin/state`.
    pub fn suffix(self) -> &'static str {
        match self {
            Topic::Gnss => "gnss",
            Topic::Nmea => "nmea",
            Topic::Actuators => "actuators",
            Topic::TwinState => "twin/state",
            Topic::TwinFault => "twin/fault",
            Topic::TwinPrediction => "twin/prediction",
            Topic::TwinAlarm => "twin/alarm",
            Topic::TwinAlive => "twin/alive",
            Topic::TwinStats => "twin/stats",
            Topic::TwinFinding => "twin/finding",
        }
    }

    /// The topic of a key suffix, if it is one of the contract's.
    pub fn from_suffix(suffix: &str) -> Option<Topic> {
        Topic::ALL.into_iter().find(|t| t.suffix() == suffix)
    }

    /// True for the topics the twin subscribes to (`gnss`, `nmea`, `actuators`).
    pub fn is_input(self) -> bool {
        matches!(self, Topic::Gnss | Topic::Nmea | Topic::Actuators)
    }
}

impl fmt::Display for Topic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.suffix())
    }
}

/// Builds and parses the keys of one deployment (one prefix).
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct KeySpace {
    prefix: String,
}

impl Default for KeySpace {
    fn default() -> Self {
        Self {
            prefix: DEFAULT_PREFIX.to_owned(),
        }
    }
}

impl KeySpace {
    /// A key space under `prefix` (one or more `/`-separated chunks of
    /// letters, digits, `-`, `_`, `.`; no wildcard).
    pub fn new(prefix: &str) -> Result<Self, KeyError> {
        let chunk_ok = |c: &str| {
            !c.is_empty()
                && c.bytes()
                    .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'-' | b'_' | b'.'))
        };
        if prefix.is_empty() || !prefix.split('/').all(chunk_ok) {
            return Err(KeyError::BadPrefix);
        }
        Ok(Self {
            prefix: prefix.to_owned(),
        })
    }

    /// The prefix.
    pub fn prefix(&self) -> &str {
        &self.prefix
    }

    /// The key of `topic` for `vessel`: `{prefix}/{vessel}/{suffix}`.
    pub fn key(&self, vessel: &VesselId, topic: Topic) -> String {
        format!("{}/{}/{}", self.prefix, vessel, topic.suffix())
    }

    /// The key expression matching `topic` of every vessel:
    /// `{prefix}/*/{suffix}` (for subscriptions).
    pub fn all_vessels(&self, topic: Topic) -> String {
        format!("{}/*/{}", self.prefix, topic.suffix())
    }

    /// `{prefix}/{vessel}/gnss`.
    pub fn gnss(&self, vessel: &VesselId) -> String {
        self.key(vessel, Topic::Gnss)
    }

    /// `{prefix}/{vessel}/nmea`.
    pub fn nmea(&self, vessel: &VesselId) -> String {
        self.key(vessel, Topic::Nmea)
    }

    /// `{prefix}/{vessel}/actuators`.
    pub fn actuators(&self, vessel: &VesselId) -> String {
        self.key(vessel, Topic::Actuators)
    }

    /// `{prefix}/{vessel}/twin/state`.
    pub fn twin_state(&self, vessel: &VesselId) -> String {
        self.key(vessel, Topic::TwinState)
    }

    /// `{prefix}/{vessel}/twin/fault`.
    pub fn twin_fault(&self, vessel: &VesselId) -> String {
        self.key(vessel, Topic::TwinFault)
    }

    /// `{prefix}/{vessel}/twin/prediction`.
    pub fn twin_prediction(&self, vessel: &VesselId) -> String {
        self.key(vessel, Topic::TwinPrediction)
    }

    /// `{prefix}/{vessel}/twin/alarm`.
    pub fn twin_alarm(&self, vessel: &VesselId) -> String {
        self.key(vessel, Topic::TwinAlarm)
    }

    /// `{prefix}/{vessel}/twin/alive`.
    pub fn twin_alive(&self, vessel: &VesselId) -> String {
        self.key(vessel, Topic::TwinAlive)
    }

    /// `{prefix}/{vessel}/twin/stats`.
    pub fn twin_stats(&self, vessel: &VesselId) -> String {
        self.key(vessel, Topic::TwinStats)
    }

    /// `{prefix}/{vessel}/twin/finding`.
    pub fn twin_finding(&self, vessel: &VesselId) -> String {
        self.key(vessel, Topic::TwinFinding)
    }

    /// `{prefix}/@twind/{daemon}/stats`: the daemon's own counters (what it
    /// refused before any vessel could be named or admitted). `@twind` is a
    /// verbatim chunk: no wildcard matches it, so subscriptions to
    /// `{prefix}/*/...` or `{prefix}/**` never receive it by accident (and
    /// the daemon's input subscriber never hears its own statistics); ask
    /// for `{prefix}/@twind/*/stats`. `daemon` follows the vessel id rule.
    pub fn daemon_stats(&self, daemon: &VesselId) -> String {
        format!("{}/{DAEMON_CHUNK}/{daemon}/stats", self.prefix)
    }

    /// `{prefix}/@twind/*/stats`: every daemon's statistics.
    pub fn all_daemon_stats(&self) -> String {
        format!("{}/{DAEMON_CHUNK}/*/stats", self.prefix)
    }

    /// Parses a received key into its vessel id and topic. The key must be
    /// exactly `{prefix}/{vessel}/{suffix}` with a valid id and a known topic.
    pub fn parse(&self, key: &str) -> Result<(VesselId, Topic), KeyError> {
        let (vessel, topic) = self.parse_borrowed(key)?;
        Ok((VesselId(vessel.to_owned()), topic))
    }

    /// [`KeySpace::parse`] without allocating: the vessel id (validated) is
    /// a slice of `key`.
    pub fn parse_borrowed<'k>(&self, key: &'k str) -> Result<(&'k str, Topic), KeyError> {
        let rest = key
            .strip_prefix(self.prefix.as_str())
            .and_then(|r| r.strip_prefix('/'))
            .ok_or(KeyError::WrongPrefix)?;
        let (vessel, suffix) = rest.split_once('/').ok_or(KeyError::MissingTopic)?;
        validate_vessel_id(vessel)?;
        let topic = Topic::from_suffix(suffix).ok_or(KeyError::UnknownTopic)?;
        Ok((vessel, topic))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn vessel_ids() {
        assert!(VesselId::new("otter-1_B").is_ok());
        assert!(VesselId::new(&"a".repeat(64)).is_ok());
        assert_eq!(
            VesselId::new(&"a".repeat(65)),
            Err(KeyError::VesselIdTooLong { len: 65 })
        );
        assert_eq!(VesselId::new(""), Err(KeyError::EmptyVesselId));
        for (bad, ch, index) in [
            ("a/b", '/', 1),
            ("*", '*', 0),
            ("a b", ' ', 1),
            ("$x", '$', 0),
            ("é", 'é', 0),
            ("a.b", '.', 1),
            ("**", '*', 0),
        ] {
            assert_eq!(
                VesselId::new(bad),
                Err(KeyError::VesselIdBadChar { ch, index }),
                "{bad}"
            );
        }
    }

    #[test]
    fn keys_are_the_contract_ones() {
        let ks = KeySpace::default();
        let v = VesselId::new("otter1").unwrap();
        assert_eq!(ks.gnss(&v), "asv/otter1/gnss");
        assert_eq!(ks.nmea(&v), "asv/otter1/nmea");
        assert_eq!(ks.actuators(&v), "asv/otter1/actuators");
        assert_eq!(ks.twin_state(&v), "asv/otter1/twin/state");
        assert_eq!(ks.twin_fault(&v), "asv/otter1/twin/fault");
        assert_eq!(ks.twin_prediction(&v), "asv/otter1/twin/prediction");
        assert_eq!(ks.twin_alarm(&v), "asv/otter1/twin/alarm");
        assert_eq!(ks.twin_alive(&v), "asv/otter1/twin/alive");
        assert_eq!(ks.twin_stats(&v), "asv/otter1/twin/stats");
        assert_eq!(ks.twin_finding(&v), "asv/otter1/twin/finding");
        assert_eq!(ks.all_vessels(Topic::Gnss), "asv/*/gnss");
        let d = VesselId::new("north").unwrap();
        assert_eq!(ks.daemon_stats(&d), "asv/@twind/north/stats");
        assert_eq!(ks.all_daemon_stats(), "asv/@twind/*/stats");
        // Not a vessel's key: a daemon's statistics are never taken for input.
        assert!(ks.parse(&ks.daemon_stats(&d)).is_err());
        let fleet = KeySpace::new("fleet/north.sea").unwrap();
        assert_eq!(fleet.twin_state(&v), "fleet/north.sea/otter1/twin/state");
    }

    #[test]
    fn parse_rejects_bad_keys() {
        let ks = KeySpace::default();
        assert_eq!(
            ks.parse("asv/otter1/twin/fault"),
            Ok((VesselId::new("otter1").unwrap(), Topic::TwinFault))
        );
        assert_eq!(ks.parse("asvx/otter1/gnss"), Err(KeyError::WrongPrefix));
        assert_eq!(ks.parse("other/otter1/gnss"), Err(KeyError::WrongPrefix));
        assert_eq!(ks.parse("asv/otter1"), Err(KeyError::MissingTopic));
        assert_eq!(ks.parse("asv/otter1/gps"), Err(KeyError::UnknownTopic));
        assert_eq!(ks.parse("asv/otter1/twin"), Err(KeyError::UnknownTopic));
        assert_eq!(ks.parse("asv/otter1/gnss/x"), Err(KeyError::UnknownTopic));
        assert_eq!(ks.parse("asv//gnss"), Err(KeyError::EmptyVesselId));
        assert!(matches!(
            ks.parse("asv/*/gnss"),
            Err(KeyError::VesselIdBadChar { ch: '*', .. })
        ));
    }

    #[test]
    fn prefixes() {
        for bad in ["", "/asv", "asv/", "a//b", "asv/*", "asv/**", "a$b", "a b"] {
            assert_eq!(KeySpace::new(bad), Err(KeyError::BadPrefix), "{bad}");
        }
    }

    proptest! {
        #[test]
        fn valid_keys_round_trip(id in "[A-Za-z0-9_-]{1,64}", topic in 0usize..10) {
            let ks = KeySpace::default();
            let vessel = VesselId::new(&id).unwrap();
            let t = Topic::ALL[topic];
            prop_assert_eq!(ks.parse(&ks.key(&vessel, t)), Ok((vessel, t)));
        }

        #[test]
        fn arbitrary_keys_never_panic(key in "\\PC{0,80}") {
            let ks = KeySpace::default();
            if let Ok((vessel, topic)) = ks.parse(&key) {
                // Anything accepted is exactly a key this key space builds.
                prop_assert_eq!(ks.key(&vessel, topic), key);
            }
        }
    }
}
