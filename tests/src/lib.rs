//! Shared helpers of the cross-crate tests: run the twin over a simulated
//! trial and collect what the tests judge.

use twin_core::geodesy::wrap_pi;
use twin_core::twin::{StepOutput, TwinConfig, VesselTwin};
use twin_sim::{SensorEvent, SimRun};

/// What a run of the twin over a simulated trial gives.
#[derive(Debug, Clone)]
pub struct TwinRun {
    /// Every accepted fix's output, in order.
    pub outputs: Vec<StepOutput>,
    /// Rejections by reason.
    pub rejected: Vec<&'static str>,
    /// The twin at the end.
    pub twin: VesselTwin,
}

/// Feeds the simulator's GNSS fixes and measured propeller speeds to a twin
/// (propeller data only if `with_propellers`), in time order.
pub fn run_twin(run: &SimRun, config: TwinConfig, with_propellers: bool) -> TwinRun {
    let mut twin = VesselTwin::new(config).expect("valid config");
    let mut outputs = Vec::new();
    let mut rejected = Vec::new();
    for event in &run.events {
        match event {
            SensorEvent::Gnss(fix) => match twin.on_gnss(fix) {
                Ok(out) => outputs.push(out),
                Err(e) => rejected.push(e.reason()),
            },
            SensorEvent::PropellerMeasured(p) if with_propellers => {
                if let Err(e) = twin.on_propellers(p) {
                    rejected.push(e.reason());
                }
            }
            _ => {}
        }
    }
    TwinRun {
        outputs,
        rejected,
        twin,
    }
}

/// Smallest signed difference of two angles, for comparing courses.
pub fn angle_error(a: f64, b: f64) -> f64 {
    wrap_pi(a - b)
}
