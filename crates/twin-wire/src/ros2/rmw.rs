//! What rmw_zenoh (`rmw_zenoh_cpp` 0.2 and later: ROS 2 Jazzy, Kilted)
//! expects of a Zenoh peer that publishes or subscribes as a ROS 2 node:
//! the key of a topic's data, the liveliness tokens of the graph, and the
//! attachment on every publication. Pure string and byte building; the
//! daemon does the Zenoh calls.
//!
//! - A topic's data key: `{domain_id}/{topic without its outer slashes}/{dds
//!   type name}/{RIHS01 type hash}`, e.g.
//!   `0/usv/otter1/twin/fault/diagnostic_msgs::msg::dds_::DiagnosticArray_/RIHS01_5a8a...`.
//! - A liveliness token per node and per publisher or subscription:
//!   `@ros2_lv/{domain_id}/{zenoh session id}/{node id}/{entity id}/{NN|MP|MS}/{enclave}/{namespace}/{node name}`
//!   and, for a publisher or subscription, `/{topic}/{dds type name}/{type
//!   hash}/{qos}`; every `/` inside a name is written `%` (the root
//!   enclave `/` is `%`, the namespace `/usv` is `%usv`).
//! - The QoS chunk: `reliability:durability:history,depth:deadline
//!   s,ns:lifespan s,ns:liveliness,lease s,ns`, each field left empty when
//!   it is rmw_zenoh's default (reliable, volatile, keep last 42, infinite
//!   durations, automatic liveliness).
//! - The attachment of each publication: the sequence number (`int64`,
//!   little endian), the source time stamp (`int64` ns since the Unix
//!   epoch), then the publisher's 16-byte GID as a sequence: its length as
//!   a LEB128 varint (`0x10`) and the bytes. A subscription of rmw_zenoh
//!   drops a sample without one. The GID is the XXH3 128-bit hash of the
//!   publisher's liveliness key, low 64 bits first, as rmw_zenoh computes it.

/// The verbatim chunk of the ROS 2 graph's liveliness tokens.
pub const ADMIN_SPACE: &str = "@ros2_lv";

/// The length of a ROS 2 GID, bytes.
pub const GID_BYTES: usize = 16;

/// The QoS chunk of the twin's publishers and subscriptions: reliable,
/// volatile, keep last 10 (every other field rmw_zenoh's default).
pub const QOS_KEEP_LAST_10: &str = "::,10:,:,:,,";

/// rmw_zenoh's escaping of a name in a liveliness key: `/` becomes `%`.
pub fn mangle(name: &str) -> String {
    name.replace('/', "%")
}

/// The key of a topic's data for `domain_id`: the topic name without its
/// leading and trailing `/`, between the domain and the type.
pub fn topic_key(domain_id: u32, topic: &str, dds_type: &str, type_hash: &str) -> String {
    format!(
        "{domain_id}/{}/{dds_type}/{type_hash}",
        topic.trim_matches('/')
    )
}

/// A ROS 2 node as the graph sees it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NodeIdentity {
    /// The ROS domain id.
    pub domain_id: u32,
    /// The Zenoh session id, as Zenoh prints it.
    pub zid: String,
    /// The node's id within the session.
    pub node_id: u32,
    /// The enclave, `/` by default.
    pub enclave: String,
    /// The namespace, starting with `/`.
    pub namespace: String,
    /// The node's name.
    pub name: String,
}

/// What a liveliness token announces.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EntityKind {
    /// The node itself (`NN`).
    Node,
    /// A publisher (`MP`).
    Publisher,
    /// A subscription (`MS`).
    Subscription,
}

impl EntityKind {
    fn code(self) -> &'static str {
        match self {
            EntityKind::Node => "NN",
            EntityKind::Publisher => "MP",
            EntityKind::Subscription => "MS",
        }
    }
}

/// A topic endpoint: its name, types and QoS chunk.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Endpoint<'a> {
    /// The fully qualified topic name, e.g. `/usv/otter1/twin/fault`.
    pub topic: &'a str,
    /// The dds type name ([`super::msgs::dds_type_name`]).
    pub dds_type: &'a str,
    /// The RIHS01 type hash.
    pub type_hash: &'a str,
    /// The QoS chunk, e.g. [`QOS_KEEP_LAST_10`].
    pub qos: &'a str,
}

impl NodeIdentity {
    /// The node's own token (entity id = node id, as rmw_zenoh does).
    pub fn node_token(&self) -> String {
        self.token(self.node_id, EntityKind::Node, None)
    }

    /// The liveliness key of entity `entity_id` of kind `kind`; `endpoint`
    /// for a publisher or subscription.
    pub fn token(
        &self,
        entity_id: u32,
        kind: EntityKind,
        endpoint: Option<Endpoint<'_>>,
    ) -> String {
        let mut key = format!(
            "{ADMIN_SPACE}/{}/{}/{}/{entity_id}/{}/{}/{}/{}",
            self.domain_id,
            self.zid,
            self.node_id,
            kind.code(),
            mangle(&self.enclave),
            mangle(&self.namespace),
            mangle(&self.name),
        );
        if let Some(e) = endpoint {
            key.push_str(&format!(
                "/{}/{}/{}/{}",
                mangle(e.topic),
                mangle(e.dds_type),
                mangle(e.type_hash),
                e.qos
            ));
        }
        key
    }
}

/// The GID rmw_zenoh derives from an entity's liveliness key.
pub fn gid_of(liveliness_key: &str) -> [u8; GID_BYTES] {
    xxhash_rust::xxh3::xxh3_128(liveliness_key.as_bytes()).to_le_bytes()
}

/// The attachment of one publication.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Attachment {
    /// The publisher's sequence number (from 0 or 1, one more each time).
    pub sequence_number: i64,
    /// When it was published, ns since the Unix epoch.
    pub source_timestamp_ns: i64,
    /// The publisher's GID.
    pub source_gid: [u8; GID_BYTES],
}

/// The attachment's size, bytes.
pub const ATTACHMENT_BYTES: usize = 8 + 8 + 1 + GID_BYTES;

impl Attachment {
    /// The attachment's bytes (Zenoh's `zenoh-ext` serialization of an
    /// `(i64, i64, [u8; 16])` as rmw_zenoh writes it).
    pub fn to_bytes(&self) -> [u8; ATTACHMENT_BYTES] {
        let mut out = [0u8; ATTACHMENT_BYTES];
        out[..8].copy_from_slice(&self.sequence_number.to_le_bytes());
        out[8..16].copy_from_slice(&self.source_timestamp_ns.to_le_bytes());
        out[16] = GID_BYTES as u8;
        out[17..].copy_from_slice(&self.source_gid);
        out
    }

    /// Reads an attachment; `None` unless it is exactly one.
    pub fn from_bytes(bytes: &[u8]) -> Option<Self> {
        if bytes.len() != ATTACHMENT_BYTES || bytes[16] as usize != GID_BYTES {
            return None;
        }
        let mut seq = [0u8; 8];
        seq.copy_from_slice(&bytes[..8]);
        let mut ts = [0u8; 8];
        ts.copy_from_slice(&bytes[8..16]);
        let mut source_gid = [0u8; GID_BYTES];
        source_gid.copy_from_slice(&bytes[17..]);
        Some(Self {
            sequence_number: i64::from_le_bytes(seq),
            source_timestamp_ns: i64::from_le_bytes(ts),
            source_gid,
        })
    }
}

/// The largest jump in a publisher's sequence numbers counted as missed
/// messages: about three hours of a 100 Hz topic.
pub const MAX_SEQUENCE_GAP: u64 = 1_000_000;

/// The messages each ROS 2 publisher numbered but that never arrived: the
/// gaps in its attachments' sequence numbers. rmw_zenoh publishes with
/// Zenoh's `Drop` congestion control on every topic but KEEP_ALL +
/// TRANSIENT_LOCAL ones, so a sender whose receiver falls behind loses
/// messages on its own side; only these gaps tell the receiver.
///
/// A sequence number at or below the last one seen (a restarted
/// publisher, or a message overtaken), or further ahead than
/// [`MAX_SEQUENCE_GAP`] (not a gap a live publisher leaves: a new one
/// under a reused GID, or garbage), starts the count again from it and
/// counts nothing. At most `max_publishers` are tracked; a new one beyond
/// that forgets all (a flood of made-up GIDs costs bounded memory, and
/// a real publisher's next gap is counted from its next message).
#[derive(Debug, Clone)]
pub struct SequenceGaps {
    last: std::collections::HashMap<[u8; GID_BYTES], i64>,
    max_publishers: usize,
}

impl SequenceGaps {
    /// Tracks at most `max_publishers` publishers at once.
    pub fn new(max_publishers: usize) -> Self {
        Self {
            last: std::collections::HashMap::new(),
            max_publishers: max_publishers.max(1),
        }
    }

    /// Notes one publication; returns how many of its publisher's messages
    /// went missing just before it.
    pub fn note(&mut self, attachment: &Attachment) -> u64 {
        let seq = attachment.sequence_number;
        let gid = attachment.source_gid;
        if !self.last.contains_key(&gid) && self.last.len() >= self.max_publishers {
            self.last.clear();
        }
        match self.last.insert(gid, seq) {
            // In i128: two i64 numbers far apart do not overflow.
            Some(last) => u64::try_from(i128::from(seq) - i128::from(last) - 1)
                .ok()
                .filter(|gap| *gap <= MAX_SEQUENCE_GAP)
                .unwrap_or(0),
            None => 0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn from(gid: u8, sequence_number: i64) -> Attachment {
        Attachment {
            sequence_number,
            source_timestamp_ns: 0,
            source_gid: [gid; GID_BYTES],
        }
    }

    #[test]
    fn sequence_gaps_count_what_each_publisher_skipped_and_nothing_else() {
        let mut gaps = SequenceGaps::new(2);
        assert_eq!(gaps.note(&from(1, 1)), 0, "a first message has no gap");
        assert_eq!(gaps.note(&from(1, 2)), 0);
        assert_eq!(
            gaps.note(&from(2, 7)),
            0,
            "another publisher, its own count"
        );
        assert_eq!(gaps.note(&from(1, 5)), 2, "3 and 4 never came");
        assert_eq!(gaps.note(&from(2, 8)), 0);
        assert_eq!(gaps.note(&from(1, 1)), 0, "a restart counts nothing");
        assert_eq!(gaps.note(&from(1, 3)), 1);
        assert_eq!(gaps.note(&from(3, 10)), 0, "a third forgets the two");
        assert_eq!(gaps.note(&from(1, 9)), 0, "counted again from here");
        assert_eq!(gaps.note(&from(1, 11)), 1);
        // Sequence numbers a sender made up: no overflow, no huge count.
        assert_eq!(gaps.note(&from(1, i64::MIN)), 0);
        assert_eq!(gaps.note(&from(1, i64::MAX)), 0);
        assert_eq!(gaps.note(&from(1, i64::MIN)), 0);
        assert_eq!(gaps.note(&from(1, i64::MIN + 3)), 2);
    }

    fn node() -> NodeIdentity {
        NodeIdentity {
            domain_id: 0,
            zid: "a1b2c3".into(),
            node_id: 0,
            enclave: "/".into(),
            namespace: "/usv".into(),
            name: "twind".into(),
        }
    }

    #[test]
    fn keys_and_tokens_have_rmw_zenohs_shape() {
        assert_eq!(
            topic_key(
                3,
                "/usv/otter1/twin/fault",
                "diagnostic_msgs::msg::dds_::DiagnosticArray_",
                "RIHS01_5a"
            ),
            "3/usv/otter1/twin/fault/diagnostic_msgs::msg::dds_::DiagnosticArray_/RIHS01_5a"
        );
        let n = node();
        assert_eq!(n.node_token(), "@ros2_lv/0/a1b2c3/0/0/NN/%/%usv/twind");
        let e = Endpoint {
            topic: "/usv/otter1/twin/fault",
            dds_type: "diagnostic_msgs::msg::dds_::DiagnosticArray_",
            type_hash: "RIHS01_5a",
            qos: QOS_KEEP_LAST_10,
        };
        assert_eq!(
            n.token(7, EntityKind::Publisher, Some(e)),
            "@ros2_lv/0/a1b2c3/0/7/MP/%/%usv/twind/%usv%otter1%twin%fault/diagnostic_msgs::msg::dds_::DiagnosticArray_/RIHS01_5a/::,10:,:,:,,"
        );
    }

    #[test]
    fn an_attachment_round_trips_and_a_bad_one_is_none() {
        let a = Attachment {
            sequence_number: 5,
            source_timestamp_ns: 1_700_000_000_123_456_789,
            source_gid: gid_of("@ros2_lv/0/a/0/1/MP/%/%/n/%t/x/y/::,10:,:,:,,"),
        };
        let bytes = a.to_bytes();
        assert_eq!(bytes[..8], [5, 0, 0, 0, 0, 0, 0, 0]);
        assert_eq!(bytes[16], 16);
        assert_eq!(Attachment::from_bytes(&bytes), Some(a));
        assert_eq!(Attachment::from_bytes(&bytes[..20]), None);
        // The XXH3-128 of the empty input (the reference vector).
        assert_eq!(
            u128::from_le_bytes(gid_of("")),
            0x99aa06d3014798d86001c324468d497f
        );
    }
}
