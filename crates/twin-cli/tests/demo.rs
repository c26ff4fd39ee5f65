//! The bundled demo trial cannot rot: the committed log is exactly what
//! `twin simulate` writes for the committed scenario (byte for byte).

use twin_cli::demo::{LOG, REGENERATE, SCENARIO, workspace_root};
use twin_cli::simulate::{OutputFormat, simulate_to_bytes};
use twin_sim::Scenario;

#[test]
fn the_committed_demo_log_is_what_the_command_writes() {
    let root = workspace_root();
    let scenario = Scenario::from_path(&root.join(SCENARIO)).expect("the demo scenario loads");
    let (fresh, summary) =
        simulate_to_bytes(&scenario, OutputFormat::JsonLines).expect("the demo simulates");
    let committed = std::fs::read(root.join(LOG)).expect("the demo log is committed");
    if fresh != committed {
        let fresh_text = String::from_utf8_lossy(&fresh);
        let committed_text = String::from_utf8_lossy(&committed);
        let first_difference = fresh_text
            .lines()
            .zip(committed_text.lines())
            .position(|(a, b)| a != b);
        panic!(
            "{LOG} differs from what the scenario gives now ({} vs {} bytes, first differing line {:?}); regenerate it with\n  {REGENERATE}",
            fresh.len(),
            committed.len(),
            first_difference.map(|i| i + 1)
        );
    }
    // Five minutes: GNSS at 5 Hz with a heading on every fix, shafts at 10 Hz.
    assert_eq!(summary.fixes, 1501);
    assert_eq!(summary.fixes_with_heading, 1501);
    assert_eq!(summary.propeller_samples, 3001);
    assert_eq!(summary.fixes_without_course, 0);
}

#[test]
fn the_demo_scenario_is_what_its_readme_says() {
    let scenario =
        Scenario::from_path(&workspace_root().join(SCENARIO)).expect("the demo scenario loads");
    assert_eq!(scenario.duration_s, 300.0);
    assert_eq!(scenario.propellers.port.loss, 0.25);
    assert_eq!(scenario.propellers.port.onset_s, 0.0);
    assert_eq!(scenario.propellers.starboard.loss, 0.0);
    assert!(scenario.disturbance.is_some(), "harbour water");
    let readme = std::fs::read_to_string(workspace_root().join("data/demo/README.md"))
        .expect("the demo README");
    assert!(readme.contains("--scenario config/scenarios/demo_broken-port.toml"));
    assert!(readme.contains("--out data/demo/otter-broken-port.jsonl"));
}
