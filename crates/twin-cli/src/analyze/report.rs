//! The report of `twin analyze`: the types of [`Analysis`], which
//! serialise to the JSON schema documented in [`crate::analyze`], and the
//! plot data kept beside them.

use std::collections::BTreeMap;

use serde::Serialize;
use twin_wire::assemble::AssembleStats;
use twin_wire::outputs::{ProfileMismatchMessage, ThrusterStatusName};
use twin_wire::read::ReadStats;

use crate::quality::Quality;

use super::MAX_SERIES_POINTS;

/// The span of the records read.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Span {
    /// First record time.
    pub start: String,
    /// Last record time.
    pub end: String,
    /// `end - start`, s.
    pub duration_s: f64,
    /// First record time, epoch seconds.
    #[serde(skip)]
    pub start_s: f64,
}

/// The sources the assembler chose.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Sources {
    /// Positions.
    pub position: Option<String>,
    /// Course and speed.
    pub course: Option<String>,
    /// Heading.
    pub heading: Option<String>,
    /// Yaw rate (a rate gyro, a rate of turn).
    pub yaw_rate: Option<String>,
}

/// Inputs the twin used, by kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Default)]
pub struct SamplesByKind {
    /// GNSS fixes accepted.
    pub fixes: u64,
    /// Propeller-speed samples accepted.
    pub propellers: u64,
}

/// Rejections by stage and reason.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Default)]
pub struct RejectedByReason {
    /// The log reader's.
    pub reader: BTreeMap<String, u64>,
    /// The twin's, of GNSS fixes.
    pub twin_fixes: BTreeMap<String, u64>,
    /// The twin's, of propeller samples.
    pub twin_propellers: BTreeMap<String, u64>,
}

/// The first rejection of one reason.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct RejectionExample {
    /// `reader`, `twin_fixes` or `twin_propellers`.
    pub stage: &'static str,
    /// The reason's name.
    pub reason: String,
    /// What and where.
    pub detail: String,
}

/// What the assembler did (`twin_wire::assemble::AssembleStats`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Default)]
pub struct AssemblyCounts {
    /// Fixes emitted.
    pub fixes: u64,
    /// Fixes with a course or speed.
    pub fixes_with_course: u64,
    /// Fixes with a heading.
    pub fixes_with_heading: u64,
    /// Fixes with a yaw rate (a rate gyro, a rate of turn).
    pub fixes_with_yaw_rate: u64,
    /// Propeller pairs.
    pub propeller_pairs: u64,
    /// Thrust commands (the twin takes shaft speeds; these are not used).
    pub thrust_commands: u64,
    /// Positions of sources other than the chosen one.
    pub positions_other_sources: u64,
    /// Positions not after the previous fix (the second position of a burst).
    pub positions_not_after_previous: u64,
    /// Positions dropped as re-sent copies.
    pub positions_repeated: u64,
    /// Course/speed records of other sources.
    pub courses_other_sources: u64,
    /// Course/speed records never joined to a fix.
    pub courses_unused: u64,
    /// Headings of other sources.
    pub headings_other_sources: u64,
    /// Propeller samples replaced before pairing.
    pub propeller_unpaired: u64,
    /// Outputs older than one already emitted.
    pub out_of_order: u64,
}

impl From<&AssembleStats> for AssemblyCounts {
    fn from(s: &AssembleStats) -> Self {
        Self {
            fixes: s.fixes,
            fixes_with_course: s.fixes_with_course,
            fixes_with_heading: s.fixes_with_heading,
            fixes_with_yaw_rate: s.fixes_with_yaw_rate,
            propeller_pairs: s.propeller_pairs,
            thrust_commands: s.thrusts,
            positions_other_sources: s.positions_other_sources,
            positions_not_after_previous: s.positions_not_after_previous,
            positions_repeated: s.positions_repeated,
            courses_other_sources: s.courses_other_sources,
            courses_unused: s.courses_unused,
            headings_other_sources: s.headings_other_sources,
            propeller_unpaired: s.propeller_unpaired,
            out_of_order: s.out_of_order,
        }
    }
}

/// One thruster's final estimate.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ThrusterResult {
    /// Final loss clamped to 0..1; null when not observable.
    pub loss: Option<f64>,
    /// The raw final estimate.
    pub loss_raw: Option<f64>,
    /// Its standard deviation.
    pub sigma: Option<f64>,
    /// Whether the data of the filter's memory could tell it at the end.
    pub excited: bool,
    /// The decision.
    pub status: ThrusterStatusName,
    /// Onset of the current suspect/fault episode.
    pub onset: Option<String>,
    /// Fixes the extended twin stepped on.
    pub samples: u64,
    /// Propeller samples the twin refused.
    pub rejected: u64,
}

/// The port/starboard effectiveness ratio.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Ratio {
    /// `(1 - loss_port) / (1 - loss_starboard)`.
    pub value: f64,
    /// Its standard deviation.
    pub sigma: f64,
}

/// Both thrusters.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ThrustersResult {
    /// Whether thrust loss could be estimated (propeller speeds in the log).
    pub observable: bool,
    /// Time of the estimate.
    pub time: Option<String>,
    /// The worst status.
    pub status: ThrusterStatusName,
    /// Onset of the earliest current episode.
    pub onset: Option<String>,
    /// What a straight run can tell even when the losses are not excited.
    pub effectiveness_ratio: Option<Ratio>,
    /// At the end of the log, why the comparison of the propellers is
    /// withheld, where the profile does not describe the vessel (`null`
    /// where it does).
    pub profile_mismatch: Option<ProfileMismatchMessage>,
    /// What the figures are.
    pub note: &'static str,
    /// Port.
    pub port: ThrusterResult,
    /// Starboard.
    pub starboard: ThrusterResult,
}

/// A status change.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Alarm {
    /// When declared.
    pub time: String,
    /// `port` or `starboard`.
    pub side: &'static str,
    /// Status before.
    pub from: ThrusterStatusName,
    /// Status after.
    pub to: ThrusterStatusName,
    /// When the evidence appeared.
    pub onset: String,
    /// How sure.
    pub confidence: f64,
    /// Seconds since the start of the log.
    #[serde(skip)]
    pub elapsed_s: f64,
}

/// The water current estimate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CurrentResult {
    /// North, m/s.
    pub north_mps: f64,
    /// East, m/s.
    pub east_mps: f64,
    /// Speed, m/s.
    pub speed_mps: f64,
    /// Direction the water flows toward, degrees true.
    pub toward_deg: f64,
    /// Standard deviation per component (RMS of north and east), m/s.
    pub sigma_mps: f64,
}

/// The seed method's figures.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SeedMethodResult {
    /// Final input faults `[theta_a, theta_r]`.
    pub input_faults: Option<[f64; 2]>,
    /// Their standard deviations.
    pub input_fault_sigma: Option<[f64; 2]>,
    /// Largest magnitude of each over the run.
    pub input_fault_peak: Option<[f64; 2]>,
    /// The seed's step 4 per-thruster values at the end `[port, starboard]`
    /// (null where the thrust was too small to divide by).
    pub thruster_values: [Option<f64>; 2],
    /// Their peaks over the run.
    pub thruster_peak: [Option<f64>; 2],
    /// What these are.
    pub note: &'static str,
}

/// The seed method's note.
pub const SEED_NOTE: &str = "The seed's method (GNSS-derived inputs, kinematic AEKF, step 4 with the Otter's parameters), kept for comparison: its faults are not a measurement of thrust loss.";

/// Quality per estimator.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct QualityByModel {
    /// The extended twin.
    pub kinetic: Option<Quality>,
    /// The seed method's kinematic filter (only while it reported).
    pub seed_method: Option<Quality>,
}

/// The last state estimate.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FinalState {
    /// Time.
    pub time: String,
    /// Latitude, deg.
    pub lat_deg: f64,
    /// Longitude, deg.
    pub lon_deg: f64,
    /// North of the first fix, m.
    pub north_m: f64,
    /// East of the first fix, m.
    pub east_m: f64,
    /// North sigma, m.
    pub sigma_north_m: f64,
    /// East sigma, m.
    pub sigma_east_m: f64,
    /// Speed over ground, m/s.
    pub sog_mps: f64,
    /// Course over ground, rad.
    pub cog_rad: f64,
    /// Heading, rad, where estimated.
    pub heading_rad: Option<f64>,
    /// `kinetic` or `seed_method`.
    pub model: &'static str,
}

/// A pair for the truth comparison.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PortStarboard {
    /// Port.
    pub port: f64,
    /// Starboard.
    pub starboard: f64,
}

/// The comparison with the truth file.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TruthComparison {
    /// Truth samples read.
    pub samples: usize,
    /// The true losses at the end.
    pub loss: Option<PortStarboard>,
    /// Estimate minus truth, where both exist.
    pub loss_error: Option<PortStarboard>,
}

/// A forecast from the middle of the run scored against the truth.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PredictionResult {
    /// `kinetic` (through the recorded shaft speeds) or `seed_method`
    /// (inputs held).
    pub model: &'static str,
    /// Start of the forecast.
    pub start: String,
    /// Horizon, s.
    pub horizon_s: f64,
    /// Points scored.
    pub points: usize,
    /// RMS north error, m.
    pub rmse_north_m: f64,
    /// RMS east error, m.
    pub rmse_east_m: f64,
    /// RMS horizontal error, m.
    pub rmse_position_m: f64,
    /// Horizontal error at the horizon, m.
    pub final_error_m: f64,
    /// Fraction of north/east errors within their 1-sigma band.
    pub within_1_sigma: f64,
    /// Fraction within 2 sigma.
    pub within_2_sigma: f64,
}

/// One point of a plotted track, in the twin's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackPoint {
    /// Seconds since the start of the log.
    pub elapsed_s: f64,
    /// The fix, north/east, m.
    pub measured: [f64; 2],
    /// The estimate after the fix.
    pub estimated: [f64; 2],
}

/// One point of a plotted fault series.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FaultPoint {
    /// Seconds since the start of the log.
    pub elapsed_s: f64,
    /// Which estimator.
    pub kinetic: bool,
    /// Losses `[port, starboard]` (extended twin), NaN otherwise.
    pub loss: [f64; 2],
    /// Their sigmas.
    pub loss_sigma: [f64; 2],
    /// Seed input faults `[a, r]`.
    pub input_faults: [f64; 2],
    /// Their sigmas.
    pub input_fault_sigma: [f64; 2],
}

/// A scored forecast point, in the twin's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PredictionPoint {
    /// Seconds since the start of the log.
    pub elapsed_s: f64,
    /// Forecast north/east, m.
    pub forecast: [f64; 2],
    /// Its sigmas, m.
    pub sigma: [f64; 2],
    /// Truth north/east, m.
    pub truth: [f64; 2],
}

/// A series kept with at most [`MAX_SERIES_POINTS`] points.
#[derive(Debug, Clone, PartialEq)]
pub struct Decimated<T> {
    items: Vec<T>,
    stride: usize,
    seen: usize,
}

impl<T> Default for Decimated<T> {
    fn default() -> Self {
        Self {
            items: Vec::new(),
            stride: 1,
            seen: 0,
        }
    }
}

impl<T> Decimated<T> {
    /// Offers a point; keeps every `stride`-th.
    pub fn push(&mut self, item: T) {
        if self.seen.is_multiple_of(self.stride) {
            self.items.push(item);
            if self.items.len() >= MAX_SERIES_POINTS {
                let mut i = 0;
                self.items.retain(|_| {
                    i += 1;
                    i % 2 == 1
                });
                self.stride *= 2;
            }
        }
        self.seen += 1;
    }

    /// The points kept.
    pub fn items(&self) -> &[T] {
        &self.items
    }
}

/// What the plots need.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Series {
    /// The track.
    pub track: Decimated<TrackPoint>,
    /// The fault estimates.
    pub faults: Decimated<FaultPoint>,
    /// The truth over the log, in the twin's frame: (elapsed s, north, east).
    pub truth_track: Vec<(f64, [f64; 2])>,
    /// The true losses over time: (elapsed s, [port, starboard]).
    pub truth_loss: Vec<(f64, [f64; 2])>,
    /// The scored forecast.
    pub prediction: Vec<PredictionPoint>,
}

/// Everything `twin analyze` found; serialises to the JSON schema of the
/// module doc.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Analysis {
    /// [`super::SCHEMA`].
    pub schema: &'static str,
    /// The log, as given.
    pub log: String,
    /// The vessel profile the twin ran on, `name@fingerprint`.
    pub profile: String,
    /// `nmea0183`, `n2k` or `json_lines`.
    pub format: &'static str,
    /// Span of the records.
    pub span: Option<Span>,
    /// Sources chosen.
    pub sources: Sources,
    /// Inputs used.
    pub samples: u64,
    /// Inputs refused (reader + twin).
    pub rejected: u64,
    /// Inputs used by kind.
    pub samples_by_kind: SamplesByKind,
    /// Refusals by stage and reason.
    pub rejected_by_reason: RejectedByReason,
    /// The first refusal of each reason.
    pub first_rejections: Vec<RejectionExample>,
    /// The reader's counts.
    pub read: ReadStats,
    /// The assembler's counts.
    pub assembled: AssemblyCounts,
    /// The estimator of the thruster figures.
    pub model: Option<&'static str>,
    /// Thruster faults.
    pub thrusters: ThrustersResult,
    /// Status changes.
    pub alarms: Vec<Alarm>,
    /// Water current.
    pub current: Option<CurrentResult>,
    /// The seed method.
    pub seed_method: SeedMethodResult,
    /// Consistency per estimator.
    pub quality: QualityByModel,
    /// The last state.
    pub final_state: Option<FinalState>,
    /// The truth comparison.
    pub truth: Option<TruthComparison>,
    /// The forecast scored.
    pub prediction: Option<PredictionResult>,
    /// Plot data (not serialised).
    #[serde(skip)]
    pub series: Option<Series>,
}
