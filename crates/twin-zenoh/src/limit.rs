//! The rule every network-facing binary logs refusals by: each reason the
//! first time, then at most once per interval (a minute) with the number
//! of times it happened since, so that a flood of bad input is counted in
//! full and logged in a few lines. The caller counts and writes the line;
//! this only says when.

use std::collections::HashMap;
use std::time::{Duration, Instant};

/// How often one reason may be logged.
pub const LOG_EVERY: Duration = Duration::from_secs(60);

/// When each reason was last logged and how often it happened since.
#[derive(Debug, Clone)]
pub struct ReasonLog {
    every: Duration,
    reasons: HashMap<String, (Instant, u64)>,
}

impl Default for ReasonLog {
    fn default() -> Self {
        Self::new(LOG_EVERY)
    }
}

impl ReasonLog {
    /// Logs each reason at most once per `every`.
    pub fn new(every: Duration) -> Self {
        Self {
            every,
            reasons: HashMap::new(),
        }
    }

    /// Notes one occurrence of `reason` at `now`. `Some(n)` when it is to
    /// be logged now, `n` being the occurrences since it was last logged
    /// (0 the first time); `None` when it was logged less than the interval
    /// ago (the occurrence is remembered for the next line).
    pub fn note(&mut self, reason: &str, now: Instant) -> Option<u64> {
        match self.reasons.get_mut(reason) {
            None => {
                self.reasons.insert(reason.to_owned(), (now, 0));
                Some(0)
            }
            Some((at, since)) => {
                *since += 1;
                if now.saturating_duration_since(*at) >= self.every {
                    *at = now;
                    Some(std::mem::take(since))
                } else {
                    None
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_then_once_per_interval_with_the_count_since() {
        let mut log = ReasonLog::new(Duration::from_secs(60));
        let t0 = Instant::now();
        assert_eq!(log.note("bad_checksum", t0), Some(0));
        for s in 1..60 {
            assert_eq!(log.note("bad_checksum", t0 + Duration::from_secs(s)), None);
        }
        assert_eq!(log.note("other", t0), Some(0));
        assert_eq!(
            log.note("bad_checksum", t0 + Duration::from_secs(60)),
            Some(60)
        );
        assert_eq!(log.note("bad_checksum", t0 + Duration::from_secs(61)), None);
    }
}
