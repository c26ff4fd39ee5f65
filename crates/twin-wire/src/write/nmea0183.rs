//! NMEA 0183 sentence writers with correct checksums.
//!
//! Precision: time to the millisecond (`hhmmss.sss`), latitude/longitude to
//! 1e-6 minute of arc (about 2 mm), speeds to 0.001 kn, directions to
//! 0.001 deg, propeller speed to 0.01 rpm. Sentences are returned without a
//! line ending; [`NmeaWriter`] writes them with `\r\n`.

use std::io::Write;

use twin_core::geodesy::{MPS_PER_KNOT, rad_to_compass_deg};
use twin_core::sample::{GnssFix, RADPS_PER_RPM, Side};

use super::WriteError;
use crate::measurement::{FixMethod, MAX_SPEED_MPS, Talker};
use crate::messages::MAX_ABS_RPM;
use crate::read::nmea0183::checksum;
use crate::time::{format_ddmmyy, format_hhmmss_ms, split_date_time_ms};

/// `$` + `body` + `*hh`, the checksum being the XOR of `body`.
pub fn sentence(body: &str) -> String {
    format!("${body}*{:02X}", checksum(body.as_bytes()))
}

fn finite(value: f64, field: &'static str) -> Result<f64, WriteError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(WriteError::NotFinite { field })
    }
}

/// Signed degrees as `(d)ddmm.mmmmmm` and a hemisphere letter.
fn degrees_minutes(
    deg: f64,
    width: usize,
    max: f64,
    letters: (char, char),
    field: &'static str,
) -> Result<(String, char), WriteError> {
    let deg = finite(deg, field)?;
    if deg.abs() > max {
        return Err(WriteError::OutOfRange { field });
    }
    // Whole micro-minutes first, so rounding carries into minutes and degrees.
    let micro_minutes = (deg.abs() * 60.0e6).round() as i64;
    let whole_deg = micro_minutes / 60_000_000;
    let rest = micro_minutes % 60_000_000;
    let text = format!(
        "{whole_deg:0width$}{:02}.{:06}",
        rest / 1_000_000,
        rest % 1_000_000
    );
    let letter = if deg < 0.0 { letters.1 } else { letters.0 };
    Ok((text, letter))
}

/// A direction in rad as compass degrees with three decimals, [0, 360).
fn compass_deg(rad: f64, field: &'static str) -> Result<String, WriteError> {
    let milli = (rad_to_compass_deg(finite(rad, field)?) * 1000.0).round() as i64 % 360_000;
    Ok(format!("{}.{:03}", milli / 1000, milli % 1000))
}

fn speed_knots(mps: f64, field: &'static str) -> Result<f64, WriteError> {
    let mps = finite(mps, field)?;
    if !(0.0..=MAX_SPEED_MPS).contains(&mps) {
        return Err(WriteError::OutOfRange { field });
    }
    Ok(mps / MPS_PER_KNOT)
}

fn optional<T>(
    value: Option<T>,
    f: impl FnOnce(T) -> Result<String, WriteError>,
) -> Result<String, WriteError> {
    value.map_or(Ok(String::new()), f)
}

/// RMC: time, date, position, SOG (kn) and true COG of a fix; mode `A`.
pub fn rmc(talker: Talker, fix: &GnssFix) -> Result<String, WriteError> {
    let (date, ms) = split_date_time_ms(fix.time_s)?;
    let (lat, ns) = degrees_minutes(fix.position.lat_deg, 2, 90.0, ('N', 'S'), "lat_deg")?;
    let (lon, ew) = degrees_minutes(fix.position.lon_deg, 3, 180.0, ('E', 'W'), "lon_deg")?;
    let sog = optional(fix.sog_mps, |v| {
        Ok(format!("{:.3}", speed_knots(v, "sog_mps")?))
    })?;
    let cog = optional(fix.cog_rad, |v| compass_deg(v, "cog_rad"))?;
    Ok(sentence(&format!(
        "{talker}RMC,{},A,{lat},{ns},{lon},{ew},{sog},{cog},{},,,A",
        format_hhmmss_ms(ms),
        format_ddmmyy(date)
    )))
}

/// GGA: time, position, quality, satellites, HDOP and height. `altitude_m`
/// is above the ellipsoid and is written as altitude with a zero geoid
/// separation (so it reads back as the same height).
pub fn gga(
    talker: Talker,
    fix: &GnssFix,
    quality: FixMethod,
    satellites: Option<u8>,
    altitude_m: Option<f64>,
) -> Result<String, WriteError> {
    let (_, ms) = split_date_time_ms(fix.time_s)?;
    let (lat, ns) = degrees_minutes(fix.position.lat_deg, 2, 90.0, ('N', 'S'), "lat_deg")?;
    let (lon, ew) = degrees_minutes(fix.position.lon_deg, 3, 180.0, ('E', 'W'), "lon_deg")?;
    let sats = optional(satellites, |n| Ok(format!("{n:02}")))?;
    let hdop = optional(fix.hdop, |h| {
        if finite(h, "hdop")? <= 0.0 {
            return Err(WriteError::OutOfRange { field: "hdop" });
        }
        Ok(format!("{h:.2}"))
    })?;
    let (alt, sep) = match altitude_m {
        Some(a) => (format!("{:.3}", finite(a, "altitude_m")?), "0.0"),
        None => (String::new(), ""),
    };
    Ok(sentence(&format!(
        "{talker}GGA,{},{lat},{ns},{lon},{ew},{},{sats},{hdop},{alt},M,{sep},M,,",
        format_hhmmss_ms(ms),
        quality.code()
    )))
}

/// VTG: true COG, SOG in knots and km/h; mode `A`. No magnetic course.
pub fn vtg(
    talker: Talker,
    cog_rad: Option<f64>,
    sog_mps: Option<f64>,
) -> Result<String, WriteError> {
    let cog = optional(cog_rad, |v| compass_deg(v, "cog_rad"))?;
    let (kn, kmh) = match sog_mps {
        Some(v) => {
            let kn = speed_knots(v, "sog_mps")?;
            (format!("{kn:.3}"), format!("{:.3}", v * 3.6))
        }
        None => (String::new(), String::new()),
    };
    Ok(sentence(&format!(
        "{talker}VTG,{cog},T,,M,{kn},N,{kmh},K,A"
    )))
}

/// HDT: true heading.
pub fn hdt(talker: Talker, heading_rad: f64) -> Result<String, WriteError> {
    Ok(sentence(&format!(
        "{talker}HDT,{},T",
        compass_deg(heading_rad, "heading_rad")?
    )))
}

/// ROT: a rate of turn (rad/s, positive to starboard) in degrees per
/// minute; status `A`.
pub fn rot(talker: Talker, yaw_rate_radps: f64) -> Result<String, WriteError> {
    let r = finite(yaw_rate_radps, "yaw_rate_radps")?;
    if r.abs() > crate::messages::MAX_ABS_YAW_RATE_RADPS {
        return Err(WriteError::OutOfRange {
            field: "yaw_rate_radps",
        });
    }
    Ok(sentence(&format!(
        "{talker}ROT,{:.3},A",
        r.to_degrees() * 60.0
    )))
}

/// RPM of one propeller shaft (source `S`): starboard is shaft 1, port shaft 2
/// (numbered from the centre line, odd = starboard, even = port); status `A`.
pub fn rpm(talker: Talker, side: Side, radps: f64) -> Result<String, WriteError> {
    let rpm = finite(radps, "radps")? / RADPS_PER_RPM;
    if rpm.abs() > MAX_ABS_RPM {
        return Err(WriteError::OutOfRange { field: "radps" });
    }
    let shaft = match side {
        Side::Starboard => 1,
        Side::Port => 2,
    };
    Ok(sentence(&format!("{talker}RPM,S,{shaft},{rpm:.2},,A")))
}

/// ZDA: date and time (UTC, zone 00:00).
pub fn zda(talker: Talker, time_s: f64) -> Result<String, WriteError> {
    let (date, ms) = split_date_time_ms(time_s)?;
    Ok(sentence(&format!(
        "{talker}ZDA,{},{:02},{:02},{:04},00,00",
        format_hhmmss_ms(ms),
        date.day(),
        date.month(),
        date.year()
    )))
}

/// Writes sentences to an output, each followed by `\r\n`.
#[derive(Debug)]
pub struct NmeaWriter<W> {
    out: W,
    talker: Talker,
}

impl<W: Write> NmeaWriter<W> {
    /// A writer using `talker` for every sentence.
    pub fn new(out: W, talker: Talker) -> Self {
        Self { out, talker }
    }

    fn line(&mut self, sentence: Result<String, WriteError>) -> Result<(), WriteError> {
        let s = sentence?;
        self.out.write_all(s.as_bytes())?;
        self.out.write_all(b"\r\n")?;
        Ok(())
    }

    /// Writes an RMC of `fix`.
    pub fn rmc(&mut self, fix: &GnssFix) -> Result<(), WriteError> {
        let s = rmc(self.talker, fix);
        self.line(s)
    }

    /// Writes a GGA of `fix`.
    pub fn gga(
        &mut self,
        fix: &GnssFix,
        quality: FixMethod,
        satellites: Option<u8>,
        altitude_m: Option<f64>,
    ) -> Result<(), WriteError> {
        let s = gga(self.talker, fix, quality, satellites, altitude_m);
        self.line(s)
    }

    /// Writes a VTG.
    pub fn vtg(&mut self, cog_rad: Option<f64>, sog_mps: Option<f64>) -> Result<(), WriteError> {
        let s = vtg(self.talker, cog_rad, sog_mps);
        self.line(s)
    }

    /// Writes an HDT.
    pub fn hdt(&mut self, heading_rad: f64) -> Result<(), WriteError> {
        let s = hdt(self.talker, heading_rad);
        self.line(s)
    }

    /// Writes an RPM.
    pub fn rpm(&mut self, side: Side, radps: f64) -> Result<(), WriteError> {
        let s = rpm(self.talker, side, radps);
        self.line(s)
    }

    /// Writes a ZDA.
    pub fn zda(&mut self, time_s: f64) -> Result<(), WriteError> {
        let s = zda(self.talker, time_s);
        self.line(s)
    }

    /// The output back.
    pub fn into_inner(self) -> W {
        self.out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measurement::{Measurement, Record};
    use crate::read::{Decoder, Item, NmeaDecoder, ReadOptions, RejectKind};
    use proptest::prelude::*;
    use twin_core::geodesy::LatLon;

    fn fix(t: f64, lat: f64, lon: f64) -> GnssFix {
        GnssFix {
            time_s: t,
            position: LatLon {
                lat_deg: lat,
                lon_deg: lon,
            },
            sog_mps: Some(2.5),
            cog_rad: Some(1.0),
            heading_rad: None,
            yaw_rate_radps: None,
            hdop: Some(0.9),
        }
    }

    fn read(lines: &[String]) -> Vec<Item> {
        let mut d = NmeaDecoder::new(ReadOptions::default());
        let mut out = Vec::new();
        for (i, l) in lines.iter().enumerate() {
            d.decode_line(l.as_bytes(), i as u64 + 1, &mut out);
        }
        out
    }

    #[test]
    fn known_sentences_and_checksums() {
        // 2026-08-03T04:27:20.588Z, 34.41 N 133.54 E.
        let f = fix(1_785_731_240.588, 34.41, 133.54);
        assert_eq!(
            rmc(Talker::GP, &f).unwrap(),
            "$GPRMC,042720.588,A,3424.600000,N,13332.400000,E,4.860,57.296,030826,,,A*51"
        );
        assert_eq!(
            hdt(Talker::new(*b"HE").unwrap(), 0.0).unwrap(),
            "$HEHDT,0.000,T*2F"
        );
        // The plaka HDT checksum: "IIHDT,,T" XORs to 0x0C.
        assert_eq!(sentence("IIHDT,,T"), "$IIHDT,,T*0C");
        assert_eq!(
            rpm(
                Talker::new(*b"ER").unwrap(),
                Side::Port,
                -60.0 * RADPS_PER_RPM
            )
            .unwrap(),
            "$ERRPM,S,2,-60.00,,A*51"
        );
    }

    #[test]
    fn writers_refuse_unwritable_values() {
        let f = fix(0.0, 91.0, 0.0);
        assert!(matches!(
            rmc(Talker::GP, &f),
            Err(WriteError::OutOfRange { field: "lat_deg" })
        ));
        assert!(matches!(
            hdt(Talker::GP, f64::NAN),
            Err(WriteError::NotFinite { .. })
        ));
        assert!(matches!(
            vtg(Talker::GP, None, Some(-1.0)),
            Err(WriteError::OutOfRange { .. })
        ));
        assert!(matches!(
            rmc(Talker::GP, &fix(f64::INFINITY, 0.0, 0.0)),
            Err(WriteError::Time(_))
        ));
    }

    #[test]
    fn round_trip_each_sentence_through_the_reader() {
        let t = 1_785_731_240.588;
        let f = fix(t, -33.858_333, -70.620_833);
        let lines = vec![
            rmc(Talker::GP, &f).unwrap(),
            gga(Talker::GP, &f, FixMethod::RtkFloat, Some(14), Some(31.25)).unwrap(),
            vtg(Talker::GP, Some(6.2), Some(3.1)).unwrap(),
            hdt(Talker::GP, 0.5).unwrap(),
            rpm(Talker::GP, Side::Starboard, 100.0).unwrap(),
            rpm(Talker::GP, Side::Port, -20.0).unwrap(),
        ];
        let items = read(&lines);
        let records: Vec<&Record> = items.iter().map(|i| i.as_ref().unwrap()).collect();
        assert_eq!(records.len(), 7);
        assert!(records.iter().all(|r| (r.time_s - t).abs() < 1e-6));
        let Measurement::Position {
            lat_deg, lon_deg, ..
        } = records[0].measurement
        else {
            panic!()
        };
        assert!(
            (lat_deg - f.position.lat_deg).abs() < 1e-7
                && (lon_deg - f.position.lon_deg).abs() < 1e-7
        );
        let Measurement::Position {
            hdop,
            method,
            altitude_m,
            ..
        } = records[2].measurement
        else {
            panic!()
        };
        assert_eq!(
            (hdop, method, altitude_m),
            (Some(0.9), Some(FixMethod::RtkFloat), Some(31.25))
        );
        let Measurement::CourseSpeed { cog_rad, sog_mps } = records[3].measurement else {
            panic!()
        };
        assert!((cog_rad.unwrap() - 6.2).abs() < 1e-4 && (sog_mps.unwrap() - 3.1).abs() < 1e-3);
        let Measurement::Heading { heading_rad } = records[4].measurement else {
            panic!()
        };
        assert!((heading_rad - 0.5).abs() < 1e-4);
        assert!(matches!(records[5].measurement,
            Measurement::PropellerSpeed { side: Side::Starboard, radps } if (radps - 100.0).abs() < 1e-3));
        assert!(matches!(records[6].measurement,
            Measurement::PropellerSpeed { side: Side::Port, radps } if (radps + 20.0).abs() < 1e-3));
    }

    #[test]
    fn rounding_carries_into_minutes_and_degrees() {
        // 59.999 999 999 9 deg rounds to 60 deg 00.000000'.
        let f = fix(0.0, 59.999_999_999_9, -0.000_000_000_1);
        let s = rmc(Talker::GP, &f).unwrap();
        assert!(s.contains(",6000.000000,N,00000.000000,W,"), "{s}");
        // 359.9999 deg rounds to 0.000, never 360.000.
        assert_eq!(
            hdt(Talker::GP, (359.9999f64).to_radians()).unwrap(),
            sentence("GPHDT,0.000,T")
        );
    }

    proptest! {
        #[test]
        fn generated_fixes_round_trip(
            // RMC's two-digit year covers 1980-2079 only.
            t in 315_532_800.0f64..3.47e9, lat in -90.0f64..=90.0, lon in -180.0f64..=180.0,
            sog in 0.0f64..50.0, cog in 0.0f64..std::f64::consts::TAU, heading in 0.0f64..std::f64::consts::TAU,
            port in -2000.0f64..2000.0, stbd in -2000.0f64..2000.0,
        ) {
            let mut f = fix(t, lat, lon);
            f.sog_mps = Some(sog);
            f.cog_rad = Some(cog);
            let lines = vec![
                zda(Talker::GP, t).unwrap(),
                rmc(Talker::GP, &f).unwrap(),
                gga(Talker::GP, &f, FixMethod::Dgnss, None, None).unwrap(),
                vtg(Talker::GP, Some(cog), Some(sog)).unwrap(),
                hdt(Talker::GP, heading).unwrap(),
                rpm(Talker::GP, Side::Port, port).unwrap(),
                rpm(Talker::GP, Side::Starboard, stbd).unwrap(),
            ];
            let items = read(&lines);
            prop_assert_eq!(items.len(), 7, "{:?}", items);
            let angle_close = |a: f64, b: f64| twin_core::geodesy::angle_diff(a, b).abs() < 2e-5;
            for item in &items {
                let r = item.as_ref().unwrap();
                prop_assert!((r.time_s - t).abs() < 6e-4, "{} vs {}", r.time_s, t);
                match r.measurement {
                    Measurement::Position { lat_deg, lon_deg, .. } => {
                        prop_assert!((lat_deg - lat).abs() < 2e-8 && (lon_deg - lon).abs() < 2e-8);
                    }
                    Measurement::CourseSpeed { cog_rad, sog_mps } => {
                        prop_assert!(angle_close(cog_rad.unwrap(), cog));
                        prop_assert!((sog_mps.unwrap() - sog).abs() < 3e-4);
                    }
                    Measurement::Heading { heading_rad } => prop_assert!(angle_close(heading_rad, heading)),
                    Measurement::PropellerSpeed { side: Side::Port, radps } => prop_assert!((radps - port).abs() < 1e-3),
                    Measurement::PropellerSpeed { side: Side::Starboard, radps } => prop_assert!((radps - stbd).abs() < 1e-3),
                    ref m => prop_assert!(false, "unexpected {:?}", m),
                }
            }
        }

        #[test]
        fn corrupting_one_character_is_detected(
            lat in -90.0f64..=90.0, lon in -180.0f64..=180.0, which in 0usize..1000, replacement in 0x20u8..0x7f,
        ) {
            let s = rmc(Talker::GP, &fix(1.7e9, lat, lon)).unwrap();
            let bytes = s.as_bytes();
            let star = s.rfind('*').unwrap();
            // Any character between '$' and '*' (not turning it into '*').
            let i = 1 + which % (star - 1);
            prop_assume!(bytes[i] != replacement && replacement != b'*');
            let mut corrupted = bytes.to_vec();
            corrupted[i] = replacement;
            let mut d = NmeaDecoder::new(ReadOptions::default());
            let mut out = Vec::new();
            d.decode_line(&corrupted, 1, &mut out);
            prop_assert_eq!(out.len(), 1);
            prop_assert_eq!(d.stats().rejected(RejectKind::BadChecksum), 1);
        }
    }
}
