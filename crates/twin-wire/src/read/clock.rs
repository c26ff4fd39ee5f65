//! Dates for formats whose lines carry only a time of day (NMEA 0183 GGA
//! and GLL, Yacht Devices RAW, Actisense N2K ASCII): the day is the current
//! date, the day before or the day after, whichever puts the line nearest
//! the latest time, so that midnight advances the date and a line stamped
//! just before midnight that arrives just after it does not jump a day
//! ahead. Shared so that every such reader dates its lines the same way.

use super::{Monotonic, RejectReason};
use crate::time::{CivilDate, SECONDS_PER_DAY};

/// A time resolved for a line: seconds since the epoch, and whether its
/// date was assumed rather than given.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Stamp {
    pub(crate) time_s: f64,
    pub(crate) undated: bool,
}

/// The current date and the latest time of one stream.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct DayClock {
    /// The current date, days since the epoch, and whether it was assumed.
    date: Option<(i64, bool)>,
    /// The latest accepted time, and whether its date was assumed.
    latest: Option<(f64, bool)>,
    monotonic: Monotonic,
}

impl DayClock {
    /// The time of a line with a full date; it sets the date.
    pub(crate) fn dated(
        &mut self,
        days: i64,
        tod_s: f64,
        tolerance_s: f64,
    ) -> Result<Stamp, RejectReason> {
        let time_s = (days * SECONDS_PER_DAY) as f64 + tod_s;
        self.monotonic.check(time_s, tolerance_s)?;
        self.date = Some((days, false));
        self.latest = Some((time_s, false));
        Ok(Stamp {
            time_s,
            undated: false,
        })
    }

    /// The time of a time-of-day-only line: the current date, else
    /// `assumed` (the record then counts as undated), else `NoDate`.
    pub(crate) fn time_of_day(
        &mut self,
        tod_s: f64,
        assumed: Option<CivilDate>,
        tolerance_s: f64,
    ) -> Result<Stamp, RejectReason> {
        let (days, assumed) = match (self.date, assumed) {
            (Some(date), _) => date,
            (None, Some(assumed)) => (assumed.days_since_epoch(), true),
            (None, None) => return Err(RejectReason::NoDate),
        };
        let at = |d: i64| (d * SECONDS_PER_DAY) as f64 + tod_s;
        let day = match self.latest {
            Some((latest, _)) => [days - 1, days, days + 1]
                .into_iter()
                .min_by(|a, b| (at(*a) - latest).abs().total_cmp(&(at(*b) - latest).abs()))
                .unwrap_or(days),
            None => days,
        };
        let time_s = at(day);
        self.monotonic.check(time_s, tolerance_s)?;
        // A day before the current date is a late line: the date stays.
        self.date = Some((day.max(days), assumed));
        self.latest = Some((time_s, assumed));
        Ok(Stamp {
            time_s,
            undated: assumed,
        })
    }

    /// The time of a line without time: the latest timed line's.
    pub(crate) fn untimed(&self) -> Result<Stamp, RejectReason> {
        self.latest
            .map(|(time_s, undated)| Stamp { time_s, undated })
            .ok_or(RejectReason::NoTime)
    }

    /// A full time given from outside (a receive time): checked against the
    /// newest time, and it becomes the latest.
    pub(crate) fn exact(&mut self, time_s: f64, tolerance_s: f64) -> Result<Stamp, RejectReason> {
        self.monotonic.check(time_s, tolerance_s)?;
        self.latest = Some((time_s, false));
        Ok(Stamp {
            time_s,
            undated: false,
        })
    }
}
