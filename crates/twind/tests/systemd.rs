//! twind under systemd: `deploy/systemd/twind.service` passes
//! `systemd-analyze verify` (Debian's `systemd` package) with the built
//! binary in place of the installed one, and its hardening keeps
//! `systemd-analyze security` at a low exposure; and the real binary,
//! started with `$NOTIFY_SOCKET` on a socket this test binds and
//! `$WATCHDOG_USEC`, says `READY=1`, then `WATCHDOG=1` again and again,
//! then `STOPPING=1` on SIGTERM.

use std::os::unix::net::UnixDatagram;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use twin_tests::net::free_port;
use twin_tests::peers::require_program;

const INSTALL: &str = "apt-get install systemd";
const INSTALLED_BINARY: &str = "/usr/local/bin/twind";

fn unit_text() -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../deploy/systemd/twind.service");
    std::fs::read_to_string(path).unwrap()
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("twind-systemd-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `systemd-analyze ARGS FILE` on `unit` written as `FILE` in `dir`:
/// whether it succeeded, and what it said.
fn analyze(dir: &Path, file: &str, unit: &str, args: &[&str]) -> (bool, String) {
    let program = require_program("systemd-analyze", INSTALL);
    let path = dir.join(file);
    std::fs::write(&path, unit).unwrap();
    let out = Command::new(program)
        .args(args)
        .arg(&path)
        .output()
        .unwrap();
    let said = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.success(), said)
}

/// The unit with the built binary where the installed one would be.
fn unit_with_built_binary() -> String {
    let text = unit_text();
    assert!(
        text.contains(&format!("ExecStart={INSTALLED_BINARY} ")),
        "the unit runs {INSTALLED_BINARY}"
    );
    text.replace(INSTALLED_BINARY, env!("CARGO_BIN_EXE_twind"))
}

#[test]
fn the_unit_verifies_and_is_hardened() {
    let unit = unit_with_built_binary();
    for line in [
        "Type=notify",
        "WatchdogSec=10s",
        "StateDirectory=twind",
        "DynamicUser=yes",
    ] {
        assert!(unit.lines().any(|l| l == line), "no {line}");
    }
    assert!(
        unit.contains("--state-dir /var/lib/twind"),
        "the calibrations go to the state directory"
    );
    let dir = scratch("verify");
    let (ok, said) = analyze(&dir, "twind.service", &unit, &["verify"]);
    assert!(
        ok && said.trim().is_empty(),
        "systemd-analyze verify: {said}"
    );

    let (_, said) = analyze(&dir, "twind.service", &unit, &["security", "--offline=yes"]);
    let exposure: f64 = said
        .lines()
        .find_map(|l| l.split_once("Overall exposure level for twind.service: "))
        .and_then(|(_, rest)| rest.split_whitespace().next()?.parse().ok())
        .unwrap_or_else(|| panic!("no exposure level in: {said}"));
    println!("systemd-analyze security: exposure {exposure}");
    assert!(exposure <= 2.0, "exposure {exposure} (10 is none)");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `systemd-analyze verify` is a real check: a misspelt key is reported,
/// and so is a binary that does not exist.
#[test]
fn verify_reports_a_broken_unit() {
    let dir = scratch("broken");
    let unit = unit_with_built_binary().replace("\nType=notify", "\nTyp=notify");
    let (_, said) = analyze(&dir, "twind.service", &unit, &["verify"]);
    assert!(said.contains("Unknown key 'Typ'"), "{said}");
    let unit = unit_text().replace(INSTALLED_BINARY, "/nonexistent/twind");
    let (ok, said) = analyze(&dir, "twind.service", &unit, &["verify"]);
    assert!(!ok, "a missing binary passes: {said}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The next notification, or a failure after `within`.
fn next_notification(socket: &UnixDatagram, within: Duration) -> String {
    socket.set_read_timeout(Some(within)).unwrap();
    let mut buf = [0u8; 4096];
    let len = socket
        .recv(&mut buf)
        .unwrap_or_else(|e| panic!("no notification within {within:?}: {e}"));
    String::from_utf8_lossy(&buf[..len]).into_owned()
}

#[test]
fn twind_tells_systemd_ready_watchdog_and_stopping() {
    let dir = scratch("notify");
    let path = dir.join("notify.sock");
    let socket = UnixDatagram::bind(&path).unwrap();
    let port = free_port();
    let mut child = Command::new(env!("CARGO_BIN_EXE_twind"))
        .args(["--mode", "peer", "--no-multicast-scouting"])
        .args(["--listen", &format!("tcp/127.0.0.1:{port}")])
        .arg("--state-dir")
        .arg(dir.join("state"))
        .env("NOTIFY_SOCKET", &path)
        .env("WATCHDOG_USEC", "400000")
        .env_remove("WATCHDOG_PID")
        .current_dir(&dir)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("twind starts");
    let patience = Duration::from_secs(30);
    let first = next_notification(&socket, patience);
    assert!(
        first.lines().any(|l| l == "READY=1"),
        "the first notification says READY=1: {first:?}"
    );
    // Half of WATCHDOG_USEC: a ping every 0.2 s while it runs.
    for _ in 0..3 {
        let n = next_notification(&socket, patience);
        assert_eq!(n, "WATCHDOG=1");
    }
    let status = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let deadline = Instant::now() + patience;
    let stopping = loop {
        let n = next_notification(&socket, patience);
        if n != "WATCHDOG=1" || Instant::now() > deadline {
            break n;
        }
    };
    assert!(
        stopping.lines().any(|l| l == "STOPPING=1"),
        "after SIGTERM: {stopping:?}"
    );
    let exit = child.wait().unwrap();
    assert!(exit.success(), "twind exited with {exit}");
    let _ = std::fs::remove_dir_all(&dir);
}
