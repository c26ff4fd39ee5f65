//! The raw NMEA 2000 layouts the bridge reads, held against canboatjs
//! (npm @canboat/canboatjs), which reads them too: the real logs of
//! `tests/fixtures/real/` (canboat FAST text) are carried into candump,
//! Yacht Devices RAW and Actisense N2K ASCII lines by `twin_wire`'s writers
//! (fast packets split into frames), and canboatjs decodes every layout to
//! the very fields of the original; `twin_wire`'s readers give the very
//! records of the canboat reader for the same lines.

mod common;

use std::collections::{HashMap, HashSet};
use std::process::Command;

use common::*;
use twin_wire::measurement::Record;
use twin_wire::read::n2k::parse_message;
use twin_wire::read::{LogReader, RawFormat, ReadOptions};
use twin_wire::time::split_date_time_ms;
use twin_wire::write::n2k_raw::message_lines;

/// The PGNs canboat's database sends as fast packets, of those in `text`.
fn fast_pgns(text: &str) -> HashSet<u32> {
    let pgns: HashSet<u32> = text
        .lines()
        .filter_map(|l| l.split(',').nth(2)?.parse().ok())
        .collect();
    let output = Command::new("node")
        .arg(repo().join("tests/peers/canboat_compare.js"))
        .arg("--fast-pgns")
        .args(pgns.iter().map(u32::to_string))
        .env("NODE_PATH", peers().join("node_modules"))
        .output()
        .expect("node runs");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    serde_json::from_slice(&output.stdout).unwrap()
}

/// The first `lines` messages of a fixture, and the same as each layout.
fn layouts(name: &str, lines: usize) -> (String, Vec<(RawFormat, String)>) {
    let text = std::fs::read_to_string(repo().join("tests/fixtures/real").join(name)).unwrap();
    let fast = fast_pgns(&text);
    // The twin's own list agrees with canboat's for the PGNs it decodes.
    for pgn in twin_wire::read::fast_packet::FAST_PGNS {
        if text.contains(&format!(",{pgn},")) {
            assert!(fast.contains(&pgn), "{pgn}");
        }
    }
    let mut reference = String::from("# format=FAST\n");
    let mut others: Vec<(RawFormat, String)> = [
        RawFormat::Candump,
        RawFormat::YdRaw,
        RawFormat::ActisenseAscii,
    ]
    .into_iter()
    .map(|f| (f, String::new()))
    .collect();
    let mut sequences: HashMap<(u8, u32), u8> = HashMap::new();
    let mut data = Vec::new();
    let mut taken = 0;
    for line in text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
    {
        let header = parse_message(line.as_bytes(), &mut data).unwrap();
        // Only what a CAN bus carries (not a logger's own PGNs).
        if header.id.pgn > 0x3_FFFF {
            continue;
        }
        if taken == lines {
            break;
        }
        taken += 1;
        reference.push_str(line);
        reference.push('\n');
        let sequence = sequences
            .entry((header.id.source, header.id.pgn))
            .or_insert(0);
        for (format, out) in &mut others {
            let fast = fast.contains(&header.id.pgn);
            for l in
                message_lines(*format, header.time_s, header.id, &data, fast, *sequence).unwrap()
            {
                out.push_str(&l);
                out.push('\n');
            }
        }
        *sequence = (*sequence + 1) % 8;
    }
    (reference, others)
}

fn records(text: &str, options: ReadOptions) -> Vec<Record> {
    LogReader::open(text.as_bytes(), options)
        .unwrap()
        .filter_map(Result::ok)
        .collect()
}

#[test]
fn canboatjs_reads_every_layout_as_the_original() {
    require_node_module("@canboat/canboatjs");
    let dir = std::env::temp_dir().join(format!("twin-bridge-canboat-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // aava: 129029 and 130577 fast packets, AIS and other PGNs; furuno:
    // 130842 fast packets.
    for name in ["aava-n2k.data", "furuno-130842.raw"] {
        let (reference, others) = layouts(name, 3000);
        let reference_path = dir.join(format!("{name}.fast"));
        std::fs::write(&reference_path, &reference).unwrap();
        let mut command = Command::new("node");
        command
            .arg(repo().join("tests/peers/canboat_compare.js"))
            .arg(&reference_path)
            .env("NODE_PATH", peers().join("node_modules"));
        let want = records(&reference, ReadOptions::default());
        assert!(want.len() > 500, "{name}: {}", want.len());
        let (date, _) = split_date_time_ms(want[0].time_s).unwrap();
        for (format, text) in &others {
            let path = dir.join(format!("{name}.{format:?}"));
            std::fs::write(&path, text).unwrap();
            command.arg(&path);
            // Our readers: the records of the original.
            let options = ReadOptions {
                assumed_date: Some(date),
                ..ReadOptions::default()
            };
            let got = records(text, options);
            assert_eq!(got.len(), want.len(), "{name} as {format:?}");
            for (g, w) in got.iter().zip(&want) {
                assert_eq!((g.source, g.measurement), (w.source, w.measurement));
                assert!((g.time_s - w.time_s).abs() < 1e-6);
            }
        }
        let output = command.output().expect("node runs");
        let report = String::from_utf8_lossy(&output.stdout);
        assert!(
            output.status.success(),
            "canboatjs disagrees on {name}:\n{report}{}",
            String::from_utf8_lossy(&output.stderr)
        );
        // canboatjs decoded a message for every line of the original.
        let counts: Vec<u64> = report
            .lines()
            .map(|l| {
                serde_json::from_str::<serde_json::Value>(l).unwrap()["messages"]
                    .as_u64()
                    .unwrap()
            })
            .collect();
        assert_eq!(counts.len(), 4, "{report}");
        assert!(counts[0] > 2000, "{report}");
        assert!(counts.iter().all(|c| *c == counts[0]), "{report}");
    }
    std::fs::remove_dir_all(&dir).ok();
}
