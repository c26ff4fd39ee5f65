//! Access control with the shipped `config/zenoh-acl.json5`: a router on
//! loopback enforcing it (only the listen port and the password dictionary
//! replaced, the dictionary a throwaway file written here), the daemons
//! (`twind::run`) and the others as clients logging in with
//! `config/zenoh-usrpwd.json5` and their own user names.
//!
//! What it shows:
//! - each vessel's GNSS reaches its owning daemon only (`twind` owns
//!   `otter-1`, `twind-2` owns `otter-2`), and the outputs, query answers,
//!   liveliness tokens and daemon statistics reach the operator; a vessel
//!   putting another vessel's GNSS, and a daemon's identity putting GNSS,
//!   are dropped by the router although the publishers see the daemons'
//!   subscriber;
//! - nobody but a vessel's owning daemon can publish its outputs: an
//!   operator, the vessel and another daemon cannot forge a fault, a
//!   liveliness token or a query answer;
//! - a wrong password, an unknown user or no credentials cannot open a session.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use tokio_util::sync::CancellationToken;
use twin_tests::net::free_port;
use twin_tests::wire::{live_fix, now_s, wait_matching};
use twind::settings::Settings;
use zenoh::handlers::{FifoChannel, FifoChannelHandler};
use zenoh::pubsub::Subscriber;
use zenoh::sample::Sample;
use zenoh::{Session, Wait};

const USERS: [(&str, &str); 5] = [
    ("twind", "throwaway-twind-password"),
    ("twind-2", "throwaway-twind-2-password"),
    ("otter-1", "throwaway-otter-1-password"),
    ("otter-2", "throwaway-otter-2-password"),
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

/// `n` live GNSS fixes 0.2 s apart, heading north at 1 m/s, the last one
/// stamped now.
fn fixes(n: usize) -> Vec<Vec<u8>> {
    let t0 = now_s() - 0.2 * n as f64;
    (0..n).map(|i| live_fix(t0 + 0.2 * i as f64, i)).collect()
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

fn drain(sub: &Subscriber<FifoChannelHandler<Sample>>, into: &mut Vec<Sample>) {
    while let Ok(Some(s)) = sub.try_recv() {
        into.push(s);
    }
}

fn keys_of(samples: &[Sample]) -> Vec<String> {
    let mut keys: Vec<String> = samples
        .iter()
        .map(|s| s.key_expr().as_str().to_string())
        .collect();
    keys.sort();
    keys.dedup();
    keys
}

/// A daemon logged in as `user`, with that id, serving what the router
/// lets it hear.
struct Daemon {
    session: Session,
    cancel: CancellationToken,
    handle: tokio::task::JoinHandle<anyhow::Result<twind::RunSummary>>,
}

impl Daemon {
    async fn start(port: u16, user: &str) -> Self {
        let session = open_as(port, user).await;
        let settings = Settings::from_toml(&format!(
            "[daemon]\nid = \"{user}\"\n[publish]\nstats_interval_s = 0.5\n"
        ))
        .unwrap();
        let cancel = CancellationToken::new();
        let handle = tokio::spawn(twind::run(twind::RunConfig::new(
            settings,
            session.clone(),
            cancel.clone(),
        )));
        Self {
            session,
            cancel,
            handle,
        }
    }

    async fn stop(self) -> twind::RunSummary {
        self.cancel.cancel();
        let summary = tokio::time::timeout(Duration::from_secs(20), self.handle)
            .await
            .unwrap()
            .unwrap()
            .unwrap();
        self.session.close().await.unwrap();
        summary
    }
}

/// Receives on `sub` into `seen` until every key of `wanted` has come, for
/// at most 20 s.
async fn wait_for(
    sub: &Subscriber<FifoChannelHandler<Sample>>,
    seen: &mut Vec<Sample>,
    wanted: &[&str],
) {
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        drain(sub, seen);
        let keys = keys_of(seen);
        if wanted.iter().all(|w| keys.iter().any(|k| k == w)) {
            return;
        }
        assert!(
            Instant::now() < deadline,
            "not all of {wanted:?} came: {keys:?}"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

async fn replies(session: &Session, key: &str) -> Vec<Sample> {
    session
        .get(key)
        .timeout(Duration::from_secs(5))
        .await
        .unwrap()
        .into_iter()
        .filter_map(|r| r.into_result().ok())
        .collect()
}

async fn tokens(session: &Session, key: &str) -> Vec<String> {
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

/// Two daemons, each the owner of one vessel: each vessel's inputs reach
/// its owner only, and its outputs, query answers, liveliness token and the
/// daemons' statistics reach the operator; a vessel putting another
/// vessel's GNSS, and a daemon's identity putting GNSS, are dropped by the
/// router although the publishers see the daemons' subscribers.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn each_vessel_reaches_its_owning_daemon_only_and_its_outputs_the_operator() {
    let dictionary = Dictionary::new("owners");
    let port = free_port();
    let router = zenoh::open(router(port, &dictionary)).await.unwrap();
    let operator = open_as(port, "operator").await;
    let watch = operator
        .declare_subscriber("asv/*/twin/**")
        .with(FifoChannel::new(100_000))
        .await
        .unwrap();
    let watch_daemons = operator
        .declare_subscriber("asv/@twind/*/stats")
        .with(FifoChannel::new(100_000))
        .await
        .unwrap();
    let a = Daemon::start(port, "twind").await;
    let b = Daemon::start(port, "twind-2").await;
    let otter1 = open_as(port, "otter-1").await;
    let otter2 = open_as(port, "otter-2").await;
    // Another session with a daemon's identity (a daemon gone wrong).
    let rogue = open_as(port, "twind").await;

    let gnss = fixes(10);
    // Refused: another vessel's GNSS, and GNSS from a daemon's identity.
    put_all(&otter1, "asv/otter-2/gnss", &gnss).await;
    put_all(&rogue, "asv/otter-1/gnss", &gnss[..3]).await;
    // Allowed: each vessel's own GNSS, last.
    put_all(&otter1, "asv/otter-1/gnss", &gnss).await;
    put_all(&otter2, "asv/otter-2/gnss", &gnss).await;

    let mut seen = Vec::new();
    wait_for(
        &watch,
        &mut seen,
        &["asv/otter-1/twin/state", "asv/otter-2/twin/state"],
    )
    .await;
    let mut daemon_stats = Vec::new();
    wait_for(
        &watch_daemons,
        &mut daemon_stats,
        &["asv/@twind/twind/stats", "asv/@twind/twind-2/stats"],
    )
    .await;
    let states = keys_of(&replies(&operator, "asv/*/twin/state").await);
    assert_eq!(states, ["asv/otter-1/twin/state", "asv/otter-2/twin/state"]);
    let mut alive = tokens(&operator, "asv/*/twin/alive").await;
    alive.sort();
    assert_eq!(alive, ["asv/otter-1/twin/alive", "asv/otter-2/twin/alive"]);

    // Give any refused message time to arrive, had it got through.
    tokio::time::sleep(Duration::from_millis(500)).await;
    let (sa, sb) = (a.stop().await, b.stop().await);
    drain(&watch, &mut seen);
    let served = |s: &twind::RunSummary| {
        let mut v: Vec<String> = s.vessels.keys().cloned().collect();
        v.sort();
        v
    };
    println!(
        "twind served {:?}, twind-2 {:?}; the operator saw {:?}",
        served(&sa),
        served(&sb),
        keys_of(&seen)
    );
    assert_eq!(served(&sa), ["otter-1"]);
    assert_eq!(served(&sb), ["otter-2"]);
    for s in [&sa, &sb] {
        assert_eq!(s.refused.total_rejected(), 0);
        // Each vessel's ten fixes, nothing from the rogue or the neighbour.
        assert!(s.vessels.values().all(|c| c.total_received() == 10));
    }
    for s in [operator, otter1, otter2, rogue, router] {
        s.close().await.unwrap();
    }
}

/// Item 6: nobody but a vessel's owning daemon can publish its outputs.
/// An operator, the vessel itself and another daemon's identity each try to
/// put a forged `twin/fault` for otter-1, to hold liveliness tokens for
/// otter-1 and for a vessel that does not exist, and (the other daemon) to
/// answer the operator's state query with a forged state: the router drops
/// all of it, while the owning daemon's faults, token and answer reach the
/// operator.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn no_identity_but_the_owning_daemons_can_publish_a_vessels_outputs() {
    let dictionary = Dictionary::new("forge");
    let port = free_port();
    let router = zenoh::open(router(port, &dictionary)).await.unwrap();
    let operator = open_as(port, "operator").await;
    let watch = operator
        .declare_subscriber("asv/*/twin/**")
        .with(FifoChannel::new(100_000))
        .await
        .unwrap();
    let owner = Daemon::start(port, "twind").await;
    let vessel = open_as(port, "otter-1").await;
    put_all(&vessel, "asv/otter-1/gnss", &fixes(10)).await;
    let mut seen = Vec::new();
    wait_for(&watch, &mut seen, &["asv/otter-1/twin/fault"]).await;

    let forgers = [
        ("an operator", open_as(port, "operator").await),
        ("the vessel", open_as(port, "otter-1").await),
        ("another daemon", open_as(port, "twind-2").await),
    ];
    let mut held = Vec::new();
    for (who, session) in &forgers {
        let forged = format!("{{\"forged_by\":\"{who}\"}}");
        put_all(session, "asv/otter-1/twin/fault", &[forged.into_bytes()]).await;
        for key in ["asv/otter-1/twin/alive", "asv/ghost/twin/alive"] {
            // Declared (or refused at once): either way nobody may see it.
            if let Ok(token) = session.liveliness().declare_token(key).await {
                held.push(token);
            }
        }
    }
    let (_, other_daemon) = &forgers[2];
    let answering = other_daemon
        .declare_queryable("asv/*/twin/*")
        .callback(|query| {
            for vessel in ["otter-1", "ghost"] {
                let key = format!("asv/{vessel}/twin/state");
                if query
                    .key_expr()
                    .intersects(&zenoh::key_expr::KeyExpr::try_from(key.as_str()).unwrap())
                {
                    let _ = query
                        .reply(key, "{\"forged_by\":\"another daemon\"}")
                        .wait();
                }
            }
        })
        .await
        .unwrap();
    tokio::time::sleep(Duration::from_millis(500)).await;

    let states = replies(&operator, "asv/*/twin/state").await;
    let alive = tokens(&operator, "asv/*/twin/alive").await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    drain(&watch, &mut seen);
    let forged: Vec<String> = seen
        .iter()
        .chain(&states)
        .map(|s| String::from_utf8_lossy(&s.payload().to_bytes()).into_owned())
        .filter(|p| p.contains("forged_by"))
        .collect();
    println!(
        "the operator saw {:?}, {} state replies, tokens {alive:?}",
        keys_of(&seen),
        states.len()
    );
    assert!(forged.is_empty(), "forgeries got through: {forged:?}");
    assert_eq!(alive, ["asv/otter-1/twin/alive"]);
    assert_eq!(keys_of(&states), ["asv/otter-1/twin/state"]);
    assert_eq!(states.len(), 1);

    answering.undeclare().await.unwrap();
    drop(held);
    owner.stop().await;
    for (_, s) in forgers {
        s.close().await.unwrap();
    }
    for s in [operator, vessel, router] {
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
