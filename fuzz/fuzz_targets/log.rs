//! Fuzz target: format detection, whichever reader it picks, and the fix
//! assembler on its records; assembled inputs must come out in time order.
#![no_main]

use libfuzzer_sys::fuzz_target;
use twin_wire::assemble::{AssemblerConfig, assemble};
use twin_wire::read::{LogReader, ReadOptions};

fuzz_target!(|data: &[u8]| {
    let options = ReadOptions {
        max_line_bytes: 4096,
        ..ReadOptions::default()
    };
    let Ok(reader) = LogReader::open(data, options) else {
        return;
    };
    let mut last = f64::NEG_INFINITY;
    for input in assemble(reader.filter_map(Result::ok), AssemblerConfig::default()) {
        assert!(input.time_s() >= last);
        last = input.time_s();
    }
});
