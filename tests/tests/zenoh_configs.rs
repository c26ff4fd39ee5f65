//! The Zenoh configuration files of `config/`: every `*.json5` there loads
//! with `zenoh::Config::from_file` (and a new one is picked up without
//! touching this test); each file's key settings are what `config/README.md`
//! says; the command-line flags combine with them as documented; and the
//! client configuration waits for its router at start (the router comes up
//! after the client, the client connects, data flows).

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use serde_json::{Value, json};
use twin_tests::net::free_port;
use twin_zenoh::{Mode, ZenohArgs};
use zenoh::Wait;

fn config_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../config")
}

fn load(name: &str) -> zenoh::Config {
    let path = config_dir().join(name);
    zenoh::Config::from_file(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// A configuration key as JSON (`null` when unset).
fn get(config: &zenoh::Config, key: &str) -> Value {
    let text = config
        .get_json(key)
        .unwrap_or_else(|e| panic!("no key {key}: {e}"));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{key} = {text}: {e}"))
}

fn shipped() -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(config_dir())
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".json5"))
        .collect();
    names.sort();
    names
}

#[test]
fn every_shipped_file_loads_and_is_documented() {
    let names = shipped();
    println!("config/*.json5: {names:?}");
    for expected in [
        "zenoh.json5",
        "zenoh-client.json5",
        "zenoh-router.json5",
        "zenoh-acl.json5",
        "zenoh-tls.json5",
        "zenoh-usrpwd.json5",
    ] {
        assert!(names.iter().any(|n| n == expected), "{expected} missing");
    }
    let readme = std::fs::read_to_string(config_dir().join("README.md")).unwrap();
    for name in &names {
        load(name);
        assert!(
            readme.contains(&format!("`{name}`")),
            "config/README.md says nothing about {name}"
        );
    }
}

/// The fleet's router keeps, with zenohd's storage manager, the keys on
/// which the daemons of a fleet put their calibrations.
#[test]
fn the_fleet_router_stores_the_calibrations_the_daemons_put() {
    let c = load("zenoh-router-fleet.json5");
    assert_eq!(get(&c, "mode"), Value::from("router"));
    let storage = get(&c, "plugins/storage_manager/storages/twin_calibrations");
    let fleet = twind::settings::Settings::from_toml("[fleet]\nenabled = true\n").unwrap();
    let key = fleet.fleet.calibration_key("otter-1").unwrap();
    let stored = zenoh::key_expr::KeyExpr::try_from(storage["key_expr"].as_str().unwrap()).unwrap();
    assert!(stored.includes(&zenoh::key_expr::KeyExpr::try_from(key.as_str()).unwrap()));
    assert_eq!(storage["volume"], Value::from("memory"));
}

/// Item 6: the default is safe as shipped: a peer that listens on the
/// loopback interface only and connects to nothing it discovers, so that
/// nothing on the network can reach the daemon (Zenoh has no log-in
/// there).
#[test]
fn the_default_is_a_peer_reachable_from_this_host_only() {
    let c = load("zenoh.json5");
    assert_eq!(get(&c, "mode"), json!("peer"));
    assert_eq!(
        get(&c, "listen/endpoints"),
        json!({"peer": ["tcp/127.0.0.1:7447"], "router": ["tcp/127.0.0.1:7447"]})
    );
    assert_eq!(get(&c, "connect/endpoints"), json!([]));
    // It answers scouts (with its loopback address) but connects to nobody
    // it discovers, directly or by gossip.
    assert_eq!(get(&c, "scouting/multicast/enabled"), json!(true));
    assert_eq!(
        get(&c, "scouting/multicast/autoconnect"),
        json!({"router": [], "peer": [], "client": []})
    );
    assert_eq!(get(&c, "scouting/gossip/enabled"), json!(false));
}

#[test]
fn flags_override_the_default_file_as_the_readme_says() {
    let default = config_dir().join("zenoh.json5");
    // `twind --mode client --connect E`: a client of E that listens on nothing
    // (the file's listeners are per mode, and a client has none).
    let client = ZenohArgs {
        config: Some(default.clone()),
        mode: Some(Mode::Client),
        connect: vec!["tcp/192.0.2.7:7447".into()],
        ..ZenohArgs::default()
    }
    .to_config()
    .unwrap();
    assert_eq!(get(&client, "mode"), json!("client"));
    assert_eq!(
        get(&client, "connect/endpoints"),
        json!(["tcp/192.0.2.7:7447"])
    );
    let listen = get(&client, "listen/endpoints");
    assert!(listen.get("client").is_none(), "{listen}");
    // `twind --listen E --no-multicast-scouting`: E replaces the listeners.
    let peer = ZenohArgs {
        config: Some(default),
        listen: vec!["tcp/127.0.0.1:7448".into()],
        no_multicast_scouting: true,
        ..ZenohArgs::default()
    }
    .to_config()
    .unwrap();
    assert_eq!(
        get(&peer, "listen/endpoints"),
        json!(["tcp/127.0.0.1:7448"])
    );
    assert_eq!(get(&peer, "scouting/multicast/enabled"), json!(false));
}

#[test]
fn the_client_and_router_files_say_what_the_readme_says() {
    let c = load("zenoh-client.json5");
    assert_eq!(get(&c, "mode"), json!("client"));
    assert_eq!(get(&c, "connect/timeout_ms"), json!(-1));
    assert_eq!(get(&c, "connect/exit_on_failure"), json!(false));
    assert_eq!(get(&c, "listen/endpoints"), json!([]));
    assert_eq!(get(&c, "scouting/multicast/enabled"), json!(false));

    let r = load("zenoh-router.json5");
    assert_eq!(get(&r, "mode"), json!("router"));
    assert_eq!(get(&r, "listen/endpoints"), json!(["tcp/0.0.0.0:7447"]));
    assert_eq!(get(&r, "scouting/multicast/enabled"), json!(false));
}

#[test]
fn the_acl_router_denies_by_default_and_gives_each_vessel_one_owner() {
    let c = load("zenoh-acl.json5");
    assert_eq!(get(&c, "mode"), json!("router"));
    assert_eq!(get(&c, "access_control/enabled"), json!(true));
    assert_eq!(get(&c, "access_control/default_permission"), json!("deny"));
    assert!(
        get(&c, "transport/auth/usrpwd/dictionary_file")
            .as_str()
            .is_some()
    );
    let subjects = get(&c, "access_control/subjects");
    let users: Vec<&str> = subjects
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|s| s["usernames"].as_array())
        .flatten()
        .filter_map(Value::as_str)
        .collect();
    assert_eq!(
        users,
        [
            "twind", "twind-2", "twind", "twind-2", "otter-1", "otter-2", "operator"
        ]
    );
    let rules = get(&c, "access_control/rules");
    let rule = |id: &str| {
        rules
            .as_array()
            .unwrap()
            .iter()
            .find(|r| r["id"] == id)
            .unwrap_or_else(|| panic!("no rule {id}"))
            .clone()
    };
    // Each daemon puts and answers under its own vessel's twin/** only,
    // each vessel its own inputs only.
    assert_eq!(
        rule("twind-publish")["key_exprs"],
        json!(["asv/otter-1/twin/**", "asv/@twind/twind/stats"])
    );
    assert_eq!(
        rule("twind-2-publish")["key_exprs"],
        json!(["asv/otter-2/twin/**", "asv/@twind/twind-2/stats"])
    );
    assert_eq!(
        rule("otter-1-put-inputs")["key_exprs"],
        json!([
            "asv/otter-1/gnss",
            "asv/otter-1/nmea",
            "asv/otter-1/actuators"
        ])
    );
    // No rule lets anyone put (or answer, or hold a token) on a wildcard of
    // vessels' outputs: every output rule names its vessel.
    for r in rules.as_array().unwrap() {
        assert_eq!(r["permission"], json!("allow"), "{r}");
        let sends = r["flows"] == json!(["ingress"])
            && r["messages"]
                .as_array()
                .unwrap()
                .iter()
                .any(|m| m == "put" || m == "reply" || m == "liveliness_token");
        if sends {
            for k in r["key_exprs"].as_array().unwrap() {
                assert!(!k.as_str().unwrap().starts_with("asv/*"), "{r}");
            }
        }
    }
}

#[test]
fn the_tls_file_is_mutual_tls_only() {
    let c = load("zenoh-tls.json5");
    assert_eq!(
        get(&c, "listen/endpoints"),
        json!({"peer": ["tls/0.0.0.0:7447"], "router": ["tls/0.0.0.0:7447"]})
    );
    assert_eq!(get(&c, "transport/link/protocols"), json!(["tls"]));
    let tls = get(&c, "transport/link/tls");
    assert_eq!(tls["enable_mtls"], json!(true));
    assert_eq!(tls["verify_name_on_connect"], json!(true));
    for key in [
        "root_ca_certificate",
        "listen_certificate",
        "listen_private_key",
        "connect_certificate",
        "connect_private_key",
    ] {
        assert!(
            tls[key].as_str().unwrap().starts_with("/etc/zenoh/tls/"),
            "{key}: {tls}"
        );
    }
}

#[test]
fn the_usrpwd_client_logs_in_as_the_daemon() {
    let c = load("zenoh-usrpwd.json5");
    assert_eq!(get(&c, "mode"), json!("client"));
    assert_eq!(get(&c, "transport/auth/usrpwd/user"), json!("twind"));
    assert_eq!(get(&c, "connect/timeout_ms"), json!(-1));
}

/// The shipped client file, pointed at a loopback port.
fn client_of(port: u16) -> zenoh::Config {
    let mut c = load("zenoh-client.json5");
    c.insert_json5("connect/endpoints", &format!("[\"tcp/127.0.0.1:{port}\"]"))
        .unwrap();
    c
}

/// The shipped router file, on a loopback port.
fn router_on(port: u16) -> zenoh::Config {
    let mut c = load("zenoh-router.json5");
    c.insert_json5("listen/endpoints", &format!("[\"tcp/127.0.0.1:{port}\"]"))
        .unwrap();
    c.insert_json5("scouting/gossip/enabled", "false").unwrap();
    c
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_started_before_its_router_connects_when_it_comes() {
    let port = free_port();
    let started = Instant::now();
    // The client opens first: with the shipped file it waits. (Its open
    // blocks the calling thread while it retries, so it gets one of its own.)
    let config = client_of(port);
    let early = std::thread::spawn(move || zenoh::open(config).wait());
    tokio::time::sleep(Duration::from_millis(800)).await;
    assert!(!early.is_finished(), "the client must wait for its router");
    let router = zenoh::open(router_on(port)).await.unwrap();
    let router_up = Instant::now();
    let deadline = Instant::now() + Duration::from_secs(15);
    while !early.is_finished() {
        assert!(
            Instant::now() < deadline,
            "the client must connect once the router is up"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let subscriber_side = early.join().unwrap().unwrap();
    println!(
        "client opened {:.1} s after the router came up ({:.1} s after it started)",
        router_up.elapsed().as_secs_f64(),
        started.elapsed().as_secs_f64()
    );
    // And the router routes between two clients.
    let sub = subscriber_side
        .declare_subscriber("asv/otter-1/gnss")
        .await
        .unwrap();
    let publisher_side = zenoh::open(client_of(port)).await.unwrap();
    let publisher = publisher_side
        .declare_publisher("asv/otter-1/gnss")
        .await
        .unwrap();
    twin_tests::wire::wait_matching(&publisher, Duration::from_secs(10)).await;
    publisher.put("hello").await.unwrap();
    let sample = tokio::time::timeout(Duration::from_secs(10), sub.recv_async())
        .await
        .unwrap()
        .unwrap();
    assert_eq!(sample.payload().to_bytes().as_ref(), b"hello");
    for s in [publisher_side, subscriber_side, router] {
        s.close().await.unwrap();
    }
}
