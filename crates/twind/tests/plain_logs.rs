//! twind's log is plain text when stderr is not a terminal (item 4): a log
//! written to a file (a journal, `2> twind.log`) holds no colour escapes.

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use twin_tests::net::free_port;

#[test]
fn a_log_written_to_a_file_has_no_colour_escapes() {
    let dir = std::env::temp_dir().join(format!("twind-plain-log-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let log = dir.join("twind.log");
    let port = free_port();
    let mut child = Command::new(env!("CARGO_BIN_EXE_twind"))
        .args(["--mode", "peer", "--no-multicast-scouting"])
        .args(["--listen", &format!("tcp/127.0.0.1:{port}")])
        // No settings or Zenoh file in this directory: the defaults.
        .current_dir(&dir)
        .env("RUST_LOG", "info")
        .env_remove("NO_COLOR")
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&log).unwrap())
        .spawn()
        .expect("twind starts");
    let deadline = Instant::now() + Duration::from_secs(30);
    let text = loop {
        let text = std::fs::read_to_string(&log).unwrap_or_default();
        if text.contains("twind running") || Instant::now() > deadline {
            break text;
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    // Ours: started above, stopped by its id.
    let _ = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status();
    let _ = child.wait();
    let _ = std::fs::remove_dir_all(&dir);
    println!("{text}");
    assert!(text.contains("twind running"), "no start line in the log");
    assert!(text.contains("INFO"), "the level is written");
    assert!(!text.contains('\u{1b}'), "colour escapes in a log file");
}
