//! MCAP recordings read by an independent reader: `twin analyze --mcap`
//! over a simulated trial with a 25 % port loss writes a recording that
//! PyPI's `mcap` package (requirements.txt; `tests/peers/mcap_summary.py`)
//! reads with the expected channels, JSON Schema encodings, Foxglove's
//! `LocationFix` for the position, and exactly as many messages per channel
//! as the run produced. Read back, the recording gives the same fault as
//! the original log: through `twin analyze`, and through `twin-replay` into
//! the daemon. And `twind --record`: a live daemon's recording holds every
//! input it was sent and every output it published, read by the same
//! reader.

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;
use twin_cli::analyze::{AnalyzeOptions, analyze_path};
use twin_tests::daemon::{outputs, replayed_faults, rig, rig_with};
use twin_tests::peers::{repo_root, require_python_module};
use twin_tests::wire::{messages, receive_until_fault, simulate};
use twin_wire::outputs::FaultMessage;
use twind::settings::Settings;

/// The tests of this file drive a live daemon at full speed, and their
/// outcome depends on it keeping up: they run one at a time.
static SERIAL: tokio::sync::Mutex<()> = tokio::sync::Mutex::const_new(());

/// A directory of this test's own files.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("twin-mcap-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The trial as the project's JSON lines.
fn write_trial(path: &Path, seed: u64) {
    let mut text = String::new();
    for (topic, bytes) in messages(&simulate("s-manoeuvre_new-broken", 0.25, seed)) {
        let mut v: Value = serde_json::from_slice(&bytes).unwrap();
        v["type"] = Value::from(topic);
        text.push_str(&v.to_string());
        text.push('\n');
    }
    std::fs::write(path, text).unwrap();
}

/// What PyPI's `mcap` reads in `file`.
fn python_summary(file: &Path) -> Value {
    let install = "python3 -m pip install -r requirements.txt";
    require_python_module("python3", "mcap", install);
    let out = Command::new("python3")
        .arg(repo_root().join("tests/peers/mcap_summary.py"))
        .arg(file)
        .output()
        .expect("python3 runs");
    assert!(
        out.status.success(),
        "mcap_summary.py failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("a JSON summary")
}

#[test]
fn twin_analyze_mcap_is_read_by_pypi_mcap_with_every_message_of_the_run() {
    let _serial = SERIAL.blocking_lock();
    let dir = scratch("analyze");
    let (log, recording) = (dir.join("trial.jsonl"), dir.join("trial.mcap"));
    write_trial(&log, 91);
    let options = AnalyzeOptions {
        mcap: Some(recording.clone()),
        ..AnalyzeOptions::default()
    };
    let analysis: Value =
        serde_json::from_str(&analyze_path(&log, &options).unwrap().to_json()).unwrap();
    let summary = python_summary(&recording);
    let channels = summary["channels"].as_object().unwrap();
    let mut topics: Vec<&str> = channels.keys().map(String::as_str).collect();
    topics.sort();
    assert_eq!(
        topics,
        [
            "/log/actuators",
            "/log/gnss",
            "/log/twin/alarm",
            "/log/twin/fault",
            "/log/twin/location",
            "/log/twin/state"
        ]
    );
    let count = |topic: &str| channels[topic]["messages"].as_u64().unwrap();
    let n = |v: &Value| v.as_u64().unwrap();
    let assembled = &analysis["assembled"];
    assert_eq!(count("/log/gnss"), n(&assembled["fixes"]));
    assert_eq!(
        count("/log/actuators"),
        n(&assembled["propeller_pairs"]) + n(&assembled["thrust_commands"])
    );
    let steps = n(&analysis["samples_by_kind"]["fixes"]);
    assert!(steps > 100, "{steps} steps");
    for topic in ["/log/twin/state", "/log/twin/fault", "/log/twin/location"] {
        assert_eq!(count(topic), steps, "{topic}");
    }
    assert_eq!(
        count("/log/twin/alarm"),
        analysis["alarms"].as_array().unwrap().len() as u64
    );
    let total: u64 = channels.values().map(|c| n(&c["messages"])).sum();
    assert_eq!(n(&summary["message_count"]), total);
    for (topic, c) in channels {
        assert_eq!(c["message_encoding"], "json", "{topic}");
        assert_eq!(c["schema_encoding"], "jsonschema", "{topic}");
        assert_eq!(
            c["valid_json"], c["messages"],
            "{topic}: required fields missing"
        );
    }
    let location = &channels["/log/twin/location"];
    assert_eq!(location["schema_name"], "foxglove.LocationFix");
    let fix = &location["first"];
    assert_eq!(fix["position_covariance"].as_array().unwrap().len(), 9);
    assert!(fix["timestamp"]["sec"].as_u64().unwrap() > 0);
    assert!(fix["latitude"].as_f64().unwrap().abs() <= 90.0);
    assert_eq!(
        channels["/log/twin/state"]["schema_name"],
        "twin_wire.StateMessage"
    );

    // The recording's inputs read back: the same conclusion.
    let again: Value = serde_json::from_str(
        &analyze_path(&recording, &AnalyzeOptions::default())
            .unwrap()
            .to_json(),
    )
    .unwrap();
    assert_eq!(again["format"], "json_lines");
    assert_eq!(again["thrusters"], analysis["thrusters"]);
    assert_eq!(again["thrusters"]["port"]["status"], "fault");
    std::fs::remove_dir_all(&dir).ok();
}

/// The last fault the daemon publishes for `vessel` while `twin-replay`
/// plays `file` as fast as it takes it.
async fn replayed_fault(rig: &twin_tests::daemon::Rig, file: &Path, vessel: &str) -> FaultMessage {
    replayed_faults(rig, file, vessel)
        .await
        .pop()
        .expect("a fault")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn twin_replay_of_the_recording_gives_the_daemon_the_same_fault_as_the_log() {
    let _serial = SERIAL.lock().await;
    let dir = scratch("replay");
    let (log, recording) = (dir.join("trial.jsonl"), dir.join("trial.mcap"));
    write_trial(&log, 92);
    let options = AnalyzeOptions {
        mcap: Some(recording.clone()),
        ..AnalyzeOptions::default()
    };
    analyze_path(&log, &options).unwrap();
    let settings = Settings::from_toml("[diagnose]\nenabled = false\n").unwrap();
    let rig = rig(settings).await;
    let from_log = replayed_fault(&rig, &log, "from-log").await;
    let from_mcap = replayed_fault(&rig, &recording, "from-mcap").await;
    rig.stop().await;
    assert_eq!(from_mcap.time, from_log.time);
    assert_eq!(from_mcap.thrusters, from_log.thrusters);
    assert_eq!(
        from_mcap.thrusters.port.status,
        twin_wire::outputs::ThrusterStatusName::Fault
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn twind_record_holds_every_input_sent_and_every_output_published() {
    let _serial = SERIAL.lock().await;
    let dir = scratch("record");
    let recording = dir.join("live.mcap");
    let msgs = messages(&simulate("s-manoeuvre_new-broken", 0.25, 93));
    let sent = |topic: &str| msgs.iter().filter(|(t, _)| *t == topic).count() as u64;
    let last_time = {
        let (_, bytes) = msgs.iter().rev().find(|(t, _)| *t == "gnss").unwrap();
        let v: Value = serde_json::from_slice(bytes).unwrap();
        v["time"].as_str().unwrap().to_owned()
    };
    let settings = Settings::from_toml("[diagnose]\nenabled = false\n").unwrap();
    let path = recording.clone();
    let rig = rig_with(settings, move |run| twind::RunConfig {
        record: Some(path),
        ..run
    })
    .await;
    let sub = rig.collect("rec-1").await;
    rig.publish("rec-1", &msgs).await;
    let mut samples = receive_until_fault(&sub, &last_time).await;
    let summary = rig.stop().await;
    samples.extend(twin_tests::daemon::drain(&sub));
    let record = summary.record.expect("a recording");
    assert_eq!(
        (record.dropped, record.refused, &record.error),
        (0, 0, &None)
    );

    let read = python_summary(&recording);
    let channels = read["channels"].as_object().unwrap();
    let count = |topic: &str| {
        channels
            .get(topic)
            .map_or(0, |c| c["messages"].as_u64().unwrap())
    };
    assert_eq!(count("/rec-1/gnss"), sent("gnss"));
    assert_eq!(count("/rec-1/actuators"), sent("actuators"));
    let states: Vec<twin_wire::outputs::StateMessage> = outputs(&samples, "twin/state");
    let faults: Vec<FaultMessage> = outputs(&samples, "twin/fault");
    assert!(states.len() > 100, "{} states", states.len());
    assert_eq!(count("/rec-1/twin/state"), states.len() as u64);
    assert_eq!(count("/rec-1/twin/location"), states.len() as u64);
    assert_eq!(count("/rec-1/twin/fault"), faults.len() as u64);
    for (topic, c) in channels {
        assert_eq!(c["message_encoding"], "json", "{topic}");
        assert_eq!(c["schema_encoding"], "jsonschema", "{topic}");
        assert_eq!(c["valid_json"], c["messages"], "{topic}");
        assert_eq!(
            record.counts.get(topic),
            c["messages"].as_u64().as_ref(),
            "{topic}"
        );
    }
    // The recording's inputs read back give the twin's conclusion.
    let again: Value = serde_json::from_str(
        &analyze_path(&recording, &AnalyzeOptions::default())
            .unwrap()
            .to_json(),
    )
    .unwrap();
    assert_eq!(again["thrusters"]["port"]["status"], "fault");
    std::fs::remove_dir_all(&dir).ok();
}
