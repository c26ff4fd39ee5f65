//! The operator's web page: `twind --web` (on by default in `--demo`).
//!
//! A small read-only HTTP/1.1 server (axum on the daemon's tokio runtime)
//! that serves the page, embedded in the binary at compile time from
//! `crates/twind/web-dist/` (built from `web/`; nothing is fetched from the
//! internet at run time), and streams the daemon's outputs live. The page
//! asks nothing of any other server unless `[web] tile_url` or
//! `tile_overlay_url` name map tiles, which the browser then fetches (the
//! page's content security policy lets in their origins' images only).
//!
//! # Routes
//! - `GET /`, `GET /assets/...`, `GET /licenses/three.txt`: the page.
//! - `GET /events`: server-sent events. First a snapshot so that a new page
//!   is not blank (`hello`, then per vessel its latest `state`, `fault`,
//!   `prediction`, `stats`, `finding`, `gnss`, `actuators`, then the recent
//!   `alarm`s), then every output as the daemon publishes it, in order:
//!   `event: <state|fault|prediction|alarm|stats|finding>` and
//!   `data: <the published JSON>`. `gnss` and `actuators` carry what was
//!   measured (the JSON inputs as decoded and validated, at most 5 and 2 per
//!   second per vessel). `lagged` (`{"skipped": n}`) says that this client
//!   read too slowly and `n` events were skipped for it.
//! - `GET /api/vessels`: the latest state of every vessel (a JSON array).
//! - `GET /api/history/{vessel}`: the last ten minutes of one vessel's
//!   estimated track, fault estimates and measured fixes, one point a second
//!   of message time, to fill a page opened mid-run.
//! - `GET /api/info`: the daemon's version and the settings the page draws
//!   (decision levels, forecast horizon, the chart's tiles if any).
//! - `GET /healthz`: `ok`.
//! - `GET /metrics`: the daemon's Prometheus metrics ([`crate::metrics`]).
//!
//! # Never blocking the daemon
//! The daemon copies every output into a `tokio::sync::broadcast` channel
//! ([`crate::OutputTap`]); sending never waits. One pump task reads it into a
//! cache (latest outputs and short histories) and re-broadcasts to the page
//! clients. A client that reads too slowly lags behind its bounded queue and
//! skips events (it is told how many); a client that vanishes ends its
//! stream. At most [`MAX_EVENT_CLIENTS`] event streams are served at once.
//! The measured inputs are taken from Zenoh in a callback that never waits
//! either. Everything ends with the daemon's `CancellationToken`.

use std::collections::{HashMap, VecDeque};
use std::convert::Infallible;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use crate::settings::TileSettings;
use crate::{LatestStates, OutputEvent};
use axum::Router;
use axum::extract::{Path, State};
use axum::http::{HeaderValue, Method, StatusCode, header};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use serde::Serialize;
use tokio::sync::broadcast;
use tokio::sync::broadcast::error::RecvError;
use tokio_util::sync::CancellationToken;
use twin_wire::messages::{
    ActuatorsMessage, GnssMessage, decode_actuators_limited, decode_gnss_limited,
};
use twin_wire::outputs::{FaultMessage, StateMessage};
use twin_wire::{KeySpace, Topic};

/// Events queued per page client before it lags and skips.
pub const CLIENT_QUEUE: usize = 8192;
/// Most event streams served at once; more get 503.
pub const MAX_EVENT_CLIENTS: usize = 64;
/// Most vessels kept in the page's cache (the least recently heard go first).
pub const MAX_VESSELS: usize = 5000;
/// Most vessels with a history kept (about 45 kB each).
pub const MAX_HISTORIES: usize = 1000;
/// History points per vessel and series.
pub const HISTORY_LEN: usize = 600;
/// Message time between two history points, s.
pub const HISTORY_STEP_S: f64 = 1.0;
/// Alarms kept for new pages.
pub const ALARMS_KEPT: usize = 100;
/// Least wall-clock time between two measured fixes forwarded per vessel.
const GNSS_EVERY: Duration = Duration::from_millis(200);
/// Least wall-clock time between two measured shaft speeds forwarded per vessel.
const ACTUATORS_EVERY: Duration = Duration::from_millis(500);

/// The page, compiled in: `(path, content type, bytes)`.
pub const ASSETS: &[(&str, &str, &[u8])] = &[
    (
        "/",
        "text/html; charset=utf-8",
        include_bytes!("../web-dist/index.html"),
    ),
    (
        "/assets/app.js",
        "text/javascript; charset=utf-8",
        include_bytes!("../web-dist/assets/app.js"),
    ),
    (
        "/assets/app.css",
        "text/css; charset=utf-8",
        include_bytes!("../web-dist/assets/app.css"),
    ),
    (
        "/licenses/three.txt",
        "text/plain; charset=utf-8",
        include_bytes!("../web-dist/licenses/three.txt"),
    ),
];

/// The page's content security policy: everything from this server only,
/// and images from the configured tile servers' origins.
fn content_security_policy(tiles: Option<&TileSettings>) -> String {
    let mut img_src = String::from("'self' data: blob:");
    let urls = tiles.into_iter().flat_map(|t| [&t.url, &t.overlay_url]);
    for url in urls.flatten() {
        let origin = tile_origin(url);
        if !img_src.split(' ').any(|o| o == origin) {
            img_src.push(' ');
            img_src.push_str(origin);
        }
    }
    format!(
        "default-src 'self'; script-src 'self'; style-src 'self' 'unsafe-inline'; \
         img-src {img_src}; connect-src 'self'; object-src 'none'; base-uri 'none'; \
         frame-ancestors 'none'"
    )
}

/// `scheme://host[:port]` of a tile URL template (checked in the settings:
/// `http(s)://` and a fixed host).
fn tile_origin(url: &str) -> &str {
    let host_at = url.find("://").map_or(0, |i| i + 3);
    let end = url[host_at..]
        .find(['/', '?', '#'])
        .map_or(url.len(), |i| host_at + i);
    &url[..end]
}

/// What the page is told about the daemon (`GET /api/info`, and the `hello`
/// event).
#[derive(Debug, Clone, Serialize)]
pub struct WebInfo {
    /// `twind`.
    pub service: &'static str,
    /// The daemon's version.
    pub version: &'static str,
    /// The key prefix.
    pub prefix: String,
    /// A thruster is `suspect` above this loss.
    pub suspect_loss: f64,
    /// ... and `fault` above this one.
    pub fault_loss: f64,
    /// ... and clears below this one.
    pub clear_loss: f64,
    /// Forecast horizon, s.
    pub prediction_horizon_s: f64,
    /// Message time between forecasts, s.
    pub prediction_interval_s: f64,
    /// Message time between history points, s.
    pub history_step_s: f64,
    /// History points kept per vessel.
    pub history_len: usize,
    /// The chart's background tiles (`[web] tile_url`...), `null` for none.
    pub tiles: Option<TileSettings>,
}

impl WebInfo {
    /// From the daemon's settings.
    pub fn new(settings: &crate::settings::Settings) -> Self {
        let d = settings.twin.decision;
        Self {
            service: "twind",
            version: env!("CARGO_PKG_VERSION"),
            prefix: settings.keys.prefix().to_string(),
            suspect_loss: d.suspect_loss,
            fault_loss: d.fault_loss,
            clear_loss: d.clear_loss,
            prediction_horizon_s: settings.publish.prediction_horizon_s,
            prediction_interval_s: settings.publish.prediction_interval_s,
            history_step_s: HISTORY_STEP_S,
            history_len: HISTORY_LEN,
            tiles: settings.web.tiles.clone(),
        }
    }
}

/// Where the measured inputs come from: the daemon's own Zenoh session.
#[derive(Clone)]
pub struct InputFeed {
    /// The session.
    pub session: zenoh::Session,
    /// Key expressions.
    pub keys: KeySpace,
    /// The vessel chunk the daemon serves (`*`).
    pub own: String,
    /// Larger payloads are not read.
    pub max_payload_bytes: usize,
}

/// What the page shows.
pub struct Sources {
    /// The daemon's output tap (the server subscribes to it at once).
    pub tap: broadcast::Sender<OutputEvent>,
    /// The daemon's latest states.
    pub latest: LatestStates,
    /// The measured inputs, if wanted.
    pub inputs: Option<InputFeed>,
    /// What the page is told.
    pub info: WebInfo,
    /// The daemon's metrics, served on `/metrics`.
    pub metrics: crate::metrics::Metrics,
}

/// One event for the page.
#[derive(Debug, Clone)]
struct WebEvent {
    kind: &'static str,
    json: Arc<str>,
}

/// A history point: message time (s since the epoch) and four values.
type Point = (f64, f32, f32, f32, f32);

#[derive(Debug, Default, Serialize)]
struct History {
    /// Estimated track: time, north m, east m, sigma north m, sigma east m.
    track: VecDeque<Point>,
    /// Faults: time, port loss, port sigma, starboard loss, starboard sigma.
    faults: VecDeque<Point>,
    /// Measured fixes: time, lat deg, lon deg, sog m/s, cog rad (f32 loses
    /// ~1 m in latitude: latitude and longitude go as offsets from `origin`).
    fixes: VecDeque<Point>,
    /// The latitude and longitude the fixes' offsets are from, degrees.
    origin: Option<(f64, f64)>,
}

fn push(series: &mut VecDeque<Point>, p: Point) {
    match series.back() {
        // Time went back (a replay looped): start over.
        Some(last) if p.0 < last.0 => series.clear(),
        Some(last) if p.0 - last.0 < HISTORY_STEP_S => return,
        _ => {}
    }
    if series.len() == HISTORY_LEN {
        series.pop_front();
    }
    series.push_back(p);
}

#[derive(Default)]
struct VesselCache {
    state: Option<Arc<str>>,
    fault: Option<Arc<str>>,
    prediction: Option<Arc<str>>,
    stats: Option<Arc<str>>,
    finding: Option<Arc<str>>,
    gnss: Option<Arc<str>>,
    actuators: Option<Arc<str>>,
    history: Option<Box<History>>,
    heard: Option<Instant>,
    gnss_sent: Option<Instant>,
    actuators_sent: Option<Instant>,
}

#[derive(Default)]
struct Cache {
    vessels: HashMap<String, VesselCache>,
    alarms: VecDeque<Arc<str>>,
    histories: usize,
}

impl Cache {
    fn vessel(&mut self, vessel: &str) -> &mut VesselCache {
        if !self.vessels.contains_key(vessel) {
            if self.vessels.len() >= MAX_VESSELS {
                let oldest = self
                    .vessels
                    .iter()
                    .min_by_key(|(_, v)| v.heard)
                    .map(|(k, _)| k.clone());
                if let Some(k) = oldest
                    && let Some(gone) = self.vessels.remove(&k)
                    && gone.history.is_some()
                {
                    self.histories -= 1;
                }
            }
            let mut v = VesselCache::default();
            if self.histories < MAX_HISTORIES {
                v.history = Some(Box::default());
                self.histories += 1;
            }
            self.vessels.insert(vessel.to_string(), v);
        }
        let v = self
            .vessels
            .get_mut(vessel)
            .expect("inserted just above when missing");
        v.heard = Some(Instant::now());
        v
    }
}

fn time_s(text: &str) -> Option<f64> {
    twin_wire::time::parse_rfc3339(text).ok()
}

fn f32_or_nan(v: Option<f64>) -> f32 {
    v.map_or(f32::NAN, |v| v as f32)
}

struct Hub {
    cache: Mutex<Cache>,
    tx: broadcast::Sender<WebEvent>,
    latest: LatestStates,
    info: WebInfo,
    hello: Arc<str>,
    clients: AtomicUsize,
    skipped: AtomicU64,
}

impl Hub {
    fn ingest(&self, kind: &'static str, vessel: &str, json: Arc<str>) {
        {
            let Ok(mut cache) = self.cache.lock() else {
                return;
            };
            if kind == "alarm" {
                if cache.alarms.len() == ALARMS_KEPT {
                    cache.alarms.pop_front();
                }
                cache.alarms.push_back(json.clone());
            }
            let v = cache.vessel(vessel);
            let slot = match kind {
                "state" => Some(&mut v.state),
                "fault" => Some(&mut v.fault),
                "prediction" => Some(&mut v.prediction),
                "stats" => Some(&mut v.stats),
                "finding" => Some(&mut v.finding),
                "gnss" => Some(&mut v.gnss),
                "actuators" => Some(&mut v.actuators),
                _ => None,
            };
            if let Some(slot) = slot {
                *slot = Some(json.clone());
            }
            if let Some(h) = v.history.as_deref_mut() {
                record(h, kind, &json);
            }
        }
        // No page open: nobody to tell.
        let _ = self.tx.send(WebEvent { kind, json });
    }

    /// What a new page is sent first.
    fn snapshot(&self) -> Vec<WebEvent> {
        let mut out = vec![WebEvent {
            kind: "hello",
            json: self.hello.clone(),
        }];
        let states: HashMap<String, Arc<str>> = self
            .latest
            .snapshot()
            .into_iter()
            .map(|(k, v)| (k, Arc::from(String::from_utf8_lossy(&v).as_ref())))
            .collect();
        let Ok(cache) = self.cache.lock() else {
            return out;
        };
        let mut names: Vec<&String> = cache.vessels.keys().chain(states.keys()).collect();
        names.sort();
        names.dedup();
        for name in names {
            let v = cache.vessels.get(name);
            let state = v
                .and_then(|v| v.state.clone())
                .or_else(|| states.get(name).cloned());
            let mut put = |kind: &'static str, json: Option<Arc<str>>| {
                if let Some(json) = json {
                    out.push(WebEvent { kind, json });
                }
            };
            put("state", state);
            if let Some(v) = v {
                put("fault", v.fault.clone());
                put("prediction", v.prediction.clone());
                put("stats", v.stats.clone());
                put("finding", v.finding.clone());
                put("gnss", v.gnss.clone());
                put("actuators", v.actuators.clone());
            }
        }
        for a in &cache.alarms {
            out.push(WebEvent {
                kind: "alarm",
                json: a.clone(),
            });
        }
        out
    }

    /// Forwards a measured input of a vessel, at most so often.
    fn measured(&self, key: &str, bytes: &[u8], feed: &InputFeed) {
        let Ok((id, topic)) = feed.keys.parse(key) else {
            return;
        };
        let (kind, every) = match topic {
            Topic::Gnss => ("gnss", GNSS_EVERY),
            Topic::Actuators => ("actuators", ACTUATORS_EVERY),
            _ => return,
        };
        let now = Instant::now();
        {
            let Ok(mut cache) = self.cache.lock() else {
                return;
            };
            // Only vessels the twin already publishes: a stray sender
            // cannot fill the cache.
            let Some(v) = cache.vessels.get_mut(id.as_str()) else {
                return;
            };
            let sent = if kind == "gnss" {
                &mut v.gnss_sent
            } else {
                &mut v.actuators_sent
            };
            if sent.is_some_and(|t| now.duration_since(t) < every) {
                return;
            }
            *sent = Some(now);
        }
        #[derive(Serialize)]
        struct Measured<'a, T> {
            vessel: &'a str,
            #[serde(flatten)]
            message: T,
        }
        let json = if kind == "gnss" {
            decode_gnss_limited(bytes, feed.max_payload_bytes)
                .ok()
                .and_then(|d| GnssMessage::from_fix(&d.value, d.replay).ok())
                .and_then(|message| {
                    serde_json::to_string(&Measured {
                        vessel: id.as_str(),
                        message,
                    })
                    .ok()
                })
        } else {
            decode_actuators_limited(bytes, feed.max_payload_bytes)
                .ok()
                .and_then(|d| ActuatorsMessage::from_command(&d.value, d.replay).ok())
                .and_then(|message| {
                    serde_json::to_string(&Measured {
                        vessel: id.as_str(),
                        message,
                    })
                    .ok()
                })
        };
        if let Some(json) = json {
            self.ingest(kind, id.as_str(), json.into());
        }
    }

    fn history(&self, vessel: &str) -> Option<String> {
        let cache = self.cache.lock().ok()?;
        let h = cache.vessels.get(vessel)?.history.as_deref()?;
        #[derive(Serialize)]
        struct Out<'a> {
            vessel: &'a str,
            step_s: f64,
            #[serde(flatten)]
            history: &'a History,
        }
        serde_json::to_string(&Out {
            vessel,
            step_s: HISTORY_STEP_S,
            history: h,
        })
        .ok()
    }
}

/// Adds an output to a vessel's history, one point per [`HISTORY_STEP_S`].
fn record(h: &mut History, kind: &str, json: &str) {
    match kind {
        "state" => {
            if let Ok(s) = serde_json::from_str::<StateMessage>(json)
                && let Some(t) = time_s(&s.time)
            {
                let p = (
                    t,
                    s.north_m as f32,
                    s.east_m as f32,
                    s.sigma.north_m as f32,
                    s.sigma.east_m as f32,
                );
                push(&mut h.track, p);
            }
        }
        "fault" => {
            if let Ok(f) = serde_json::from_str::<FaultMessage>(json)
                && let Some(t) = time_s(&f.time)
            {
                let (p, s) = (&f.thrusters.port, &f.thrusters.starboard);
                let pt = (
                    t,
                    f32_or_nan(p.loss),
                    f32_or_nan(p.sigma),
                    f32_or_nan(s.loss),
                    f32_or_nan(s.sigma),
                );
                push(&mut h.faults, pt);
            }
        }
        "gnss" => {
            if let Ok(g) = serde_json::from_str::<GnssMessage>(json)
                && let Some(t) = time_s(&g.time)
            {
                let (lat0, lon0) = *h.origin.get_or_insert((g.lat_deg, g.lon_deg));
                let pt = (
                    t,
                    (g.lat_deg - lat0) as f32,
                    (g.lon_deg - lon0) as f32,
                    g.sog_mps as f32,
                    g.cog_rad as f32,
                );
                push(&mut h.fixes, pt);
            }
        }
        _ => {}
    }
}

fn kind_of(topic: Topic) -> Option<&'static str> {
    Some(match topic {
        Topic::TwinState => "state",
        Topic::TwinFault => "fault",
        Topic::TwinPrediction => "prediction",
        Topic::TwinAlarm => "alarm",
        Topic::TwinStats => "stats",
        Topic::TwinFinding => "finding",
        _ => return None,
    })
}

/// The running server.
pub struct WebServer {
    local_addr: SocketAddr,
    task: tokio::task::JoinHandle<()>,
    hub: Arc<Hub>,
    _inputs: Option<zenoh::pubsub::Subscriber<()>>,
}

impl WebServer {
    /// The address it listens on (the real port when 0 was asked).
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
    }

    /// The page's address, for people: `http://127.0.0.1:8080/` (a wildcard
    /// listen address is shown as loopback).
    pub fn url(&self) -> String {
        let mut a = self.local_addr();
        if a.ip().is_unspecified() {
            a.set_ip(std::net::Ipv4Addr::LOCALHOST.into());
        }
        format!("http://{a}/")
    }

    /// Events skipped for clients that read too slowly, in all.
    pub fn skipped(&self) -> u64 {
        self.hub.skipped.load(Ordering::Relaxed)
    }

    /// Waits for the server to stop (after the shutdown token), at most
    /// `within`; then drops whatever connection is still open.
    pub async fn stopped(self, within: Duration) {
        let abort = self.task.abort_handle();
        if tokio::time::timeout(within, self.task).await.is_err() {
            abort.abort();
        }
    }
}

/// Binds `listen` and serves the page until `shutdown` is cancelled.
pub async fn start(
    listen: SocketAddr,
    sources: Sources,
    shutdown: CancellationToken,
) -> anyhow::Result<WebServer> {
    let listener = tokio::net::TcpListener::bind(listen)
        .await
        .map_err(|e| anyhow::anyhow!("cannot serve the web page on {listen}: {e}"))?;
    let local_addr = listener.local_addr()?;
    let (tx, _) = broadcast::channel(CLIENT_QUEUE);
    let hello: Arc<str> = serde_json::to_string(&sources.info)?.into();
    let csp = HeaderValue::from_str(&content_security_policy(sources.info.tiles.as_ref()))?;
    let hub = Arc::new(Hub {
        cache: Mutex::default(),
        tx,
        latest: sources.latest,
        info: sources.info,
        hello,
        clients: AtomicUsize::new(0),
        skipped: AtomicU64::new(0),
    });

    // The pump: daemon outputs -> cache -> page clients.
    let mut rx = sources.tap.subscribe();
    let pump_hub = hub.clone();
    let pump_stop = shutdown.clone();
    tokio::spawn(async move {
        loop {
            let ev = tokio::select! {
                _ = pump_stop.cancelled() => break,
                ev = rx.recv() => ev,
            };
            match ev {
                Ok(ev) => {
                    if let Some(kind) = kind_of(ev.topic) {
                        pump_hub.ingest(kind, &ev.vessel, ev.json);
                    }
                }
                Err(RecvError::Lagged(n)) => {
                    pump_hub.skipped.fetch_add(n, Ordering::Relaxed);
                }
                Err(RecvError::Closed) => break,
            }
        }
    });

    let inputs = match sources.inputs {
        Some(feed) => {
            let expr = format!("{}/{}/*", feed.keys.prefix(), feed.own);
            let feed_hub = hub.clone();
            let session = feed.session.clone();
            let sub = session
                .declare_subscriber(expr.clone())
                .callback(move |sample| {
                    let bytes = sample.payload().to_bytes();
                    if bytes.len() <= feed.max_payload_bytes {
                        feed_hub.measured(sample.key_expr().as_str(), &bytes, &feed);
                    }
                })
                .await
                .map_err(|e| anyhow::anyhow!("cannot subscribe to {expr}: {e}"))?;
            Some(sub)
        }
        None => None,
    };

    let app = Router::new()
        .route("/events", get(events))
        .route("/api/vessels", get(vessels))
        .route("/api/history/{vessel}", get(history))
        .route("/api/info", get(info))
        .route("/healthz", get(|| async { "ok" }))
        .route("/metrics", get(metrics))
        .fallback(asset)
        .with_state(AppState {
            hub: hub.clone(),
            csp,
            shutdown: shutdown.clone(),
            metrics: sources.metrics,
        })
        .layer(axum::middleware::map_response(common_headers));
    let task = tokio::spawn(async move {
        let serve = axum::serve(listener, app).with_graceful_shutdown(shutdown.cancelled_owned());
        if let Err(e) = serve.await {
            tracing::warn!("web page server: {e}");
        }
    });
    tracing::info!(%local_addr, "web page served");
    Ok(WebServer {
        local_addr,
        task,
        hub,
        _inputs: inputs,
    })
}

#[derive(Clone)]
struct AppState {
    hub: Arc<Hub>,
    /// The page's content security policy.
    csp: HeaderValue,
    shutdown: CancellationToken,
    metrics: crate::metrics::Metrics,
}

async fn common_headers(mut r: Response) -> Response {
    let h = r.headers_mut();
    h.insert(
        header::X_CONTENT_TYPE_OPTIONS,
        HeaderValue::from_static("nosniff"),
    );
    h.insert(
        header::REFERRER_POLICY,
        HeaderValue::from_static("no-referrer"),
    );
    r
}

fn json_response(body: String) -> Response {
    (
        [
            (header::CONTENT_TYPE, "application/json"),
            (header::CACHE_CONTROL, "no-store"),
        ],
        body,
    )
        .into_response()
}

async fn asset(State(app): State<AppState>, method: Method, uri: axum::http::Uri) -> Response {
    if method != Method::GET && method != Method::HEAD {
        return (StatusCode::METHOD_NOT_ALLOWED, "read-only\n").into_response();
    }
    let path = match uri.path() {
        "/index.html" => "/",
        p => p,
    };
    match ASSETS.iter().find(|(p, _, _)| *p == path) {
        Some((_, mime, bytes)) => {
            let mut r = (
                [
                    (header::CONTENT_TYPE, *mime),
                    // The names carry no hash: always revalidate.
                    (header::CACHE_CONTROL, "no-cache"),
                ],
                *bytes,
            )
                .into_response();
            if path == "/" {
                r.headers_mut()
                    .insert(header::CONTENT_SECURITY_POLICY, app.csp.clone());
            }
            r
        }
        None => (StatusCode::NOT_FOUND, "not found\n").into_response(),
    }
}

async fn vessels(State(app): State<AppState>) -> Response {
    let items = app.hub.latest.snapshot();
    let mut body = String::from("[");
    for (i, (_, json)) in items.iter().enumerate() {
        if i > 0 {
            body.push(',');
        }
        body.push_str(&String::from_utf8_lossy(json));
    }
    body.push(']');
    json_response(body)
}

async fn history(State(app): State<AppState>, Path(vessel): Path<String>) -> Response {
    match app.hub.history(&vessel) {
        Some(body) => json_response(body),
        None => (StatusCode::NOT_FOUND, "no such vessel\n").into_response(),
    }
}

/// The daemon's metrics and the page's own (events skipped).
async fn metrics(State(app): State<AppState>) -> Response {
    let mut text = app.metrics.render();
    crate::metrics::counter(
        &mut text,
        "twind_page_events_skipped_total",
        "Events of the web page skipped for pages that read too slowly.",
        app.hub.skipped.load(Ordering::Relaxed),
    );
    (
        [
            (header::CONTENT_TYPE, crate::metrics::CONTENT_TYPE),
            (header::CACHE_CONTROL, "no-store"),
        ],
        text,
    )
        .into_response()
}

async fn info(State(app): State<AppState>) -> Response {
    json_response(serde_json::to_string(&app.hub.info).unwrap_or_default())
}

/// Counts open event streams; the count goes down when the stream is dropped.
struct ClientSlot(Arc<Hub>);

impl Drop for ClientSlot {
    fn drop(&mut self) {
        self.0.clients.fetch_sub(1, Ordering::Relaxed);
    }
}

struct Stream {
    snapshot: std::vec::IntoIter<WebEvent>,
    rx: broadcast::Receiver<WebEvent>,
    shutdown: CancellationToken,
    slot: ClientSlot,
}

fn sse_event(ev: &WebEvent) -> Event {
    Event::default().event(ev.kind).data(&*ev.json)
}

async fn events(State(app): State<AppState>) -> Response {
    let hub = app.hub;
    if hub.clients.fetch_add(1, Ordering::Relaxed) >= MAX_EVENT_CLIENTS {
        hub.clients.fetch_sub(1, Ordering::Relaxed);
        return (StatusCode::SERVICE_UNAVAILABLE, "too many pages open\n").into_response();
    }
    // Subscribe before the snapshot: nothing falls between the two (an
    // event may come twice, which the page does not mind).
    let rx = hub.tx.subscribe();
    let snapshot = hub.snapshot().into_iter();
    let st = Stream {
        snapshot,
        rx,
        shutdown: app.shutdown,
        slot: ClientSlot(hub),
    };
    let stream = futures_util::stream::unfold(st, |mut st| async move {
        if let Some(ev) = st.snapshot.next() {
            return Some((Ok::<_, Infallible>(sse_event(&ev)), st));
        }
        let ev = tokio::select! {
            _ = st.shutdown.cancelled() => return None,
            ev = st.rx.recv() => ev,
        };
        let event = match ev {
            Ok(ev) => sse_event(&ev),
            Err(RecvError::Lagged(n)) => {
                st.slot.0.skipped.fetch_add(n, Ordering::Relaxed);
                Event::default()
                    .event("lagged")
                    .data(format!("{{\"skipped\":{n}}}"))
            }
            Err(RecvError::Closed) => return None,
        };
        Some((Ok(event), st))
    });
    Sse::new(stream)
        .keep_alive(KeepAlive::new().interval(Duration::from_secs(10)))
        .into_response()
}
