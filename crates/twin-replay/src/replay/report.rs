//! What a replay tells its caller: [`Progress`] about once a second and a
//! [`ReplaySummary`] at the end, both printable as one human-readable text.

use std::fmt;
use std::time::Duration;

use twin_wire::assemble::AssembleStats;
use twin_wire::read::{LogFormat, ReadStats};
use twin_wire::time::format_rfc3339;

/// Messages published, by topic.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Published {
    /// On `{prefix}/{vessel}/gnss`.
    pub gnss: u64,
    /// On `{prefix}/{vessel}/actuators`.
    pub actuators: u64,
}

impl Published {
    /// Both topics together.
    pub fn total(&self) -> u64 {
        self.gnss + self.actuators
    }
}

/// Assembled inputs not published because the contract cannot carry them
/// (a fix without course or speed; a value outside the contract's range).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Skipped {
    /// Fixes.
    pub gnss: u64,
    /// Propeller speeds and thrusts.
    pub actuators: u64,
}

/// Where a replay is, reported about once a second of wall time and once at
/// the end.
#[derive(Debug, Clone, PartialEq)]
pub struct Progress {
    /// The pass under way, from 0 (the number of passes completed at the end).
    pub pass: u32,
    /// Passes asked for (0: until cancelled).
    pub loops: u32,
    /// Log time of the latest message published, s since the epoch.
    pub log_time_s: Option<f64>,
    /// The same, in log seconds after the first record.
    pub log_offset_s: Option<f64>,
    /// Share of the whole replay done, 0..=1; `None` for an endless replay
    /// or when the log's size is unknown and no duration was given.
    pub fraction: Option<f64>,
    /// Share of the current pass done, 0..=1: by log time when a duration is
    /// given, else by bytes of the log read (when its size is known).
    pub pass_fraction: Option<f64>,
    /// Messages published so far.
    pub published: Published,
    /// Wall time since the replay began.
    pub wall: Duration,
}

/// What a replay did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ReplaySummary {
    /// The log's path or name.
    pub name: String,
    /// Its format, once opened.
    pub format: Option<LogFormat>,
    /// Messages published, by topic (all passes).
    pub published: Published,
    /// Inputs not published (all passes).
    pub skipped: Skipped,
    /// Passes completed.
    pub passes: u32,
    /// True when the replay was stopped before it finished ([`crate::run`]'s
    /// shutdown).
    pub interrupted: bool,
    /// The reader's counts (records by kind, rejections by reason) of the
    /// last completed pass; a pass that ends at the end of a window stops
    /// reading there.
    pub read_stats: ReadStats,
    /// The assembler's counts of the last completed pass.
    pub assemble_stats: AssembleStats,
    /// Log time of the first message published, s since the epoch.
    pub first_published_s: Option<f64>,
    /// Log time of the last message published, s since the epoch.
    pub last_published_s: Option<f64>,
    /// Wall time the replay took.
    pub wall: Duration,
}

impl ReplaySummary {
    /// Log seconds between the first and the last message published.
    pub fn log_span_s(&self) -> f64 {
        match (self.first_published_s, self.last_published_s) {
            (Some(first), Some(last)) => last - first,
            _ => 0.0,
        }
    }
}

fn time(time_s: f64) -> String {
    format_rfc3339(time_s).unwrap_or_else(|_| format!("{time_s:.3} s"))
}

fn format_name(format: LogFormat) -> &'static str {
    format.description()
}

/// One line: `log 2026-08-03T04:27:20.588Z (+123.4 s), 42.0 %, published
/// 1234 (gnss 1234, actuators 0), pass 1/1, wall 12.3 s`.
impl fmt::Display for Progress {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (self.log_time_s, self.log_offset_s) {
            (Some(t), Some(offset)) => write!(f, "log {} (+{offset:.1} s)", time(t))?,
            _ => f.write_str("log -")?,
        }
        if let Some(fraction) = self.fraction.or(self.pass_fraction) {
            write!(f, ", {:.1} %", 100.0 * fraction)?;
        }
        write!(
            f,
            ", published {} (gnss {}, actuators {})",
            self.published.total(),
            self.published.gnss,
            self.published.actuators
        )?;
        match self.loops {
            0 => write!(f, ", pass {} (looping)", self.pass + 1)?,
            1 => {}
            n => write!(f, ", pass {}/{n}", (self.pass + 1).min(n))?,
        }
        write!(f, ", wall {:.1} s", self.wall.as_secs_f64())
    }
}

/// A few lines: what was published, the log's span, what the reader made
/// of the log and the rejections by reason.
impl fmt::Display for ReplaySummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let format = self.format.map_or("unknown format", format_name);
        write!(
            f,
            "{} {} ({format}): {} pass{} in {:.3} s",
            if self.interrupted {
                "interrupted"
            } else {
                "replayed"
            },
            self.name,
            self.passes,
            if self.passes == 1 { "" } else { "es" },
            self.wall.as_secs_f64()
        )?;
        write!(
            f,
            "\npublished: {} gnss, {} actuators",
            self.published.gnss, self.published.actuators
        )?;
        if self.skipped != Skipped::default() {
            write!(
                f,
                "\nskipped (the contract cannot carry them): {} fixes, {} actuator samples",
                self.skipped.gnss, self.skipped.actuators
            )?;
        }
        if let (Some(first), Some(last)) = (self.first_published_s, self.last_published_s) {
            write!(
                f,
                "\nlog: {} to {} ({:.1} s)",
                time(first),
                time(last),
                self.log_span_s()
            )?;
        }
        let stats = &self.read_stats;
        write!(
            f,
            "\nread: {} lines, {} records, {} rejected, {} ignored, {} empty",
            stats.lines,
            stats.total_records(),
            stats.total_rejected(),
            stats.ignored,
            stats.empty
        )?;
        let rejected: Vec<String> = stats
            .rejected_by_kind()
            .map(|(kind, n)| format!("{} {n}", kind.name()))
            .collect();
        if !rejected.is_empty() {
            write!(f, " ({})", rejected.join(", "))?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn progress_reads_as_one_line() {
        let p = Progress {
            pass: 1,
            loops: 2,
            log_time_s: Some(1_785_731_240.5),
            log_offset_s: Some(12.25),
            fraction: Some(0.75),
            pass_fraction: Some(0.5),
            published: Published {
                gnss: 10,
                actuators: 5,
            },
            wall: Duration::from_millis(1500),
        };
        assert_eq!(
            p.to_string(),
            "log 2026-08-03T04:27:20.500Z (+12.2 s), 75.0 %, published 15 (gnss 10, actuators 5), pass 2/2, wall 1.5 s"
        );
    }

    #[test]
    fn summary_names_the_rejections() {
        let summary = ReplaySummary {
            name: "x.log".into(),
            format: Some(LogFormat::Nmea0183),
            published: Published {
                gnss: 3,
                actuators: 0,
            },
            skipped: Skipped {
                gnss: 1,
                actuators: 0,
            },
            passes: 1,
            first_published_s: Some(0.0),
            last_published_s: Some(2.0),
            wall: Duration::from_millis(20),
            ..ReplaySummary::default()
        };
        let text = summary.to_string();
        assert!(
            text.starts_with("replayed x.log (NMEA 0183): 1 pass in 0.020 s"),
            "{text}"
        );
        assert!(text.contains("published: 3 gnss, 0 actuators"), "{text}");
        assert!(
            text.contains("skipped (the contract cannot carry them): 1 fixes"),
            "{text}"
        );
        assert!(text.contains("(2.0 s)"), "{text}");
    }
}
