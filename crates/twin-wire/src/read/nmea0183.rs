//! NMEA 0183 sentences to [`Record`](crate::measurement::Record)s: RMC, GGA, GLL, VTG, HDT, HDG, HDM,
//! ROT, VHW, RPM and ZDA. Other sentences (wind, depth, AIS `!` sentences,
//! proprietary `$P...`) are counted as ignored.
//!
//! # Checks
//! A `*hh` checksum, when present, must match the XOR of the characters
//! between `$` and `*`; a sentence without one is accepted and counted in
//! `ReadStats::without_checksum`. The talker id is kept as the record's
//! source. An empty field means "absent", never zero: plaka.log's
//! `$IIHDT,,T` is a heading sentence with no heading (counted as `empty`).
//!
//! # Timing, decided here on purpose
//! - RMC (date + time) and ZDA with its date set the date and the time.
//! - GGA, GLL and a ZDA without date (plaka.log) carry only a time of day:
//!   they take the current date. Of that date, the day before and the day
//!   after, the one that puts the sentence nearest the latest time is used,
//!   so a log crossing midnight (time of day wrapping from 23:59:59 to
//!   00:00:00) advances the date, and a sentence stamped just before
//!   midnight that arrives just after it does not jump a day ahead.
//! - With no date yet, `ReadOptions::assumed_date` is used (default
//!   1970-01-01, each such record counted as `undated`); `None` rejects them
//!   (`NoDate`).
//! - VTG, HDT, HDG, HDM, ROT, VHW and RPM carry no time: they take the time of the
//!   latest timed sentence. A text log has no arrival times, so a "burst" of
//!   sentences cannot be told apart from the next one; in plaka.log the
//!   untimed VTG/VHW of a burst come before its ZDA/GLL and so are stamped
//!   with the previous burst's time (one burst, about 2 s, early). Untimed
//!   sentences before any timed one are rejected (`NoTime`).
//! - A time more than `backwards_tolerance_s` before the newest time seen is
//!   rejected (`TimeBackwards`) and does not move the clock. Gaps are gaps.
//!
//! # Conversions
//! Knots to m/s (1852/3600), km/h only when knots are absent; degrees to rad
//! wrapped to [0, 2 pi); `ddmm.mmm` to degrees. Headings: HDT true; HDG and
//! HDM magnetic, made true with the sentence's own variation (HDG) or the
//! latest variation seen in an RMC or HDG, else rejected as
//! `MagneticWithoutVariation`. Courses: only the true VTG/RMC course is used;
//! a VTG with only a magnetic course gives its speed and a `MagneticCourse`
//! rejection. ROT: degrees per minute, negative turning to port, to rad/s;
//! status `V` rejected. RPM: shaft (`S`) and engine (`E`) sources both map to propeller
//! speed; numbers from the centre line, odd = starboard, even = port, 0
//! (centre line) rejected as `UnknownPropeller`.

use twin_core::geodesy::{MPS_PER_KNOT, wrap_two_pi};
use twin_core::sample::{RADPS_PER_RPM, Side};

use super::clock::{DayClock, Stamp};
use super::{
    Decoder, Emit, Item, ReadOptions, ReadStats, RejectReason, reject_whole_line, trim_line,
};
use crate::measurement::{FixMethod, MAX_SPEED_MPS, Measurement, Source, Talker};
use crate::messages::MAX_ABS_YAW_RATE_RADPS;
use crate::time::{parse_ddmmyy, parse_hhmmss};

/// The most comma-separated fields a sentence may have (standard sentences
/// have at most ~20; GSV and proprietary ones a few more).
pub const MAX_FIELDS: usize = 40;

/// The XOR checksum of the characters between `$` (or `!`) and `*`.
pub fn checksum(body: &[u8]) -> u8 {
    body.iter().fold(0, |acc, b| acc ^ b)
}

/// The stateful NMEA 0183 decoder (date, latest time, magnetic variation).
#[derive(Debug, Clone)]
pub struct NmeaDecoder {
    options: ReadOptions,
    stats: ReadStats,
    state: State,
}

#[derive(Debug, Clone, Default)]
struct State {
    /// The date and the latest timed sentence's time.
    clock: DayClock,
    /// Latest magnetic variation seen (RMC, HDG), rad, east positive.
    variation_rad: Option<f64>,
}

/// The fields of one sentence after its address (`f[0]` is the first data
/// field); a missing trailing field reads as empty.
struct Fields<'a> {
    fields: [&'a str; MAX_FIELDS],
    len: usize,
}

impl<'a> Fields<'a> {
    fn get(&self, i: usize) -> &'a str {
        if i < self.len { self.fields[i] } else { "" }
    }
}

impl NmeaDecoder {
    /// A decoder with `options`.
    pub fn new(options: ReadOptions) -> Self {
        Self {
            options,
            stats: ReadStats::default(),
            state: State::default(),
        }
    }

    /// Decodes a payload of one or more sentences (lines separated by `\n`
    /// or `\r\n`), e.g. a message of `{prefix}/{vessel}/nmea`. Line numbers
    /// in rejections count from 1 within the payload.
    pub fn decode_payload(&mut self, payload: &[u8], out: &mut Vec<Item>) {
        for (i, line) in payload.split(|&b| b == b'\n').enumerate() {
            if trim_line(line).is_empty() {
                continue;
            }
            if line.len() > self.options.max_line_bytes {
                self.reject_line(
                    i as u64 + 1,
                    RejectReason::LineTooLong {
                        limit: self.options.max_line_bytes,
                    },
                    out,
                );
            } else {
                self.decode_line(line, i as u64 + 1, out);
            }
        }
    }
}

impl Decoder for NmeaDecoder {
    fn decode_line(&mut self, line: &[u8], line_no: u64, out: &mut Vec<Item>) {
        self.stats.lines += 1;
        let mut emit = Emit {
            out,
            stats: &mut self.stats,
            line: line_no,
        };
        if let Err(reason) = self.state.sentence(line, &self.options, &mut emit) {
            emit.reject(reason);
        }
    }

    fn reject_line(&mut self, line_no: u64, reason: RejectReason, out: &mut Vec<Item>) {
        reject_whole_line(&mut self.stats, line_no, reason, out);
    }

    fn stats(&self) -> &ReadStats {
        &self.stats
    }
}

/// Parses a plain decimal number (`-12.5`, `.5`, `7`): no exponent, no
/// `inf`/`nan`, at most 32 characters.
fn decimal(text: &str) -> Option<f64> {
    let bytes = text.as_bytes();
    if bytes.is_empty() || bytes.len() > 32 {
        return None;
    }
    let digits = match bytes[0] {
        b'-' | b'+' => &bytes[1..],
        _ => bytes,
    };
    let mut seen_digit = false;
    let mut seen_point = false;
    for &b in digits {
        match b {
            b'0'..=b'9' => seen_digit = true,
            b'.' if !seen_point => seen_point = true,
            _ => return None,
        }
    }
    if !seen_digit {
        return None;
    }
    text.parse::<f64>().ok().filter(|v| v.is_finite())
}

/// An optional number field: empty is `None`, garbage is `BadField`.
fn number(text: &str, field: &'static str) -> Result<Option<f64>, RejectReason> {
    if text.is_empty() {
        return Ok(None);
    }
    decimal(text)
        .map(Some)
        .ok_or(RejectReason::BadField { field })
}

/// A unit or reference letter field: must be empty or `letter`.
fn unit(text: &str, letter: &str, field: &'static str) -> Result<(), RejectReason> {
    if text.is_empty() || text == letter {
        Ok(())
    } else {
        Err(RejectReason::BadField { field })
    }
}

/// Degrees and minutes (`ddmm.mmm` or `dddmm.mmm`) with a hemisphere letter
/// to signed degrees. Both empty is `None`; one of the two empty is an error.
fn angle_dm(
    value: &str,
    hemisphere: &str,
    positive: &str,
    negative: &str,
    max_deg: f64,
    field: &'static str,
) -> Result<Option<f64>, RejectReason> {
    match (value.is_empty(), hemisphere.is_empty()) {
        (true, true) => return Ok(None),
        (false, false) => {}
        _ => return Err(RejectReason::BadField { field }),
    }
    let sign = if hemisphere == positive {
        1.0
    } else if hemisphere == negative {
        -1.0
    } else {
        return Err(RejectReason::BadField { field });
    };
    let bad = RejectReason::BadField { field };
    if !value.bytes().all(|b| b.is_ascii_digit() || b == b'.') {
        return Err(bad);
    }
    // The last two digits before the point are whole minutes.
    let point = value.find('.').unwrap_or(value.len());
    if point < 3 {
        return Err(bad);
    }
    let degrees = decimal(&value[..point - 2]).ok_or(bad.clone())?;
    let minutes = decimal(&value[point - 2..]).ok_or(bad)?;
    if minutes >= 60.0 {
        return Err(RejectReason::OutOfRange { field });
    }
    let deg = degrees + minutes / 60.0;
    if deg > max_deg {
        return Err(RejectReason::OutOfRange { field });
    }
    Ok(Some(sign * deg))
}

/// A speed in m/s from a knots field, else a km/h field; range checked.
fn speed(knots: &str, kmh: &str, field: &'static str) -> Result<Option<f64>, RejectReason> {
    let mps = match number(knots, field)? {
        Some(kn) => Some(kn * MPS_PER_KNOT),
        None => number(kmh, field)?.map(|v| v / 3.6),
    };
    match mps {
        Some(v) if !(0.0..=MAX_SPEED_MPS).contains(&v) => Err(RejectReason::OutOfRange { field }),
        other => Ok(other),
    }
}

/// A direction in degrees to rad in [0, 2 pi).
fn direction(text: &str, field: &'static str) -> Result<Option<f64>, RejectReason> {
    Ok(number(text, field)?.map(|deg| wrap_two_pi(deg.to_radians())))
}

/// A signed magnetic variation or deviation (degrees + `E`/`W`) in rad, east
/// positive.
fn east_west(value: &str, letter: &str, field: &'static str) -> Result<Option<f64>, RejectReason> {
    let Some(deg) = number(value, field)? else {
        return Ok(None);
    };
    match letter {
        "E" => Ok(Some(deg.to_radians())),
        "W" => Ok(Some(-deg.to_radians())),
        _ => Err(RejectReason::BadField { field }),
    }
}

/// The fix method of a mode indicator; `N` (not valid) is an error.
fn mode(text: &str) -> Result<Option<FixMethod>, RejectReason> {
    match text.as_bytes().first() {
        None => Ok(None),
        Some(b'N') => Err(RejectReason::NotValid { what: "mode" }),
        Some(&m) => Ok(FixMethod::from_mode(m)),
    }
}

impl State {
    /// Decodes one sentence; `Err` rejects the whole sentence.
    fn sentence(
        &mut self,
        line: &[u8],
        options: &ReadOptions,
        emit: &mut Emit<'_>,
    ) -> Result<(), RejectReason> {
        let line = trim_line(line);
        if line.is_empty() {
            emit.stats.blank += 1;
            return Ok(());
        }
        if !line.iter().all(|b| (0x20..0x7f).contains(b)) {
            return Err(RejectReason::NotText);
        }
        // Printable ASCII only, so this cannot fail.
        let text = std::str::from_utf8(line).map_err(|_| RejectReason::NotText)?;
        let Some(start) = text.chars().next().filter(|c| *c == '$' || *c == '!') else {
            return Err(RejectReason::UnknownFormat);
        };
        let rest = &text[1..];
        let body = match rest.rfind('*') {
            Some(star) => {
                let (body, sum) = (&rest[..star], &rest[star + 1..]);
                if sum.len() != 2 || !sum.bytes().all(|b| b.is_ascii_hexdigit()) {
                    return Err(RejectReason::Malformed { what: "checksum" });
                }
                let expected = u8::from_str_radix(sum, 16)
                    .map_err(|_| RejectReason::Malformed { what: "checksum" })?;
                let computed = checksum(body.as_bytes());
                if expected != computed {
                    return Err(RejectReason::BadChecksum { expected, computed });
                }
                body
            }
            None => {
                emit.stats.without_checksum += 1;
                rest
            }
        };
        let mut parts = body.split(',');
        let address = parts.next().unwrap_or("");
        let mut fields = Fields {
            fields: [""; MAX_FIELDS],
            len: 0,
        };
        for part in parts {
            if fields.len == MAX_FIELDS {
                return Err(RejectReason::Malformed {
                    what: "field count",
                });
            }
            fields.fields[fields.len] = part;
            fields.len += 1;
        }
        if !address
            .bytes()
            .all(|b| b.is_ascii_uppercase() || b.is_ascii_digit())
            || address.is_empty()
        {
            return Err(RejectReason::Malformed { what: "address" });
        }
        // AIS (`!`) and proprietary (`$P...`) sentences are not read.
        if start == '!' || address.starts_with('P') {
            emit.stats.ignored += 1;
            return Ok(());
        }
        let bytes = address.as_bytes();
        if bytes.len() != 5 {
            return Err(RejectReason::Malformed { what: "address" });
        }
        let talker =
            Talker::new([bytes[0], bytes[1]]).ok_or(RejectReason::Malformed { what: "address" })?;
        let source = Source::Nmea(talker);
        let f = &fields;
        match &address[2..] {
            "RMC" => self.rmc(f, source, options, emit),
            "GGA" => self.gga(f, source, options, emit),
            "GLL" => self.gll(f, source, options, emit),
            "ZDA" => self.zda(f, options, emit),
            "VTG" => self.vtg(f, source, options, emit),
            "HDT" => self.hdt(f, source, options, emit),
            "HDG" => self.hdg(f, source, options, emit),
            "HDM" => self.hdm(f, source, options, emit),
            "ROT" => self.rot(f, source, emit),
            "VHW" => self.vhw(f, source, options, emit),
            "RPM" => self.rpm(f, source, options, emit),
            _ => {
                emit.stats.ignored += 1;
                Ok(())
            }
        }
    }

    /// The time of a sentence with a full date.
    fn dated(
        &mut self,
        days: i64,
        tod_s: f64,
        options: &ReadOptions,
    ) -> Result<Stamp, RejectReason> {
        self.clock.dated(days, tod_s, options.backwards_tolerance_s)
    }

    /// The time of a time-of-day-only sentence (see the module doc).
    fn time_of_day(&mut self, tod_s: f64, options: &ReadOptions) -> Result<Stamp, RejectReason> {
        self.clock
            .time_of_day(tod_s, options.assumed_date, options.backwards_tolerance_s)
    }

    /// The time of a sentence without time: the latest timed sentence's.
    fn untimed(&self) -> Result<Stamp, RejectReason> {
        self.clock.untimed()
    }

    fn record(emit: &mut Emit<'_>, stamp: Stamp, source: Source, measurement: Measurement) {
        if stamp.undated {
            emit.stats.undated += 1;
        }
        emit.record(stamp.time_s, source, measurement);
    }

    fn time_field(text: &str) -> Result<f64, RejectReason> {
        if text.is_empty() {
            return Err(RejectReason::BadField { field: "time" });
        }
        parse_hhmmss(text).map_err(RejectReason::BadTime)
    }

    fn position(f: &Fields<'_>, at: usize) -> Result<Option<(f64, f64)>, RejectReason> {
        let lat = angle_dm(f.get(at), f.get(at + 1), "N", "S", 90.0, "latitude")?;
        let lon = angle_dm(f.get(at + 2), f.get(at + 3), "E", "W", 180.0, "longitude")?;
        match (lat, lon) {
            (Some(lat), Some(lon)) => Ok(Some((lat, lon))),
            (None, None) => Ok(None),
            (Some(_), None) => Err(RejectReason::BadField { field: "longitude" }),
            (None, Some(_)) => Err(RejectReason::BadField { field: "latitude" }),
        }
    }

    /// `$--RMC,hhmmss.ss,A,llll.ll,a,yyyyy.yy,a,x.x,x.x,ddmmyy,x.x,a,m[,s]`
    fn rmc(
        &mut self,
        f: &Fields<'_>,
        source: Source,
        options: &ReadOptions,
        emit: &mut Emit<'_>,
    ) -> Result<(), RejectReason> {
        if f.len < 9 {
            return Err(RejectReason::Malformed {
                what: "RMC field count",
            });
        }
        match f.get(1) {
            "A" => {}
            "V" => return Err(RejectReason::NotValid { what: "RMC status" }),
            _ => return Err(RejectReason::BadField { field: "status" }),
        }
        let method = mode(f.get(11))?;
        let tod = Self::time_field(f.get(0))?;
        let position = Self::position(f, 2)?;
        let sog = speed(f.get(6), "", "sog")?;
        let cog = direction(f.get(7), "cog")?;
        let variation = east_west(f.get(9), f.get(10), "variation")?;
        let stamp = if f.get(8).is_empty() {
            self.time_of_day(tod, options)?
        } else {
            let date = parse_ddmmyy(f.get(8)).map_err(RejectReason::BadTime)?;
            self.dated(date.days_since_epoch(), tod, options)?
        };
        if variation.is_some() {
            self.variation_rad = variation;
        }
        if position.is_none() && sog.is_none() && cog.is_none() {
            emit.stats.empty += 1;
            return Ok(());
        }
        if let Some((lat_deg, lon_deg)) = position {
            let m = Measurement::Position {
                lat_deg,
                lon_deg,
                hdop: None,
                method,
                altitude_m: None,
            };
            Self::record(emit, stamp, source, m);
        }
        if sog.is_some() || cog.is_some() {
            let m = Measurement::CourseSpeed {
                cog_rad: cog,
                sog_mps: sog,
            };
            Self::record(emit, stamp, source, m);
        }
        Ok(())
    }

    /// `$--GGA,hhmmss.ss,llll.ll,a,yyyyy.yy,a,q,nn,h.h,a.a,M,g.g,M,x.x,xxxx`
    fn gga(
        &mut self,
        f: &Fields<'_>,
        source: Source,
        options: &ReadOptions,
        emit: &mut Emit<'_>,
    ) -> Result<(), RejectReason> {
        if f.len < 6 {
            return Err(RejectReason::Malformed {
                what: "GGA field count",
            });
        }
        let quality = match number(f.get(5), "quality")? {
            Some(0.0) => {
                return Err(RejectReason::NotValid {
                    what: "GGA quality",
                });
            }
            Some(q) if q.fract() == 0.0 && (1.0..=9.0).contains(&q) => {
                FixMethod::from_code(q as u64)
            }
            Some(_) => return Err(RejectReason::BadField { field: "quality" }),
            None => None,
        };
        let tod = Self::time_field(f.get(0))?;
        let position = Self::position(f, 1)?;
        let hdop = number(f.get(7), "hdop")?.filter(|h| *h > 0.0);
        unit(f.get(9), "M", "altitude unit")?;
        unit(f.get(11), "M", "geoid separation unit")?;
        let altitude = number(f.get(8), "altitude")?;
        let separation = number(f.get(10), "geoid separation")?;
        let stamp = self.time_of_day(tod, options)?;
        let Some((lat_deg, lon_deg)) = position else {
            emit.stats.empty += 1;
            return Ok(());
        };
        let m = Measurement::Position {
            lat_deg,
            lon_deg,
            hdop,
            method: quality,
            altitude_m: altitude.zip(separation).map(|(a, s)| a + s),
        };
        Self::record(emit, stamp, source, m);
        Ok(())
    }

    /// `$--GLL,llll.ll,a,yyyyy.yy,a[,hhmmss.ss,A[,m]]`
    fn gll(
        &mut self,
        f: &Fields<'_>,
        source: Source,
        options: &ReadOptions,
        emit: &mut Emit<'_>,
    ) -> Result<(), RejectReason> {
        if f.len < 4 {
            return Err(RejectReason::Malformed {
                what: "GLL field count",
            });
        }
        match f.get(5) {
            "" | "A" => {}
            "V" => return Err(RejectReason::NotValid { what: "GLL status" }),
            _ => return Err(RejectReason::BadField { field: "status" }),
        }
        let method = mode(f.get(6))?;
        let position = Self::position(f, 0)?;
        if position.is_none() && f.get(4).is_empty() {
            emit.stats.empty += 1;
            return Ok(());
        }
        let stamp = if f.get(4).is_empty() {
            self.untimed()?
        } else {
            let tod = Self::time_field(f.get(4))?;
            self.time_of_day(tod, options)?
        };
        let Some((lat_deg, lon_deg)) = position else {
            emit.stats.empty += 1;
            return Ok(());
        };
        let m = Measurement::Position {
            lat_deg,
            lon_deg,
            hdop: None,
            method,
            altitude_m: None,
        };
        Self::record(emit, stamp, source, m);
        Ok(())
    }

    /// `$--ZDA,hhmmss.ss,dd,mm,yyyy,zh,zm`: sets the clock, gives no record.
    fn zda(
        &mut self,
        f: &Fields<'_>,
        options: &ReadOptions,
        emit: &mut Emit<'_>,
    ) -> Result<(), RejectReason> {
        let tod = Self::time_field(f.get(0))?;
        let (day, month, year) = (f.get(1), f.get(2), f.get(3));
        if day.is_empty() && month.is_empty() && year.is_empty() {
            self.time_of_day(tod, options)?;
        } else {
            fn parse(s: &str, field: &'static str) -> Result<u16, RejectReason> {
                if !s.is_empty() && s.len() <= 4 && s.bytes().all(|b| b.is_ascii_digit()) {
                    s.parse::<u16>()
                        .map_err(|_| RejectReason::BadField { field })
                } else {
                    Err(RejectReason::BadField { field })
                }
            }
            let day = parse(day, "day")?;
            let month = parse(month, "month")?;
            let year = parse(year, "year")?;
            if year < 1000 {
                return Err(RejectReason::BadField { field: "year" });
            }
            let date = crate::time::CivilDate::new(
                i32::from(year),
                u8::try_from(month).map_err(|_| RejectReason::BadField { field: "month" })?,
                u8::try_from(day).map_err(|_| RejectReason::BadField { field: "day" })?,
            )
            .map_err(RejectReason::BadTime)?;
            self.dated(date.days_since_epoch(), tod, options)?;
        }
        emit.stats.time_only += 1;
        Ok(())
    }

    /// `$--VTG,x.x,T,x.x,M,x.x,N,x.x,K[,m]`
    fn vtg(
        &mut self,
        f: &Fields<'_>,
        source: Source,
        _options: &ReadOptions,
        emit: &mut Emit<'_>,
    ) -> Result<(), RejectReason> {
        if f.len < 8 {
            return Err(RejectReason::Malformed {
                what: "VTG field count",
            });
        }
        unit(f.get(1), "T", "true course unit")?;
        unit(f.get(3), "M", "magnetic course unit")?;
        unit(f.get(5), "N", "knots unit")?;
        unit(f.get(7), "K", "km/h unit")?;
        mode(f.get(8))?;
        let cog = direction(f.get(0), "cog")?;
        let magnetic = direction(f.get(2), "magnetic cog")?;
        let sog = speed(f.get(4), f.get(6), "sog")?;
        if cog.is_none() && sog.is_none() && magnetic.is_none() {
            emit.stats.empty += 1;
            return Ok(());
        }
        let stamp = self.untimed()?;
        if cog.is_none() && sog.is_none() {
            return Err(RejectReason::MagneticCourse);
        }
        let m = Measurement::CourseSpeed {
            cog_rad: cog,
            sog_mps: sog,
        };
        Self::record(emit, stamp, source, m);
        if cog.is_none() && magnetic.is_some() {
            emit.reject(RejectReason::MagneticCourse);
        }
        Ok(())
    }

    fn heading(emit: &mut Emit<'_>, stamp: Stamp, source: Source, heading_rad: f64) {
        let m = Measurement::Heading {
            heading_rad: wrap_two_pi(heading_rad),
        };
        Self::record(emit, stamp, source, m);
    }

    /// `$--HDT,x.x,T`
    fn hdt(
        &mut self,
        f: &Fields<'_>,
        source: Source,
        _options: &ReadOptions,
        emit: &mut Emit<'_>,
    ) -> Result<(), RejectReason> {
        unit(f.get(1), "T", "heading reference")?;
        let Some(heading) = direction(f.get(0), "heading")? else {
            emit.stats.empty += 1;
            return Ok(());
        };
        let stamp = self.untimed()?;
        Self::heading(emit, stamp, source, heading);
        Ok(())
    }

    /// `$--ROT,x.x,A`: rate of turn, degrees per minute, negative turning to
    /// port; status `A` valid, `V` not.
    fn rot(
        &mut self,
        f: &Fields<'_>,
        source: Source,
        emit: &mut Emit<'_>,
    ) -> Result<(), RejectReason> {
        match f.get(1) {
            "A" | "" => {}
            "V" => return Err(RejectReason::NotValid { what: "ROT status" }),
            _ => {
                return Err(RejectReason::BadField {
                    field: "rot status",
                });
            }
        }
        let Some(deg_per_min) = number(f.get(0), "rate of turn")? else {
            emit.stats.empty += 1;
            return Ok(());
        };
        let radps = deg_per_min.to_radians() / 60.0;
        if radps.abs() > MAX_ABS_YAW_RATE_RADPS {
            return Err(RejectReason::OutOfRange {
                field: "rate of turn",
            });
        }
        let stamp = self.untimed()?;
        Self::record(emit, stamp, source, Measurement::RateOfTurn { radps });
        Ok(())
    }

    /// `$--HDM,x.x,M`: magnetic heading, made true with the latest variation.
    fn hdm(
        &mut self,
        f: &Fields<'_>,
        source: Source,
        _options: &ReadOptions,
        emit: &mut Emit<'_>,
    ) -> Result<(), RejectReason> {
        unit(f.get(1), "M", "heading reference")?;
        let Some(heading) = number(f.get(0), "heading")?.map(f64::to_radians) else {
            emit.stats.empty += 1;
            return Ok(());
        };
        let stamp = self.untimed()?;
        let variation = self
            .variation_rad
            .ok_or(RejectReason::MagneticWithoutVariation)?;
        Self::heading(emit, stamp, source, heading + variation);
        Ok(())
    }

    /// `$--HDG,x.x,x.x,a,x.x,a`: magnetic sensor heading, deviation and
    /// variation (east positive); true = sensor + deviation + variation.
    fn hdg(
        &mut self,
        f: &Fields<'_>,
        source: Source,
        _options: &ReadOptions,
        emit: &mut Emit<'_>,
    ) -> Result<(), RejectReason> {
        let heading = number(f.get(0), "heading")?.map(f64::to_radians);
        let deviation = east_west(f.get(1), f.get(2), "deviation")?;
        let variation = east_west(f.get(3), f.get(4), "variation")?;
        if variation.is_some() {
            self.variation_rad = variation;
        }
        let Some(heading) = heading else {
            emit.stats.empty += 1;
            return Ok(());
        };
        let stamp = self.untimed()?;
        let variation = self
            .variation_rad
            .ok_or(RejectReason::MagneticWithoutVariation)?;
        Self::heading(
            emit,
            stamp,
            source,
            heading + deviation.unwrap_or(0.0) + variation,
        );
        Ok(())
    }

    /// `$--VHW,x.x,T,x.x,M,x.x,N,x.x,K`: heading and speed through water.
    fn vhw(
        &mut self,
        f: &Fields<'_>,
        source: Source,
        _options: &ReadOptions,
        emit: &mut Emit<'_>,
    ) -> Result<(), RejectReason> {
        if f.len < 8 {
            return Err(RejectReason::Malformed {
                what: "VHW field count",
            });
        }
        unit(f.get(1), "T", "true heading unit")?;
        unit(f.get(3), "M", "magnetic heading unit")?;
        unit(f.get(5), "N", "knots unit")?;
        unit(f.get(7), "K", "km/h unit")?;
        let true_heading = direction(f.get(0), "heading")?;
        let magnetic = number(f.get(2), "magnetic heading")?.map(f64::to_radians);
        let stw = speed(f.get(4), f.get(6), "stw")?;
        if true_heading.is_none() && magnetic.is_none() && stw.is_none() {
            emit.stats.empty += 1;
            return Ok(());
        }
        let stamp = self.untimed()?;
        let heading = match (true_heading, magnetic, self.variation_rad) {
            (Some(h), _, _) => Some(Ok(h)),
            (None, Some(m), Some(v)) => Some(Ok(m + v)),
            (None, Some(_), None) => Some(Err(RejectReason::MagneticWithoutVariation)),
            (None, None, _) => None,
        };
        if let Some(mps) = stw {
            Self::record(emit, stamp, source, Measurement::SpeedThroughWater { mps });
        }
        match heading {
            Some(Ok(h)) => Self::heading(emit, stamp, source, h),
            Some(Err(reason)) => emit.reject(reason),
            None => {}
        }
        Ok(())
    }

    /// `$--RPM,a,x,x.x,x.x,A`: source (S shaft / E engine), number, rpm,
    /// pitch %, status.
    fn rpm(
        &mut self,
        f: &Fields<'_>,
        source: Source,
        _options: &ReadOptions,
        emit: &mut Emit<'_>,
    ) -> Result<(), RejectReason> {
        if f.len < 5 {
            return Err(RejectReason::Malformed {
                what: "RPM field count",
            });
        }
        match f.get(0) {
            "S" | "E" => {}
            _ => {
                return Err(RejectReason::BadField {
                    field: "rpm source",
                });
            }
        }
        match f.get(4) {
            "A" => {}
            "V" => return Err(RejectReason::NotValid { what: "RPM status" }),
            _ => {
                return Err(RejectReason::BadField {
                    field: "rpm status",
                });
            }
        }
        let number_field = f.get(1);
        if number_field.is_empty()
            || number_field.len() > 3
            || !number_field.bytes().all(|b| b.is_ascii_digit())
        {
            return Err(RejectReason::BadField {
                field: "shaft number",
            });
        }
        let shaft: u32 = number_field.parse().map_err(|_| RejectReason::BadField {
            field: "shaft number",
        })?;
        let side = match shaft {
            0 => return Err(RejectReason::UnknownPropeller { number: 0 }),
            n if n % 2 == 1 => Side::Starboard,
            _ => Side::Port,
        };
        let rpm = number(f.get(2), "rpm")?;
        if let Some(r) = rpm
            && r.abs() > crate::messages::MAX_ABS_RPM
        {
            return Err(RejectReason::OutOfRange { field: "rpm" });
        }
        let Some(rpm) = rpm else {
            emit.stats.empty += 1;
            return Ok(());
        };
        let stamp = self.untimed()?;
        let m = Measurement::PropellerSpeed {
            side,
            radps: rpm * RADPS_PER_RPM,
        };
        Self::record(emit, stamp, source, m);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measurement::MeasurementKind;
    use crate::read::RejectKind;
    use crate::time::{CivilDate, parse_rfc3339};

    fn decode(lines: &[&str]) -> (Vec<Item>, ReadStats) {
        decode_with(lines, ReadOptions::default())
    }

    fn decode_with(lines: &[&str], options: ReadOptions) -> (Vec<Item>, ReadStats) {
        let mut d = NmeaDecoder::new(options);
        let mut out = Vec::new();
        for (i, l) in lines.iter().enumerate() {
            d.decode_line(l.as_bytes(), i as u64 + 1, &mut out);
        }
        (out, d.stats().clone())
    }

    fn ok(item: &Item) -> &Record {
        item.as_ref().expect("record expected")
    }

    use crate::measurement::Record;

    fn with_checksum(body: &str) -> String {
        format!("${body}*{:02X}", checksum(body.as_bytes()))
    }

    #[test]
    fn plaka_burst_decodes_by_hand() {
        // The first burst of plaka.log with the previous ZDA/GLL in front.
        let lines = [
            "$GPZDA,095557,,,,00,*43",
            "$IIVHW,,T,,M,06.11,N,11.31,K*51",
            "$IIVTG,224.44,T,224.44,M,5.81,N,,,D*68",
            "$IIHDT,,T*0C",
            "$GPZDA,095559,,,,00,*4D",
            "$GPGLL,6005.071,N,02332.346,E,095559,A,D*43",
            "$IIHDM,,M*0C",
            "$IIMWV,338,R,13.41,N,A*2C",
        ];
        let (items, stats) = decode(&lines);
        // ZDA without date: 09:55:57 on the assumed 1970-01-01 = 35 757 s.
        // VHW: STW 6.11 kn * 1852/3600 = 3.143 2 m/s, stamped 35 757.
        let stw = ok(&items[0]);
        assert_eq!(stw.time_s, 35_757.0);
        assert_eq!(stw.source.to_string(), "nmea:II");
        let Measurement::SpeedThroughWater { mps } = stw.measurement else {
            panic!()
        };
        assert!((mps - 6.11 * 1852.0 / 3600.0).abs() < 1e-12);
        // VTG: COG 224.44 deg = 3.917 201 rad (true), SOG 5.81 kn = 2.988 9 m/s.
        let cs = ok(&items[1]);
        assert_eq!(
            cs.measurement,
            Measurement::CourseSpeed {
                cog_rad: Some(224.44f64.to_radians()),
                sog_mps: Some(5.81 * 1852.0 / 3600.0)
            }
        );
        // GLL: 60 deg 05.071' N = 60.084 516 67; 023 deg 32.346' E = 23.539 1.
        let pos = ok(&items[2]);
        assert_eq!(pos.time_s, 35_759.0);
        let Measurement::Position {
            lat_deg,
            lon_deg,
            method,
            hdop,
            altitude_m,
        } = pos.measurement
        else {
            panic!()
        };
        assert!((lat_deg - (60.0 + 5.071 / 60.0)).abs() < 1e-12);
        assert!((lon_deg - (23.0 + 32.346 / 60.0)).abs() < 1e-12);
        assert_eq!(method, Some(FixMethod::Dgnss));
        assert_eq!((hdop, altitude_m), (None, None));
        assert_eq!(items.len(), 3);
        // Empty HDT and HDM: absent, not errors. MWV: not read.
        assert_eq!(stats.empty, 2);
        assert_eq!(stats.ignored, 1);
        assert_eq!(stats.time_only, 2);
        assert_eq!(stats.total_rejected(), 0);
        assert_eq!(stats.undated, 3);
    }

    #[test]
    fn rmc_gga_golden_with_southern_western_values() {
        let rmc =
            with_checksum("GPRMC,235959.50,A,3351.5000,S,07037.2500,W,10.0,350.0,311225,3.5,W,A");
        let gga =
            with_checksum("GPGGA,000000.25,3351.5000,S,07037.2500,W,4,12,0.8,10.5,M,-20.0,M,,");
        let (items, stats) = decode(&[&rmc, &gga]);
        assert_eq!(stats.total_rejected(), 0, "{items:?}");
        // 2025-12-31 23:59:59.5 UTC.
        let t0 = parse_rfc3339("2025-12-31T23:59:59.5Z").unwrap();
        let p = ok(&items[0]);
        assert_eq!(p.time_s, t0);
        // 33 deg 51.5' S = -33.858 333; 70 deg 37.25' W = -70.620 833.
        let Measurement::Position {
            lat_deg,
            lon_deg,
            method,
            ..
        } = p.measurement
        else {
            panic!()
        };
        assert!((lat_deg + 33.858_333_333).abs() < 1e-9);
        assert!((lon_deg + 70.620_833_333).abs() < 1e-9);
        assert_eq!(method, Some(FixMethod::Gnss));
        // 10 kn = 5.144 44 m/s; 350 deg = 6.108 65 rad.
        let Measurement::CourseSpeed { cog_rad, sog_mps } = ok(&items[1]).measurement else {
            panic!()
        };
        assert!((sog_mps.unwrap() - 5.144_444_444).abs() < 1e-9);
        assert!((cog_rad.unwrap() - 6.108_652_382).abs() < 1e-9);
        // GGA 00:00:00.25 after 23:59:59.5: the date advances to 2026-01-01.
        let g = ok(&items[2]);
        assert!((g.time_s - (t0 + 0.75)).abs() < 1e-6, "{}", g.time_s - t0);
        let Measurement::Position {
            hdop,
            method,
            altitude_m,
            ..
        } = g.measurement
        else {
            panic!()
        };
        assert_eq!(hdop, Some(0.8));
        assert_eq!(method, Some(FixMethod::RtkFixed));
        // 10.5 m above MSL, geoid 20 m below the ellipsoid: -9.5 m.
        assert_eq!(altitude_m, Some(-9.5));
    }

    #[test]
    fn midnight_wrap_and_late_sentences() {
        let lines = [
            "$GPZDA,235959.00,31,12,2025,00,00",
            "$GPGLL,6000.000,N,02400.000,E,235959.80,A,A",
            "$GPGLL,6000.000,N,02400.000,E,000000.30,A,A",
            // Stamped just before midnight, arriving after: stays on the 31st.
            "$GPGLL,6000.000,N,02400.000,E,235959.90,A,A",
            "$GPGLL,6000.000,N,02400.000,E,000001.60,A,A",
        ];
        let (items, stats) = decode(&lines);
        let midnight = parse_rfc3339("2026-01-01T00:00:00Z").unwrap();
        let times: Vec<f64> = items.iter().map(|i| ok(i).time_s - midnight).collect();
        let expected = [-0.2, 0.3, -0.1, 1.6];
        for (t, e) in times.iter().zip(expected) {
            assert!((t - e).abs() < 1e-6, "{times:?}");
        }
        assert_eq!(stats.undated, 0);
    }

    #[test]
    fn time_going_backwards_is_rejected_with_its_size() {
        let lines = [
            "$GPZDA,120000,01,01,2026,00,00",
            "$GPGLL,6000.000,N,02400.000,E,115959.70,A,A", // 0.3 s back: tolerated
            "$GPGLL,6000.000,N,02400.000,E,115950.00,A,A", // 10 s back: rejected
            "$GPGLL,6000.000,N,02400.000,E,120001.00,A,A",
        ];
        let (items, stats) = decode(&lines);
        assert!(items[0].is_ok());
        let Err(rejection) = &items[1] else { panic!() };
        assert_eq!(rejection.line, 3);
        let RejectReason::TimeBackwards { by_s } = rejection.reason else {
            panic!()
        };
        assert!((by_s - 10.0).abs() < 1e-6);
        assert!(items[2].is_ok());
        assert_eq!(stats.rejected(RejectKind::TimeBackwards), 1);
    }

    #[test]
    fn untimed_before_any_time_and_no_date_policy() {
        let (items, _) = decode(&["$IIHDT,10.0,T"]);
        assert_eq!(items[0].as_ref().unwrap_err().reason, RejectReason::NoTime);
        let options = ReadOptions {
            assumed_date: None,
            ..ReadOptions::default()
        };
        let (items, _) = decode_with(&["$GPGLL,6000.000,N,02400.000,E,120000,A,A"], options);
        assert_eq!(items[0].as_ref().unwrap_err().reason, RejectReason::NoDate);
        let options = ReadOptions {
            assumed_date: Some(CivilDate::new(2014, 8, 15).unwrap()),
            ..ReadOptions::default()
        };
        let (items, stats) = decode_with(&["$GPGLL,6000.000,N,02400.000,E,120000,A,A"], options);
        assert_eq!(
            ok(&items[0]).time_s,
            parse_rfc3339("2014-08-15T12:00:00Z").unwrap()
        );
        assert_eq!(stats.undated, 1);
    }

    #[test]
    fn headings_true_and_magnetic() {
        let lines = [
            "$GPZDA,120000,01,01,2026,00,00",
            "$HEHDT,359.9,T",
            "$HCHDM,100.0,M", // no variation known yet
            "$HCHDG,100.0,1.5,W,7.0,E",
            "$HCHDM,100.0,M", // variation 7 E now known
            "$IIVHW,,T,200.0,M,5.0,N,,K",
        ];
        let (items, stats) = decode(&lines);
        let h = |i: usize| match ok(&items[i]).measurement {
            Measurement::Heading { heading_rad } => heading_rad.to_degrees(),
            ref m => panic!("{m:?}"),
        };
        assert!((h(0) - 359.9).abs() < 1e-9);
        assert_eq!(
            items[1].as_ref().unwrap_err().reason,
            RejectReason::MagneticWithoutVariation
        );
        // HDG: 100 - 1.5 (deviation W) + 7 (variation E) = 105.5 true.
        assert!((h(2) - 105.5).abs() < 1e-9);
        assert!((h(3) - 107.0).abs() < 1e-9);
        // VHW: STW then the magnetic heading made true, 207.
        assert!(matches!(
            ok(&items[4]).measurement,
            Measurement::SpeedThroughWater { .. }
        ));
        assert!((h(5) - 207.0).abs() < 1e-9);
        assert_eq!(stats.records(MeasurementKind::Heading), 4);
    }

    #[test]
    fn vtg_magnetic_only_keeps_speed_and_rejects_course() {
        let lines = [
            "$GPZDA,120000,01,01,2026,00,00",
            "$GPVTG,,T,90.0,M,2.0,N,,K,A",
        ];
        let (items, stats) = decode(&lines);
        assert_eq!(
            ok(&items[0]).measurement,
            Measurement::CourseSpeed {
                cog_rad: None,
                sog_mps: Some(2.0 * 1852.0 / 3600.0)
            }
        );
        assert_eq!(
            items[1].as_ref().unwrap_err().reason,
            RejectReason::MagneticCourse
        );
        assert_eq!(stats.rejected(RejectKind::MagneticCourse), 1);
        // km/h when knots are absent: 36 km/h = 10 m/s.
        let (items, _) = decode(&[
            "$GPZDA,120000,01,01,2026,00,00",
            "$GPVTG,10.0,T,,M,,N,36.0,K",
        ]);
        assert_eq!(
            ok(&items[0]).measurement,
            Measurement::CourseSpeed {
                cog_rad: Some(10f64.to_radians()),
                sog_mps: Some(10.0)
            }
        );
    }

    #[test]
    fn rot_is_degrees_per_minute_to_starboard_and_refuses_invalid_or_absurd_rates() {
        let (items, _) = decode(&[
            "$GPZDA,120000,01,01,2026,00,00",
            "$TIROT,-60.0,A",
            "$TIROT,30.0,V",
            "$TIROT,,A",
            "$TIROT,99999.0,A",
        ]);
        let rates: Vec<f64> = items
            .iter()
            .filter_map(|i| match i.as_ref().ok()?.measurement {
                Measurement::RateOfTurn { radps } => Some(radps),
                _ => None,
            })
            .collect();
        // -60 deg/min = -1 deg/s to port.
        assert_eq!(rates.len(), 1, "{items:?}");
        assert!((rates[0] + 1f64.to_radians()).abs() < 1e-12);
        let rejected = items.iter().filter(|i| i.is_err()).count();
        assert_eq!(rejected, 2, "{items:?}");
    }

    #[test]
    fn rpm_shafts_odd_starboard_even_port() {
        let lines = [
            "$GPZDA,120000,01,01,2026,00,00",
            "$ERRPM,S,1,1200.0,,A",
            "$ERRPM,S,2,-60.0,10.0,A",
            "$ERRPM,E,0,100,,A",
            "$ERRPM,S,3,100,,V",
        ];
        let (items, _) = decode(&lines);
        // 1200 rpm = 20 rev/s = 125.663 7 rad/s.
        assert_eq!(
            ok(&items[0]).measurement,
            Measurement::PropellerSpeed {
                side: Side::Starboard,
                radps: 1200.0 * RADPS_PER_RPM
            }
        );
        assert_eq!(
            ok(&items[1]).measurement,
            Measurement::PropellerSpeed {
                side: Side::Port,
                radps: -60.0 * RADPS_PER_RPM
            }
        );
        assert_eq!(
            items[2].as_ref().unwrap_err().reason,
            RejectReason::UnknownPropeller { number: 0 }
        );
        assert_eq!(
            items[3].as_ref().unwrap_err().reason,
            RejectReason::NotValid { what: "RPM status" }
        );
    }

    #[test]
    fn checksums_and_structure() {
        let (items, stats) = decode(&[
            "$IIHDT,,T*0D",
            "$IIHDT,,T*0",
            "$IIHDT,,T*0G",
            "GPGLL,1",
            "$GPGLL\u{7f}",
            "$gpgll,1",
            "$GPGLLX,1",
            "$PFEC,GPatt,1",
            "!AIVDM,1,1,,A,x,0",
        ]);
        let reasons: Vec<_> = items
            .iter()
            .map(|i| i.as_ref().unwrap_err().reason.clone())
            .collect();
        assert_eq!(
            reasons,
            [
                RejectReason::BadChecksum {
                    expected: 0x0D,
                    computed: 0x0C
                },
                RejectReason::Malformed { what: "checksum" },
                RejectReason::Malformed { what: "checksum" },
                RejectReason::UnknownFormat,
                RejectReason::NotText,
                RejectReason::Malformed { what: "address" },
                RejectReason::Malformed { what: "address" },
            ]
        );
        assert_eq!(stats.ignored, 2);
        assert_eq!(stats.without_checksum, 4);
    }

    #[test]
    fn bad_fields_are_typed() {
        let base = "$GPZDA,120000,01,01,2026,00,00";
        let cases = [
            (
                "$GPGLL,6060.000,N,02400.000,E,120000,A,A",
                RejectReason::OutOfRange { field: "latitude" },
            ),
            (
                "$GPGLL,9100.000,N,02400.000,E,120000,A,A",
                RejectReason::OutOfRange { field: "latitude" },
            ),
            (
                "$GPGLL,6000.000,X,02400.000,E,120000,A,A",
                RejectReason::BadField { field: "latitude" },
            ),
            (
                "$GPGLL,6000.000,N,,E,120000,A,A",
                RejectReason::BadField { field: "longitude" },
            ),
            (
                "$GPGLL,6000.000,N,02400.000,E,120000,V,A",
                RejectReason::NotValid { what: "GLL status" },
            ),
            (
                "$GPGLL,6000.000,N,02400.000,E,120000,A,N",
                RejectReason::NotValid { what: "mode" },
            ),
            (
                "$GPGLL,6000.0e0,N,02400.000,E,120000,A,A",
                RejectReason::BadField { field: "latitude" },
            ),
            (
                "$GPVTG,inf,T,,M,1,N,,K",
                RejectReason::BadField { field: "cog" },
            ),
            (
                "$GPVTG,1,T,,M,-1,N,,K",
                RejectReason::OutOfRange { field: "sog" },
            ),
            (
                "$GPVTG,1,T,,M,1,X,,K",
                RejectReason::BadField {
                    field: "knots unit",
                },
            ),
            (
                "$GPGGA,120000,6000.000,N,02400.000,E,0,,,,,,,,",
                RejectReason::NotValid {
                    what: "GGA quality",
                },
            ),
            (
                "$GPRMC,120000,V,,,,,,,010126,,,N",
                RejectReason::NotValid { what: "RMC status" },
            ),
            (
                "$GPRMC,120000,A,,,,,,,320126,,,A",
                RejectReason::BadTime(crate::time::TimeError::OutOfRange { field: "day" }),
            ),
            (
                "$GPGGA,250000,6000.000,N,02400.000,E,1,,,,,,,,",
                RejectReason::BadTime(crate::time::TimeError::OutOfRange { field: "hour" }),
            ),
        ];
        for (line, reason) in cases {
            let (items, _) = decode(&[base, line]);
            assert_eq!(items.len(), 1, "{line}: {items:?}");
            assert_eq!(items[0].as_ref().unwrap_err().reason, reason, "{line}");
        }
    }

    #[test]
    fn boundary_positions_and_speeds() {
        // 90 deg 00.000' N and 180 deg 00.000' W are the edges: accepted.
        let (items, stats) = decode(&[
            "$GPZDA,120000,01,01,2026,00,00",
            "$GPGLL,9000.000,N,18000.000,W,120000,A,A",
            "$GPGLL,9000.001,N,18000.000,W,120001,A,A",
            "$GPGLL,0000.000,S,18000.001,E,120002,A,A",
            // 97.19 kn = 49.998 m/s (accepted), 97.2 kn = 50.004 m/s (not).
            "$GPVTG,0.0,T,,M,97.19,N,,K",
            "$GPVTG,0.0,T,,M,97.2,N,,K",
        ]);
        assert_eq!(
            ok(&items[0]).measurement,
            Measurement::Position {
                lat_deg: 90.0,
                lon_deg: -180.0,
                hdop: None,
                method: Some(FixMethod::Gnss),
                altitude_m: None
            }
        );
        assert_eq!(
            items[1].as_ref().unwrap_err().reason,
            RejectReason::OutOfRange { field: "latitude" }
        );
        assert_eq!(
            items[2].as_ref().unwrap_err().reason,
            RejectReason::OutOfRange { field: "longitude" }
        );
        assert!(items[3].is_ok());
        assert_eq!(
            items[4].as_ref().unwrap_err().reason,
            RejectReason::OutOfRange { field: "sog" }
        );
        assert_eq!(stats.total_records(), 2);
    }

    #[test]
    fn payloads_with_several_sentences() {
        let mut d = NmeaDecoder::new(ReadOptions::default());
        let mut out = Vec::new();
        d.decode_payload(
            b"$GPZDA,120000,01,01,2026,00,00\r\n$HEHDT,10.0,T\r\n\r\n$HEHDT,20.0,T",
            &mut out,
        );
        assert_eq!(out.len(), 2);
        assert!(out.iter().all(Result::is_ok));
    }
}
