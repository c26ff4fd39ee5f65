//! A fleet on the web page: many vessels published through Zenoh to a real
//! `twind --web-listen`, checked at the page's API and event stream.
//!
//! The fleet is the demo's simulated trial (`twind::demo::OTTER_TRIAL`: GNSS
//! at 5 Hz with heading, shaft speeds at 10 Hz, a 25 % port-propeller loss)
//! replayed at its recorded pace under many vessel ids, each on its own spot
//! of a 250 m grid, started at a different point of the trial, with message
//! times from the wall clock, and every other vessel mirrored east-west with
//! its shafts swapped (so that it has lost starboard thrust instead).
//!
//! `fleet_publisher` (ignored) is the publisher of the browser test
//! `web/tests/fleet.test.js`, which runs this test binary with
//! `--ignored --exact fleet_publisher` and `TWIN_FLEET_CONNECT` (a Zenoh
//! endpoint of the daemon), `TWIN_FLEET_VESSELS` (default 100) and
//! `TWIN_FLEET_SECONDS` (default 60, at most 180).

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use twin_tests::net::{config, free_port};
use twin_wire::time::{format_rfc3339, parse_rfc3339};
use zenoh::qos::CongestionControl;

/// One line of the trial.
struct Record {
    t: f64,
    gnss: bool,
    value: serde_json::Value,
}

fn trial() -> Vec<Record> {
    std::str::from_utf8(twind::demo::OTTER_TRIAL)
        .expect("the trial is text")
        .lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let mut value: serde_json::Value = serde_json::from_str(l).expect("JSON lines");
            let obj = value.as_object_mut().unwrap();
            let kind = obj.remove("type").expect("a type");
            let t = parse_rfc3339(obj["time"].as_str().unwrap()).unwrap();
            Record {
                t,
                gnss: kind == "gnss",
                value,
            }
        })
        .collect()
}

/// Trial seconds skipped by the vessel `i` (so the fleet is not in step).
fn start_offset_s(i: usize) -> f64 {
    ((i * 7) % 110) as f64
}

/// The trial's record as vessel `i` sends it: moved to its grid spot,
/// mirrored for odd `i`, at message time `time_s`.
fn message(r: &Record, i: usize, origin: (f64, f64), time_s: f64) -> Vec<u8> {
    let mut v = r.value.clone();
    v["time"] = format_rfc3339(time_s).unwrap().into();
    let mirrored = i % 2 == 1;
    if r.gnss {
        let (lat0, lon0) = origin;
        let m_per_deg = 111_320.0;
        let north = (i / 10) as f64 * 250.0;
        let east = (i % 10) as f64 * 250.0;
        let lat = v["lat_deg"].as_f64().unwrap();
        let mut lon = v["lon_deg"].as_f64().unwrap();
        if mirrored {
            lon = lon0 - (lon - lon0);
            for k in ["cog_rad", "heading_rad"] {
                if let Some(a) = v[k].as_f64() {
                    v[k] = (-a).rem_euclid(std::f64::consts::TAU).into();
                }
            }
        }
        v["lat_deg"] = (lat + north / m_per_deg).into();
        v["lon_deg"] = (lon + east / (m_per_deg * lat0.to_radians().cos())).into();
    } else if mirrored && let Some(rpm) = v.get_mut("rpm") {
        let (p, s) = (rpm["port"].clone(), rpm["starboard"].clone());
        rpm["port"] = s;
        rpm["starboard"] = p;
    }
    serde_json::to_vec(&v).unwrap()
}

/// Publishes `vessels` vessels for `seconds` through `session`, in real
/// time; returns the messages published.
async fn publish_fleet(session: &zenoh::Session, vessels: usize, seconds: f64) -> u64 {
    let records = trial();
    let t_first = records[0].t;
    let origin = records
        .iter()
        .find(|r| r.gnss)
        .map(|r| {
            (
                r.value["lat_deg"].as_f64().unwrap(),
                r.value["lon_deg"].as_f64().unwrap(),
            )
        })
        .unwrap();
    let mut publishers = Vec::new();
    for i in 0..vessels {
        let declare = |topic: &str| {
            session
                .declare_publisher(format!("asv/fleet-{i:03}/{topic}"))
                .congestion_control(CongestionControl::Block)
        };
        publishers.push((
            declare("gnss").await.unwrap(),
            declare("actuators").await.unwrap(),
        ));
    }
    twin_tests::wire::wait_matching(&publishers[0].0, Duration::from_secs(20)).await;
    twin_tests::wire::wait_matching(&publishers[0].1, Duration::from_secs(20)).await;
    let wall0 = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap()
        .as_secs_f64();
    let mut cursor: Vec<usize> = (0..vessels)
        .map(|i| {
            records
                .iter()
                .position(|r| r.t - t_first >= start_offset_s(i))
                .unwrap_or(records.len())
        })
        .collect();
    let started = Instant::now();
    let mut sent = 0u64;
    loop {
        let elapsed = started.elapsed().as_secs_f64();
        if elapsed > seconds {
            break;
        }
        for (i, (gnss, act)) in publishers.iter().enumerate() {
            let t_start = t_first + start_offset_s(i);
            while let Some(r) = records.get(cursor[i]) {
                if r.t - t_start > elapsed {
                    break;
                }
                let bytes = message(r, i, origin, wall0 + (r.t - t_start));
                let p = if r.gnss { gnss } else { act };
                p.put(bytes).await.expect("put");
                cursor[i] += 1;
                sent += 1;
            }
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    sent
}

fn env_or<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[ignore = "the fleet publisher of web/tests/fleet.test.js, which runs it"]
async fn fleet_publisher() {
    let connect = std::env::var("TWIN_FLEET_CONNECT")
        .expect("TWIN_FLEET_CONNECT: the daemon's Zenoh endpoint");
    let vessels: usize = env_or("TWIN_FLEET_VESSELS", 100);
    let seconds: f64 = env_or("TWIN_FLEET_SECONDS", 60.0f64).min(180.0);
    let mut c = zenoh::Config::default();
    c.insert_json5("mode", "\"peer\"").unwrap();
    c.insert_json5("connect/endpoints", &format!("[\"{connect}\"]"))
        .unwrap();
    c.insert_json5("scouting/multicast/enabled", "false")
        .unwrap();
    let session = zenoh::open(c).await.expect("a Zenoh session");
    println!("fleet: publishing {vessels} vessels for {seconds} s to {connect}");
    let started = Instant::now();
    let sent = publish_fleet(&session, vessels, seconds).await;
    println!(
        "fleet: published {sent} messages in {:.1} s ({:.0} per second)",
        started.elapsed().as_secs_f64(),
        sent as f64 / started.elapsed().as_secs_f64()
    );
    session.close().await.unwrap();
}

/// twind with the page on a free port, its Zenoh on `port`; its page URL.
fn start_twind(port: u16) -> (Child, SocketAddr) {
    let dir = std::env::temp_dir().join(format!("twind-web-fleet-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_twind"))
        .args(["--mode", "peer", "--no-multicast-scouting"])
        .args(["--listen", &format!("tcp/127.0.0.1:{port}")])
        .args(["--web-listen", "127.0.0.1:0"])
        .current_dir(&dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("twind starts");
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let addr = loop {
        let line = lines.next().expect("twind prints its page's URL").unwrap();
        if let Some(url) = line.strip_prefix("twind web page: http://") {
            break url.trim_end_matches('/').parse().unwrap();
        }
    };
    // Keep draining stdout so that twind never blocks on it.
    std::thread::spawn(move || for _ in lines {});
    (child, addr)
}

fn get(addr: SocketAddr, path: &str) -> Vec<u8> {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    write!(s, "GET {path} HTTP/1.0\r\nHost: test\r\n\r\n").unwrap();
    let mut raw = Vec::new();
    s.read_to_end(&mut raw).unwrap();
    let split = raw.windows(4).position(|w| w == b"\r\n\r\n").unwrap();
    assert!(raw.starts_with(b"HTTP/1.0 200") || raw.starts_with(b"HTTP/1.1 200"));
    raw[split + 4..].to_vec()
}

/// The event names and vessels of the first `secs` of `/events`.
fn events_for(addr: SocketAddr, secs: u64) -> Vec<(String, String)> {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(secs))).unwrap();
    write!(s, "GET /events HTTP/1.0\r\nHost: test\r\n\r\n").unwrap();
    let mut out = Vec::new();
    let mut name = String::new();
    let deadline = Instant::now() + Duration::from_secs(secs);
    for line in BufReader::new(s).lines() {
        let Ok(line) = line else { break };
        if let Some(n) = line.strip_prefix("event: ") {
            name = n.to_string();
        } else if let Some(d) = line.strip_prefix("data: ") {
            let v: serde_json::Value = serde_json::from_str(d).unwrap_or_default();
            out.push((name.clone(), v["vessel"].as_str().unwrap_or("").to_string()));
        }
        if Instant::now() > deadline {
            break;
        }
    }
    out
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_fleet_published_through_zenoh_reaches_the_page() {
    let port = free_port();
    let (mut daemon, web) = start_twind(port);
    let session = zenoh::open(config("peer", &[], &[port])).await.unwrap();
    let vessels = 20;
    let sent = publish_fleet(&session, vessels, 5.0).await;
    assert!(sent > 20 * 5 * 10, "published {sent}");
    tokio::time::sleep(Duration::from_millis(500)).await;

    let states: serde_json::Value = serde_json::from_slice(
        &tokio::task::spawn_blocking(move || get(web, "/api/vessels"))
            .await
            .unwrap(),
    )
    .unwrap();
    let states = states.as_array().unwrap();
    assert_eq!(states.len(), vessels, "{states:?}");
    assert!(
        states
            .iter()
            .all(|s| s["vessel"].as_str().unwrap().starts_with("fleet-"))
    );

    // A new page gets every vessel's latest outputs, and what was measured.
    let events = tokio::task::spawn_blocking(move || events_for(web, 2))
        .await
        .unwrap();
    let of = |kind: &str| -> std::collections::BTreeSet<String> {
        events
            .iter()
            .filter(|(k, _)| k == kind)
            .map(|(_, v)| v.clone())
            .collect()
    };
    assert_eq!(events[0].0, "hello");
    for kind in ["state", "fault", "gnss", "actuators"] {
        assert_eq!(of(kind).len(), vessels, "{kind}: {:?}", of(kind));
    }
    let history: serde_json::Value = serde_json::from_slice(
        &tokio::task::spawn_blocking(move || get(web, "/api/history/fleet-007"))
            .await
            .unwrap(),
    )
    .unwrap();
    assert!(history["track"].as_array().unwrap().len() >= 3, "{history}");
    assert!(history["fixes"].as_array().unwrap().len() >= 3, "{history}");

    session.close().await.unwrap();
    let status = Command::new("kill")
        .args(["-TERM", &daemon.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let deadline = Instant::now() + Duration::from_secs(20);
    let exit = loop {
        if let Some(s) = daemon.try_wait().unwrap() {
            break s;
        }
        assert!(Instant::now() < deadline, "twind did not stop on SIGTERM");
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(exit.success(), "twind exited with {exit}");
}
