//! Counting what was accepted and rejected, and logging rejections without
//! flooding the log: each reason is logged the first time and then at most
//! once a minute with the count since, for each vessel (rerun's rule: if you
//! log it, don't pass it on; here we count it and log it, once).

use std::collections::{BTreeMap, HashMap};
use std::time::{Duration, Instant};

/// How often one reason may be logged for one vessel.
pub const LOG_EVERY: Duration = Duration::from_secs(60);

/// Accepted and rejected counts of one vessel (or of the daemon itself, for
/// messages no vessel can be named for).
#[derive(Debug, Default, Clone)]
pub struct Counters {
    /// Accepted messages per topic (`gnss`, `nmea`, `actuators`) and per
    /// assembled input from NMEA (`nmea_fix`, `nmea_propellers`).
    pub accepted: BTreeMap<String, u64>,
    /// Rejections per reason.
    pub rejected: BTreeMap<String, u64>,
    last_logged: HashMap<String, (Instant, u64)>,
}

impl Counters {
    /// Counts an accepted message.
    pub fn accept(&mut self, what: &str) {
        // Allocates the name only the first time (every message comes here).
        match self.accepted.get_mut(what) {
            Some(n) => *n += 1,
            None => {
                self.accepted.insert(what.to_string(), 1);
            }
        }
    }

    /// Counts a rejection and logs it, rate-limited.
    pub fn reject(&mut self, who: &str, reason: &str, detail: &dyn std::fmt::Display) {
        *self.rejected.entry(reason.to_string()).or_default() += 1;
        let now = Instant::now();
        let entry = self.last_logged.entry(reason.to_string());
        match entry {
            std::collections::hash_map::Entry::Vacant(v) => {
                tracing::warn!(vessel = who, reason, "rejected: {detail}");
                v.insert((now, 0));
            }
            std::collections::hash_map::Entry::Occupied(mut o) => {
                let (at, since) = o.get_mut();
                *since += 1;
                if now.duration_since(*at) >= LOG_EVERY {
                    tracing::warn!(
                        vessel = who,
                        reason,
                        repeated = *since,
                        "rejected: {detail}"
                    );
                    *at = now;
                    *since = 0;
                }
            }
        }
    }

    /// Total rejections.
    pub fn total_rejected(&self) -> u64 {
        self.rejected.values().sum()
    }

    /// Total accepted.
    pub fn total_accepted(&self) -> u64 {
        self.accepted.values().sum()
    }
}
