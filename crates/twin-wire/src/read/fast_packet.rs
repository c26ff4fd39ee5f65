//! NMEA 2000 fast-packet reassembly: a message of up to 223 bytes sent as
//! up to 32 CAN frames of 8 bytes. The first byte of every frame holds a
//! 3-bit sequence number (the same for all frames of one message) and a
//! 5-bit frame counter; frame 0 then gives the message length and its first
//! 6 bytes, every later frame 7 more. One assembler serves every reader of
//! frame-by-frame logs (canboat plain, candump, Yacht Devices RAW), so a
//! message reads the same whichever of them carried it.
//!
//! Messages are joined per source address and PGN, at most
//! [`MAX_FAST_SLOTS`] at once (memory stays bounded whatever arrives); a
//! frame out of order, a continuation without its first frame, or a first
//! frame that cuts short an unfinished message loses the message, and the
//! caller is told why.

use super::RejectReason;

/// The most fast-packet reassemblies in progress at once.
pub const MAX_FAST_SLOTS: usize = 32;

/// The largest fast-packet payload, bytes (6 + 31 x 7).
pub const MAX_FAST_BYTES: usize = 223;

/// The fast-packet PGNs the readers decode: 129029 GNSS position data,
/// 130577 direction data, 130842 (Furuno) six degrees of freedom. Frames of
/// other fast-packet PGNs are counted as ignored frame by frame.
pub const FAST_PGNS: [u32; 3] = [129_029, 130_577, 130_842];

/// True for a PGN the readers decode that is sent as fast packets.
pub fn is_fast(pgn: u32) -> bool {
    FAST_PGNS.contains(&pgn)
}

#[derive(Debug, Clone)]
struct Slot {
    source: u8,
    pgn: u32,
    sequence: u8,
    next_frame: u8,
    expected: usize,
    data: Vec<u8>,
}

/// The reassemblies in progress.
#[derive(Debug, Clone, Default)]
pub struct FastPackets {
    slots: Vec<Slot>,
}

/// What one frame did.
#[derive(Debug, Clone, PartialEq)]
pub enum FastFrame {
    /// The frame completed a message: its bytes.
    Complete(Vec<u8>),
    /// The frame was taken; the message is not complete yet.
    Pending,
    /// The frame lost a message (`Malformed`, saying how); a first frame
    /// that cut short an unfinished message still starts its own.
    Lost(RejectReason),
}

impl FastPackets {
    /// Adds one frame (at most 8 bytes) of `pgn` from `source`.
    pub fn push(&mut self, source: u8, pgn: u32, frame: &[u8]) -> FastFrame {
        let Some(&first) = frame.first() else {
            return FastFrame::Lost(RejectReason::Malformed {
                what: "fast packet: empty frame",
            });
        };
        let sequence = first >> 5;
        let counter = first & 0x1f;
        let index = self
            .slots
            .iter()
            .position(|s| s.source == source && s.pgn == pgn);
        if counter == 0 {
            let Some(&length) = frame.get(1) else {
                return FastFrame::Lost(RejectReason::Malformed {
                    what: "fast packet: first frame without length",
                });
            };
            let expected = usize::from(length);
            if expected > MAX_FAST_BYTES {
                return FastFrame::Lost(RejectReason::Malformed {
                    what: "fast packet: length over 223",
                });
            }
            let mut data = Vec::with_capacity(expected);
            data.extend_from_slice(frame.get(2..).unwrap_or(&[]));
            let slot = Slot {
                source,
                pgn,
                sequence,
                next_frame: 1,
                expected,
                data,
            };
            let cut_short = match index {
                Some(i) => {
                    self.slots[i] = slot;
                    true
                }
                None if self.slots.len() < MAX_FAST_SLOTS => {
                    self.slots.push(slot);
                    false
                }
                None => {
                    self.slots[0] = slot;
                    true
                }
            };
            if let Some(done) = self.take_if_complete(source, pgn) {
                return FastFrame::Complete(done);
            }
            return if cut_short {
                FastFrame::Lost(RejectReason::Malformed {
                    what: "fast packet: message cut short by a new one",
                })
            } else {
                FastFrame::Pending
            };
        }
        let Some(i) = index else {
            return FastFrame::Lost(RejectReason::Malformed {
                what: "fast packet: frame without its first frame",
            });
        };
        let slot = &mut self.slots[i];
        if slot.sequence != sequence || slot.next_frame != counter {
            self.slots.swap_remove(i);
            return FastFrame::Lost(RejectReason::Malformed {
                what: "fast packet: frame out of order",
            });
        }
        slot.data.extend_from_slice(frame.get(1..).unwrap_or(&[]));
        slot.next_frame = slot.next_frame.saturating_add(1);
        match self.take_if_complete(source, pgn) {
            Some(done) => FastFrame::Complete(done),
            None => FastFrame::Pending,
        }
    }

    fn take_if_complete(&mut self, source: u8, pgn: u32) -> Option<Vec<u8>> {
        let i = self
            .slots
            .iter()
            .position(|s| s.source == source && s.pgn == pgn)?;
        if self.slots[i].data.len() < self.slots[i].expected {
            return None;
        }
        let mut slot = self.slots.swap_remove(i);
        slot.data.truncate(slot.expected);
        Some(slot.data)
    }

    /// Bytes held (for the constant-memory checks).
    pub fn state_bytes(&self) -> usize {
        self.slots
            .iter()
            .map(|s| s.data.capacity() + std::mem::size_of::<Slot>())
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frames(message: &[u8], sequence: u8) -> Vec<Vec<u8>> {
        crate::write::n2k_raw::fast_packet_frames(message, sequence)
    }

    #[test]
    fn frames_join_back_into_the_message() {
        let message: Vec<u8> = (0..43).collect();
        let mut fp = FastPackets::default();
        let split = frames(&message, 3);
        assert_eq!(split.len(), 7);
        for f in &split[..6] {
            assert_eq!(fp.push(160, 129_029, f), FastFrame::Pending);
        }
        assert_eq!(
            fp.push(160, 129_029, &split[6]),
            FastFrame::Complete(message)
        );
        assert_eq!(fp.state_bytes(), 0);
    }

    #[test]
    fn lost_messages_say_why() {
        let message: Vec<u8> = (0..20).collect();
        let split = frames(&message, 1);
        let mut fp = FastPackets::default();
        assert!(matches!(
            fp.push(7, 130_577, &split[1]),
            FastFrame::Lost(RejectReason::Malformed { what }) if what.contains("without its first")
        ));
        assert_eq!(fp.push(7, 130_577, &split[0]), FastFrame::Pending);
        assert!(matches!(
            fp.push(7, 130_577, &split[2]),
            FastFrame::Lost(RejectReason::Malformed { what }) if what.contains("out of order")
        ));
        assert_eq!(fp.push(7, 130_577, &split[0]), FastFrame::Pending);
        assert!(matches!(
            fp.push(7, 130_577, &split[0]),
            FastFrame::Lost(RejectReason::Malformed { what }) if what.contains("cut short")
        ));
        // The cut-short first frame started its own message.
        assert_eq!(fp.push(7, 130_577, &split[1]), FastFrame::Pending);
        assert_eq!(fp.push(7, 130_577, &split[2]), FastFrame::Complete(message));
    }

    #[test]
    fn slots_are_bounded() {
        let mut fp = FastPackets::default();
        for source in 0..=255u8 {
            fp.push(source, 129_029, &[0x00, 200, 1, 2, 3, 4, 5, 6]);
        }
        assert!(fp.slots.len() <= MAX_FAST_SLOTS);
    }
}
