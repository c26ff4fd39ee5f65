//! The daemon behind a Zenoh router: a router restart mid-stream (the daemon
//! and the publisher are clients and reconnect), and two daemons sharing a
//! fleet by key expression.

use std::time::{Duration, Instant};

use tokio_util::sync::CancellationToken;
use twin_tests::net::{config, free_port};
use twin_tests::wire::{
    fault_of, messages, offline, publish, receive_until, receive_until_fault, simulate,
};
use twin_wire::outputs::FaultMessage;
use twind::settings::Settings;

fn trial(port_loss: f64, seed: u64) -> twin_sim::SimRun {
    simulate("s-manoeuvre_new-new", port_loss, seed)
}

fn offline_fault(msgs: &[(&'static str, Vec<u8>)]) -> FaultMessage {
    let twin = offline(msgs);
    FaultMessage::new(
        "x",
        &twin.fault_report(twin.state_report().unwrap().time_s),
        true,
    )
}

fn last_fault(
    sub: &zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>,
) -> Option<FaultMessage> {
    let mut last = None;
    while let Ok(Some(s)) = sub.try_recv() {
        if s.key_expr().as_str().ends_with("/twin/fault") {
            last = Some(serde_json::from_slice(&s.payload().to_bytes()).unwrap());
        }
    }
    last
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_daemon_reconnects_when_the_router_restarts() {
    let port = free_port();
    let router = zenoh::open(config("router", &[port], &[])).await.unwrap();
    let daemon = zenoh::open(config("client", &[], &[port])).await.unwrap();
    let input = zenoh::open(config("client", &[], &[port])).await.unwrap();
    let output = zenoh::open(config("client", &[], &[port])).await.unwrap();
    let cancel = CancellationToken::new();
    let handle = tokio::spawn(twind::run(twind::RunConfig::new(
        Settings::default(),
        daemon.clone(),
        cancel.clone(),
    )));
    let sub = output
        .declare_subscriber("asv/otter-9/twin/**")
        .with(zenoh::handlers::FifoChannel::new(100_000))
        .await
        .unwrap();

    let msgs = messages(&trial(0.25, 31));
    let half = msgs.len() / 2;
    publish(&input, "otter-9", &msgs[..half]).await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    let before = last_fault(&sub).expect("outputs before the restart");

    // The router goes away and comes back on the same port.
    router.close().await.unwrap();
    tokio::time::sleep(Duration::from_secs(2)).await;
    assert!(
        !handle.is_finished(),
        "the daemon must survive losing its router"
    );
    let router = zenoh::open(config("router", &[port], &[])).await.unwrap();
    let reconnected = Instant::now();
    publish(&input, "otter-9", &msgs[half..]).await;
    println!(
        "clients reconnected and the stream resumed {:.1} s after the router came back",
        reconnected.elapsed().as_secs_f64()
    );
    let expected = offline_fault(&msgs);
    let received = receive_until_fault(&sub, &expected.time).await;
    let after = received
        .iter()
        .filter_map(fault_of)
        .chain(last_fault(&sub))
        .last()
        .expect("outputs after the restart");
    cancel.cancel();
    let summary = tokio::time::timeout(Duration::from_secs(20), handle)
        .await
        .unwrap()
        .unwrap()
        .unwrap();

    // Nothing corrupted: the estimate is exactly the offline one over the
    // whole trial (no message was published while the router was down).
    println!(
        "before the restart: port {:?}; after: port {:?}; offline {:?}",
        before.thrusters.port.loss, after.thrusters.port.loss, expected.thrusters.port.loss
    );
    assert_eq!(after.thrusters, expected.thrusters);
    assert_eq!(summary.vessels["otter-9"].total_rejected(), 0);
    for s in [daemon, input, output, router] {
        s.close().await.unwrap();
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_daemons_share_a_fleet_by_key_expression() {
    let port = free_port();
    let router = zenoh::open(config("router", &[port], &[])).await.unwrap();
    let north = zenoh::open(config("client", &[], &[port])).await.unwrap();
    let south = zenoh::open(config("client", &[], &[port])).await.unwrap();
    let input = zenoh::open(config("client", &[], &[port])).await.unwrap();
    let output = zenoh::open(config("client", &[], &[port])).await.unwrap();
    let owning = |own: &str| Settings::from_toml(&format!("[vessels]\nown = \"{own}\"\n")).unwrap();
    let cancel = CancellationToken::new();
    let hn = tokio::spawn(twind::run(twind::RunConfig::new(
        owning("north-$*"),
        north.clone(),
        cancel.clone(),
    )));
    let hs = tokio::spawn(twind::run(twind::RunConfig::new(
        owning("south-$*"),
        south.clone(),
        cancel.clone(),
    )));
    let sub = output
        .declare_subscriber("asv/*/twin/fault")
        .with(zenoh::handlers::FifoChannel::new(100_000))
        .await
        .unwrap();
    let fleet = [
        ("north-1", 0.1, 41),
        ("north-2", 0.3, 42),
        ("south-1", 0.2, 43),
    ];
    let mut expected = Vec::new();
    for (vessel, loss, seed) in fleet {
        let msgs = messages(&trial(loss, seed));
        publish(&input, vessel, &msgs).await;
        expected.push((vessel, offline_fault(&msgs)));
    }
    // Every vessel's last fault (stamped with its last fix's time), or 30 s.
    let mut awaited: std::collections::HashMap<&str, String> = expected
        .iter()
        .map(|(vessel, e)| (*vessel, e.time.clone()))
        .collect();
    let received = receive_until(&sub, Duration::from_secs(30), |s| {
        if let Some(f) = fault_of(s)
            && awaited.get(f.vessel.as_str()) == Some(&f.time)
        {
            awaited.remove(f.vessel.as_str());
        }
        awaited.is_empty()
    })
    .await;
    cancel.cancel();
    let sn = tokio::time::timeout(Duration::from_secs(20), hn)
        .await
        .unwrap()
        .unwrap()
        .unwrap();
    let ss = tokio::time::timeout(Duration::from_secs(20), hs)
        .await
        .unwrap()
        .unwrap()
        .unwrap();
    let mut north_names: Vec<_> = sn.vessels.keys().cloned().collect();
    north_names.sort();
    let south_names: Vec<_> = ss.vessels.keys().cloned().collect();
    println!("north daemon served {north_names:?}, south daemon served {south_names:?}");
    assert_eq!(north_names, ["north-1", "north-2"]);
    assert_eq!(south_names, ["south-1"]);
    // Each vessel's last fault message came from exactly one daemon, with
    // its own estimate.
    let mut last: std::collections::HashMap<String, FaultMessage> = Default::default();
    let mut late = Vec::new();
    while let Ok(Some(s)) = sub.try_recv() {
        late.push(s);
    }
    for s in received.iter().chain(&late) {
        let f: FaultMessage = serde_json::from_slice(&s.payload().to_bytes()).unwrap();
        last.insert(f.vessel.clone(), f);
    }
    for (vessel, e) in expected {
        assert_eq!(last[vessel].thrusters, e.thrusters, "{vessel}");
    }
    for s in [north, south, input, output, router] {
        s.close().await.unwrap();
    }
}
