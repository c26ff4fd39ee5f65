//! Shared pieces of the bridge's tests: the independent peers installed by
//! `.ci/run` (each test fails loudly, naming the install command, when its
//! peer is missing), a sink that keeps what the bridge publishes, a bridge
//! running on a thread, free loopback ports, and waiting with a deadline.

#![allow(dead_code)] // Each test binary uses its own subset.

use std::net::{TcpListener, UdpSocket};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use twin_bridge::output::{Key, Sink};
use twin_bridge::spec::SourceSpec;
use twin_bridge::stats::BridgeStats;
use twin_bridge::{BridgeConfig, run};
use twin_wire::VesselId;

/// The repository root.
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The npm peers' directory (`tests/peers`, installed by `.ci/run`).
pub fn peers() -> PathBuf {
    repo().join("tests/peers")
}

/// How long a test waits for what it expects before it fails.
pub const PATIENCE: Duration = Duration::from_secs(30);

/// Fails the test, saying how to install a missing peer.
pub fn missing(what: &str, install: &str) -> ! {
    panic!(
        "{what} is missing: this test needs it as an independent peer. Install it with `{install}` (.ci/run does)."
    )
}

/// A program on PATH, or a loud failure.
pub fn require_program(program: &str, install: &str) -> PathBuf {
    let found = std::env::var_os("PATH").and_then(|paths| {
        std::env::split_paths(&paths)
            .map(|p| p.join(program))
            .find(|p| p.is_file())
    });
    found.unwrap_or_else(|| missing(program, install))
}

/// An npm package of `tests/peers`, or a loud failure.
pub fn require_node_module(name: &str) -> PathBuf {
    require_program("node", "apt-get install nodejs");
    let dir = peers().join("node_modules").join(name);
    if !dir.join("package.json").is_file() {
        missing(
            &format!("the npm package {name}"),
            "npm ci --prefix tests/peers",
        );
    }
    dir
}

/// A Python module, or a loud failure.
pub fn require_python_module(python: &str, module: &str, install: &str) {
    let ok = Command::new(python)
        .args(["-c", &format!("import {module}")])
        .status()
        .is_ok_and(|s| s.success());
    if !ok {
        missing(&format!("the Python module {module} ({python})"), install);
    }
}

/// A TCP port free on loopback now.
pub fn free_tcp_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// A UDP port free on loopback now.
pub fn free_udp_port() -> u16 {
    UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

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

/// A peer server started in a process group of its own (with whatever it
/// starts: gpsfake starts gpsd), the whole group killed when dropped.
pub struct Child(pub std::process::Child);

impl Child {
    /// Spawns `command` as the leader of a new process group.
    pub fn spawn(command: &mut Command) -> std::io::Result<Self> {
        use std::os::unix::process::CommandExt;
        command.process_group(0).spawn().map(Child)
    }
}

impl Drop for Child {
    fn drop(&mut self) {
        let group = format!("-{}", self.0.id());
        let _ = Command::new("kill")
            .args(["-KILL", "--", &group])
            .stderr(std::process::Stdio::null())
            .status();
        let _ = self.0.kill();
        let _ = self.0.wait();
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
