//! Vessel profiles in the daemon, from the outside in: each vessel runs on
//! the profile its rule in `[profiles]` names (the estimates are the
//! offline twin's on that profile, not the Otter's), and its statistics
//! say which; and a profile identified from a healthy trial of a vessel
//! unlike the Otter (a 4 m workboat, on both of the project's simulators)
//! lets the daemon find a later port loss on it.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use twin_cli::identify::identify_path;
use twin_core::diagnose::IdentifyConfig;
use twin_core::twin::TwinConfig;
use twin_tests::daemon::{drain, outputs, replayed_faults, rig};
use twin_tests::peers::{python_with, repo_root};
use twin_tests::trust::OTHER_SIMULATOR;
use twin_tests::wire::{
    messages, offline, offline_with, receive_until, receive_until_fault, scenario, simulate,
};
use twin_wire::SourceChoice;
use twin_wire::outputs::{FaultMessage, StatsMessage, ThrusterStatusName};
use twin_wire::profile::VesselProfile;
use twind::settings::Settings;

/// The Otter's profile made into another vessel: heavier, draggier, with
/// stronger propellers.
fn workboat() -> VesselProfile {
    let mut p = VesselProfile::otter();
    p.name = "workboat".into();
    p.mass.mass_kg *= 2.0;
    p.mass.yaw_inertia_kgm2 *= 2.0;
    p.damping.surge_n_per_mps *= 1.5;
    p.propellers.thrust_coeff_ahead_n_per_radps2 *= 1.5;
    p
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn each_vessel_runs_on_the_profile_its_rule_names() {
    let dir = std::env::temp_dir().join(format!("twind-profiles-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("workboat.toml");
    let profile = workboat();
    std::fs::write(&path, profile.to_toml()).unwrap();
    let settings = Settings::from_toml(&format!(
        "[publish]\nstats_interval_s = 0.5\n[diagnose]\nenabled = false\n\
         [profiles]\nfiles = [{:?}]\nvessels = [{{ id = \"work-*\", profile = \"workboat\" }}]\n",
        path.display().to_string()
    ))
    .unwrap();
    let msgs = messages(&simulate("s-manoeuvre_new-broken", 0.25, 71));
    let on_workboat = offline_with(&msgs, profile.twin_config(TwinConfig::default()));
    let on_otter = offline(&msgs);
    let end_s = on_otter.state_report().unwrap().time_s;
    let expected = |id: &str, twin: &twin_core::twin::VesselTwin| {
        FaultMessage::new(id, &twin.fault_report(end_s), true)
    };
    let (work, otter) = (
        expected("work-1", &on_workboat),
        expected("otter-1", &on_otter),
    );
    // The two profiles tell the trial apart.
    let gap = (work.thrusters.port.loss.unwrap() - otter.thrusters.port.loss.unwrap()).abs();
    assert!(gap > 0.01, "{gap}");

    let rig = rig(settings).await;
    let work_sub = rig.collect("work-1").await;
    let otter_sub = rig.collect("otter-1").await;
    rig.publish("work-1", &msgs).await;
    rig.publish("otter-1", &msgs).await;
    let mut work_samples = receive_until_fault(&work_sub, &work.time).await;
    let mut otter_samples = receive_until_fault(&otter_sub, &otter.time).await;
    for (sub, samples) in [
        (&work_sub, &mut work_samples),
        (&otter_sub, &mut otter_samples),
    ] {
        samples.extend(
            receive_until(sub, Duration::from_secs(10), |s| {
                s.key_expr().as_str().ends_with("/twin/stats")
            })
            .await,
        );
    }
    rig.stop().await;
    work_samples.extend(drain(&work_sub));
    otter_samples.extend(drain(&otter_sub));

    for (samples, want, identity) in [
        (&work_samples, &work, profile.identity()),
        (&otter_samples, &otter, VesselProfile::otter().identity()),
    ] {
        let faults: Vec<FaultMessage> = outputs(samples, "twin/fault");
        let last = faults
            .iter()
            .find(|f| f.time == want.time)
            .expect("the last fault");
        assert_eq!(last.thrusters, want.thrusters, "{}", want.vessel);
        let stats: Vec<StatsMessage> = outputs(samples, "twin/stats");
        assert!(!stats.is_empty(), "{}: no statistics", want.vessel);
        assert!(
            stats.iter().all(|s| s.profile == identity),
            "{}",
            want.vessel
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// The bar for a loss found on an identified profile: within 0.03
/// of the truth, fixed before the run.
const FOUND_WITHIN: f64 = 0.03;

/// Runs the independent simulator with the workboat and `args`.
fn other_workboat(args: &[&str]) {
    let python = python_with("numpy", "python3 -m pip install -r requirements.txt");
    let out = Command::new(python)
        .arg(OTHER_SIMULATOR)
        .args(["--vessel", "workboat"])
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The profile identified from the healthy trial at `log`, from the
/// workboat's shipped starting profile, written to `dir` as `name`.
fn identified(dir: &Path, log: &Path, name: &str) -> PathBuf {
    let start =
        VesselProfile::from_file(&repo_root().join("config/profiles/workboat-start.toml")).unwrap();
    let report = identify_path(
        log,
        SourceChoice::Best,
        &start,
        name,
        &IdentifyConfig::default(),
    )
    .expect("an identification trial");
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, report.identified.to_toml()).unwrap();
    path
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_profile_identified_from_a_healthy_trial_finds_a_later_port_loss_in_the_daemon() {
    let dir = std::env::temp_dir().join(format!("twind-identified-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // The vessel on both simulators: a healthy identification
    // trial, identified as `twin identify` does from the workboat's
    // starting profile; then the same vessel again, other noise, a 25 %
    // port loss from 60 s, replayed into the daemon.
    let write = |name: &str, file: &str| {
        let run = twin_sim::simulate(&scenario(name)).expect("simulation");
        let path = dir.join(file);
        twin_cli::simulate::write_nmea(&run, std::fs::File::create(&path).unwrap()).unwrap();
        path
    };
    let sim_trial = write("identify_workboat", "trial.nmea");
    let sim_loss = write("identify_workboat_port-loss", "loss.nmea");
    let (other_trial, other_loss) = (dir.join("other-trial.jsonl"), dir.join("other-loss.jsonl"));
    other_workboat(&["--seed", "5", "--out", other_trial.to_str().unwrap()]);
    other_workboat(&[
        "--seed",
        "6",
        "--effect",
        "loss",
        "--loss-side",
        "port",
        "--loss",
        "0.25",
        "--loss-onset-s",
        "60",
        "--out",
        other_loss.to_str().unwrap(),
    ]);
    let profiles = [
        identified(&dir, &sim_trial, "workboat-sim"),
        identified(&dir, &other_trial, "workboat-other"),
    ];
    let settings = Settings::from_toml(&format!(
        "[diagnose]\nenabled = false\n\
         [profiles]\nfiles = [{:?}, {:?}]\nvessels = [\
         {{ id = \"sim-*\", profile = \"workboat-sim\" }}, \
         {{ id = \"other-*\", profile = \"workboat-other\" }}]\n",
        profiles[0].display().to_string(),
        profiles[1].display().to_string(),
    ))
    .unwrap();

    let rig = rig(settings).await;
    for (vessel, log) in [("sim-1", &sim_loss), ("other-1", &other_loss)] {
        let faults = replayed_faults(&rig, log, vessel).await;
        let last = faults.last().expect("faults published");
        let (port, stb) = (&last.thrusters.port, &last.thrusters.starboard);
        let (port_loss, stb_loss) = (port.loss.unwrap(), stb.loss.unwrap());
        assert!(
            (port_loss - 0.25).abs() <= FOUND_WITHIN,
            "{vessel}: port loss {port_loss} (truth 0.25)"
        );
        assert!(
            stb_loss.abs() <= FOUND_WITHIN,
            "{vessel}: starboard loss {stb_loss} (truth 0)"
        );
        assert_eq!(port.status, ThrusterStatusName::Fault, "{vessel}");
        assert_eq!(last.profile_mismatch, None, "{vessel}");
        let stb_faults = faults
            .iter()
            .filter(|f| f.thrusters.starboard.status == ThrusterStatusName::Fault)
            .count();
        assert_eq!(
            stb_faults, 0,
            "{vessel}: the healthy starboard propeller declared FAULT"
        );
    }
    // The same log on the Otter's profile (no rule names `otter-1`): the
    // twin withholds the comparison, says why on `twin/fault`, and never
    // declares the healthy propeller FAULT.
    let faults = replayed_faults(&rig, &other_loss, "otter-1").await;
    let last = faults.last().expect("faults published");
    let mismatch = last
        .profile_mismatch
        .expect("twin/fault says the profile does not describe the vessel");
    assert!(
        mismatch.yaw_damping_error.abs() > mismatch.yaw_damping_bound
            || mismatch.mass_error.abs() > mismatch.mass_bound
            || mismatch.thrust_error.abs() > mismatch.thrust_bound
            || mismatch.nis_per_dof > mismatch.max_nis_per_dof,
        "{mismatch:?}"
    );
    assert!(!last.excited);
    assert!(
        faults
            .iter()
            .all(|f| f.thrusters.starboard.status != ThrusterStatusName::Fault),
        "otter-1: the healthy starboard propeller declared FAULT"
    );
    rig.stop().await;
    let _ = std::fs::remove_dir_all(&dir);
}
