//! The real NMEA 2000 logs (canboat FAST text) carried into the raw layouts
//! a boat's gateways and SocketCAN produce (candump, Yacht Devices RAW: a
//! line per CAN frame, fast packets split; Actisense N2K ASCII: a line per
//! message) and read back: every layout gives the very records the canboat
//! reader gives, and `LogReader` recognises each layout by its content.

use std::collections::HashMap;
use std::fs;
use std::path::PathBuf;

use twin_wire::measurement::Record;
use twin_wire::read::fast_packet::is_fast;
use twin_wire::read::n2k::parse_message;
use twin_wire::read::{LogFormat, LogReader, RawFormat, ReadOptions};
use twin_wire::time::{CivilDate, split_date_time_ms};
use twin_wire::write::n2k_raw::message_lines;

fn fixture(name: &str) -> String {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/fixtures/real")
        .join(name);
    fs::read_to_string(path).expect("fixture present")
}

/// The log in `layout`, fast-packet sequence numbers counting per source
/// and PGN as a sender's do.
fn convert(canboat: &str, layout: RawFormat) -> String {
    let mut out = String::new();
    let mut sequences: HashMap<(u8, u32), u8> = HashMap::new();
    let mut data = Vec::new();
    for line in canboat.lines() {
        if line.starts_with('#') || line.trim().is_empty() {
            continue;
        }
        let header = parse_message(line.as_bytes(), &mut data).expect("the fixtures parse");
        let sequence = sequences
            .entry((header.id.source, header.id.pgn))
            .or_insert(0);
        // The logger's own PGNs (above 18 bits) never travel on a CAN bus.
        let fast = is_fast(header.id.pgn);
        let Ok(lines) = message_lines(layout, header.time_s, header.id, &data, fast, *sequence)
        else {
            assert!(header.id.pgn > 0x3_FFFF, "{line}");
            continue;
        };
        for l in lines {
            out.push_str(&l);
            out.push('\n');
        }
        *sequence = (*sequence + 1) % 8;
    }
    out
}

fn records(text: &str, options: ReadOptions) -> (LogFormat, Vec<Record>, u64) {
    let mut reader = LogReader::open(text.as_bytes(), options).unwrap();
    let records: Vec<Record> = reader.by_ref().filter_map(Result::ok).collect();
    (reader.format(), records, reader.stats().total_rejected())
}

#[test]
fn every_layout_gives_the_records_of_the_canboat_reader() {
    // aava: 129029 and 130577 fast packets; furuno: 130842 fast packets.
    for name in ["aava-n2k.data", "furuno-130842.raw"] {
        let canboat = fixture(name);
        let (format, expected, rejected) = records(&canboat, ReadOptions::default());
        assert_eq!(format, LogFormat::N2k);
        assert!(expected.len() > 4_000, "{name}: {}", expected.len());
        // The time-of-day layouts need the log's date.
        let (date, _) = split_date_time_ms(expected[0].time_s).unwrap();
        let options = ReadOptions {
            assumed_date: Some(CivilDate::new(date.year(), date.month(), date.day()).unwrap()),
            ..ReadOptions::default()
        };
        for (layout, want) in [
            (RawFormat::Candump, LogFormat::Candump),
            (RawFormat::YdRaw, LogFormat::YdRaw),
            (RawFormat::ActisenseAscii, LogFormat::ActisenseAscii),
        ] {
            let text = convert(&canboat, layout);
            let (format, got, got_rejected) = records(&text, options);
            assert_eq!(format, want, "{name} as {layout:?}");
            assert_eq!(got_rejected, rejected, "{name} as {layout:?}");
            assert_eq!(got.len(), expected.len(), "{name} as {layout:?}");
            for (i, (g, e)) in got.iter().zip(&expected).enumerate() {
                assert_eq!(
                    (g.source, g.measurement),
                    (e.source, e.measurement),
                    "{name} as {layout:?}, record {i}"
                );
                assert!(
                    (g.time_s - e.time_s).abs() < 1e-6,
                    "{name} as {layout:?}, record {i}: {} vs {}",
                    g.time_s,
                    e.time_s
                );
            }
        }
    }
}

#[test]
fn fast_packets_cut_in_the_middle_are_counted_not_decoded() {
    let canboat = fixture("aava-n2k.data");
    let text = convert(&canboat, RawFormat::Candump);
    // Drop every 50th frame line of 129029 (7 frames a message).
    let mut dropped = 0;
    let cut: String = text
        .lines()
        .filter(|l| {
            // 129029, priority 3, from source 160.
            if l.contains(" 0DF805A0#") {
                dropped += 1;
                dropped % 50 != 0
            } else {
                true
            }
        })
        .map(|l| format!("{l}\n"))
        .collect();
    assert!(dropped > 1000, "{dropped}");
    let mut reader = LogReader::open(cut.as_bytes(), ReadOptions::default()).unwrap();
    let (_, whole, _) = records(&text, ReadOptions::default());
    let kept: Vec<Record> = reader.by_ref().filter_map(Result::ok).collect();
    let lost = dropped / 50;
    assert!(kept.len() < whole.len());
    assert!(
        reader.stats().total_rejected() >= lost as u64,
        "{:?}",
        reader.stats()
    );
}
