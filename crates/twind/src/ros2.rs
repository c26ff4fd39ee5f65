//! ROS 2 over rmw_zenoh, on the daemon's own Zenoh session (no bridge, no
//! extra router): with `[ros2] enabled = true` the daemon is a ROS 2 node
//! (`{namespace}/{node_name}`, `/usv/twind` by default) in domain
//! `domain_id` that publishes each vessel's fault, state and prediction as
//! standard ROS 2 messages, and takes GNSS fixes from ROS 2 GNSS drivers.
//! The messages, their CDR and the mapping are `twin_wire::ros2`'s; this
//! module makes the Zenoh calls.
//!
//! What it declares, as rmw_zenoh does (`twin_wire::ros2::rmw`): a node
//! liveliness token; per vessel, at its first output, a publisher
//! liveliness token for each of `{namespace}/{vessel}/twin/odometry`,
//! `.../fix`, `.../fault` and `.../prediction` (dropped with the vessel's
//! task); each publication on the topic's data key with the attachment
//! (sequence number, source time stamp, GID) that an rmw_zenoh
//! subscription requires. Inputs: four subscribers on the data keys of
//! `{namespace}/{own}/fix`, `.../vel`, `.../heading` and `.../imu`; each completed fix
//! goes, as the contract's JSON fix, through the daemon's dispatcher like
//! a fix on `{prefix}/{vessel}/gnss`. What cannot be read (bad CDR, no
//! fix, no velocity near the fix, a value out of range) is refused with a
//! reason (`ros2_bad_cdr`, `ros2_no_fix`, `ros2_no_velocity`, or the JSON
//! path's own) and counted in the daemon's statistics. rmw_zenoh
//! publishers drop messages under congestion (all but KEEP_ALL +
//! TRANSIENT_LOCAL topics), so a sender whose daemon falls behind loses
//! them on its own side: the gaps in each publisher's sequence numbers
//! are counted as `ros2_missed`.
//!
//! In ROS names a vessel id's `-` is written `_` (ROS names allow letters,
//! digits and `_`); the input's vessel is the id as the topic spells it.

use std::collections::HashMap;
use std::sync::atomic::{AtomicI64, AtomicU32, Ordering};
use std::sync::{Arc, Mutex};

use serde::Deserialize;
use twin_wire::outputs::{FaultMessage, PredictionMessage, StateMessage};
use twin_wire::ros2::input::{GnssTopic, NavSatInput};
use twin_wire::ros2::map::{Frames, estimated_fix, fault_diagnostics, odometry, prediction_path};
use twin_wire::ros2::msgs::{
    DiagnosticArray, NavSatFix, Odometry, Path, RosMessage, dds_type_name,
};
use twin_wire::ros2::rmw::{
    Attachment, Endpoint, EntityKind, NodeIdentity, QOS_KEEP_LAST_10, SequenceGaps, gid_of,
    topic_key,
};
use zenoh::Session;
use zenoh::bytes::ZBytes;
use zenoh::key_expr::KeyExpr;
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Subscriber;
use zenoh::qos::CongestionControl;

use crate::dispatch::Dispatcher;
use crate::settings::{Settings, SettingsError};
use crate::vessel::declare_key;

/// `[ros2]` as read.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawRos2 {
    enabled: Option<bool>,
    domain_id: Option<u32>,
    namespace: Option<String>,
    node_name: Option<String>,
    max_gap_s: Option<f64>,
}

/// `[ros2]`, validated.
#[derive(Debug, Clone, PartialEq)]
pub struct Ros2Settings {
    /// Publish and subscribe as a ROS 2 node (default false).
    pub enabled: bool,
    /// The ROS domain id (`ROS_DOMAIN_ID`), default 0.
    pub domain_id: u32,
    /// The namespace of the node and of every topic, default `/usv`.
    pub namespace: String,
    /// The node's name, default `twind`.
    pub node_name: String,
    /// How far apart in time a fix and the velocity or heading it takes may
    /// be, s (default 0.5).
    pub max_gap_s: f64,
}

/// A ROS name token: a letter or `_`, then letters, digits and `_`.
fn ros_token(s: &str) -> bool {
    let mut chars = s.chars();
    chars
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

impl Ros2Settings {
    pub(crate) fn from_raw(raw: RawRos2) -> Result<Self, SettingsError> {
        let invalid = |key, reason: String| SettingsError::Invalid { key, reason };
        let namespace = raw.namespace.unwrap_or_else(|| "/usv".to_string());
        let ns_ok = namespace
            .strip_prefix('/')
            .is_some_and(|rest| rest.is_empty() || rest.split('/').all(ros_token));
        if !ns_ok {
            return Err(invalid(
                "ros2.namespace",
                format!("{namespace:?}: an absolute ROS namespace such as /usv"),
            ));
        }
        let node_name = raw.node_name.unwrap_or_else(|| "twind".to_string());
        if !ros_token(&node_name) {
            return Err(invalid(
                "ros2.node_name",
                format!("{node_name:?}: letters, digits and _, not starting with a digit"),
            ));
        }
        let max_gap_s = raw.max_gap_s.unwrap_or(0.5);
        if !(max_gap_s.is_finite() && max_gap_s > 0.0) {
            return Err(invalid(
                "ros2.max_gap_s",
                format!("{max_gap_s}: must be > 0"),
            ));
        }
        Ok(Self {
            enabled: raw.enabled.unwrap_or(false),
            domain_id: raw.domain_id.unwrap_or(0),
            namespace: namespace.trim_end_matches('/').to_string(),
            node_name,
            max_gap_s,
        })
    }

    /// The ROS name of a vessel's topic `suffix` (e.g. `twin/fault`).
    pub fn topic(&self, vessel: &str, suffix: &str) -> String {
        format!("{}/{}/{suffix}", self.namespace, vessel.replace('-', "_"))
    }

    /// The data key of topic `name` of type `T`.
    pub fn data_key<T: RosMessage>(&self, name: &str) -> String {
        topic_key(
            self.domain_id,
            name,
            &dds_type_name(T::TYPE_NAME),
            T::TYPE_HASH,
        )
    }
}

/// The daemon's ROS 2 node: its identity and the ids of its entities.
#[derive(Debug)]
pub struct Ros2Node {
    settings: Ros2Settings,
    identity: NodeIdentity,
    next_entity_id: AtomicU32,
}

impl Ros2Node {
    /// The node of `session` with `settings`.
    pub fn new(settings: Ros2Settings, session: &Session) -> Self {
        let identity = NodeIdentity {
            domain_id: settings.domain_id,
            zid: session.zid().to_string(),
            node_id: 0,
            enclave: "/".to_string(),
            namespace: if settings.namespace.is_empty() {
                "/".to_string()
            } else {
                settings.namespace.clone()
            },
            name: settings.node_name.clone(),
        };
        Self {
            settings,
            identity,
            next_entity_id: AtomicU32::new(1),
        }
    }

    /// The node's liveliness key.
    pub fn token_key(&self) -> String {
        self.identity.node_token()
    }
}

/// One ROS 2 publisher: its data key, liveliness token, GID and count.
struct RosPublisher {
    key: KeyExpr<'static>,
    _token: Option<LivelinessToken>,
    gid: [u8; 16],
    sequence: AtomicI64,
}

impl RosPublisher {
    fn declare<T: RosMessage>(
        node: &Ros2Node,
        session: &Session,
        name: &str,
    ) -> zenoh::Result<Self> {
        let dds_type = dds_type_name(T::TYPE_NAME);
        let key = KeyExpr::try_from(node.settings.data_key::<T>(name))?;
        let id = node.next_entity_id.fetch_add(1, Ordering::Relaxed);
        let token_key = node.identity.token(
            id,
            EntityKind::Publisher,
            Some(Endpoint {
                topic: name,
                dds_type: &dds_type,
                type_hash: T::TYPE_HASH,
                qos: QOS_KEEP_LAST_10,
            }),
        );
        let token = zenoh::Wait::wait(session.liveliness().declare_token(token_key.clone()))
            .map_err(|e| tracing::warn!(%token_key, "no liveliness token: {e}"))
            .ok();
        Ok(Self {
            key: declare_key(session, key),
            _token: token,
            gid: gid_of(&token_key),
            sequence: AtomicI64::new(1),
        })
    }

    async fn put<T: RosMessage>(&self, session: &Session, message: &T) {
        let now_ns = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| i64::try_from(d.as_nanos()).unwrap_or(i64::MAX));
        let attachment = Attachment {
            sequence_number: self.sequence.fetch_add(1, Ordering::Relaxed),
            source_timestamp_ns: now_ns,
            source_gid: self.gid,
        };
        let put = session
            .put(&self.key, message.to_cdr())
            .attachment(ZBytes::from(attachment.to_bytes().to_vec()))
            .congestion_control(CongestionControl::Block)
            .await;
        if let Err(e) = put {
            tracing::warn!(key = %self.key, "ROS 2 message not published: {e}");
        }
    }
}

/// One vessel's ROS 2 publishers, declared at its first output and
/// undeclared (tokens dropped) with the vessel's task.
pub struct VesselPublishers {
    frames: Frames,
    odometry: RosPublisher,
    fix: RosPublisher,
    fault: RosPublisher,
    prediction: RosPublisher,
}

impl VesselPublishers {
    /// Declares the publishers of `vessel`.
    pub fn declare(node: &Ros2Node, session: &Session, vessel: &str) -> zenoh::Result<Self> {
        let topic = |suffix| node.settings.topic(vessel, suffix);
        Ok(Self {
            frames: Frames::of(&vessel.replace('-', "_")),
            odometry: RosPublisher::declare::<Odometry>(node, session, &topic("twin/odometry"))?,
            fix: RosPublisher::declare::<NavSatFix>(node, session, &topic("twin/fix"))?,
            fault: RosPublisher::declare::<DiagnosticArray>(node, session, &topic("twin/fault"))?,
            prediction: RosPublisher::declare::<Path>(node, session, &topic("twin/prediction"))?,
        })
    }

    /// Publishes a state as `Odometry` and `NavSatFix`.
    pub async fn state(&self, session: &Session, state: &StateMessage) {
        self.odometry
            .put(session, &odometry(state, &self.frames))
            .await;
        self.fix
            .put(session, &estimated_fix(state, &self.frames))
            .await;
    }

    /// Publishes a fault picture as `DiagnosticArray`.
    pub async fn fault(&self, session: &Session, fault: &FaultMessage) {
        self.fault.put(session, &fault_diagnostics(fault)).await;
    }

    /// Publishes a forecast (its JSON payload) as `Path`.
    pub async fn prediction(&self, session: &Session, json: &[u8]) {
        match serde_json::from_slice::<PredictionMessage>(json) {
            Ok(p) => {
                self.prediction
                    .put(session, &prediction_path(&p, &self.frames))
                    .await;
            }
            Err(e) => tracing::error!("a forecast that does not read back: {e}"),
        }
    }
}

/// The GNSS input: one subscriber per topic and each vessel's pending
/// velocity and heading.
pub(crate) struct Ros2Input {
    subscribers: Vec<Subscriber<()>>,
}

/// What the input subscribers share.
struct InputState {
    settings: Arc<Settings>,
    dispatcher: Dispatcher,
    /// `{domain}/{namespace}/`: what precedes the vessel in a data key.
    key_head: String,
    /// Each vessel's pending velocity and heading (at most `max_vessels`
    /// plus the known ones).
    pending: Mutex<HashMap<String, NavSatInput>>,
    /// The gaps in each publisher's sequence numbers.
    gaps: Mutex<SequenceGaps>,
}

impl InputState {
    /// Counts the messages the publisher of `attachment` numbered before it
    /// that never arrived.
    fn note_sequence(&self, attachment: Option<&ZBytes>) {
        let Some(attachment) = attachment.and_then(|a| Attachment::from_bytes(&a.to_bytes()))
        else {
            return;
        };
        let missed = match self.gaps.lock() {
            Ok(mut gaps) => gaps.note(&attachment),
            Err(_) => return,
        };
        self.dispatcher.missed_upstream(missed);
    }

    fn on_sample(&self, topic: GnssTopic, key: &str, payload: &[u8]) {
        let vessel = key
            .strip_prefix(self.key_head.as_str())
            .and_then(|rest| rest.split('/').next())
            .unwrap_or_default();
        if let Err(e) = twin_wire::keys::validate_vessel_id(vessel) {
            self.dispatcher
                .refuse(key, "bad_key", &format_args!("{key}: {e}"));
            return;
        }
        let done = {
            let Ok(mut pending) = self.pending.lock() else {
                return;
            };
            let cap = self.settings.vessels.max_vessels + self.settings.vessels.known.len();
            if !pending.contains_key(vessel) && pending.len() >= cap {
                drop(pending);
                self.dispatcher.refuse(
                    vessel,
                    "too_many_vessels",
                    &format_args!("ROS 2 input, {cap} vessels"),
                );
                return;
            }
            let max_gap_s = self.settings.ros2.max_gap_s;
            pending
                .entry(vessel.to_string())
                .or_insert_with(|| NavSatInput::new(max_gap_s))
                .push(topic, payload)
        };
        match done {
            Ok(None) => {}
            Ok(Some(fix)) => match (serde_json::to_vec(&fix), twin_wire::VesselId::new(vessel)) {
                (Ok(json), Ok(id)) => match KeyExpr::try_from(self.settings.keys.gnss(&id)) {
                    Ok(gnss_key) => self.dispatcher.on_message(&gnss_key, &ZBytes::from(json)),
                    Err(e) => self.dispatcher.refuse(vessel, "bad_key", &e),
                },
                _ => self
                    .dispatcher
                    .refuse(vessel, "ros2_bad_fix", &"not encodable"),
            },
            Err(e) => {
                let detail = format_args!("{} on {key}: {e}", topic.name());
                self.dispatcher.refuse(vessel, e.reason(), &detail);
            }
        }
    }
}

impl Ros2Input {
    /// Subscribes to `fix`, `vel`, `heading` and `imu` of the vessels this daemon
    /// owns, feeding `dispatcher`.
    pub(crate) async fn start(
        session: &Session,
        settings: Arc<Settings>,
        dispatcher: Dispatcher,
    ) -> anyhow::Result<Self> {
        let ros = &settings.ros2;
        let key_head = format!(
            "{}/{}/",
            ros.domain_id,
            ros.namespace.trim_start_matches('/')
        );
        let key_head = key_head.replace("//", "/");
        let state = Arc::new(InputState {
            settings: settings.clone(),
            dispatcher,
            key_head,
            pending: Mutex::new(HashMap::new()),
            // Three topics per vessel, each usually one publisher.
            gaps: Mutex::new(SequenceGaps::new(
                3 * (settings.vessels.max_vessels + settings.vessels.known.len()),
            )),
        });
        let mut subscribers = Vec::new();
        for topic in GnssTopic::ALL {
            let name = format!(
                "{}/{}/{}",
                ros.namespace,
                settings.vessels.own,
                topic.name()
            );
            let key = topic_key(
                ros.domain_id,
                &name,
                &dds_type_name(topic.type_name()),
                topic.type_hash(),
            );
            let state = state.clone();
            let sub = session
                .declare_subscriber(key.clone())
                .callback(move |sample| {
                    state.note_sequence(sample.attachment());
                    let payload = sample.payload().to_bytes();
                    state.on_sample(topic, sample.key_expr().as_str(), &payload);
                })
                .await
                .map_err(|e| anyhow::anyhow!("cannot subscribe to {key}: {e}"))?;
            subscribers.push(sub);
        }
        Ok(Self { subscribers })
    }

    /// Undeclares the subscribers (before the dispatcher closes).
    pub(crate) async fn stop(self) {
        for s in self.subscribers {
            if let Err(e) = s.undeclare().await {
                tracing::warn!("a ROS 2 input subscriber was not undeclared: {e}");
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_are_validated_and_names_are_ros_names() {
        let s = Settings::from_toml("[ros2]\nenabled = true\ndomain_id = 7\n").unwrap();
        assert!(s.ros2.enabled);
        assert_eq!(
            s.ros2.topic("otter-1", "twin/fault"),
            "/usv/otter_1/twin/fault"
        );
        assert_eq!(
            s.ros2
                .data_key::<DiagnosticArray>("/usv/otter_1/twin/fault"),
            format!(
                "7/usv/otter_1/twin/fault/diagnostic_msgs::msg::dds_::DiagnosticArray_/{}",
                DiagnosticArray::TYPE_HASH
            )
        );
        for bad in [
            "[ros2]\nnamespace = \"usv\"\n",
            "[ros2]\nnamespace = \"/u-s-v\"\n",
            "[ros2]\nnode_name = \"1twind\"\n",
            "[ros2]\nmax_gap_s = 0.0\n",
            "[ros2]\nbogus = 1\n",
        ] {
            assert!(Settings::from_toml(bad).is_err(), "{bad}");
        }
        assert!(!Settings::default().ros2.enabled);
    }
}
