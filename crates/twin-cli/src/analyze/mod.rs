//! `twin analyze LOG`: streams a log through `twin_wire::LogReader` ->
//! `twin_wire::FixAssembler` -> `twin_core::twin::VesselTwin` (default
//! `TwinConfig`, the same engine the daemon runs) in constant memory, and
//! reports what the twin concluded and how well its model explained the data.
//!
//! # What is reported
//! - the log: format, span, the sources chosen, what was read, assembled,
//!   used, and rejected with reasons (the reader's typed rejections AND the
//!   twin's own: duplicates, jumps, refused steps...), with the first example
//!   of each reason;
//! - the estimate's quality per estimator ([`crate::quality`]): innovation RMS
//!   per component, mean NIS per degree of freedom against its chi-square
//!   95 % band, and the fraction of steps above their 95 % quantile;
//! - thruster faults: where the log has propeller speeds, the extended twin
//!   (the Otter's kinetic model driven by the shaft speeds) gives each
//!   propeller's loss with its sigma, status and onset, and the water current;
//!   where it has none, the losses are `null` and the seed method's input
//!   faults are given instead, with the note that a loss of thrust cannot be
//!   seen from GNSS alone (docs/model.md section 5);
//! - with a truth file ([`crate::truth`]): the true losses beside the
//!   estimates, and a forecast from the middle of the run (the extended
//!   twin's through the recorded propeller speeds; the seed model's with its
//!   inputs held) scored against the truth.
//!
//! # The JSON schema (`--json`), `"schema": "twin-analyze/1"`
//! One object; numbers are SI with the unit in the name; times RFC 3339 UTC;
//! `null` where a value does not exist. Fields are only ever added.
//! ```text
//! schema            "twin-analyze/1"
//! log               the path given
//! format            "nmea0183" | "n2k" | "json_lines" | "candump" | "ydraw" |
//!                   "actisense_ascii" | "gpsd_json" | "mavlink_tlog"
//! span              {start, end, duration_s} of the records read, or null
//! sources           {position, course, heading, yaw_rate}: "n2k:25", "nmea:GP", "json" or null
//! samples           inputs the twin used: GNSS fixes + propeller samples
//! rejected          inputs refused: reader rejections + twin rejections
//! samples_by_kind   {fixes, propellers}
//! rejected_by_reason {reader: {reason: n}, twin_fixes: {reason: n}, twin_propellers: {reason: n}}
//! first_rejections  [{stage, reason, detail}]: the first of each reason
//! read              twin_wire::ReadStats (lines, blank, ignored, empty, time_only,
//!                   without_checksum, undated, records {kind: n}, rejected {reason: n})
//! assembled         {fixes, fixes_with_course, fixes_with_heading, fixes_with_yaw_rate,
//!                   propeller_pairs,
//!                   thrust_commands, positions_other_sources, positions_not_after_previous,
//!                   positions_repeated, courses_other_sources, courses_unused,
//!                   headings_other_sources, propeller_unpaired, out_of_order}
//! model             the estimator the thruster figures come from: "kinetic"
//!                   (extended twin) or "seed_method"; null with no fix
//! thrusters         {observable, time, status, onset, effectiveness_ratio {value, sigma} | null,
//!                    note,
//!                    port: {loss, loss_raw, sigma, excited, status, onset, samples, rejected},
//!                    starboard: {...}}
//!                   loss: the final estimate clamped to 0..1, null when not observable;
//!                   status: "not_excited" | "nominal" | "suspect" | "fault";
//!                   samples: fixes the extended twin stepped on;
//!                   rejected: propeller samples the twin refused
//! alarms            [{time, side, from, to, onset, confidence}] status changes
//! current           {north_mps, east_mps, speed_mps, toward_deg, sigma_mps} where the
//!                   extended twin ran, else null
//! seed_method       {input_faults [a, r], input_fault_sigma, input_fault_peak,
//!                    thruster_values [port, starboard], thruster_peak, note}
//! quality           {kinetic: Quality | null, seed_method: Quality | null}, each over
//!                   the steps in which that estimator reported (the seed method's
//!                   only while no propeller data drove the extended twin); Quality:
//!                   {steps, innovation_rms {north_m, east_m, position_m, sog_mps,
//!                    cog_rad, heading_rad}, measured [n, e, sog, cog, heading],
//!                    mean_nis, mean_dof, mean_nis_per_dof, nis_band_95 [lo, hi],
//!                    nis_within_band, fraction_above_95, max_nis_per_dof}
//! final_state       {time, lat_deg, lon_deg, north_m, east_m, sigma_north_m, sigma_east_m,
//!                    sog_mps, cog_rad, heading_rad, model} or null
//! truth             {samples, loss {port, starboard}, loss_error {port, starboard}} or null
//! prediction        {model, start, horizon_s, points, rmse_north_m, rmse_east_m,
//!                    rmse_position_m, final_error_m, within_1_sigma, within_2_sigma} or null
//! ```
//!
//! # Memory
//! Nothing grows with the log's length: counters, the twin, the latest
//! reports, the first example of each rejection reason, the first 1000
//! status changes. The optional series for `--plot` are decimated to at most
//! [`MAX_SERIES_POINTS`] points (every second one dropped, and the stride
//! doubled, when full); the forecast inputs after the middle of the run are
//! kept only when a truth file is given.

use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};

use twin_core::decision::ThrusterStatus;
use twin_core::geodesy::{LatLon, NorthEast, rad_to_compass_deg};
use twin_core::models::otter_twin::{ShaftSpeeds, idx};
use twin_core::sample::{GnssFix, PropellerSpeeds};
use twin_core::twin::{
    FaultReport, FaultSource, ForecastPoint, StateReport, StepOutput, TwinConfig, TwinConfigError,
    VesselTwin,
};
use twin_wire::assemble::{Assembled, AssemblerConfig, FixAssembler, SourceChoice};
use twin_wire::measurement::{Source, Talker};
use twin_wire::outputs::ProfileMismatchMessage;
use twin_wire::profile::VesselProfile;
use twin_wire::read::{LogFormat, LogReader, OpenError, ReadOptions};
use twin_wire::time::format_rfc3339;

use crate::quality::QualityAccumulator;
use crate::truth::{TruthError, TruthPoint};

pub mod mcap;
mod report;
mod text;

pub use report::*;
pub use text::duration_text;

/// The schema name and version written in every JSON report.
pub const SCHEMA: &str = "twin-analyze/1";

/// The most points kept per plotted series.
pub const MAX_SERIES_POINTS: usize = 4096;

/// The note printed where thrust loss cannot be estimated.
pub const NOT_OBSERVABLE_NOTE: &str = "The log has no propeller speeds: a loss of thrust is not observable from GNSS alone (docs/model.md section 5). With inputs derived from the same GNSS track the filter observes, any loss is already inside the inputs; the seed method's input faults below follow the lag and noise of the input derivation, not the propellers.";

/// The note printed with the extended twin's estimates.
pub const KINETIC_NOTE: &str = "Extended twin: the Otter's kinetic model driven by the logged shaft speeds, estimating each propeller's loss of effectiveness and the water current.";

/// Why `twin analyze` failed.
#[derive(Debug, thiserror::Error)]
pub enum AnalyzeError {
    /// The log cannot be opened.
    #[error("cannot open log {path}: {source}")]
    Open {
        /// The log.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The log is empty, in no known format, or unreadable.
    #[error("cannot read log {path}: {source}")]
    Log {
        /// The log.
        path: PathBuf,
        /// Why.
        source: OpenError,
    },
    /// The twin's configuration is unusable.
    #[error("twin configuration: {0}")]
    Config(#[from] TwinConfigError),
    /// `--source` names no source.
    #[error(
        "unknown source `{0}`: use best, an NMEA 2000 address (0-255), an NMEA 0183 talker (GP), or n2k:ADDRESS / nmea:TALKER / json"
    )]
    BadSource(String),
    /// The MCAP recording cannot be written.
    #[error("MCAP recording {path}: {source}")]
    Mcap {
        /// The file.
        path: PathBuf,
        /// Why.
        source: twin_wire::mcap::McapError,
    },
    /// The truth file cannot be read.
    #[error("truth file {path}: {source}")]
    Truth {
        /// The file.
        path: PathBuf,
        /// Why.
        source: TruthError,
    },
}

/// Parses `--source`: `best`, an NMEA 2000 address (`25`), an NMEA 0183
/// talker (`GP`), or `n2k:25`, `nmea:GP`, `json`.
pub fn parse_source(text: &str) -> Result<SourceChoice, AnalyzeError> {
    let t = text.trim();
    if t.eq_ignore_ascii_case("best") {
        return Ok(SourceChoice::Best);
    }
    if let Ok(address) = t.parse::<u8>() {
        return Ok(SourceChoice::Fixed(Source::N2k(address)));
    }
    if let Ok(s) = t.parse::<Source>() {
        return Ok(SourceChoice::Fixed(s));
    }
    let upper = t.to_ascii_uppercase();
    if let Ok(bytes) = <[u8; 2]>::try_from(upper.as_bytes())
        && let Some(talker) = Talker::new(bytes)
    {
        return Ok(SourceChoice::Fixed(Source::Nmea(talker)));
    }
    Err(AnalyzeError::BadSource(text.to_string()))
}

/// How to analyse.
#[derive(Debug, Clone, PartialEq)]
pub struct AnalyzeOptions {
    /// Which GNSS source gives positions.
    pub source: SourceChoice,
    /// The twin's tuning ...
    pub config: TwinConfig,
    /// ... for the vessel this profile describes
    /// ([`VesselProfile::twin_config`]).
    pub profile: VesselProfile,
    /// The readers' options.
    pub read: ReadOptions,
    /// The truth to compare with, if any (sorted by time).
    pub truth: Option<Vec<TruthPoint>>,
    /// Keep decimated series for plots.
    pub keep_series: bool,
    /// Record the inputs and outputs into this MCAP file ([`mcap`]).
    pub mcap: Option<PathBuf>,
}

impl Default for AnalyzeOptions {
    fn default() -> Self {
        Self {
            source: SourceChoice::Best,
            config: TwinConfig::default(),
            profile: VesselProfile::otter(),
            read: ReadOptions::default(),
            truth: None,
            keep_series: false,
            mcap: None,
        }
    }
}

/// Reads a truth file for [`AnalyzeOptions::truth`].
pub fn load_truth(path: &Path) -> Result<Vec<TruthPoint>, AnalyzeError> {
    let file = File::open(path).map_err(|e| AnalyzeError::Truth {
        path: path.to_path_buf(),
        source: e.into(),
    })?;
    crate::truth::read_truth(BufReader::new(file)).map_err(|source| AnalyzeError::Truth {
        path: path.to_path_buf(),
        source,
    })
}

fn time_text(time_s: f64) -> String {
    format_rfc3339(time_s).unwrap_or_else(|_| format!("{time_s} s"))
}

fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}
/// The format's name in reports.
pub fn format_name(f: LogFormat) -> &'static str {
    f.name()
}

/// Interpolates the truth at `time_s` (linear in lat/lon; `None` outside).
fn truth_at(truth: &[TruthPoint], time_s: f64) -> Option<LatLon> {
    let i = truth.partition_point(|p| p.time_s < time_s);
    let after = truth.get(i)?;
    if (after.time_s - time_s).abs() < 1e-6 {
        return Some(after.position);
    }
    let before = truth.get(i.checked_sub(1)?)?;
    let w = (time_s - before.time_s) / (after.time_s - before.time_s);
    Some(LatLon {
        lat_deg: before.position.lat_deg + w * (after.position.lat_deg - before.position.lat_deg),
        lon_deg: before.position.lon_deg + w * (after.position.lon_deg - before.position.lon_deg),
    })
}

/// The forecast being prepared: the twin at the split, and the inputs after.
struct Forecast {
    twin: VesselTwin,
    split_s: f64,
    last_fix_s: f64,
    kinetic: Vec<(f64, ShaftSpeeds)>,
    dts: Vec<f64>,
}

/// The streaming analysis.
struct Analyzer<'a> {
    options: &'a AnalyzeOptions,
    twin: VesselTwin,
    first_s: Option<f64>,
    last_s: f64,
    samples: SamplesByKind,
    rejected: RejectedByReason,
    examples: Vec<RejectionExample>,
    quality_kinetic: QualityAccumulator,
    quality_seed: QualityAccumulator,
    kinetic_steps: u64,
    last_kinetic: Option<FaultReport>,
    last_state: Option<StateReport>,
    current: Option<CurrentResult>,
    seed_peak: Option<[f64; 2]>,
    seed_thruster_peak: [Option<f64>; 2],
    alarms: Vec<Alarm>,
    series: Option<Series>,
    forecast: Option<Forecast>,
    forecast_prop: (f64, f64, u32, Option<ShaftSpeeds>),
    recorder: Option<mcap::AnalyzeRecorder>,
}

/// At most this many alarms are listed.
const MAX_ALARMS: usize = 1000;

impl<'a> Analyzer<'a> {
    fn new(options: &'a AnalyzeOptions) -> Result<Self, AnalyzeError> {
        Ok(Self {
            options,
            twin: VesselTwin::new(options.profile.twin_config(options.config))?,
            first_s: None,
            last_s: f64::NAN,
            samples: SamplesByKind::default(),
            rejected: RejectedByReason::default(),
            examples: Vec::new(),
            quality_kinetic: QualityAccumulator::default(),
            quality_seed: QualityAccumulator::default(),
            kinetic_steps: 0,
            last_kinetic: None,
            last_state: None,
            current: None,
            seed_peak: None,
            seed_thruster_peak: [None, None],
            alarms: Vec::new(),
            series: options.keep_series.then(Series::default),
            forecast: None,
            forecast_prop: (0.0, 0.0, 0, None),
            recorder: match &options.mcap {
                Some(path) => Some(mcap::AnalyzeRecorder::create(path)?),
                None => None,
            },
        })
    }

    fn elapsed(&self, time_s: f64) -> f64 {
        time_s - self.first_s.unwrap_or(time_s)
    }

    fn example(&mut self, stage: &'static str, reason: &str, detail: String) {
        if !self
            .examples
            .iter()
            .any(|e| e.stage == stage && e.reason == reason)
        {
            self.examples.push(RejectionExample {
                stage,
                reason: reason.to_string(),
                detail,
            });
        }
    }

    fn split_time(&self) -> Option<f64> {
        let truth = self.options.truth.as_ref()?;
        let (first, last) = (truth.first()?, truth.last()?);
        Some((first.time_s + last.time_s) / 2.0)
    }

    fn on_fix(&mut self, fix: &GnssFix) {
        let out = match self.twin.on_gnss(fix) {
            Ok(out) => out,
            Err(r) => {
                *self
                    .rejected
                    .twin_fixes
                    .entry(r.reason().to_string())
                    .or_insert(0) += 1;
                self.example(
                    "twin_fixes",
                    r.reason(),
                    format!("fix at {}: {r}", time_text(fix.time_s)),
                );
                return;
            }
        };
        self.samples.fixes += 1;
        if let Some(r) = &mut self.recorder {
            r.step(&out);
        }
        let kinetic = out.state.source == FaultSource::Kinetic;
        self.record_quality(&out, kinetic);
        if kinetic {
            self.record_kinetic(&out);
        }
        let seed = self.record_seed_peaks();
        self.record_alarms(&out);
        self.record_series(fix, &out, kinetic, seed);
        self.last_state = Some(out.state);
        self.advance_forecast(fix);
    }

    /// The innovations of a step that ran, into its model's quality.
    fn record_quality(&mut self, out: &StepOutput, kinetic: bool) {
        let stepped = if kinetic {
            self.twin.kinetic_state().is_some_and(|k| k.steps > 0)
        } else {
            self.twin.seed_state().is_some_and(|s| s.steps > 0)
        };
        if kinetic {
            self.kinetic_steps += u64::from(stepped);
        }
        if !stepped {
            return;
        }
        let acc = if kinetic {
            &mut self.quality_kinetic
        } else {
            &mut self.quality_seed
        };
        acc.push(
            &out.innovation,
            &out.innovation_available,
            out.state.nis,
            out.state.nis_dof,
        );
    }

    /// The kinetic twin's faults and current.
    fn record_kinetic(&mut self, out: &StepOutput) {
        self.last_kinetic = Some(out.faults);
        if let (Some(c), Some(k)) = (out.state.current_mps, self.twin.kinetic_state()) {
            let var = (k.p[(idx::CURRENT_NORTH, idx::CURRENT_NORTH)]
                + k.p[(idx::CURRENT_EAST, idx::CURRENT_EAST)])
                / 2.0;
            self.current = Some(CurrentResult {
                north_mps: c[0],
                east_mps: c[1],
                speed_mps: c[0].hypot(c[1]),
                toward_deg: rad_to_compass_deg(c[1].atan2(c[0])),
                sigma_mps: var.max(0.0).sqrt(),
            });
        }
    }

    /// The seed method's input faults with their sigmas, and their peaks.
    fn record_seed_peaks(&mut self) -> Option<([f64; 2], [f64; 2])> {
        let seed = self.twin.seed_state().map(|s| {
            let sigma = s.fault_sigma();
            ([s.theta[0], s.theta[1]], [sigma[0], sigma[1]])
        });
        if let Some((theta, _)) = seed {
            let peak = self.seed_peak.get_or_insert([0.0; 2]);
            for i in 0..2 {
                peak[i] = peak[i].max(theta[i].abs());
            }
        }
        for (peak, v) in self
            .seed_thruster_peak
            .iter_mut()
            .zip(self.twin.seed_thruster_loss())
        {
            if let Some(v) = v.filter(|v| v.is_finite()) {
                *peak = Some(peak.map_or(v, |p: f64| p.max(v)));
            }
        }
        seed
    }

    /// The status changes, up to [`MAX_ALARMS`].
    fn record_alarms(&mut self, out: &StepOutput) {
        for c in &out.changes {
            if self.alarms.len() < MAX_ALARMS {
                self.alarms.push(Alarm {
                    time: time_text(c.time_s),
                    side: c.side.name(),
                    from: c.from.into(),
                    to: c.to.into(),
                    onset: time_text(c.onset_time_s),
                    confidence: c.confidence,
                    elapsed_s: self.elapsed(c.time_s),
                });
            }
        }
    }

    /// The track and the faults over time, when the series are kept.
    fn record_series(
        &mut self,
        fix: &GnssFix,
        out: &StepOutput,
        kinetic: bool,
        seed: Option<([f64; 2], [f64; 2])>,
    ) {
        let elapsed = self.elapsed(fix.time_s);
        let (Some(series), Some(frame)) = (self.series.as_mut(), self.twin.frame()) else {
            return;
        };
        let m = frame.to_local(fix.position);
        series.track.push(TrackPoint {
            elapsed_s: elapsed,
            measured: [m.north_m, m.east_m],
            estimated: [out.state.local.north_m, out.state.local.east_m],
        });
        let (theta, theta_sigma) = seed.unwrap_or(([f64::NAN; 2], [f64::NAN; 2]));
        let f = &out.faults;
        let kinetic_only = |v: [f64; 2]| if kinetic { v } else { [f64::NAN; 2] };
        series.faults.push(FaultPoint {
            elapsed_s: elapsed,
            kinetic,
            loss: kinetic_only(f.thrusters.map(|t| t.loss)),
            loss_sigma: kinetic_only(f.thrusters.map(|t| t.sigma)),
            input_faults: theta,
            input_fault_sigma: theta_sigma,
        });
    }

    /// The forecast from the middle of the run: started at the first fix
    /// past the truth's middle, then fed each interval's mean shaft speeds.
    fn advance_forecast(&mut self, fix: &GnssFix) {
        if let Some(fc) = self.forecast.as_mut() {
            let (sp, ss, n, last) = self.forecast_prop;
            let u = if n > 0 {
                Some(ShaftSpeeds {
                    port_radps: sp / f64::from(n),
                    starboard_radps: ss / f64::from(n),
                })
            } else {
                last
            };
            let dt = fix.time_s - fc.last_fix_s;
            fc.dts.push(dt);
            fc.kinetic.push((dt, u.unwrap_or_default()));
            fc.last_fix_s = fix.time_s;
        } else if let Some(split) = self.split_time()
            && fix.time_s >= split
        {
            self.forecast = Some(Forecast {
                twin: self.twin.clone(),
                split_s: fix.time_s,
                last_fix_s: fix.time_s,
                kinetic: Vec::new(),
                dts: Vec::new(),
            });
        }
        let last = self.forecast_prop.3;
        self.forecast_prop = (0.0, 0.0, 0, last);
    }

    fn on_propellers(&mut self, p: &PropellerSpeeds) {
        match self.twin.on_propellers(p) {
            Ok(()) => {
                self.samples.propellers += 1;
                let fp = &mut self.forecast_prop;
                fp.0 += p.port_radps;
                fp.1 += p.starboard_radps;
                fp.2 += 1;
                fp.3 = Some(ShaftSpeeds {
                    port_radps: p.port_radps,
                    starboard_radps: p.starboard_radps,
                });
            }
            Err(r) => {
                *self
                    .rejected
                    .twin_propellers
                    .entry(r.reason().to_string())
                    .or_insert(0) += 1;
                self.example(
                    "twin_propellers",
                    r.reason(),
                    format!("propeller sample at {}: {r}", time_text(p.time_s)),
                );
            }
        }
    }

    fn feed(&mut self, a: &Assembled) {
        if let Some(r) = &mut self.recorder {
            r.input(a);
        }
        match a {
            Assembled::Fix(fix) => self.on_fix(fix),
            Assembled::Propellers(p) => self.on_propellers(p),
            // The twin is driven by shaft speeds; thrust commands are counted
            // by the assembler and not used.
            Assembled::Thrust(_) => {}
        }
    }

    fn prediction(&mut self) -> Option<PredictionResult> {
        let fc = self.forecast.take()?;
        let truth = self.options.truth.as_ref()?;
        let frame = *fc.twin.frame()?;
        let (model, points): (&'static str, Vec<ForecastPoint>) = if fc.twin.kinetic_active() {
            (
                "kinetic",
                fc.twin.forecast_kinetic(fc.kinetic.iter().copied()),
            )
        } else {
            let u = fc.twin.seed_last_input();
            (
                "seed_method",
                fc.twin.forecast_seed(fc.dts.iter().map(|&dt| (dt, u))),
            )
        };
        let mut scored = Vec::new();
        for p in &points {
            let Some(t) = truth_at(truth, p.time_s) else {
                continue;
            };
            let tl = frame.to_local(t);
            scored.push(PredictionPoint {
                elapsed_s: self.elapsed(p.time_s),
                forecast: [p.local.north_m, p.local.east_m],
                sigma: p.position_sigma_m,
                truth: [tl.north_m, tl.east_m],
            });
        }
        if scored.is_empty() {
            return None;
        }
        let n = scored.len() as f64;
        let (mut sn, mut se, mut w1, mut w2) = (0.0, 0.0, 0usize, 0usize);
        for p in &scored {
            let e = [p.forecast[0] - p.truth[0], p.forecast[1] - p.truth[1]];
            sn += e[0] * e[0];
            se += e[1] * e[1];
            for (err, sigma) in e.iter().zip(p.sigma) {
                w1 += usize::from(err.abs() <= sigma);
                w2 += usize::from(err.abs() <= 2.0 * sigma);
            }
        }
        let last = scored[scored.len() - 1];
        let result = PredictionResult {
            model,
            start: time_text(fc.split_s),
            horizon_s: points.last().map_or(0.0, |p| p.time_s - fc.split_s),
            points: scored.len(),
            rmse_north_m: (sn / n).sqrt(),
            rmse_east_m: (se / n).sqrt(),
            rmse_position_m: ((sn + se) / n).sqrt(),
            final_error_m: (last.forecast[0] - last.truth[0])
                .hypot(last.forecast[1] - last.truth[1]),
            within_1_sigma: w1 as f64 / (2.0 * n),
            within_2_sigma: w2 as f64 / (2.0 * n),
        };
        if let Some(series) = self.series.as_mut() {
            series.prediction = scored;
        }
        Some(result)
    }
}

fn thruster_result(
    report: Option<&FaultReport>,
    i: usize,
    samples: u64,
    rejected: u64,
) -> ThrusterResult {
    match report {
        Some(f) => {
            let t = &f.thrusters[i];
            ThrusterResult {
                loss: finite(t.loss).map(|l| l.clamp(0.0, 1.0)),
                loss_raw: finite(t.loss),
                sigma: finite(t.sigma),
                excited: t.excited,
                status: t.decision.status.into(),
                onset: t.decision.onset_time_s.map(time_text),
                samples,
                rejected,
            }
        }
        None => ThrusterResult {
            loss: None,
            loss_raw: None,
            sigma: None,
            excited: false,
            status: ThrusterStatus::NotExcited.into(),
            onset: None,
            samples: 0,
            rejected,
        },
    }
}

/// The sources chosen; JSON lines carry whole fixes (no source choice), so
/// their source is `json` for what the fixes carried.
fn sources(
    format: LogFormat,
    assembled: &AssemblyCounts,
    position: Option<Source>,
    course: Option<Source>,
    heading: Option<Source>,
    yaw_rate: Option<Source>,
) -> Sources {
    let json = |present: bool, s: Option<Source>| {
        s.map(|s| s.to_string())
            .or_else(|| (format == LogFormat::JsonLines && present).then(|| "json".to_string()))
    };
    Sources {
        position: json(assembled.fixes > 0, position),
        course: json(assembled.fixes_with_course > 0, course),
        heading: json(assembled.fixes_with_heading > 0, heading),
        yaw_rate: json(assembled.fixes_with_yaw_rate > 0, yaw_rate),
    }
}

/// Analyses a log file.
pub fn analyze_path(path: &Path, options: &AnalyzeOptions) -> Result<Analysis, AnalyzeError> {
    // An MCAP recording is read as its input channels.
    let input = twin_wire::mcap::open_log_file(path).map_err(|source| AnalyzeError::Open {
        path: path.to_path_buf(),
        source,
    })?;
    analyze_reader(input, &path.display().to_string(), options).map_err(|e| match e {
        AnalyzeError::Log { source, .. } => AnalyzeError::Log {
            path: path.to_path_buf(),
            source,
        },
        e => e,
    })
}

/// Analyses a log from any reader; `name` is what the report calls it.
pub fn analyze_reader<R: BufRead>(
    input: R,
    name: &str,
    options: &AnalyzeOptions,
) -> Result<Analysis, AnalyzeError> {
    let mut reader = LogReader::open(input, options.read).map_err(|source| AnalyzeError::Log {
        path: PathBuf::from(name),
        source,
    })?;
    let format = reader.format();
    let mut assembler = FixAssembler::new(AssemblerConfig {
        position_source: options.source,
        ..AssemblerConfig::default()
    });
    let mut a = Analyzer::new(options)?;
    a.read_all(&mut reader, &mut assembler);
    if let Some(r) = a.recorder.take() {
        r.finish()?;
    }
    let read = reader.stats().clone();
    let assembled = AssemblyCounts::from(assembler.stats());
    for (kind, n) in read.rejected_by_kind() {
        a.rejected.reader.insert(kind.name().to_string(), n);
    }
    let (position, course, heading) = assembler.sources();
    let span = a.first_s.map(|start_s| Span {
        start: time_text(start_s),
        end: time_text(a.last_s),
        duration_s: a.last_s - start_s,
        start_s,
    });
    let prediction = a.prediction();
    let truth = options
        .truth
        .as_ref()
        .map(|t| truth_comparison(t, a.last_kinetic.as_ref()));
    a.keep_truth_series();
    let twin_propellers_rejected: u64 = a.rejected.twin_propellers.values().sum();
    let thrusters = a.thrusters(twin_propellers_rejected);
    let observable = thrusters.observable;
    let model = if observable {
        Some("kinetic")
    } else if a.last_state.is_some() {
        Some("seed_method")
    } else {
        None
    };
    let reader_rejected = read.total_rejected();
    let twin_rejected: u64 = a.rejected.twin_fixes.values().sum::<u64>() + twin_propellers_rejected;
    Ok(Analysis {
        schema: SCHEMA,
        log: name.to_string(),
        profile: options.profile.identity(),
        format: format_name(format),
        span,
        sources: sources(
            format,
            &assembled,
            position,
            course,
            heading,
            assembler.yaw_rate_source(),
        ),
        samples: a.samples.fixes + a.samples.propellers,
        rejected: reader_rejected + twin_rejected,
        samples_by_kind: a.samples,
        rejected_by_reason: a.rejected.clone(),
        first_rejections: a.examples.clone(),
        read,
        assembled,
        model,
        thrusters,
        alarms: a.alarms.clone(),
        current: a.current,
        seed_method: a.seed_method(),
        quality: QualityByModel {
            kinetic: a.quality_kinetic.summary(),
            seed_method: a.quality_seed.summary(),
        },
        final_state: a.last_state.map(final_state),
        truth,
        prediction,
        series: a.series.take(),
    })
}

/// The final loss estimates against the truth's last.
fn truth_comparison(t: &[TruthPoint], last_kinetic: Option<&FaultReport>) -> TruthComparison {
    let loss = t.last().and_then(|p| p.loss).map(|l| PortStarboard {
        port: l[0],
        starboard: l[1],
    });
    let loss_error = match (loss, last_kinetic) {
        (Some(l), Some(f)) => Some(PortStarboard {
            port: f.thrusters[0].loss - l.port,
            starboard: f.thrusters[1].loss - l.starboard,
        }),
        _ => None,
    };
    TruthComparison {
        samples: t.len(),
        loss,
        loss_error,
    }
}

/// The state at the last fix, as reported.
fn final_state(s: StateReport) -> FinalState {
    FinalState {
        time: time_text(s.time_s),
        lat_deg: s.position.lat_deg,
        lon_deg: s.position.lon_deg,
        north_m: s.local.north_m,
        east_m: s.local.east_m,
        sigma_north_m: s.position_sigma_m[0],
        sigma_east_m: s.position_sigma_m[1],
        sog_mps: s.sog_mps,
        cog_rad: s.cog_rad,
        heading_rad: s.heading_rad,
        model: match s.source {
            FaultSource::Kinetic => "kinetic",
            FaultSource::SeedMethod => "seed_method",
        },
    }
}

impl Analyzer<'_> {
    /// Reads the whole log through the assembler into the twin.
    fn read_all<R: BufRead>(&mut self, reader: &mut LogReader<R>, assembler: &mut FixAssembler) {
        let mut out: Vec<Assembled> = Vec::new();
        loop {
            match reader.next() {
                Some(Ok(record)) => {
                    if self.first_s.is_none() {
                        self.first_s = Some(record.time_s);
                    }
                    self.last_s = record.time_s;
                    assembler.push(record, &mut out);
                }
                Some(Err(rejection)) => {
                    let kind = rejection.reason.kind().name();
                    self.example("reader", kind, rejection.to_string());
                    continue;
                }
                None => {
                    assembler.finish(&mut out);
                    for item in out.drain(..) {
                        self.feed(&item);
                    }
                    break;
                }
            }
            for item in out.drain(..) {
                self.feed(&item);
            }
        }
    }

    /// The truth's track and losses beside the estimates, when the series
    /// are kept.
    fn keep_truth_series(&mut self) {
        if let (Some(series), Some(t), Some(frame)) = (
            self.series.as_mut(),
            self.options.truth.as_ref(),
            self.twin.frame(),
        ) {
            let t0 = self.first_s.unwrap_or(0.0);
            series.truth_track = t
                .iter()
                .map(|p| {
                    let l: NorthEast = frame.to_local(p.position);
                    (p.time_s - t0, [l.north_m, l.east_m])
                })
                .collect();
            series.truth_loss = t
                .iter()
                .filter_map(|p| p.loss.map(|l| (p.time_s - t0, l)))
                .collect();
        }
    }

    /// The thrusters' results from the last kinetic report.
    fn thrusters(&self, twin_propellers_rejected: u64) -> ThrustersResult {
        let observable = self.last_kinetic.is_some();
        let report = self.last_kinetic.as_ref();
        ThrustersResult {
            observable,
            time: report.map(|f| time_text(f.time_s)),
            status: report
                .map_or(ThrusterStatus::NotExcited, |f| f.status)
                .into(),
            onset: report
                .and_then(|f| {
                    f.thrusters
                        .iter()
                        .filter_map(|t| t.decision.onset_time_s)
                        .reduce(f64::min)
                })
                .map(time_text),
            effectiveness_ratio: report
                .map(|f| f.effectiveness_ratio())
                .filter(|(v, s)| v.is_finite() && s.is_finite())
                .map(|(value, sigma)| Ratio { value, sigma }),
            profile_mismatch: self
                .twin
                .profile_mismatch()
                .filter(|_| observable)
                .as_ref()
                .map(ProfileMismatchMessage::from),
            note: if observable {
                KINETIC_NOTE
            } else {
                NOT_OBSERVABLE_NOTE
            },
            port: thruster_result(report, 0, self.kinetic_steps, twin_propellers_rejected),
            starboard: thruster_result(report, 1, self.kinetic_steps, twin_propellers_rejected),
        }
    }

    /// The seed method's input faults and their peaks.
    fn seed_method(&self) -> SeedMethodResult {
        let seed_state = self.twin.seed_state();
        SeedMethodResult {
            input_faults: seed_state.map(|s| [s.theta[0], s.theta[1]]),
            input_fault_sigma: seed_state.map(|s| {
                let sg = s.fault_sigma();
                [sg[0], sg[1]]
            }),
            input_fault_peak: self.seed_peak,
            thruster_values: self.twin.seed_thruster_loss(),
            thruster_peak: self.seed_thruster_peak,
            note: SEED_NOTE,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sources_parse() {
        assert_eq!(parse_source("best").unwrap(), SourceChoice::Best);
        assert_eq!(
            parse_source("25").unwrap(),
            SourceChoice::Fixed(Source::N2k(25))
        );
        assert_eq!(
            parse_source("n2k:52").unwrap(),
            SourceChoice::Fixed(Source::N2k(52))
        );
        assert_eq!(
            parse_source("gp").unwrap(),
            SourceChoice::Fixed(Source::Nmea(Talker::GP))
        );
        assert_eq!(
            parse_source("json").unwrap(),
            SourceChoice::Fixed(Source::Json)
        );
        assert!(parse_source("256").is_err());
        assert!(parse_source("gps").is_err());
    }

    #[test]
    fn series_stay_bounded() {
        let mut d = Decimated::default();
        for i in 0..100_000 {
            d.push(i);
        }
        assert!(d.items().len() < MAX_SERIES_POINTS);
        assert!(d.items().len() > MAX_SERIES_POINTS / 4);
        // Evenly spaced from the start.
        let step = d.items()[1] - d.items()[0];
        assert!(d.items().windows(2).all(|w| w[1] - w[0] == step));
        assert_eq!(d.items()[0], 0);
    }
}
