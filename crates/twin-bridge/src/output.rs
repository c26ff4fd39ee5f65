//! Where the bridge's messages go: the contract's keys of one vessel over
//! Zenoh ([`ZenohOutputs`]), or anything else that implements [`Sink`]
//! (tests and the benchmark count in memory).
//!
//! The publishers are reliable with `CongestionControl::Block`, as the
//! replay tool's: when the network or a subscriber cannot keep up, a put
//! waits (and the source behind it with it) rather than drop a message.

use zenoh::Session;
use zenoh::Wait;
use zenoh::bytes::Encoding;
use zenoh::pubsub::Publisher;
use zenoh::qos::CongestionControl;

use twin_wire::{KeySpace, VesselId};

/// The keys the bridge publishes on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Key {
    /// `{prefix}/{vessel}/gnss`.
    Gnss,
    /// `{prefix}/{vessel}/actuators`.
    Actuators,
    /// `{prefix}/{vessel}/nmea`.
    Nmea,
    /// `{prefix}/{vessel}/bridge/stats`.
    Stats,
}

/// The key of the bridge's counts.
pub fn stats_key(keys: &KeySpace, vessel: &VesselId) -> String {
    format!("{}/{vessel}/bridge/stats", keys.prefix())
}

/// Takes the bridge's messages.
pub trait Sink: Send + Sync {
    /// Publishes `payload` on `key`; `Err` says why it could not.
    fn put(&self, key: Key, payload: Vec<u8>) -> Result<(), String>;
}

/// The four publishers of one vessel.
pub struct ZenohOutputs {
    gnss: Publisher<'static>,
    actuators: Publisher<'static>,
    nmea: Publisher<'static>,
    stats: Publisher<'static>,
}

impl ZenohOutputs {
    /// Declares the publishers on `session`.
    pub fn declare(
        session: &Session,
        keys: &KeySpace,
        vessel: &VesselId,
    ) -> Result<Self, zenoh::Error> {
        let declare = |key: String, encoding: Encoding| {
            session
                .declare_publisher(key)
                .congestion_control(CongestionControl::Block)
                .encoding(encoding)
                .wait()
        };
        Ok(Self {
            gnss: declare(keys.gnss(vessel), Encoding::APPLICATION_JSON)?,
            actuators: declare(keys.actuators(vessel), Encoding::APPLICATION_JSON)?,
            nmea: declare(keys.nmea(vessel), Encoding::TEXT_PLAIN)?,
            stats: declare(stats_key(keys, vessel), Encoding::APPLICATION_JSON)?,
        })
    }
}

impl Sink for ZenohOutputs {
    fn put(&self, key: Key, payload: Vec<u8>) -> Result<(), String> {
        let publisher = match key {
            Key::Gnss => &self.gnss,
            Key::Actuators => &self.actuators,
            Key::Nmea => &self.nmea,
            Key::Stats => &self.stats,
        };
        publisher.put(payload).wait().map_err(|e| e.to_string())
    }
}
