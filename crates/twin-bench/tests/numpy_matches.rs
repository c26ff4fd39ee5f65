//! The NumPy reference (`bench/numpy_aekf.py`) and `twin_core`'s filter run
//! the same recursion: on a short trial of the seed's model, with noise
//! adaptation off and in both of its forms, every step's theta and x (and
//! NIS) agree to 1e-9 and the same steps are refused.
//!
//! Needs Python 3 with NumPy; without them the test fails with the command
//! that installs them (`python3 -m pip install -r requirements.txt`, part of
//! the README's test command). Timings are printed, never asserted.

use twin_bench::estimator::{NumpyOptions, compare_with_numpy};
use twin_bench::numpy::unavailable_reason;
use twin_bench::trial::{Adaptation, TrialSpec};

#[test]
fn numpy_reference_matches_the_rust_filter() {
    let python = "python3";
    if let Some(reason) = unavailable_reason(python) {
        panic!("{reason}");
    }
    for adaptation in [
        Adaptation::Off,
        Adaptation::AuthorsCode,
        Adaptation::PostFitResidual,
    ] {
        // 450 steps (90 s): the fault switches on at 20 s, the input stops
        // from 60 to 75 s, the course wraps and components drop out.
        let spec = TrialSpec {
            steps: 450,
            dt_s: 0.2,
            seed: 5,
            adaptation,
        };
        let opts = NumpyOptions {
            work_dir: std::env::temp_dir().join(format!(
                "twin-bench-test-{}-{adaptation:?}",
                std::process::id()
            )),
            rust_repeats: 1,
            numpy_repeats: 1,
            ..NumpyOptions::default()
        };
        let outcome = compare_with_numpy(&spec, &opts).unwrap();
        print!("{}", outcome.table());
        let _ = std::fs::remove_dir_all(&opts.work_dir);
        assert!(outcome.masked_steps > 0);
        assert!(
            outcome.agrees(),
            "{adaptation:?}: NumPy and Rust disagree: {}",
            outcome.difference.failures(outcome.tolerance).join("; ")
        );
    }
}
