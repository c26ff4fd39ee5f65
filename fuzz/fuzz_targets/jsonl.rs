//! Fuzz target: the project's JSON lines through the streaming reader.
#![no_main]

use libfuzzer_sys::fuzz_target;
use twin_wire::measurement::Measurement;
use twin_wire::read::{ReadOptions, jsonl_reader};

fuzz_target!(|data: &[u8]| {
    let mut reader = jsonl_reader(data, ReadOptions::default());
    let mut items = 0u64;
    for item in reader.by_ref() {
        items += 1;
        if let Ok(record) = item
            && let Measurement::GnssFix(fix) = record.measurement
        {
            assert!(fix.position.is_valid());
        }
    }
    let stats = reader.stats();
    assert_eq!(items, stats.total_records() + stats.total_rejected());
});
