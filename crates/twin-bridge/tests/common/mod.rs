//! Shared pieces of the bridge's tests: the independent peers installed by
//! `.ci/run` (each test fails loudly, naming the install command, when its
//! peer is missing), a sink that keeps what the bridge publishes, a bridge
//! running on a thread, free loopback ports, and waiting with a deadline.

#![allow(dead_code)] // Each test binary uses its own subset.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use twin_bridge::output::{Key, Sink};
use twin_bridge::spec::SourceSpec;
use twin_bridge::stats::BridgeStats;
use twin_bridge::{BridgeConfig, run};
use twin_wire::VesselId;

// The peers (found or a loud failure with the install command), free
// ports, process groups and the Signal K server: one copy for every test
// of the workspace, in the tests crate, included as a file so that these
// tests do not depend on the daemon.
#[path = "../../../../tests/src/peers.rs"]
mod peers;
pub use peers::*;

/// The repository root.
pub fn repo() -> PathBuf {
    repo_root()
}

/// The npm peers' directory (`tests/peers`, installed by `.ci/run`).
pub fn peers() -> PathBuf {
    peers_dir()
}

/// How long a test waits for what it expects before it fails.
pub const PATIENCE: Duration = Duration::from_secs(30);

/// Keeps everything the bridge publishes, in order.
#[derive(Default)]
pub struct MemorySink {
    pub messages: Mutex<Vec<(Key, Vec<u8>)>>,
}

impl Sink for MemorySink {
    fn put(&self, key: Key, payload: Vec<u8>) -> Result<(), String> {
        self.messages.lock().unwrap().push((key, payload));
        Ok(())
    }
}

impl MemorySink {
    /// The payloads published on `key`.
    pub fn on(&self, key: Key) -> Vec<Vec<u8>> {
        self.messages
            .lock()
            .unwrap()
            .iter()
            .filter(|(k, _)| *k == key)
            .map(|(_, p)| p.clone())
            .collect()
    }
}

/// A bridge running on a thread.
pub struct Running {
    pub sink: Arc<MemorySink>,
    pub stop: Arc<AtomicBool>,
    pub latest: Arc<Mutex<BridgeStats>>,
    thread: Option<JoinHandle<anyhow::Result<BridgeStats>>>,
}

/// Starts a bridge for vessel `test` reading `sources`.
pub fn start(sources: &[&str]) -> Running {
    let specs: Vec<SourceSpec> = sources.iter().map(|s| s.parse().unwrap()).collect();
    start_with(BridgeConfig::new(VesselId::new("test").unwrap(), specs))
}

/// Starts a bridge with `config`.
pub fn start_with(config: BridgeConfig) -> Running {
    let sink = Arc::new(MemorySink::default());
    let stop = Arc::new(AtomicBool::new(false));
    let latest = Arc::new(Mutex::new(BridgeStats::default()));
    let thread = {
        let (sink, stop, latest) = (sink.clone(), stop.clone(), latest.clone());
        std::thread::spawn(move || {
            run(&config, sink, stop, |s| *latest.lock().unwrap() = s.clone())
        })
    };
    Running {
        sink,
        stop,
        latest,
        thread: Some(thread),
    }
}

impl Running {
    /// Waits until `done` holds for what was published (or fails after
    /// [`PATIENCE`], saying `what`).
    pub fn wait_until(&self, what: &str, mut done: impl FnMut(&MemorySink) -> bool) {
        let deadline = Instant::now() + PATIENCE;
        while !done(&self.sink) {
            assert!(
                Instant::now() < deadline,
                "timed out waiting for {what}; counts: {:#?}",
                self.latest.lock().unwrap()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Waits until the counts satisfy `done`.
    pub fn wait_stats(&self, what: &str, mut done: impl FnMut(&BridgeStats) -> bool) {
        let deadline = Instant::now() + PATIENCE;
        loop {
            if done(&self.latest.lock().unwrap()) {
                return;
            }
            assert!(
                Instant::now() < deadline,
                "timed out waiting for {what}; counts: {:#?}",
                self.latest.lock().unwrap()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Stops the bridge and returns its final counts.
    pub fn stop(mut self) -> BridgeStats {
        self.stop.store(true, Ordering::Relaxed);
        self.thread.take().unwrap().join().unwrap().unwrap()
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

/// Every gnss payload decodes; their fixes in order.
pub fn fixes(sink: &MemorySink) -> Vec<twin_wire::messages::Decoded<twin_core::sample::GnssFix>> {
    sink.on(Key::Gnss)
        .iter()
        .map(|p| {
            twin_wire::messages::decode_gnss(p).unwrap_or_else(|e| {
                panic!("malformed gnss payload {e}: {}", String::from_utf8_lossy(p))
            })
        })
        .collect()
}

/// Every actuators payload decodes; their commands in order.
pub fn commands(
    sink: &MemorySink,
) -> Vec<twin_wire::messages::Decoded<twin_wire::ActuatorCommand>> {
    sink.on(Key::Actuators)
        .iter()
        .map(|p| {
            twin_wire::messages::decode_actuators(p).unwrap_or_else(|e| {
                panic!(
                    "malformed actuators payload {e}: {}",
                    String::from_utf8_lossy(p)
                )
            })
        })
        .collect()
}

/// The fixes `twin_wire`'s log reader and assembler make of `log` (what
/// `twin analyze` would see), in order.
pub fn expected_fixes(log: &str) -> Vec<twin_core::sample::GnssFix> {
    use twin_wire::assemble::{Assembled, AssemblerConfig, FixAssembler};
    let reader =
        twin_wire::LogReader::open(log.as_bytes(), twin_wire::ReadOptions::default()).unwrap();
    let mut assembler = FixAssembler::new(AssemblerConfig::default());
    let mut out = Vec::new();
    for record in reader.filter_map(Result::ok) {
        assembler.push(record, &mut out);
    }
    assembler.finish(&mut out);
    out.into_iter()
        .filter_map(|a| match a {
            Assembled::Fix(f) => Some(f),
            _ => None,
        })
        .collect()
}
