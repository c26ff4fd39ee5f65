//! Parity of the live path with the offline one: a simulated sea trial
//! (the Otter with a damaged port propeller) written as NMEA 0183, served
//! by a TCP server the way a multiplexer serves a boat's sentences, read by
//! the bridge and published over Zenoh to the daemon, gives the daemon the
//! very estimates `twin analyze` computes from the same trial as a file:
//! the same final state, the same propeller losses.

use std::io::Write;
use std::net::TcpListener;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use tokio_util::sync::CancellationToken;
use twin_bridge::output::ZenohOutputs;
use twin_bridge::{BridgeConfig, run as run_bridge};
use twin_cli::analyze::{AnalyzeOptions, analyze_path};
use twin_tests::net::{config, free_port};
use twin_tests::wire::{fault_of, receive_until, simulate};
use twin_wire::outputs::StateMessage;
use twin_wire::{KeySpace, VesselId};
use twind::settings::Settings;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_trial_through_the_bridge_is_twin_analyze_of_the_file() {
    // The trial as a file, and what `twin analyze` makes of it.
    let run = simulate("s-manoeuvre_new-broken", 0.3, 11);
    let mut log = Vec::new();
    twin_cli::simulate::write_nmea(&run, &mut log).unwrap();
    let dir = std::env::temp_dir().join(format!("twin-bridge-parity-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("trial.nmea");
    std::fs::write(&path, &log).unwrap();
    let analysis = analyze_path(&path, &AnalyzeOptions::default()).unwrap();
    let final_state = analysis.final_state.clone().expect("a final state");
    let port_loss = analysis
        .thrusters
        .port
        .loss
        .expect("propeller speeds in the log");
    assert!(
        port_loss > 0.1,
        "the trial's damage is seen offline: {port_loss}"
    );

    // The daemon, and a session watching what it says.
    let port = free_port();
    let daemon = zenoh::open(config("peer", &[port], &[])).await.unwrap();
    let cancel = CancellationToken::new();
    // The multiplexer plays a recorded trial, live to the bridge: its times
    // are the recording's, hours behind the daemon's clock, which a live
    // input is otherwise held to.
    let mut settings = Settings::default();
    settings.live_time.max_behind_s = 1e12;
    let handle = tokio::spawn(twind::run(twind::RunConfig::new(
        settings,
        daemon.clone(),
        cancel.clone(),
    )));
    let watcher = zenoh::open(config("peer", &[], &[port])).await.unwrap();
    let outputs = watcher
        .declare_subscriber("asv/trial/twin/**")
        .with(zenoh::handlers::FifoChannel::new(100_000))
        .await
        .unwrap();
    let probe = daemon
        .declare_publisher("asv/trial/twin/state")
        .await
        .unwrap();
    twin_tests::wire::wait_matching(&probe, Duration::from_secs(10)).await;

    // The bridge, on a session of its own, reading the multiplexer.
    let vessel = VesselId::new("trial").unwrap();
    let bridge_session = zenoh::open(config("peer", &[], &[port])).await.unwrap();
    let gnss = bridge_session
        .declare_publisher("asv/trial/gnss")
        .await
        .unwrap();
    twin_tests::wire::wait_matching(&gnss, Duration::from_secs(10)).await;
    let sink = ZenohOutputs::declare(&bridge_session, &KeySpace::default(), &vessel).unwrap();
    let multiplexer = TcpListener::bind("127.0.0.1:0").unwrap();
    let address = multiplexer.local_addr().unwrap();
    let server = std::thread::spawn(move || {
        let (mut peer, _) = multiplexer.accept().unwrap();
        peer.write_all(&log).unwrap();
        // Stay connected, as a multiplexer does.
        std::thread::sleep(Duration::from_secs(60));
    });
    let stop = Arc::new(AtomicBool::new(false));
    let bridge = {
        let stop = stop.clone();
        let config = BridgeConfig::new(
            vessel,
            vec![format!("nmea0183:tcp:{address}").parse().unwrap()],
        );
        std::thread::spawn(move || run_bridge(&config, Arc::new(sink), stop, |_| {}))
    };

    // The daemon's fault at the trial's last fix, and its state then.
    let samples = receive_until(&outputs, Duration::from_secs(60), |s| {
        fault_of(s).is_some_and(|f| f.time == final_state.time)
    })
    .await;
    stop.store(true, Ordering::Relaxed);
    let stats = bridge.join().unwrap().unwrap();
    drop(server);
    let fault = samples
        .iter()
        .rev()
        .find_map(fault_of)
        .expect("a fault message");
    assert_eq!(fault.time, final_state.time, "bridge counts: {stats:#?}");
    let state: StateMessage = samples
        .iter()
        .rev()
        .filter(|s| s.key_expr().as_str().ends_with("/twin/state"))
        .map(|s| serde_json::from_slice(&s.payload().to_bytes()).unwrap())
        .find(|s: &StateMessage| s.time == final_state.time)
        .expect("the state at the last fix");
    assert_eq!(
        (state.lat_deg, state.lon_deg, state.north_m, state.east_m),
        (
            final_state.lat_deg,
            final_state.lon_deg,
            final_state.north_m,
            final_state.east_m
        )
    );
    assert_eq!(
        (state.sog_mps, state.cog_rad, state.heading_rad),
        (
            final_state.sog_mps,
            final_state.cog_rad,
            final_state.heading_rad
        )
    );
    assert_eq!(fault.thrusters.port.loss, Some(port_loss));
    assert_eq!(
        fault.thrusters.starboard.loss,
        analysis.thrusters.starboard.loss
    );
    assert!(!state.replay, "live data");
    let source = &stats.sources[0];
    assert!(source.rejected.is_empty(), "{:?}", source.rejected);

    cancel.cancel();
    tokio::time::timeout(Duration::from_secs(20), handle)
        .await
        .unwrap()
        .unwrap()
        .unwrap();
    bridge_session.close().await.unwrap();
    watcher.close().await.unwrap();
    daemon.close().await.unwrap();
    std::fs::remove_dir_all(&dir).ok();
}
