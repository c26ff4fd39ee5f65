//! NMEA 0183 from a multiplexer's TCP server, the way a boat's Signal K
//! server offers it: signalk-server (npm) plays its sample NMEA 0183 data
//! (`samples/plaka.log`, a sailing boat) and serves the sentences on its
//! NMEA 0183 TCP server (port 10110 on a boat, a free port here). The real
//! `twin-bridge` binary connects to it and publishes over Zenoh on
//! loopback; a Zenoh subscriber receives fixes that are the sample's own
//! (positions at their time of day) and the bridge's counts on
//! `asv/{vessel}/bridge/stats`. SIGTERM stops the bridge cleanly.

mod common;

use std::process::{Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use common::*;
use twin_bridge::stats::BridgeStats;
use twin_wire::messages::decode_gnss;
use zenoh::Wait;

/// A key and its payload.
type Received = (String, Vec<u8>);

#[test]
fn signalk_server_sample_data_through_the_bridge_binary() {
    let signalk = SignalkServer::start(true);
    let nmea_port = signalk.nmea0183_port;

    // A Zenoh subscriber on loopback, listening for the bridge.
    let zenoh_port = free_tcp_port();
    let args = twin_zenoh::ZenohArgs {
        mode: Some(twin_zenoh::Mode::Peer),
        listen: vec![format!("tcp/127.0.0.1:{zenoh_port}")],
        no_multicast_scouting: true,
        ..twin_zenoh::ZenohArgs::default()
    };
    let session = zenoh::open(args.to_config().unwrap()).wait().unwrap();
    let received: Arc<Mutex<Vec<Received>>> = Arc::default();
    let sink = received.clone();
    let _subscriber = session
        .declare_subscriber("asv/sk/**")
        .callback(move |s| {
            sink.lock().unwrap().push((
                s.key_expr().as_str().to_owned(),
                s.payload().to_bytes().into_owned(),
            ))
        })
        .wait()
        .unwrap();

    let mut bridge = Child::spawn(
        Command::new(env!("CARGO_BIN_EXE_twin-bridge"))
            .args(["--vessel", "sk", "--source"])
            .arg(format!("nmea0183:tcp:127.0.0.1:{nmea_port}"))
            .args(["--mode", "peer", "--no-multicast-scouting", "--connect"])
            .arg(format!("tcp/127.0.0.1:{zenoh_port}"))
            .args(["--listen", "tcp/127.0.0.1:0"])
            .stdout(Stdio::piped())
            .stderr(Stdio::null()),
    )
    .expect("twin-bridge starts");

    let deadline = Instant::now() + Duration::from_secs(60);
    let (fixes, stats) = loop {
        std::thread::sleep(Duration::from_millis(200));
        let got = received.lock().unwrap().clone();
        let fixes: Vec<_> = got
            .iter()
            .filter(|(k, _)| k == "asv/sk/gnss")
            .map(|(_, p)| decode_gnss(p).expect("a valid gnss payload"))
            .collect();
        let stats: Option<BridgeStats> = got
            .iter()
            .rev()
            .find(|(k, _)| k == "asv/sk/bridge/stats")
            .map(|(_, p)| serde_json::from_slice(p).expect("a stats payload"));
        if fixes.len() >= 3
            && stats
                .as_ref()
                .is_some_and(|s| s.sources[0].published.gnss >= 3)
        {
            break (fixes, stats.unwrap());
        }
        assert!(
            Instant::now() < deadline,
            "no fixes from signalk-server through the bridge: {} fixes, stats {stats:?}",
            fixes.len()
        );
    };

    // Each fix is one of plaka.log's, at its time of day (the sample has
    // no date: the bridge takes the receiving computer's).
    let plaka = std::fs::read_to_string(signalk.package.join("samples/plaka.log")).unwrap();
    let expected = expected_fixes(&plaka);
    for f in &fixes {
        let time_of_day = f.value.time_s.rem_euclid(86_400.0);
        let e = expected
            .iter()
            .find(|e| (e.time_s.rem_euclid(86_400.0) - time_of_day).abs() < 1e-6)
            .unwrap_or_else(|| panic!("no fix of plaka.log at {time_of_day} s of the day"));
        assert_eq!(e.position, f.value.position);
        assert_eq!(e.sog_mps, f.value.sog_mps);
        assert!(!f.replay);
    }
    let source = &stats.sources[0];
    assert_eq!(source.format, "nmea0183");
    assert!(source.connected && source.connects == 1, "{source:?}");
    assert!(source.lines > 0 && source.bytes > 0);

    // SIGTERM: a clean stop with a summary.
    let status = Command::new("kill")
        .args(["-TERM", &bridge.0.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let mut stdout = String::new();
    std::io::Read::read_to_string(&mut bridge.0.stdout.take().unwrap(), &mut stdout).unwrap();
    let exit = bridge.0.wait().unwrap();
    assert!(exit.success(), "{exit:?}");
    assert!(stdout.contains("twin-bridge: published"), "{stdout}");
    session.close().wait().unwrap();
}
