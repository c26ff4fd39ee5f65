//! The trust matrix's sensor noise scale (`Draw::sensor_noise_scale`, the
//! example's `--sensor-noise-scale`): on the project's simulator it scales
//! what the logged fixes carry of the sensors' noise, so that a bias an
//! estimate keeps at the sensors' noise and loses without it can be told
//! from the model's. Checked on the logged positions of a straight run
//! against its true track.

use twin_core::geodesy::LocalFrame;
use twin_tests::trust::{Class, Draw, Simulator, assembled, draws, simulate};
use twin_wire::Assembled;

/// The root mean square distance of the logged fixes from the true track
/// at the same times, m.
fn position_error_rms_m(draw: &Draw) -> f64 {
    let trial = simulate(draw).expect("the project's simulator runs");
    let items = assembled(&trial);
    let frame = LocalFrame::new(trial.track[0].1).expect("a valid origin");
    let mut sum_square = 0.0;
    let mut count = 0.0;
    for fix in items.iter().filter_map(|i| match i {
        Assembled::Fix(f) => Some(f),
        _ => None,
    }) {
        let elapsed_s = fix.time_s - trial.start_s;
        let Some((_, truth)) = trial
            .track
            .iter()
            .find(|(t, _)| (t - elapsed_s).abs() < 1e-6)
        else {
            continue;
        };
        let (logged, truth) = (frame.to_local(fix.position), frame.to_local(*truth));
        sum_square +=
            (logged.north_m - truth.north_m).powi(2) + (logged.east_m - truth.east_m).powi(2);
        count += 1.0;
    }
    assert!(count > 100.0, "{count} fixes matched the true track");
    (sum_square / count).sqrt()
}

#[test]
fn the_sensor_noise_scale_scales_the_project_simulators_noise() {
    let noisy = draws(Simulator::Own, Class::ALL.len(), 7)
        .into_iter()
        .find(|d| d.class == Class::Straight)
        .expect("every block of classes has a straight run");
    assert_eq!(
        noisy.sensor_noise_scale, 1.0,
        "the matrix's draws are as drawn"
    );
    let quiet = Draw {
        sensor_noise_scale: 0.1,
        ..noisy
    };
    let (noisy_m, quiet_m) = (position_error_rms_m(&noisy), position_error_rms_m(&quiet));
    let ratio = quiet_m / noisy_m;
    assert!(
        (0.07..0.13).contains(&ratio),
        "position error {quiet_m:.3} m at a tenth of the noise against {noisy_m:.3} m"
    );
}
