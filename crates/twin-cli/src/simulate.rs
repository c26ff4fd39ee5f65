//! `twin simulate`: runs a scenario in the Otter simulator (`twin-sim`) and
//! writes what its sensors measured as a log the readers of `twin-wire` take
//! back, plus (optionally) the true state as a truth file ([`crate::truth`]).
//!
//! # Formats
//! - **NMEA 0183** (`.nmea`, `.log`, `.txt`): a `$GPZDA` first (the date),
//!   then per GNSS fix `$GPGGA` (position, quality, HDOP), `$GPRMC` (date,
//!   position, SOG, true COG), `$GPVTG` (COG, SOG); per heading sample
//!   `$HEHDT`; per yaw-rate sample `$TIROT` (degrees per minute); per
//!   measured shaft-speed sample `$ERRPM,S,1` (starboard) and
//!   `$ERRPM,S,2` (port): shafts numbered from the centre line, odd =
//!   starboard, even = port. HDT and RPM carry no time: the reader gives
//!   them the time of the latest timed sentence, so one that is not at a
//!   fix's time is preceded by a `$GPZDA` of its own time. The commanded
//!   shaft speeds are not written (a log records what the shafts did).
//! - **JSON lines** (`.jsonl`): the project's own format (`twin-wire`
//!   `JsonlWriter`): a `gnss` line per fix (heading and yaw rate joined,
//!   see below) and an `actuators` line (`rpm`) per measured shaft-speed
//!   sample.
//!
//! # Heading and yaw rate
//! The simulator gives headings and yaw rates as samples of their own. A
//! fix carries the latest heading sample stamped at or before it, not older
//! than [`MAX_HEADING_AGE_S`] and not used by an earlier fix, and likewise
//! the latest yaw-rate sample within [`MAX_YAW_RATE_AGE_S`]: the rules by
//! which `twin_wire::FixAssembler` joins an NMEA HDT and ROT to a fix, so
//! both formats read back as the same fixes.
//!
//! # Precision (what the NMEA text loses; checked by the round-trip tests)
//! The `twin-wire` writers keep more than most receivers do: time to the
//! millisecond (receivers: often hundredths of a second), latitude and
//! longitude to 1e-6 minute of arc (1.9 mm north; receivers: 1e-4 to 1e-5
//! minute, 0.2 to 0.02 m), SOG to 0.001 kn (0.5 mm/s), COG and heading to
//! 0.001 deg, shaft speed to 0.01 rpm, HDOP to 0.01. At the usual sensor
//! rates (5, 10 Hz) the sample times are whole milliseconds, so an NMEA log
//! of a simulated run loses (measured by `tests/simulate.rs`, worst case over
//! a minute) nothing of the time but the f64 rounding (2.4e-7 s), 8.3e-9 deg
//! of latitude and longitude (0.9 mm), 2.6e-4 m/s of SOG, 5e-4 deg of COG and
//! heading and 5e-3 rpm of shaft speed: half a unit of the last digit
//! written. JSON lines keep everything: latitude, longitude, SOG, COG,
//! heading and HDOP read back bit for bit, times to the microsecond (RFC 3339
//! with six decimals), shaft speeds to within the rounding of the
//! rad/s -> rpm -> rad/s conversion (1e-13 relative).
//!
//! Reading an NMEA log back, the assembler counts each burst's RMC position
//! as "not after the previous fix" (the GGA of the same instant made the
//! fix) and its RMC course as "not joined" (the VTG after it replaced it):
//! the same fix said twice, not data lost.
//!
//! JSON lines need a COG and a SOG on every fix (the `gnss` payload
//! contract); the simulator gives no COG below its `cog_min_sog_mps`, so
//! such fixes cannot be written as JSON lines: they are left out and
//! counted ([`SimulateSummary::fixes_without_course`]). NMEA writes them
//! with empty COG fields.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::str::FromStr;

use twin_core::sample::{GnssFix, Side};
use twin_sim::{Scenario, ScenarioError, SensorEvent, SimRun};
use twin_wire::measurement::{FixMethod, Talker};
use twin_wire::messages::ActuatorCommand;
use twin_wire::write::{JsonlWriter, WriteError, nmea0183};

use crate::truth::{TruthError, write_truth};

/// A heading joins a fix only if at most this much older, s (the
/// assembler's default `max_heading_age_s`).
pub const MAX_HEADING_AGE_S: f64 = 1.0;

/// A yaw rate joins a fix only if at most this much older, s (the
/// assembler's default `max_yaw_rate_age_s`).
pub const MAX_YAW_RATE_AGE_S: f64 = 0.5;

/// Two stamps closer than this are the same instant, s.
const SAME_STAMP_S: f64 = 1e-6;

/// The log format `twin simulate` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutputFormat {
    /// NMEA 0183 sentences.
    Nmea,
    /// The project's JSON lines.
    JsonLines,
}

impl OutputFormat {
    /// The format a file name implies: `.nmea`, `.log`, `.txt` are NMEA 0183,
    /// `.jsonl` JSON lines (case-insensitive); anything else is `None`.
    pub fn from_path(path: &Path) -> Option<Self> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "nmea" | "log" | "txt" => Some(OutputFormat::Nmea),
            "jsonl" => Some(OutputFormat::JsonLines),
            _ => None,
        }
    }

    /// `nmea` or `jsonl`.
    pub fn name(self) -> &'static str {
        match self {
            OutputFormat::Nmea => "nmea",
            OutputFormat::JsonLines => "jsonl",
        }
    }
}

impl FromStr for OutputFormat {
    type Err = SimulateError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "nmea" => Ok(OutputFormat::Nmea),
            "jsonl" => Ok(OutputFormat::JsonLines),
            other => Err(SimulateError::UnknownFormat(other.to_string())),
        }
    }
}

/// Why `twin simulate` failed.
#[derive(Debug, thiserror::Error)]
pub enum SimulateError {
    /// The scenario cannot be read or is invalid.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// The output format is neither given nor implied by the file name.
    #[error(
        "cannot tell the log format of {0}: name it .nmea, .log, .txt (NMEA 0183) or .jsonl (JSON lines), or pass --format"
    )]
    FormatNotImplied(PathBuf),
    /// `--format` names no known format.
    #[error("unknown format `{0}`: use nmea or jsonl")]
    UnknownFormat(String),
    /// A sentence or line cannot be written.
    #[error("cannot write the log: {0}")]
    Write(#[from] WriteError),
    /// The truth file cannot be written.
    #[error(transparent)]
    Truth(#[from] TruthError),
    /// A file cannot be created or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
}

/// What was written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SimulateSummary {
    /// GNSS fixes written.
    pub fixes: usize,
    /// Fixes that carry a heading.
    pub fixes_with_heading: usize,
    /// Fixes left out of a JSON-lines log for lack of a COG or SOG.
    pub fixes_without_course: usize,
    /// Heading samples written (HDT; in JSON lines they ride on the fixes).
    pub headings: usize,
    /// Yaw-rate samples written (ROT; in JSON lines they ride on the fixes).
    pub yaw_rates: usize,
    /// Measured shaft-speed samples written (pairs).
    pub propeller_samples: usize,
    /// Lines written to the log.
    pub lines: usize,
    /// Truth samples written.
    pub truth_samples: usize,
}

fn talker(id: &[u8; 2]) -> Talker {
    // The ids used here are upper-case ASCII letters, which `new` accepts.
    Talker::new(*id).unwrap_or(Talker::GP)
}

/// The latest sample at or before each fix, not older than `max_age_s` and
/// not used by an earlier fix: `(time, value)` samples in time order.
fn join_latest(fix_times: &[f64], samples: &[(f64, f64)], max_age_s: f64) -> Vec<Option<f64>> {
    let mut next = 0;
    // The latest sample reached and whether a fix has used it.
    let mut latest: Option<((f64, f64), bool)> = None;
    fix_times
        .iter()
        .map(|t| {
            while next < samples.len() && samples[next].0 <= t + SAME_STAMP_S {
                latest = Some((samples[next], false));
                next += 1;
            }
            match &mut latest {
                Some(((ts, value), used)) if !*used && t - *ts <= max_age_s => {
                    *used = true;
                    Some(*value)
                }
                _ => None,
            }
        })
        .collect()
}

/// The simulator's GNSS fixes with the heading and yaw-rate samples joined
/// as a logger joins them (module doc).
pub fn fixes_as_logged(run: &SimRun) -> Vec<GnssFix> {
    let fixes: Vec<GnssFix> = run.gnss_fixes().copied().collect();
    let times: Vec<f64> = fixes.iter().map(|f| f.time_s).collect();
    let headings: Vec<(f64, f64)> = run.headings().map(|h| (h.time_s, h.heading_rad)).collect();
    let rates: Vec<(f64, f64)> = run
        .events
        .iter()
        .filter_map(|e| match e {
            SensorEvent::YawRate(y) => Some((y.time_s, y.yaw_rate_radps)),
            _ => None,
        })
        .collect();
    let headings = join_latest(&times, &headings, MAX_HEADING_AGE_S);
    let rates = join_latest(&times, &rates, MAX_YAW_RATE_AGE_S);
    fixes
        .into_iter()
        .zip(headings.into_iter().zip(rates))
        .map(|(mut fix, (heading, rate))| {
            fix.heading_rad = heading;
            fix.yaw_rate_radps = rate;
            fix
        })
        .collect()
}

/// Writes the run's sensor events as NMEA 0183 (module doc).
pub fn write_nmea<W: Write>(run: &SimRun, out: W) -> Result<SimulateSummary, SimulateError> {
    let gp = Talker::GP;
    let he = talker(b"HE");
    let ti = talker(b"TI");
    let er = talker(b"ER");
    let mut w = LineWriter::new(out);
    let mut summary = SimulateSummary::default();
    let fixes = fixes_as_logged(run);
    let mut fix_iter = fixes.iter();
    // Time of the latest timed sentence written, s.
    let mut clock: Option<f64> = None;
    let timed = |w: &mut LineWriter<W>, clock: &mut Option<f64>, t: f64| {
        if clock.is_none_or(|c| (c - t).abs() >= 5e-4) {
            w.line(&nmea0183::zda(gp, t)?)?;
            *clock = Some(t);
        }
        Ok::<(), SimulateError>(())
    };
    if let Some(first) = run.events.first() {
        timed(&mut w, &mut clock, first.time_s())?;
    }
    for event in &run.events {
        match event {
            SensorEvent::Gnss(_) => {
                // The same fix, heading joined.
                let Some(fix) = fix_iter.next() else { continue };
                w.line(&nmea0183::gga(gp, fix, FixMethod::Gnss, Some(12), None)?)?;
                w.line(&nmea0183::rmc(gp, fix)?)?;
                w.line(&nmea0183::vtg(gp, fix.cog_rad, fix.sog_mps)?)?;
                clock = Some(fix.time_s);
                summary.fixes += 1;
                summary.fixes_with_heading += usize::from(fix.heading_rad.is_some());
            }
            SensorEvent::Heading(h) => {
                timed(&mut w, &mut clock, h.time_s)?;
                w.line(&nmea0183::hdt(he, h.heading_rad)?)?;
                summary.headings += 1;
            }
            SensorEvent::YawRate(y) => {
                timed(&mut w, &mut clock, y.time_s)?;
                w.line(&nmea0183::rot(ti, y.yaw_rate_radps)?)?;
                summary.yaw_rates += 1;
            }
            SensorEvent::PropellerMeasured(p) => {
                timed(&mut w, &mut clock, p.time_s)?;
                w.line(&nmea0183::rpm(er, Side::Starboard, p.starboard_radps)?)?;
                w.line(&nmea0183::rpm(er, Side::Port, p.port_radps)?)?;
                summary.propeller_samples += 1;
            }
            SensorEvent::PropellerCommanded(_) => {}
        }
    }
    summary.lines = w.finish()?;
    Ok(summary)
}

/// Counts lines while writing them with `\r\n`.
struct LineWriter<W> {
    out: W,
    lines: usize,
}

impl<W: Write> LineWriter<W> {
    fn new(out: W) -> Self {
        Self { out, lines: 0 }
    }

    fn line(&mut self, sentence: &str) -> Result<(), SimulateError> {
        self.out
            .write_all(sentence.as_bytes())
            .and_then(|()| self.out.write_all(b"\r\n"))
            .map_err(WriteError::from)?;
        self.lines += 1;
        Ok(())
    }

    fn finish(mut self) -> Result<usize, SimulateError> {
        self.out.flush().map_err(WriteError::from)?;
        Ok(self.lines)
    }
}

/// Writes the run's sensor events as the project's JSON lines (module doc).
pub fn write_jsonl<W: Write>(run: &SimRun, out: W) -> Result<SimulateSummary, SimulateError> {
    let mut w = JsonlWriter::new(out);
    let mut summary = SimulateSummary::default();
    let fixes = fixes_as_logged(run);
    let mut fix_iter = fixes.iter();
    for event in &run.events {
        match event {
            SensorEvent::Gnss(_) => {
                let Some(fix) = fix_iter.next() else { continue };
                if fix.sog_mps.is_none() || fix.cog_rad.is_none() {
                    summary.fixes_without_course += 1;
                    continue;
                }
                w.gnss(fix)?;
                summary.fixes += 1;
                summary.fixes_with_heading += usize::from(fix.heading_rad.is_some());
                summary.lines += 1;
            }
            SensorEvent::PropellerMeasured(p) => {
                w.actuators(&ActuatorCommand::Speeds(*p))?;
                summary.propeller_samples += 1;
                summary.lines += 1;
            }
            SensorEvent::Heading(_) => summary.headings += 1,
            SensorEvent::YawRate(_) => summary.yaw_rates += 1,
            SensorEvent::PropellerCommanded(_) => {}
        }
    }
    w.into_inner()?;
    Ok(summary)
}

/// Writes the run's log in `format` to `out`.
pub fn write_log<W: Write>(
    run: &SimRun,
    format: OutputFormat,
    out: W,
) -> Result<SimulateSummary, SimulateError> {
    match format {
        OutputFormat::Nmea => write_nmea(run, out),
        OutputFormat::JsonLines => write_jsonl(run, out),
    }
}

/// What `twin simulate` is asked to do.
#[derive(Debug, Clone, PartialEq)]
pub struct SimulateRequest {
    /// The scenario file.
    pub scenario: PathBuf,
    /// The log to write.
    pub out: PathBuf,
    /// The format; `None`: from `out`'s extension.
    pub format: Option<OutputFormat>,
    /// The truth file to write, if any.
    pub truth: Option<PathBuf>,
}

fn create(path: &Path) -> Result<BufWriter<File>, SimulateError> {
    File::create(path)
        .map(BufWriter::new)
        .map_err(|source| SimulateError::Io {
            path: path.to_path_buf(),
            source,
        })
}

/// Runs `twin simulate`: simulates, writes the log and the truth.
pub fn simulate_to_files(request: &SimulateRequest) -> Result<SimulateSummary, SimulateError> {
    let format = match request.format {
        Some(f) => f,
        None => OutputFormat::from_path(&request.out)
            .ok_or_else(|| SimulateError::FormatNotImplied(request.out.clone()))?,
    };
    let scenario = Scenario::from_path(&request.scenario)?;
    let run = twin_sim::simulate(&scenario)?;
    let mut summary = write_log(&run, format, create(&request.out)?)?;
    if let Some(path) = &request.truth {
        summary.truth_samples = write_truth(&run.truth, create(path)?)?;
    }
    Ok(summary)
}

/// The log of a scenario, in memory (what the demo test compares with).
pub fn simulate_to_bytes(
    scenario: &Scenario,
    format: OutputFormat,
) -> Result<(Vec<u8>, SimulateSummary), SimulateError> {
    let run = twin_sim::simulate(scenario)?;
    let mut bytes = Vec::new();
    let summary = write_log(&run, format, &mut bytes)?;
    Ok((bytes, summary))
}
