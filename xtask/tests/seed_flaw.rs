//! The seed's flaw, with numbers (docs/model.md sections 5 and 9): with inputs
//! derived from the same GNSS track the filter observes, a loss of thrust is
//! already inside the inputs, so the seed's method cannot see it. A 20 % port
//! loss and no loss give the same estimates (and a healthy run can show a
//! higher peak "fault" than a lossy one). The extended twin, driven by the
//! propeller speeds, separates the two by the loss itself.

use xtask::trials::{Cell, PropellerSet, TrialPath, run_cell};

#[test]
fn a_twenty_percent_port_loss_is_invisible_to_the_seed_method() {
    let healthy = PropellerSet {
        name: "healthy",
        port_loss: 0.0,
        starboard_loss: 0.0,
    };
    let broken = PropellerSet {
        name: "port-20",
        port_loss: 0.2,
        starboard_loss: 0.0,
    };
    let mut peaks = [Vec::new(), Vec::new()];
    for seed in [1000, 1001, 1002] {
        let cell = |set| Cell {
            path: TrialPath::SManoeuvre,
            set,
            current: None,
            seed,
        };
        let h = run_cell(&cell(healthy));
        let b = run_cell(&cell(broken));
        println!(
            "seed {seed}: seed method input faults [a, r]: no loss {:.3?}, 20 % port loss {:.3?}; \
             step-4 peaks [port, stb]: {:.3?} vs {:.3?}; extended twin port loss {:.3} vs {:.3}",
            h.seed_method.input_faults,
            b.seed_method.input_faults,
            h.seed_method.thruster_peak,
            b.seed_method.thruster_peak,
            h.extended.loss[0],
            b.extended.loss[0]
        );
        // The seed's input faults do not move with the loss...
        for i in 0..2 {
            let d = (h.seed_method.input_faults[i] - b.seed_method.input_faults[i]).abs();
            assert!(d < 0.02, "input fault {i} moved by {d}");
        }
        // ...while the extended twin's port estimate moves by the loss.
        assert!((b.extended.loss[0] - h.extended.loss[0] - 0.2).abs() < 0.03);
        peaks[0].push(h.seed_method.thruster_peak[0]);
        peaks[1].push(b.seed_method.thruster_peak[0]);
        // What the seed's per-thruster values follow, for the record: on
        // this simulator (white GNSS velocity noise) they follow the error of
        // the derived inputs weakly and the turns not at all; the seed's
        // peaks in the turns are not reproduced here (docs/known-issues.md).
        for r in [&h, &b] {
            println!(
                "    correlation of the step-4 values with the derived inputs' error {:.2}, with |yaw rate| {:.2}",
                r.seed_method.input_error_correlation, r.seed_method.turn_correlation
            );
        }
    }
    // Indistinguishable: the port peaks of the healthy runs and of the lossy
    // runs overlap; some healthy run has a higher port "fault" than some lossy run.
    let healthy_max = peaks[0].iter().cloned().fold(f64::MIN, f64::max);
    let broken_min = peaks[1].iter().cloned().fold(f64::MAX, f64::min);
    println!("step-4 port peak: healthy up to {healthy_max:.3}, 20 % loss from {broken_min:.3}");
    assert!(healthy_max >= broken_min);
}
