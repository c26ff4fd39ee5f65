//! Turns a stream of [`Record`]s into the estimator's inputs, in time order:
//! [`GnssFix`]es (a position with the freshest course/speed and heading) and
//! [`PropellerSpeeds`] (port and starboard paired), streaming.
//!
//! # Fixes
//! Every position record of the chosen position source opens a fix. The fix
//! is completed, and emitted, when a record with a later time arrives (or at
//! the end), so measurements stamped with the very same time as the position
//! (an NMEA burst's untimed VTG/HDT) still join it. It takes the latest
//! course/speed and heading of their chosen sources only if they are new
//! since the previous fix and at most `max_course_age_s` / `max_heading_age_s`
//! (default 1 s) from the position's time: a 3.6 Hz COG is used by one 8 Hz
//! position, not repeated on the next ones. Fix times strictly increase; a
//! position not after the previous fix is dropped and counted.
//!
//! # Re-sent positions
//! Some receivers send each fix twice: in aava-n2k.data source 160 sends a
//! position in PGN 129025 and the very same coordinates again in 129029 about
//! 0.5 s later (129029's own time field shows the fix is the earlier one). With
//! `drop_repeated_positions` (the default) an NMEA 2000 position equal to the
//! previous position of its source (within 1e-9 deg, about 0.1 mm) and less
//! than `repeat_window_s` (2 s) after it is taken as the same fix re-sent:
//! dropped and counted, so it neither doubles the fix rate nor carries a
//! stale time. NMEA 2000 positions resolve 1e-7 deg (1 cm), so equal ones
//! mean a re-send or a vessel at rest; the price is that a receiver at rest
//! reporting identical positions gives a fix only every `repeat_window_s`.
//! NMEA 0183 positions (often 1e-3 minute, 2 m) repeat legitimately at low
//! speed and are never dropped this way.
//!
//! # Which source
//! Logs often have several GNSS receivers (the Furuno trials: source 25, a
//! ZEUS SR-16 at 8 Hz, and source 52, a satellite compass at 5 Hz). With
//! [`SourceChoice::Best`] (the default) the assembler holds back the first
//! `decision_window_s` seconds (default 5 s) of records, then picks,
//! deterministically:
//! - positions: the source with the best fix method seen ([`FixMethod::rank`]:
//!   RTK fixed > RTK float > precise > DGNSS > GNSS > unknown > estimated),
//!   then the most positions (the higher rate), then the lowest source;
//! - course/speed: the position source if it gave any, else the source
//!   with the most, then the lowest;
//! - heading: the source with the most headings (true headings, and
//!   attitude yaw when `heading_from_attitude`), then the lowest;
//! - yaw rate: the source and kind (a gyro's yaw rate, a rate of turn)
//!   with the most records, then the lowest source, then the gyro's: a
//!   compass that sends a damped rate of turn beside its gyro's rate has
//!   only one of them used.
//!
//! It then replays the held records in order. A kind with no source in the
//! window locks onto the first source that sends it later.
//! [`SourceChoice::Fixed`] names the position source instead.
//!
//! # Logs without positions
//! With `fixes_at_course` the assembler builds the time line of a log that
//! has course/speed but no positions (the Furuno trials without PGN 129025):
//! positions are ignored, and every course/speed record of the chosen
//! course source opens a fix at its own time whose position is not measured
//! (NaN). Heading and yaw rate join it as they join a position fix.
//!
//! # Propellers
//! A port and a starboard speed within `pair_window_s` (default 0.25 s) of
//! each other make one [`PropellerSpeeds`] at the later time; each sample is
//! used once; a sample replaced before it was paired is counted as unpaired.
//! JSON fixes, propeller pairs and thrusts pass straight through.

use std::collections::VecDeque;

use twin_core::geodesy::{LatLon, wrap_two_pi};
use twin_core::sample::{GnssFix, PropellerSpeeds, Side};

use crate::measurement::{FixMethod, Measurement, Record, Source, ThrustCommand};

/// The most records held while choosing sources (a pathological stream with
/// many records at one time cannot grow the window past this).
pub const MAX_WINDOW_RECORDS: usize = 100_000;

/// How the position source is chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SourceChoice {
    /// Decided on the first seconds of data (see the module doc).
    #[default]
    Best,
    /// Only positions of this source.
    Fixed(Source),
}

/// Settings of the assembler.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AssemblerConfig {
    /// Which source gives positions.
    pub position_source: SourceChoice,
    /// Seconds of data looked at to choose sources.
    pub decision_window_s: f64,
    /// Oldest course/speed joined to a fix, seconds from the fix time.
    pub max_course_age_s: f64,
    /// Oldest heading joined to a fix, seconds from the fix time.
    pub max_heading_age_s: f64,
    /// Largest time between a port and a starboard speed that are paired, s.
    pub pair_window_s: f64,
    /// Use attitude yaw (PGN 127257) as a true heading.
    pub heading_from_attitude: bool,
    /// Oldest yaw rate joined to a fix, seconds from the fix time.
    pub max_yaw_rate_age_s: f64,
    /// Drop a position equal to the previous one of its source (a re-sent fix).
    pub drop_repeated_positions: bool,
    /// How long after a position an equal one counts as re-sent, seconds.
    pub repeat_window_s: f64,
    /// Ignore positions and open a fix, its position NaN (not measured), at
    /// every course/speed record: the time line of a log without positions.
    pub fixes_at_course: bool,
}

impl Default for AssemblerConfig {
    fn default() -> Self {
        Self {
            position_source: SourceChoice::Best,
            decision_window_s: 5.0,
            max_course_age_s: 1.0,
            max_heading_age_s: 1.0,
            pair_window_s: 0.25,
            heading_from_attitude: true,
            max_yaw_rate_age_s: 0.5,
            drop_repeated_positions: true,
            repeat_window_s: 2.0,
            fixes_at_course: false,
        }
    }
}

/// One input of the estimator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Assembled {
    /// A GNSS fix.
    Fix(GnssFix),
    /// Both propeller speeds.
    Propellers(PropellerSpeeds),
    /// Both propeller thrusts.
    Thrust(ThrustCommand),
}

impl Assembled {
    /// Its time, seconds since the epoch.
    pub fn time_s(&self) -> f64 {
        match self {
            Assembled::Fix(f) => f.time_s,
            Assembled::Propellers(p) => p.time_s,
            Assembled::Thrust(t) => t.time_s,
        }
    }
}

/// What the assembler did.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct AssembleStats {
    /// Fixes emitted.
    pub fixes: u64,
    /// Fixes that carry a course or speed.
    pub fixes_with_course: u64,
    /// Fixes that carry a heading.
    pub fixes_with_heading: u64,
    /// Positions of sources other than the chosen one (not used).
    pub positions_other_sources: u64,
    /// Positions dropped because they were not after the previous fix.
    pub positions_not_after_previous: u64,
    /// Positions dropped as a re-sent copy of the previous one.
    pub positions_repeated: u64,
    /// Course/speed records of other sources (not used).
    pub courses_other_sources: u64,
    /// Course/speed records never joined to a fix (too old, or replaced).
    pub courses_unused: u64,
    /// Heading records of other sources (not used).
    pub headings_other_sources: u64,
    /// Fixes that carry a yaw rate.
    pub fixes_with_yaw_rate: u64,
    /// Yaw-rate records of other sources, or of the chosen source's other
    /// kind (a compass that sends both a damped rate of turn and its
    /// gyro's rate), not used.
    pub yaw_rates_other_sources: u64,
    /// Propeller pairs emitted (paired here or passed through).
    pub propeller_pairs: u64,
    /// Propeller samples replaced before they were paired.
    pub propeller_unpaired: u64,
    /// Thrust commands passed through.
    pub thrusts: u64,
    /// Outputs dropped because they were older than one already emitted.
    pub out_of_order: u64,
}

#[derive(Debug, Clone, Copy, Default)]
struct Tally {
    positions: u64,
    best_rank: Option<i8>,
    courses: u64,
    headings: u64,
    /// Rates of turn and gyro yaw rates, counted apart.
    yaw_rates: [u64; 2],
}

#[derive(Debug, Clone, Copy)]
struct Fresh<T> {
    time_s: f64,
    value: T,
}

/// Of `candidates` with a count (a score's second part) above zero, the
/// first with the highest score `(rank, count)`: a later one wins only by
/// beating it.
fn first_best<K>(candidates: impl Iterator<Item = (K, (i8, u64))>) -> Option<K> {
    candidates
        .filter(|(_, score)| score.1 > 0)
        .fold(None::<(K, (i8, u64))>, |best, (k, score)| match best {
            Some((_, b)) if b >= score => best,
            _ => Some((k, score)),
        })
        .map(|(k, _)| k)
}

/// The two kinds of yaw-rate record, counted apart when a source's is
/// chosen: a compass can send a damped rate of turn beside its gyro's
/// rate, and a fix must not take one then the other.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum YawRateKind {
    /// [`Measurement::RateOfTurn`].
    RateOfTurn = 0,
    /// [`Measurement::GyroRates`]' yaw rate.
    Gyro = 1,
}

impl YawRateKind {
    /// In the order that wins a tie: a gyro's own rate before a rate of
    /// turn, which a sensor may have damped.
    const ALL: [YawRateKind; 2] = [YawRateKind::Gyro, YawRateKind::RateOfTurn];
}

/// The streaming assembler. Feed records with [`Self::push`], call
/// [`Self::finish`] at the end; or use [`assemble`] on an iterator.
#[derive(Debug, Clone)]
pub struct FixAssembler {
    config: AssemblerConfig,
    deciding: bool,
    window: VecDeque<Record>,
    window_end_s: Option<f64>,
    position_source: Option<Source>,
    course_source: Option<Source>,
    heading_source: Option<Source>,
    /// The source and kind of yaw rates used (see [`YawRateKind`]).
    yaw_rate_stream: Option<(Source, YawRateKind)>,
    pending: Option<GnssFix>,
    /// The latest accepted position of the position source: time, lat, lon.
    last_position: Option<(f64, f64, f64)>,
    course: Option<Fresh<(Option<f64>, Option<f64>)>>,
    heading: Option<Fresh<f64>>,
    yaw_rate: Option<Fresh<f64>>,
    port: Option<Fresh<f64>>,
    starboard: Option<Fresh<f64>>,
    last_fix_s: Option<f64>,
    last_out_s: Option<f64>,
    stats: AssembleStats,
}

impl FixAssembler {
    /// An assembler with `config`.
    pub fn new(config: AssemblerConfig) -> Self {
        let position_source = match config.position_source {
            SourceChoice::Best => None,
            SourceChoice::Fixed(s) => Some(s),
        };
        Self {
            config,
            deciding: true,
            window: VecDeque::new(),
            window_end_s: None,
            position_source,
            course_source: None,
            heading_source: None,
            yaw_rate_stream: None,
            pending: None,
            last_position: None,
            course: None,
            heading: None,
            yaw_rate: None,
            port: None,
            starboard: None,
            last_fix_s: None,
            last_out_s: None,
            stats: AssembleStats::default(),
        }
    }

    /// The counts so far.
    pub fn stats(&self) -> &AssembleStats {
        &self.stats
    }

    /// The chosen source of yaw rates, once known: the source and kind
    /// (rate of turn, gyro yaw rate) that sent the most; only that kind of
    /// the source is used.
    pub fn yaw_rate_source(&self) -> Option<Source> {
        self.yaw_rate_stream.map(|(source, _)| source)
    }

    /// The chosen sources (position, course/speed, heading), once known.
    pub fn sources(&self) -> (Option<Source>, Option<Source>, Option<Source>) {
        (
            self.position_source,
            self.course_source,
            self.heading_source,
        )
    }

    /// Records held back while choosing sources (bounded by the window).
    pub fn held_records(&self) -> usize {
        self.window.len()
    }

    /// Takes one record; appends any inputs it completes to `out`.
    pub fn push(&mut self, record: Record, out: &mut Vec<Assembled>) {
        if self.deciding {
            let end = *self
                .window_end_s
                .get_or_insert(record.time_s + self.config.decision_window_s);
            if record.time_s < end && self.window.len() < MAX_WINDOW_RECORDS {
                self.window.push_back(record);
                return;
            }
            self.decide(out);
        }
        self.process(record, out);
    }

    /// A live stream has gone quiet: emits the pending fix now rather than
    /// when the next record comes (a 1 Hz receiver's fix would otherwise
    /// wait a second). Nothing while the sources are still being chosen.
    /// What arrives later with the same time as that fix no longer joins it.
    pub fn flush_idle(&mut self, out: &mut Vec<Assembled>) {
        if !self.deciding {
            self.flush(out);
        }
    }

    /// Ends the stream: decides if still deciding, emits the last fix.
    pub fn finish(&mut self, out: &mut Vec<Assembled>) {
        if self.deciding {
            self.decide(out);
        }
        self.flush(out);
    }

    fn heading_of(&self, m: &Measurement) -> Option<f64> {
        match *m {
            Measurement::Heading { heading_rad } => Some(heading_rad),
            Measurement::Attitude {
                yaw_rad: Some(yaw), ..
            } if self.config.heading_from_attitude => Some(wrap_two_pi(yaw)),
            _ => None,
        }
    }

    fn yaw_rate_of(m: &Measurement) -> Option<(f64, YawRateKind)> {
        match *m {
            Measurement::RateOfTurn { radps } => Some((radps, YawRateKind::RateOfTurn)),
            Measurement::GyroRates {
                yaw_radps: Some(r), ..
            } => Some((r, YawRateKind::Gyro)),
            _ => None,
        }
    }

    /// Chooses the sources from the held records, then replays them.
    fn decide(&mut self, out: &mut Vec<Assembled>) {
        let mut tallies: Vec<(Source, Tally)> = Vec::new();
        for record in &self.window {
            let heading = self.heading_of(&record.measurement).is_some();
            let i = match tallies.iter().position(|(s, _)| *s == record.source) {
                Some(i) => i,
                None => {
                    tallies.push((record.source, Tally::default()));
                    tallies.len() - 1
                }
            };
            let tally = &mut tallies[i].1;
            match record.measurement {
                Measurement::Position { .. } if self.config.fixes_at_course => {}
                Measurement::Position { method, .. } => {
                    tally.positions += 1;
                    let rank = FixMethod::rank(method);
                    tally.best_rank = Some(tally.best_rank.map_or(rank, |r| r.max(rank)));
                }
                Measurement::CourseSpeed { .. } => tally.courses += 1,
                _ if heading => tally.headings += 1,
                ref m => {
                    if let Some((_, kind)) = Self::yaw_rate_of(m) {
                        tally.yaw_rates[kind as usize] += 1;
                    }
                }
            }
        }
        // Deterministic: sort by source so ties go to the lowest.
        tallies.sort_by_key(|(s, _)| *s);
        let best_by = |key: &dyn Fn(&Tally) -> (i8, u64)| {
            first_best(tallies.iter().map(|(s, t)| (*s, key(t))))
        };
        if self.position_source.is_none() {
            self.position_source = best_by(&|t| (t.best_rank.unwrap_or(i8::MIN), t.positions));
        }
        let position_gives_course = tallies
            .iter()
            .any(|(s, t)| Some(*s) == self.position_source && t.courses > 0);
        self.course_source = if position_gives_course {
            self.position_source
        } else {
            best_by(&|t| (0, t.courses))
        };
        self.heading_source = best_by(&|t| (0, t.headings));
        // The source and kind with the most yaw rates (ties: the lowest
        // source, a gyro's rate before a rate of turn).
        self.yaw_rate_stream = first_best(tallies.iter().flat_map(|(s, t)| {
            YawRateKind::ALL.map(|kind| ((*s, kind), (0, t.yaw_rates[kind as usize])))
        }));
        self.deciding = false;
        let window = std::mem::take(&mut self.window);
        for record in window {
            self.process(record, out);
        }
    }

    fn emit(&mut self, item: Assembled, out: &mut Vec<Assembled>) -> bool {
        let t = item.time_s();
        if self.last_out_s.is_some_and(|last| t < last) {
            self.stats.out_of_order += 1;
            return false;
        }
        self.last_out_s = Some(t);
        out.push(item);
        true
    }

    /// Completes and emits the pending fix.
    fn flush(&mut self, out: &mut Vec<Assembled>) {
        let Some(mut fix) = self.pending.take() else {
            return;
        };
        if let Some(course) = self.course
            && (fix.time_s - course.time_s).abs() <= self.config.max_course_age_s
        {
            (fix.cog_rad, fix.sog_mps) = course.value;
            self.course = None;
        }
        if let Some(heading) = self.heading
            && (fix.time_s - heading.time_s).abs() <= self.config.max_heading_age_s
        {
            fix.heading_rad = Some(heading.value);
            self.heading = None;
        }
        if let Some(rate) = self.yaw_rate
            && (fix.time_s - rate.time_s).abs() <= self.config.max_yaw_rate_age_s
        {
            fix.yaw_rate_radps = Some(rate.value);
            self.yaw_rate = None;
        }
        let with_course = fix.cog_rad.is_some() || fix.sog_mps.is_some();
        let with_heading = fix.heading_rad.is_some();
        let with_yaw_rate = fix.yaw_rate_radps.is_some();
        if self.emit(Assembled::Fix(fix), out) {
            self.last_fix_s = Some(fix.time_s);
            self.stats.fixes += 1;
            self.stats.fixes_with_course += u64::from(with_course);
            self.stats.fixes_with_heading += u64::from(with_heading);
            self.stats.fixes_with_yaw_rate += u64::from(with_yaw_rate);
        }
    }

    /// Takes a source for a kind: the chosen one, or locks onto this one if
    /// none was found in the window.
    fn accepts<T: PartialEq + Copy>(chosen: &mut Option<T>, source: T) -> bool {
        *chosen.get_or_insert(source) == source
    }

    fn process(&mut self, record: Record, out: &mut Vec<Assembled>) {
        if self.pending.is_some_and(|p| record.time_s > p.time_s) {
            self.flush(out);
        }
        let heading = self.heading_of(&record.measurement);
        match record.measurement {
            Measurement::Position { .. } if self.config.fixes_at_course => {}
            Measurement::Position {
                lat_deg,
                lon_deg,
                hdop,
                ..
            } => self.on_position(&record, LatLon { lat_deg, lon_deg }, hdop),
            Measurement::CourseSpeed { cog_rad, sog_mps } => {
                if !Self::accepts(&mut self.course_source, record.source) {
                    self.stats.courses_other_sources += 1;
                    return;
                }
                if self.config.fixes_at_course {
                    let unmeasured = LatLon {
                        lat_deg: f64::NAN,
                        lon_deg: f64::NAN,
                    };
                    self.open_fix(record.time_s, unmeasured, None);
                }
                if self.course.is_some() {
                    self.stats.courses_unused += 1;
                }
                self.course = Some(Fresh {
                    time_s: record.time_s,
                    value: (cog_rad, sog_mps),
                });
            }
            Measurement::PropellerSpeed { side, radps } => {
                let sample = Fresh {
                    time_s: record.time_s,
                    value: radps,
                };
                self.on_propeller_speed(side, sample, out);
            }
            Measurement::GnssFix(fix) => self.on_gnss_fix(fix, out),
            Measurement::Propellers(pair) => {
                if self.emit(Assembled::Propellers(pair), out) {
                    self.stats.propeller_pairs += 1;
                }
            }
            Measurement::Thrust(thrust) => {
                if self.emit(Assembled::Thrust(thrust), out) {
                    self.stats.thrusts += 1;
                }
            }
            ref m => {
                if let Some(h) = heading {
                    if !Self::accepts(&mut self.heading_source, record.source) {
                        self.stats.headings_other_sources += 1;
                        return;
                    }
                    self.heading = Some(Fresh {
                        time_s: record.time_s,
                        value: h,
                    });
                } else if let Some((r, kind)) = Self::yaw_rate_of(m) {
                    if !Self::accepts(&mut self.yaw_rate_stream, (record.source, kind)) {
                        self.stats.yaw_rates_other_sources += 1;
                        return;
                    }
                    self.yaw_rate = Some(Fresh {
                        time_s: record.time_s,
                        value: r,
                    });
                }
            }
        }
    }

    /// A position record: from the chosen source, after the previous fix,
    /// and not an NMEA 2000 repeat of the last position (when the
    /// configuration drops those), it starts the pending fix.
    fn on_position(&mut self, record: &Record, position: LatLon, hdop: Option<f64>) {
        if !Self::accepts(&mut self.position_source, record.source) {
            self.stats.positions_other_sources += 1;
            return;
        }
        let not_after = self.last_fix_s.is_some_and(|t| record.time_s <= t)
            || self.pending.is_some_and(|p| record.time_s <= p.time_s);
        if not_after {
            self.stats.positions_not_after_previous += 1;
            return;
        }
        let LatLon { lat_deg, lon_deg } = position;
        let fine = matches!(record.source, Source::N2k(_));
        let repeated = fine
            && self.last_position.is_some_and(|(t, lat, lon)| {
                record.time_s - t < self.config.repeat_window_s
                    && (lat - lat_deg).abs() < 1e-9
                    && (lon - lon_deg).abs() < 1e-9
            });
        if repeated && self.config.drop_repeated_positions {
            self.stats.positions_repeated += 1;
            return;
        }
        self.last_position = Some((record.time_s, lat_deg, lon_deg));
        self.open_fix(record.time_s, position, hdop);
    }

    /// Starts the pending fix at `time_s`, unless it is not after the
    /// previous fix (dropped and counted).
    fn open_fix(&mut self, time_s: f64, position: LatLon, hdop: Option<f64>) {
        let not_after = self.last_fix_s.is_some_and(|t| time_s <= t)
            || self.pending.is_some_and(|p| time_s <= p.time_s);
        if not_after {
            self.stats.positions_not_after_previous += 1;
            return;
        }
        self.pending = Some(GnssFix {
            time_s,
            position,
            sog_mps: None,
            cog_rad: None,
            heading_rad: None,
            yaw_rate_radps: None,
            hdop,
        });
    }

    /// One shaft's speed: paired with the other shaft's when that came
    /// within the pairing window.
    fn on_propeller_speed(&mut self, side: Side, sample: Fresh<f64>, out: &mut Vec<Assembled>) {
        let (mine, other) = match side {
            Side::Port => (&mut self.port, &mut self.starboard),
            Side::Starboard => (&mut self.starboard, &mut self.port),
        };
        if mine.replace(sample).is_some() {
            self.stats.propeller_unpaired += 1;
        }
        if let Some(o) = *other
            && (o.time_s - sample.time_s).abs() <= self.config.pair_window_s
        {
            let (port, starboard) = match side {
                Side::Port => (sample, o),
                Side::Starboard => (o, sample),
            };
            self.port = None;
            self.starboard = None;
            let pair = PropellerSpeeds {
                time_s: port.time_s.max(starboard.time_s),
                port_radps: port.value,
                starboard_radps: starboard.value,
            };
            if self.emit(Assembled::Propellers(pair), out) {
                self.stats.propeller_pairs += 1;
            }
        }
    }

    /// A whole fix (the project's JSON lines): emitted if after the
    /// previous one.
    fn on_gnss_fix(&mut self, fix: GnssFix, out: &mut Vec<Assembled>) {
        let after = self.last_fix_s.is_none_or(|t| fix.time_s > t);
        if after && self.emit(Assembled::Fix(fix), out) {
            self.last_fix_s = Some(fix.time_s);
            self.stats.fixes += 1;
            self.stats.fixes_with_course +=
                u64::from(fix.cog_rad.is_some() || fix.sog_mps.is_some());
            self.stats.fixes_with_heading += u64::from(fix.heading_rad.is_some());
            self.stats.fixes_with_yaw_rate += u64::from(fix.yaw_rate_radps.is_some());
        } else if !after {
            self.stats.positions_not_after_previous += 1;
        }
    }
}

/// An iterator of assembled inputs over an iterator of records.
pub struct Assemble<I> {
    records: I,
    assembler: FixAssembler,
    /// Outputs not yet returned, in reverse order.
    ready: Vec<Assembled>,
    finished: bool,
}

/// Assembles `records` with `config` (see the module doc).
pub fn assemble<I: Iterator<Item = Record>>(records: I, config: AssemblerConfig) -> Assemble<I> {
    Assemble {
        records,
        assembler: FixAssembler::new(config),
        ready: Vec::new(),
        finished: false,
    }
}

impl<I> Assemble<I> {
    /// The assembler (sources chosen, counts).
    pub fn assembler(&self) -> &FixAssembler {
        &self.assembler
    }

    /// The record iterator.
    pub fn records(&self) -> &I {
        &self.records
    }
}

impl<I: Iterator<Item = Record>> Iterator for Assemble<I> {
    type Item = Assembled;

    fn next(&mut self) -> Option<Assembled> {
        loop {
            if let Some(item) = self.ready.pop() {
                return Some(item);
            }
            if self.finished {
                return None;
            }
            match self.records.next() {
                Some(record) => self.assembler.push(record, &mut self.ready),
                None => {
                    self.assembler.finish(&mut self.ready);
                    self.finished = true;
                }
            }
            self.ready.reverse();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rec(time_s: f64, source: Source, measurement: Measurement) -> Record {
        Record {
            time_s,
            source,
            measurement,
        }
    }

    fn pos(time_s: f64, source: u8, method: Option<FixMethod>) -> Record {
        rec(
            time_s,
            Source::N2k(source),
            Measurement::Position {
                lat_deg: 34.4 + time_s * 1e-6,
                lon_deg: 133.5,
                hdop: None,
                method,
                altitude_m: None,
            },
        )
    }

    fn course(time_s: f64, source: u8, cog_rad: f64) -> Record {
        rec(
            time_s,
            Source::N2k(source),
            Measurement::CourseSpeed {
                cog_rad: Some(cog_rad),
                sog_mps: Some(2.0),
            },
        )
    }

    fn run(records: Vec<Record>, config: AssemblerConfig) -> (Vec<Assembled>, FixAssembler) {
        let mut a = FixAssembler::new(config);
        let mut out = Vec::new();
        for r in records {
            a.push(r, &mut out);
        }
        a.finish(&mut out);
        (out, a)
    }

    fn fixes(out: &[Assembled]) -> Vec<GnssFix> {
        out.iter()
            .filter_map(|a| match a {
                Assembled::Fix(f) => Some(*f),
                _ => None,
            })
            .collect()
    }

    #[test]
    fn slow_course_is_used_once_not_repeated() {
        // Positions at 8 Hz, COG at 2 Hz for 10 s (COG 0.01 s after a position).
        let mut records = Vec::new();
        for i in 0..80 {
            let t = i as f64 * 0.125;
            records.push(pos(t, 25, None));
            if i % 4 == 0 {
                records.push(course(t + 0.01, 25, i as f64 * 0.01));
            }
        }
        let (out, a) = run(records, AssemblerConfig::default());
        let f = fixes(&out);
        assert_eq!(f.len(), 80);
        let with: Vec<usize> = (0..80).filter(|&i| f[i].cog_rad.is_some()).collect();
        // Each COG joins the position after it (index 1, 5, 9, ...), once.
        assert_eq!(with, (0..20).map(|k| 4 * k + 1).collect::<Vec<_>>());
        assert_eq!(f[5].cog_rad, Some(0.04));
        assert_eq!(a.stats().fixes_with_course, 20);
        assert!(f.windows(2).all(|w| w[1].time_s > w[0].time_s));
    }

    /// A satellite compass (source 52) sends a damped rate of turn and its
    /// gyro's rate, each at 10 Hz; a rate sensor (source 27) sends its
    /// rate of turn at 10 Hz too, a record fewer. Counted by source, the
    /// compass would win and its fixes take one rate then the other; by
    /// source and kind, each fix takes one stream's rate.
    #[test]
    fn one_kind_of_yaw_rate_of_one_source_rides_on_the_fixes() {
        let mut records = Vec::new();
        for i in 0..100 {
            let t = i as f64 * 0.1;
            records.push(pos(t, 25, None));
            let rate = |source: u8, measurement: Measurement| {
                rec(t + 0.01, Source::N2k(source), measurement)
            };
            records.push(rate(
                52,
                Measurement::GyroRates {
                    roll_radps: None,
                    pitch_radps: None,
                    yaw_radps: Some(0.03),
                },
            ));
            records.push(rate(52, Measurement::RateOfTurn { radps: 0.01 }));
            if i > 0 {
                records.push(rate(27, Measurement::RateOfTurn { radps: 0.02 }));
            }
        }
        let (out, a) = run(records, AssemblerConfig::default());
        let rates: Vec<Option<f64>> = fixes(&out).iter().map(|f| f.yaw_rate_radps).collect();
        // The first 5 s decide: source 52's gyro rates (50) against its
        // rates of turn (50) and source 27's (49); the tie goes to the
        // gyro. Every fix after the first takes the 0.03 rad/s stream, none
        // the compass's damped 0.01.
        assert_eq!(a.yaw_rate_source(), Some(Source::N2k(52)));
        assert!(rates[1..].iter().all(|r| *r == Some(0.03)), "{rates:?}");
        assert_eq!(a.stats().yaw_rates_other_sources, 100 + 99);
    }

    #[test]
    fn without_positions_every_course_opens_a_fix_with_heading_and_yaw_rate() {
        // COG/SOG at 4 Hz from source 25, heading at 10 Hz and yaw rate at
        // 20 Hz from source 27, and a few positions that must be ignored.
        let mut records = Vec::new();
        for i in 0..200 {
            let t = i as f64 * 0.05;
            if i % 2 == 0 {
                records.push(rec(
                    t + 0.001,
                    Source::N2k(27),
                    Measurement::Heading {
                        heading_rad: 1.0 + t * 0.01,
                    },
                ));
            }
            records.push(rec(
                t + 0.002,
                Source::N2k(27),
                Measurement::RateOfTurn { radps: 0.02 },
            ));
            if i % 5 == 0 {
                records.push(course(t + 0.003, 25, t * 0.01));
            }
            if i % 40 == 0 {
                records.push(pos(t + 0.004, 25, None));
            }
        }
        let config = AssemblerConfig {
            fixes_at_course: true,
            ..AssemblerConfig::default()
        };
        let (out, a) = run(records, config);
        let f = fixes(&out);
        assert_eq!(f.len(), 40, "one fix per course record, none per position");
        assert!(f.iter().all(|f| f.position.lat_deg.is_nan()));
        for (k, fix) in f.iter().enumerate() {
            let t = k as f64 * 0.25 + 0.003;
            assert!((fix.time_s - t).abs() < 1e-9);
            assert!((fix.cog_rad.unwrap() - (t - 0.003) * 0.01).abs() < 1e-12);
            // The freshest heading: of the course's instant, or of the one
            // before when no heading was sent at it (10 Hz against 20 Hz).
            let heading = fix.heading_rad.unwrap();
            let heading_i = 5 * k - (5 * k) % 2;
            assert!(
                (heading - (1.0 + heading_i as f64 * 0.05 * 0.01)).abs() < 1e-12,
                "fix {k}: heading {heading}"
            );
            assert_eq!(fix.yaw_rate_radps, Some(0.02));
        }
        assert_eq!(a.sources().0, None, "no position source");
        assert_eq!(a.stats().fixes_with_heading, 40);
        // The same records without the option: fixes only at the positions.
        let mut plain = Vec::new();
        for i in 0..5 {
            plain.push(pos(i as f64 * 2.0, 25, None));
        }
        let (out, _) = run(plain, AssemblerConfig::default());
        assert_eq!(fixes(&out).len(), 5);
    }

    #[test]
    fn records_stamped_with_the_position_time_join_it() {
        // The plaka pattern: the untimed VTG of the next burst carries the
        // GLL's time and arrives after it.
        let gp = Source::Nmea(crate::measurement::Talker::GP);
        let ii = Source::Nmea(crate::measurement::Talker::new(*b"II").unwrap());
        let p = |t| {
            rec(
                t,
                gp,
                Measurement::Position {
                    lat_deg: 60.0,
                    lon_deg: 23.5,
                    hdop: None,
                    method: None,
                    altitude_m: None,
                },
            )
        };
        let c = |t, cog| {
            rec(
                t,
                ii,
                Measurement::CourseSpeed {
                    cog_rad: Some(cog),
                    sog_mps: None,
                },
            )
        };
        let (out, _) = run(
            vec![p(0.0), c(0.0, 1.0), p(2.0), c(2.0, 2.0), p(4.0)],
            AssemblerConfig::default(),
        );
        let f = fixes(&out);
        assert_eq!(
            f.iter().map(|f| f.cog_rad).collect::<Vec<_>>(),
            [Some(1.0), Some(2.0), None]
        );
    }

    #[test]
    fn stale_course_and_heading_are_not_joined() {
        let h = |t, heading_rad| rec(t, Source::N2k(52), Measurement::Heading { heading_rad });
        let (out, _) = run(
            vec![
                course(0.0, 25, 1.0),
                h(0.0, 0.5),
                pos(1.5, 25, None),
                pos(1.6, 25, None),
            ],
            AssemblerConfig::default(),
        );
        let f = fixes(&out);
        assert_eq!((f[0].cog_rad, f[0].heading_rad), (None, None));
        let (out, _) = run(
            vec![course(0.0, 25, 1.0), h(0.0, 0.5), pos(0.9, 25, None)],
            AssemblerConfig::default(),
        );
        assert_eq!(fixes(&out)[0].heading_rad, Some(0.5));
        assert_eq!(fixes(&out)[0].cog_rad, Some(1.0));
    }

    #[test]
    fn best_source_prefers_method_then_rate_then_lowest() {
        // Source 52 at 5 Hz with DGNSS beats source 25 at 8 Hz with plain GNSS.
        let mut records = Vec::new();
        for i in 0..80 {
            records.push(pos(i as f64 * 0.125, 25, Some(FixMethod::Gnss)));
        }
        for i in 0..50 {
            records.push(pos(i as f64 * 0.2 + 0.01, 52, Some(FixMethod::Dgnss)));
        }
        records.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
        let (out, a) = run(records.clone(), AssemblerConfig::default());
        assert_eq!(a.sources().0, Some(Source::N2k(52)));
        assert_eq!(fixes(&out).len(), 50);
        assert_eq!(a.stats().positions_other_sources, 80);
        // Without methods the higher rate wins.
        let no_method: Vec<Record> = records
            .iter()
            .map(|r| match r.measurement {
                Measurement::Position {
                    lat_deg, lon_deg, ..
                } => rec(
                    r.time_s,
                    r.source,
                    Measurement::Position {
                        lat_deg,
                        lon_deg,
                        hdop: None,
                        method: None,
                        altitude_m: None,
                    },
                ),
                m => rec(r.time_s, r.source, m),
            })
            .collect();
        let (_, a) = run(no_method, AssemblerConfig::default());
        assert_eq!(a.sources().0, Some(Source::N2k(25)));
        // Equal rate and method: the lowest source.
        let tie: Vec<Record> = (0..20)
            .flat_map(|i| {
                [
                    pos(i as f64 * 0.5, 60, None),
                    pos(i as f64 * 0.5 + 0.1, 40, None),
                ]
            })
            .collect();
        let (_, a) = run(tie, AssemblerConfig::default());
        assert_eq!(a.sources().0, Some(Source::N2k(40)));
        // A fixed choice wins over everything.
        let config = AssemblerConfig {
            position_source: SourceChoice::Fixed(Source::N2k(25)),
            ..AssemblerConfig::default()
        };
        let (out, a) = run(records, config);
        assert_eq!(
            (a.sources().0, fixes(&out).len()),
            (Some(Source::N2k(25)), 80)
        );
    }

    #[test]
    fn propellers_pair_within_the_window_in_time_order() {
        let p = |t, side, radps| {
            rec(
                t,
                Source::N2k(0),
                Measurement::PropellerSpeed { side, radps },
            )
        };
        let (out, a) = run(
            vec![
                p(0.0, Side::Port, 10.0),
                p(0.1, Side::Starboard, 11.0), // pairs with port at 0.0
                p(1.0, Side::Port, 12.0),      // replaced before pairing
                p(2.0, Side::Port, 13.0),
                p(3.0, Side::Starboard, 14.0), // 1 s apart: no pair
                p(3.2, Side::Port, 15.0),      // pairs with starboard at 3.0
            ],
            AssemblerConfig::default(),
        );
        let pairs: Vec<PropellerSpeeds> = out
            .iter()
            .filter_map(|a| match a {
                Assembled::Propellers(p) => Some(*p),
                _ => None,
            })
            .collect();
        assert_eq!(
            pairs,
            [
                PropellerSpeeds {
                    time_s: 0.1,
                    port_radps: 10.0,
                    starboard_radps: 11.0
                },
                PropellerSpeeds {
                    time_s: 3.2,
                    port_radps: 15.0,
                    starboard_radps: 14.0
                },
            ]
        );
        assert_eq!(a.stats().propeller_unpaired, 2);
    }

    #[test]
    fn positions_not_after_the_previous_fix_are_dropped() {
        let (out, a) = run(
            vec![
                pos(1.0, 25, None),
                pos(1.0, 25, None),
                pos(2.0, 25, None),
                pos(1.5, 25, None),
                pos(3.0, 25, None),
            ],
            AssemblerConfig::default(),
        );
        let times: Vec<f64> = fixes(&out).iter().map(|f| f.time_s).collect();
        assert_eq!(times, [1.0, 2.0, 3.0]);
        assert_eq!(a.stats().positions_not_after_previous, 2);
    }

    #[test]
    fn a_resent_position_is_not_a_new_fix() {
        // The aava pattern: 129025 at t, the same coordinates in 129029 at t + 0.5.
        let at = |t: f64, lat: f64| {
            rec(
                t,
                Source::N2k(160),
                Measurement::Position {
                    lat_deg: lat,
                    lon_deg: 24.7,
                    hdop: None,
                    method: None,
                    altitude_m: None,
                },
            )
        };
        let records = vec![
            at(0.5, 59.72),
            at(1.0, 59.72 + 1e-12),
            at(1.5, 59.7201),
            at(2.0, 59.7201),
            at(4.0, 59.7201),
        ];
        let (out, a) = run(records.clone(), AssemblerConfig::default());
        let times: Vec<f64> = fixes(&out).iter().map(|f| f.time_s).collect();
        // 4.0 repeats 1.5 but 2.5 s later: a vessel at rest, kept.
        assert_eq!(times, [0.5, 1.5, 4.0]);
        assert_eq!(a.stats().positions_repeated, 2);
        let keep = AssemblerConfig {
            drop_repeated_positions: false,
            ..AssemblerConfig::default()
        };
        let (out, _) = run(records, keep);
        assert_eq!(fixes(&out).len(), 5);
    }

    #[test]
    fn the_window_is_released_once_decided() {
        let mut a = FixAssembler::new(AssemblerConfig::default());
        let mut out = Vec::new();
        for i in 0..100 {
            a.push(pos(i as f64 * 0.1, 25, None), &mut out);
            if i < 50 {
                assert!(out.is_empty() && a.held_records() == i + 1);
            }
        }
        // Decided at t = 5 s: everything held came out, nothing is held now.
        assert_eq!(a.held_records(), 0);
        assert_eq!(out.len(), 99);
        assert_eq!(a.sources().0, Some(Source::N2k(25)));
    }

    #[test]
    fn iterator_adapter_streams() {
        let records = (0..1000).map(|i| pos(i as f64 * 0.1, 25, None));
        let mut it = assemble(records, AssemblerConfig::default());
        let first = it.next().unwrap();
        assert_eq!(first.time_s(), 0.0);
        assert_eq!(it.count(), 999);
    }
}
