//! Counting what was accepted and rejected, and logging rejections without
//! flooding the log: each reason is logged the first time and then at most
//! once a minute with the count since, for each vessel (rerun's rule: if you
//! log it, don't pass it on; here we count it and log it, once).

use std::collections::{BTreeMap, HashMap};
use std::time::{Duration, Instant};

/// How often one reason may be logged for one vessel.
pub const LOG_EVERY: Duration = Duration::from_secs(60);

/// The names counted on every message, kept in a fixed array: the counting
/// is on the path of every fix, and a map there costs a search (and, with
/// thousands of vessels, a cache miss) per message.
const COMMON: [&str; 5] = ["gnss", "actuators", "nmea", "nmea_fix", "nmea_propellers"];

/// Accepted and rejected counts of one vessel (or of the daemon itself, for
/// messages no vessel can be named for).
#[derive(Debug, Default, Clone)]
pub struct Counters {
    /// Accepted messages of the names in `COMMON`, in its order.
    accepted_common: [u64; COMMON.len()],
    /// Accepted messages of any other name.
    accepted_other: BTreeMap<String, u64>,
    /// Rejections per reason.
    pub rejected: BTreeMap<String, u64>,
    last_logged: HashMap<String, (Instant, u64)>,
}

impl Counters {
    /// Counts an accepted message: per topic (`gnss`, `nmea`, `actuators`)
    /// and per assembled input from NMEA (`nmea_fix`, `nmea_propellers`).
    pub fn accept(&mut self, what: &str) {
        match COMMON.iter().position(|c| *c == what) {
            Some(i) => self.accepted_common[i] += 1,
            // Allocates the name only the first time.
            None => match self.accepted_other.get_mut(what) {
                Some(n) => *n += 1,
                None => {
                    self.accepted_other.insert(what.to_string(), 1);
                }
            },
        }
    }

    /// Accepted messages per name, the names never accepted left out.
    pub fn accepted(&self) -> BTreeMap<String, u64> {
        let mut all = self.accepted_other.clone();
        for (name, n) in COMMON.iter().zip(self.accepted_common) {
            if n > 0 {
                all.insert((*name).to_string(), n);
            }
        }
        all
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
        self.accepted_common.iter().sum::<u64>() + self.accepted_other.values().sum::<u64>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accepted_counts_every_name_common_or_not() {
        let mut c = Counters::default();
        for what in [
            "gnss",
            "gnss",
            "actuators",
            "nmea_propellers",
            "other",
            "other",
        ] {
            c.accept(what);
        }
        let expected: BTreeMap<String, u64> = [
            ("actuators", 1),
            ("gnss", 2),
            ("nmea_propellers", 1),
            ("other", 2),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect();
        assert_eq!(c.accepted(), expected);
        assert_eq!(c.total_accepted(), 6);
        assert_eq!(Counters::default().accepted(), BTreeMap::new());
    }
}
