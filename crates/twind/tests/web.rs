//! The web page's server (`src/web.rs`) on a free port with a fake output
//! tap: `/events` sends the snapshot (latest states first) and then every
//! output in the order the daemon published it; `/` serves the embedded
//! page; the API answers; a client that never reads skips events without
//! holding up the sender; the server stops with its token even with event
//! streams open.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::Arc;
use std::time::{Duration, Instant};

use tokio::sync::broadcast;
use tokio_util::sync::CancellationToken;
use twin_wire::Topic;
use twind::web;
use twind::{LatestStates, OutputEvent};

fn info() -> web::WebInfo {
    web::WebInfo::new(&twind::settings::Settings::default())
}

/// A state payload as the daemon writes it, with a sequence number in
/// `north_m`.
fn state_json(vessel: &str, seq: u64) -> String {
    format!(
        r#"{{"vessel":"{vessel}","time":"2024-06-01T10:00:{:02}.{:03}Z","lat_deg":62.47,"lon_deg":6.15,"north_m":{seq},"east_m":0.0,"sog_mps":1.5,"cog_rad":0.0,"heading_rad":null,"sigma":{{"north_m":0.1,"east_m":0.1,"sog_mps":0.1,"cog_rad":0.1}},"nis":1.0,"nis_dof":4,"current":null,"model":"seed_method","stale":false,"replay":false}}"#,
        (seq / 1000) % 60,
        seq % 1000
    )
}

struct Server {
    addr: SocketAddr,
    tap: broadcast::Sender<OutputEvent>,
    stop: CancellationToken,
    server: web::WebServer,
}

async fn serve(latest: LatestStates) -> Server {
    serve_with(latest, info()).await
}

async fn serve_with(latest: LatestStates, info: web::WebInfo) -> Server {
    let (tap, _) = broadcast::channel(1 << 16);
    let stop = CancellationToken::new();
    let sources = web::Sources {
        tap: tap.clone(),
        latest,
        inputs: None,
        info,
        metrics: twind::metrics::Metrics::default(),
    };
    let server = web::start("127.0.0.1:0".parse().unwrap(), sources, stop.clone())
        .await
        .expect("the server starts on a free port");
    Server {
        addr: server.local_addr(),
        tap,
        stop,
        server,
    }
}

/// A plain HTTP/1.0 GET (no chunked framing, the body ends at close):
/// status line, headers, body.
fn get(addr: SocketAddr, path: &str) -> (String, String, Vec<u8>) {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    write!(s, "GET {path} HTTP/1.0\r\nHost: test\r\n\r\n").unwrap();
    let mut raw = Vec::new();
    s.read_to_end(&mut raw).unwrap();
    let split = raw
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .expect("a header block");
    let head = String::from_utf8_lossy(&raw[..split]).to_string();
    let (status, headers) = head.split_once("\r\n").unwrap_or((&head, ""));
    (
        status.to_string(),
        headers.to_lowercase(),
        raw[split + 4..].to_vec(),
    )
}

/// An open event stream, read one event at a time.
struct Events {
    reader: BufReader<TcpStream>,
}

impl Events {
    fn open(addr: SocketAddr) -> Self {
        let mut s = TcpStream::connect(addr).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        write!(s, "GET /events HTTP/1.0\r\nHost: test\r\n\r\n").unwrap();
        let mut reader = BufReader::new(s);
        let mut line = String::new();
        reader.read_line(&mut line).unwrap();
        assert!(
            line.starts_with("HTTP/1.0 200") || line.starts_with("HTTP/1.1 200"),
            "{line}"
        );
        let mut content_type = String::new();
        loop {
            line.clear();
            reader.read_line(&mut line).unwrap();
            if line.to_lowercase().starts_with("content-type:") {
                content_type = line.clone();
            }
            if line == "\r\n" {
                break;
            }
        }
        assert!(content_type.contains("text/event-stream"), "{content_type}");
        Self { reader }
    }

    /// The next event's name and data (keep-alive comments skipped); `None`
    /// at the end of the stream.
    fn next(&mut self) -> Option<(String, String)> {
        let (mut name, mut data) = (String::new(), String::new());
        let mut line = String::new();
        loop {
            line.clear();
            if self.reader.read_line(&mut line).ok()? == 0 {
                return None;
            }
            let l = line.trim_end_matches(['\r', '\n']);
            if l.is_empty() {
                if !data.is_empty() || !name.is_empty() {
                    return Some((name, data));
                }
                continue;
            }
            if let Some(v) = l.strip_prefix("event:") {
                name = v.trim_start().to_string();
            } else if let Some(v) = l.strip_prefix("data:") {
                data.push_str(v.strip_prefix(' ').unwrap_or(v));
            }
        }
    }
}

fn send(tap: &broadcast::Sender<OutputEvent>, vessel: &str, topic: Topic, json: String) {
    tap.send(OutputEvent {
        vessel: vessel.to_string(),
        topic,
        json: Arc::from(json),
    })
    .expect("the web page's pump listens");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn events_come_in_order_after_a_snapshot_of_the_latest_states() {
    let latest = LatestStates::default();
    latest.slot("early").set(state_json("early", 7).as_bytes());
    let s = serve(latest).await;
    let addr = s.addr;
    let mut ev = tokio::task::spawn_blocking(move || Events::open(addr))
        .await
        .unwrap();

    // The snapshot: what the daemon is, then the latest state of the vessel
    // that was there before the page.
    let (ev2, first) = tokio::task::spawn_blocking(move || {
        let a = ev.next().unwrap();
        let b = ev.next().unwrap();
        (ev, vec![a, b])
    })
    .await
    .unwrap();
    ev = ev2;
    assert_eq!(first[0].0, "hello");
    assert!(
        first[0].1.contains(r#""service":"twind""#),
        "{}",
        first[0].1
    );
    assert_eq!(first[1].0, "state");
    assert_eq!(first[1].1, state_json("early", 7));

    // Then every output, in order, with its topic as the event name.
    let kinds = [
        (Topic::TwinState, "state"),
        (Topic::TwinFault, "fault"),
        (Topic::TwinPrediction, "prediction"),
        (Topic::TwinAlarm, "alarm"),
        (Topic::TwinStats, "stats"),
        (Topic::TwinFinding, "finding"),
    ];
    let n = 600u64;
    let expected: Vec<(String, String)> = (0..n)
        .map(|i| {
            let (topic, name) = kinds[i as usize % kinds.len()];
            let json = if topic == Topic::TwinState {
                state_json("otter-1", i)
            } else {
                format!(r#"{{"vessel":"otter-1","seq":{i}}}"#)
            };
            send(&s.tap, "otter-1", topic, json.clone());
            (name.to_string(), json)
        })
        .collect();
    // Not forwarded: inputs and liveliness are not outputs.
    send(&s.tap, "otter-1", Topic::TwinAlive, "{}".into());
    let got = tokio::task::spawn_blocking(move || {
        (0..n)
            .map(|_| ev.next().expect("an event"))
            .collect::<Vec<_>>()
    })
    .await
    .unwrap();
    assert_eq!(got, expected);

    // The latest outputs are what a new page starts from.
    let mut late = tokio::task::spawn_blocking(move || Events::open(addr))
        .await
        .unwrap();
    let snapshot = tokio::task::spawn_blocking(move || {
        (0..9).map(|_| late.next().unwrap()).collect::<Vec<_>>()
    })
    .await
    .unwrap();
    let names: Vec<&str> = snapshot.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        [
            "hello",
            "state",
            "state",
            "fault",
            "prediction",
            "stats",
            "finding",
            "alarm",
            "alarm"
        ],
        "hello, then per vessel (sorted) its latest outputs, then the alarms"
    );
    assert_eq!(snapshot[2].1, state_json("otter-1", 594));
    assert_eq!(snapshot[3].1, r#"{"vessel":"otter-1","seq":595}"#);

    s.stop.cancel();
    s.server.stopped(Duration::from_secs(5)).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn serves_the_embedded_page_and_the_api() {
    let latest = LatestStates::default();
    latest
        .slot("otter-2")
        .set(state_json("otter-2", 1).as_bytes());
    let s = serve(latest).await;
    let addr = s.addr;
    // A state through the tap fills the history.
    send(
        &s.tap,
        "otter-2",
        Topic::TwinState,
        state_json("otter-2", 3),
    );
    tokio::time::sleep(Duration::from_millis(100)).await;
    let results = tokio::task::spawn_blocking(move || {
        [
            "/",
            "/assets/app.js",
            "/assets/app.css",
            "/licenses/three.txt",
            "/api/vessels",
            "/api/history/otter-2",
            "/api/history/nobody",
            "/api/info",
            "/healthz",
            "/etc/passwd",
            "/../Cargo.toml",
        ]
        .map(|p| (p, get(addr, p)))
    })
    .await
    .unwrap();
    let find = |p: &str| results.iter().find(|r| r.0 == p).unwrap().1.clone();

    let (status, headers, body) = find("/");
    assert!(status.contains(" 200"), "{status}");
    assert!(headers.contains("content-type: text/html"), "{headers}");
    assert!(
        headers.contains("content-security-policy: default-src 'self'"),
        "{headers}"
    );
    assert!(
        headers.contains("img-src 'self' data: blob:; "),
        "no tiles configured, images from this server only: {headers}"
    );
    let html = String::from_utf8(body).unwrap();
    assert!(html.contains(r#"src="/assets/app.js""#), "{html}");
    assert!(html.contains(r#"data-testid="map""#), "{html}");
    assert!(
        !html.contains("http://") && !html.contains("https://"),
        "the page loads nothing from elsewhere"
    );

    let (status, headers, body) = find("/assets/app.js");
    assert!(status.contains(" 200"), "{status}");
    assert!(
        headers.contains("content-type: text/javascript"),
        "{headers}"
    );
    assert!(body.len() > 100_000, "three.js is bundled");
    assert!(String::from_utf8_lossy(&body[..200]).contains("MIT licence"));
    let (status, _, body) = find("/licenses/three.txt");
    assert!(status.contains(" 200"), "{status}");
    assert!(String::from_utf8_lossy(&body).contains("three.js authors"));

    let (status, headers, body) = find("/api/vessels");
    assert!(status.contains(" 200"), "{status}");
    assert!(
        headers.contains("content-type: application/json"),
        "{headers}"
    );
    let v: serde_json::Value = serde_json::from_slice(&body).unwrap();
    assert_eq!(v.as_array().unwrap().len(), 1);
    assert_eq!(v[0]["vessel"], "otter-2");

    let (status, _, body) = find("/api/history/otter-2");
    assert!(status.contains(" 200"), "{status}");
    let h: serde_json::Value = serde_json::from_slice(&body).unwrap();
    assert_eq!(h["vessel"], "otter-2");
    assert_eq!(h["track"][0][1], 3.0, "{h}");
    assert!(find("/api/history/nobody").0.contains(" 404"));

    let (_, _, body) = find("/api/info");
    let i: serde_json::Value = serde_json::from_slice(&body).unwrap();
    assert_eq!(i["fault_loss"], info().fault_loss);
    assert!(i["tiles"].is_null(), "no tiles unless configured: {i}");
    assert_eq!(find("/healthz").2, b"ok");
    assert!(find("/etc/passwd").0.contains(" 404"));
    assert!(!find("/../Cargo.toml").0.contains(" 200"));

    // Read-only.
    let (status, _, _) = tokio::task::spawn_blocking(move || {
        let mut s = TcpStream::connect(addr).unwrap();
        write!(
            s,
            "POST /api/vessels HTTP/1.0\r\nHost: t\r\nContent-Length: 2\r\n\r\n{{}}"
        )
        .unwrap();
        let mut raw = String::new();
        s.read_to_string(&mut raw).unwrap();
        (raw.lines().next().unwrap_or_default().to_string(), (), ())
    })
    .await
    .unwrap();
    assert!(status.contains(" 405"), "{status}");

    s.stop.cancel();
    s.server.stopped(Duration::from_secs(5)).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn configured_tiles_reach_the_page_and_its_image_policy() {
    let settings = twind::settings::Settings::from_toml(
        "[web]\ntile_url = \"https://tile.openstreetmap.org/{z}/{x}/{y}.png\"\n\
         tile_overlay_url = \"http://127.0.0.1:8099/seamark/{z}/{x}/{y}.png?v=2\"\n\
         tile_attribution = \"© OpenStreetMap contributors\"\ntile_max_zoom = 18\n",
    )
    .unwrap();
    let s = serve_with(LatestStates::default(), web::WebInfo::new(&settings)).await;
    let addr = s.addr;
    let (page, api) = tokio::task::spawn_blocking(move || (get(addr, "/"), get(addr, "/api/info")))
        .await
        .unwrap();
    assert!(
        page.1.contains(
            "img-src 'self' data: blob: https://tile.openstreetmap.org http://127.0.0.1:8099; "
        ),
        "{}",
        page.1
    );
    assert!(page.1.contains("connect-src 'self';"), "{}", page.1);
    let i: serde_json::Value = serde_json::from_slice(&api.2).unwrap();
    assert_eq!(
        i["tiles"],
        serde_json::json!({
            "url": "https://tile.openstreetmap.org/{z}/{x}/{y}.png",
            "overlay_url": "http://127.0.0.1:8099/seamark/{z}/{x}/{y}.png?v=2",
            "attribution": "© OpenStreetMap contributors",
            "max_zoom": 18,
        })
    );
    s.stop.cancel();
    s.server.stopped(Duration::from_secs(10)).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_that_does_not_read_skips_and_holds_up_nothing() {
    let s = serve(LatestStates::default()).await;
    let addr = s.addr;
    // A client that opens the stream and then reads nothing for a while.
    let mut slow = tokio::task::spawn_blocking(move || Events::open(addr))
        .await
        .unwrap();
    // Far more than its queue and the sockets' buffers hold.
    let big = format!(r#"{{"vessel":"v","pad":"{}"}}"#, "x".repeat(1000));
    let n = 6 * web::CLIENT_QUEUE;
    for i in 0..n {
        // `send` on a broadcast channel never waits: the daemon is never held.
        send(
            &s.tap,
            "v",
            Topic::TwinStats,
            big.replace("\"v\"", &format!("\"v{}\"", i % 3)),
        );
        if i % 64 == 0 {
            tokio::task::yield_now().await;
        }
    }
    // A new page is served at once, from the snapshot.
    let mut fresh = tokio::task::spawn_blocking(move || Events::open(addr))
        .await
        .unwrap();
    let first = tokio::task::spawn_blocking(move || fresh.next().unwrap())
        .await
        .unwrap();
    assert_eq!(first.0, "hello");
    // The slow client, once it reads, is told that it missed events, and
    // then goes on with the newest.
    send(&s.tap, "v", Topic::TwinState, state_json("v", 1));
    let (lagged, seen) = tokio::task::spawn_blocking(move || {
        let mut seen = 0usize;
        loop {
            let (name, data) = slow.next().expect("the stream goes on");
            seen += 1;
            if name == "lagged" {
                return (data, seen);
            }
            assert!(seen < n, "never told of the skipped events");
        }
    })
    .await
    .unwrap();
    let skipped: serde_json::Value = serde_json::from_str(&lagged).unwrap();
    assert!(skipped["skipped"].as_u64().unwrap() > 0, "{lagged}");
    assert!(seen < n, "read {seen} of {n}: some were skipped");
    assert!(s.server.skipped() > 0);
    s.stop.cancel();
    s.server.stopped(Duration::from_secs(5)).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn stops_with_the_token_even_with_streams_open() {
    let s = serve(LatestStates::default()).await;
    let addr = s.addr;
    let mut ev = tokio::task::spawn_blocking(move || Events::open(addr))
        .await
        .unwrap();
    let started = Instant::now();
    s.stop.cancel();
    s.server.stopped(Duration::from_secs(10)).await;
    assert!(
        started.elapsed() < Duration::from_secs(5),
        "the stream held the server up"
    );
    // The stream ends, and nobody is listening any more.
    let ended = tokio::task::spawn_blocking(move || {
        while ev.next().is_some() {}
        true
    })
    .await
    .unwrap();
    assert!(ended);
    assert!(
        TcpStream::connect(addr).is_err(),
        "still listening after the stop"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn refuses_event_streams_beyond_its_limit() {
    let s = serve(LatestStates::default()).await;
    let addr = s.addr;
    let open = tokio::task::spawn_blocking(move || {
        (0..web::MAX_EVENT_CLIENTS)
            .map(|_| Events::open(addr))
            .collect::<Vec<_>>()
    })
    .await
    .unwrap();
    let (status, _, _) = tokio::task::spawn_blocking(move || get(addr, "/events"))
        .await
        .unwrap();
    assert!(status.contains(" 503"), "{status}");
    drop(open);
    // Closed streams free their places (noticed at the next write).
    let mut ok = false;
    for i in 0..100 {
        send(
            &s.tap,
            "v",
            Topic::TwinStats,
            format!(r#"{{"vessel":"v","seq":{i}}}"#),
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
        let addr = s.addr;
        let mut s = TcpStream::connect(addr).unwrap();
        write!(s, "GET /events HTTP/1.0\r\n\r\n").unwrap();
        let mut line = String::new();
        BufReader::new(s).read_line(&mut line).unwrap();
        if line.contains(" 200") {
            ok = true;
            break;
        }
    }
    assert!(ok, "places were not freed");
    s.stop.cancel();
    s.server.stopped(Duration::from_secs(5)).await;
}
