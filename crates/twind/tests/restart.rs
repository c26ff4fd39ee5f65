//! Kill (SIGTERM) and restart mid-trial: the daemon saves the calibration on
//! its way out, and the restarted daemon's fault estimate starts exactly from
//! the saved one and continues from it.

use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use twin_tests::net::{config, free_port};
use twin_tests::wire::{messages, publish, simulate};
use twin_wire::outputs::FaultMessage;

fn start(port: u16, state_dir: &std::path::Path) -> Child {
    Command::new(env!("CARGO_BIN_EXE_twind"))
        .args(["--mode", "peer", "--no-multicast-scouting"])
        .args(["--listen", &format!("tcp/127.0.0.1:{port}")])
        .arg("--state-dir")
        .arg(state_dir)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("twind starts")
}

fn terminate(mut child: Child) -> std::process::ExitStatus {
    let status = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        if let Some(s) = child.try_wait().unwrap() {
            return s;
        }
        assert!(Instant::now() < deadline, "twind did not stop on SIGTERM");
        std::thread::sleep(Duration::from_millis(50));
    }
}

fn faults(
    sub: &zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>,
) -> Vec<FaultMessage> {
    let mut v = Vec::new();
    while let Ok(Some(s)) = sub.try_recv() {
        v.push(serde_json::from_slice(&s.payload().to_bytes()).unwrap());
    }
    v
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_restart_keeps_the_calibration() {
    let dir = std::env::temp_dir().join(format!("twind-restart-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let msgs = messages(&simulate("s-manoeuvre_new-new", 0.3, 77));
    let half = msgs.len() / 2;

    // First life: half the trial.
    let port = free_port();
    let daemon = start(port, &dir);
    let client = zenoh::open(config("peer", &[], &[port])).await.unwrap();
    let sub = client
        .declare_subscriber("asv/otter-7/twin/fault")
        .with(zenoh::handlers::FifoChannel::new(100_000))
        .await
        .unwrap();
    publish(&client, "otter-7", &msgs[..half]).await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    let status = terminate(daemon);
    assert!(status.success(), "twind exited with {status}");
    tokio::time::sleep(Duration::from_millis(200)).await;
    let first_life = faults(&sub);
    let last = first_life.last().expect("faults were published");
    let saved: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join("otter-7.json")).expect("calibration saved on SIGTERM"),
    )
    .unwrap();
    let saved_theta = [
        saved["theta"][0].as_f64().unwrap(),
        saved["theta"][1].as_f64().unwrap(),
    ];
    println!(
        "first life: last published port loss {:?}; saved theta {saved_theta:?}",
        last.thrusters.port.loss_raw
    );
    // The saved calibration is the extended twin's: both losses and the
    // profile's four errors; the loss published from it is the truth's.
    assert_eq!(saved["theta"].as_array().map(Vec::len), Some(6), "{saved}");
    let learnt = last.thrusters.port.loss_raw.expect("a port loss");
    assert!((learnt - 0.3).abs() < 0.05, "{learnt}");

    // Second life: the rest of the trial, on a new daemon with the same state.
    let port2 = free_port();
    let daemon = start(port2, &dir);
    let client2 = zenoh::open(config("peer", &[], &[port2])).await.unwrap();
    let sub2 = client2
        .declare_subscriber("asv/otter-7/twin/fault")
        .with(zenoh::handlers::FifoChannel::new(100_000))
        .await
        .unwrap();
    publish(&client2, "otter-7", &msgs[half..]).await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    assert!(terminate(daemon).success());
    tokio::time::sleep(Duration::from_millis(200)).await;
    let second_life = faults(&sub2);
    let first = second_life.first().expect("faults after the restart");
    println!(
        "second life: first port loss {:?} (restored), last {:?}; status from the start {:?}",
        first.thrusters.port.loss_raw,
        second_life.last().unwrap().thrusters.port.loss_raw,
        first.thrusters.port.status
    );
    // The restored estimate is the one published last, and the decision held.
    assert_eq!(first.thrusters.port.loss_raw, last.thrusters.port.loss_raw);
    assert_eq!(
        first.thrusters.starboard.loss_raw,
        last.thrusters.starboard.loss_raw
    );
    assert_eq!(first.effectiveness_ratio, last.effectiveness_ratio);
    assert_eq!(first.thrusters.port.status, last.thrusters.port.status);
    // And it continues from there: never re-learning from zero.
    assert!(
        second_life
            .iter()
            .all(|f| f.thrusters.port.loss.unwrap() > 0.2)
    );
    assert!((second_life.last().unwrap().thrusters.port.loss.unwrap() - 0.3).abs() < 0.03);
    client.close().await.unwrap();
    client2.close().await.unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}
