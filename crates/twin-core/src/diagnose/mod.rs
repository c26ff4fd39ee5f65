//! `diagnose`: what the twin's model gets wrong on measured data, the cause,
//! the extended model, and the gain, measured on data the fit never saw.
//!
//! # Method
//! 1. **Prepare.** The log's fixes (position, speed and course over ground,
//!    heading), speed through water and propeller speeds are put on one
//!    time line in the local frame ([`prepare`]).
//! 2. **Base model.** With propeller speeds, the Otter's kinetic twin
//!    ([`crate::models::otter_twin`]); without, a kinematic model of any
//!    vessel through water ([`crate::models::water_kinematic`]). The nominal
//!    model has no current, no propeller loss and no sensor effect.
//! 3. **Residuals of the nominal model** (`residuals`): innovation bias,
//!    whiteness, NIS against its chi-square band, k-step-ahead prediction
//!    errors at several horizons, and the correlation of the innovations
//!    with candidate signatures (heading, speed, turn rate, acceleration,
//!    time).
//! 4. **Catalogue of causes** ([`Cause`], declared as data in
//!    `catalogue`): the water current (two states), a loss per propeller
//!    (where propeller data exist), a heading-sensor offset, a scale error
//!    of the reported SOG or of the speed through water, GNSS latency, the
//!    GNSS antenna's lever arm, a sideslip in turns (kinematic base; of
//!    two shapes, never named together: a sway per yaw rate, or one that
//!    also grows with the speed through water), a
//!    scale error of the rate sensor's yaw rate, and the vessel's own
//!    dynamics on the kinetic base: its surge damping, yaw damping and mass
//!    over the profile's. Each is fitted on the first part
//!    of the log (states: estimated by the filter; parameters: maximum
//!    likelihood over the filter's one-step-ahead predictions, within the
//!    cause's physical bounds), then held fixed and judged on the held-out
//!    rest against the model without it. A fit that wants to leave its
//!    physical bounds (a negative latency, an antenna off the hull, a
//!    negative loss, a current of several m/s) is evidence of something
//!    else and is rejected with what it means.
//! 5. **Selection.** Greedy: the cause with the largest held-out gain is
//!    accepted if it clears three bars fixed in advance ([`Acceptance`]): the
//!    held-out log-likelihood gains at least `min_gain_nll` (a likelihood
//!    ratio of e^10 by default; a parameter that only fits noise loses
//!    held-out likelihood), the fitted size is at least `min_z` standard
//!    deviations from none, and at least the practical size a user would
//!    act on; of two causes whose gains are within `min_gain_nll` of each
//!    other, the one with fewer parameters, and of two with as many, the
//!    one that does not say a sensor is wrong. A scalar cause about to be
//!    accepted must sit at a minimum of its training likelihood: where the
//!    slope read over a thousandth of its standard deviation puts the
//!    minimum more than three of them away, Newton steps move it there and
//!    it is judged again, and where they find none it is not named (a
//!    likelihood that jumps, as after a standstill without a heading
//!    sensor, gives fits and standard deviations that say nothing of the
//!    data). Then the others are tried again
//!    on top of it, until none clears the bars: combined effects are found
//!    one after the other. Then each finding is judged again against the
//!    model with all the others, and one that no longer gains
//!    `min_gain_nll` is dropped; each is fitted again with the others in
//!    the model (a joint refit, one cause at a time), and every cause not
//!    named is fitted in its place: one that explains the held-out data
//!    better by `min_gain_nll`, or as well with fewer parameters, without
//!    forecasting worse, replaces it (the greedy order can name first what
//!    imitates two effects at once), and one whose refit no longer clears
//!    its bars is dropped. A part of a cause that another cause imitates exactly on
//!    steady motion (the loss both propellers share, and the hull's
//!    resistance) is fitted with that cause beside it, as a candidate of
//!    its own in each round, and once more at the end; where the data do
//!    not tell the two apart, the split that leaves none shared is named. A cause of the vessel's dynamics
//!    must make the held-out forecasts better over the horizons taken
//!    together (a steady force it only absorbs makes them worse). Last,
//!    the sizes of a yaw damping, a mass and a yaw-rate scale finding are
//!    fitted again jointly with the level of the velocities' process noise
//!    per axis (`noise_level`): the search holds that noise at the harbour
//!    water's, and a likelihood maximised with a noise level that is not
//!    the data's biases a dynamics parameter towards a faster-contracting
//!    hull, and a rate sensor's scale below one.
//!    In every round, a loss candidate whose estimate rises more than 30 s
//!    into the log is a step: its size and onset are fitted as one on the
//!    training part (the filter's estimate at the split lags a step, and
//!    shortly after the onset is a transient). At the end, where no loss
//!    is named, the losses are tracked by the filter
//!    through the held-out part as well: a loss that starts there, with
//!    nothing to fit in the training part, is named where the tracked
//!    losses are nothing at the split and clear the same bars on the
//!    held-out part, its size and onset fitted as a step over the whole
//!    log.
//! 6. **Report** ([`Diagnosis`]): per finding the cause, its parameters
//!    with uncertainty, the evidence in the residuals, and the gain on
//!    held-out data against the model with every other finding
//!    (log-likelihood, NIS per degree of freedom, position prediction RMSE
//!    at each horizon, without and with it); and
//!    [`Unexplained`] when the findings leave the held-out residuals well
//!    outside what the filter expects.
//!
//! 7. **Live** ([`LiveMonitor`]): the daemon keeps the recent past per
//!    vessel and diagnoses it on an interval, or earlier when the live twin's
//!    innovations turn biased.
//! 8. **Identification** ([`identify()`]): a vessel profile's mass and damping
//!    from a trial of the healthy vessel, on the same passes and the same
//!    held-out judging.
//!
//! Pure like the rest of the crate: the log comes in as values; nothing is
//! read, no clock is used. The truth of a simulated log is never an input.

// Measurement components are indexed across parallel arrays (innovation,
// sigma, availability, statistics); an index loop says so most plainly.
#![allow(clippy::needless_range_loop)]

mod catalogue;
mod fit;
mod identify;
mod monitor;
mod noise_level;
mod pass;
mod prepare;
mod residuals;

pub use catalogue::Cause;
pub use fit::{
    Acceptance, BaseModel, DiagnoseConfig, Diagnosis, Finding, Gain, Rejected, Unexplained,
    diagnose,
};
pub use identify::{
    Fallback, HeldOut, IDENTIFIED_PARAMETERS, Identification, IdentifyConfig, ParameterEstimate,
    identify,
};
pub use monitor::{BIAS_BATCHES, LiveMonitor, MonitorConfig, Trigger};
pub use prepare::{DiagEvent, Prepared, UNDER_WAY_MPS, prepare};
pub use residuals::{
    COMPONENT_COUNT, COMPONENTS, InnovationRecord, ResidualSummary, SIGNATURES,
    SignatureCorrelation,
};
