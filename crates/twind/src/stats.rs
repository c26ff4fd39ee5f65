//! Counting what was received, used and refused, and logging refusals
//! without flooding the log.
//!
//! Counts are exact. Logging is limited twice: each reason is logged the
//! first time and then at most once a minute with the count since, per
//! counter (a vessel, or the daemon itself); and every refusal warning of
//! the whole process shares one budget of [`GLOBAL_WARNINGS_PER_MINUTE`]
//! lines a minute, so that a thousand misbehaving vessels write no more
//! than one does, the lines left out being counted in the next one written
//! (rerun's rule: if you log it, don't pass it on; here we count it and
//! log it, once).

use std::collections::{BTreeMap, HashMap};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use twin_wire::Topic;
use twin_wire::outputs::NmeaStats;

use crate::metrics::FleetCounts;

/// How often one reason may be logged for one counter.
pub const LOG_EVERY: Duration = Duration::from_secs(60);

/// Refusal warnings the whole process writes in a minute, at most.
pub const GLOBAL_WARNINGS_PER_MINUTE: u32 = 30;

/// At most `allowance` events pass per window of `every`; the others are
/// counted and reported with the next one that passes.
#[derive(Debug, Clone)]
pub struct RateLimit {
    every: Duration,
    allowance: u32,
    window: Option<(Instant, u32)>,
    suppressed: u64,
}

impl RateLimit {
    /// `allowance` events per `every`.
    pub const fn new(every: Duration, allowance: u32) -> Self {
        Self {
            every,
            allowance,
            window: None,
            suppressed: 0,
        }
    }

    /// Whether an event at `now` passes; if it does, how many were held
    /// back since the last one that passed.
    pub fn check(&mut self, now: Instant) -> Option<u64> {
        let used = match &mut self.window {
            Some((start, used)) if now.saturating_duration_since(*start) < self.every => used,
            _ => &mut self.window.insert((now, 0)).1,
        };
        if *used < self.allowance {
            *used += 1;
            Some(std::mem::take(&mut self.suppressed))
        } else {
            self.suppressed += 1;
            None
        }
    }
}

/// The process-wide budget of refusal warnings.
static GLOBAL: Mutex<RateLimit> = Mutex::new(RateLimit::new(
    Duration::from_secs(60),
    GLOBAL_WARNINGS_PER_MINUTE,
));

/// Whether the process-wide budget lets a warning through at `now`; if it
/// does, how many it held back since the last one.
fn global_allows(now: Instant) -> Option<u64> {
    match GLOBAL.lock() {
        Ok(mut g) => g.check(now),
        Err(poisoned) => poisoned.into_inner().check(now),
    }
}

/// The input topics, in the order of the counters' arrays.
const INPUTS: [Topic; 3] = [Topic::Gnss, Topic::Nmea, Topic::Actuators];

fn input_index(topic: Topic) -> Option<usize> {
    INPUTS.iter().position(|t| *t == topic)
}

/// Received, accepted and rejected counts of one vessel (or of the daemon
/// itself, for messages no vessel's twin saw). The input counts are fixed
/// arrays: they are on the path of every fix, and a map there costs a
/// search per message.
#[derive(Debug, Default, Clone)]
pub struct Counters {
    received: [u64; INPUTS.len()],
    accepted: [u64; INPUTS.len()],
    /// Refused messages per reason.
    pub rejected: BTreeMap<String, u64>,
    /// What the sentences of accepted NMEA payloads gave.
    pub nmea: NmeaStats,
    limits: HashMap<String, RateLimit>,
    /// The fleet's counts (the daemon's metrics), counted too.
    fleet: Option<Arc<FleetCounts>>,
}

/// Which count a refusal goes to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refused {
    /// A whole message.
    Message,
    /// A sentence inside an accepted NMEA payload.
    NmeaSentence,
    /// A fix assembled from NMEA.
    NmeaFix,
    /// Shaft speeds assembled from NMEA.
    NmeaPropellers,
}

fn names(counts: &[u64; INPUTS.len()]) -> BTreeMap<String, u64> {
    INPUTS
        .iter()
        .zip(counts)
        .filter(|(_, n)| **n > 0)
        .map(|(t, n)| (t.suffix().to_string(), *n))
        .collect()
}

impl Counters {
    /// Counters of one vessel whose counts also go to the fleet's.
    pub fn for_fleet(fleet: Arc<FleetCounts>) -> Self {
        Self {
            fleet: Some(fleet),
            ..Self::default()
        }
    }

    /// Counts a message received on an input topic.
    pub fn receive(&mut self, topic: Topic) {
        if let Some(i) = input_index(topic) {
            self.received[i] += 1;
        }
        if let Some(f) = &self.fleet {
            f.receive(topic);
        }
    }

    /// Counts a message the twin used.
    pub fn accept(&mut self, topic: Topic) {
        if let Some(i) = input_index(topic) {
            self.accepted[i] += 1;
        }
        if let Some(f) = &self.fleet {
            f.accept(topic);
        }
    }

    /// Messages received per topic, the topics never heard left out.
    pub fn received(&self) -> BTreeMap<String, u64> {
        names(&self.received)
    }

    /// Messages accepted per topic, the topics never accepted left out.
    pub fn accepted(&self) -> BTreeMap<String, u64> {
        names(&self.accepted)
    }

    /// Counts a refused message and logs it, rate-limited.
    pub fn reject(&mut self, who: &str, reason: &str, detail: &dyn std::fmt::Display) {
        self.refuse(Refused::Message, who, reason, detail);
    }

    /// Counts a refusal of `what` and logs it, rate-limited.
    pub fn refuse(
        &mut self,
        what: Refused,
        who: &str,
        reason: &str,
        detail: &dyn std::fmt::Display,
    ) {
        if let (Refused::Message, Some(f)) = (what, &self.fleet) {
            f.reject(reason);
        }
        let map = match what {
            Refused::Message => &mut self.rejected,
            Refused::NmeaSentence => &mut self.nmea.sentences_rejected,
            Refused::NmeaFix => &mut self.nmea.fixes_rejected,
            Refused::NmeaPropellers => &mut self.nmea.propellers_rejected,
        };
        match map.get_mut(reason) {
            Some(n) => *n += 1,
            None => {
                map.insert(reason.to_string(), 1);
            }
        }
        let now = Instant::now();
        let limit = match self.limits.get_mut(reason) {
            Some(l) => l,
            None => self
                .limits
                .entry(reason.to_string())
                .or_insert(RateLimit::new(LOG_EVERY, 1)),
        };
        let Some(repeated) = limit.check(now) else {
            return;
        };
        let Some(left_out) = global_allows(now) else {
            return;
        };
        match (repeated, left_out) {
            (0, 0) => tracing::warn!(vessel = who, reason, "rejected: {detail}"),
            (r, 0) => tracing::warn!(vessel = who, reason, repeated = r, "rejected: {detail}"),
            (r, l) => tracing::warn!(
                vessel = who,
                reason,
                repeated = r,
                other_warnings_not_logged = l,
                "rejected: {detail}"
            ),
        }
    }

    /// Total messages refused.
    pub fn total_rejected(&self) -> u64 {
        self.rejected.values().sum()
    }

    /// Total messages accepted.
    pub fn total_accepted(&self) -> u64 {
        self.accepted.iter().sum()
    }

    /// Total messages received.
    pub fn total_received(&self) -> u64 {
        self.received.iter().sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_are_per_topic_and_per_reason() {
        let mut c = Counters::default();
        for t in [Topic::Gnss, Topic::Gnss, Topic::Actuators, Topic::Nmea] {
            c.receive(t);
        }
        c.accept(Topic::Gnss);
        c.accept(Topic::Actuators);
        c.reject("v", "duplicate", &"x");
        c.reject("v", "empty_nmea", &"x");
        c.refuse(Refused::NmeaSentence, "v", "checksum", &"x");
        let map = |v: &[(&str, u64)]| -> BTreeMap<String, u64> {
            v.iter().map(|(k, n)| (k.to_string(), *n)).collect()
        };
        assert_eq!(
            c.received(),
            map(&[("actuators", 1), ("gnss", 2), ("nmea", 1)])
        );
        assert_eq!(c.accepted(), map(&[("actuators", 1), ("gnss", 1)]));
        assert_eq!(c.rejected, map(&[("duplicate", 1), ("empty_nmea", 1)]));
        assert_eq!(c.nmea.sentences_rejected, map(&[("checksum", 1)]));
        assert_eq!(
            c.total_received(),
            c.total_accepted() + c.total_rejected(),
            "a sentence refused inside a payload is not a message"
        );
        assert_eq!(Counters::default().accepted(), BTreeMap::new());
    }

    #[test]
    fn a_rate_limit_passes_its_allowance_per_window_and_counts_the_rest() {
        let t0 = Instant::now();
        let mut l = RateLimit::new(Duration::from_secs(60), 2);
        assert_eq!(l.check(t0), Some(0));
        assert_eq!(l.check(t0 + Duration::from_secs(1)), Some(0));
        for s in 2..50 {
            assert_eq!(l.check(t0 + Duration::from_secs(s)), None);
        }
        // A new window: the next one passes with the count held back.
        assert_eq!(l.check(t0 + Duration::from_secs(61)), Some(48));
        assert_eq!(l.check(t0 + Duration::from_secs(62)), Some(0));
        assert_eq!(l.check(t0 + Duration::from_secs(63)), None);
    }
}
