//! The daemon end to end, with in-process Zenoh sessions on loopback: a
//! simulated trial published through Zenoh gives the daemon exactly the
//! estimates the offline path computes from the same messages; vessels do not
//! talk across; bad inputs are refused with their reasons counted and leave
//! the estimates as they were; the live residual monitor names a hidden
//! current and propeller loss, and nothing on a clean trial.

use std::time::Duration;

use twin_core::diagnose::MonitorConfig;
use twin_tests::daemon::{drain, last_fault, outputs, rig, rig_observed, states, wait_matching};
use twin_tests::wire::{
    Messages, messages, messages_as_logged, offline, receive_until, receive_until_fault,
    scenario as scenario_file, simulate as scenario,
};
use twin_wire::outputs::{
    FaultMessage, FindingsMessage, PredictionMessage, StateMessage, ThrusterStatusName,
};
use twind::forecast::{FaultPathLoad, SATURATED_AFTER};
use twind::settings::Settings;
use zenoh::Session;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_replayed_trial_gives_the_daemon_the_offline_estimates() {
    let run = scenario("s-manoeuvre_new-broken", 0.18, 8);
    let msgs = messages(&run);
    let expected = offline(&msgs);
    let rig = rig(Settings::default()).await;
    let sub = rig.collect("otter-1").await;
    rig.publish("otter-1", &msgs).await;
    let offline_fault = FaultMessage::new(
        "otter-1",
        &expected.fault_report(expected.state_report().unwrap().time_s),
        true,
    );
    let mut samples = receive_until_fault(&sub, &offline_fault.time).await;
    let summary = rig.stop().await;
    samples.extend(drain(&sub));
    let fault = last_fault(&samples);
    println!(
        "daemon: port {:?} +- {:?} ({:?}); offline: port {:?}",
        fault.thrusters.port.loss,
        fault.thrusters.port.sigma,
        fault.thrusters.port.status,
        offline_fault.thrusters.port.loss
    );
    // Identical estimates: the same messages, the same code, the same numbers.
    assert_eq!(fault.thrusters, offline_fault.thrusters);
    // And right: the port propeller's effectiveness, against the starboard
    // one's, within two of its standard deviations of the truth's 0.82.
    let ratio = fault.effectiveness_ratio.expect("a ratio");
    assert!((ratio.value - 0.82).abs() <= 2.0 * ratio.sigma, "{ratio:?}");
    assert_eq!(fault.thrusters.port.status, ThrusterStatusName::Fault);
    // Every fix gave a state, in order, and the last one is the offline one.
    let st = states(&samples);
    let fixes = msgs.iter().filter(|(t, _)| *t == "gnss").count();
    assert!(st.len() >= fixes, "{} states for {fixes} fixes", st.len());
    let offline_state =
        StateMessage::new("otter-1", &expected.state_report().unwrap(), false, true);
    assert_eq!(st.last().unwrap(), &offline_state);
    let counters = &summary.vessels["otter-1"];
    assert_eq!(counters.accepted()["gnss"] as usize, fixes);
    assert_eq!(counters.total_rejected(), 0, "{:?}", counters.rejected);
    // Forecasts (computed on the forecast threads) come in order, and the
    // last one is the offline twin's forecast from the same messages.
    let predictions = predictions(&samples);
    assert!(!predictions.is_empty(), "no prediction");
    let starts: Vec<f64> = predictions
        .iter()
        .map(|p| twin_wire::time::parse_rfc3339(&p.start).unwrap())
        .collect();
    assert!(starts.windows(2).all(|w| w[0] < w[1]), "{starts:?}");
    let last = predictions.last().unwrap();
    let offline = offline_predictions(&msgs, *starts.last().unwrap());
    assert!(
        offline.contains(last),
        "the last prediction ({}) is none of the {} offline forecasts from its fix",
        last.start,
        offline.len()
    );
}

fn predictions(samples: &[zenoh::sample::Sample]) -> Vec<PredictionMessage> {
    outputs(samples, "/twin/prediction")
}

/// The forecasts the offline twin gives, with the daemon's default horizon
/// and step, after each prefix of `msgs` whose last fix is at `start_s`:
/// the daemon asks for one right after a fix, or, when one was still being
/// computed, as soon as that one is out, possibly after shaft speeds that
/// came since.
fn offline_predictions(msgs: &[(&'static str, Vec<u8>)], start_s: f64) -> Vec<PredictionMessage> {
    let settings = Settings::default();
    let (horizon, step) = (
        settings.publish.prediction_horizon_s,
        settings.publish.prediction_step_s,
    );
    let mut twin = twin_core::twin::VesselTwin::new(settings.twin).unwrap();
    let mut candidates = Vec::new();
    for (topic, bytes) in msgs {
        if *topic == "gnss" {
            let _ = twin.on_gnss(&twin_wire::messages::decode_gnss(bytes).unwrap().value);
        } else if let twin_wire::messages::ActuatorCommand::Speeds(s) =
            twin_wire::messages::decode_actuators(bytes).unwrap().value
        {
            let _ = twin.on_propellers(&s);
        }
        let Some(state) = twin.state_report() else {
            continue;
        };
        if state.time_s == start_s {
            candidates.push(PredictionMessage::new(
                "otter-1",
                state.time_s,
                horizon,
                step,
                state.source,
                &twin.forecast(horizon, step),
                true,
            ));
        } else if state.time_s > start_s {
            break;
        }
    }
    candidates
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn three_vessels_at_once_do_not_talk_across() {
    // Three different boats: port losses 0, 0.2 and 0.35, different noise.
    let trials: Vec<(&str, Messages)> = vec![
        ("alpha", messages(&scenario("s-manoeuvre_new-new", 0.0, 11))),
        ("bravo", messages(&scenario("s-manoeuvre_new-new", 0.2, 12))),
        (
            "charlie",
            messages(&scenario("s-manoeuvre_new-new", 0.35, 13)),
        ),
    ];
    let rig = rig(Settings::default()).await;
    let subs = [
        rig.collect("alpha").await,
        rig.collect("bravo").await,
        rig.collect("charlie").await,
    ];
    // Interleave: one message of each vessel in turn, through one session.
    let mut publishers = Vec::new();
    for (vessel, _) in &trials {
        let g = rig
            .input
            .declare_publisher(format!("asv/{vessel}/gnss"))
            .congestion_control(zenoh::qos::CongestionControl::Block)
            .await
            .unwrap();
        let a = rig
            .input
            .declare_publisher(format!("asv/{vessel}/actuators"))
            .congestion_control(zenoh::qos::CongestionControl::Block)
            .await
            .unwrap();
        wait_matching(&g).await;
        wait_matching(&a).await;
        publishers.push((g, a));
    }
    let longest = trials.iter().map(|(_, m)| m.len()).max().unwrap();
    for k in 0..longest {
        for (i, (_, msgs)) in trials.iter().enumerate() {
            if let Some((topic, bytes)) = msgs.get(k) {
                let p = if *topic == "gnss" {
                    &publishers[i].0
                } else {
                    &publishers[i].1
                };
                p.put(bytes.clone()).await.unwrap();
            }
        }
    }
    let mut received = Vec::new();
    for (i, (vessel, msgs)) in trials.iter().enumerate() {
        let expected = offline(msgs);
        let last = FaultMessage::new(
            vessel,
            &expected.fault_report(expected.state_report().unwrap().time_s),
            true,
        );
        received.push(receive_until_fault(&subs[i], &last.time).await);
    }
    rig.stop().await;
    for (i, (vessel, msgs)) in trials.iter().enumerate() {
        let expected = offline(msgs);
        let mut samples = std::mem::take(&mut received[i]);
        samples.extend(drain(&subs[i]));
        assert!(
            samples
                .iter()
                .all(|s| s.key_expr().as_str().starts_with(&format!("asv/{vessel}/")))
        );
        let fault = last_fault(&samples);
        assert_eq!(fault.vessel, *vessel);
        let offline_fault = FaultMessage::new(
            vessel,
            &expected.fault_report(expected.state_report().unwrap().time_s),
            true,
        );
        println!(
            "{vessel}: port {:.3?} starboard {:.3?}",
            fault.thrusters.port.loss, fault.thrusters.starboard.loss
        );
        assert_eq!(fault.thrusters, offline_fault.thrusters, "{vessel}");
        assert_eq!(
            states(&samples).last().unwrap(),
            &StateMessage::new(vessel, &expected.state_report().unwrap(), false, true)
        );
    }
}

/// The forecast threads learn whether the fault path keeps up from the
/// count of events routed and not yet handled: once a trial has been
/// handled and the daemon waits for input, the fault path does not count as
/// saturated, however long it waits (else every forecast of a quiet daemon
/// would be held back).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_daemon_waiting_for_input_does_not_count_as_saturated() {
    let msgs = messages(&scenario("s-manoeuvre_new-new", 0.0, 41));
    let load = FaultPathLoad::new();
    let rig = rig_observed(Settings::default(), load.clone()).await;
    let sub = rig.collect("echo").await;
    rig.publish("echo", &msgs).await;
    let expected = offline(&msgs);
    let last = FaultMessage::new(
        "echo",
        &expected.fault_report(expected.state_report().unwrap().time_s),
        true,
    );
    receive_until_fault(&sub, &last.time).await;
    tokio::time::sleep(SATURATED_AFTER * 5).await;
    assert!(!load.saturated());
    rig.stop().await;
}

/// The keys of the liveliness tokens that `session` sees under `key`.
async fn alive(session: &Session, key: &str) -> Vec<String> {
    session
        .liveliness()
        .get(key)
        .await
        .unwrap()
        .into_iter()
        .filter_map(|r| r.into_result().ok())
        .map(|s| s.key_expr().as_str().to_string())
        .collect()
}

/// `publish.vessel_liveliness_key` moves each twin's liveliness token out
/// of the data prefix (for large fleets): the token is at the configured
/// key while the twin runs, and none is under the contract's key.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_liveliness_token_can_move_out_of_the_data_prefix() {
    let settings =
        Settings::from_toml("[publish]\nvessel_liveliness_key = \"asv-twins/alive/{vessel}\"\n")
            .unwrap();
    let msgs = messages(&scenario("s-manoeuvre_new-new", 0.0, 51));
    let rig = rig(settings).await;
    let sub = rig.collect("golf").await;
    rig.publish("golf", &msgs[..20]).await;
    receive_until(&sub, Duration::from_secs(30), |s| {
        s.key_expr().as_str().ends_with("/twin/fault")
    })
    .await;
    assert_eq!(
        alive(&rig.output, "asv-twins/alive/*").await,
        ["asv-twins/alive/golf"]
    );
    assert!(alive(&rig.output, "asv/*/twin/alive").await.is_empty());
    rig.stop().await;
}

/// The states received until the first one marked stale (which is last),
/// and how long after `paused` it came; panics when none comes within
/// `within`.
async fn states_until_stale(
    sub: &twin_tests::wire::Outputs,
    paused: std::time::Instant,
    within: Duration,
) -> (Vec<StateMessage>, Duration) {
    let samples = twin_tests::wire::receive_until(sub, within, |s| {
        s.key_expr().as_str().ends_with("/twin/state")
            && serde_json::from_slice::<StateMessage>(&s.payload().to_bytes())
                .is_ok_and(|m| m.stale)
    })
    .await;
    let waited = paused.elapsed();
    let received = states(&samples);
    assert!(
        received.last().is_some_and(|m| m.stale),
        "no stale state within {within:?}"
    );
    (received, waited)
}

/// GNSS dropout: a vessel whose fixes stop is published as stale once
/// `stale_after_s` has passed (state and fault again, from the last fix),
/// fresh again with its next fix, and stale again when the fixes stop
/// again. The statistics' interval is long, so only a timer armed for the
/// stale deadline can publish in time.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_vessel_whose_fixes_stop_is_published_stale_then_fresh_again() {
    let stale_after = Duration::from_millis(400);
    let settings = Settings::from_toml(&format!(
        "[vessels]\nstale_after_s = {}\n[publish]\nstats_interval_s = 600.0\n",
        stale_after.as_secs_f64()
    ))
    .unwrap();
    let msgs = messages(&scenario("s-manoeuvre_new-new", 0.0, 31));
    let (first, second) = msgs.split_at(msgs.len() / 2);
    let rig = rig(settings).await;
    let sub = rig.collect("delta").await;
    // Ample for a loaded test machine; the periodic statistics (the only
    // other wake) are ten minutes away.
    let within = Duration::from_secs(20);

    for (round, part) in [first, second].into_iter().enumerate() {
        rig.publish("delta", part).await;
        let paused = std::time::Instant::now();
        let (mut received, waited) = states_until_stale(&sub, paused, within).await;
        println!("round {round}: stale state {waited:?} after the last fix was sent");
        assert!(
            waited >= stale_after,
            "round {round}: stale after {waited:?}, before {stale_after:?}"
        );
        // The stale state repeats the last fix's estimate ...
        let upto = if round == 0 { first.len() } else { msgs.len() };
        let expected = offline(&msgs[..upto]);
        let last_fix = StateMessage::new("delta", &expected.state_report().unwrap(), true, true);
        assert_eq!(received.pop().unwrap(), last_fix, "round {round}");
        // ... after one fresh state per fix of this part.
        let fixes = part.iter().filter(|(t, _)| *t == "gnss").count();
        assert_eq!(received.len(), fixes, "round {round}");
        assert!(received.iter().all(|m| !m.stale), "round {round}");
        // Nothing fresh is published while the vessel is silent.
        assert!(
            states(&drain(&sub)).iter().all(|m| m.stale),
            "round {round}: a fresh state without a fix"
        );
    }
    rig.stop().await;
}

/// A table of bad inputs, each refused with its reason counted; the
/// estimates at the end are exactly those of the good messages alone.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_inputs_are_refused_with_their_reasons_and_change_nothing() {
    let run = scenario("s-manoeuvre_new-broken", 0.18, 21);
    let good = messages(&run);
    let expected = offline(&good);
    // A fix from the middle of the trial, to build bad ones from.
    let (split, _) = good
        .iter()
        .enumerate()
        .filter(|(_, (t, _))| *t == "gnss")
        .nth(100)
        .unwrap();
    let last_good: serde_json::Value = serde_json::from_slice(&good[split].1).unwrap();
    let with = |f: &dyn Fn(&mut serde_json::Value)| {
        let mut v = last_good.clone();
        f(&mut v);
        serde_json::to_vec(&v).unwrap()
    };
    let time_of = |v: &serde_json::Value| v["time"].as_str().unwrap().to_string();
    let earlier = time_of(&serde_json::from_slice(&good[split - 4].1).unwrap());
    let lat = last_good["lat_deg"].as_f64().unwrap();
    // The next good fix's time, to place the jump between fixes.
    let later_fix: serde_json::Value = serde_json::from_slice(
        &good
            .iter()
            .skip(split + 1)
            .find(|(t, _)| *t == "gnss")
            .unwrap()
            .1,
    )
    .unwrap();
    let table: Vec<(&'static str, &'static str, Vec<u8>)> = vec![
        ("gnss", "bad_json", b"\x00\xffnot json at all".to_vec()),
        ("gnss", "bad_json", b"{\"time\":\"2022-05-20T11:10:00Z\",\"lat_deg\":NaN,\"lon_deg\":6.1,\"sog_mps\":1,\"cog_rad\":0}".to_vec()),
        ("gnss", "out_of_range", with(&|v| v["lat_deg"] = serde_json::json!(95.0))),
        ("gnss", "out_of_range", with(&|v| v["sog_mps"] = serde_json::json!(-3.0))),
        ("gnss", "bad_time", with(&|v| v["time"] = serde_json::json!("yesterday at noon"))),
        ("gnss", "time_backwards", with(&|v| v["time"] = serde_json::json!(earlier.clone()))),
        ("gnss", "duplicate", good[split].1.clone()),
        ("gnss", "position_jump", with(&|v| {
            v["time"] = later_fix["time"].clone();
            v["lat_deg"] = serde_json::json!(lat + 1000.0 / 111_000.0);
        })),
        ("gnss", "payload_too_large", vec![b' '; 10 * 1024 * 1024]),
        ("actuators", "out_of_range", b"{\"time\":\"2022-05-20T11:10:30Z\",\"rpm\":{\"port\":1e9,\"starboard\":500}}".to_vec()),
        ("actuators", "no_command", b"{\"time\":\"2022-05-20T11:10:30Z\"}".to_vec()),
    ];
    let mut msgs: Vec<(&'static str, Vec<u8>)> = good[..=split].to_vec();
    for (topic, _, bytes) in &table {
        msgs.push((topic, bytes.clone()));
    }
    msgs.extend_from_slice(&good[split + 1..]);

    let rig = rig(Settings::default()).await;
    let sub = rig.collect("otter-1").await;
    rig.publish("otter-1", &msgs).await;
    // Vessel ids that are not plain names: Zenoh itself refuses a key with a
    // wildcard; a `/` makes another key that the daemon never subscribed to;
    // other characters reach the daemon and are refused there.
    assert!(
        rig.input
            .put("asv/a*b/gnss", good[split].1.clone())
            .await
            .is_err()
    );
    let sneaky = rig
        .input
        .declare_publisher("asv/bad.id/gnss")
        .await
        .unwrap();
    wait_matching(&sneaky).await;
    sneaky.put(good[split].1.clone()).await.unwrap();
    rig.input
        .put("asv/a/b/gnss", good[split].1.clone())
        .await
        .unwrap();
    let offline_fault = FaultMessage::new(
        "otter-1",
        &expected.fault_report(expected.state_report().unwrap().time_s),
        true,
    );
    let mut samples = receive_until_fault(&sub, &offline_fault.time).await;
    let summary = rig.stop().await;

    let counters = &summary.vessels["otter-1"];
    println!(
        "rejected by reason: {:?}; refused by the daemon: {:?}",
        counters.rejected, summary.refused.rejected
    );
    let mut want = std::collections::BTreeMap::<String, u64>::new();
    for (_, reason, _) in &table {
        *want.entry(reason.to_string()).or_default() += 1;
    }
    assert_eq!(counters.rejected, want);
    assert_eq!(summary.refused.rejected.get("bad_key"), Some(&1));
    assert_eq!(
        summary.vessels.len(),
        1,
        "no twin for a bad id: {:?}",
        summary.vessels.keys()
    );
    samples.extend(drain(&sub));
    let fault = last_fault(&samples);
    assert_eq!(fault.thrusters, offline_fault.thrusters);
}

/// The live residual monitor: a trial with a hidden water current and port
/// propeller loss gives a `twin/finding` naming both, with their sizes; the
/// same trial without them gives a finding message with no finding, and
/// explained; with a current that turns (no cause of the catalogue), the
/// message says `unexplained`, with its figures.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_live_monitor_names_a_hidden_current_and_loss_and_nothing_on_a_clean_trial() {
    let mut hidden = scenario_file("demo_broken-port");
    hidden.seed = 31;
    let mut clean = hidden.clone();
    clean.current = None;
    clean.propellers.port.loss = 0.0;
    let hidden_msgs = messages(&twin_sim::simulate(&hidden).unwrap());
    let clean_msgs = messages(&twin_sim::simulate(&clean).unwrap());
    // The hidden-effect tests' base trial (S-turns, a heading sensor), with
    // a current turning through 450 deg over five minutes.
    let mut turning = scenario_file("diagnose_base");
    turning.current = Some(twin_sim::CurrentSpec {
        speed_mps: 0.3,
        toward_deg: 0.0,
        rotation_deg_s: 1.5,
        speed_amplitude_mps: 0.0,
        speed_period_s: 600.0,
    });
    let turning_msgs = messages_as_logged(&twin_sim::simulate(&turning).unwrap());
    let mut settings = Settings::default();
    // One diagnosis per vessel, of 280 s, when 280 s are held (the early
    // trigger off, so that the test knows when it runs).
    settings.diagnose.monitor = MonitorConfig {
        window_s: 280.0,
        min_window_s: 280.0,
        interval_s: 1000.0,
        bias_t: 1e9,
        ..MonitorConfig::default()
    };
    let rig = rig(settings).await;
    let sub_hidden = rig.collect("hidden").await;
    let sub_clean = rig.collect("clean").await;
    let sub_turning = rig.collect("turning").await;
    rig.publish("hidden", &hidden_msgs).await;
    rig.publish("clean", &clean_msgs).await;
    rig.publish("turning", &turning_msgs).await;
    let findings = |samples: &[zenoh::sample::Sample]| -> Vec<FindingsMessage> {
        outputs(samples, "/twin/finding")
    };
    let (mut got_hidden, mut got_clean, mut got_turning) = (Vec::new(), Vec::new(), Vec::new());
    let deadline = std::time::Instant::now() + Duration::from_secs(180);
    while (got_hidden.is_empty() || got_clean.is_empty() || got_turning.is_empty())
        && std::time::Instant::now() < deadline
    {
        tokio::time::sleep(Duration::from_millis(200)).await;
        got_hidden.extend(findings(&drain(&sub_hidden)));
        got_clean.extend(findings(&drain(&sub_clean)));
        got_turning.extend(findings(&drain(&sub_turning)));
    }
    rig.stop().await;
    assert_eq!(got_hidden.len(), 1, "one diagnosis: {got_hidden:?}");
    assert_eq!(got_clean.len(), 1, "one diagnosis: {got_clean:?}");
    let h = &got_hidden[0];
    println!("hidden: {}", serde_json::to_string(h).unwrap());
    println!("clean: {}", serde_json::to_string(&got_clean[0]).unwrap());
    assert_eq!(h.vessel, "hidden");
    assert_eq!(h.trigger, "routine");
    assert_eq!(h.base_model, "kinetic");
    assert!((h.window_s - 280.0).abs() < 1.0, "{}", h.window_s);
    assert_eq!(h.causes(), vec!["current", "thruster_loss:port"]);
    let param = |cause: &str, name: &str| -> f64 {
        h.findings
            .iter()
            .find(|f| f.cause == cause)
            .and_then(|f| f.parameters.get(name))
            .and_then(|v| v.as_f64())
            .unwrap()
    };
    // Within 20 % of the truth, as in the hidden-effect tests: the current
    // as a vector within 20 % of its speed, the loss within 20 % of itself.
    let (speed, toward) = (
        param("current", "speed_mps"),
        param("current", "toward_deg").to_radians(),
    );
    let truth = 120f64.to_radians();
    let miss =
        (speed * toward.cos() - 0.1 * truth.cos()).hypot(speed * toward.sin() - 0.1 * truth.sin());
    assert!(miss <= 0.02, "current off by {miss} m/s");
    assert!((param("thruster_loss", "loss") - 0.25).abs() <= 0.05);
    assert!(got_clean[0].findings.is_empty(), "{:?}", got_clean[0]);
    assert_eq!(got_clean[0].unexplained, None);
    assert_eq!(got_turning.len(), 1, "one diagnosis: {got_turning:?}");
    let t = &got_turning[0];
    let u = t
        .unexplained
        .as_ref()
        .unwrap_or_else(|| panic!("a turning current explained: {t:?}"));
    assert!(u.nis_per_dof > 2.0 || !u.biased.is_empty(), "{u:?}");
    assert!(t.causes().contains(&"unexplained".to_string()));
}
