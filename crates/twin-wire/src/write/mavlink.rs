//! Writers of MAVLink 2 frames and `.tlog` records (with the `mavlink`
//! crate's serializer), for tests and the bridge's benchmark: what they
//! write reads back through [`crate::read::mavlink`].

use mavlink::{MAVLinkV2MessageRaw, MavHeader};

use crate::read::mavlink::dialect::MavMessage;

/// A MAVLink 2 frame of `message` from `system`/`component`.
pub fn frame_v2(system: u8, component: u8, sequence: u8, message: &MavMessage) -> Vec<u8> {
    let mut raw = MAVLinkV2MessageRaw::new();
    raw.serialize_message(
        MavHeader {
            system_id: u32::from(system),
            component_id: component,
            sequence,
        },
        message,
    );
    raw.raw_bytes().to_vec()
}

/// A `.tlog` record: the big-endian microseconds since the epoch of
/// `time_s`, then the frame.
pub fn tlog_record(time_s: f64, frame: &[u8]) -> Vec<u8> {
    let us = (time_s * 1e6).round().max(0.0) as u64;
    let mut record = us.to_be_bytes().to_vec();
    record.extend_from_slice(frame);
    record
}
