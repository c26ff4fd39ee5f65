//! Prediction after calibration, as the seed's Table 4.9: calibrate on the
//! broken-port S-manoeuvre up to a split, predict open loop to the end of the
//! run from the recorded inputs, compare with the truth; and the calibration
//! of the extended twin's forecast bands.
//!
//! Two facts shape these tests (docs/accuracy.md): the seed method's
//! "recorded inputs" are derived from the GNSS track over the horizon itself,
//! so its prediction is fed the future it predicts; and the Otter's hull is
//! directionally unstable in open loop (the Munk moment), so an open-loop
//! forecast through the recorded commands, which the autopilot made to
//! answer gusts the forecast does not know, turns away from the truth over
//! tens of seconds, the simulated vessel's own replay as much as the
//! extended twin's. Its bands widen accordingly.

use xtask::trials::{
    Cell, TrialPath, forecast_coverage, live_forecast_rmse, loss_sets, prediction_comparison,
    seed_sets,
};

/// The forecast's 1-sigma band holds the truth 60-75 % of the time and the
/// 2-sigma band 90-98 %, over the S-manoeuvre cells in harbour water (12
/// propeller sets, 2 noise seeds, forecasts from 40, 60 and 80 s to the end).
#[test]
fn forecast_bands_hold_the_truth_at_their_stated_rates() {
    let (mut w1, mut w2, mut n) = (0, 0, 0);
    for set in seed_sets(0.18).into_iter().chain(loss_sets()) {
        for seed in [1000, 1001] {
            let cell = Cell {
                path: TrialPath::SManoeuvre,
                set,
                current: None,
                seed,
            };
            let (a, b, m) =
                forecast_coverage(&cell, xtask::trials::trials_twin(), &[40.0, 60.0, 80.0]);
            w1 += a;
            w2 += b;
            n += m;
        }
    }
    let (f1, f2) = (w1 as f64 / n as f64, w2 as f64 / n as f64);
    println!(
        "forecast coverage over {n} predicted positions: 1-sigma {:.1} %, 2-sigma {:.1} %",
        100.0 * f1,
        100.0 * f2
    );
    assert!((0.60..=0.75).contains(&f1), "{f1}");
    assert!((0.90..=0.98).contains(&f2), "{f2}");
}

/// Like for like on the seed's run: in calm water, after a minute the
/// extended twin's position errors are a fraction of the seed method's; in
/// harbour water neither predicts a minute ahead well, and the extended twin
/// says so (the truth stays within three of its standard deviations).
///
/// Why the seed method's harbour figures are the better ones: its inputs
/// are derived from the track it predicts (held at the split instead, its
/// 30 s and 60 s errors grow past those figures), while the extended twin's
/// error at 30 s and 60 s is that of the simulated vessel itself, started
/// from its true state on the recorded commands with calm water ahead
/// (within 25 %): the disturbance to come, which the recorded commands
/// answer, is what neither knows. In calm water that replay is the truth.
#[test]
fn prediction_after_calibration_against_the_seed_method() {
    let horizontal = |r: [f64; 4]| r[0].hypot(r[1]);
    for calm in [true, false] {
        for horizon in [10.0, 30.0, 60.0] {
            let (mut seed_rmse, mut ext_rmse, mut worst_z) = ([0.0; 4], [0.0; 4], 0.0f64);
            let (mut seed_held_m, mut replay_m) = (0.0, 0.0);
            let seeds = [1000, 1001, 1002];
            for seed in seeds {
                let p = prediction_comparison(seed, horizon, calm);
                for i in 0..4 {
                    seed_rmse[i] += p.seed_rmse[i] / seeds.len() as f64;
                    ext_rmse[i] += p.extended_rmse[i] / seeds.len() as f64;
                }
                seed_held_m += horizontal(p.seed_held_rmse) / seeds.len() as f64;
                replay_m += horizontal(p.replay_rmse) / seeds.len() as f64;
                worst_z = worst_z
                    .max(p.extended_final_error_sigmas[0].max(p.extended_final_error_sigmas[1]));
            }
            println!(
                "{} water, {horizon} s: RMSE [north m, east m, SOG m/s, COG rad] seed method {seed_rmse:.3?}, \
                 extended twin {ext_rmse:.3?}; extended final error {worst_z:.2} sigma at worst",
                if calm { "calm" } else { "harbour" }
            );
            let (seed_m, ext_m) = (horizontal(seed_rmse), horizontal(ext_rmse));
            println!(
                "  position RMSE, m: seed method {seed_m:.2}, held input {seed_held_m:.2}; \
                 extended twin {ext_m:.2}; the vessel itself without the disturbance ahead {replay_m:.2}"
            );
            assert!(worst_z < 3.0, "{worst_z}");
            if calm {
                assert!(replay_m < 0.05, "{replay_m}");
            }
            if horizon >= 30.0 {
                assert!(seed_held_m > seed_m, "{seed_held_m} vs {seed_m}");
                if !calm {
                    assert!(ext_m <= 1.25 * replay_m, "{ext_m} vs {replay_m}");
                }
            }
            if calm && horizon == 60.0 {
                assert!(ext_rmse[0] < 0.5 * seed_rmse[0] && ext_rmse[1] < 0.5 * seed_rmse[1]);
            }
        }
    }
}

/// The live forecasts, as `twin/prediction` publishes them (each twin's
/// input held at the split), over many splits of the broken-port
/// S-manoeuvre (every 5 s from 40 s, three noise seeds): the extended
/// twin's horizontal position error is no larger than the seed method's at
/// any horizon, in calm and in harbour water.
#[test]
fn the_live_forecast_is_at_least_as_good_as_the_seed_methods_at_every_horizon() {
    for calm in [true, false] {
        for horizon in [10.0, 30.0, 60.0] {
            let ([seed_m, twin_m], splits) = live_forecast_rmse(&[1000, 1001, 1002], horizon, calm);
            let water = if calm { "calm" } else { "harbour" };
            println!(
                "{water} water, {horizon} s, {splits} live forecasts: position RMSE seed method {seed_m:.2} m, extended twin {twin_m:.2} m"
            );
            assert!(splits >= 15, "{splits} forecasts");
            assert!(twin_m > 0.0 && seed_m > 0.0, "forecasts were scored");
            assert!(
                twin_m <= seed_m,
                "{water}, {horizon} s: {twin_m} vs {seed_m}"
            );
        }
    }
}
