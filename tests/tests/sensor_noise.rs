//! The trust matrix's sensor noise scale (`Draw::sensor_noise_scale`, the
//! example's `--sensor-noise-scale`): on the project's simulator it scales
//! what the logged fixes carry of the sensors' noise, so that a bias an
//! estimate keeps at the sensors' noise and loses without it can be told
//! from the model's. Checked on a straight run in calm water: the logged
//! positions against the true track, and the step-to-step scatter of the
//! logged speed over ground and heading (the vessel's own changes over a
//! fix interval being far smaller than the sensors' noise there).

use twin_core::geodesy::{LocalFrame, wrap_pi};
use twin_core::sample::GnssFix;
use twin_tests::trust::{Class, Draw, Simulator, assembled, draws, simulate};
use twin_wire::Assembled;

/// What a trial's logged fixes carry of the sensors' noise.
struct Scatter {
    /// Root mean square distance of the fixes from the true track at the
    /// same times, m.
    position_m: f64,
    /// Root mean square change of the speed over ground from fix to fix
    /// after the first 30 s, m/s.
    sog_step_mps: f64,
    /// The same of the heading, rad.
    heading_step_rad: f64,
}

/// The root mean square of `values`.
fn rms(values: &[f64]) -> f64 {
    (values.iter().map(|v| v * v).sum::<f64>() / values.len() as f64).sqrt()
}

fn scatter(draw: &Draw) -> Scatter {
    let trial = simulate(draw).expect("the project's simulator runs");
    let fixes: Vec<GnssFix> = assembled(&trial)
        .into_iter()
        .filter_map(|i| match i {
            Assembled::Fix(f) => Some(f),
            _ => None,
        })
        .collect();
    let settled: Vec<&GnssFix> = fixes
        .iter()
        .filter(|f| f.time_s - trial.start_s >= 30.0)
        .collect();
    let steps = |read: &dyn Fn(&GnssFix) -> Option<f64>, wrap: bool| {
        let d: Vec<f64> = settled
            .windows(2)
            .filter_map(|w| Some(read(w[1])? - read(w[0])?))
            .map(|d| if wrap { wrap_pi(d) } else { d })
            .collect();
        assert!(d.len() > 100, "{} steps", d.len());
        rms(&d)
    };
    Scatter {
        position_m: position_error_rms_m(&trial, &fixes),
        sog_step_mps: steps(&|f| f.sog_mps, false),
        heading_step_rad: steps(&|f| f.heading_rad, true),
    }
}

/// The root mean square distance of `fixes` from `trial`'s true track at
/// the same times, m.
fn position_error_rms_m(trial: &twin_tests::trust::Trial, fixes: &[GnssFix]) -> f64 {
    let frame = LocalFrame::new(trial.track[0].1).expect("a valid origin");
    let mut sum_square = 0.0;
    let mut count = 0.0;
    for fix in fixes {
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
    let drawn = draws(Simulator::Own, Class::ALL.len(), 7)
        .into_iter()
        .find(|d| d.class == Class::Straight)
        .expect("every block of classes has a straight run");
    assert_eq!(
        drawn.sensor_noise_scale, 1.0,
        "the matrix's draws are as drawn"
    );
    let noisy = Draw {
        calm_water: true,
        ..drawn
    };
    let quiet = Draw {
        sensor_noise_scale: 0.1,
        ..noisy
    };
    let (noisy, quiet) = (scatter(&noisy), scatter(&quiet));
    for (what, loud, low) in [
        ("position error, m", noisy.position_m, quiet.position_m),
        ("SOG step, m/s", noisy.sog_step_mps, quiet.sog_step_mps),
        (
            "heading step, rad",
            noisy.heading_step_rad,
            quiet.heading_step_rad,
        ),
    ] {
        assert!(
            (0.07..0.13).contains(&(low / loud)),
            "{what}: {low:.4} at a tenth of the noise against {loud:.4}"
        );
    }
}
