//! Reads a log (any supported format) and prints what the reader and the
//! assembler made of it: `cargo run -p twin-wire --example log_stats -- LOG`.
//! Handy to look at a new log before pinning its counts in a test.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufReader;

use twin_wire::assemble::{AssemblerConfig, FixAssembler};
use twin_wire::read::{LogReader, ReadOptions};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args().nth(1).ok_or("usage: log_stats LOG")?;
    let mut reader = LogReader::open(BufReader::new(File::open(&path)?), ReadOptions::default())?;
    let mut assembler = FixAssembler::new(AssemblerConfig::default());
    let mut out = Vec::new();
    let mut per_source: BTreeMap<String, BTreeMap<&'static str, u64>> = BTreeMap::new();
    let mut first_rejections = Vec::new();
    let (mut first_s, mut last_s) = (None, 0.0);
    for item in reader.by_ref() {
        match item {
            Ok(record) => {
                first_s.get_or_insert(record.time_s);
                last_s = record.time_s;
                *per_source
                    .entry(record.source.to_string())
                    .or_default()
                    .entry(record.measurement.kind().name())
                    .or_default() += 1;
                assembler.push(record, &mut out);
            }
            Err(rejection) if first_rejections.len() < 5 => first_rejections.push(rejection),
            Err(_) => {}
        }
    }
    assembler.finish(&mut out);
    println!("format: {:?}", reader.format());
    println!("stats: {}", serde_json::to_string(reader.stats())?);
    println!("per source: {per_source:?}");
    println!("span: {:.3} s", last_s - first_s.unwrap_or(last_s));
    println!(
        "sources (position, course, heading): {:?}",
        assembler.sources()
    );
    println!("assembler: {:?}", assembler.stats());
    for r in first_rejections {
        println!("rejected: {r}");
    }
    Ok(())
}
