//! The readers stream: a synthetic 4-hour NMEA 0183 log, generated on the fly
//! by an `io::Read` adapter (never a file, never in memory as a whole), is
//! read and assembled with buffers that stop growing after the first lines,
//! through a midnight crossing, to the exact last timestamp.

use std::io::{self, BufReader, Read};
use std::time::Instant;

use twin_core::geodesy::LatLon;
use twin_core::sample::{GnssFix, Side};
use twin_wire::assemble::{Assembled, AssemblerConfig, FixAssembler};
use twin_wire::measurement::{FixMethod, Talker};
use twin_wire::read::{LogReader, ReadOptions};
use twin_wire::time::parse_rfc3339;
use twin_wire::write::nmea0183::{gga, hdt, rpm, vtg, zda};

/// Bursts per second.
const RATE_HZ: f64 = 2.0;
/// Four hours of bursts.
const BURSTS: u64 = 4 * 3600 * 2;

/// Produces the log burst by burst as it is read.
struct SyntheticLog {
    start_s: f64,
    burst: u64,
    pending: Vec<u8>,
    offset: usize,
}

impl SyntheticLog {
    fn new(start_s: f64) -> Self {
        Self {
            start_s,
            burst: 0,
            pending: Vec::new(),
            offset: 0,
        }
    }

    fn next_burst(&mut self) {
        let t = self.start_s + self.burst as f64 / RATE_HZ;
        let k = self.burst as f64;
        let fix = GnssFix {
            time_s: t,
            position: LatLon {
                lat_deg: 60.0 + 1e-6 * k,
                lon_deg: 23.5,
            },
            sog_mps: None,
            cog_rad: None,
            heading_rad: None,
            yaw_rate_radps: None,
            hdop: Some(0.9),
        };
        let gp = Talker::GP;
        let mut lines = Vec::new();
        if self.burst == 0 {
            // The only date in the log: the midnight crossing must carry it.
            lines.push(zda(gp, t).expect("zda"));
        }
        lines.push(gga(gp, &fix, FixMethod::Dgnss, Some(9), None).expect("gga"));
        lines.push(vtg(gp, Some((k * 0.001) % 6.0), Some(2.0)).expect("vtg"));
        lines.push(hdt(gp, 1.0).expect("hdt"));
        lines.push(rpm(gp, Side::Port, 100.0).expect("rpm"));
        lines.push(rpm(gp, Side::Starboard, 101.0).expect("rpm"));
        self.pending.clear();
        for l in lines {
            self.pending.extend_from_slice(l.as_bytes());
            self.pending.extend_from_slice(b"\r\n");
        }
        self.offset = 0;
        self.burst += 1;
    }
}

impl Read for SyntheticLog {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if self.offset == self.pending.len() {
            if self.burst == BURSTS {
                return Ok(0);
            }
            self.next_burst();
        }
        let n = buf.len().min(self.pending.len() - self.offset);
        buf[..n].copy_from_slice(&self.pending[self.offset..self.offset + n]);
        self.offset += n;
        Ok(n)
    }
}

#[test]
fn four_hour_log_streams_in_constant_memory() {
    let started = Instant::now();
    let start_s = parse_rfc3339("2025-12-31T22:00:00Z").unwrap();
    let input = BufReader::with_capacity(8192, SyntheticLog::new(start_s));
    let mut reader = LogReader::open(input, ReadOptions::default()).unwrap();
    let mut assembler = FixAssembler::new(AssemblerConfig::default());
    let mut out = Vec::new();
    let (mut records, mut fixes, mut pairs) = (0u64, 0u64, 0u64);
    let (mut last_record_s, mut last_out_s) = (f64::NEG_INFINITY, f64::NEG_INFINITY);
    let mut buffered_after_warmup = None;
    let mut max_buffered = 0;
    let mut max_held = 0;
    while let Some(item) = reader.next() {
        let record = item.expect("every synthetic line is valid");
        assert!(record.time_s >= last_record_s);
        last_record_s = record.time_s;
        records += 1;
        assembler.push(record, &mut out);
        max_held = max_held.max(assembler.held_records());
        for a in out.drain(..) {
            assert!(a.time_s() >= last_out_s);
            last_out_s = a.time_s();
            match a {
                Assembled::Fix(f) => {
                    fixes += 1;
                    assert!((f.heading_rad.expect("heading") - 1.0).abs() < 1e-4);
                    assert!(f.cog_rad.is_some());
                }
                Assembled::Propellers(_) => pairs += 1,
                Assembled::Thrust(_) => unreachable!("no thrust in the log"),
            }
        }
        if records % 997 == 0 {
            let bytes = reader.buffered_bytes();
            max_buffered = max_buffered.max(bytes);
            if records > 10_000 {
                // After warm-up the buffers never grow again.
                assert_eq!(*buffered_after_warmup.get_or_insert(bytes), bytes);
            }
        }
    }
    assembler.finish(&mut out);
    fixes += out
        .iter()
        .filter(|a| matches!(a, Assembled::Fix(_)))
        .count() as u64;
    assert_eq!(records, BURSTS * 5);
    assert_eq!(reader.stats().total_rejected(), 0);
    assert_eq!(reader.stats().time_only, 1);
    // Through midnight to 01:59:59.5 on 2026-01-01, not on 2025-12-31.
    let last_expected = parse_rfc3339("2026-01-01T01:59:59.5Z").unwrap();
    assert!(
        (last_record_s - last_expected).abs() < 1e-6,
        "{last_record_s}"
    );
    assert_eq!(fixes, BURSTS);
    assert_eq!(pairs, BURSTS);
    // One line and its records, the detection lines, the decoder: a few KiB.
    assert!(max_buffered < 16 * 1024, "{max_buffered}");
    // The assembler holds only its 5-s decision window (5 s x 2 Hz x 5).
    assert!(max_held <= 50, "{max_held}");
    assert_eq!(assembler.held_records(), 0);
    // Loose guard against accidental quadratic work (debug build, shared CI).
    assert!(started.elapsed().as_secs() < 60, "{:?}", started.elapsed());
}
