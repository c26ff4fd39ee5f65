//! The twin's answers where a boat's operators already look: a real
//! signalk-server (npm, `tests/peers`) on loopback receives the daemon's
//! deltas over its WebSocket stream (`[signalk]` in the settings) while a
//! simulated trial with a 25 % port loss is replayed through Zenoh; its
//! REST API then shows the twin's position, SOG, COG and current under the
//! vessel's context (`vessels.self`) with the twin's `$source`, the port
//! propeller's `thrustLoss` notification in `alarm` and the starboard one
//! not. A server that comes up after the daemon (or goes away) costs the
//! daemon nothing: it reconnects and sends the latest notifications.

use twin_tests::daemon::{drain, rig, states};
use twin_tests::peers::{SignalkServer, free_tcp_port};
use twin_tests::wire::{fault_of, messages, offline, receive_until_fault, simulate};
use twin_wire::outputs::{FaultMessage, StateMessage, ThrusterStatusName};
use twind::settings::Settings;

const VESSEL: &str = "sk-twin";

fn settings(url: &str) -> Settings {
    Settings::from_toml(&format!(
        "[diagnose]\nenabled = false\n[signalk]\nurl = \"{url}\"\nself_vessel = \"{VESSEL}\"\n\
         reconnect_min_s = 0.2\nreconnect_max_s = 1.0\n"
    ))
    .unwrap()
}

/// The trial and the fault the offline path ends with (port in fault,
/// starboard not: the premise of the test).
fn trial(seed: u64) -> (twin_tests::wire::Messages, FaultMessage) {
    let msgs = messages(&simulate("s-manoeuvre_new-broken", 0.25, seed));
    let twin = offline(&msgs);
    let last = FaultMessage::new(
        VESSEL,
        &twin.fault_report(twin.state_report().unwrap().time_s),
        true,
    );
    assert_eq!(last.thrusters.port.status, ThrusterStatusName::Fault);
    assert_ne!(last.thrusters.starboard.status, ThrusterStatusName::Fault);
    (msgs, last)
}

const PORT_LOSS: &str = "/signalk/v1/api/vessels/self/notifications/propulsion/port/thrustLoss";
const STARBOARD_LOSS: &str =
    "/signalk/v1/api/vessels/self/notifications/propulsion/starboard/thrustLoss";

/// The server's notifications: port in alarm, with the twin's words and
/// methods; starboard in the state its status says, not alarm.
fn assert_notifications(server: &SignalkServer, last: &FaultMessage) {
    let port = server
        .get_json_when(PORT_LOSS, |v| v["value"]["state"] == "alarm")
        .unwrap_or_else(|| panic!("no port alarm: {:?}", server.get(PORT_LOSS)));
    println!("port: {port}");
    assert_eq!(port["$source"], "usv-twin");
    assert_eq!(
        port["value"]["method"],
        serde_json::json!(["visual", "sound"])
    );
    let message = port["value"]["message"].as_str().unwrap();
    assert!(
        message.starts_with("port thruster fault: loss "),
        "{message}"
    );
    let starboard = server
        .get_json_when(STARBOARD_LOSS, |v| v["value"]["state"].is_string())
        .expect("a starboard notification");
    println!("starboard: {starboard}");
    let expected = twind::signalk::alarm_state(last.thrusters.starboard.status);
    assert_eq!(starboard["value"]["state"], expected);
    assert_ne!(starboard["value"]["state"], "alarm");
    assert_eq!(starboard["$source"], "usv-twin");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_signalk_server_shows_the_twins_position_and_the_port_alarm() {
    let server = tokio::task::block_in_place(|| SignalkServer::start(false));
    let (msgs, last) = trial(81);
    let rig = rig(settings(&server.stream_url())).await;
    let sub = rig.collect(VESSEL).await;
    rig.publish(VESSEL, &msgs).await;
    let mut samples = receive_until_fault(&sub, &last.time).await;
    let summary = rig.stop().await;
    samples.extend(drain(&sub));
    let pushed = summary.signalk.expect("the Signal K output ran");
    println!("signalk: {pushed:?}");
    assert_eq!(pushed.connects, 1, "{pushed:?}");
    assert!(pushed.dropped.is_empty(), "{pushed:?}");
    let last_state: StateMessage = states(&samples)
        .into_iter()
        .rev()
        .find(|s| !s.stale)
        .expect("a state");

    tokio::task::block_in_place(|| {
        let path = "/signalk/v1/api/vessels/self/navigation";
        let nav = server
            .get_json_when(path, |v| {
                v["position"]["timestamp"].as_str().is_some_and(|t| {
                    twin_wire::time::parse_rfc3339(t).ok()
                        == twin_wire::time::parse_rfc3339(&last_state.time).ok()
                })
            })
            .unwrap_or_else(|| panic!("not the last state's position: {:?}", server.get(path)));
        let close = |a: &serde_json::Value, b: f64| (a.as_f64().unwrap() - b).abs() < 1e-9;
        assert_eq!(nav["position"]["$source"], "usv-twin");
        assert!(
            close(&nav["position"]["value"]["latitude"], last_state.lat_deg),
            "{nav}"
        );
        assert!(
            close(&nav["position"]["value"]["longitude"], last_state.lon_deg),
            "{nav}"
        );
        assert!(
            close(&nav["speedOverGround"]["value"], last_state.sog_mps),
            "{nav}"
        );
        assert!(
            close(&nav["courseOverGroundTrue"]["value"], last_state.cog_rad),
            "{nav}"
        );
        if let Some(h) = last_state.heading_rad {
            let sk = nav["headingTrue"]["value"].as_f64().expect("a heading");
            assert!(
                (sk - h.rem_euclid(std::f64::consts::TAU)).abs() < 1e-9,
                "{nav}"
            );
        }
        let current = last_state.current.expect("the current is estimated");
        let env = server
            .get_json_when("/signalk/v1/api/vessels/self/environment/current", |v| {
                v["value"]["drift"].is_number()
            })
            .expect("the current");
        assert!(close(&env["value"]["drift"], current.speed_mps), "{env}");
        let set_deg = env["value"]["setTrue"].as_f64().unwrap().to_degrees();
        assert!(
            (set_deg - current.toward_deg).abs() < 1e-6,
            "{env} {current:?}"
        );
        assert_notifications(&server, &last);
    });
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_server_that_comes_up_late_gets_the_latest_notifications() {
    let (msgs, last) = trial(82);
    let http_port = free_tcp_port();
    let rig = rig(settings(&SignalkServer::stream_url_on(http_port))).await;
    let sub = rig.collect(VESSEL).await;
    // The whole trial while no server listens: the daemon is not held up.
    rig.publish(VESSEL, &msgs).await;
    let samples = receive_until_fault(&sub, &last.time).await;
    assert!(
        samples
            .iter()
            .filter_map(fault_of)
            .any(|f| f.time == last.time),
        "the daemon went through the trial without a server"
    );
    let server = tokio::task::block_in_place(|| {
        let server = SignalkServer::start_on(http_port, false);
        assert_notifications(&server, &last);
        server
    });
    let summary = rig.stop().await;
    let pushed = summary.signalk.expect("the Signal K output ran");
    println!("signalk: {pushed:?}");
    assert!(pushed.connect_failures >= 1, "{pushed:?}");
    assert!(pushed.connects >= 1, "{pushed:?}");
    assert!(pushed.dropped["disconnected"] > 0, "{pushed:?}");
    drop(server);
}
