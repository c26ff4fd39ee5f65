//! Fuzz target: canboat NMEA 2000 text (plain and FAST, with fast-packet
//! reassembly) through the streaming reader.
#![no_main]

use libfuzzer_sys::fuzz_target;
use twin_wire::measurement::Measurement;
use twin_wire::read::{ReadOptions, n2k_reader};

fuzz_target!(|data: &[u8]| {
    let options = ReadOptions {
        max_line_bytes: 8192,
        ..ReadOptions::default()
    };
    let mut reader = n2k_reader(data, options);
    let mut items = 0u64;
    for item in reader.by_ref() {
        items += 1;
        if let Ok(record) = item {
            assert!(record.time_s.is_finite());
            if let Measurement::Position {
                lat_deg, lon_deg, ..
            } = record.measurement
            {
                assert!(lat_deg.abs() <= 90.0 && lon_deg.abs() <= 180.0);
            }
        }
    }
    let stats = reader.stats();
    assert_eq!(items, stats.total_records() + stats.total_rejected());
});
