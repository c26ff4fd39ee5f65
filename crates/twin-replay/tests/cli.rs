//! The `twin-replay` binary: refuses what it cannot replay with a non-zero
//! exit and a clear message, and replays a log to a subscriber in this
//! process (loopback, explicit endpoint, no multicast scouting).

mod common;

use std::process::{Command, Output};

use common::*;
use twin_wire::VesselId;

const BIN: &str = env!("CARGO_BIN_EXE_twin-replay");

/// Flags that keep the binary's session on loopback.
const LOOPBACK: [&str; 3] = ["--no-multicast-scouting", "--listen", "tcp/127.0.0.1:0"];

fn twin_replay(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .args(LOOPBACK)
        .output()
        .expect("the binary runs")
}

fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

#[test]
fn a_missing_log_exits_non_zero_naming_it() {
    let out = twin_replay(&["/nonexistent/trial.log", "--vessel", "v1"]);
    assert!(!out.status.success());
    let err = stderr(&out);
    assert!(
        err.contains("cannot open the log /nonexistent/trial.log"),
        "{err}"
    );
}

#[test]
fn a_garbage_log_exits_non_zero_saying_why() {
    let path = scratch("garbage.log", &b"\x00\x01garbage \xff\n".repeat(64));
    let out = twin_replay(&[path.to_str().unwrap(), "--vessel", "v1"]);
    assert!(!out.status.success());
    let err = stderr(&out);
    assert!(
        err.contains("cannot read") && err.contains("unknown log format"),
        "{err}"
    );
}

#[test]
fn bad_arguments_exit_non_zero_naming_the_flag() {
    let log = format!("{REAL_LOGS}/plaka.log");
    for (args, flag) in [
        (vec![log.as_str(), "--vessel", "a/b"], "--vessel"),
        (
            vec![log.as_str(), "--vessel", "v1", "--rate", "fast"],
            "--rate",
        ),
        (
            vec![log.as_str(), "--vessel", "v1", "--rate", "0"],
            "--rate",
        ),
        (
            vec![log.as_str(), "--vessel", "v1", "--start", "-5"],
            "--start",
        ),
        (
            vec![log.as_str(), "--vessel", "v1", "--duration", "0"],
            "--duration",
        ),
        (
            vec![log.as_str(), "--vessel", "v1", "--duration", "-1"],
            "--duration",
        ),
        (
            vec![log.as_str(), "--vessel", "v1", "--start", "nan"],
            "--start",
        ),
        (
            vec![log.as_str(), "--vessel", "v1", "--wait", "-1"],
            "--wait",
        ),
        (
            vec![log.as_str(), "--vessel", "v1", "--prefix", "a/*"],
            "--prefix",
        ),
        (
            vec![log.as_str(), "--vessel", "v1", "--mode", "server"],
            "--mode",
        ),
        (
            vec![log.as_str(), "--vessel", "v1", "--connect", "7447"],
            "--connect",
        ),
        (vec![log.as_str()], "--vessel"),
    ] {
        let out = twin_replay(&args);
        assert!(!out.status.success(), "{args:?} succeeded");
        let err = stderr(&out);
        assert!(err.contains(flag), "{args:?}: {err}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_binary_replays_a_log_to_a_subscriber() {
    let vessel = VesselId::new("cli").unwrap();
    let log = generated_log(3);
    let (expected, _) = expected(std::io::Cursor::new(log.clone()), &vessel, 0.0, None);
    let path = scratch("generated.jsonl", &log);
    let (session, endpoint) = listening_session().await;
    let collector = Collector::new(&session, "asv/cli/**").await;
    let args: Vec<String> = [
        path.to_str().unwrap(),
        "--vessel",
        "cli",
        "--rate",
        "max",
        "--connect",
        endpoint.as_str(),
    ]
    .map(str::to_owned)
    .to_vec();
    let out = tokio::task::spawn_blocking(move || {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        twin_replay(&args)
    })
    .await
    .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let summary = String::from_utf8_lossy(&out.stdout);
    assert!(
        summary.contains(&format!(
            "published: {} gnss, {} actuators",
            expected.len() / 2,
            expected.len() / 2
        )),
        "{summary}"
    );
    let received = collector.wait_for(expected.len()).await;
    assert_eq!(received, expected);
}
