//! Access control with the shipped `config/zenoh-acl.json5`: a router on
//! loopback enforcing it (only the listen port and the password dictionary
//! replaced, the dictionary a throwaway file written here), the daemon
//! (`twind::run`) and the others as clients logging in with
//! `config/zenoh-usrpwd.json5` and their own user names.
//!
//! What it shows:
//! - `otter-1`'s GNSS reaches the daemon: a state comes out for `otter-1`, its
//!   twin answers the operator's query and holds a liveliness token;
//! - `otter-1` putting `otter-2`'s GNSS, and a session with the daemon's
//!   identity putting `otter-3`'s GNSS, are dropped by the router: the
//!   publishers see the daemon's subscriber (so the puts are really sent)
//!   yet the daemon never hears of `otter-2` or `otter-3`, while the same
//!   daemon-identity session's put under `asv/*/twin/**` does reach the
//!   operator;
//! - a wrong password, an unknown user or no credentials cannot open a session.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use tokio_util::sync::CancellationToken;
use twin_tests::net::free_port;
use twin_tests::wire::wait_matching;
use twin_wire::messages::{GnssMessage, TimeSource};
use twind::settings::Settings;
use zenoh::Session;
use zenoh::handlers::{FifoChannel, FifoChannelHandler};
use zenoh::pubsub::Subscriber;
use zenoh::sample::Sample;

const USERS: [(&str, &str); 3] = [
    ("twind", "throwaway-twind-password"),
    ("otter-1", "throwaway-otter-1-password"),
    ("operator", "throwaway-operator-password"),
];

fn config_file(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../config")
        .join(name)
}

/// A throwaway password dictionary, one per test.
struct Dictionary(PathBuf);

impl Dictionary {
    fn new(test: &str) -> Self {
        let dir =
            std::env::temp_dir().join(format!("twin-zenoh-acl-{test}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("credentials.txt");
        let text: String = USERS.iter().map(|(u, p)| format!("{u}:{p}\n")).collect();
        std::fs::write(&path, text).unwrap();
        Self(path)
    }
}

impl Drop for Dictionary {
    fn drop(&mut self) {
        if let Some(dir) = self.0.parent() {
            let _ = std::fs::remove_dir_all(dir);
        }
    }
}

/// The shipped ACL router on a loopback port with the throwaway dictionary.
fn router(port: u16, dictionary: &Dictionary) -> zenoh::Config {
    let mut c = zenoh::Config::from_file(config_file("zenoh-acl.json5")).unwrap();
    c.insert_json5("listen/endpoints", &format!("[\"tcp/127.0.0.1:{port}\"]"))
        .unwrap();
    c.insert_json5(
        "transport/auth/usrpwd/dictionary_file",
        &serde_json::Value::from(dictionary.0.to_string_lossy()).to_string(),
    )
    .unwrap();
    c.insert_json5("scouting/gossip/enabled", "false").unwrap();
    c
}

/// The shipped log-in client file for `user`, pointed at the router.
fn login(port: u16, user: Option<(&str, &str)>) -> zenoh::Config {
    let mut c = zenoh::Config::from_file(config_file("zenoh-usrpwd.json5")).unwrap();
    c.insert_json5("connect/endpoints", &format!("[\"tcp/127.0.0.1:{port}\"]"))
        .unwrap();
    match user {
        Some((u, p)) => {
            c.insert_json5("transport/auth/usrpwd/user", &format!("\"{u}\""))
                .unwrap();
            c.insert_json5("transport/auth/usrpwd/password", &format!("\"{p}\""))
                .unwrap();
        }
        None => {
            c.insert_json5("transport/auth/usrpwd/user", "null")
                .unwrap();
            c.insert_json5("transport/auth/usrpwd/password", "null")
                .unwrap();
        }
    }
    c
}

async fn open_as(port: u16, user: &str) -> Session {
    let pair = USERS.iter().find(|(u, _)| *u == user).copied().unwrap();
    zenoh::open(login(port, Some(pair))).await.unwrap()
}

/// `n` GNSS fixes 0.2 s apart, heading north at 1 m/s.
fn fixes(n: usize) -> Vec<Vec<u8>> {
    (0..n)
        .map(|i| {
            let t_ms = 200 * i as u64;
            let m = GnssMessage {
                time: format!("2024-06-01T12:00:{:02}.{:03}Z", t_ms / 1000, t_ms % 1000),
                lat_deg: 59.9 + i as f64 * 0.2 / 111_320.0,
                lon_deg: 10.7,
                sog_mps: 1.0,
                cog_rad: 0.0,
                heading_rad: Some(0.0),
                hdop: Some(0.8),
                replay: false,
                time_source: TimeSource::Source,
            };
            serde_json::to_vec(&m).unwrap()
        })
        .collect()
}

/// Declares a publisher on `key`, waits until it sees a subscriber, puts
/// every payload.
async fn put_all(session: &Session, key: &str, payloads: &[Vec<u8>]) {
    let p = session.declare_publisher(key.to_string()).await.unwrap();
    wait_matching(&p, Duration::from_secs(10)).await;
    for bytes in payloads {
        p.put(bytes.clone()).await.unwrap();
    }
}

fn drain(sub: &Subscriber<FifoChannelHandler<Sample>>, into: &mut Vec<String>) {
    while let Ok(Some(s)) = sub.try_recv() {
        into.push(s.key_expr().as_str().to_string());
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn only_allowed_identities_reach_the_daemon_and_it_publishes_only_twin_outputs() {
    let dictionary = Dictionary::new("allow");
    let port = free_port();
    let router = zenoh::open(router(port, &dictionary)).await.unwrap();
    let daemon = open_as(port, "twind").await;
    let vessel = open_as(port, "otter-1").await;
    let operator = open_as(port, "operator").await;
    // Another session with the daemon's identity (a daemon gone wrong).
    let rogue = open_as(port, "twind").await;

    let cancel = CancellationToken::new();
    let handle = tokio::spawn(twind::run(twind::RunConfig::new(
        Settings::default(),
        daemon.clone(),
        cancel.clone(),
    )));
    let watch = operator
        .declare_subscriber("asv/*/twin/**")
        .with(FifoChannel::new(100_000))
        .await
        .unwrap();

    let gnss = fixes(10);
    // Refused: another vessel's GNSS, and GNSS from the daemon's identity.
    // Each publisher first sees the daemon's subscriber, so the puts do go
    // out to the router.
    put_all(&vessel, "asv/otter-2/gnss", &gnss).await;
    put_all(&rogue, "asv/otter-3/gnss", &gnss).await;
    // Allowed: the daemon's identity under asv/*/twin/** (to the operator) ...
    let probe = rogue
        .declare_publisher("asv/probe/twin/check")
        .await
        .unwrap();
    wait_matching(&probe, Duration::from_secs(10)).await;
    probe.put("probe").await.unwrap();
    // ... and otter-1's own GNSS, last.
    put_all(&vessel, "asv/otter-1/gnss", &gnss).await;

    let mut seen = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(15);
    while !(seen.iter().any(|k| k == "asv/otter-1/twin/state")
        && seen.iter().any(|k| k == "asv/probe/twin/check"))
    {
        assert!(
            Instant::now() < deadline,
            "no state for otter-1 or no probe: {seen:?}"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
        drain(&watch, &mut seen);
    }

    // The operator asks for the latest states and the running twins.
    let replies: Vec<String> = operator
        .get("asv/*/twin/state")
        .await
        .unwrap()
        .into_iter()
        .filter_map(|r| r.into_result().ok())
        .map(|s| s.key_expr().as_str().to_string())
        .collect();
    assert_eq!(replies, ["asv/otter-1/twin/state"]);
    let alive: Vec<String> = operator
        .liveliness()
        .get("asv/*/twin/alive")
        .await
        .unwrap()
        .into_iter()
        .filter_map(|r| r.into_result().ok())
        .map(|s| s.key_expr().as_str().to_string())
        .collect();
    assert_eq!(alive, ["asv/otter-1/twin/alive"]);

    // Give any refused message time to arrive, had it got through.
    tokio::time::sleep(Duration::from_millis(500)).await;
    cancel.cancel();
    let summary = tokio::time::timeout(Duration::from_secs(20), handle)
        .await
        .unwrap()
        .unwrap()
        .unwrap();
    drain(&watch, &mut seen);
    let mut vessels: Vec<&String> = summary.vessels.keys().collect();
    vessels.sort();
    let mut keys = seen.clone();
    keys.sort();
    keys.dedup();
    println!("daemon served {vessels:?}; the operator saw {keys:?}");
    assert_eq!(vessels, ["otter-1"]);
    assert_eq!(summary.vessels["otter-1"].total_rejected(), 0);
    assert_eq!(summary.refused.total_rejected(), 0);
    assert!(
        !seen
            .iter()
            .any(|k| k.starts_with("asv/otter-2/") || k.starts_with("asv/otter-3/")),
        "{keys:?}"
    );
    for s in [daemon, vessel, operator, rogue, router] {
        s.close().await.unwrap();
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_credentials_cannot_open_a_session() {
    let dictionary = Dictionary::new("deny");
    let port = free_port();
    let router = zenoh::open(router(port, &dictionary)).await.unwrap();
    let attempts = [
        ("a wrong password", Some(("twind", "not-the-password"))),
        ("an unknown user", Some(("mallory", "anything"))),
        ("no credentials", None),
    ];
    for (what, user) in attempts {
        let mut c = login(port, user);
        // Try once instead of waiting for ever as the shipped client does.
        c.insert_json5("connect/timeout_ms", "0").unwrap();
        c.insert_json5("connect/exit_on_failure", "true").unwrap();
        let result = tokio::time::timeout(Duration::from_secs(20), zenoh::open(c))
            .await
            .unwrap_or_else(|_| panic!("{what}: no answer"));
        assert!(result.is_err(), "{what}: a session was opened");
        println!("{what}: refused ({})", result.err().unwrap());
    }
    // The right password does open one.
    let ok = open_as(port, "operator").await;
    ok.close().await.unwrap();
    router.close().await.unwrap();
}
