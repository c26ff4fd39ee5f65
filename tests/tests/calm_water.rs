//! The trust matrix's calm water (`Draw::calm_water`, the example's
//! `--calm`): a draw sailed with it has no random forces of the water on
//! either simulator, so what an estimate keeps there is the vessel's
//! difference from its profile alone. Checked on the true track of a
//! straight run: in the harbour water the vessel wanders across its line,
//! in calm water it hardly does.

use twin_core::geodesy::{LatLon, LocalFrame};
use twin_tests::trust::{Class, Draw, Simulator, draws, other_simulator_unavailable, simulate};

/// A straight run of `simulator`'s draws, with the water as drawn.
fn straight_run(simulator: Simulator) -> Draw {
    draws(simulator, Class::ALL.len(), 7)
        .into_iter()
        .find(|d| d.class == Class::Straight)
        .expect("every block of classes has a straight run")
}

/// The standard deviation of the true track's cross-track (east) position
/// after the first 30 s, m: the straight run sails north.
fn cross_track_spread_m(draw: &Draw) -> f64 {
    let trial = simulate(draw).expect("the simulator runs");
    let origin: LatLon = trial.track[0].1;
    let frame = LocalFrame::new(origin).expect("a valid origin");
    let east: Vec<f64> = trial
        .track
        .iter()
        .filter(|(t, _)| *t >= 30.0)
        .map(|(_, p)| frame.to_local(*p).east_m)
        .collect();
    let mean = east.iter().sum::<f64>() / east.len() as f64;
    (east.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / east.len() as f64).sqrt()
}

fn check(simulator: Simulator) {
    let rough = straight_run(simulator);
    assert!(
        !rough.calm_water,
        "the matrix's draws have the harbour water"
    );
    let calm = Draw {
        calm_water: true,
        ..rough
    };
    let (rough_m, calm_m) = (cross_track_spread_m(&rough), cross_track_spread_m(&calm));
    assert!(
        calm_m < 0.5 * rough_m,
        "{}: cross-track spread {calm_m:.3} m in calm water against {rough_m:.3} m in the harbour's",
        simulator.name()
    );
}

#[test]
fn calm_water_takes_the_waters_forces_out_of_the_projects_simulator() {
    check(Simulator::Own);
}

#[test]
fn calm_water_takes_the_waters_forces_out_of_the_independent_simulator() {
    if let Some(why) = other_simulator_unavailable() {
        panic!("the independent simulator cannot run: {why}");
    }
    check(Simulator::Other);
}
