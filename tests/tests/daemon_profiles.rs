//! Vessel profiles in the daemon, from the outside in: each vessel runs on
//! the profile its rule in `[profiles]` names (the estimates are the
//! offline twin's on that profile, not the Otter's), and its statistics
//! say which.

use std::time::Duration;

use twin_core::twin::TwinConfig;
use twin_tests::daemon::{drain, outputs, rig};
use twin_tests::wire::{
    messages, offline, offline_with, receive_until, receive_until_fault, simulate,
};
use twin_wire::outputs::{FaultMessage, StatsMessage};
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
