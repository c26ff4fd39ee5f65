//! Daemons sharing a fleet behind a Zenoh router (`[fleet] enabled`): the
//! active owner killed with SIGKILL mid-trial and its hot standby taking
//! over with the twin it kept; a daemon started after the owner's loss
//! restoring the vessel's calibration from the network; overlapping shares
//! with exactly one daemon publishing; the fleet's report naming overlaps
//! and gaps.
//!
//! The router is a Zenoh session in router mode in this process (the same
//! Zenoh as `zenohd`, which cannot be installed here: docs/deploy.md); the
//! daemons of the failover tests are `twind` processes, clients of it. What
//! a `zenohd` storage would keep of the calibrations is kept by a stand-in
//! in this process ([`CalibrationStore`]).

use std::collections::BTreeSet;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use tokio_util::sync::CancellationToken;
use twin_tests::net::{config, free_port};
use twin_tests::wire::{messages, offline, publish, simulate};
use twin_wire::outputs::{DaemonStatsMessage, FaultMessage};
use twind::fleet::FleetReport;
use twind::settings::Settings;

type Samples =
    zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>;

/// Longest any step of these tests waits before it fails (not a timing
/// assertion: the times are printed, the benchmark measures them).
const PATIENCE: Duration = Duration::from_secs(30);

fn fleet_settings(id: &str, own: &str, roster: &[&str]) -> String {
    let roster: Vec<String> = roster.iter().map(|v| format!("\"{v}\"")).collect();
    format!(
        "[daemon]\nid = \"{id}\"\n[vessels]\nown = \"{own}\"\n\
         [publish]\nstats_interval_s = 0.2\n[diagnose]\nenabled = false\n\
         [fleet]\nenabled = true\nreport_interval_s = 0.5\nroster = [{}]\n",
        roster.join(", ")
    )
}

fn start(port: u16, dir: &std::path::Path, id: &str) -> Child {
    start_with(port, dir, id, &fleet_settings(id, "*", &["otter-1"]))
}

/// A `twind` process with the settings `text`, a client of the router at
/// `port`, its state in `dir/{id}`.
fn start_with(port: u16, dir: &std::path::Path, id: &str, text: &str) -> Child {
    let settings = dir.join(format!("{id}.toml"));
    std::fs::write(&settings, text).unwrap();
    Command::new(env!("CARGO_BIN_EXE_twind"))
        .args(["--mode", "client", "--no-multicast-scouting"])
        .args(["--connect", &format!("tcp/127.0.0.1:{port}")])
        .arg("--settings")
        .arg(&settings)
        .arg("--state-dir")
        .arg(dir.join(id))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("twind starts")
}

/// The daemon id a fleet daemon's output carries (`daemon=<id>`).
fn publisher_of(sample: &zenoh::sample::Sample) -> String {
    let attachment = sample
        .attachment()
        .map(|a| String::from_utf8_lossy(&a.to_bytes()).into_owned())
        .unwrap_or_default();
    attachment
        .strip_prefix("daemon=")
        .unwrap_or_else(|| panic!("output without the daemon's id: {attachment:?}"))
        .to_string()
}

/// Waits until `daemon`'s fleet token is visible from `session`.
async fn wait_token(session: &zenoh::Session, daemon: &str) {
    let deadline = Instant::now() + PATIENCE;
    loop {
        let replies = session
            .liveliness()
            .get(format!("asv-fleet/daemon/{daemon}/**"))
            .await
            .unwrap();
        if replies.recv_async().await.is_ok() {
            return;
        }
        assert!(Instant::now() < deadline, "{daemon} never joined the fleet");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

/// Waits until `daemon`'s statistics say it has routed `routed` messages.
async fn wait_routed(stats: &Samples, daemon: &str, routed: u64) {
    let deadline = Instant::now() + PATIENCE;
    loop {
        while let Ok(Some(s)) = stats.try_recv() {
            let m: DaemonStatsMessage = serde_json::from_slice(&s.payload().to_bytes()).unwrap();
            if m.daemon == daemon && m.routed >= routed {
                return;
            }
        }
        assert!(
            Instant::now() < deadline,
            "{daemon} did not route {routed} messages"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

/// Every fault received so far, with the daemon that published it.
fn faults(sub: &Samples) -> Vec<(String, FaultMessage)> {
    let mut out = Vec::new();
    while let Ok(Some(s)) = sub.try_recv() {
        out.push((
            publisher_of(&s),
            serde_json::from_slice(&s.payload().to_bytes()).unwrap(),
        ));
    }
    out
}

fn kill(child: &mut Child) {
    let status = Command::new("kill")
        .args(["-KILL", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    child.wait().unwrap();
}

fn terminate(child: &mut Child) {
    let _ = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status();
    let deadline = Instant::now() + PATIENCE;
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > deadline {
            let _ = child.kill();
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// A fresh directory for the daemons' files, a router in this process, a
/// client of it, and the client's subscribers to `otter-1`'s faults and to
/// the daemons' statistics.
struct Harness {
    dir: std::path::PathBuf,
    port: u16,
    router: zenoh::Session,
    client: zenoh::Session,
    sub: Samples,
    stats: Samples,
}

async fn harness(name: &str) -> Harness {
    let dir = std::env::temp_dir().join(format!("{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let port = free_port();
    let router = zenoh::open(config("router", &[port], &[])).await.unwrap();
    let client = zenoh::open(config("client", &[], &[port])).await.unwrap();
    let sub = client
        .declare_subscriber("asv/otter-1/twin/fault")
        .with(zenoh::handlers::FifoChannel::new(100_000))
        .await
        .unwrap();
    let stats = client
        .declare_subscriber("asv/@twind/*/stats")
        .with(zenoh::handlers::FifoChannel::new(100_000))
        .await
        .unwrap();
    Harness {
        dir,
        port,
        router,
        client,
        sub,
        stats,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_standby_takes_over_with_its_twin_when_the_owner_is_killed() {
    let Harness {
        dir,
        port,
        router,
        client,
        sub,
        stats,
    } = harness("twind-fleet").await;

    // a starts first (the older: the owner), b joins as its standby.
    let mut a = start(port, &dir, "a");
    wait_token(&client, "a").await;
    let mut b = start(port, &dir, "b");
    wait_token(&client, "b").await;

    let msgs = messages(&simulate("s-manoeuvre_new-new", 0.3, 41));
    let half = msgs.len() / 2;
    publish(&client, "otter-1", &msgs[..half]).await;
    let half_count = u64::try_from(half).unwrap();
    wait_routed(&stats, "a", half_count).await;
    wait_routed(&stats, "b", half_count).await;
    // Both have handled the half (routed is counted as handed to the
    // vessel's task; its handling takes microseconds).
    tokio::time::sleep(Duration::from_secs(1)).await;
    let before = faults(&sub);
    let publishers: BTreeSet<&str> = before.iter().map(|(d, _)| d.as_str()).collect();
    assert_eq!(
        publishers,
        BTreeSet::from(["a"]),
        "only the owner publishes"
    );
    let (_, last_of_a) = before.last().unwrap().clone();

    kill(&mut a);
    let killed = Instant::now();
    let takeover = loop {
        if let Some((_, fault)) = faults(&sub).into_iter().find(|(d, _)| d == "b") {
            break fault;
        }
        assert!(killed.elapsed() < PATIENCE, "b never took over");
        tokio::time::sleep(Duration::from_millis(20)).await;
    };
    println!(
        "b took over {:.2} s after a was killed; port loss {:?} (a's last {:?})",
        killed.elapsed().as_secs_f64(),
        takeover.thrusters.port.loss_raw,
        last_of_a.thrusters.port.loss_raw
    );
    // With no input since the kill, b publishes at once the estimate it
    // learnt as a standby: the one a published last.
    assert_eq!(takeover.time, last_of_a.time);
    assert_eq!(
        takeover.thrusters.port.loss_raw,
        last_of_a.thrusters.port.loss_raw
    );
    assert_eq!(
        takeover.thrusters.starboard.loss_raw,
        last_of_a.thrusters.starboard.loss_raw
    );
    assert_eq!(
        takeover.thrusters.port.status,
        last_of_a.thrusters.port.status
    );

    // The rest of the trial, served by b alone: its last estimate is the
    // offline one over the whole trial.
    publish(&client, "otter-1", &msgs[half..]).await;
    wait_routed(&stats, "b", u64::try_from(msgs.len()).unwrap()).await;
    tokio::time::sleep(Duration::from_secs(1)).await;
    let after = faults(&sub);
    assert!(after.iter().all(|(d, _)| d == "b"), "a is dead");
    let (_, last) = after.last().expect("b publishes the rest");
    let twin = offline(&msgs);
    let expected = FaultMessage::new(
        "otter-1",
        &twin.fault_report(twin.state_report().unwrap().time_s),
        true,
    );
    assert_eq!(
        last.thrusters.port.loss_raw,
        expected.thrusters.port.loss_raw
    );
    assert_eq!(last.effectiveness_ratio, expected.effectiveness_ratio);
    let learnt = last.thrusters.port.loss_raw.unwrap();
    assert!((learnt - 0.3).abs() < 0.05, "{learnt}");

    terminate(&mut b);
    client.close().await.unwrap();
    router.close().await.unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}

/// Per key, the daemon that put the latest value and the value.
type Kept = std::sync::Arc<std::sync::Mutex<std::collections::BTreeMap<String, (String, Vec<u8>)>>>;

/// A stand-in for the routers' storage of the calibrations
/// (`config/zenohd-fleet.json5`'s memory storage on
/// `asv-fleet/calibration/**`): it keeps the latest value put on each key,
/// with the daemon that put it, and answers queries with them.
struct CalibrationStore {
    kept: Kept,
    _subscriber: zenoh::pubsub::Subscriber<()>,
    answering: tokio::task::JoinHandle<()>,
}

impl CalibrationStore {
    async fn on(session: &zenoh::Session) -> Self {
        let kept = Kept::default();
        let into = kept.clone();
        let subscriber = session
            .declare_subscriber("asv-fleet/calibration/**")
            .callback(move |sample: zenoh::sample::Sample| {
                into.lock().unwrap().insert(
                    sample.key_expr().to_string(),
                    (publisher_of(&sample), sample.payload().to_bytes().to_vec()),
                );
            })
            .await
            .unwrap();
        let queryable = session
            .declare_queryable("asv-fleet/calibration/**")
            .await
            .unwrap();
        let from = kept.clone();
        let answering = tokio::spawn(async move {
            while let Ok(query) = queryable.recv_async().await {
                let matching: Vec<(String, Vec<u8>)> = from
                    .lock()
                    .unwrap()
                    .iter()
                    .filter(|(key, _)| {
                        zenoh::key_expr::KeyExpr::try_from(key.as_str())
                            .is_ok_and(|k| query.key_expr().intersects(&k))
                    })
                    .map(|(key, (_, bytes))| (key.clone(), bytes.clone()))
                    .collect();
                for (key, bytes) in matching {
                    let _ = query.reply(key, bytes).await;
                }
            }
        });
        Self {
            kept,
            _subscriber: subscriber,
            answering,
        }
    }

    fn close(self) {
        self.answering.abort();
    }

    /// The calibration kept for `vessel`, with the daemon that put it.
    fn get(&self, vessel: &str) -> Option<(String, Vec<u8>)> {
        self.kept
            .lock()
            .unwrap()
            .get(&format!("asv-fleet/calibration/{vessel}"))
            .cloned()
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_daemon_started_after_the_owners_loss_restores_the_calibration_from_the_network() {
    let Harness {
        dir,
        port,
        router,
        client,
        sub,
        stats,
    } = harness("twind-fleet-net").await;
    let store = CalibrationStore::on(&client).await;
    let settings = |id: &str| {
        format!(
            "{}[persistence]\nsave_interval_s = 0.5\n",
            fleet_settings(id, "*", &["otter-1"])
        )
    };

    // a alone learns the first half of a trial with a 30 % port loss.
    let mut a = start_with(port, &dir, "a", &settings("a"));
    wait_token(&client, "a").await;
    let msgs = messages(&simulate("s-manoeuvre_new-new", 0.3, 41));
    let half = msgs.len() / 2;
    publish(&client, "otter-1", &msgs[..half]).await;
    wait_routed(&stats, "a", u64::try_from(half).unwrap()).await;
    let learnt = offline(&msgs[..half]);
    let last_fix_s = learnt.state_report().unwrap().time_s;
    // Until the storage holds what a learnt from the whole half.
    let deadline = Instant::now() + PATIENCE;
    let (putter, kept) = loop {
        if let Some((putter, bytes)) = store.get("otter-1") {
            let v: serde_json::Value = serde_json::from_slice(&bytes).unwrap();
            if v["time_s"].as_f64() == Some(last_fix_s) {
                break (putter, bytes);
            }
        }
        assert!(Instant::now() < deadline, "a never shared its calibration");
        tokio::time::sleep(Duration::from_millis(50)).await;
    };
    assert_eq!(putter, "a");
    let last_of_a = faults(&sub).last().unwrap().1.clone();

    // a's machine is lost with its disk; c starts on another, with an
    // empty state directory, and serves the rest of the trial.
    kill(&mut a);
    let mut c = start_with(port, &dir, "c", &settings("c"));
    wait_token(&client, "c").await;
    publish(&client, "otter-1", &msgs[half..]).await;
    wait_routed(&stats, "c", u64::try_from(msgs.len() - half).unwrap()).await;
    tokio::time::sleep(Duration::from_secs(1)).await;
    let from_c: Vec<FaultMessage> = faults(&sub)
        .into_iter()
        .filter(|(d, _)| d == "c")
        .map(|(_, f)| f)
        .collect();
    let first = from_c.first().expect("c publishes");
    println!(
        "a's last port loss {:?} ({:?}); c's first {:?} ({:?})",
        last_of_a.thrusters.port.loss_raw,
        last_of_a.thrusters.port.status,
        first.thrusters.port.loss_raw,
        first.thrusters.port.status
    );
    // c goes on from what a learnt, not from a cold start (a port loss of
    // 0): a's port loss from its first fix, and at the end exactly the twin
    // restored from the calibration the storage kept, fed the second half.
    let learnt_loss = last_of_a.thrusters.port.loss_raw.unwrap();
    assert!(learnt_loss > 0.2, "{learnt_loss}");
    let first_loss = first.thrusters.port.loss_raw.unwrap();
    assert!((first_loss - learnt_loss).abs() < 0.02, "{first_loss}");
    let profile = twin_wire::profile::VesselProfile::otter().identity();
    let calibration = twind::persist::decode(&kept, "otter-1", &profile).unwrap();
    let mut expected =
        twin_core::twin::VesselTwin::new(twin_core::twin::TwinConfig::default()).unwrap();
    expected.restore(calibration);
    let expected = twin_tests::wire::feed(expected, &msgs[half..]);
    let expected = FaultMessage::new(
        "otter-1",
        &expected.fault_report(expected.state_report().unwrap().time_s),
        true,
    );
    let last = from_c.last().unwrap();
    assert_eq!(
        last.thrusters.port.loss_raw,
        expected.thrusters.port.loss_raw
    );
    assert_eq!(last.effectiveness_ratio, expected.effectiveness_ratio);

    terminate(&mut c);
    store.close();
    client.close().await.unwrap();
    router.close().await.unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}

/// A daemon in this process, a client of the router at `port`.
async fn in_process(
    port: u16,
    id: &str,
    own: &str,
    roster: &[&str],
) -> (
    tokio::task::JoinHandle<anyhow::Result<twind::RunSummary>>,
    CancellationToken,
) {
    let settings = Settings::from_toml(&fleet_settings(id, own, roster)).unwrap();
    let session = zenoh::open(config("client", &[], &[port])).await.unwrap();
    let cancel = CancellationToken::new();
    let handle = tokio::spawn(twind::run(twind::RunConfig::new(
        settings,
        session,
        cancel.clone(),
    )));
    (handle, cancel)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn overlapping_shares_have_one_publisher_and_the_report_names_overlaps_and_gaps() {
    let port = free_port();
    let router = zenoh::open(config("router", &[port], &[])).await.unwrap();
    let client = zenoh::open(config("client", &[], &[port])).await.unwrap();
    let reports = client
        .declare_subscriber("asv-fleet/report/*")
        .with(zenoh::handlers::FifoChannel::new(10_000))
        .await
        .unwrap();
    let sub = client
        .declare_subscriber("asv/*/twin/fault")
        .with(zenoh::handlers::FifoChannel::new(100_000))
        .await
        .unwrap();
    let stats = client
        .declare_subscriber("asv/@twind/*/stats")
        .with(zenoh::handlers::FifoChannel::new(100_000))
        .await
        .unwrap();
    let roster = ["north-1", "south-1"];
    let (a, stop_a) = in_process(port, "north-a", "north-$*", &roster).await;
    wait_token(&client, "north-a").await;
    let (b, stop_b) = in_process(port, "north-b", "north-$*", &roster).await;
    wait_token(&client, "north-b").await;

    // Each daemon reports the overlap of the two and the gap south-1.
    let mut seen = BTreeSet::new();
    let deadline = Instant::now() + PATIENCE;
    while seen.len() < 2 {
        assert!(Instant::now() < deadline, "reports seen from {seen:?} only");
        let Ok(Some(s)) = reports.try_recv() else {
            tokio::time::sleep(Duration::from_millis(50)).await;
            continue;
        };
        let report: FleetReport = serde_json::from_slice(&s.payload().to_bytes()).unwrap();
        if report.members.len() < 2 {
            continue;
        }
        assert_eq!(
            s.key_expr().as_str(),
            format!("asv-fleet/report/{}", report.daemon)
        );
        assert_eq!(
            report.members,
            vec![
                ["north-a".to_string(), "north-$*".to_string()],
                ["north-b".to_string(), "north-$*".to_string()],
            ]
        );
        assert_eq!(report.overlaps.len(), 1);
        assert_eq!(report.overlaps[0].daemons, ["north-a", "north-b"]);
        assert_eq!(report.gaps, vec!["south-1".to_string()]);
        seen.insert(report.daemon);
    }

    // Both run north-1's twin; only the owner, north-a, publishes it.
    let msgs = messages(&simulate("s-manoeuvre_new-new", 0.25, 5));
    publish(&client, "north-1", &msgs).await;
    let all = u64::try_from(msgs.len()).unwrap();
    wait_routed(&stats, "north-a", all).await;
    wait_routed(&stats, "north-b", all).await;
    // The standby leaves first (the owner leaving first would hand north-1
    // over to it, which would then publish, as it should).
    stop_b.cancel();
    let summary_b = b.await.unwrap().unwrap();
    stop_a.cancel();
    let summary_a = a.await.unwrap().unwrap();
    for summary in [&summary_a, &summary_b] {
        assert_eq!(summary.routed, u64::try_from(msgs.len()).unwrap());
    }
    tokio::time::sleep(Duration::from_millis(500)).await;
    let published = faults(&sub);
    assert!(!published.is_empty());
    assert!(
        published
            .iter()
            .all(|(d, f)| d == "north-a" && f.vessel == "north-1"),
        "{:?}",
        published.iter().map(|(d, _)| d).collect::<BTreeSet<_>>()
    );
    client.close().await.unwrap();
    router.close().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn without_vessel_tokens_the_daemon_has_one_token_and_lists_its_vessels() {
    let port = free_port();
    let router = zenoh::open(config("router", &[port], &[])).await.unwrap();
    let client = zenoh::open(config("client", &[], &[port])).await.unwrap();
    let settings =
        Settings::from_toml("[daemon]\nid = \"d1\"\n[publish]\nvessel_liveliness = false\n")
            .unwrap();
    let session = zenoh::open(config("client", &[], &[port])).await.unwrap();
    let cancel = CancellationToken::new();
    let handle = tokio::spawn(twind::run(twind::RunConfig::new(
        settings,
        session,
        cancel.clone(),
    )));
    let msgs = messages(&simulate("s-manoeuvre_new-new", 0.0, 9));
    let few = twin_tests::wire::nth_fix(&msgs, 20);
    publish(&client, "otter-3", &msgs[..few]).await;
    publish(&client, "otter-4", &msgs[..few]).await;

    let deadline = Instant::now() + PATIENCE;
    let listed = loop {
        let replies = client.get("asv/@twind/*/vessels").await.unwrap();
        let mut listed = Vec::new();
        while let Ok(reply) = replies.recv_async().await {
            let sample = reply.result().unwrap();
            listed.push(
                serde_json::from_slice::<serde_json::Value>(&sample.payload().to_bytes()).unwrap(),
            );
        }
        if listed.len() == 1
            && listed[0]["vessels"]
                .as_array()
                .is_some_and(|v| v.len() == 2)
        {
            break listed;
        }
        assert!(Instant::now() < deadline, "vessels listed: {listed:?}");
        tokio::time::sleep(Duration::from_millis(100)).await;
    };
    assert_eq!(
        listed[0],
        serde_json::json!({"daemon": "d1", "vessels": ["otter-3", "otter-4"]})
    );
    let tokens = |key: &'static str| {
        let client = client.clone();
        async move {
            let replies = client.liveliness().get(key).await.unwrap();
            let mut keys = Vec::new();
            while let Ok(reply) = replies.recv_async().await {
                keys.push(reply.result().unwrap().key_expr().to_string());
            }
            keys
        }
    };
    assert_eq!(
        tokens("asv/@twind/*/alive").await,
        vec!["asv/@twind/d1/alive"]
    );
    assert!(tokens("asv/*/twin/alive").await.is_empty());
    cancel.cancel();
    handle.await.unwrap().unwrap();
    client.close().await.unwrap();
    router.close().await.unwrap();
}
