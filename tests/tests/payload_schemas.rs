//! The contract's JSON Schemas (`docs/schemas/`, from `twin_wire::schema`)
//! hold for what a real daemon publishes: a simulated trial goes through
//! `twind::run` over Zenoh, every payload of every output topic (state,
//! fault, prediction, alarm, finding, the vessel's and the daemon's
//! statistics) and every input sent is kept, and the independent validator
//! of PyPI's `jsonschema` (`tests/schemas/validate.py`) checks each against
//! its schema.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use twin_core::diagnose::MonitorConfig;
use twin_tests::daemon::{drain, rig};
use twin_tests::peers::require_python_module;
use twin_tests::wire::{messages, offline, receive_until, receive_until_fault, scenario};
use twin_wire::outputs::FaultMessage;
use twind::settings::Settings;
use zenoh::sample::Sample;

const INSTALL: &str = "python3 -m pip install -r requirements.txt";

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The schema a published key's payload follows: the last chunks of the
/// key (`twin/state` -> `state`, `@twind/{id}/stats` -> `daemon-stats`).
fn schema_of(key: &str) -> String {
    if key.contains("/@twind/") {
        return "daemon-stats".to_string();
    }
    key.rsplit('/').next().unwrap_or(key).to_string()
}

/// Writes each payload list to `{dir}/{schema}.jsonl`.
fn write_payloads(dir: &Path, payloads: &BTreeMap<String, Vec<Vec<u8>>>) {
    std::fs::create_dir_all(dir).unwrap();
    for (schema, list) in payloads {
        let mut text = Vec::new();
        for p in list {
            assert!(!p.contains(&b'\n'), "one payload per line: {schema}");
            text.extend_from_slice(p);
            text.push(b'\n');
        }
        std::fs::write(dir.join(format!("{schema}.jsonl")), text).unwrap();
    }
}

/// Runs the validator over `dir`; its report and whether all were valid.
fn validate(dir: &Path) -> (serde_json::Value, bool) {
    let out = Command::new("python3")
        .arg(repo().join("tests/schemas/validate.py"))
        .arg(repo().join("docs/schemas"))
        .arg(dir)
        .output()
        .expect("python3 runs");
    let report = serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "the validator's report ({e}): {}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        )
    });
    (report, out.status.success())
}

/// Every output of a trial with a thruster fault (so an alarm) and the
/// live diagnosis on (so a finding), with the statistics every 0.5 s; per
/// schema, the payloads in the order received, the inputs included.
async fn published_payloads() -> BTreeMap<String, Vec<Vec<u8>>> {
    let mut sc = scenario("demo_broken-port");
    sc.seed = 73;
    let msgs = messages(&twin_sim::simulate(&sc).unwrap());
    let mut settings =
        Settings::from_toml("[daemon]\nid = \"schemas\"\n[publish]\nstats_interval_s = 0.5\n")
            .unwrap();
    // One diagnosis, of 120 s, once 120 s are held.
    settings.diagnose.monitor = MonitorConfig {
        window_s: 120.0,
        min_window_s: 120.0,
        interval_s: 1000.0,
        bias_t: 1e9,
        ..MonitorConfig::default()
    };
    let expected = offline(&msgs);
    let last = FaultMessage::new(
        "v",
        &expected.fault_report(expected.state_report().unwrap().time_s),
        true,
    );
    let rig = rig(settings).await;
    let sub = rig.collect("schema-1").await;
    let daemon_sub = rig
        .watch("asv/@twind/*/stats", "asv/@twind/schemas/stats")
        .await;
    rig.publish("schema-1", &msgs).await;
    let mut samples: Vec<Sample> = receive_until_fault(&sub, &last.time).await;
    for topic in ["/twin/finding", "/twin/stats"] {
        if !samples
            .iter()
            .any(|s| s.key_expr().as_str().ends_with(topic))
        {
            samples.extend(
                receive_until(&sub, Duration::from_secs(120), |s| {
                    s.key_expr().as_str().ends_with(topic)
                })
                .await,
            );
        }
    }
    samples.extend(receive_until(&daemon_sub, Duration::from_secs(10), |_| true).await);
    rig.stop().await;
    samples.extend(drain(&sub));
    samples.extend(drain(&daemon_sub));
    let mut payloads: BTreeMap<String, Vec<Vec<u8>>> = BTreeMap::new();
    for s in &samples {
        payloads
            .entry(schema_of(s.key_expr().as_str()))
            .or_default()
            .push(s.payload().to_bytes().to_vec());
    }
    for (topic, bytes) in msgs {
        payloads.entry(topic.to_string()).or_default().push(bytes);
    }
    payloads
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_payload_the_daemon_publishes_validates_against_its_schema() {
    require_python_module("python3", "jsonschema", INSTALL);
    let payloads = published_payloads().await;
    let schemas: Vec<&str> = twin_wire::schema::all().iter().map(|s| s.name).collect();
    let seen: Vec<&str> = payloads.keys().map(String::as_str).collect();
    let mut wanted = schemas.clone();
    wanted.sort_unstable();
    assert_eq!(seen, wanted, "a payload of every schema, and no other");

    let dir = repo().join("target/payload-schemas/published");
    let _ = std::fs::remove_dir_all(&dir);
    write_payloads(&dir, &payloads);
    let (report, valid) = validate(&dir);
    println!("validator: {report}");
    assert!(valid, "payloads the schemas refuse: {report:#}");
    for (schema, list) in &payloads {
        assert_eq!(
            report[schema]["checked"].as_u64(),
            Some(list.len() as u64),
            "{schema}: every payload checked ({report})"
        );
    }
}

/// The validator is not a rubber stamp: payloads that break the contract
/// the way a careless change would (a field renamed, a required field
/// missing, an enum's variant in the wrong case, a field added, a string
/// for a number) are each refused.
#[test]
fn the_validator_refuses_payloads_that_break_the_contract() {
    require_python_module("python3", "jsonschema", INSTALL);
    let fault: serde_json::Value = serde_json::json!({
        "vessel": "v", "time": "2026-01-01T00:00:00Z",
        "thrusters": {
            "port": {"loss": 0.2, "sigma": 0.05, "loss_raw": 0.2, "excited": true,
                     "status": "suspect", "onset": null},
            "starboard": {"loss": 0.0, "sigma": 0.05, "loss_raw": 0.0, "excited": true,
                          "status": "nominal", "onset": null}
        },
        "status": "suspect", "excited": true, "onset": null, "model": "kinetic",
        "effectiveness_ratio": {"value": 0.8, "sigma": 0.02},
        "seed_input_faults": [0.0, 0.0], "replay": true, "profile_mismatch": null
    });
    let broken: Vec<serde_json::Value> = vec![
        {
            let mut f = fault.clone();
            let v = f.as_object_mut().unwrap().remove("status").unwrap();
            f["thruster_status"] = v;
            f
        },
        {
            let mut f = fault.clone();
            f.as_object_mut().unwrap().remove("vessel");
            f
        },
        {
            let mut f = fault.clone();
            f["status"] = "Suspect".into();
            f
        },
        {
            let mut f = fault.clone();
            f["thrusters"]["port"]["loss_pct"] = 20.into();
            f
        },
        {
            let mut f = fault.clone();
            f["thrusters"]["port"]["loss"] = "0.2".into();
            f
        },
    ];
    let dir = repo().join("target/payload-schemas/broken");
    let _ = std::fs::remove_dir_all(&dir);
    let mut payloads = BTreeMap::new();
    // And one whose profile does not describe the vessel, saying why.
    let mut withheld = fault.clone();
    withheld["profile_mismatch"] = serde_json::json!({
        "yaw_damping_error": 1.24, "yaw_damping_bound": 0.75, "mass_error": 0.06,
        "mass_bound": 0.75, "thrust_error": -0.12, "thrust_bound": 0.62,
        "nis_per_dof": 0.66, "max_nis_per_dof": 2.0
    });
    payloads.insert(
        "fault".to_string(),
        vec![
            serde_json::to_vec(&fault).unwrap(),
            serde_json::to_vec(&withheld).unwrap(),
        ],
    );
    write_payloads(&dir.join("good"), &payloads);
    let (report, valid) = validate(&dir.join("good"));
    assert!(valid, "the well-formed fault is valid: {report}");
    for (i, b) in broken.iter().enumerate() {
        let case = dir.join(format!("case-{i}"));
        payloads.insert("fault".to_string(), vec![serde_json::to_vec(b).unwrap()]);
        write_payloads(&case, &payloads);
        let (report, valid) = validate(&case);
        assert!(!valid, "case {i} accepted: {b}");
        assert_eq!(report["fault"]["checked"].as_u64(), Some(1), "{report}");
    }
}
