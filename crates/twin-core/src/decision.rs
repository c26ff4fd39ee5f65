//! From fault estimates and their uncertainty to a decision per thruster:
//! `nominal`, `suspect` or `fault`, with the onset time, hysteresis in level
//! and in time, and `not excited` while the data have never been able to tell.
//!
//! Each propeller's loss is judged twice ([`LossEvidence`]): on its own
//! (absolute), and relative to the other propeller (what the yaw balance
//! measures even when the losses' common part cannot be told from the
//! hull's drag). Each judgement, where the data excite it, applies these
//! rules to its value and standard deviation (thresholds in
//! [`DecisionConfig`], `k` = `confidence_sigmas`):
//! - evidence of a fault: `loss >= fault_loss` and `loss - k sigma >= suspect_loss`;
//! - evidence of a suspect: `loss >= suspect_loss` and `loss - k sigma >=
//!   clear_loss` (the loss confidently outside the nominal band); for a
//!   thruster already at fault, also `loss + k sigma < fault_loss` (the
//!   loss confidently below the fault level: a fault's estimate wandering
//!   near its threshold is not a recovery);
//! - evidence of nominal: `loss < clear_loss` or `loss + k sigma < suspect_loss`;
//! - anything else (between the clear and suspect levels, or too uncertain)
//!   is no evidence.
//!
//! The stronger judgement decides: a fault if either shows one, a suspect if
//! either shows one and neither a fault, nominal if one shows nominal and
//! the other nothing worse; no evidence keeps the current status (that gap
//! is the level hysteresis). A loss whose σ is wide (its common part
//! unknown) shows nothing on its own, so a hull draggier than its profile
//! raises no fault, while one propeller weaker than the other does;
//! - a new level must persist `confirm_s` (up to a fault),
//!   `suspect_confirm_s` (up to a suspect) or `clear_s` (going down) before
//!   the status changes: the time hysteresis. Evidence that moves further
//!   the same way (suspect, then fault) keeps the clock, and the status goes
//!   straight to the level the evidence shows then. A suspect waits longer
//!   than a fault: an estimate converging on a real loss passes through the
//!   suspect band on its way, and one change (nominal to fault) says it
//!   better than two; nothing acts on a suspect, so waiting costs little;
//! - while a thruster is not excited its status holds (a broken propeller
//!   stays broken on a straight line); a thruster never excited is
//!   `NotExcited`, and so is one whose evidence has not yet shown health
//!   or worse: told for the first time with its estimate in the gap (a
//!   loss of 0.17 +- 0.08 from the start), it is not `Nominal`;
//! - but a `Nominal` holds only while the estimate does not contradict
//!   it: once the estimate the data do not excite (its loss, or its loss
//!   relative to the other, also where only weakly told) has shown a
//!   suspect or a fault by the rules above for `clear_s`, the `Nominal` is
//!   withdrawn to `NotExcited` (a status change, so an alarm). A propeller
//!   judged healthy before a steady turn one way, whose loss the turn
//!   then shows but cannot tell from a yaw damping error (0.35 +- 0.05),
//!   is not published `nominal` beside it; nor is a warning raised, which
//!   needs the data to tell (or the weak rule below). Told again, the
//!   status goes to the level the evidence shows, from `NotExcited`, and
//!   to `Nominal` only where the evidence shows that;
//! - while the profile does not describe the vessel
//!   ([`LossEvidence::profile_describes`] false) no evidence counts: a
//!   warning holds, and neither a claim of health nor a new warning is
//!   read off a model that no longer explains the vessel (a filter whose
//!   mass had run to 4.7 times the profile's read a loss of 1.0 +- 0.1
//!   on a healthy propeller, docs/model.md section 10). Once
//!   that has lasted `mismatch_withdraw_s`, a `Nominal` status judged
//!   before it is withdrawn to `NotExcited` (a status change, so an
//!   alarm): whatever made the model stop explaining the vessel may be a
//!   loss the comparison can no longer see, and a controller must not
//!   read the earlier judgement as a measurement of now. A `Suspect` or
//!   `Fault` holds. Once the profile describes the vessel again, the
//!   status returns to `Nominal` where the evidence shows it, again as a
//!   change;
//! - where neither judgement is excited but the comparison is told weakly
//!   (`relative_weakly_told`: its standard deviation within a wider bar),
//!   only its evidence of a fault counts, and it must persist
//!   `weak_confirm_s`, a filter's memory: a loss the data have shown for
//!   that long is declared, while a transient of the estimate is not.
//!   Weak evidence of anything less claims nothing;
//! - the onset is the last time before the episode's first evidence that
//!   the propeller looked healthy (its loss, and its loss relative to the
//!   other, below `clear_loss`, whether or not the data excited them): an
//!   estimate moves towards a new loss from the moment it starts, and its
//!   evidence clears the bars only later. Without such a time (a loss from
//!   the start), the episode's first evidence. Never the time it was
//!   confirmed.
//!
//! Time is the message time, passed in; nothing here reads a clock.

use crate::sample::Side;

/// What the twin says of one thruster.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum ThrusterStatus {
    /// The data have not yet been able to tell (no excitation so far).
    NotExcited,
    /// No loss beyond the clear level.
    Nominal,
    /// A loss beyond the suspect level, not yet a fault.
    Suspect,
    /// A confirmed loss beyond the fault level.
    Fault,
}

impl ThrusterStatus {
    /// Lower-case name as used in payloads.
    pub fn name(self) -> &'static str {
        match self {
            ThrusterStatus::NotExcited => "not_excited",
            ThrusterStatus::Nominal => "nominal",
            ThrusterStatus::Suspect => "suspect",
            ThrusterStatus::Fault => "fault",
        }
    }
}

/// Thresholds of the decision.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DecisionConfig {
    /// Loss at which a thruster becomes suspect (0..1).
    pub suspect_loss: f64,
    /// Loss at which a thruster is at fault (0..1).
    pub fault_loss: f64,
    /// Loss below which a thruster is nominal again (below `suspect_loss`).
    pub clear_loss: f64,
    /// How many standard deviations the evidence must clear.
    pub confidence_sigmas: f64,
    /// How long evidence of a fault must persist before it is declared, s.
    pub confirm_s: f64,
    /// How long evidence of a suspect must persist before it is declared, s.
    pub suspect_confirm_s: f64,
    /// How long evidence of a fault from a weakly told comparison (and
    /// nothing else told) must persist before it is declared, s.
    pub weak_confirm_s: f64,
    /// How long a lower level must persist before it is declared, s.
    pub clear_s: f64,
    /// How long the profile must fail to describe the vessel before a
    /// `Nominal` status is withdrawn to `NotExcited`, s.
    pub mismatch_withdraw_s: f64,
}

impl Default for DecisionConfig {
    /// Suspect at 5 %, fault at 10 %, clear below 3 %, two and a half
    /// sigmas, 3 s to confirm a fault (30 s from a weakly told
    /// comparison), 30 s to confirm a suspect and 10 s to clear. The seed's
    /// healthy propellers showed 0-4 % input faults, its broken one
    /// 12-18 %. The sigmas, the two longer confirmations, the comparison's
    /// excitation bar (`KineticConfig::relative_excitation_sigma`) and the
    /// profile's plausibility guard
    /// (`KineticConfig::plausible_profile_sigmas`) were chosen together on
    /// the trust matrix and checked on seeds not used to choose them
    /// (docs/model.md section 10): a healthy vessel unlike its profile
    /// drifts its relative loss 2-3.5 sigmas for tens of seconds, which two
    /// sigmas took for a fault.
    fn default() -> Self {
        Self {
            suspect_loss: 0.05,
            fault_loss: 0.10,
            clear_loss: 0.03,
            confidence_sigmas: 2.5,
            confirm_s: 3.0,
            suspect_confirm_s: 30.0,
            weak_confirm_s: 30.0,
            clear_s: 10.0,
            mismatch_withdraw_s: 10.0,
        }
    }
}

impl DecisionConfig {
    /// The probability, under a normal uncertainty `sigma`, that a loss
    /// estimated at `loss` is above the suspect level: a status change's
    /// confidence ([`StatusChange::confidence`]).
    fn probability_above_suspect(&self, loss: f64, sigma: f64) -> f64 {
        normal_cdf((loss - self.suspect_loss) / sigma.max(1e-12))
    }
}

/// What the estimate says of one propeller's loss.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LossEvidence {
    /// The loss, 0..1.
    pub loss: f64,
    /// Its standard deviation.
    pub sigma: f64,
    /// Whether the data can tell the loss on its own.
    pub excited: bool,
    /// The loss relative to the other propeller.
    pub relative_loss: f64,
    /// Its standard deviation.
    pub relative_sigma: f64,
    /// Whether the data can tell the relative loss.
    pub relative_excited: bool,
    /// Whether they tell it weakly: not excited, but within a wider bar
    /// (`KineticConfig::relative_release_sigma`).
    pub relative_weakly_told: bool,
    /// Whether the vessel's profile describes the vessel (no
    /// `profile_mismatch`); where it does not, no evidence counts, and a
    /// `Nominal` status is withdrawn after
    /// [`DecisionConfig::mismatch_withdraw_s`].
    pub profile_describes: bool,
}

/// A change of one thruster's status (an alarm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StatusChange {
    /// Which thruster.
    pub side: Side,
    /// The status before.
    pub from: ThrusterStatus,
    /// The status now.
    pub to: ThrusterStatus,
    /// When the change was declared, s.
    pub time_s: f64,
    /// When the evidence for it first appeared, s.
    pub onset_time_s: f64,
    /// Probability, under the estimate's normal uncertainty, that the loss is
    /// above the suspect level (for changes up) or below it (for changes
    /// down, a `Nominal` withdrawn to `NotExcited` included).
    pub confidence: f64,
}

/// The decision about one thruster at one time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThrusterDecision {
    /// Current status.
    pub status: ThrusterStatus,
    /// Onset of the current suspect/fault episode, s.
    pub onset_time_s: Option<f64>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct SideState {
    status: ThrusterStatus,
    onset_time_s: Option<f64>,
    candidate: Option<(ThrusterStatus, f64)>,
    /// The last time the propeller looked healthy (module doc).
    looked_healthy_s: Option<f64>,
    /// Since when the profile has not described the vessel, s.
    mismatch_since_s: Option<f64>,
    /// Since when a `Nominal` status has been contradicted by an estimate
    /// the data no longer excite ([`FaultDecider::track_contradiction`]), s.
    contradicted_since_s: Option<f64>,
    /// Whether the status is `NotExcited` because a `Nominal` one was
    /// withdrawn: its return is then a change of its own.
    withdrawn: bool,
}

impl SideState {
    /// A `Nominal` status withdrawn to `NotExcited`: no episode, and its
    /// return is a change of its own.
    fn withdraw(&mut self) {
        self.status = ThrusterStatus::NotExcited;
        self.onset_time_s = None;
        self.withdrawn = true;
    }
}

/// The alarm of a `Nominal` status of `side` withdrawn at `time_s`, for a
/// reason that has held since `since_s`, with the probability `p_below`
/// that the loss is below the suspect level.
fn withdrawal(side: Side, time_s: f64, since_s: f64, p_below: f64) -> StatusChange {
    StatusChange {
        side,
        from: ThrusterStatus::Nominal,
        to: ThrusterStatus::NotExcited,
        time_s,
        onset_time_s: since_s,
        confidence: p_below,
    }
}

/// The decision state for two thrusters. Plain data, so it can be saved.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FaultDecider {
    config: DecisionConfig,
    sides: [SideState; 2],
}

impl FaultDecider {
    /// A decider with nothing decided yet.
    pub fn new(config: DecisionConfig) -> Self {
        let fresh = SideState {
            status: ThrusterStatus::NotExcited,
            onset_time_s: None,
            candidate: None,
            looked_healthy_s: None,
            mismatch_since_s: None,
            contradicted_since_s: None,
            withdrawn: false,
        };
        Self {
            config,
            sides: [fresh; 2],
        }
    }

    /// The thresholds.
    pub fn config(&self) -> &DecisionConfig {
        &self.config
    }

    /// The current decision for `side`.
    pub fn decision(&self, side: Side) -> ThrusterDecision {
        let s = &self.sides[side.index()];
        ThrusterDecision {
            status: s.status,
            onset_time_s: s.onset_time_s,
        }
    }

    /// Restores a decision (e.g. from a saved calibration).
    pub fn restore(&mut self, side: Side, decision: ThrusterDecision) {
        self.sides[side.index()] = SideState {
            status: decision.status,
            onset_time_s: decision.onset_time_s,
            candidate: None,
            looked_healthy_s: None,
            mismatch_since_s: None,
            contradicted_since_s: None,
            withdrawn: false,
        };
    }

    /// The worst status over both thrusters.
    pub fn overall(&self) -> ThrusterStatus {
        self.sides[0].status.max(self.sides[1].status)
    }

    /// Feeds the estimates at `time_s` (`[port, starboard]`) and returns the
    /// status changes this update declared.
    pub fn update(&mut self, time_s: f64, evidence: [LossEvidence; 2]) -> Vec<StatusChange> {
        let mut changes = Vec::new();
        for side in Side::BOTH {
            let i = side.index();
            let e = evidence[i];
            let clear = self.config.clear_loss;
            let readings = [e.loss, e.relative_loss];
            if readings.iter().any(|l| l.is_finite())
                && readings.iter().all(|l| !l.is_finite() || *l < clear)
            {
                self.sides[i].looked_healthy_s = Some(time_s);
            }
            if let Some(change) = self.track_mismatch(side, time_s, &e) {
                changes.push(change);
            }
            let at_fault = self.sides[i].status == ThrusterStatus::Fault;
            let judged = self.judge(&e, at_fault);
            if let Some(change) = self.track_contradiction(side, time_s, &e, judged.as_ref()) {
                changes.push(change);
            }
            let Some(judged) = judged else {
                continue;
            };
            let weak = judged.weak;
            let (loss_i, sigma_i) = (judged.loss, judged.sigma);
            let cfg = self.config;
            let st = &mut self.sides[i];
            // Without a profile that describes the vessel, no evidence
            // counts (module doc).
            let evidence = judged.level.filter(|_| e.profile_describes);
            if st.status == ThrusterStatus::NotExcited
                && !weak
                && evidence == Some(ThrusterStatus::Nominal)
            {
                // The data tell, and show health: nominal at once (after a
                // withdrawal, say so). Evidence of worse goes from
                // `NotExcited` to its level, and none keeps `NotExcited`.
                st.status = ThrusterStatus::Nominal;
                if std::mem::take(&mut st.withdrawn) {
                    changes.push(StatusChange {
                        side,
                        from: ThrusterStatus::NotExcited,
                        to: ThrusterStatus::Nominal,
                        time_s,
                        onset_time_s: time_s,
                        confidence: 1.0 - cfg.probability_above_suspect(loss_i, sigma_i),
                    });
                }
            }
            let Some(level) = evidence else {
                // In the hysteresis gap: keep the status; a pending change
                // keeps its clock only while its own evidence holds.
                st.candidate = None;
                continue;
            };
            if level == st.status {
                st.candidate = None;
                continue;
            }
            // A pending change in the same direction keeps its clock: a loss
            // growing through the suspect level into a fault is one episode.
            let same_direction =
                |c: ThrusterStatus| (c > st.status) == (level > st.status) && c != st.status;
            let since = match st.candidate {
                Some((c, t)) if same_direction(c) => {
                    st.candidate = Some((level, t));
                    t
                }
                _ => {
                    st.candidate = Some((level, time_s));
                    time_s
                }
            };
            let needed = if weak {
                cfg.weak_confirm_s
            } else if level == ThrusterStatus::Fault {
                cfg.confirm_s
            } else if level > st.status {
                cfg.suspect_confirm_s
            } else {
                cfg.clear_s
            };
            if time_s - since >= needed {
                let from = st.status;
                let onset = if level > ThrusterStatus::Nominal {
                    // An episode's onset stays from its start.
                    if from > ThrusterStatus::Nominal {
                        st.onset_time_s.unwrap_or(since)
                    } else {
                        st.looked_healthy_s.filter(|t| *t <= since).unwrap_or(since)
                    }
                } else {
                    since
                };
                st.status = level;
                st.withdrawn = false;
                st.onset_time_s = (level > ThrusterStatus::Nominal).then_some(onset);
                st.candidate = None;
                let p_above = cfg.probability_above_suspect(loss_i, sigma_i);
                changes.push(StatusChange {
                    side,
                    from,
                    to: level,
                    time_s,
                    onset_time_s: onset,
                    confidence: if level > from { p_above } else { 1.0 - p_above },
                });
            }
        }
        changes
    }

    /// Keeps the time since which the profile has not described the
    /// vessel, and withdraws a `Nominal` status of `side` once that has
    /// lasted `mismatch_withdraw_s` (module doc); the change, if any.
    fn track_mismatch(
        &mut self,
        side: Side,
        time_s: f64,
        e: &LossEvidence,
    ) -> Option<StatusChange> {
        let cfg = self.config;
        let st = &mut self.sides[side.index()];
        if e.profile_describes {
            st.mismatch_since_s = None;
            return None;
        }
        let since = *st.mismatch_since_s.get_or_insert(time_s);
        if st.status != ThrusterStatus::Nominal || time_s - since < cfg.mismatch_withdraw_s {
            return None;
        }
        st.candidate = None;
        st.withdraw();
        // How sure the withdrawn claim was: the probability, under the
        // published loss, that it is below the suspect level.
        let p_below = if e.loss.is_finite() && e.sigma.is_finite() {
            1.0 - cfg.probability_above_suspect(e.loss, e.sigma)
        } else {
            0.5
        };
        Some(withdrawal(side, time_s, since, p_below))
    }

    /// Withdraws a `Nominal` status of `side` to `NotExcited` once the
    /// estimate, while the data do not excite it (`judged` `None`, or weak),
    /// has shown a suspect or a fault for `clear_s` (module doc); the
    /// change, if any.
    fn track_contradiction(
        &mut self,
        side: Side,
        time_s: f64,
        e: &LossEvidence,
        judged: Option<&Judged>,
    ) -> Option<StatusChange> {
        let cfg = self.config;
        let told = judged.is_some_and(|j| !j.weak);
        let shows_worse = |loss: f64, sigma: f64| {
            loss.is_finite()
                && sigma.is_finite()
                && self
                    .evidence(loss, sigma, false)
                    .is_some_and(|l| l > ThrusterStatus::Nominal)
        };
        let relative_worse = shows_worse(e.relative_loss, e.relative_sigma);
        let contradicted =
            !told && e.profile_describes && (relative_worse || shows_worse(e.loss, e.sigma));
        let st = &mut self.sides[side.index()];
        if !contradicted || st.status != ThrusterStatus::Nominal {
            st.contradicted_since_s = None;
            return None;
        }
        let since = *st.contradicted_since_s.get_or_insert(time_s);
        if time_s - since < cfg.clear_s {
            return None;
        }
        // A pending warning keeps its clock: the estimate that withdraws
        // the claim of health may be the one confirming a fault.
        st.contradicted_since_s = None;
        st.withdraw();
        // How sure the withdrawn claim still is, under the estimate that
        // contradicts it.
        let (loss, sigma) = if relative_worse {
            (e.relative_loss, e.relative_sigma)
        } else {
            (e.loss, e.sigma)
        };
        let p_below = 1.0 - cfg.probability_above_suspect(loss, sigma);
        Some(withdrawal(side, time_s, since, p_below))
    }

    /// What the evidence `e` shows (module doc), `None` where nothing is
    /// told; `at_fault`: whether the thruster is at fault now.
    fn judge(&self, e: &LossEvidence, at_fault: bool) -> Option<Judged> {
        let absolute = (e.excited && e.loss.is_finite() && e.sigma.is_finite())
            .then(|| self.evidence(e.loss, e.sigma, at_fault));
        let relative =
            (e.relative_excited && e.relative_loss.is_finite() && e.relative_sigma.is_finite())
                .then(|| self.evidence(e.relative_loss, e.relative_sigma, at_fault));
        if absolute.is_none() && relative.is_none() {
            // Only a weakly told comparison: only its fault counts.
            let weak = e.relative_weakly_told
                && e.relative_loss.is_finite()
                && e.relative_sigma.is_finite();
            return weak.then(|| Judged {
                level: (self.evidence(e.relative_loss, e.relative_sigma, at_fault)
                    == Some(ThrusterStatus::Fault))
                .then_some(ThrusterStatus::Fault),
                weak: true,
                loss: e.relative_loss,
                sigma: e.relative_sigma,
            });
        }
        let level = combine(absolute.flatten(), relative.flatten());
        // The confidence of a change is that of the judgement that made it.
        let (loss, sigma) = match relative.flatten() {
            Some(r) if Some(r) == level => (e.relative_loss, e.relative_sigma),
            _ => (e.loss, e.sigma),
        };
        Some(Judged {
            level,
            weak: false,
            loss,
            sigma,
        })
    }

    /// What one judgement shows (module doc); `at_fault`: whether the
    /// thruster is at fault now.
    fn evidence(&self, loss: f64, sigma: f64, at_fault: bool) -> Option<ThrusterStatus> {
        let c = &self.config;
        let k = c.confidence_sigmas;
        if loss >= c.fault_loss && loss - k * sigma >= c.suspect_loss {
            Some(ThrusterStatus::Fault)
        } else if loss >= c.suspect_loss
            && loss - k * sigma >= c.clear_loss
            && (!at_fault || loss + k * sigma < c.fault_loss)
        {
            Some(ThrusterStatus::Suspect)
        } else if loss < c.clear_loss || loss + k * sigma < c.suspect_loss {
            Some(ThrusterStatus::Nominal)
        } else {
            None
        }
    }
}

/// What one propeller's evidence shows.
struct Judged {
    /// The level it shows, if any.
    level: Option<ThrusterStatus>,
    /// Whether it comes from a weakly told comparison alone.
    weak: bool,
    /// The loss of the judgement that decides, and its sigma.
    loss: f64,
    sigma: f64,
}

/// The stronger of two judgements (module doc): a fault or suspect from
/// either wins; nominal needs one judgement to show it and the other not to
/// show worse.
fn combine(a: Option<ThrusterStatus>, b: Option<ThrusterStatus>) -> Option<ThrusterStatus> {
    match (a, b) {
        (Some(x), Some(y)) => Some(x.max(y)),
        (Some(x), None) | (None, Some(x)) => Some(x),
        (None, None) => None,
    }
}

/// The standard normal cumulative distribution, by the complementary error
/// function of Numerical Recipes (`erfc` with fractional error below 1.2e-7).
pub fn normal_cdf(z: f64) -> f64 {
    if z.is_nan() {
        return f64::NAN;
    }
    let x = z.abs() / std::f64::consts::SQRT_2;
    let t = 1.0 / (1.0 + 0.5 * x);
    let poly = -x * x - 1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98
                                + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let erfc = t * poly.exp();
    if z >= 0.0 {
        1.0 - 0.5 * erfc
    } else {
        0.5 * erfc
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Absolute evidence only (the relative loss not excited).
    fn absolute(loss: f64, sigma: f64, excited: bool) -> LossEvidence {
        LossEvidence {
            loss,
            sigma,
            excited,
            relative_loss: f64::NAN,
            relative_sigma: f64::NAN,
            relative_excited: false,
            relative_weakly_told: false,
            profile_describes: true,
        }
    }

    fn run(decider: &mut FaultDecider, series: &[(f64, f64, f64, bool)]) -> Vec<StatusChange> {
        series
            .iter()
            .flat_map(|(t, loss, sigma, excited)| {
                decider.update(
                    *t,
                    [
                        absolute(*loss, *sigma, *excited),
                        absolute(0.0, 0.01, *excited),
                    ],
                )
            })
            .collect()
    }

    /// A loss whose common part is unknown (wide sigma) but whose side is
    /// told by the yaw balance (relative loss) is a fault on its side only;
    /// a common loss as uncertain as a hull's drag is no fault on either.
    #[test]
    fn the_relative_loss_names_the_side_and_a_wide_common_loss_is_no_fault() {
        let mut d = FaultDecider::new(DecisionConfig::default());
        let port = LossEvidence {
            loss: 0.12,
            sigma: 0.15,
            excited: true,
            relative_loss: 0.2,
            relative_sigma: 0.02,
            relative_excited: true,
            relative_weakly_told: false,
            profile_describes: true,
        };
        let starboard = LossEvidence {
            loss: -0.08,
            sigma: 0.15,
            excited: true,
            relative_loss: -0.25,
            relative_sigma: 0.025,
            relative_excited: true,
            relative_weakly_told: false,
            profile_describes: true,
        };
        let changes: Vec<StatusChange> = (0..60)
            .flat_map(|k| d.update(k as f64 * 0.2, [port, starboard]))
            .collect();
        assert_eq!(d.decision(Side::Port).status, ThrusterStatus::Fault);
        assert_eq!(d.decision(Side::Starboard).status, ThrusterStatus::Nominal);
        assert_eq!(changes.len(), 1, "{changes:?}");
        assert!(changes[0].confidence > 0.99);
        // Both 30 % weaker than the profile, as a draggier hull makes them
        // look, but as uncertain as the hull's drag: no fault.
        let mut d = FaultDecider::new(DecisionConfig::default());
        let common = LossEvidence {
            loss: 0.3,
            sigma: 0.18,
            excited: true,
            relative_loss: 0.0,
            relative_sigma: 0.02,
            relative_excited: true,
            relative_weakly_told: false,
            profile_describes: true,
        };
        let changes: Vec<StatusChange> = (0..60)
            .flat_map(|k| d.update(k as f64 * 0.2, [common, common]))
            .collect();
        assert!(changes.is_empty(), "{changes:?}");
        for side in Side::BOTH {
            assert_eq!(d.decision(side).status, ThrusterStatus::Nominal);
        }
    }

    #[test]
    fn normal_cdf_values() {
        assert!((normal_cdf(0.0) - 0.5).abs() < 1e-7);
        assert!((normal_cdf(1.0) - 0.841_344_746).abs() < 1e-7);
        assert!((normal_cdf(-1.96) - 0.024_997_895).abs() < 1e-7);
        assert!((normal_cdf(3.0) - 0.998_650_102).abs() < 1e-7);
    }

    #[test]
    fn not_excited_until_the_data_can_tell_then_nominal() {
        let mut d = FaultDecider::new(DecisionConfig::default());
        assert!(run(&mut d, &[(0.0, 0.3, 0.01, false), (10.0, 0.3, 0.01, false)]).is_empty());
        assert_eq!(d.decision(Side::Port).status, ThrusterStatus::NotExcited);
        run(&mut d, &[(11.0, 0.0, 0.01, true)]);
        assert_eq!(d.decision(Side::Port).status, ThrusterStatus::Nominal);
    }

    #[test]
    fn a_loss_is_confirmed_after_the_confirmation_time_with_its_onset() {
        let mut d = FaultDecider::new(DecisionConfig::default());
        let mut series = vec![];
        for k in 0..100 {
            let t = k as f64 * 0.2;
            // Loss appears at 5 s and ramps to 18 % by 8 s.
            let loss = if t < 5.0 {
                0.0
            } else {
                (0.06 * (t - 5.0)).min(0.18)
            };
            series.push((t, loss, 0.02, true));
        }
        let changes = run(&mut d, &series);
        let port: Vec<_> = changes.iter().filter(|c| c.side == Side::Port).collect();
        assert_eq!(port.len(), 1, "{port:?}");
        // Suspect evidence from t where loss >= 0.05 and loss - 0.05 >= 0.03:
        // t ~ 6.4 s; 3 s later the evidence shows a fault, declared at once
        // (no suspect on the way). The onset is the last sample before that
        // evidence with the loss below the clear level (5.4 s, 0.024), not
        // the confirmation.
        assert_eq!(port[0].to, ThrusterStatus::Fault);
        assert!((port[0].onset_time_s - 5.4).abs() < 0.05, "{:?}", port[0]);
        assert!((port[0].time_s - 9.4).abs() < 0.05, "{:?}", port[0]);
        assert!(port[0].confidence > 0.99);
        assert_eq!(
            d.decision(Side::Port).onset_time_s,
            Some(port[0].onset_time_s)
        );
        assert_eq!(d.overall(), ThrusterStatus::Fault);
        assert_eq!(d.decision(Side::Starboard).status, ThrusterStatus::Nominal);
        // A steady 7 % loss is a suspect, not a fault, declared after the
        // suspect's longer confirmation.
        let mut d = FaultDecider::new(DecisionConfig::default());
        let c = run(
            &mut d,
            &(0..400)
                .map(|k| (k as f64 * 0.1, 0.07, 0.01, true))
                .collect::<Vec<_>>(),
        );
        assert_eq!(c.len(), 1);
        assert_eq!(c[0].to, ThrusterStatus::Suspect);
        assert_eq!(c[0].onset_time_s, 0.0);
        assert!((c[0].time_s - 30.0).abs() < 0.05, "{:?}", c[0]);
    }

    /// `(time s, loss, sigma, excited)` held from step `ticks.start` to
    /// `ticks.end` (exclusive), `step_s` apart.
    fn steady(
        ticks: std::ops::Range<u32>,
        step_s: f64,
        loss: f64,
        sigma: f64,
        excited: bool,
    ) -> Vec<(f64, f64, f64, bool)> {
        ticks
            .map(|k| (f64::from(k) * step_s, loss, sigma, excited))
            .collect()
    }

    /// `changes` is one change, `from` to `to`.
    fn assert_one_change(changes: &[StatusChange], from: ThrusterStatus, to: ThrusterStatus) {
        assert_eq!(changes.len(), 1, "{changes:?}");
        assert_eq!((changes[0].from, changes[0].to), (from, to));
    }

    /// A `nominal` judged while the data told the loss is withdrawn once
    /// the estimate, no longer excited, has shown a suspect for 10 s (a
    /// steady turn one way with a loss from its start: the comparison is
    /// not told, yet reads 0.35 +- 0.05); one that wanders within the
    /// nominal band, or beyond it for less than 10 s, holds. Told again, a
    /// fault goes from `not_excited` straight to `fault`.
    #[test]
    fn a_nominal_the_unexcited_estimate_contradicts_is_withdrawn() {
        let mut d = FaultDecider::new(DecisionConfig::default());
        run(&mut d, &[(0.0, 0.0, 0.01, true), (1.0, 0.0, 0.01, true)]);
        assert_eq!(d.decision(Side::Port).status, ThrusterStatus::Nominal);
        // Within the band, and beyond it for 9 s: nothing.
        let mut series = steady(20..100, 0.1, 0.04, 0.05, false);
        series.extend(steady(100..190, 0.1, 0.35, 0.05, false));
        series.extend(steady(190..200, 0.1, 0.0, 0.05, false));
        assert!(run(&mut d, &series).is_empty());
        assert_eq!(d.decision(Side::Port).status, ThrusterStatus::Nominal);
        // Beyond it for 10 s: withdrawn, with how sure the claim still is.
        let c = run(&mut d, &steady(200..310, 0.1, 0.35, 0.05, false));
        assert_one_change(&c, ThrusterStatus::Nominal, ThrusterStatus::NotExcited);
        assert!((c[0].time_s - 30.0).abs() < 0.05, "{:?}", c[0]);
        assert!(c[0].confidence < 1e-6, "{:?}", c[0]);
        assert_eq!(d.decision(Side::Starboard).status, ThrusterStatus::Nominal);
        // Told again, the loss is a fault: one change, from not_excited.
        let c = run(&mut d, &steady(310..400, 0.1, 0.35, 0.05, true));
        assert_one_change(&c, ThrusterStatus::NotExcited, ThrusterStatus::Fault);
        // Withdrawn again on a healthy propeller, told healthy again: the
        // return to nominal is announced.
        let mut d = FaultDecider::new(DecisionConfig::default());
        run(&mut d, &[(0.0, 0.0, 0.01, true)]);
        run(&mut d, &steady(10..130, 0.1, 0.2, 0.04, false));
        assert_eq!(d.decision(Side::Port).status, ThrusterStatus::NotExcited);
        let c = run(&mut d, &[(13.0, 0.0, 0.01, true)]);
        assert_one_change(&c, ThrusterStatus::NotExcited, ThrusterStatus::Nominal);
    }

    /// Told for the first time with the estimate in the hysteresis gap
    /// (a loss of 0.17 +- 0.077 from the start: neither health nor a fault
    /// at two and a half sigmas) the propeller stays `not_excited`; a
    /// fault the data then show goes there in one change, and a healthy
    /// propeller becomes `nominal` only once its evidence shows it.
    #[test]
    fn a_first_tell_that_shows_no_health_is_no_nominal() {
        let mut d = FaultDecider::new(DecisionConfig::default());
        let gap = steady(0..300, 0.2, 0.17, 0.077, true);
        assert!(run(&mut d, &gap).is_empty());
        assert_eq!(d.decision(Side::Port).status, ThrusterStatus::NotExcited);
        assert_eq!(d.decision(Side::Starboard).status, ThrusterStatus::Nominal);
        let c = run(&mut d, &steady(300..330, 0.2, 0.2, 0.04, true));
        assert_one_change(&c, ThrusterStatus::NotExcited, ThrusterStatus::Fault);
        let mut d = FaultDecider::new(DecisionConfig::default());
        run(&mut d, &gap);
        assert!(run(&mut d, &[(61.0, 0.01, 0.03, true)]).is_empty());
        assert_eq!(d.decision(Side::Port).status, ThrusterStatus::Nominal);
    }

    #[test]
    fn level_and_time_hysteresis_prevent_chatter() {
        let mut d = FaultDecider::new(DecisionConfig::default());
        // Once told healthy, a noisy loss around 5 % with small sigma:
        // hovering in the gap (0.03..0.05) never clears, and short
        // excursions never confirm.
        let mut series = vec![(-0.1, 0.0, 0.005, true)];
        for k in 0..600 {
            let t = k as f64 * 0.1;
            let loss = if k % 20 < 5 { 0.07 } else { 0.04 };
            series.push((t, loss, 0.005, true));
        }
        let changes = run(&mut d, &series);
        assert!(changes.is_empty(), "{changes:?}");
        assert_eq!(d.decision(Side::Port).status, ThrusterStatus::Nominal);
        // A fault is held while not excited, and clears only after 10 s of
        // clear evidence.
        let mut d = FaultDecider::new(DecisionConfig::default());
        run(
            &mut d,
            &(0..100)
                .map(|k| (k as f64 * 0.1, 0.2, 0.01, true))
                .collect::<Vec<_>>(),
        );
        assert_eq!(d.decision(Side::Port).status, ThrusterStatus::Fault);
        run(
            &mut d,
            &(100..400)
                .map(|k| (k as f64 * 0.1, 0.0, 0.5, false))
                .collect::<Vec<_>>(),
        );
        assert_eq!(d.decision(Side::Port).status, ThrusterStatus::Fault);
        let c = run(
            &mut d,
            &(400..495)
                .map(|k| (k as f64 * 0.1, 0.0, 0.01, true))
                .collect::<Vec<_>>(),
        );
        assert!(c.is_empty());
        let c = run(
            &mut d,
            &(495..520)
                .map(|k| (k as f64 * 0.1, 0.0, 0.01, true))
                .collect::<Vec<_>>(),
        );
        assert_eq!(c.len(), 1);
        assert_eq!(c[0].to, ThrusterStatus::Nominal);
        assert!(d.decision(Side::Port).onset_time_s.is_none());
    }

    #[test]
    fn a_fault_wandering_near_its_threshold_stays_a_fault_until_confidently_below() {
        let mut d = FaultDecider::new(DecisionConfig::default());
        run(
            &mut d,
            &(0..100)
                .map(|k| (k as f64 * 0.1, 0.2, 0.02, true))
                .collect::<Vec<_>>(),
        );
        assert_eq!(d.decision(Side::Port).status, ThrusterStatus::Fault);
        // 0.08 +- 0.03 for a minute: within reach of the fault level at two
        // sigmas, so no evidence of a suspect; the fault holds.
        let c = run(
            &mut d,
            &(100..700)
                .map(|k| (k as f64 * 0.1, 0.08, 0.03, true))
                .collect::<Vec<_>>(),
        );
        assert!(c.is_empty(), "{c:?}");
        assert_eq!(d.decision(Side::Port).status, ThrusterStatus::Fault);
        // 0.07 +- 0.01: confidently below the fault level, above the clear
        // level: a suspect after the clearing time, the episode's onset kept.
        let c = run(
            &mut d,
            &(700..900)
                .map(|k| (k as f64 * 0.1, 0.07, 0.01, true))
                .collect::<Vec<_>>(),
        );
        assert_eq!(c.len(), 1, "{c:?}");
        assert_eq!(
            (c[0].from, c[0].to),
            (ThrusterStatus::Fault, ThrusterStatus::Suspect)
        );
        assert!((c[0].time_s - 80.0).abs() < 0.05, "{:?}", c[0]);
        assert_eq!(d.decision(Side::Port).onset_time_s, Some(0.0));
    }

    /// A comparison told only weakly, nothing else told.
    fn weakly(relative_loss: f64) -> LossEvidence {
        LossEvidence {
            loss: relative_loss.max(0.0),
            sigma: 0.5,
            excited: false,
            relative_loss,
            relative_sigma: 0.08,
            relative_excited: false,
            relative_weakly_told: true,
            profile_describes: true,
        }
    }

    #[test]
    fn a_weakly_told_fault_must_last_half_a_minute_and_claims_nothing_else() {
        let feed = |d: &mut FaultDecider, from: usize, to: usize, port: f64| -> Vec<StatusChange> {
            (from..to)
                .flat_map(|k| d.update(k as f64 * 0.2, [weakly(port), weakly(-port)]))
                .collect()
        };
        // 0.3 +- 0.08: fault evidence (0.3 - 0.2 >= 0.05), but weak.
        let mut d = FaultDecider::new(DecisionConfig::default());
        assert!(feed(&mut d, 0, 145, 0.3).is_empty());
        assert_eq!(d.decision(Side::Port).status, ThrusterStatus::NotExcited);
        let c = feed(&mut d, 145, 155, 0.3);
        assert_eq!(c.len(), 1, "{c:?}");
        assert_eq!(
            (c[0].from, c[0].to, c[0].time_s),
            (ThrusterStatus::NotExcited, ThrusterStatus::Fault, 30.0)
        );
        // The other side's weak comparison shows nothing worse than
        // nominal: it is not called nominal on weak evidence.
        assert_eq!(
            d.decision(Side::Starboard).status,
            ThrusterStatus::NotExcited
        );
        // Weak fault evidence that lapses before the half minute is nothing.
        let mut d = FaultDecider::new(DecisionConfig::default());
        assert!(feed(&mut d, 0, 100, 0.3).is_empty());
        assert!(feed(&mut d, 100, 101, 0.1).is_empty());
        assert!(feed(&mut d, 101, 200, 0.3).is_empty());
        assert_eq!(d.decision(Side::Port).status, ThrusterStatus::NotExcited);
    }

    /// Told nominal, then the profile stops describing the vessel: the
    /// health is withdrawn after `mismatch_withdraw_s` and not claimed
    /// again until the profile describes it; a fault holds throughout, and
    /// none is raised.
    #[test]
    fn a_profile_mismatch_withdraws_a_health_claim_and_holds_a_fault() {
        let cfg = DecisionConfig::default();
        let mut d = FaultDecider::new(cfg);
        let at = |loss: f64, describes: bool| LossEvidence {
            profile_describes: describes,
            ..absolute(loss, 0.02, true)
        };
        let feed = |d: &mut FaultDecider, from: usize, to: usize, port: f64, describes: bool| {
            (from..to)
                .flat_map(|k| d.update(k as f64 * 0.2, [at(port, describes), at(0.0, describes)]))
                .collect::<Vec<_>>()
        };
        // Nominal while the profile describes the vessel (0-20 s).
        assert!(feed(&mut d, 0, 100, 0.0, true).is_empty());
        assert_eq!(d.decision(Side::Port).status, ThrusterStatus::Nominal);
        // From 20 s it does not, and the estimate still reads healthy: the
        // claim holds 10 s, then both sides are withdrawn at once.
        let c = feed(&mut d, 100, 149, 0.0, false);
        assert!(c.is_empty(), "{c:?}");
        let c = feed(&mut d, 149, 151, 0.0, false);
        assert_eq!(c.len(), 2, "{c:?}");
        for change in &c {
            assert_eq!(
                (change.from, change.to),
                (ThrusterStatus::Nominal, ThrusterStatus::NotExcited)
            );
            assert!((change.time_s - 30.0).abs() < 1e-9, "{change:?}");
            assert!((change.onset_time_s - 20.0).abs() < 1e-9, "{change:?}");
        }
        // Healthy readings under the mismatch claim nothing.
        assert!(feed(&mut d, 151, 300, 0.0, false).is_empty());
        assert_eq!(d.decision(Side::Port).status, ThrusterStatus::NotExcited);
        // The profile describes the vessel again: nominal, said as a change.
        let c = feed(&mut d, 300, 301, 0.0, true);
        assert_eq!(c.len(), 2, "{c:?}");
        assert!(
            c.iter()
                .all(|x| (x.from, x.to) == (ThrusterStatus::NotExcited, ThrusterStatus::Nominal))
        );

        // A fault declared before the mismatch holds through it, even where
        // the estimate then reads healthy, and a suspect is not stepped down.
        let mut d = FaultDecider::new(cfg);
        feed(&mut d, 0, 100, 0.3, true);
        assert_eq!(d.decision(Side::Port).status, ThrusterStatus::Fault);
        let c = feed(&mut d, 100, 400, 0.0, false);
        assert_eq!(d.decision(Side::Port).status, ThrusterStatus::Fault);
        assert!(c.iter().all(|x| x.side == Side::Starboard), "{c:?}");
        // Nor is a fault read off the model under the mismatch: the claim
        // of health is withdrawn, no warning is raised.
        let mut d = FaultDecider::new(cfg);
        feed(&mut d, 0, 100, 0.0, true);
        let c = feed(&mut d, 100, 250, 0.3, false);
        assert_eq!(d.decision(Side::Port).status, ThrusterStatus::NotExcited);
        assert!(
            c.iter().all(|x| x.to == ThrusterStatus::NotExcited),
            "{c:?}"
        );
        // Once the profile describes the vessel again, the same evidence
        // is a fault.
        feed(&mut d, 250, 300, 0.3, true);
        assert_eq!(d.decision(Side::Port).status, ThrusterStatus::Fault);
    }

    #[test]
    fn an_uncertain_large_estimate_is_not_a_fault() {
        let mut d = FaultDecider::new(DecisionConfig::default());
        // 15 % +- 10 %: not distinguishable from zero at two and a half sigmas.
        let c = run(
            &mut d,
            &(0..200)
                .map(|k| (k as f64 * 0.1, 0.15, 0.10, true))
                .collect::<Vec<_>>(),
        );
        assert!(c.is_empty(), "{c:?}");
    }
}
