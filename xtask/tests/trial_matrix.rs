//! The seed's sea-trial matrix re-run in the simulator with known truth
//! (docs/accuracy.md): every cell of 4 propeller sets and 8 losses x 2
//! paths x 3 noise seeds, with and without a 0.3 m/s current. The bars are
//! the project's accuracy targets: on S-manoeuvres the extended twin's
//! final estimate within 0.03 of the true loss on each propeller, healthy
//! propellers below 0.03, and the right side named every time.

use twin_core::decision::ThrusterStatus;
use xtask::trials::{CellResult, TrialPath, matrix, run_cell};

fn run(path: TrialPath, current_mps: f64) -> Vec<CellResult> {
    matrix(3, current_mps)
        .iter()
        .filter(|c| c.path == path)
        .map(run_cell)
        .collect()
}

/// Largest error of an estimator over the cells.
fn worst(results: &[CellResult], pick: impl Fn(&CellResult) -> [f64; 2]) -> f64 {
    results
        .iter()
        .map(|r| {
            let truth = r.cell.set.losses();
            let est = pick(r);
            (est[0] - truth[0]).abs().max((est[1] - truth[1]).abs())
        })
        .fold(0.0, f64::max)
}

// The index is the propeller side (0 port, 1 starboard) across three arrays.
#[allow(clippy::needless_range_loop)]
fn check_bar(results: &[CellResult]) {
    assert_eq!(results.len(), 36, "12 propeller sets x 3 seeds");
    for r in results {
        let truth = r.cell.set.losses();
        let e = &r.extended;
        for i in 0..2 {
            assert!(
                (e.loss[i] - truth[i]).abs() <= 0.03,
                "{} seed {} current {:?}: side {i} estimate {:.3} truth {}",
                r.cell.set.name,
                r.cell.seed,
                r.cell.current,
                e.loss[i],
                truth[i]
            );
            if truth[i] == 0.0 {
                assert!(e.loss[i] < 0.03, "healthy side {i} at {:.3}", e.loss[i]);
            }
            assert!(
                e.excited[i],
                "{} side {i} not excited on an S-manoeuvre",
                r.cell.set.name
            );
        }
        // The right side named: a lossy side is suspect or fault, a healthy one is not.
        assert_eq!(
            e.named(),
            [truth[0] > 0.0, truth[1] > 0.0],
            "{} seed {}: statuses {:?}",
            r.cell.set.name,
            r.cell.seed,
            e.status
        );
    }
}

#[test]
fn s_manoeuvre_cells_meet_the_bar() {
    let results = run(TrialPath::SManoeuvre, 0.0);
    check_bar(&results);
    println!(
        "S-manoeuvre, no current, {} cells: worst error extended twin {:.4}, without current state {:.4}",
        results.len(),
        worst(&results, |r| r.extended.loss),
        worst(&results, |r| r.without_current.loss)
    );
}

#[test]
fn s_manoeuvre_cells_in_a_current_need_the_current_state() {
    let results = run(TrialPath::SManoeuvre, 0.3);
    check_bar(&results);
    let with = worst(&results, |r| r.extended.loss);
    let without = worst(&results, |r| r.without_current.loss);
    println!(
        "S-manoeuvre in a 0.3 m/s current: worst error with the current state {with:.4}, without {without:.4}"
    );
    for r in &results {
        println!(
            "  {:18} toward {:5.1}: with [{:.3}, {:.3}], without [{:.3}, {:.3}], truth {:?}",
            r.cell.set.name,
            r.cell.current.map(|c| c.toward_deg).unwrap_or(0.0),
            r.extended.loss[0],
            r.extended.loss[1],
            r.without_current.loss[0],
            r.without_current.loss[1],
            r.cell.set.losses()
        );
    }
    // The twin without a current state misreads the current as thrust loss:
    // it misses the bar, by several times its width.
    assert!(
        without > 0.09,
        "without the current state the worst error is only {without}"
    );
    let failing = results
        .iter()
        .filter(|r| {
            let t = r.cell.set.losses();
            (0..2).any(|i| (r.without_current.loss[i] - t[i]).abs() > 0.03)
        })
        .count();
    println!(
        "  cells the twin without a current state gets wrong: {failing} of {}",
        results.len()
    );
    assert!(failing * 2 > results.len());
}

/// On a straight line at constant propeller speeds, a loss shared by both
/// propellers and a current along the track slow the vessel alike: with the
/// current estimated, the losses themselves cannot be told until the vessel
/// turns, and the twin says so: each loss within three of its stated
/// standard deviations, and no healthy propeller declared FAULT. What can be told is the ratio of the two propellers'
/// effectiveness, from the yaw balance: `(1 - loss_port) / (1 - loss_stb)`,
/// which lies within three of its stated standard deviations of the truth.
/// Without a current state (and with no current), the losses are told, within
/// their stated uncertainty.
#[test]
// The index is the propeller side (0 port, 1 starboard) across three arrays.
#[allow(clippy::needless_range_loop)]
fn straight_line_cells_say_what_can_be_told() {
    for current in [0.0, 0.3] {
        let results = run(TrialPath::Straight, current);
        let (mut worst_ratio, mut worst_z, mut mean_sigma) = (0.0f64, 0.0f64, 0.0);
        for r in &results {
            let e = &r.extended;
            // What the twin claims to know, it knows: each loss within
            // three of its stated standard deviations; excited or not, a
            // healthy propeller is never declared FAULT.
            let t = r.cell.set.losses();
            for i in 0..2 {
                let z = (e.loss[i] - t[i]).abs() / e.sigma[i];
                assert!(
                    z < 3.0,
                    "{}: side {i} {:.3} +- {:.3}, truth {}; {e:?}",
                    r.cell.set.name,
                    e.loss[i],
                    e.sigma[i],
                    t[i]
                );
                if t[i] == 0.0 {
                    assert_ne!(
                        e.status[i],
                        ThrusterStatus::Fault,
                        "{}: healthy side {i}",
                        r.cell.set.name
                    );
                }
            }
            let (ratio, sigma) = e.effectiveness_ratio;
            let truth = (1.0 - t[0]) / (1.0 - t[1]);
            worst_ratio = worst_ratio.max((ratio - truth).abs());
            println!(
                "    {:18} ratio {ratio:.3} +- {sigma:.3} (truth {truth:.3}); losses {:.3?} +- {:.3?}",
                r.cell.set.name, e.loss, e.sigma
            );
            worst_z = worst_z.max((ratio - truth).abs() / sigma);
            mean_sigma += sigma / results.len() as f64;
        }
        println!(
            "straight line, current {current} m/s: effectiveness ratio worst error {worst_ratio:.4}, \
             mean stated sigma {mean_sigma:.4}, worst error in sigmas {worst_z:.2}"
        );
        assert!(worst_z < 3.0, "{worst_z}");
        if current == 0.0 {
            // With no current and no current state, the losses themselves are
            // told, within their stated uncertainty.
            let w = worst(&results, |r| r.without_current.loss);
            let mut worst_z = 0.0f64;
            for r in &results {
                let t = r.cell.set.losses();
                let w = &r.without_current;
                for ((loss, sigma), truth) in w.loss.iter().zip(w.sigma).zip(t) {
                    worst_z = worst_z.max((loss - truth).abs() / sigma);
                }
                assert!(r.without_current.excited.iter().all(|e| *e));
            }
            println!(
                "straight line, no current, the twin without a current state: worst error {w:.4}, in sigmas {worst_z:.2}"
            );
            assert!(worst_z < 3.0, "{worst_z}");
        }
    }
}
