//! Time on the wire: RFC 3339 timestamps and the NMEA 0183 date and
//! time-of-day fields, to and from `f64` seconds since the Unix epoch (UTC).
//!
//! The calendar arithmetic is the proleptic Gregorian "days from civil" and
//! "civil from days" conversion done on 400-year eras (146 097 days each), so it
//! needs no table and no library. Every parser here takes untrusted text and
//! returns a [`TimeError`] rather than panicking.
//!
//! Seconds are `f64`: at today's epoch values (~1.8e9 s) an `f64` resolves about
//! 0.24 us, far finer than any navigation message.

/// Seconds in a (non-leap-second) day.
pub const SECONDS_PER_DAY: i64 = 86_400;

/// Why a timestamp or a date/time field cannot be read or written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum TimeError {
    /// The text is empty.
    #[error("empty time")]
    Empty,
    /// The text does not have the expected shape (a separator, a digit or the
    /// zone is missing or misplaced); `expected` names what was expected.
    #[error("malformed time: expected {expected}")]
    Malformed {
        /// What the parser expected at the point it gave up.
        expected: &'static str,
    },
    /// A component is outside its calendar range (month 13, hour 24, minute
    /// 60, day 31 of a 30-day month...); `field` names it.
    #[error("time component {field} out of range")]
    OutOfRange {
        /// The offending component (`month`, `day`, `hour`, ...).
        field: &'static str,
    },
    /// A time in seconds to format is NaN or infinite.
    #[error("time is not a finite number")]
    NotFinite,
    /// A time in seconds to format falls outside the years 0000-9999 that
    /// RFC 3339 can write.
    #[error("time is outside the years 0000-9999")]
    YearOutOfRange,
}

/// A calendar date (proleptic Gregorian), validated on construction.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct CivilDate {
    year: i32,
    month: u8,
    day: u8,
}

impl CivilDate {
    /// 1970-01-01, day 0 of the Unix epoch.
    pub const UNIX_EPOCH: CivilDate = CivilDate {
        year: 1970,
        month: 1,
        day: 1,
    };

    /// A date from its parts; years 0 to 9999 only.
    pub fn new(year: i32, month: u8, day: u8) -> Result<Self, TimeError> {
        if !(0..=9999).contains(&year) {
            return Err(TimeError::OutOfRange { field: "year" });
        }
        if !(1..=12).contains(&month) {
            return Err(TimeError::OutOfRange { field: "month" });
        }
        if day == 0 || day > days_in_month(year, month) {
            return Err(TimeError::OutOfRange { field: "day" });
        }
        Ok(Self { year, month, day })
    }

    /// The year.
    pub fn year(self) -> i32 {
        self.year
    }

    /// The month, 1 to 12.
    pub fn month(self) -> u8 {
        self.month
    }

    /// The day of the month, from 1.
    pub fn day(self) -> u8 {
        self.day
    }

    /// Days since 1970-01-01 (negative before it).
    pub fn days_since_epoch(self) -> i64 {
        days_from_civil(i64::from(self.year), self.month, self.day)
    }

    /// The date `days` days after 1970-01-01. Fails outside the years 0-9999.
    pub fn from_days_since_epoch(days: i64) -> Result<Self, TimeError> {
        // Year 0 starts 719 528 days before the epoch, year 10000 2 932 897 after.
        if !(-719_528..2_932_897).contains(&days) {
            return Err(TimeError::YearOutOfRange);
        }
        let (year, month, day) = civil_from_days(days);
        // In range by the check above, so the conversion cannot fail.
        let year = i32::try_from(year).map_err(|_| TimeError::YearOutOfRange)?;
        Ok(Self { year, month, day })
    }

    /// Seconds since the epoch of midnight (00:00:00 UTC) of this date.
    pub fn midnight_s(self) -> f64 {
        (self.days_since_epoch() * SECONDS_PER_DAY) as f64
    }
}

fn is_leap(year: i32) -> bool {
    (year % 4 == 0 && year % 100 != 0) || year % 400 == 0
}

fn days_in_month(year: i32, month: u8) -> u8 {
    match month {
        1 | 3 | 5 | 7 | 8 | 10 | 12 => 31,
        4 | 6 | 9 | 11 => 30,
        2 if is_leap(year) => 29,
        2 => 28,
        _ => 0,
    }
}

/// Days since 1970-01-01 of a proleptic Gregorian date. The date is not
/// validated (month 1-12 and day 1-31 keep the arithmetic meaningful).
pub fn days_from_civil(year: i64, month: u8, day: u8) -> i64 {
    // Count from 0000-03-01 so that the leap day is the last day of a "year".
    let month = i64::from(month);
    let year = if month <= 2 { year - 1 } else { year };
    let era = year.div_euclid(400);
    let year_of_era = year - era * 400; // 0..=399
    let shifted_month = (month + 9) % 12; // March = 0 ... February = 11
    let day_of_year = (153 * shifted_month + 2) / 5 + i64::from(day) - 1; // 0..=365
    let day_of_era = year_of_era * 365 + year_of_era / 4 - year_of_era / 100 + day_of_year;
    // 719 468 days from 0000-03-01 to 1970-01-01.
    era * 146_097 + day_of_era - 719_468
}

/// The proleptic Gregorian date `(year, month, day)` of a day count since
/// 1970-01-01: the inverse of [`days_from_civil`].
pub fn civil_from_days(days: i64) -> (i64, u8, u8) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let day_of_era = z - era * 146_097; // 0..=146096
    let year_of_era =
        (day_of_era - day_of_era / 1460 + day_of_era / 36_524 - day_of_era / 146_096) / 365;
    let day_of_year = day_of_era - (365 * year_of_era + year_of_era / 4 - year_of_era / 100);
    let shifted_month = (5 * day_of_year + 2) / 153; // March = 0
    let day = day_of_year - (153 * shifted_month + 2) / 5 + 1;
    let month = if shifted_month < 10 {
        shifted_month + 3
    } else {
        shifted_month - 9
    };
    let year = year_of_era + era * 400 + i64::from(month <= 2);
    // day is 1..=31 and month 1..=12 by construction.
    (year, month as u8, day as u8)
}

/// Reads `n` ASCII digits at `at` as a number.
fn digits(bytes: &[u8], at: usize, n: usize, what: &'static str) -> Result<u32, TimeError> {
    let slice = bytes
        .get(at..at + n)
        .ok_or(TimeError::Malformed { expected: what })?;
    let mut value = 0u32;
    for &b in slice {
        if !b.is_ascii_digit() {
            return Err(TimeError::Malformed { expected: what });
        }
        value = value * 10 + u32::from(b - b'0');
    }
    Ok(value)
}

fn expect_byte(
    bytes: &[u8],
    at: usize,
    allowed: &[u8],
    what: &'static str,
) -> Result<u8, TimeError> {
    match bytes.get(at) {
        Some(b) if allowed.contains(b) => Ok(*b),
        _ => Err(TimeError::Malformed { expected: what }),
    }
}

/// Reads an optional `.ddd` fraction at `at`: returns the fraction and the
/// index after it. At most 12 digits.
fn fraction(bytes: &[u8], at: usize) -> Result<(f64, usize), TimeError> {
    if bytes.get(at) != Some(&b'.') {
        return Ok((0.0, at));
    }
    let mut end = at + 1;
    let mut numerator = 0u64;
    let mut denominator = 1u64;
    while let Some(b) = bytes.get(end) {
        if !b.is_ascii_digit() {
            break;
        }
        if end - at > 12 {
            return Err(TimeError::Malformed {
                expected: "at most 12 fraction digits",
            });
        }
        numerator = numerator * 10 + u64::from(b - b'0');
        denominator *= 10;
        end += 1;
    }
    if end == at + 1 {
        return Err(TimeError::Malformed {
            expected: "a digit after the decimal point",
        });
    }
    Ok((numerator as f64 / denominator as f64, end))
}

fn check_clock(hour: u32, minute: u32, second: u32) -> Result<(), TimeError> {
    if hour > 23 {
        return Err(TimeError::OutOfRange { field: "hour" });
    }
    if minute > 59 {
        return Err(TimeError::OutOfRange { field: "minute" });
    }
    // 60 is a leap second: it reads as the first instant of the next minute.
    if second > 60 {
        return Err(TimeError::OutOfRange { field: "second" });
    }
    Ok(())
}

/// Parses an RFC 3339 timestamp (`2026-08-03T04:27:20.588Z`,
/// `2026-08-03T06:27:20+02:00`) to seconds since the Unix epoch, UTC.
///
/// Accepts `T`, `t` or a space between date and time, any number of fraction
/// digits up to 12, `Z`/`z` or a `+hh:mm`/`-hh:mm` offset (`-00:00` is UTC). A
/// leap second (`:60`) reads as the first instant of the next minute. Nothing
/// may follow the zone.
pub fn parse_rfc3339(text: &str) -> Result<f64, TimeError> {
    let bytes = text.as_bytes();
    if bytes.is_empty() {
        return Err(TimeError::Empty);
    }
    let year = digits(bytes, 0, 4, "a four-digit year")?;
    expect_byte(bytes, 4, b"-", "'-' after the year")?;
    let month = digits(bytes, 5, 2, "a two-digit month")?;
    expect_byte(bytes, 7, b"-", "'-' after the month")?;
    let day = digits(bytes, 8, 2, "a two-digit day")?;
    expect_byte(bytes, 10, b"Tt ", "'T' between date and time")?;
    let hour = digits(bytes, 11, 2, "a two-digit hour")?;
    expect_byte(bytes, 13, b":", "':' after the hour")?;
    let minute = digits(bytes, 14, 2, "two-digit minutes")?;
    expect_byte(bytes, 16, b":", "':' after the minutes")?;
    let second = digits(bytes, 17, 2, "two-digit seconds")?;
    let (frac, at) = fraction(bytes, 19)?;
    let offset_s = match bytes.get(at) {
        Some(b'Z' | b'z') if bytes.len() == at + 1 => 0i64,
        Some(sign @ (b'+' | b'-')) if bytes.len() == at + 6 => {
            let oh = digits(bytes, at + 1, 2, "offset hours")?;
            expect_byte(bytes, at + 3, b":", "':' in the offset")?;
            let om = digits(bytes, at + 4, 2, "offset minutes")?;
            if oh > 23 || om > 59 {
                return Err(TimeError::OutOfRange { field: "offset" });
            }
            let magnitude = i64::from(oh * 3600 + om * 60);
            if *sign == b'-' { -magnitude } else { magnitude }
        }
        _ => {
            return Err(TimeError::Malformed {
                expected: "'Z' or a +hh:mm offset at the end",
            });
        }
    };
    // Month and day ranges are checked by CivilDate; the u32 -> u8 casts are
    // exact because two digits are at most 99.
    let date = CivilDate::new(year as i32, month as u8, day as u8)?;
    check_clock(hour, minute, second)?;
    let whole_s = date.days_since_epoch() * SECONDS_PER_DAY
        + i64::from(hour * 3600 + minute * 60 + second)
        - offset_s;
    let time_s = whole_s as f64 + frac;
    // An offset can push 0000-01-01 or 9999-12-31 out of the years that
    // can be written back; refuse those so every parsed time formats.
    if !(MIN_TIME_S..MAX_TIME_S).contains(&time_s) {
        return Err(TimeError::YearOutOfRange);
    }
    Ok(time_s)
}

/// 0000-01-01T00:00:00Z, seconds since the epoch.
const MIN_TIME_S: f64 = -62_167_219_200.0;
/// 10000-01-01T00:00:00Z, seconds since the epoch.
const MAX_TIME_S: f64 = 253_402_300_800.0;

/// Formats seconds since the Unix epoch as RFC 3339 UTC with a `Z`, to the
/// microsecond, trailing zeros trimmed down to milliseconds:
/// `2026-08-03T04:27:20.588Z`, `2026-08-03T04:27:20.588125Z`.
pub fn format_rfc3339(time_s: f64) -> Result<String, TimeError> {
    if !time_s.is_finite() {
        return Err(TimeError::NotFinite);
    }
    // Years 0000 to 9999 in seconds; inside them the microsecond count fits
    // an i64 with room to spare.
    if !(MIN_TIME_S..MAX_TIME_S).contains(&time_s) {
        return Err(TimeError::YearOutOfRange);
    }
    // Whole seconds and their fraction are split exactly (`t - floor(t)` is
    // representable); only the fraction is scaled. `time_s * 1e6` would
    // round to the spacing of doubles near 1e17 (up to 16 us after the
    // year 6000). Rounding the last microsecond of 9999 up must not leave
    // the range.
    let whole_s = time_s.floor();
    let fraction_us = ((time_s - whole_s) * 1e6).round() as i64;
    let total_us = (whole_s as i64 * 1_000_000 + fraction_us).min(253_402_300_799_999_999);
    let us_per_day = SECONDS_PER_DAY * 1_000_000;
    let days = total_us.div_euclid(us_per_day);
    let us_of_day = total_us.rem_euclid(us_per_day);
    let date = CivilDate::from_days_since_epoch(days)?;
    let secs = us_of_day / 1_000_000;
    let micros = us_of_day % 1_000_000;
    // Digits written into a fixed buffer: this runs for every output
    // message and every forecast point, and the formatting machinery with
    // its two allocations was a visible share of the daemon's time.
    let mut buf = *b"0000-00-00T00:00:00.000000Z";
    put_digits(&mut buf[0..4], date.year as u64);
    put_digits(&mut buf[5..7], date.month as u64);
    put_digits(&mut buf[8..10], date.day as u64);
    put_digits(&mut buf[11..13], (secs / 3600) as u64);
    put_digits(&mut buf[14..16], ((secs / 60) % 60) as u64);
    put_digits(&mut buf[17..19], (secs % 60) as u64);
    put_digits(&mut buf[20..26], micros as u64);
    // Trailing zeros of the fraction trimmed, down to milliseconds.
    let mut end = 26;
    while end > 23 && buf[end - 1] == b'0' {
        end -= 1;
    }
    buf[end] = b'Z';
    let text = std::str::from_utf8(&buf[..=end]).expect("ASCII digits and separators");
    Ok(text.to_string())
}

/// Writes `value` as decimal digits filling `out`, zero-padded (`value` must
/// fit: the callers' fields are range-checked).
fn put_digits(out: &mut [u8], mut value: u64) {
    for d in out.iter_mut().rev() {
        *d = b'0' + (value % 10) as u8;
        value /= 10;
    }
}

/// Parses an NMEA 0183 time of day `hhmmss` or `hhmmss.ss...` to seconds
/// since midnight UTC. A leap second (`60`) is accepted.
pub fn parse_hhmmss(text: &str) -> Result<f64, TimeError> {
    let bytes = text.as_bytes();
    if bytes.is_empty() {
        return Err(TimeError::Empty);
    }
    let hour = digits(bytes, 0, 2, "hhmmss")?;
    let minute = digits(bytes, 2, 2, "hhmmss")?;
    let second = digits(bytes, 4, 2, "hhmmss")?;
    let (frac, end) = fraction(bytes, 6)?;
    if end != bytes.len() {
        return Err(TimeError::Malformed {
            expected: "nothing after hhmmss.ss",
        });
    }
    check_clock(hour, minute, second)?;
    Ok(f64::from(hour * 3600 + minute * 60 + second) + frac)
}

/// Parses an NMEA 0183 `ddmmyy` date. Two-digit years pivot at 80: 80-99 are
/// 1980-1999, 00-79 are 2000-2079 (GPS receivers appeared in 1980).
pub fn parse_ddmmyy(text: &str) -> Result<CivilDate, TimeError> {
    let bytes = text.as_bytes();
    if bytes.is_empty() {
        return Err(TimeError::Empty);
    }
    if bytes.len() != 6 {
        return Err(TimeError::Malformed { expected: "ddmmyy" });
    }
    let day = digits(bytes, 0, 2, "ddmmyy")?;
    let month = digits(bytes, 2, 2, "ddmmyy")?;
    let yy = digits(bytes, 4, 2, "ddmmyy")?;
    let year = if yy >= 80 { 1900 + yy } else { 2000 + yy };
    CivilDate::new(year as i32, month as u8, day as u8)
}

/// Splits seconds since the epoch into the UTC date and the time of day in
/// whole milliseconds, rounding to the nearest millisecond first so that
/// 23:59:59.9996 becomes the next day's 00:00:00.000 rather than "24:00:00".
pub fn split_date_time_ms(time_s: f64) -> Result<(CivilDate, i64), TimeError> {
    if !time_s.is_finite() {
        return Err(TimeError::NotFinite);
    }
    if !(MIN_TIME_S..MAX_TIME_S).contains(&time_s) {
        return Err(TimeError::YearOutOfRange);
    }
    let total_ms = ((time_s * 1e3).round() as i64).min(253_402_300_799_999);
    let ms_per_day = SECONDS_PER_DAY * 1000;
    let date = CivilDate::from_days_since_epoch(total_ms.div_euclid(ms_per_day))?;
    Ok((date, total_ms.rem_euclid(ms_per_day)))
}

/// Formats a millisecond time of day as NMEA `hhmmss.sss`.
pub fn format_hhmmss_ms(ms_of_day: i64) -> String {
    let ms = ms_of_day.rem_euclid(SECONDS_PER_DAY * 1000);
    let secs = ms / 1000;
    format!(
        "{:02}{:02}{:02}.{:03}",
        secs / 3600,
        (secs / 60) % 60,
        secs % 60,
        ms % 1000
    )
}

/// Formats a date as NMEA `ddmmyy` (the century is dropped).
pub fn format_ddmmyy(date: CivilDate) -> String {
    format!(
        "{:02}{:02}{:02}",
        date.day,
        date.month,
        date.year.rem_euclid(100)
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn known_dates_convert_both_ways() {
        assert_eq!(days_from_civil(1970, 1, 1), 0);
        assert_eq!(days_from_civil(2000, 3, 1), 11_017);
        // 2026-08-03: 56 years incl. 14 leap days -> 20 454 days to 2026-01-01,
        // plus 31+28+31+30+31+30+31 = 212 days, plus 2.
        assert_eq!(days_from_civil(2026, 8, 3), 20_454 + 212 + 2);
        assert_eq!(civil_from_days(20_668), (2026, 8, 3));
        assert_eq!(civil_from_days(-1), (1969, 12, 31));
        assert_eq!(civil_from_days(11_016), (2000, 2, 29));
    }

    #[test]
    fn rfc3339_parses_the_log_timestamps() {
        // 2026-08-03 is day 20 668; 04:27:20.588 is 16 040.588 s into it.
        let t = parse_rfc3339("2026-08-03T04:27:20.588Z").unwrap();
        assert!((t - (20_668.0 * 86_400.0 + 16_040.588)).abs() < 1e-6, "{t}");
        let with_offset = parse_rfc3339("2026-08-03T06:27:20.588+02:00").unwrap();
        assert!((with_offset - t).abs() < 1e-6);
        let negative = parse_rfc3339("2026-08-02T23:27:20.588-05:00").unwrap();
        assert!((negative - t).abs() < 1e-6);
        assert_eq!(parse_rfc3339("1970-01-01T00:00:00Z"), Ok(0.0));
        assert_eq!(parse_rfc3339("1970-01-01 00:00:01z"), Ok(1.0));
        // A leap second is the first instant of the next minute.
        assert_eq!(
            parse_rfc3339("2016-12-31T23:59:60Z"),
            parse_rfc3339("2017-01-01T00:00:00Z")
        );
    }

    #[test]
    fn rfc3339_rejects_garbage() {
        for bad in [
            "",
            "2026-08-03",
            "2026-08-03T04:27:20",
            "2026-08-03T04:27:20.Z",
            "2026-13-03T04:27:20Z",
            "2026-02-29T04:27:20Z",
            "2026-08-03T24:00:00Z",
            "2026-08-03T04:60:00Z",
            "2026-08-03T04:27:20Zjunk",
            "2026-08-03T04:27:20+2:00",
            "2026-08-03T04:27:20+24:00",
            "２026-08-03T04:27:20Z",
            "0000-01-01T00:30:00+01:00",
            "9999-12-31T23:59:59-00:01",
            "2026-08-03T04:27:20.1234567890123Z",
        ] {
            assert!(parse_rfc3339(bad).is_err(), "{bad}");
        }
        assert_eq!(
            parse_rfc3339("2026-13-03T04:27:20Z"),
            Err(TimeError::OutOfRange { field: "month" })
        );
    }

    #[test]
    fn rfc3339_formats_trimmed_fractions() {
        let t = parse_rfc3339("2026-08-03T04:27:20.588Z").unwrap();
        assert_eq!(format_rfc3339(t).unwrap(), "2026-08-03T04:27:20.588Z");
        assert_eq!(format_rfc3339(0.0).unwrap(), "1970-01-01T00:00:00.000Z");
        assert_eq!(
            format_rfc3339(-0.000_001).unwrap(),
            "1969-12-31T23:59:59.999999Z"
        );
        assert_eq!(format_rfc3339(f64::NAN), Err(TimeError::NotFinite));
        assert_eq!(format_rfc3339(1e12), Err(TimeError::YearOutOfRange));
        // The largest f64 before year 10000 still formats (rounding clamped).
        let last = f64::from_bits(MAX_TIME_S.to_bits() - 1);
        assert!(
            format_rfc3339(last)
                .unwrap()
                .starts_with("9999-12-31T23:59:59.99")
        );
        assert!(split_date_time_ms(last).is_ok());
    }

    #[test]
    fn nmea_fields() {
        assert_eq!(parse_hhmmss("095559"), Ok(35_759.0));
        assert!((parse_hhmmss("235959.95").unwrap() - 86_399.95).abs() < 1e-9);
        assert!(parse_hhmmss("245959").is_err());
        assert!(parse_hhmmss("0955").is_err());
        assert!(parse_hhmmss("095559.").is_err());
        assert!(parse_hhmmss("09555a").is_err());
        assert_eq!(
            parse_ddmmyy("150814").unwrap(),
            CivilDate::new(2014, 8, 15).unwrap()
        );
        assert_eq!(parse_ddmmyy("010199").unwrap().year(), 1999);
        assert!(parse_ddmmyy("300214").is_err());
        let (date, ms) = split_date_time_ms(86_399.999_6).unwrap();
        assert_eq!((date, ms), (CivilDate::new(1970, 1, 2).unwrap(), 0));
        assert_eq!(format_hhmmss_ms(35_759_250), "095559.250");
        assert_eq!(format_ddmmyy(CivilDate::new(2026, 8, 3).unwrap()), "030826");
    }

    proptest! {
        #[test]
        fn days_round_trip(days in -719_528i64..2_932_897) {
            let date = CivilDate::from_days_since_epoch(days).unwrap();
            prop_assert_eq!(date.days_since_epoch(), days);
            prop_assert!(CivilDate::new(date.year(), date.month(), date.day()).is_ok());
        }

        #[test]
        fn rfc3339_round_trip(t in -62_167_219_200.0f64..253_402_300_799.0) {
            let text = format_rfc3339(t).unwrap();
            let back = parse_rfc3339(&text).unwrap();
            // Microsecond formatting plus f64 resolution at 2.5e11 s (~3e-5 s).
            prop_assert!((back - t).abs() <= 1e-6 + t.abs() * 2e-16, "{} {} {}", t, text, back);
        }

        #[test]
        fn rfc3339_never_panics(s in "\\PC{0,40}") {
            let _ = parse_rfc3339(&s);
            let _ = parse_hhmmss(&s);
            let _ = parse_ddmmyy(&s);
        }

        #[test]
        fn rfc3339_like_strings_never_panic(s in "[0-9]{4}-[0-9]{2}-[0-9]{2}T[0-9]{2}:[0-9]{2}:[0-9]{2}(\\.[0-9]{0,14})?(Z|[+-][0-9]{2}:[0-9]{2})?") {
            if let Ok(t) = parse_rfc3339(&s) {
                prop_assert!(t.is_finite());
            }
        }
    }
}
