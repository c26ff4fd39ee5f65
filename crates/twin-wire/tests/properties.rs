//! Property tests across the readers: random bytes and random line-shaped
//! input never panic and every item is counted; generated valid messages
//! round-trip; corrupted checksums are caught; whatever is accepted is in
//! range.

use proptest::prelude::*;
use twin_core::geodesy::angle_diff;
use twin_core::sample::Side;
use twin_wire::measurement::{Measurement, Record, Talker};
use twin_wire::read::{
    Decoder, Item, JsonlDecoder, LogReader, N2kDecoder, NmeaDecoder, ReadOptions, ReadStats,
    RejectKind, jsonl_reader, n2k_reader, nmea0183_reader,
};
use twin_wire::write::nmea0183::{gga, hdt, rmc, rpm, sentence, vtg};

/// Every item is a counted record or a counted rejection.
fn check_accounting(items: &[Item], stats: &ReadStats) -> Result<(), TestCaseError> {
    let records = items.iter().filter(|i| i.is_ok()).count() as u64;
    prop_assert_eq!(records, stats.total_records());
    prop_assert_eq!(items.len() as u64 - records, stats.total_rejected());
    Ok(())
}

/// What any accepted record must satisfy.
fn check_record(r: &Record) -> Result<(), TestCaseError> {
    prop_assert!(r.time_s.is_finite());
    let tau = std::f64::consts::TAU;
    let compass = |a: f64| (0.0..tau).contains(&a);
    match r.measurement {
        Measurement::Position {
            lat_deg,
            lon_deg,
            hdop,
            altitude_m,
            ..
        } => {
            prop_assert!(lat_deg.abs() <= 90.0 && lon_deg.abs() <= 180.0);
            prop_assert!(hdop.is_none_or(|h| h > 0.0 && h.is_finite()));
            prop_assert!(altitude_m.is_none_or(f64::is_finite));
        }
        Measurement::CourseSpeed { cog_rad, sog_mps } => {
            prop_assert!(cog_rad.is_none_or(compass));
            prop_assert!(sog_mps.is_none_or(|s| (0.0..=50.0).contains(&s)));
        }
        Measurement::Heading { heading_rad } => prop_assert!(compass(heading_rad)),
        Measurement::SpeedThroughWater { mps } => prop_assert!((0.0..=50.0).contains(&mps)),
        Measurement::SetDrift { set_rad, drift_mps } => {
            prop_assert!(compass(set_rad) && drift_mps.is_finite());
        }
        Measurement::RateOfTurn { radps } | Measurement::PropellerSpeed { radps, .. } => {
            prop_assert!(radps.is_finite());
        }
        Measurement::GnssFix(f) => prop_assert!(f.position.is_valid()),
        _ => {}
    }
    Ok(())
}

fn drive<D: Decoder>(mut decoder: D, lines: &[Vec<u8>]) -> Result<(), TestCaseError> {
    let mut out = Vec::new();
    for (i, line) in lines.iter().enumerate() {
        decoder.decode_line(line, i as u64 + 1, &mut out);
    }
    for r in out.iter().flatten() {
        check_record(r)?;
    }
    check_accounting(&out, decoder.stats())
}

/// Little-endian bytes of a canboat line.
fn n2k_line(pgn: u32, source: u8, data: &[u8]) -> String {
    let hex: Vec<String> = data.iter().map(|b| format!("{b:02x}")).collect();
    format!(
        "2026-08-03T04:27:20.588Z,2,{pgn},{source},255,{},{}",
        data.len(),
        hex.join(",")
    )
}

fn decode_n2k(line: &str) -> Vec<Item> {
    let mut d = N2kDecoder::new(ReadOptions::default());
    let mut out = Vec::new();
    d.decode_line(line.as_bytes(), 1, &mut out);
    out
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn random_bytes_never_panic_in_any_reader(bytes in proptest::collection::vec(any::<u8>(), 0..2048)) {
        let options = ReadOptions { max_line_bytes: 256, ..ReadOptions::default() };
        let mut r = nmea0183_reader(&bytes[..], options);
        let items: Vec<_> = r.by_ref().collect();
        check_accounting(&items, r.stats())?;
        let mut r = n2k_reader(&bytes[..], options);
        let items: Vec<_> = r.by_ref().collect();
        check_accounting(&items, r.stats())?;
        let mut r = jsonl_reader(&bytes[..], options);
        let items: Vec<_> = r.by_ref().collect();
        check_accounting(&items, r.stats())?;
        if let Ok(mut r) = LogReader::open(&bytes[..], options) {
            let items: Vec<_> = r.by_ref().collect();
            check_accounting(&items, r.stats())?;
        }
    }

    #[test]
    fn nmea_shaped_lines_never_panic(
        lines in proptest::collection::vec(
            ("(GP|II|HE|ER|GN)(RMC|GGA|GLL|VTG|HDT|HDG|HDM|VHW|RPM|ZDA)", proptest::collection::vec("[0-9A-Z.+-]{0,10}", 0..16), any::<bool>()),
            1..20),
    ) {
        let lines: Vec<Vec<u8>> = lines.into_iter().map(|(address, fields, with_sum)| {
            let body = format!("{address},{}", fields.join(","));
            if with_sum { sentence(&body).into_bytes() } else { format!("${body}").into_bytes() }
        }).collect();
        drive(NmeaDecoder::new(ReadOptions::default()), &lines)?;
    }

    #[test]
    fn n2k_shaped_lines_never_panic(
        messages in proptest::collection::vec(
            (prop::sample::select(vec![127_250u32, 127_251, 127_257, 127_488, 128_259, 129_025, 129_026, 129_029, 130_577, 130_842, 60_928]),
             any::<u8>(), proptest::collection::vec(any::<u8>(), 0..48)),
            1..20),
    ) {
        let lines: Vec<Vec<u8>> = messages.iter().map(|(pgn, src, data)| n2k_line(*pgn, *src, data).into_bytes()).collect();
        drive(N2kDecoder::new(ReadOptions::default()), &lines)?;
    }

    #[test]
    fn json_shaped_lines_never_panic(
        lines in proptest::collection::vec(
            ("(gnss|actuators|wind)", -200.0f64..200.0, -200.0f64..200.0, -10.0f64..60.0, -10.0f64..10.0, proptest::option::of(-1.0f64..5.0), any::<bool>()),
            1..20),
    ) {
        let lines: Vec<Vec<u8>> = lines.into_iter().map(|(kind, a, b, c, d, e, rpm)| {
            let hdop = e.map(|h| format!(",\"hdop\":{h}")).unwrap_or_default();
            let cmd = if rpm { "rpm" } else { "thrust_n" };
            format!(r#"{{"type":"{kind}","time":"2026-08-03T04:27:20Z","lat_deg":{a},"lon_deg":{b},"sog_mps":{c},"cog_rad":{d}{hdop},"{cmd}":{{"port":{a},"starboard":{c}}}}}"#).into_bytes()
        }).collect();
        drive(JsonlDecoder::new(ReadOptions::default()), &lines)?;
    }

    #[test]
    fn n2k_generated_messages_round_trip(
        lat in -90.0f64..=90.0, lon in -180.0f64..=180.0, cog in 0.0f64..std::f64::consts::TAU, sog in 0.0f64..50.0,
        rate in -1.0f64..1.0, rpm_value in 0.0f64..16_000.0, starboard in any::<bool>(),
    ) {
        // 129025: two signed 32-bit fields at 1e-7 deg.
        let mut data = Vec::new();
        data.extend_from_slice(&((lat * 1e7).round() as i32).to_le_bytes());
        data.extend_from_slice(&((lon * 1e7).round() as i32).to_le_bytes());
        let items = decode_n2k(&n2k_line(129_025, 25, &data));
        let Ok(Record { measurement: Measurement::Position { lat_deg, lon_deg, .. }, .. }) = items[0] else {
            return Err(TestCaseError::fail(format!("{items:?}")));
        };
        prop_assert!((lat_deg - lat).abs() <= 0.6e-7 && (lon_deg - lon).abs() <= 0.6e-7);
        // 129026: sid, reference 0 (true) in the low 2 bits, COG u16 1e-4, SOG u16 0.01.
        let mut data = vec![0x01, 0xfc];
        data.extend_from_slice(&((cog * 1e4).round() as u16).to_le_bytes());
        data.extend_from_slice(&((sog * 100.0).round() as u16).to_le_bytes());
        data.extend_from_slice(&[0xff, 0xff]);
        let items = decode_n2k(&n2k_line(129_026, 25, &data));
        let Ok(Record { measurement: Measurement::CourseSpeed { cog_rad: Some(c), sog_mps: Some(s) }, .. }) = items[0] else {
            return Err(TestCaseError::fail(format!("{items:?}")));
        };
        prop_assert!(angle_diff(c, cog).abs() <= 0.6e-4 && (s - sog).abs() <= 0.006);
        // 127251: signed 32-bit at 3.125e-8 rad/s.
        let mut data = vec![0x00];
        data.extend_from_slice(&((rate / 3.125e-8).round() as i32).to_le_bytes());
        data.extend_from_slice(&[0xff, 0xff, 0xff]);
        let items = decode_n2k(&n2k_line(127_251, 27, &data));
        let Ok(Record { measurement: Measurement::RateOfTurn { radps }, .. }) = items[0] else {
            return Err(TestCaseError::fail(format!("{items:?}")));
        };
        prop_assert!((radps - rate).abs() <= 2e-8);
        // 127488: instance, speed u16 at 0.25 rpm.
        let mut data = vec![u8::from(starboard)];
        data.extend_from_slice(&((rpm_value * 4.0).round() as u16).to_le_bytes());
        data.extend_from_slice(&[0xff, 0xff, 0x7f, 0xff, 0xff]);
        let items = decode_n2k(&n2k_line(127_488, 0, &data));
        let Ok(Record { measurement: Measurement::PropellerSpeed { side, radps }, .. }) = items[0] else {
            return Err(TestCaseError::fail(format!("{items:?}")));
        };
        prop_assert_eq!(side, if starboard { Side::Starboard } else { Side::Port });
        prop_assert!((radps / twin_core::sample::RADPS_PER_RPM - rpm_value).abs() <= 0.125 + 1e-9);
    }

    #[test]
    fn any_written_sentence_with_one_corrupted_character_is_rejected(
        which_sentence in 0usize..5, position in 0usize..200, replacement in 0x20u8..0x7f,
        lat in -90.0f64..=90.0, value in 0.0f64..6.0,
    ) {
        let fix = twin_core::sample::GnssFix {
            time_s: 1.7e9,
            position: twin_core::geodesy::LatLon { lat_deg: lat, lon_deg: 10.0 },
            sog_mps: Some(value),
            cog_rad: Some(value),
            heading_rad: None, yaw_rate_radps: None,
            hdop: Some(1.0),
        };
        let gp = Talker::GP;
        let s = match which_sentence {
            0 => rmc(gp, &fix),
            1 => gga(gp, &fix, twin_wire::measurement::FixMethod::Gnss, Some(7), Some(value)),
            2 => vtg(gp, Some(value), Some(value)),
            3 => hdt(gp, value),
            _ => rpm(gp, Side::Port, value * 100.0),
        }.unwrap();
        let star = s.rfind('*').unwrap();
        let i = 1 + position % (star - 1);
        prop_assume!(s.as_bytes()[i] != replacement && replacement != b'*');
        let mut bytes = s.into_bytes();
        bytes[i] = replacement;
        let mut d = NmeaDecoder::new(ReadOptions::default());
        let mut out = Vec::new();
        d.decode_line(&bytes, 1, &mut out);
        prop_assert_eq!(out.len(), 1);
        prop_assert_eq!(d.stats().rejected(RejectKind::BadChecksum), 1);
    }
}
