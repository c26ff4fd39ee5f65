//! What a client of the daemon gets, from the outside in: every output and
//! every query reply says it is JSON (`application/json`), so that generic
//! clients (the Zenoh REST plugin, bridges) show it as such; and a client
//! that starts after the last alarm learns the latest fault, alarm and
//! finding of a vessel by a query, in the default setup (one daemon, no
//! router).

use std::time::Duration;

use twin_core::diagnose::MonitorConfig;
use twin_tests::daemon::{drain, outputs, rig};
use twin_tests::net::{config, free_port};
use twin_tests::wire::{fault_of, messages, offline, receive_until, receive_until_fault, scenario};
use twin_wire::outputs::{AlarmMessage, FaultMessage, FindingsMessage};
use twind::settings::Settings;
use zenoh::Session;
use zenoh::bytes::Encoding;
use zenoh::sample::Sample;

/// The replies to a query on `key`, as samples.
async fn query(session: &Session, key: &str) -> Vec<Sample> {
    session
        .get(key)
        .await
        .unwrap()
        .into_iter()
        .filter_map(|r| r.into_result().ok())
        .collect()
}

/// Item 10: every output published for a vessel (state, fault, forecast,
/// alarm, statistics), the daemon's own statistics and every query reply
/// carry the encoding `application/json`.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_output_and_reply_is_json() {
    let settings = Settings::from_toml(
        "[daemon]\nid = \"enc\"\n[publish]\nstats_interval_s = 0.5\n[diagnose]\nenabled = false\n",
    )
    .unwrap();
    let msgs = messages(&twin_tests::wire::simulate(
        "s-manoeuvre_new-broken",
        0.25,
        71,
    ));
    let expected = offline(&msgs);
    let last = FaultMessage::new(
        "json",
        &expected.fault_report(expected.state_report().unwrap().time_s),
        true,
    );
    let rig = rig(settings).await;
    let sub = rig.collect("json").await;
    let daemon_sub = rig
        .watch("asv/@twind/*/stats", "asv/@twind/enc/stats")
        .await;
    rig.publish("json", &msgs).await;
    let mut samples = receive_until_fault(&sub, &last.time).await;
    // The vessel's statistics come every 0.5 s.
    samples.extend(
        receive_until(&sub, Duration::from_secs(10), |s| {
            s.key_expr().as_str().ends_with("/twin/stats")
        })
        .await,
    );
    let daemon_stats = receive_until(&daemon_sub, Duration::from_secs(10), |_| true).await;
    let replies = query(&rig.output, "asv/json/twin/*").await;
    rig.stop().await;
    samples.extend(drain(&sub));
    let mut topics: Vec<&str> = samples
        .iter()
        .map(|s| s.key_expr().as_str().trim_start_matches("asv/json/"))
        .collect();
    topics.sort();
    topics.dedup();
    println!("topics: {topics:?}; {} replies", replies.len());
    for t in [
        "twin/alarm",
        "twin/fault",
        "twin/prediction",
        "twin/state",
        "twin/stats",
    ] {
        assert!(topics.contains(&t), "no {t}: {topics:?}");
    }
    assert!(!daemon_stats.is_empty(), "no daemon statistics");
    assert!(
        replies.len() >= 2,
        "state and fault at least: {}",
        replies.len()
    );
    for s in samples.iter().chain(&daemon_stats).chain(&replies) {
        assert_eq!(
            s.encoding(),
            &Encoding::APPLICATION_JSON,
            "{}",
            s.key_expr()
        );
    }
}

/// Item 9: a client that starts after the trial (after the last alarm and
/// the last finding) learns the vessel's latest fault, alarm and finding by
/// querying the daemon with Zenoh's default query: the replies are exactly
/// the last ones published.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_late_joiner_learns_the_latest_fault_alarm_and_finding_by_query() {
    let mut sc = scenario("demo_broken-port");
    sc.seed = 72;
    let msgs = messages(&twin_sim::simulate(&sc).unwrap());
    let mut settings = Settings::default();
    // One diagnosis, of 120 s, once 120 s are held.
    settings.diagnose.monitor = MonitorConfig {
        window_s: 120.0,
        min_window_s: 120.0,
        interval_s: 1000.0,
        bias_t: 1e9,
        ..MonitorConfig::default()
    };
    let expected = offline(&msgs);
    let last = FaultMessage::new(
        "late",
        &expected.fault_report(expected.state_report().unwrap().time_s),
        true,
    );
    let port = free_port();
    let daemon = zenoh::open(config("peer", &[port], &[])).await.unwrap();
    let cancel = tokio_util::sync::CancellationToken::new();
    let handle = tokio::spawn(twind::run(twind::RunConfig::new(
        settings,
        daemon.clone(),
        cancel.clone(),
    )));
    let watcher = zenoh::open(config("peer", &[], &[port])).await.unwrap();
    let sub = watcher
        .declare_subscriber("asv/late/twin/**")
        .with(zenoh::handlers::FifoChannel::new(100_000))
        .await
        .unwrap();
    let input = zenoh::open(config("peer", &[], &[port])).await.unwrap();
    twin_tests::wire::publish(&input, "late", &msgs).await;
    let mut seen = receive_until_fault(&sub, &last.time).await;
    seen.extend(
        receive_until(&sub, Duration::from_secs(120), |s| {
            s.key_expr().as_str().ends_with("/twin/finding")
        })
        .await,
    );
    // Give any output still on its way time to come, then note the last of
    // each.
    tokio::time::sleep(Duration::from_millis(500)).await;
    seen.extend(drain(&sub));
    let last_fault = seen.iter().rev().find_map(fault_of).expect("a fault");
    let alarms: Vec<AlarmMessage> = outputs(&seen, "/twin/alarm");
    let findings: Vec<FindingsMessage> = outputs(&seen, "/twin/finding");
    assert!(!alarms.is_empty(), "the trial raises an alarm");
    assert!(!findings.is_empty(), "the monitor published a finding");
    // The late joiner.
    let late = zenoh::open(config("peer", &[], &[port])).await.unwrap();
    let decode = |samples: Vec<Sample>| -> Vec<serde_json::Value> {
        samples
            .iter()
            .map(|s| serde_json::from_slice(&s.payload().to_bytes()).unwrap())
            .collect()
    };
    let fault = decode(query(&late, "asv/late/twin/fault").await);
    let alarm = decode(query(&late, "asv/late/twin/alarm").await);
    let finding = decode(query(&late, "asv/late/twin/finding").await);
    assert_eq!(fault, [serde_json::to_value(&last_fault).unwrap()]);
    assert_eq!(
        alarm,
        [serde_json::to_value(alarms.last().unwrap()).unwrap()]
    );
    assert_eq!(
        finding,
        [serde_json::to_value(findings.last().unwrap()).unwrap()]
    );

    cancel.cancel();
    tokio::time::timeout(Duration::from_secs(20), handle)
        .await
        .unwrap()
        .unwrap()
        .unwrap();
    for s in [late, input, watcher, daemon] {
        s.close().await.unwrap();
    }
}
