//! The Prometheus metrics of a real `twind`, from the outside in: the
//! binary runs with its web page and its own metrics port, a Zenoh client
//! sends one vessel good fixes and a bad one, a vessel that is never
//! admitted a bad one and a key that is no input topic; `GET /metrics` on
//! both ports then counts exactly those, and Prometheus' own `promtool
//! check metrics` (Debian's `prometheus` package) accepts the text.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use twin_tests::net::{config, free_port};
use twin_tests::peers::require_program;
use twin_tests::wire::{live_fix, now_s, publish};

const PROMTOOL_INSTALL: &str = "apt-get install prometheus";

/// A running twind, killed when dropped.
struct Twind {
    child: Child,
    page: SocketAddr,
    metrics: SocketAddr,
}

impl Drop for Twind {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// twind on a free Zenoh port (returned), its page and its metrics each on
/// a free port. A port found free can be taken by another process before
/// twind binds it: twind then exits before printing its URLs, and is
/// started again on another port (three tries, then its error is shown).
fn start_twind() -> (Twind, u16) {
    let mut failures = Vec::new();
    for _ in 0..3 {
        let port = free_port();
        match try_start_twind(port) {
            Ok(twind) => return (twind, port),
            Err(why) => failures.push(why),
        }
    }
    panic!("twind did not start: {failures:#?}");
}

/// twind on Zenoh `port`, or what it printed on stderr when it stopped
/// before printing both URLs.
fn try_start_twind(port: u16) -> Result<Twind, String> {
    let dir = std::env::temp_dir().join(format!("twind-metrics-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_twind"))
        .args(["--mode", "peer", "--no-multicast-scouting"])
        .args(["--listen", &format!("tcp/127.0.0.1:{port}")])
        .args(["--id", "metrics-test"])
        .args(["--web-listen", "127.0.0.1:0"])
        .args(["--metrics-listen", "127.0.0.1:0"])
        .current_dir(&dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("twind starts");
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let mut errors = child.stderr.take().unwrap();
    let (mut page, mut metrics) = (None, None);
    while page.is_none() || metrics.is_none() {
        let Some(Ok(line)) = lines.next() else {
            let _ = child.kill();
            let _ = child.wait();
            let mut said = String::new();
            let _ = errors.read_to_string(&mut said);
            return Err(said);
        };
        if let Some(url) = line.strip_prefix("twind web page: http://") {
            page = Some(url.trim_end_matches('/').parse().unwrap());
        } else if let Some(url) = line.strip_prefix("twind metrics: http://") {
            metrics = Some(url.trim_end_matches("/metrics").parse().unwrap());
        }
    }
    std::thread::spawn(move || for _ in lines {});
    // Keep reading stderr so that twind never blocks on a full pipe.
    std::thread::spawn(move || std::io::copy(&mut errors, &mut std::io::sink()));
    Ok(Twind {
        child,
        page: page.unwrap(),
        metrics: metrics.unwrap(),
    })
}

/// `GET /metrics`: the content type and the text.
fn scrape(addr: SocketAddr) -> (String, String) {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    write!(s, "GET /metrics HTTP/1.0\r\nHost: test\r\n\r\n").unwrap();
    let mut raw = String::new();
    s.read_to_string(&mut raw).unwrap();
    let (head, body) = raw.split_once("\r\n\r\n").expect("an HTTP response");
    assert!(
        head.starts_with("HTTP/1.0 200") || head.starts_with("HTTP/1.1 200"),
        "{head}"
    );
    let content_type = head
        .lines()
        .find_map(|l| l.strip_prefix("content-type: "))
        .unwrap_or_default()
        .to_string();
    (content_type, body.to_string())
}

/// The value of the sample `series` (name and labels as written), if any.
fn value(text: &str, series: &str) -> Option<f64> {
    text.lines()
        .filter(|l| !l.starts_with('#'))
        .find_map(|l| l.strip_prefix(series)?.strip_prefix(' ')?.parse().ok())
}

/// Runs `promtool check metrics` on `text`: whether it accepts it, and what
/// it said.
fn promtool(text: &str) -> (bool, String) {
    let promtool = require_program("promtool", PROMTOOL_INSTALL);
    let mut child = Command::new(promtool)
        .args(["check", "metrics"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child
        .stdin
        .take()
        .unwrap()
        .write_all(text.as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    let said = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.success(), said)
}

const GOOD_FIXES: usize = 5;

/// What the test sends: five good fixes and a bad one for `m-1`, a bad fix
/// for `m-2` (never admitted), and a message on `asv/m-1/rudder`.
async fn send(port: u16) -> zenoh::Session {
    let client = zenoh::open(config("peer", &[], &[port])).await.unwrap();
    let t0 = now_s();
    let mut msgs: Vec<(&'static str, Vec<u8>)> = (0..GOOD_FIXES)
        .map(|i| ("gnss", live_fix(t0 + 0.2 * i as f64, i)))
        .collect();
    msgs.push(("gnss", b"{not json".to_vec()));
    publish(&client, "m-1", &msgs).await;
    client.put("asv/m-2/gnss", "{not json").await.unwrap();
    client.put("asv/m-1/rudder", "{}").await.unwrap();
    client
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn metrics_count_what_the_daemon_received_and_promtool_accepts_them() {
    require_program("promtool", PROMTOOL_INSTALL);
    let (twind, port) = start_twind();
    let client = send(port).await;

    // The daemon handles the messages on its own time: scrape until the
    // last counts are there (or give up and let the assertions say what
    // is missing).
    let deadline = Instant::now() + Duration::from_secs(30);
    let mut text;
    loop {
        text = scrape(twind.metrics).1;
        let received = value(
            &text,
            "twind_vessel_messages_received_total{topic=\"gnss\"}",
        );
        let refused = value(&text, "twind_messages_refused_total{reason=\"bad_key\"}");
        if (received == Some(6.0) && refused == Some(1.0)) || Instant::now() > deadline {
            break;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    println!("{text}");
    let expected = [
        ("twind_info{daemon=\"metrics-test\",version=\"0.1.0\"}", 1.0),
        ("twind_messages_received_total", 8.0),
        ("twind_messages_routed_total", 6.0),
        ("twind_messages_refused_total{reason=\"bad_json\"}", 1.0),
        ("twind_messages_refused_total{reason=\"bad_key\"}", 1.0),
        ("twind_vessels", 1.0),
        ("twind_vessels_max", 20_000.0),
        ("twind_queue_capacity", 256.0),
        ("twind_queued_events", 0.0),
        ("twind_vessel_messages_received_total{topic=\"gnss\"}", 6.0),
        (
            "twind_vessel_messages_received_total{topic=\"actuators\"}",
            0.0,
        ),
        (
            "twind_vessel_messages_accepted_total{topic=\"gnss\"}",
            GOOD_FIXES as f64,
        ),
        (
            "twind_vessel_messages_rejected_total{reason=\"bad_json\"}",
            1.0,
        ),
        (
            "twind_estimator_update_seconds_count{input=\"fix\"}",
            GOOD_FIXES as f64,
        ),
        (
            "twind_estimator_update_seconds_bucket{input=\"fix\",le=\"+Inf\"}",
            GOOD_FIXES as f64,
        ),
        (
            "twind_estimator_update_seconds_count{input=\"propellers\"}",
            0.0,
        ),
        ("twind_calibration_save_failures_total", 0.0),
        ("twind_ros2_missed_total", 0.0),
    ];
    for (series, want) in expected {
        assert_eq!(value(&text, series), Some(want), "{series}");
    }
    for family in [
        "twind_messages_received_total",
        "twind_estimator_update_seconds",
    ] {
        assert!(
            text.contains(&format!("# HELP {family} ")),
            "no HELP for {family}"
        );
    }
    assert!(text.contains("# TYPE twind_estimator_update_seconds histogram"));

    let (ok, said) = promtool(&text);
    assert!(ok, "promtool refuses the metrics: {said}");

    // The page's port serves the same, and its own count of skipped events.
    let (content_type, page_text) = scrape(twind.page);
    assert_eq!(content_type, "text/plain; version=0.0.4; charset=utf-8");
    assert_eq!(
        value(
            &page_text,
            "twind_vessel_messages_accepted_total{topic=\"gnss\"}"
        ),
        Some(GOOD_FIXES as f64)
    );
    assert_eq!(
        value(&page_text, "twind_page_events_skipped_total"),
        Some(0.0)
    );
    let (ok, said) = promtool(&page_text);
    assert!(ok, "promtool refuses the page's metrics: {said}");
    client.close().await.unwrap();
}

/// promtool is a real check: a text that breaks the format is refused.
#[test]
fn promtool_refuses_a_broken_exposition() {
    let (ok, said) = promtool("# TYPE twind_x counter\ntwind_x{reason=\"a\" 1\n");
    assert!(!ok, "accepted: {said}");
}
