//! Signal K output: the twin's estimates pushed to a Signal K server as
//! deltas over its WebSocket stream, under the twin's own `$source`, for
//! the chart plotters, displays and alarm panels already on the boat.
//!
//! Enabled by a `[signalk]` section of the settings (`url`, optional
//! `token`, `source`, `self_vessel`, `contexts`). Fed by the same outputs
//! the daemon publishes on Zenoh (its output tap): from each `twin/state`
//! (not stale) the estimated position, SOG, COG, heading where estimated
//! and the water current as set and drift; from each `twin/fault` the
//! health of each propeller as a notification
//! (`notifications.propulsion.{port,starboard}.thrustLoss`: `nominal` and
//! `not_excited` are `normal`, `suspect` is `warn`, `fault` is `alarm`),
//! sent when a state changes and at least every `notification_interval_s`
//! of message time, and again after every reconnection.
//!
//! Each vessel id maps to a Signal K context: `self_vessel` to
//! `vessels.self` (the server's own boat), the ids of `contexts` to the
//! context given there (`vessels.urn:mrn:imo:mmsi:...`); the outputs of
//! other vessels are not pushed (counted as `unmapped_vessel`).
//!
//! The pusher runs on a task of its own: a server that is down, slow or
//! refuses never blocks or crashes the daemon. It reconnects with
//! exponential backoff; what cannot be sent is counted by reason
//! ([`SignalkStats`]) and logged at most once a minute.

use std::collections::{BTreeMap, HashMap};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use futures_util::{SinkExt, StreamExt};
use serde::Deserialize;
use serde_json::{Value, json};
use tokio::sync::broadcast;
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use tokio_util::sync::CancellationToken;
use twin_wire::Topic;
use twin_wire::outputs::{
    FaultMessage, ProfileMismatchMessage, StateMessage, ThrusterMessage, ThrusterStatusName,
};

use crate::settings::SettingsError;
use crate::stats::{LOG_EVERY, RateLimit};
use crate::{OutputEvent, OutputTap};

/// Events the daemon may be ahead of the pusher before the pusher skips
/// some (counted as `lagged`).
const TAP_CAPACITY: usize = 16_384;

/// How long a connection attempt may take.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(10);

/// `[signalk]` as written in the settings file.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawSignalk {
    url: Option<String>,
    token: Option<String>,
    source: Option<String>,
    self_vessel: Option<String>,
    contexts: Option<BTreeMap<String, String>>,
    reconnect_min_s: Option<f64>,
    reconnect_max_s: Option<f64>,
    notification_interval_s: Option<f64>,
}

/// Where and how the estimates go to a Signal K server.
#[derive(Debug, Clone, PartialEq)]
pub struct SignalkSettings {
    /// The server's WebSocket stream, `ws://HOST:PORT/signalk/v1/stream?subscribe=none`.
    pub url: String,
    /// An access token, sent as `Authorization: Bearer` (a server with
    /// security on needs one with write permission).
    pub token: Option<String>,
    /// The `$source` of every update.
    pub source: String,
    /// The vessel id whose context is `vessels.self`.
    pub self_vessel: Option<String>,
    /// Other vessel ids and their contexts (`vessels.urn:mrn:...`).
    pub contexts: BTreeMap<String, String>,
    /// The first wait before a reconnection, s (doubled up to the maximum).
    pub reconnect_min_s: f64,
    /// The longest wait between reconnections, s.
    pub reconnect_max_s: f64,
    /// Unchanged notifications are sent again after this much message time, s.
    pub notification_interval_s: f64,
}

fn invalid(key: &'static str, reason: String) -> SettingsError {
    SettingsError::Invalid { key, reason }
}

fn positive(key: &'static str, v: f64) -> Result<f64, SettingsError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(invalid(key, format!("must be a positive number, got {v}")))
    }
}

impl SignalkSettings {
    /// Validates the raw section.
    pub fn from_raw(raw: RawSignalk) -> Result<Self, SettingsError> {
        let url = raw.url.ok_or_else(|| {
            invalid(
                "signalk.url",
                "missing: the server's stream, e.g. ws://127.0.0.1:3000/signalk/v1/stream?subscribe=none".into(),
            )
        })?;
        if !url.starts_with("ws://") || url.as_str().into_client_request().is_err() {
            return Err(invalid(
                "signalk.url",
                format!("{url:?} is not a ws:// URL (wss:// is not supported)"),
            ));
        }
        let source = raw.source.unwrap_or_else(|| "usv-twin".to_string());
        if source.is_empty()
            || !source
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c))
        {
            return Err(invalid(
                "signalk.source",
                format!("{source:?}: letters, digits, '-', '_' and '.' only"),
            ));
        }
        let mut contexts = BTreeMap::new();
        for (id, context) in raw.contexts.unwrap_or_default() {
            twin_wire::keys::validate_vessel_id(&id)
                .map_err(|e| invalid("signalk.contexts", format!("{id:?}: {e}")))?;
            let context = if context.starts_with("vessels.") {
                context
            } else {
                format!("vessels.{context}")
            };
            contexts.insert(id, context);
        }
        if let Some(id) = &raw.self_vessel {
            twin_wire::keys::validate_vessel_id(id)
                .map_err(|e| invalid("signalk.self_vessel", format!("{id:?}: {e}")))?;
        }
        if raw.self_vessel.is_none() && contexts.is_empty() {
            return Err(invalid(
                "signalk.self_vessel",
                "name the vessel the server is on (or give `contexts`): no vessel would be pushed"
                    .into(),
            ));
        }
        let reconnect_min_s = positive(
            "signalk.reconnect_min_s",
            raw.reconnect_min_s.unwrap_or(1.0),
        )?;
        let reconnect_max_s = positive(
            "signalk.reconnect_max_s",
            raw.reconnect_max_s.unwrap_or(30.0),
        )?;
        if reconnect_max_s < reconnect_min_s {
            return Err(invalid(
                "signalk.reconnect_max_s",
                format!("{reconnect_max_s} is below reconnect_min_s {reconnect_min_s}"),
            ));
        }
        Ok(Self {
            url,
            token: raw.token,
            source,
            self_vessel: raw.self_vessel,
            contexts,
            reconnect_min_s,
            reconnect_max_s,
            notification_interval_s: positive(
                "signalk.notification_interval_s",
                raw.notification_interval_s.unwrap_or(5.0),
            )?,
        })
    }

    /// The Signal K context of `vessel`, if it is pushed.
    pub fn context(&self, vessel: &str) -> Option<&str> {
        if self.self_vessel.as_deref() == Some(vessel) {
            return Some("vessels.self");
        }
        self.contexts.get(vessel).map(String::as_str)
    }
}

/// What the pusher did.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SignalkStats {
    /// Connections made.
    pub connects: u64,
    /// Connection attempts that failed.
    pub connect_failures: u64,
    /// Deltas written to the server.
    pub deltas_sent: u64,
    /// Outputs or deltas not sent, per reason: `disconnected` (no
    /// connection then), `lagged` (the pusher fell behind the daemon),
    /// `send_failed` (the connection broke while writing),
    /// `unmapped_vessel` (no context for the vessel), `undecodable` (an
    /// output that did not parse).
    pub dropped: BTreeMap<String, u64>,
}

impl SignalkStats {
    fn drop_some(&mut self, reason: &str, n: u64) {
        *self.dropped.entry(reason.to_string()).or_default() += n;
    }
}

/// A Signal K alarm state for a propeller's status.
pub fn alarm_state(status: ThrusterStatusName) -> &'static str {
    match status {
        ThrusterStatusName::NotExcited | ThrusterStatusName::Nominal => "normal",
        ThrusterStatusName::Suspect => "warn",
        ThrusterStatusName::Fault => "alarm",
    }
}

fn status_name(status: ThrusterStatusName) -> &'static str {
    match status {
        ThrusterStatusName::NotExcited => "not excited",
        ThrusterStatusName::Nominal => "nominal",
        ThrusterStatusName::Suspect => "suspect",
        ThrusterStatusName::Fault => "fault",
    }
}

/// The notification value of one propeller: `state`, `method` (`visual`
/// and `sound` for an alarm, `visual` for a warning) and a `message` with
/// the loss and its standard deviation, and, where the profile does not
/// describe the vessel (`mismatch`), that the comparison of the
/// propellers is withheld and why.
pub fn thrust_notification(
    side: &str,
    t: &ThrusterMessage,
    mismatch: Option<&ProfileMismatchMessage>,
) -> Value {
    let state = alarm_state(t.status);
    let method: &[&str] = match state {
        "alarm" => &["visual", "sound"],
        "warn" => &["visual"],
        _ => &[],
    };
    let loss = match (t.loss, t.sigma) {
        (Some(l), Some(s)) => format!("loss {:.0} % (sigma {:.0} %)", l * 100.0, s * 100.0),
        (Some(l), None) => format!("loss {:.0} %", l * 100.0),
        (None, _) => "loss unknown".to_string(),
    };
    let mut message = match t.status {
        ThrusterStatusName::NotExcited => {
            format!("{side} thruster: not excited, the data do not tell its loss yet ({loss})")
        }
        other => format!("{side} thruster {}: {loss}", status_name(other)),
    };
    if let Some(m) = mismatch {
        message.push_str(&format!(
            "; comparison withheld, the profile does not describe this vessel ({m})"
        ));
    }
    json!({ "state": state, "method": method, "message": message })
}

/// An angle in [0, 2 pi).
fn compass_rad(rad: f64) -> f64 {
    rad.rem_euclid(std::f64::consts::TAU)
}

fn delta(context: &str, source: &str, timestamp: &str, values: Vec<Value>) -> Value {
    json!({
        "context": context,
        "updates": [{ "$source": source, "timestamp": timestamp, "values": values }],
    })
}

/// The delta of a state: position, SOG, COG, heading where estimated, the
/// water current as set (the direction it flows toward, true) and drift.
pub fn state_delta(context: &str, source: &str, s: &StateMessage) -> Value {
    let mut values = vec![
        json!({ "path": "navigation.position",
                "value": { "latitude": s.lat_deg, "longitude": s.lon_deg } }),
        json!({ "path": "navigation.speedOverGround", "value": s.sog_mps }),
        json!({ "path": "navigation.courseOverGroundTrue", "value": compass_rad(s.cog_rad) }),
    ];
    if let Some(h) = s.heading_rad.filter(|h| h.is_finite()) {
        values.push(json!({ "path": "navigation.headingTrue", "value": compass_rad(h) }));
    }
    if let Some(c) = &s.current {
        values.push(json!({
            "path": "environment.current",
            "value": {
                "setTrue": compass_rad(c.east_mps.atan2(c.north_mps)),
                "drift": c.speed_mps,
            },
        }));
    }
    delta(context, source, &s.time, values)
}

/// The delta of both propellers' notifications.
pub fn fault_delta(context: &str, source: &str, f: &FaultMessage) -> Value {
    let values = [
        ("port", &f.thrusters.port),
        ("starboard", &f.thrusters.starboard),
    ]
    .into_iter()
    .map(|(side, t)| {
        json!({
            "path": format!("notifications.propulsion.{side}.thrustLoss"),
            "value": thrust_notification(side, t, f.profile_mismatch.as_ref()),
        })
    })
    .collect();
    delta(context, source, &f.time, values)
}

/// The last notifications sent for a vessel.
#[derive(Debug)]
struct Notified {
    states: [ThrusterStatusName; 2],
    /// Whether the comparison was withheld (`profile_mismatch`).
    withheld: bool,
    time_s: f64,
    delta: String,
}

/// Outputs to deltas, with the notifications' throttle.
#[derive(Debug)]
struct DeltaMapper {
    settings: SignalkSettings,
    notified: HashMap<String, Notified>,
}

/// What one output becomes.
#[derive(Debug, PartialEq)]
enum Mapped {
    /// A delta to send.
    Delta(String),
    /// Nothing to send (a stale state, an unchanged notification, another topic).
    Nothing,
    /// Not sent, for this reason.
    Dropped(&'static str),
}

impl DeltaMapper {
    fn new(settings: SignalkSettings) -> Self {
        Self {
            settings,
            notified: HashMap::new(),
        }
    }

    fn map(&mut self, ev: &OutputEvent) -> Mapped {
        if !matches!(ev.topic, Topic::TwinState | Topic::TwinFault) {
            return Mapped::Nothing;
        }
        let Some(context) = self.settings.context(&ev.vessel) else {
            return Mapped::Dropped("unmapped_vessel");
        };
        let source = &self.settings.source;
        if ev.topic == Topic::TwinState {
            return match serde_json::from_str::<StateMessage>(&ev.json) {
                Ok(s) if s.stale => Mapped::Nothing,
                Ok(s) => Mapped::Delta(state_delta(context, source, &s).to_string()),
                Err(_) => Mapped::Dropped("undecodable"),
            };
        }
        let Ok(f) = serde_json::from_str::<FaultMessage>(&ev.json) else {
            return Mapped::Dropped("undecodable");
        };
        let time_s = twin_wire::time::parse_rfc3339(&f.time).unwrap_or(f64::NAN);
        let states = [f.thrusters.port.status, f.thrusters.starboard.status];
        let withheld = f.profile_mismatch.is_some();
        let due = self.notified.get(&ev.vessel).is_none_or(|last| {
            // A time that does not compare (NaN) makes it due too.
            let recent = time_s - last.time_s < self.settings.notification_interval_s;
            last.states.map(alarm_state) != states.map(alarm_state)
                || last.withheld != withheld
                || !recent
        });
        if !due {
            return Mapped::Nothing;
        }
        let delta = fault_delta(context, source, &f).to_string();
        self.notified.insert(
            ev.vessel.clone(),
            Notified {
                states,
                withheld,
                time_s,
                delta: delta.clone(),
            },
        );
        Mapped::Delta(delta)
    }

    /// The last notifications of every vessel, to send again after a
    /// reconnection.
    fn notifications(&self) -> Vec<String> {
        self.notified.values().map(|n| n.delta.clone()).collect()
    }
}

/// The pusher's counters, shared with whoever asks.
#[derive(Debug, Clone)]
struct Counters {
    stats: Arc<Mutex<SignalkStats>>,
    log: Arc<Mutex<RateLimit>>,
}

impl Counters {
    fn new() -> Self {
        Self {
            stats: Arc::default(),
            log: Arc::new(Mutex::new(RateLimit::new(LOG_EVERY, 1))),
        }
    }

    fn update(&self, f: impl FnOnce(&mut SignalkStats)) {
        if let Ok(mut s) = self.stats.lock() {
            f(&mut s);
        }
    }

    fn snapshot(&self) -> SignalkStats {
        self.stats.lock().map(|s| s.clone()).unwrap_or_default()
    }

    /// Logs a connection problem at most once a minute.
    fn warn(&self, url: &str, what: &str) {
        let passed = self
            .log
            .lock()
            .ok()
            .and_then(|mut l| l.check(Instant::now()));
        if let Some(not_logged) = passed {
            let s = self.snapshot();
            tracing::warn!(
                url,
                not_logged,
                connect_failures = s.connect_failures,
                dropped = ?s.dropped,
                "Signal K: {what}"
            );
        }
    }
}

/// The running pusher.
#[derive(Debug)]
pub struct SignalkOutput {
    stop: CancellationToken,
    task: tokio::task::JoinHandle<()>,
    counters: Counters,
}

impl SignalkOutput {
    /// Starts pushing what `events` carries to the server of `settings`.
    pub fn start(settings: SignalkSettings, events: broadcast::Receiver<OutputEvent>) -> Self {
        let stop = CancellationToken::new();
        let counters = Counters::new();
        let task = tokio::spawn(push(settings, events, stop.clone(), counters.clone()));
        Self {
            stop,
            task,
            counters,
        }
    }

    /// What it did so far.
    pub fn stats(&self) -> SignalkStats {
        self.counters.snapshot()
    }

    /// Sends what is queued (if connected), closes the connection and
    /// returns what it did; gives up after `within`.
    pub async fn finish(self, within: Duration) -> SignalkStats {
        self.stop.cancel();
        let mut task = self.task;
        if tokio::time::timeout(within, &mut task).await.is_err() {
            task.abort();
            tracing::warn!("Signal K: the last deltas were not sent within {within:?}");
        }
        let stats = self.counters.snapshot();
        tracing::info!(
            connects = stats.connects,
            deltas_sent = stats.deltas_sent,
            dropped = ?stats.dropped,
            "Signal K output stopped"
        );
        stats
    }
}

/// Starts the Signal K output when the settings ask for it, on `tap` (made
/// if there is none); the tap to give the daemon.
pub fn attach(
    settings: Option<&SignalkSettings>,
    tap: OutputTap,
) -> (OutputTap, Option<SignalkOutput>) {
    let Some(settings) = settings else {
        return (tap, None);
    };
    let tap = tap.unwrap_or_else(|| broadcast::channel(TAP_CAPACITY).0);
    let output = SignalkOutput::start(settings.clone(), tap.subscribe());
    tracing::info!(url = %settings.url, "Signal K output on");
    (Some(tap), Some(output))
}

type Socket =
    tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

async fn connect(settings: &SignalkSettings) -> Result<Socket, String> {
    let mut request = settings
        .url
        .as_str()
        .into_client_request()
        .map_err(|e| e.to_string())?;
    if let Some(token) = &settings.token {
        let value = format!("Bearer {token}")
            .parse()
            .map_err(|_| "the token is not a valid header value".to_string())?;
        request.headers_mut().insert("Authorization", value);
    }
    match tokio::time::timeout(CONNECT_TIMEOUT, tokio_tungstenite::connect_async(request)).await {
        Ok(Ok((socket, _))) => Ok(socket),
        Ok(Err(e)) => Err(e.to_string()),
        Err(_) => Err(format!("no connection within {CONNECT_TIMEOUT:?}")),
    }
}

/// How a connection ended.
enum Ended {
    /// Asked to stop (or the daemon's tap closed).
    Stopped,
    /// The connection broke.
    Lost(String),
}

async fn push(
    settings: SignalkSettings,
    mut events: broadcast::Receiver<OutputEvent>,
    stop: CancellationToken,
    counters: Counters,
) {
    let mut mapper = DeltaMapper::new(settings.clone());
    let mut backoff_s = settings.reconnect_min_s;
    while !stop.is_cancelled() {
        let attempt = tokio::select! {
            _ = stop.cancelled() => break,
            r = connect(&settings) => r,
        };
        match attempt {
            Ok(mut socket) => {
                counters.update(|s| s.connects += 1);
                tracing::info!(url = %settings.url, "Signal K: connected");
                backoff_s = settings.reconnect_min_s;
                match pump(&mut socket, &mut events, &mut mapper, &stop, &counters).await {
                    Ended::Stopped => {
                        let _ = socket.close(None).await;
                        break;
                    }
                    Ended::Lost(e) => {
                        counters.warn(&settings.url, &format!("connection lost: {e}"))
                    }
                }
            }
            Err(e) => {
                counters.update(|s| s.connect_failures += 1);
                counters.warn(&settings.url, &format!("cannot connect: {e}"));
            }
        }
        let wait = Duration::from_secs_f64(backoff_s);
        if wait_disconnected(wait, &mut events, &mut mapper, &stop, &counters).await {
            break;
        }
        backoff_s = (backoff_s * 2.0).min(settings.reconnect_max_s);
    }
}

/// Counts what arrives while there is no connection (the notifications
/// are still noted, to be sent on reconnection) for `wait`; true when
/// asked to stop.
async fn wait_disconnected(
    wait: Duration,
    events: &mut broadcast::Receiver<OutputEvent>,
    mapper: &mut DeltaMapper,
    stop: &CancellationToken,
    counters: &Counters,
) -> bool {
    let deadline = tokio::time::Instant::now() + wait;
    loop {
        tokio::select! {
            _ = stop.cancelled() => return true,
            _ = tokio::time::sleep_until(deadline) => return false,
            ev = events.recv() => match ev {
                Ok(ev) => match mapper.map(&ev) {
                    Mapped::Delta(_) => counters.update(|s| s.drop_some("disconnected", 1)),
                    Mapped::Dropped(reason) => counters.update(|s| s.drop_some(reason, 1)),
                    Mapped::Nothing => {}
                },
                Err(broadcast::error::RecvError::Lagged(n)) => {
                    counters.update(|s| s.drop_some("lagged", n));
                }
                Err(broadcast::error::RecvError::Closed) => return true,
            },
        }
    }
}

async fn send(socket: &mut Socket, delta: String, counters: &Counters) -> Result<(), String> {
    match socket.send(Message::text(delta)).await {
        Ok(()) => {
            counters.update(|s| s.deltas_sent += 1);
            Ok(())
        }
        Err(e) => {
            counters.update(|s| s.drop_some("send_failed", 1));
            Err(e.to_string())
        }
    }
}

/// Sends every output's delta until asked to stop (after sending what is
/// queued) or the connection breaks.
async fn pump(
    socket: &mut Socket,
    events: &mut broadcast::Receiver<OutputEvent>,
    mapper: &mut DeltaMapper,
    stop: &CancellationToken,
    counters: &Counters,
) -> Ended {
    for delta in mapper.notifications() {
        if let Err(e) = send(socket, delta, counters).await {
            return Ended::Lost(e);
        }
    }
    loop {
        let ev = tokio::select! {
            _ = stop.cancelled() => return send_queued(socket, events, mapper, counters).await,
            incoming = socket.next() => match incoming {
                // The server's hello and pings (answered by the library).
                Some(Ok(Message::Close(_))) => return Ended::Lost("closed by the server".into()),
                Some(Ok(_)) => continue,
                Some(Err(e)) => return Ended::Lost(e.to_string()),
                None => return Ended::Lost("closed".into()),
            },
            ev = events.recv() => ev,
        };
        match ev {
            Ok(ev) => match mapper.map(&ev) {
                Mapped::Delta(delta) => {
                    if let Err(e) = send(socket, delta, counters).await {
                        return Ended::Lost(e);
                    }
                }
                Mapped::Dropped(reason) => counters.update(|s| s.drop_some(reason, 1)),
                Mapped::Nothing => {}
            },
            Err(broadcast::error::RecvError::Lagged(n)) => {
                counters.update(|s| s.drop_some("lagged", n));
            }
            Err(broadcast::error::RecvError::Closed) => return Ended::Stopped,
        }
    }
}

/// Sends the outputs already queued, then reports the stop.
async fn send_queued(
    socket: &mut Socket,
    events: &mut broadcast::Receiver<OutputEvent>,
    mapper: &mut DeltaMapper,
    counters: &Counters,
) -> Ended {
    loop {
        match events.try_recv() {
            Ok(ev) => match mapper.map(&ev) {
                Mapped::Delta(delta) => {
                    if let Err(e) = send(socket, delta, counters).await {
                        return Ended::Lost(e);
                    }
                }
                Mapped::Dropped(reason) => counters.update(|s| s.drop_some(reason, 1)),
                Mapped::Nothing => {}
            },
            Err(broadcast::error::TryRecvError::Lagged(n)) => {
                counters.update(|s| s.drop_some("lagged", n));
            }
            Err(_) => return Ended::Stopped,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings(text: &str) -> Result<SignalkSettings, SettingsError> {
        SignalkSettings::from_raw(toml::from_str(text).unwrap())
    }

    #[test]
    fn settings_need_a_ws_url_and_a_vessel() {
        let ok = settings(
            "url = \"ws://127.0.0.1:3000/signalk/v1/stream?subscribe=none\"\nself_vessel = \"otter\"\n[contexts]\nother = \"urn:mrn:imo:mmsi:257000000\"\n",
        )
        .unwrap();
        assert_eq!(ok.source, "usv-twin");
        assert_eq!(ok.context("otter"), Some("vessels.self"));
        assert_eq!(
            ok.context("other"),
            Some("vessels.urn:mrn:imo:mmsi:257000000")
        );
        assert_eq!(ok.context("third"), None);
        for (text, key) in [
            ("self_vessel = \"otter\"\n", "signalk.url"),
            (
                "url = \"http://x/\"\nself_vessel = \"otter\"\n",
                "signalk.url",
            ),
            (
                "url = \"wss://x/\"\nself_vessel = \"otter\"\n",
                "signalk.url",
            ),
            ("url = \"ws://x/\"\n", "signalk.self_vessel"),
            (
                "url = \"ws://x/\"\nself_vessel = \"a/b\"\n",
                "signalk.self_vessel",
            ),
            (
                "url = \"ws://x/\"\nself_vessel = \"a\"\nsource = \"a b\"\n",
                "signalk.source",
            ),
            (
                "url = \"ws://x/\"\nself_vessel = \"a\"\nreconnect_min_s = 0\n",
                "signalk.reconnect_min_s",
            ),
        ] {
            match settings(text) {
                Err(SettingsError::Invalid { key: k, .. }) => assert_eq!(k, key, "{text}"),
                other => panic!("{text}: {other:?}"),
            }
        }
    }

    fn thruster(status: ThrusterStatusName, loss: f64) -> ThrusterMessage {
        ThrusterMessage {
            loss: Some(loss),
            sigma: Some(0.02),
            loss_raw: Some(loss),
            excited: true,
            status,
            onset: None,
        }
    }

    #[test]
    fn statuses_become_signalk_alarm_states_with_methods_and_the_loss() {
        let alarm = thrust_notification("port", &thruster(ThrusterStatusName::Fault, 0.25), None);
        assert_eq!(alarm["state"], "alarm");
        assert_eq!(alarm["method"], json!(["visual", "sound"]));
        assert_eq!(
            alarm["message"],
            "port thruster fault: loss 25 % (sigma 2 %)"
        );
        let warn = thrust_notification("port", &thruster(ThrusterStatusName::Suspect, 0.07), None);
        assert_eq!(
            (warn["state"].as_str(), &warn["method"]),
            (Some("warn"), &json!(["visual"]))
        );
        let quiet = thrust_notification(
            "starboard",
            &thruster(ThrusterStatusName::NotExcited, 0.0),
            None,
        );
        assert_eq!(quiet["state"], "normal");
        assert_eq!(quiet["method"], json!([]));
        assert!(quiet["message"].as_str().unwrap().contains("not excited"));
        assert_eq!(alarm_state(ThrusterStatusName::Nominal), "normal");
    }

    fn fault_event(vessel: &str, time: &str, port: ThrusterStatusName) -> OutputEvent {
        let f = FaultMessage {
            vessel: vessel.into(),
            time: time.into(),
            thrusters: twin_wire::outputs::Thrusters {
                port: thruster(port, 0.2),
                starboard: thruster(ThrusterStatusName::Nominal, 0.0),
            },
            status: port,
            excited: true,
            onset: None,
            model: twin_wire::outputs::ModelName::Kinetic,
            effectiveness_ratio: None,
            seed_input_faults: [0.0, 0.0],
            replay: true,
            profile_mismatch: None,
        };
        OutputEvent {
            vessel: vessel.into(),
            topic: Topic::TwinFault,
            json: serde_json::to_string(&f).unwrap().into(),
        }
    }

    #[test]
    fn notifications_go_on_change_and_every_interval_and_only_for_mapped_vessels() {
        let s = settings("url = \"ws://x/\"\nself_vessel = \"a\"\nnotification_interval_s = 5\n")
            .unwrap();
        let mut m = DeltaMapper::new(s);
        let nominal = ThrusterStatusName::Nominal;
        let sent = |m: &mut DeltaMapper, t: &str, status| {
            matches!(m.map(&fault_event("a", t, status)), Mapped::Delta(_))
        };
        assert!(sent(&mut m, "2024-01-01T00:00:00Z", nominal));
        assert!(!sent(&mut m, "2024-01-01T00:00:01Z", nominal));
        assert!(sent(
            &mut m,
            "2024-01-01T00:00:02Z",
            ThrusterStatusName::Fault
        ));
        assert!(!sent(
            &mut m,
            "2024-01-01T00:00:03Z",
            ThrusterStatusName::Fault
        ));
        assert!(sent(
            &mut m,
            "2024-01-01T00:00:07Z",
            ThrusterStatusName::Fault
        ));
        let Mapped::Delta(last) = m.map(&fault_event("a", "2024-01-01T00:00:08Z", nominal)) else {
            panic!("a change is sent");
        };
        let v: Value = serde_json::from_str(&last).unwrap();
        assert_eq!(v["context"], "vessels.self");
        assert_eq!(v["updates"][0]["$source"], "usv-twin");
        assert_eq!(
            v["updates"][0]["values"][0]["path"],
            "notifications.propulsion.port.thrustLoss"
        );
        assert_eq!(m.notifications(), vec![last]);
        assert_eq!(
            m.map(&fault_event("b", "2024-01-01T00:00:00Z", nominal)),
            Mapped::Dropped("unmapped_vessel")
        );
    }

    /// A profile that stops describing the vessel is news on the displays
    /// at once, though no status changes, and each propeller's message
    /// says that the comparison is withheld, with the figures.
    #[test]
    fn a_withheld_comparison_is_sent_at_once_and_says_why() {
        let s = settings("url = \"ws://x/\"\nself_vessel = \"a\"\nnotification_interval_s = 60\n")
            .unwrap();
        let mut m = DeltaMapper::new(s);
        let nominal = ThrusterStatusName::Nominal;
        assert!(matches!(
            m.map(&fault_event("a", "2024-01-01T00:00:00Z", nominal)),
            Mapped::Delta(_)
        ));
        let mut withheld = fault_event("a", "2024-01-01T00:00:01Z", nominal);
        let mut f: FaultMessage = serde_json::from_str(&withheld.json).unwrap();
        f.profile_mismatch = Some(ProfileMismatchMessage {
            yaw_damping_error: 0.91,
            yaw_damping_bound: 0.75,
            mass_error: -0.52,
            mass_bound: 0.75,
            thrust_error: 0.1,
            thrust_bound: 0.62,
            nis_per_dof: 0.8,
            max_nis_per_dof: 2.0,
        });
        withheld.json = serde_json::to_string(&f).unwrap().into();
        let Mapped::Delta(delta) = m.map(&withheld) else {
            panic!("a withheld comparison is sent within the interval");
        };
        let v: Value = serde_json::from_str(&delta).unwrap();
        for (i, side) in ["port", "starboard"].into_iter().enumerate() {
            let value = &v["updates"][0]["values"][i]["value"];
            assert_eq!(value["state"], "normal");
            assert_eq!(
                value["message"],
                format!(
                    "{side} thruster nominal: loss {} % (sigma 2 %); comparison withheld, the profile does not describe this vessel (yaw damping error +0.91, at most +-0.75; mass error -0.52, at most +-0.75; thrust coefficient error +0.10, at most +-0.62; NIS per dof over the last minute 0.80, at most 2.0)",
                    if i == 0 { 20 } else { 0 }
                )
            );
        }
        // Unchanged, it waits for the interval again.
        withheld.json = serde_json::to_string(&FaultMessage {
            time: "2024-01-01T00:00:02Z".into(),
            ..f
        })
        .unwrap()
        .into();
        assert_eq!(m.map(&withheld), Mapped::Nothing);
    }
}
