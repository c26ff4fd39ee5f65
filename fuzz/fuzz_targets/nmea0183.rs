//! Fuzz target: NMEA 0183 text through the streaming reader and, as a Zenoh
//! `nmea` payload, through the decoder's payload entry point. Every item
//! must be counted, every record in range.
#![no_main]

use libfuzzer_sys::fuzz_target;
use twin_wire::read::{Decoder, NmeaDecoder, ReadOptions, nmea0183_reader};

fuzz_target!(|data: &[u8]| {
    let options = ReadOptions {
        max_line_bytes: 512,
        ..ReadOptions::default()
    };
    let mut reader = nmea0183_reader(data, options);
    let mut items = 0u64;
    for item in reader.by_ref() {
        items += 1;
        if let Ok(record) = item {
            assert!(record.time_s.is_finite());
        }
    }
    let stats = reader.stats();
    assert_eq!(items, stats.total_records() + stats.total_rejected());

    let mut decoder = NmeaDecoder::new(options);
    let mut out = Vec::new();
    decoder.decode_payload(data, &mut out);
    assert_eq!(
        out.len() as u64,
        decoder.stats().total_records() + decoder.stats().total_rejected()
    );
});
