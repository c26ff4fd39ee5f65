//! Shared pieces of the replay tests: loopback Zenoh sessions on free ports
//! (multicast scouting off, peers connected explicitly), a collecting
//! subscriber, generated logs, and the oracle: what `FixAssembler` makes of
//! a log, encoded as the replay must publish it.

#![allow(dead_code)] // Each test binary uses its own subset.

use std::io::{BufRead, Cursor};
use std::net::TcpListener;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use twin_core::geodesy::LatLon;
use twin_core::sample::{GnssFix, PropellerSpeeds};
use twin_wire::assemble::{Assembled, AssemblerConfig, FixAssembler};
use twin_wire::messages::{ActuatorCommand, encode_actuators, encode_gnss};
use twin_wire::write::JsonlWriter;
use twin_wire::{KeySpace, LogReader, ReadOptions, VesselId};
use twin_zenoh::{Mode, ZenohArgs};
use zenoh::Session;
use zenoh::pubsub::Subscriber;

/// The real logs, relative to this crate.
pub const REAL_LOGS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../tests/fixtures/real");

/// How long a test waits for messages before it fails.
pub const PATIENCE: Duration = Duration::from_secs(20);

/// A TCP port free on the loopback interface right now.
pub fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// Loopback-only peer flags: listen on `listen`, connect to `connect`, no
/// multicast scouting.
pub fn loopback(listen: &str, connect: Option<&str>) -> ZenohArgs {
    ZenohArgs {
        mode: Some(Mode::Peer),
        listen: vec![listen.to_owned()],
        connect: connect.map(|c| vec![c.to_owned()]).unwrap_or_default(),
        no_multicast_scouting: true,
        ..ZenohArgs::default()
    }
}

/// A session listening on a free loopback port, and that port's endpoint.
pub async fn listening_session() -> (Session, String) {
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let config = loopback(&endpoint, None).to_config().unwrap();
    (zenoh::open(config).await.unwrap(), endpoint)
}

/// A session connected to `endpoint`.
pub async fn connected_session(endpoint: &str) -> Session {
    let config = loopback("tcp/127.0.0.1:0", Some(endpoint))
        .to_config()
        .unwrap();
    zenoh::open(config).await.unwrap()
}

/// One received message: its key and payload.
pub type Received = (String, Vec<u8>);

/// Everything a subscriber received, in order.
pub struct Collector {
    pub received: Arc<Mutex<Vec<Received>>>,
    _subscriber: Subscriber<()>,
}

impl Collector {
    /// Subscribes to `key_expr` on `session`, keeping every sample (a
    /// callback, so a blocked test thread never blocks Zenoh).
    pub async fn new(session: &Session, key_expr: &str) -> Self {
        let received = Arc::new(Mutex::new(Vec::new()));
        let sink = received.clone();
        let subscriber = session
            .declare_subscriber(key_expr.to_owned())
            .callback(move |sample| {
                sink.lock().unwrap().push((
                    sample.key_expr().as_str().to_owned(),
                    sample.payload().to_bytes().into_owned(),
                ));
            })
            .await
            .unwrap();
        Self {
            received,
            _subscriber: subscriber,
        }
    }

    pub fn len(&self) -> usize {
        self.received.lock().unwrap().len()
    }

    /// Waits until `n` messages are in (or [`PATIENCE`] is over), then a
    /// little more to catch extras, and returns them.
    pub async fn wait_for(&self, n: usize) -> Vec<Received> {
        let deadline = Instant::now() + PATIENCE;
        while self.len() < n && Instant::now() < deadline {
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
        self.received.lock().unwrap().clone()
    }
}

/// Waits until `session` sees a subscriber matching `key`.
pub async fn wait_matching(session: &Session, key: &str) {
    let probe = session.declare_publisher(key.to_owned()).await.unwrap();
    let deadline = Instant::now() + PATIENCE;
    while !probe.matching_status().await.unwrap().matching() {
        assert!(Instant::now() < deadline, "no subscriber matched {key}");
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
}

/// A subscriber session collecting `asv/{vessel}/**` and a publisher
/// session connected to it, matched.
pub async fn subscriber_and_publisher(vessel: &VesselId) -> (Session, Collector, Session) {
    let (sub_session, endpoint) = listening_session().await;
    let keys = KeySpace::default();
    let collector = Collector::new(&sub_session, &format!("{}/{vessel}/**", keys.prefix())).await;
    let pub_session = connected_session(&endpoint).await;
    wait_matching(&pub_session, &keys.gnss(vessel)).await;
    wait_matching(&pub_session, &keys.actuators(vessel)).await;
    (sub_session, collector, pub_session)
}

/// The oracle: what the replay must publish for `input` (run through
/// `LogReader` and `FixAssembler` directly), in order, with keys, for the
/// window `[start_s, start_s + duration_s)` after the first record. Returns
/// the messages and the number of inputs the contract cannot carry.
pub fn expected(
    input: impl BufRead,
    vessel: &VesselId,
    start_s: f64,
    duration_s: Option<f64>,
) -> (Vec<Received>, usize) {
    let keys = KeySpace::default();
    let reader = LogReader::open(input, ReadOptions::default()).unwrap();
    let mut assembler = FixAssembler::new(AssemblerConfig::default());
    let mut out = Vec::new();
    let mut first = None;
    for record in reader.filter_map(Result::ok) {
        first.get_or_insert(record.time_s);
        assembler.push(record, &mut out);
    }
    assembler.finish(&mut out);
    let first = first.unwrap();
    let mut messages = Vec::new();
    let mut unencodable = 0;
    for input in out {
        let offset = input.time_s() - first;
        if offset < start_s || duration_s.is_some_and(|d| offset >= start_s + d) {
            continue;
        }
        let encoded = match input {
            Assembled::Fix(fix) => encode_gnss(&fix, true).map(|p| (keys.gnss(vessel), p)),
            Assembled::Propellers(p) => encode_actuators(&ActuatorCommand::Speeds(p), true)
                .map(|p| (keys.actuators(vessel), p)),
            Assembled::Thrust(t) => encode_actuators(&ActuatorCommand::Thrust(t), true)
                .map(|p| (keys.actuators(vessel), p)),
        };
        match encoded {
            Ok(message) => messages.push(message),
            Err(_) => unencodable += 1,
        }
    }
    (messages, unencodable)
}

/// The first record time of the generated logs.
pub const GENERATED_T0_S: f64 = 1_785_731_240.0;

/// A JSON-lines log of `seconds` at 10 Hz: a fix every 0.1 s and propeller
/// speeds 0.05 s after each fix.
pub fn generated_log(seconds: u32) -> Vec<u8> {
    let mut writer = JsonlWriter::new(Vec::new());
    for k in 0..seconds * 10 {
        let t = GENERATED_T0_S + f64::from(k) * 0.1;
        writer
            .gnss(&GnssFix {
                time_s: t,
                position: LatLon {
                    lat_deg: 59.9 + f64::from(k) * 1e-6,
                    lon_deg: 10.7,
                },
                sog_mps: Some(2.0),
                cog_rad: Some(0.5),
                heading_rad: Some(0.45),
                yaw_rate_radps: None,
                hdop: Some(0.9),
            })
            .unwrap();
        writer
            .actuators(&ActuatorCommand::Speeds(PropellerSpeeds {
                time_s: t + 0.05,
                port_radps: 100.0 + f64::from(k),
                starboard_radps: 99.0 + f64::from(k),
            }))
            .unwrap();
    }
    writer.into_inner().unwrap()
}

/// A scratch file unique to this test process.
pub fn scratch(name: &str, contents: &[u8]) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("twin-replay-tests-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, contents).unwrap();
    path
}

/// A factory over in-memory log bytes, for `replay_reader`.
pub fn bytes(data: Vec<u8>) -> impl FnMut() -> std::io::Result<Cursor<Vec<u8>>> {
    move || Ok(Cursor::new(data.clone()))
}
