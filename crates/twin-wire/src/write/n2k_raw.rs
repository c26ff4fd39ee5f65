//! Writers of NMEA 2000 in the raw layouts the readers take
//! ([`crate::read::n2k_raw`]): a message split into fast-packet frames, and
//! a frame or message as a candump log line, a Yacht Devices RAW line or an
//! Actisense N2K ASCII line. The tests use them to carry the real canboat
//! logs into the other layouts; the bridge's benchmark to make traffic.

use crate::read::fast_packet::MAX_FAST_BYTES;
#[cfg(doc)]
use crate::read::fast_packet::is_fast;
use crate::read::n2k_raw::{CanId, RawFormat};
use crate::time::split_date_time_ms;

use super::WriteError;

/// A message as fast-packet frames with sequence number `sequence` (0-7):
/// frame 0 carries the length and 6 bytes, each later frame 7; the last
/// frame is padded with 0xFF to 8 bytes. A message longer than 223 bytes
/// cannot be sent this way and gives no frames.
pub fn fast_packet_frames(message: &[u8], sequence: u8) -> Vec<Vec<u8>> {
    if message.len() > MAX_FAST_BYTES {
        return Vec::new();
    }
    let sequence = (sequence & 0x7) << 5;
    let mut frames = Vec::with_capacity(1 + message.len().saturating_sub(6).div_ceil(7));
    let (head, tail) = message.split_at(message.len().min(6));
    let mut first = vec![sequence, message.len() as u8];
    first.extend_from_slice(head);
    first.resize(8, 0xFF);
    frames.push(first);
    for (i, chunk) in tail.chunks(7).enumerate() {
        let mut frame = vec![sequence | (i as u8 + 1)];
        frame.extend_from_slice(chunk);
        frame.resize(8, 0xFF);
        frames.push(frame);
    }
    frames
}

fn hex(bytes: &[u8], separator: &str) -> String {
    bytes
        .iter()
        .map(|b| format!("{b:02X}"))
        .collect::<Vec<_>>()
        .join(separator)
}

fn time_of_day(time_s: f64) -> Result<(u32, u32, u32, u32), WriteError> {
    let (_, ms) = split_date_time_ms(time_s)?;
    let s = (ms / 1000) as u32;
    Ok((s / 3600, (s / 60) % 60, s % 60, (ms % 1000) as u32))
}

/// A candump log line: `(1436509052.249713) can0 09F8027F#00FCFFFF0000FFFF`.
pub fn candump_line(
    time_s: f64,
    interface: &str,
    id: CanId,
    frame: &[u8],
) -> Result<String, WriteError> {
    if !time_s.is_finite() {
        return Err(WriteError::NotFinite { field: "time" });
    }
    if frame.len() > 8 {
        return Err(WriteError::OutOfRange { field: "frame" });
    }
    Ok(format!(
        "({time_s:.6}) {interface} {:08X}#{}",
        id.to_raw(),
        hex(frame, "")
    ))
}

/// A Yacht Devices RAW line: `17:33:21.107 R 19F51323 01 2F 30 70 00 2F 30 70`.
pub fn ydraw_line(time_s: f64, id: CanId, frame: &[u8]) -> Result<String, WriteError> {
    if frame.len() > 8 {
        return Err(WriteError::OutOfRange { field: "frame" });
    }
    let (h, m, s, ms) = time_of_day(time_s)?;
    let mut line = format!("{h:02}:{m:02}:{s:02}.{ms:03} R {:08X}", id.to_raw());
    if !frame.is_empty() {
        line.push(' ');
        line.push_str(&hex(frame, " "));
    }
    Ok(line)
}

/// An Actisense N2K ASCII line of a whole message:
/// `A173321.107 23FF7 1F513 012F3070002F30709F`.
pub fn actisense_line(time_s: f64, id: CanId, message: &[u8]) -> Result<String, WriteError> {
    let (h, m, s, ms) = time_of_day(time_s)?;
    Ok(format!(
        "A{h:02}{m:02}{s:02}.{ms:03} {:02X}{:02X}{:X} {:05X} {}",
        id.source,
        id.destination,
        id.priority & 0x7,
        id.pgn,
        hex(message, "")
    ))
}

/// The lines that carry one message in `layout`: candump and Yacht Devices
/// RAW a line per CAN frame, Actisense N2K ASCII the whole message on one
/// line. `fast_packet` says whether the PGN is sent as fast packets (with
/// `sequence`); a message longer than 8 bytes always is. (Which PGNs are
/// fast packets is the NMEA 2000 database's to say; the readers need to
/// know it only for the PGNs they decode, [`is_fast`].) A PGN over 18 bits
/// (a gateway's own) cannot be a CAN id: refused for the frame layouts.
pub fn message_lines(
    layout: RawFormat,
    time_s: f64,
    id: CanId,
    message: &[u8],
    fast_packet: bool,
    sequence: u8,
) -> Result<Vec<String>, WriteError> {
    if layout == RawFormat::ActisenseAscii {
        return Ok(vec![actisense_line(time_s, id, message)?]);
    }
    // A CAN id holds 18 bits of PGN; gateways' own PGNs are larger.
    if id.pgn > 0x3_FFFF {
        return Err(WriteError::OutOfRange { field: "PGN" });
    }
    let frames = if message.len() > 8 || fast_packet {
        let frames = fast_packet_frames(message, sequence);
        if frames.is_empty() {
            return Err(WriteError::OutOfRange {
                field: "message length",
            });
        }
        frames
    } else {
        vec![message.to_vec()]
    };
    frames
        .iter()
        .map(|frame| match layout {
            RawFormat::Candump => candump_line(time_s, "can0", id, frame),
            _ => ydraw_line(time_s, id, frame),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_of_a_short_and_a_long_message() {
        let frames = fast_packet_frames(&[1, 2, 3], 2);
        assert_eq!(frames, vec![vec![0x40, 3, 1, 2, 3, 0xFF, 0xFF, 0xFF]]);
        let long: Vec<u8> = (0..20).collect();
        let frames = fast_packet_frames(&long, 7);
        assert_eq!(frames.len(), 3);
        assert_eq!(frames[1][0], 0xE1);
        assert_eq!(frames[2], vec![0xE2, 13, 14, 15, 16, 17, 18, 19]);
        assert!(fast_packet_frames(&[0; 224], 0).is_empty());
    }

    #[test]
    fn lines_have_the_layouts() {
        let id = CanId {
            priority: 2,
            pgn: 127_250,
            source: 160,
            destination: 255,
        };
        let t = 1_408_129_200.892;
        assert_eq!(
            candump_line(t, "can0", id, &[0xFF, 0x10]).unwrap(),
            "(1408129200.892000) can0 09F112A0#FF10"
        );
        assert_eq!(
            ydraw_line(t, id, &[0xFF, 0x10]).unwrap(),
            "19:00:00.892 R 09F112A0 FF 10"
        );
        assert_eq!(
            actisense_line(t, id, &[0xFF, 0x10]).unwrap(),
            "A190000.892 A0FF2 1F112 FF10"
        );
    }
}
