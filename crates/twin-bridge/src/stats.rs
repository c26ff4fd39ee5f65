//! What each source did: bytes and lines in, records by kind, rejections by
//! reason, messages published, connections made and lost. The counts are
//! exact; each reason is logged the first time and then at most once a
//! minute with the count since (`twin_zenoh::limit::ReasonLog`). Once a
//! second the bridge writes one line per source to stderr and puts the
//! whole as JSON ([`BridgeStats`]) on `{prefix}/{vessel}/bridge/stats`.

use std::collections::BTreeMap;
use std::fmt;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Instant;

use serde::{Deserialize, Serialize};
use twin_zenoh::limit::ReasonLog;

/// Messages published, by key.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Published {
    /// On `{prefix}/{vessel}/gnss`.
    pub gnss: u64,
    /// On `{prefix}/{vessel}/actuators`.
    pub actuators: u64,
    /// On `{prefix}/{vessel}/nmea` (payloads, each of one or more sentences).
    pub nmea: u64,
}

impl Published {
    /// All keys together.
    pub fn total(&self) -> u64 {
        self.gnss + self.actuators + self.nmea
    }
}

/// The counts of one source, as published.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct SourceStats {
    /// The source as given (`nmea0183:udp:10110`).
    pub name: String,
    /// Its format.
    pub format: String,
    /// Its transport.
    pub transport: String,
    /// Connected (a TCP peer, an open serial port, a bound socket).
    pub connected: bool,
    /// Connections made (or ports opened).
    pub connects: u64,
    /// Connections lost or refused, by reason (`refused`, `closed`, `io`...).
    pub disconnects: BTreeMap<String, u64>,
    /// Bytes received.
    pub bytes: u64,
    /// Lines (frames, datagrams of binary formats) decoded.
    pub lines: u64,
    /// Records decoded, by kind.
    pub records: BTreeMap<String, u64>,
    /// Lines or messages refused, by reason.
    pub rejected: BTreeMap<String, u64>,
    /// Well-formed messages of a kind not read (other sentences and PGNs).
    pub ignored: u64,
    /// Messages published.
    pub published: Published,
    /// Assembled inputs the contract cannot carry (a fix without course
    /// or speed...), by reason: counted, not published.
    pub not_published: BTreeMap<String, u64>,
    /// Inputs published with the receive time (the source gave none).
    pub receiver_stamped: u64,
}

/// Every source's counts: the payload of `{prefix}/{vessel}/bridge/stats`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct BridgeStats {
    /// The vessel published as.
    pub vessel: String,
    /// Seconds since the bridge started.
    pub uptime_s: f64,
    /// One entry per `--source`, in the order given.
    pub sources: Vec<SourceStats>,
}

/// The counts of one source and its log limiter, shared between its
/// thread and the reporter.
#[derive(Debug)]
pub struct Counter {
    stats: Mutex<SourceStats>,
    log: Mutex<ReasonLog>,
}

impl Counter {
    /// Counters for a source.
    pub fn new(name: &str, format: &str, transport: &str) -> Arc<Self> {
        Arc::new(Self {
            stats: Mutex::new(SourceStats {
                name: name.to_owned(),
                format: format.to_owned(),
                transport: transport.to_owned(),
                ..SourceStats::default()
            }),
            log: Mutex::new(ReasonLog::default()),
        })
    }

    /// The counts, to change them.
    pub fn lock(&self) -> MutexGuard<'_, SourceStats> {
        // A poisoned lock only means a panic elsewhere mid-update: the
        // counts are still the best there are.
        self.stats.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// A copy of the counts.
    pub fn snapshot(&self) -> SourceStats {
        self.lock().clone()
    }

    /// Logs `detail` for `reason` if the limiter lets it through.
    pub fn log(&self, reason: &str, detail: &dyn fmt::Display) {
        let verdict = self
            .log
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .note(reason, Instant::now());
        let source = self.lock().name.clone();
        match verdict {
            Some(0) => tracing::warn!(source, reason, "{detail}"),
            Some(repeated) => tracing::warn!(source, reason, repeated, "{detail}"),
            None => {}
        }
    }

    /// Counts a refusal by reason and logs it (rate-limited).
    pub fn reject(&self, reason: &str, detail: &dyn fmt::Display) {
        *self.lock().rejected.entry(reason.to_owned()).or_default() += 1;
        self.log(reason, detail);
    }

    /// Counts a lost or refused connection and logs it (rate-limited).
    pub fn disconnected(&self, reason: &str, detail: &dyn fmt::Display) {
        {
            let mut s = self.lock();
            s.connected = false;
            *s.disconnects.entry(reason.to_owned()).or_default() += 1;
        }
        self.log(reason, detail);
    }

    /// Counts a connection made.
    pub fn connected(&self, detail: &dyn fmt::Display) {
        {
            let mut s = self.lock();
            s.connected = true;
            s.connects += 1;
        }
        tracing::info!(source = self.lock().name.clone(), "{detail}");
    }
}

fn sum(map: &BTreeMap<String, u64>) -> u64 {
    map.values().sum()
}

/// One line for stderr: `nmea0183:udp:10110 up: 1520 lines, 310 records,
/// published gnss 150 actuators 0 nmea 0, rejected 3 (bad_checksum 3)`.
impl fmt::Display for SourceStats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} {}: {} bytes, {} lines, {} records, published gnss {} actuators {} nmea {}",
            self.name,
            if self.connected { "up" } else { "down" },
            self.bytes,
            self.lines,
            sum(&self.records),
            self.published.gnss,
            self.published.actuators,
            self.published.nmea
        )?;
        let rejected = sum(&self.rejected);
        if rejected > 0 {
            let reasons: Vec<String> = self
                .rejected
                .iter()
                .map(|(r, n)| format!("{r} {n}"))
                .collect();
            write!(f, ", rejected {rejected} ({})", reasons.join(", "))?;
        }
        let lost = sum(&self.disconnects);
        if lost > 0 {
            let reasons: Vec<String> = self
                .disconnects
                .iter()
                .map(|(r, n)| format!("{r} {n}"))
                .collect();
            write!(f, ", connection lost {lost} ({})", reasons.join(", "))?;
        }
        let skipped = sum(&self.not_published);
        if skipped > 0 {
            write!(f, ", not publishable {skipped}")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_and_the_stderr_line() {
        let c = Counter::new("nmea0183:udp:10110", "nmea0183", "udp");
        c.connected(&"listening");
        for _ in 0..3 {
            c.reject("bad_checksum", &"checksum 41 in the sentence, 40 computed");
        }
        c.disconnected("closed", &"peer closed");
        {
            let mut s = c.lock();
            s.lines = 10;
            s.published.gnss = 4;
        }
        let s = c.snapshot();
        assert_eq!(s.rejected["bad_checksum"], 3);
        assert_eq!(s.connects, 1);
        assert!(!s.connected);
        assert_eq!(
            s.to_string(),
            "nmea0183:udp:10110 down: 0 bytes, 10 lines, 0 records, published gnss 4 actuators 0 nmea 0, rejected 3 (bad_checksum 3), connection lost 1 (closed 1)"
        );
        let json = serde_json::to_string(&BridgeStats {
            vessel: "otter".into(),
            uptime_s: 1.0,
            sources: vec![s.clone()],
        })
        .unwrap();
        let back: BridgeStats = serde_json::from_str(&json).unwrap();
        assert_eq!(back.sources[0], s);
    }
}
