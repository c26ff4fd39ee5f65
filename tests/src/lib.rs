//! Shared helpers of the cross-crate tests: run the twin over a simulated
//! trial and collect what the tests judge; the independent peers
//! ([`peers`]) and how to start them.

pub mod peers;
pub mod trust;

use twin_core::geodesy::wrap_pi;
use twin_core::twin::{StepOutput, TwinConfig, VesselTwin};
use twin_sim::{SensorEvent, SimRun};

/// What a run of the twin over a simulated trial gives.
#[derive(Debug, Clone)]
pub struct TwinRun {
    /// Every accepted fix's output, in order.
    pub outputs: Vec<StepOutput>,
    /// Rejections by reason.
    pub rejected: Vec<&'static str>,
    /// The twin at the end.
    pub twin: VesselTwin,
}

/// Feeds the simulator's GNSS fixes and measured propeller speeds to a twin
/// (propeller data only if `with_propellers`), in time order.
pub fn run_twin(run: &SimRun, config: TwinConfig, with_propellers: bool) -> TwinRun {
    let mut twin = VesselTwin::new(config).expect("valid config");
    let mut outputs = Vec::new();
    let mut rejected = Vec::new();
    for event in &run.events {
        match event {
            SensorEvent::Gnss(fix) => match twin.on_gnss(fix) {
                Ok(out) => outputs.push(out),
                Err(e) => rejected.push(e.reason()),
            },
            SensorEvent::PropellerMeasured(p) if with_propellers => {
                if let Err(e) = twin.on_propellers(p) {
                    rejected.push(e.reason());
                }
            }
            _ => {}
        }
    }
    TwinRun {
        outputs,
        rejected,
        twin,
    }
}

/// Smallest signed difference of two angles, for comparing courses.
pub fn angle_error(a: f64, b: f64) -> f64 {
    wrap_pi(a - b)
}

/// In-process Zenoh for end-to-end tests: loopback only, no multicast
/// scouting, peers connected explicitly.
pub mod net {
    use std::net::TcpListener;

    /// A free TCP port on loopback (bound, read, released: a tiny race that
    /// tests accept).
    pub fn free_port() -> u16 {
        TcpListener::bind("127.0.0.1:0")
            .and_then(|l| l.local_addr())
            .map(|a| a.port())
            .expect("a free port on loopback")
    }

    /// A Zenoh configuration in `mode` listening on and connecting to the
    /// given loopback ports, with multicast scouting off.
    pub fn config(mode: &str, listen: &[u16], connect: &[u16]) -> zenoh::Config {
        let mut c = zenoh::Config::default();
        let ends = |ports: &[u16]| {
            let v: Vec<String> = ports
                .iter()
                .map(|p| format!("\"tcp/127.0.0.1:{p}\""))
                .collect();
            format!("[{}]", v.join(","))
        };
        c.insert_json5("mode", &format!("\"{mode}\""))
            .expect("mode");
        c.insert_json5("listen/endpoints", &ends(listen))
            .expect("listen");
        c.insert_json5("connect/endpoints", &ends(connect))
            .expect("connect");
        c.insert_json5("scouting/multicast/enabled", "false")
            .expect("scouting");
        c.insert_json5("scouting/gossip/enabled", "false")
            .expect("gossip");
        c
    }
}

/// A simulated trial as it goes on the wire, and the offline path over it.
pub mod wire {
    use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

    use twin_core::twin::{TwinConfig, VesselTwin};
    use twin_sim::{Scenario, SensorEvent, SimRun};
    use twin_wire::messages::{
        ActuatorCommand, decode_actuators, decode_gnss, encode_actuators, encode_gnss,
    };
    use twin_wire::outputs::FaultMessage;
    use zenoh::sample::Sample;

    /// Payloads in time order, each with its topic (`gnss` or `actuators`).
    pub type Messages = Vec<(&'static str, Vec<u8>)>;

    /// A scenario file of `config/scenarios/` (name without `.toml`).
    pub fn scenario(file: &str) -> Scenario {
        let path = format!(
            "{}/../config/scenarios/{file}.toml",
            env!("CARGO_MANIFEST_DIR")
        );
        Scenario::from_toml_str(&std::fs::read_to_string(path).expect("scenario file"))
            .expect("valid scenario")
    }

    /// Simulates a scenario file of `config/scenarios/` with the port loss
    /// and noise seed set.
    pub fn simulate(file: &str, port_loss: f64, seed: u64) -> SimRun {
        let mut sc = scenario(file);
        sc.propellers.port.loss = port_loss;
        sc.seed = seed;
        twin_sim::simulate(&sc).expect("simulation")
    }

    /// The trial's GNSS fixes and measured shaft speeds as contract payloads.
    pub fn messages(run: &SimRun) -> Messages {
        run.events
            .iter()
            .filter_map(|e| match e {
                SensorEvent::Gnss(f) => {
                    Some(("gnss", encode_gnss(f, true).expect("encodable fix")))
                }
                SensorEvent::PropellerMeasured(p) => Some((
                    "actuators",
                    encode_actuators(&ActuatorCommand::Speeds(*p), true).expect("encodable speeds"),
                )),
                _ => None,
            })
            .collect()
    }

    /// [`messages`] with the heading (and yaw rate) samples joined to the
    /// fixes as a logger joins them (`twin simulate`'s logs carry the
    /// same).
    pub fn messages_as_logged(run: &SimRun) -> Messages {
        let mut fixes = twin_cli::simulate::fixes_as_logged(run).into_iter();
        run.events
            .iter()
            .filter_map(|e| match e {
                SensorEvent::Gnss(_) => {
                    let f = fixes.next()?;
                    Some(("gnss", encode_gnss(&f, true).expect("encodable fix")))
                }
                SensorEvent::PropellerMeasured(p) => Some((
                    "actuators",
                    encode_actuators(&ActuatorCommand::Speeds(*p), true).expect("encodable speeds"),
                )),
                _ => None,
            })
            .collect()
    }

    /// The offline path over the same payloads: decode and feed a twin, as
    /// `twin analyze` does.
    pub fn offline(msgs: &[(&'static str, Vec<u8>)]) -> VesselTwin {
        offline_with(msgs, TwinConfig::default())
    }

    /// [`offline`] with the twin `config`.
    pub fn offline_with(msgs: &[(&'static str, Vec<u8>)], config: TwinConfig) -> VesselTwin {
        feed(VesselTwin::new(config).expect("valid config"), msgs)
    }

    /// `twin` after the offline path over `msgs`.
    pub fn feed(mut twin: VesselTwin, msgs: &[(&'static str, Vec<u8>)]) -> VesselTwin {
        for (topic, bytes) in msgs {
            if *topic == "gnss" {
                if let Ok(d) = decode_gnss(bytes) {
                    let _ = twin.on_gnss(&d.value);
                }
            } else if let Ok(d) = decode_actuators(bytes)
                && let ActuatorCommand::Speeds(s) = d.value
            {
                let _ = twin.on_propellers(&s);
            }
        }
        twin
    }

    /// Waits until a publisher has a matching subscriber (so nothing is
    /// published into the void), panicking after `within`.
    pub async fn wait_matching(p: &zenoh::pubsub::Publisher<'_>, within: Duration) {
        let deadline = Instant::now() + within;
        while !p
            .matching_status()
            .await
            .map(|m| m.matching())
            .unwrap_or(false)
        {
            assert!(
                Instant::now() < deadline,
                "no subscriber for {} within {within:?}",
                p.key_expr()
            );
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    }

    /// The daemon's output subscriber of the tests.
    pub type Outputs = zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<Sample>>;

    /// A fault output (`.../twin/fault`) decoded; `None` for other samples.
    pub fn fault_of(s: &Sample) -> Option<FaultMessage> {
        if !s.key_expr().as_str().ends_with("/twin/fault") {
            return None;
        }
        serde_json::from_slice(&s.payload().to_bytes()).ok()
    }

    /// Receives from `sub` until `arrived` says the awaited output has come,
    /// for at most `within`; every sample received. On a loaded machine the
    /// daemon can still be working through its queues when the publisher is
    /// done, and stopping it then cuts off the last outputs (a fixed pause
    /// raced with that). If the output never comes, the comparisons that
    /// follow fail.
    pub async fn receive_until(
        sub: &Outputs,
        within: Duration,
        mut arrived: impl FnMut(&Sample) -> bool,
    ) -> Vec<Sample> {
        let deadline = tokio::time::Instant::now() + within;
        let mut got = Vec::new();
        while let Ok(Ok(s)) = tokio::time::timeout_at(deadline, sub.recv_async()).await {
            let done = arrived(&s);
            got.push(s);
            if done {
                break;
            }
        }
        got
    }

    /// [`receive_until`] the fault stamped `time` (the last fix's) arrives,
    /// within 30 s.
    pub async fn receive_until_fault(sub: &Outputs, time: &str) -> Vec<Sample> {
        receive_until(sub, Duration::from_secs(30), |s| {
            fault_of(s).is_some_and(|f| f.time == time)
        })
        .await
    }

    /// The wall clock, s since the Unix epoch.
    pub fn now_s() -> f64 {
        SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .expect("a clock after 1970")
            .as_secs_f64()
    }

    /// A live fix (`replay` false) stamped `time_s`, `i` steps of 0.2 m
    /// along a line north from 59.9 N 10.7 E, at 1 m/s (so 0.2 s apart).
    /// The daemon holds a live fix to its clock: stamp it near [`now_s`].
    pub fn live_fix(time_s: f64, i: usize) -> Vec<u8> {
        serde_json::to_vec(&twin_wire::messages::GnssMessage {
            time: twin_wire::time::format_rfc3339(time_s).expect("a time to format"),
            lat_deg: 59.9 + i as f64 * 0.2 / 111_320.0,
            lon_deg: 10.7,
            sog_mps: 1.0,
            cog_rad: 0.0,
            heading_rad: Some(0.0),
            yaw_rate_radps: None,
            hdop: Some(0.8),
            replay: false,
            time_source: twin_wire::messages::TimeSource::Source,
        })
        .expect("JSON")
    }

    /// The time of a JSON input message (a fix or shaft speeds), s.
    pub fn time_of(bytes: &[u8]) -> f64 {
        let v: serde_json::Value = serde_json::from_slice(bytes).expect("a JSON message");
        twin_wire::time::parse_rfc3339(v["time"].as_str().expect("a time")).expect("RFC 3339")
    }

    /// A JSON input message with its fields changed by `edit`.
    pub fn edited(bytes: &[u8], edit: impl FnOnce(&mut serde_json::Value)) -> Vec<u8> {
        let mut v: serde_json::Value = serde_json::from_slice(bytes).expect("a JSON message");
        edit(&mut v);
        serde_json::to_vec(&v).expect("JSON")
    }

    /// A JSON input message stamped `time_s` instead.
    pub fn stamped(bytes: &[u8], time_s: f64) -> Vec<u8> {
        edited(bytes, |v| {
            v["time"] = twin_wire::time::format_rfc3339(time_s)
                .expect("a time to format")
                .into()
        })
    }

    /// `msgs` with every time moved by `by_s`.
    pub fn shifted(msgs: &[(&'static str, Vec<u8>)], by_s: f64) -> Messages {
        msgs.iter()
            .map(|(t, b)| (*t, stamped(b, time_of(b) + by_s)))
            .collect()
    }

    /// The index of the `n`-th GNSS message of `msgs`.
    pub fn nth_fix(msgs: &[(&'static str, Vec<u8>)], n: usize) -> usize {
        msgs.iter()
            .enumerate()
            .filter(|(_, (t, _))| *t == "gnss")
            .nth(n)
            .expect("that many fixes")
            .0
    }

    /// Publishes a vessel's messages in order through `session`, once the
    /// daemon's subscription is visible.
    pub async fn publish(session: &zenoh::Session, vessel: &str, msgs: &[(&'static str, Vec<u8>)]) {
        let declare = |topic: &str| {
            session
                .declare_publisher(format!("asv/{vessel}/{topic}"))
                .congestion_control(zenoh::qos::CongestionControl::Block)
        };
        let gnss = declare("gnss").await.expect("publisher");
        let act = declare("actuators").await.expect("publisher");
        wait_matching(&gnss, Duration::from_secs(20)).await;
        wait_matching(&act, Duration::from_secs(20)).await;
        for (topic, bytes) in msgs {
            let p = if *topic == "gnss" { &gnss } else { &act };
            p.put(bytes.clone()).await.expect("put");
        }
    }
}

/// The daemon (`twind::run`) in-process on a peer session listening on a
/// loopback port, with a session to publish inputs and one to watch the
/// outputs, both connected to it.
pub mod daemon {
    use std::path::Path;
    use std::time::Duration;

    use tokio_util::sync::CancellationToken;
    use twin_wire::outputs::{FaultMessage, StateMessage};
    use twind::forecast::FaultPathLoad;
    use twind::settings::Settings;
    use zenoh::Session;
    use zenoh::sample::Sample;

    use crate::net::{config, free_port};
    use crate::wire::{Outputs, fault_of, receive_until};

    /// A running daemon and its two neighbours.
    pub struct Rig {
        /// The daemon's session.
        pub daemon: Session,
        /// Publishes inputs.
        pub input: Session,
        /// Watches outputs.
        pub output: Session,
        cancel: CancellationToken,
        handle: tokio::task::JoinHandle<anyhow::Result<twind::RunSummary>>,
    }

    /// Waits (10 s at most) until `publisher` sees a subscriber.
    pub async fn wait_matching(publisher: &zenoh::pubsub::Publisher<'_>) {
        crate::wire::wait_matching(publisher, Duration::from_secs(10)).await;
    }

    /// A daemon with `settings`.
    pub async fn rig(settings: Settings) -> Rig {
        rig_observed(settings, FaultPathLoad::new()).await
    }

    /// [`rig`], the daemon's dispatcher reporting to `load`.
    pub async fn rig_observed(settings: Settings, load: FaultPathLoad) -> Rig {
        rig_with(settings, |run| twind::RunConfig { load, ..run }).await
    }

    /// A daemon as [`rig`] starts it, its run configuration changed by
    /// `adjust`.
    pub async fn rig_with(
        settings: Settings,
        adjust: impl FnOnce(twind::RunConfig) -> twind::RunConfig,
    ) -> Rig {
        let port = free_port();
        let daemon = zenoh::open(config("peer", &[port], &[])).await.unwrap();
        let input = zenoh::open(config("peer", &[], &[port])).await.unwrap();
        let output = zenoh::open(config("peer", &[], &[port])).await.unwrap();
        let cancel = CancellationToken::new();
        let handle = tokio::spawn(twind::run(adjust(twind::RunConfig::new(
            settings,
            daemon.clone(),
            cancel.clone(),
        ))));
        Rig {
            daemon,
            input,
            output,
            cancel,
            handle,
        }
    }

    impl Rig {
        /// Publishes the messages of `vessel` in order.
        pub async fn publish(&self, vessel: &str, msgs: &[(&'static str, Vec<u8>)]) {
            crate::wire::publish(&self.input, vessel, msgs).await;
        }

        /// Subscribes to everything the daemon says about `vessel`, and
        /// waits until the daemon's session sees the subscription.
        pub async fn collect(&self, vessel: &str) -> Outputs {
            self.watch(
                &format!("asv/{vessel}/twin/**"),
                &format!("asv/{vessel}/twin/state"),
            )
            .await
        }

        /// Subscribes to `key` and waits until the daemon's session sees
        /// the subscription on `probe` (a key the daemon puts on).
        pub async fn watch(&self, key: &str, probe: &str) -> Outputs {
            let sub = self
                .output
                .declare_subscriber(key.to_string())
                .with(zenoh::handlers::FifoChannel::new(100_000))
                .await
                .unwrap();
            let probe = self
                .daemon
                .declare_publisher(probe.to_string())
                .await
                .unwrap();
            wait_matching(&probe).await;
            sub
        }

        /// Stops the daemon (after letting the last messages through) and
        /// closes every session; what the daemon did.
        pub async fn stop(self) -> twind::RunSummary {
            tokio::time::sleep(Duration::from_millis(300)).await;
            self.cancel.cancel();
            let summary = tokio::time::timeout(Duration::from_secs(20), self.handle)
                .await
                .unwrap()
                .unwrap()
                .unwrap();
            // What the daemon published as it stopped is still on its way
            // to the subscribers: let it arrive before their session closes.
            tokio::time::sleep(Duration::from_millis(300)).await;
            self.input.close().await.unwrap();
            self.output.close().await.unwrap();
            self.daemon.close().await.unwrap();
            summary
        }
    }

    /// Every fault the daemon publishes for `vessel` while `twin-replay`
    /// plays `log` as fast as it takes it, until none has come for 3 s.
    pub async fn replayed_faults(rig: &Rig, log: &Path, vessel: &str) -> Vec<FaultMessage> {
        let sub = rig.collect(vessel).await;
        let mut options =
            twin_replay::ReplayOptions::new(twin_wire::VesselId::new(vessel).unwrap());
        options.rate = twin_replay::Rate::Max;
        let summary = twin_replay::replay_log(&rig.input, log, &options, |_| {})
            .await
            .unwrap();
        assert!(summary.published.gnss > 100, "{summary:?}");
        let mut faults = Vec::new();
        loop {
            let got = receive_until(&sub, Duration::from_secs(3), |_| false).await;
            let before = faults.len();
            faults.extend(got.iter().filter_map(fault_of));
            if faults.len() == before {
                return faults;
            }
        }
    }

    /// The last fault message among `samples`.
    pub fn last_fault(samples: &[Sample]) -> FaultMessage {
        let s = samples
            .iter()
            .rev()
            .find(|s| s.key_expr().as_str().ends_with("/twin/fault"))
            .expect("a fault message");
        serde_json::from_slice(&s.payload().to_bytes()).unwrap()
    }

    /// Every output on the twin topic ending in `suffix`, decoded.
    pub fn outputs<T: serde::de::DeserializeOwned>(samples: &[Sample], suffix: &str) -> Vec<T> {
        samples
            .iter()
            .filter(|s| s.key_expr().as_str().ends_with(suffix))
            .map(|s| serde_json::from_slice(&s.payload().to_bytes()).unwrap())
            .collect()
    }

    /// Every state among `samples`.
    pub fn states(samples: &[Sample]) -> Vec<StateMessage> {
        outputs(samples, "/twin/state")
    }

    /// What `sub` holds now.
    pub fn drain(sub: &Outputs) -> Vec<Sample> {
        let mut v = Vec::new();
        while let Ok(Some(s)) = sub.try_recv() {
            v.push(s);
        }
        v
    }
}
