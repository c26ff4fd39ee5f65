//! Prediction after calibration, as the seed's Table 4.9: calibrate on the
//! first 60 s of the broken-port S-manoeuvre, predict the last 60 s open loop
//! from the recorded inputs, compare with the truth.

use twin_cli::trials::{SEED_TABLE_4_9_PCT, prediction_comparison};

#[test]
fn extended_twin_predicts_better_than_the_seed_method() {
    for seed in [1000, 1001, 1002] {
        let p = prediction_comparison(seed, 60.0);
        println!(
            "seed {seed}: 60 s RMSE [north m, east m, speed m/s, course rad]: seed method {:.3?}, extended twin {:.3?}; \
             as % of the state's range: {:.2?} vs {:.2?} (seed's published table: {:?})",
            p.seed_rmse, p.extended_rmse, p.seed_rmse_pct, p.extended_rmse_pct, SEED_TABLE_4_9_PCT
        );
        for i in 0..4 {
            assert!(
                p.extended_rmse[i] < p.seed_rmse[i],
                "state {i}: {:?} vs {:?}",
                p.extended_rmse,
                p.seed_rmse
            );
        }
        // The forecast knows how far it may be off: after a minute open loop
        // the truth is within three of its standard deviations.
        println!(
            "    extended twin's final position error in forecast sigmas: {:.2?}",
            p.extended_final_error_sigmas
        );
        assert!(p.extended_final_error_sigmas.iter().all(|z| *z < 3.0));
    }
}
