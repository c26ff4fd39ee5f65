//! `twin analyze --mcap FILE`: what went into the twin and what it
//! concluded, as an MCAP recording (`twin_wire::mcap`) of the vessel
//! [`MCAP_VESSEL`]: every assembled input (`gnss`, `actuators`), and per
//! accepted fix the state (and its location), the fault, and the alarms of
//! that step, each logged at the time it carries (the fix's).

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use twin_core::twin::StepOutput;
use twin_wire::Topic;
use twin_wire::assemble::Assembled;
use twin_wire::mcap::{McapError, McapRecorder};
use twin_wire::messages::{ActuatorCommand, encode_actuators, encode_gnss};
use twin_wire::outputs::{AlarmMessage, FaultMessage, StateMessage};

use super::AnalyzeError;

/// The vessel id of the recording's channels (`/log/gnss`, `/log/twin/state`...).
pub const MCAP_VESSEL: &str = "log";

/// The recording being written; the first error is kept for the end.
pub(super) struct AnalyzeRecorder {
    path: PathBuf,
    recorder: McapRecorder<BufWriter<File>>,
    error: Option<McapError>,
}

impl AnalyzeRecorder {
    /// Creates the file.
    pub(super) fn create(path: &Path) -> Result<Self, AnalyzeError> {
        let error = |source| AnalyzeError::Mcap {
            path: path.to_path_buf(),
            source,
        };
        let file = File::create(path).map_err(|e| error(McapError::Mcap(e.into())))?;
        Ok(Self {
            path: path.to_path_buf(),
            recorder: McapRecorder::new(BufWriter::new(file)).map_err(error)?,
            error: None,
        })
    }

    fn record(&mut self, topic: Topic, payload: &[u8], time_s: f64) {
        if self.error.is_none()
            && let Err(e) = self.recorder.record(MCAP_VESSEL, topic, payload, time_s)
        {
            self.error = Some(e);
        }
    }

    /// An input as the twin receives it; one the contract cannot carry is
    /// left out.
    pub(super) fn input(&mut self, a: &Assembled) {
        let (topic, time_s, payload) = match a {
            Assembled::Fix(fix) => (Topic::Gnss, fix.time_s, encode_gnss(fix, true)),
            Assembled::Propellers(p) => (
                Topic::Actuators,
                p.time_s,
                encode_actuators(&ActuatorCommand::Speeds(*p), true),
            ),
            Assembled::Thrust(t) => (
                Topic::Actuators,
                t.time_s,
                encode_actuators(&ActuatorCommand::Thrust(*t), true),
            ),
        };
        if let Ok(payload) = payload {
            self.record(topic, &payload, time_s);
        }
    }

    /// The outputs of one accepted fix.
    pub(super) fn step(&mut self, out: &StepOutput) {
        let time_s = out.state.time_s;
        let state = StateMessage::new(MCAP_VESSEL, &out.state, false, true);
        let fault = FaultMessage::new(MCAP_VESSEL, &out.faults, true);
        for (topic, json) in [
            (Topic::TwinState, serde_json::to_vec(&state)),
            (Topic::TwinFault, serde_json::to_vec(&fault)),
        ] {
            if let Ok(json) = json {
                self.record(topic, &json, time_s);
            }
        }
        for change in &out.changes {
            let alarm = AlarmMessage::new(MCAP_VESSEL, change, true);
            if let Ok(json) = serde_json::to_vec(&alarm) {
                self.record(Topic::TwinAlarm, &json, change.time_s);
            }
        }
    }

    /// Ends the file; the first error, if any.
    pub(super) fn finish(self) -> Result<(), AnalyzeError> {
        let error = |source| AnalyzeError::Mcap {
            path: self.path.clone(),
            source,
        };
        if let Some(e) = self.error {
            return Err(error(e));
        }
        self.recorder.finish().map(|_| ()).map_err(error)
    }
}
