//! The twin's ROS 2 face (rmw_zenoh, CDR), checked against independent
//! peers and against its own JSON contract:
//! - every message type, byte for byte against the CDR of PyPI `rosbags`
//!   (`tests/peers/ros2_golden.py`), both ways, with the type hashes;
//! - the daemon with `[ros2]` enabled: a Zenoh client on rmw_zenoh's key
//!   gets the fault as a `DiagnosticArray` whose values are the JSON
//!   fault's, with the attachment and the liveliness tokens rmw_zenoh needs;
//! - a trial of a vessel with a rate gyro fed as `NavSatFix` + velocity +
//!   `Imu` gives the JSON path's estimates;
//! - truncated and garbage CDR is refused with a reason and counted.

use std::time::Duration;

use serde::Serialize;
use twin_core::twin::VesselTwin;
use twin_tests::daemon::{drain, last_fault, rig, states};
use twin_tests::peers::{python_with, script};
use twin_tests::wire::{
    Messages, Outputs, messages, now_s, offline, receive_until, receive_until_fault, shifted,
    simulate, time_of, wait_matching,
};
use twin_wire::messages::GnssMessage;
use twin_wire::outputs::{DaemonStatsMessage, FaultMessage, PredictionMessage, StateMessage};
use twin_wire::ros2::map::{
    Frames, enu_yaw, estimated_fix, fault_diagnostics, odometry, prediction_path, stamp_of,
    yaw_quaternion,
};
use twin_wire::ros2::msgs::{
    DiagnosticArray, Header, Imu, NavSatFix, NavSatStatus, Odometry, Path, Point,
    QuaternionStamped, RosMessage, Twist, TwistStamped,
};
use twin_wire::ros2::rmw::{Attachment, gid_of};
use twind::settings::Settings;
use zenoh::qos::CongestionControl;
use zenoh::sample::Sample;

/// The tests of this file drive a live daemon at full speed, and their
/// outcome depends on it keeping up: they run one at a time.
static SERIAL: tokio::sync::Mutex<()> = tokio::sync::Mutex::const_new(());

const INSTALL: &str = "python3 -m pip install -r requirements.txt";

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn unhex(s: &str) -> Vec<u8> {
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
        .collect()
}

/// A trial through the offline twin: its messages and the twin after them.
/// The demo's serpentine with a 30 % port loss: seven turns, alternately
/// to starboard and to port, so the twin on the Otter's (unidentified)
/// profile compares its propellers and declares the loss (on a straight
/// run it compares them only once the run has lasted a filter's memory,
/// `KineticConfig::straight_run_min_fill`).
fn trial() -> (Messages, VesselTwin) {
    let msgs = messages(&simulate("demo_broken-port", 0.3, 3));
    let twin = offline(&msgs);
    (msgs, twin)
}

/// The same trial with a rate gyro on the vessel, its yaw rate joined to
/// the fixes as a logger joins it.
fn trial_with_gyro() -> Messages {
    let mut sc = twin_tests::wire::scenario("straight_new-broken");
    sc.propellers.port.loss = 0.3;
    sc.seed = 3;
    sc.sensors.yaw_rate.enabled = true;
    twin_tests::wire::messages_as_logged(&twin_sim::simulate(&sc).expect("simulation"))
}

/// One golden case: a message, its JSON form and the twin's CDR.
struct Case {
    type_name: &'static str,
    type_hash: &'static str,
    value: serde_json::Value,
    cdr: Vec<u8>,
    /// The twin's decoder applied to bytes, re-encoded.
    reencode: fn(&[u8]) -> Vec<u8>,
    /// Whether the twin's decoder takes the bytes.
    decodes: fn(&[u8]) -> bool,
}

fn case<T: RosMessage + Serialize>(m: &T) -> Case {
    Case {
        type_name: T::TYPE_NAME,
        type_hash: T::TYPE_HASH,
        value: serde_json::to_value(m).unwrap(),
        cdr: m.to_cdr(),
        reencode: |b| {
            T::from_cdr(b)
                .expect("the twin reads rosbags' CDR")
                .to_cdr()
        },
        decodes: |b| T::from_cdr(b).is_ok(),
    }
}

fn gnss_inputs() -> (NavSatFix, TwistStamped, QuaternionStamped) {
    let header = Header {
        stamp: stamp_of("2024-05-01T12:00:00.25Z"),
        frame_id: "gps".into(),
    };
    let fix = NavSatFix {
        header: header.clone(),
        status: NavSatStatus {
            status: 0,
            service: 1,
        },
        latitude: 59.912_345_678,
        longitude: 10.734_567_891,
        altitude: 12.5,
        position_covariance: [0.25, 0.0, 0.0, 0.0, 0.25, 0.0, 0.0, 0.0, 1.0],
        position_covariance_type: 2,
    };
    let vel = TwistStamped {
        header: header.clone(),
        twist: Twist {
            linear: Point {
                x: 1.25,
                y: -0.5,
                z: 0.0,
            },
            angular: Point::default(),
        },
    };
    let heading = QuaternionStamped {
        header,
        quaternion: yaw_quaternion(enu_yaw(2.0)),
    };
    (fix, vel, heading)
}

/// An IMU turning to starboard at 0.05 rad/s (-z in REP 103), with every
/// field set.
fn imu_input() -> Imu {
    Imu {
        header: Header {
            stamp: stamp_of("2024-05-01T12:00:00.2Z"),
            frame_id: "base_link".into(),
        },
        orientation: yaw_quaternion(enu_yaw(2.0)),
        orientation_covariance: [1e-4, 0.0, 0.0, 0.0, 1e-4, 0.0, 0.0, 0.0, 4e-4],
        angular_velocity: Point {
            x: 0.002,
            y: -0.001,
            z: -0.05,
        },
        angular_velocity_covariance: [1e-6, 0.0, 0.0, 0.0, 1e-6, 0.0, 0.0, 0.0, 1e-6],
        linear_acceleration: Point {
            x: 0.12,
            y: -0.03,
            z: 9.81,
        },
        linear_acceleration_covariance: [0.01, 0.0, 0.0, 0.0, 0.01, 0.0, 0.0, 0.0, 0.01],
    }
}

fn golden_cases() -> Vec<Case> {
    let (_, twin) = trial();
    let report = twin.state_report().unwrap();
    let state = StateMessage::new("otter-1", &report, false, true);
    let fault = FaultMessage::new("otter-1", &twin.fault_report(report.time_s), true);
    let prediction = PredictionMessage::new(
        "otter-1",
        report.time_s,
        30.0,
        5.0,
        report.source,
        &twin.forecast(30.0, 5.0),
        true,
    );
    let frames = Frames::of("otter_1");
    let (fix, vel, heading) = gnss_inputs();
    vec![
        case(&odometry(&state, &frames)),
        case(&estimated_fix(&state, &frames)),
        case(&fault_diagnostics(&fault)),
        case(&prediction_path(&prediction, &frames)),
        case(&fix),
        case(&vel),
        case(&heading),
        case(&imu_input()),
    ]
}

/// Acceptance: for every type the twin publishes or reads, the twin's CDR
/// is rosbags' CDR of the same values, byte for byte; rosbags reads the
/// twin's bytes back to the same values and the twin reads rosbags'; the
/// type hashes in the keys are rosbags' RIHS01.
#[test]
fn every_ros2_message_is_byte_for_byte_rosbags_cdr() {
    let _serial = SERIAL.blocking_lock();
    let python = python_with("rosbags", INSTALL);
    let cases = golden_cases();
    let input: Vec<_> = cases
        .iter()
        .map(|c| serde_json::json!({"type": c.type_name, "value": c.value, "cdr": hex(&c.cdr)}))
        .collect();
    let mut child = std::process::Command::new(&python)
        .arg(script("ros2_golden.py"))
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .spawn()
        .expect("python runs");
    serde_json::to_writer(child.stdin.take().unwrap(), &input).unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "ros2_golden.py failed");
    let answers: Vec<serde_json::Value> = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(answers.len(), cases.len());
    for (c, a) in cases.iter().zip(&answers) {
        let theirs = unhex(a["cdr"].as_str().unwrap());
        assert_eq!(hex(&c.cdr), hex(&theirs), "{}: CDR differs", c.type_name);
        assert_eq!(
            a["decoded"], c.value,
            "{}: rosbags reads other values",
            c.type_name
        );
        assert_eq!(a["hash"], c.type_hash, "{}: type hash", c.type_name);
        assert_eq!((c.reencode)(&theirs), c.cdr, "{}", c.type_name);
    }
    // Real content went through: three diagnostics, a forecast, a fix.
    let fault = &cases[2].value;
    assert_eq!(fault["status"].as_array().unwrap().len(), 3);
    assert!(cases[3].value["poses"].as_array().unwrap().len() >= 6);
}

/// Truncated payloads and random bytes are refused by every decoder,
/// never a panic.
#[test]
fn truncated_and_garbage_cdr_is_refused() {
    let _serial = SERIAL.blocking_lock();
    use rand::{Rng, SeedableRng};
    let mut rng = rand::rngs::StdRng::seed_from_u64(24);
    for c in golden_cases() {
        assert!((c.decodes)(&c.cdr), "{}", c.type_name);
        for cut in 0..c.cdr.len().saturating_sub(8) {
            assert!(
                !(c.decodes)(&c.cdr[..cut]),
                "{} accepted a cut at {cut}",
                c.type_name
            );
        }
    }
    let decoders: [fn(&[u8]) -> bool; 9] = [
        |b| Odometry::from_cdr(b).is_ok(),
        |b| NavSatFix::from_cdr(b).is_ok(),
        |b| DiagnosticArray::from_cdr(b).is_ok(),
        |b| Path::from_cdr(b).is_ok(),
        |b| TwistStamped::from_cdr(b).is_ok(),
        |b| QuaternionStamped::from_cdr(b).is_ok(),
        |b| Imu::from_cdr(b).is_ok(),
        |b| {
            twin_wire::ros2::input::NavSatInput::new(1.0)
                .push(twin_wire::ros2::input::GnssTopic::Fix, b)
                .is_ok()
        },
        |b| {
            twin_wire::ros2::input::NavSatInput::new(1.0)
                .push(twin_wire::ros2::input::GnssTopic::Imu, b)
                .is_ok()
        },
    ];
    for _ in 0..2000 {
        let len = rng.random_range(0..200);
        let mut bytes: Vec<u8> = (0..len).map(|_| rng.random()).collect();
        if bytes.len() >= 4 && rng.random_bool(0.8) {
            bytes[..4].copy_from_slice(&[0, 1, 0, 0]);
        }
        for decode in decoders {
            let _ = decode(&bytes);
        }
    }
}

fn ros2_settings(extra: &str) -> Settings {
    Settings::from_toml(&format!(
        "[ros2]\nenabled = true\n[daemon]\nid = \"ros\"\n[publish]\nstats_interval_s = 0.2\n\
         [diagnose]\nenabled = false\n[input]\nlive_max_behind_s = 100000.0\n{extra}"
    ))
    .unwrap()
}

fn ros_key<T: RosMessage>(settings: &Settings, vessel: &str, suffix: &str) -> String {
    settings
        .ros2
        .data_key::<T>(&settings.ros2.topic(vessel, suffix))
}

fn value<'a>(status: &'a twin_wire::ros2::msgs::DiagnosticStatus, key: &str) -> &'a str {
    &status
        .values
        .iter()
        .find(|kv| kv.key == key)
        .unwrap_or_else(|| panic!("no {key} in {}", status.name))
        .value
}

fn number(text: &str) -> Option<f64> {
    (text != "nan").then(|| text.parse().unwrap())
}

/// Outside in: a client on rmw_zenoh's key of `/usv/otter1/twin/fault`
/// gets `DiagnosticArray`s whose values are those of the JSON fault of the
/// same fix, each with the attachment an rmw_zenoh subscription requires,
/// and the node and its publishers are in the ROS 2 graph.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_ros2_subscriber_gets_the_json_fault_as_diagnostics() {
    let _serial = SERIAL.lock().await;
    let settings = ros2_settings("");
    let fault_key = ros_key::<DiagnosticArray>(&settings, "otter1", "twin/fault");
    let (msgs, _) = trial();
    let rig = rig(settings).await;
    let json = rig.collect("otter1").await;
    let ros = rig.watch(&fault_key, &fault_key).await;
    rig.publish("otter1", &msgs).await;
    let last_time = twin_wire::time::format_rfc3339(time_of(
        &msgs.iter().rfind(|(t, _)| *t == "gnss").unwrap().1,
    ))
    .unwrap();
    let samples = receive_until_fault(&json, &last_time).await;
    let want = last_fault(&samples);
    let got = receive_until(&ros, Duration::from_secs(20), |s| {
        DiagnosticArray::from_cdr(&s.payload().to_bytes())
            .is_ok_and(|d| d.header.stamp == stamp_of(&want.time))
    })
    .await;
    let tokens: Vec<String> = rig
        .output
        .liveliness()
        .get("@ros2_lv/0/**")
        .await
        .unwrap()
        .into_iter()
        .filter_map(|r| r.into_result().ok())
        .map(|s| s.key_expr().to_string())
        .collect();
    rig.stop().await;

    let last: &Sample = got.last().expect("a ROS 2 fault");
    let d = DiagnosticArray::from_cdr(&last.payload().to_bytes()).unwrap();
    assert_eq!(d.header.stamp, stamp_of(&want.time));
    let [port, starboard, both] = &d.status[..] else {
        panic!("{} statuses", d.status.len())
    };
    for (s, t) in [
        (port, &want.thrusters.port),
        (starboard, &want.thrusters.starboard),
    ] {
        assert_eq!(number(value(s, "loss")), t.loss, "{}", s.name);
        assert_eq!(number(value(s, "sigma")), t.sigma, "{}", s.name);
        assert_eq!(value(s, "excited"), t.excited.to_string());
        let status = serde_json::to_value(t.status).unwrap();
        assert_eq!(value(s, "status"), status.as_str().unwrap());
    }
    assert_eq!(port.name, "otter1/thruster/port");
    let ratio = want.effectiveness_ratio.expect("a ratio");
    assert_eq!(
        number(value(both, "effectiveness_ratio")),
        Some(ratio.value)
    );
    // The Otter on the Otter's profile: nothing withheld.
    assert_eq!(value(both, "profile_mismatch"), "");
    // The trial's port propeller lost 30 %: the twin says so in both.
    assert_eq!(value(port, "status"), "fault");
    assert_eq!(port.level, 2);

    let attachments: Vec<Attachment> = got
        .iter()
        .map(|s| {
            Attachment::from_bytes(&s.attachment().expect("an attachment").to_bytes())
                .expect("rmw_zenoh's attachment")
        })
        .collect();
    assert!(
        attachments
            .windows(2)
            .all(|w| w[1].sequence_number == w[0].sequence_number + 1)
    );
    let publisher = tokens
        .iter()
        .find(|t| t.contains("/MP/%/%usv/twind/%usv%otter1%twin%fault/"))
        .unwrap_or_else(|| panic!("no fault publisher among {tokens:?}"));
    assert!(publisher.ends_with(&format!(
        "/diagnostic_msgs::msg::dds_::DiagnosticArray_/{}/::,10:,:,:,,",
        DiagnosticArray::TYPE_HASH
    )));
    assert_eq!(attachments[0].source_gid, gid_of(publisher));
    assert!(
        tokens.iter().any(|t| t.ends_with("/NN/%/%usv/twind")),
        "{tokens:?}"
    );
}

/// A JSON fix as a ROS 2 GNSS driver publishes it: velocity, then fix.
/// A contract fix as a ROS 2 GNSS driver and IMU publish it: its velocity,
/// its yaw rate (where it has one) as an IMU's z rate, and its position.
fn as_ros(bytes: &[u8]) -> Vec<(&'static str, Vec<u8>)> {
    let m: GnssMessage = serde_json::from_slice(bytes).unwrap();
    let header = Header {
        stamp: stamp_of(&m.time),
        frame_id: "gps".into(),
    };
    let vel = TwistStamped {
        header: header.clone(),
        twist: Twist {
            linear: Point {
                x: m.sog_mps * m.cog_rad.sin(),
                y: m.sog_mps * m.cog_rad.cos(),
                z: 0.0,
            },
            angular: Point::default(),
        },
    };
    let imu = m.yaw_rate_radps.map(|rate| Imu {
        header: header.clone(),
        angular_velocity: Point {
            x: 0.0,
            y: 0.0,
            z: -rate,
        },
        ..imu_input()
    });
    let fix = NavSatFix {
        header,
        latitude: m.lat_deg,
        longitude: m.lon_deg,
        altitude: f64::NAN,
        ..NavSatFix::default()
    };
    let mut out = vec![("vel", vel.to_cdr())];
    out.extend(imu.map(|i| ("imu", i.to_cdr())));
    out.push(("fix", fix.to_cdr()));
    out
}

/// [`as_ros`]'s velocity and position payloads.
fn vel_and_fix(bytes: &[u8]) -> (Vec<u8>, Vec<u8>) {
    let parts = as_ros(bytes);
    let of = |name: &str| {
        parts
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, p)| p.clone())
            .unwrap()
    };
    (of("vel"), of("fix"))
}

/// The trial, live (now), through the daemon; the last fault and state.
async fn run_live(msgs: &Messages, over_ros2: bool) -> (FaultMessage, StateMessage, u64) {
    let settings = ros2_settings("");
    let vel_key = ros_key::<TwistStamped>(&settings, "otter1", "vel");
    let imu_key = ros_key::<Imu>(&settings, "otter1", "imu");
    let fix_key = ros_key::<NavSatFix>(&settings, "otter1", "fix");
    let rig = rig(settings).await;
    let sub: Outputs = rig.collect("otter1").await;
    let input = &rig.input;
    // Blocking, as a sender that must lose nothing publishes: with Zenoh's
    // default (`Drop`) a busy daemon's back-pressure drops messages on this
    // side, and the two paths would see different trials.
    let declare = |key: String| {
        input
            .declare_publisher(key)
            .congestion_control(CongestionControl::Block)
    };
    let actuators = declare("asv/otter1/actuators".to_string()).await.unwrap();
    let gnss = declare("asv/otter1/gnss".to_string()).await.unwrap();
    let vel = declare(vel_key).await.unwrap();
    let imu = declare(imu_key).await.unwrap();
    let fix = declare(fix_key).await.unwrap();
    for p in [&actuators, &gnss, &vel, &imu, &fix] {
        wait_matching(p, Duration::from_secs(20)).await;
    }
    let mut sequence = 0;
    for (topic, bytes) in msgs {
        if *topic == "gnss" && over_ros2 {
            for (name, payload) in as_ros(bytes) {
                let p = match name {
                    "vel" => &vel,
                    "imu" => &imu,
                    _ => &fix,
                };
                sequence += 1;
                let attachment = Attachment {
                    sequence_number: sequence,
                    source_timestamp_ns: 0,
                    source_gid: [7; 16],
                };
                p.put(payload)
                    .attachment(attachment.to_bytes().to_vec())
                    .await
                    .unwrap();
            }
        } else if *topic == "gnss" {
            gnss.put(bytes.clone()).await.unwrap();
        } else {
            actuators.put(bytes.clone()).await.unwrap();
        }
    }
    let last = msgs.iter().rfind(|(t, _)| *t == "gnss").unwrap();
    let last_time = twin_wire::time::format_rfc3339(time_of(&last.1)).unwrap();
    let mut samples = receive_until_fault(&sub, &last_time).await;
    let summary = rig.stop().await;
    samples.extend(drain(&sub));
    let accepted = summary.vessels["otter1"].accepted()["gnss"];
    assert_eq!(summary.ros2_missed, 0, "numbered in sequence, none missed");
    (
        last_fault(&samples),
        states(&samples).last().unwrap().clone(),
        accepted,
    )
}

/// Acceptance: the same trial (a vessel with a rate gyro) fed as
/// `NavSatFix` + `TwistStamped` + `Imu` over rmw_zenoh's keys gives the
/// JSON path's estimates (the velocity's round trip through east/north
/// costs float round-off only).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_navsatfix_input_gives_the_json_paths_estimates() {
    let _serial = SERIAL.lock().await;
    let msgs = trial_with_gyro();
    let with_yaw_rate = msgs
        .iter()
        .filter(|(t, b)| {
            *t == "gnss"
                && serde_json::from_slice::<GnssMessage>(b)
                    .unwrap()
                    .yaw_rate_radps
                    .is_some()
        })
        .count();
    assert!(with_yaw_rate > 100, "{with_yaw_rate} fixes with a yaw rate");
    let start = time_of(&msgs[0].1);
    let live: Messages = shifted(&msgs, now_s() - 200.0 - start)
        .into_iter()
        .map(|(t, b)| {
            (
                t,
                twin_tests::wire::edited(&b, |v| {
                    v.as_object_mut().unwrap().remove("replay");
                }),
            )
        })
        .collect();
    let fixes = live.iter().filter(|(t, _)| *t == "gnss").count() as u64;
    let (json_fault, json_state, json_accepted) = run_live(&live, false).await;
    let (ros_fault, ros_state, ros_accepted) = run_live(&live, true).await;
    assert_eq!(json_accepted, fixes);
    assert_eq!(ros_accepted, fixes);
    assert_eq!(ros_fault.time, json_fault.time);
    for (a, b) in [
        (&ros_fault.thrusters.port, &json_fault.thrusters.port),
        (
            &ros_fault.thrusters.starboard,
            &json_fault.thrusters.starboard,
        ),
    ] {
        assert_eq!(a.status, b.status);
        assert!(
            (a.loss.unwrap() - b.loss.unwrap()).abs() < 1e-6,
            "{a:?} {b:?}"
        );
        assert!(
            (a.sigma.unwrap() - b.sigma.unwrap()).abs() < 1e-6,
            "{a:?} {b:?}"
        );
    }
    assert!((ros_state.lat_deg - json_state.lat_deg).abs() < 1e-9);
    assert!((ros_state.lon_deg - json_state.lon_deg).abs() < 1e-9);
    assert!((ros_state.sog_mps - json_state.sog_mps).abs() < 1e-6);
    assert!(
        json_fault.thrusters.port.loss.unwrap() > 0.1,
        "{json_fault:?}"
    );
}

/// A daemon with the ROS 2 input on, a watch on its statistics, and
/// publishers of `otter1`'s `fix` and `vel` that it has matched.
struct InputRig {
    rig: twin_tests::daemon::Rig,
    stats: Outputs,
    fix: zenoh::pubsub::Publisher<'static>,
    vel: zenoh::pubsub::Publisher<'static>,
}

impl InputRig {
    async fn new() -> Self {
        let settings = ros2_settings("");
        let fix_key = ros_key::<NavSatFix>(&settings, "otter1", "fix");
        let vel_key = ros_key::<TwistStamped>(&settings, "otter1", "vel");
        let rig = rig(settings).await;
        let stats = rig
            .watch("asv/@twind/*/stats", "asv/@twind/ros/stats")
            .await;
        let fix = rig.input.declare_publisher(fix_key).await.unwrap();
        let vel = rig.input.declare_publisher(vel_key).await.unwrap();
        wait_matching(&fix, Duration::from_secs(20)).await;
        wait_matching(&vel, Duration::from_secs(20)).await;
        Self {
            rig,
            stats,
            fix,
            vel,
        }
    }

    /// Waits for statistics that `want` holds for, stops the daemon, and
    /// returns the last statistics and the run's summary.
    async fn stop_when(
        self,
        want: impl Fn(&DaemonStatsMessage) -> bool,
    ) -> (DaemonStatsMessage, twind::RunSummary) {
        let got = receive_until(&self.stats, Duration::from_secs(20), |s| {
            serde_json::from_slice::<DaemonStatsMessage>(&s.payload().to_bytes())
                .is_ok_and(|m| want(&m))
        })
        .await;
        let summary = self.rig.stop().await;
        let last = serde_json::from_slice(&got.last().unwrap().payload().to_bytes()).unwrap();
        (last, summary)
    }
}

/// Truncated CDR, garbage, a fix without a velocity and a fix out of range
/// on the ROS 2 input are refused with their reasons and counted in the
/// daemon's statistics; the daemon goes on.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_ros2_input_is_refused_with_a_reason_and_counted() {
    let _serial = SERIAL.lock().await;
    let input = InputRig::new().await;
    let (fix, vel) = (&input.fix, &input.vel);
    let (v, f) = vel_and_fix(&twin_tests::wire::live_fix(now_s(), 0));
    fix.put(f.clone()).await.unwrap(); // no velocity yet
    fix.put(f[..f.len() - 9].to_vec()).await.unwrap();
    fix.put(b"\x00\x01\x00\x00\xff\xff\xff\xff".to_vec())
        .await
        .unwrap();
    fix.put(Vec::new()).await.unwrap();
    vel.put(v).await.unwrap();
    let mut far = NavSatFix::from_cdr(&f).unwrap();
    far.latitude = 95.0;
    fix.put(far.to_cdr()).await.unwrap();
    fix.put(f).await.unwrap(); // good now
    let want = |m: &DaemonStatsMessage| {
        let n = |r: &str| m.refused.get(r).copied().unwrap_or(0);
        n("ros2_no_velocity") == 1 && n("ros2_bad_cdr") == 3 && n("out_of_range") == 1
    };
    let (last, summary) = input.stop_when(want).await;
    assert!(want(&last), "{:?}", last.refused);
    assert_eq!(summary.vessels["otter1"].accepted()["gnss"], 1);
}

/// Messages a ROS 2 publisher numbered but that never came (rmw_zenoh
/// drops under congestion) are counted as `ros2_missed`, per publisher;
/// the fixes that did come are used.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn gaps_in_a_ros2_publishers_sequence_are_counted_as_missed() {
    let _serial = SERIAL.lock().await;
    let input = InputRig::new().await;
    let start = now_s() - 10.0;
    // The fix publisher skips 3 and 4, the velocity publisher 2: three
    // messages missed in all, and every fix that came has its velocity.
    let (fix_sequence, vel_sequence) = ([1, 2, 5, 6], [1, 3, 4, 5]);
    for (i, (f_seq, v_seq)) in fix_sequence.into_iter().zip(vel_sequence).enumerate() {
        let (v, f) = vel_and_fix(&twin_tests::wire::live_fix(start + 0.2 * i as f64, i));
        for (p, payload, sequence_number, gid) in
            [(&input.vel, v, v_seq, 1), (&input.fix, f, f_seq, 2)]
        {
            let attachment = Attachment {
                sequence_number,
                source_timestamp_ns: 0,
                source_gid: [gid; 16],
            };
            p.put(payload)
                .attachment(attachment.to_bytes().to_vec())
                .await
                .unwrap();
        }
    }
    let (last, summary) = input.stop_when(|m| m.ros2_missed == 3).await;
    assert_eq!(last.ros2_missed, 3);
    assert_eq!(summary.ros2_missed, 3);
    assert_eq!(summary.vessels["otter1"].accepted()["gnss"], 4);
}
