//! Fuzz target: the `gnss` and `actuators` Zenoh payloads. Whatever decodes
//! must encode again and decode to the same values (time to the microsecond).
#![no_main]

use libfuzzer_sys::fuzz_target;
use twin_wire::messages::{decode_actuators, decode_gnss, encode_actuators, encode_gnss};

fuzz_target!(|data: &[u8]| {
    if let Ok(decoded) = decode_gnss(data) {
        let fix = decoded.value;
        let bytes = encode_gnss(&fix, decoded.replay).expect("a decoded fix encodes");
        let again = decode_gnss(&bytes).expect("an encoded fix decodes");
        assert!((again.value.time_s - fix.time_s).abs() <= 1e-6 + fix.time_s.abs() * 1e-15);
        assert_eq!(again.value.position, fix.position);
        assert_eq!(again.value.sog_mps, fix.sog_mps);
        assert_eq!(again.value.cog_rad, fix.cog_rad);
        assert_eq!(again.value.heading_rad, fix.heading_rad);
        assert_eq!(again.value.hdop, fix.hdop);
        assert_eq!(again.replay, decoded.replay);
    }
    if let Ok(decoded) = decode_actuators(data) {
        let bytes =
            encode_actuators(&decoded.value, decoded.replay).expect("a decoded command encodes");
        decode_actuators(&bytes).expect("an encoded command decodes");
    }
});
