//! The independent peers of the tests (programs, npm packages of
//! `tests/peers`, Python modules) and how to start them: each is found or
//! the test fails loudly with the command that installs it, never skips.
//! The standard library and serde_json only, so that the bridge's tests
//! include this same file (`crates/twin-bridge/tests/common/mod.rs`)
//! without depending on the daemon.

#![allow(dead_code)] // The bridge's tests include this file and use a subset.

use std::net::{TcpListener, UdpSocket};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The repository root: the first directory above the compiling crate's
/// manifest that holds the workspace's `Cargo.lock`.
pub fn repo_root() -> PathBuf {
    let manifest = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    manifest
        .ancestors()
        .find(|p| p.join("Cargo.lock").is_file())
        .map_or(manifest.clone(), Path::to_path_buf)
}

/// The npm peers' directory (`tests/peers`, installed by the README's test
/// command: `npm ci --prefix tests/peers`).
pub fn peers_dir() -> PathBuf {
    repo_root().join("tests/peers")
}

/// Fails the test, saying how to install a missing peer.
pub fn missing(what: &str, install: &str) -> ! {
    panic!(
        "{what} is missing: this test needs it as an independent peer. Install it with `{install}` (.ci/run does)."
    )
}

/// A program on PATH (or in `/usr/sbin`, `/sbin`), or a loud failure.
pub fn require_program(program: &str, install: &str) -> PathBuf {
    let paths = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&paths)
        .chain(["/usr/sbin".into(), "/sbin".into()])
        .map(|p| p.join(program))
        .find(|p| p.is_file())
        .unwrap_or_else(|| missing(program, install))
}

/// An npm package of `tests/peers`, or a loud failure.
pub fn require_node_module(name: &str) -> PathBuf {
    require_program("node", "apt-get install nodejs");
    let dir = peers_dir().join("node_modules").join(name);
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

/// The Python interpreter (`$PYTHON`, else `python3`) once it imports
/// `module`; a loud failure naming `install` when it does not.
pub fn python_with(module: &str, install: &str) -> String {
    let python = std::env::var("PYTHON").unwrap_or_else(|_| "python3".to_owned());
    require_python_module(&python, module, install);
    python
}

/// The path of a file under `tests/peers/`.
pub fn script(name: &str) -> PathBuf {
    peers_dir().join(name)
}

/// A TCP port free on loopback now (bound, read, released: a tiny race
/// that tests accept).
pub fn free_tcp_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("a free TCP port on loopback")
}

/// A UDP port free on loopback now.
pub fn free_udp_port() -> u16 {
    UdpSocket::bind("127.0.0.1:0")
        .and_then(|s| s.local_addr())
        .map(|a| a.port())
        .expect("a free UDP port on loopback")
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
            .stderr(Stdio::null())
            .status();
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A signalk-server (npm, `tests/peers`) on free loopback ports, with a
/// configuration directory of its own (a fresh server: no security, so it
/// takes deltas on its WebSocket stream), stopped and its directory removed
/// when dropped.
pub struct SignalkServer {
    /// The server's HTTP and WebSocket port.
    pub http_port: u16,
    /// Its NMEA 0183 TCP server's port.
    pub nmea0183_port: u16,
    /// The installed package (for its sample files).
    pub package: PathBuf,
    config_dir: PathBuf,
    child: Option<Child>,
}

impl SignalkServer {
    /// Starts a server; with `sample_nmea0183` it plays its sample NMEA 0183
    /// data (`samples/plaka.log`). Returns once its REST API answers (within
    /// 60 s, else the test fails).
    pub fn start(sample_nmea0183: bool) -> Self {
        Self::start_on(free_tcp_port(), sample_nmea0183)
    }

    /// [`Self::start`] with its HTTP and WebSocket server on `http_port`.
    pub fn start_on(http_port: u16, sample_nmea0183: bool) -> Self {
        let package = require_node_module("signalk-server");
        let nmea0183_port = free_tcp_port();
        let config_dir =
            std::env::temp_dir().join(format!("twin-signalk-{}-{http_port}", std::process::id()));
        std::fs::create_dir_all(&config_dir).expect("a configuration directory");
        let mut command = Command::new("node");
        command.arg(package.join("bin/signalk-server"));
        if sample_nmea0183 {
            command.arg("--sample-nmea0183-data");
        }
        command
            .env("PORT", http_port.to_string())
            .env("NMEA0183PORT", nmea0183_port.to_string())
            .env("TCPSTREAMPORT", free_tcp_port().to_string())
            .env("TCPSTREAMADDRESS", "127.0.0.1")
            .env("SIGNALK_DISABLE_SERVER_UPDATES", "true")
            .env("SIGNALK_NODE_CONFIG_DIR", &config_dir)
            .stdout(Stdio::null())
            .stderr(Stdio::null());
        let child = Child::spawn(&mut command).expect("signalk-server starts");
        let server = Self {
            http_port,
            nmea0183_port,
            package,
            config_dir,
            child: Some(child),
        };
        let deadline = Instant::now() + Duration::from_secs(60);
        while server.get("/signalk").is_none() {
            assert!(
                Instant::now() < deadline,
                "signalk-server did not answer on port {http_port} within 60 s"
            );
            std::thread::sleep(Duration::from_millis(200));
        }
        server
    }

    /// The server's delta stream, for a client that only sends.
    pub fn stream_url(&self) -> String {
        Self::stream_url_on(self.http_port)
    }

    /// The delta stream of a server on `http_port`.
    pub fn stream_url_on(http_port: u16) -> String {
        format!("ws://127.0.0.1:{http_port}/signalk/v1/stream?subscribe=none")
    }

    /// The body of a 200 answer to a GET of `path` parsed as JSON, waiting
    /// (60 s at most, else `None`) until `ready` accepts it.
    pub fn get_json_when(
        &self,
        path: &str,
        mut ready: impl FnMut(&serde_json::Value) -> bool,
    ) -> Option<serde_json::Value> {
        let deadline = Instant::now() + Duration::from_secs(60);
        loop {
            if let Some(v) = self
                .get(path)
                .and_then(|b| serde_json::from_str::<serde_json::Value>(&b).ok())
                && ready(&v)
            {
                return Some(v);
            }
            if Instant::now() > deadline {
                return None;
            }
            std::thread::sleep(Duration::from_millis(200));
        }
    }

    /// A GET of `path` on the server: the body of a 200 answer, else `None`
    /// (HTTP/1.0 over a plain socket: no client library to trust).
    pub fn get(&self, path: &str) -> Option<String> {
        use std::io::{Read, Write};
        let mut stream = std::net::TcpStream::connect(("127.0.0.1", self.http_port)).ok()?;
        stream
            .set_read_timeout(Some(Duration::from_secs(10)))
            .ok()?;
        write!(
            stream,
            "GET {path} HTTP/1.0\r\nHost: 127.0.0.1\r\nAccept: application/json\r\n\r\n"
        )
        .ok()?;
        let mut answer = String::new();
        stream.read_to_string(&mut answer).ok()?;
        let (head, body) = answer.split_once("\r\n\r\n")?;
        let status = head.lines().next()?;
        status.contains(" 200 ").then(|| body.to_string())
    }
}

impl Drop for SignalkServer {
    fn drop(&mut self) {
        drop(self.child.take());
        std::fs::remove_dir_all(&self.config_dir).ok();
    }
}
