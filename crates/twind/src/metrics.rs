//! The daemon's Prometheus metrics: `GET /metrics` on the web page's port,
//! or on a port of its own (`[metrics] listen`, `--metrics-listen`), in the
//! text exposition format 0.0.4 with a `# HELP` and a `# TYPE` line per
//! metric.
//!
//! What is exposed is what the daemon counts anyway: its input
//! subscription's messages received, routed and refused by reason (the
//! daemon's statistics, `{prefix}/@twind/{id}/stats`), the vessels admitted
//! and their bound, every vessel twin's messages received, accepted and
//! rejected (summed over the fleet, by topic and by reason: a label per
//! vessel would grow without bound with the fleet), the events waiting in
//! the vessels' queues, the calibration saves that failed, and how long
//! the estimator takes per fix and per shaft-speed update (a histogram).
//!
//! Counting costs the vessels' path a few relaxed atomic additions per
//! message (a lock only for a rejection, to find its reason); the text is
//! made when scraped.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use tokio_util::sync::CancellationToken;
use twin_wire::Topic;

use crate::SaveFailures;
use crate::dispatch::Dispatcher;
use crate::forecast::FaultPathLoad;

/// The content type of the text exposition format.
pub const CONTENT_TYPE: &str = "text/plain; version=0.0.4; charset=utf-8";

/// The input topics counted, in the order of [`FleetCounts`]' arrays.
const INPUTS: [Topic; 3] = [Topic::Gnss, Topic::Nmea, Topic::Actuators];

/// Upper bounds of the estimator update histogram's buckets, s.
const UPDATE_BUCKETS_S: [f64; 12] = [
    1e-5, 2.5e-5, 5e-5, 1e-4, 2.5e-4, 5e-4, 1e-3, 2.5e-3, 5e-3, 1e-2, 2.5e-2, 1e-1,
];

/// What every vessel twin of the daemon received, accepted and rejected, in
/// all.
#[derive(Debug, Default)]
pub struct FleetCounts {
    received: [AtomicU64; INPUTS.len()],
    accepted: [AtomicU64; INPUTS.len()],
    rejected: Mutex<BTreeMap<String, u64>>,
}

impl FleetCounts {
    /// A message received on `topic`.
    pub fn receive(&self, topic: Topic) {
        if let Some(i) = INPUTS.iter().position(|t| *t == topic) {
            self.received[i].fetch_add(1, Ordering::Relaxed);
        }
    }

    /// A message on `topic` the twin used.
    pub fn accept(&self, topic: Topic) {
        if let Some(i) = INPUTS.iter().position(|t| *t == topic) {
            self.accepted[i].fetch_add(1, Ordering::Relaxed);
        }
    }

    /// A message refused for `reason`.
    pub fn reject(&self, reason: &str) {
        let mut rejected = match self.rejected.lock() {
            Ok(r) => r,
            Err(poisoned) => poisoned.into_inner(),
        };
        match rejected.get_mut(reason) {
            Some(n) => *n += 1,
            None => {
                rejected.insert(reason.to_string(), 1);
            }
        }
    }
}

/// A histogram of durations with fixed buckets.
#[derive(Debug, Default)]
struct Histogram {
    /// Observations at or below each bound of [`UPDATE_BUCKETS_S`] (not
    /// cumulative; summed when written).
    buckets: [AtomicU64; UPDATE_BUCKETS_S.len()],
    count: AtomicU64,
    sum_ns: AtomicU64,
}

impl Histogram {
    fn observe(&self, d: Duration) {
        let s = d.as_secs_f64();
        if let Some(i) = UPDATE_BUCKETS_S.iter().position(|b| s <= *b) {
            self.buckets[i].fetch_add(1, Ordering::Relaxed);
        }
        self.count.fetch_add(1, Ordering::Relaxed);
        let ns = u64::try_from(d.as_nanos()).unwrap_or(u64::MAX);
        self.sum_ns.fetch_add(ns, Ordering::Relaxed);
    }

    fn write(&self, out: &mut String, name: &str, labels: &str) {
        let mut cumulative = 0;
        for (bound, n) in UPDATE_BUCKETS_S.iter().zip(&self.buckets) {
            cumulative += n.load(Ordering::Relaxed);
            let _ = writeln!(out, "{name}_bucket{{{labels},le=\"{bound}\"}} {cumulative}");
        }
        let count = self.count.load(Ordering::Relaxed);
        let _ = writeln!(out, "{name}_bucket{{{labels},le=\"+Inf\"}} {count}");
        let sum_s = self.sum_ns.load(Ordering::Relaxed) as f64 * 1e-9;
        let _ = writeln!(out, "{name}_sum{{{labels}}} {sum_s}");
        let _ = writeln!(out, "{name}_count{{{labels}}} {count}");
    }
}

/// The running daemon, as the metrics read it.
struct DaemonView {
    id: String,
    dispatcher: Dispatcher,
    save_failures: SaveFailures,
    load: FaultPathLoad,
}

#[derive(Default)]
struct Inner {
    fleet: Arc<FleetCounts>,
    fix_update: Histogram,
    propeller_update: Histogram,
    daemon: Mutex<Option<DaemonView>>,
}

/// The daemon's metrics: shared by its run, its vessel tasks and the HTTP
/// servers that expose them. Cloning shares them.
#[derive(Clone, Default)]
pub struct Metrics(Arc<Inner>);

impl std::fmt::Debug for Metrics {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Metrics")
    }
}

/// Which estimator update a duration is of.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Update {
    /// A GNSS fix (the estimator's measurement update and its outputs' step).
    Fix,
    /// Shaft speeds (the estimator's input).
    Propellers,
}

impl Metrics {
    /// The fleet's counts, shared with every vessel's counters.
    pub fn fleet(&self) -> Arc<FleetCounts> {
        self.0.fleet.clone()
    }

    /// How long one estimator update took.
    pub fn observe(&self, update: Update, took: Duration) {
        match update {
            Update::Fix => self.0.fix_update.observe(took),
            Update::Propellers => self.0.propeller_update.observe(took),
        }
    }

    /// The running daemon's dispatcher, to read its counts when scraped.
    pub(crate) fn attach(
        &self,
        id: String,
        dispatcher: Dispatcher,
        save_failures: SaveFailures,
        load: FaultPathLoad,
    ) {
        let mut daemon = match self.0.daemon.lock() {
            Ok(d) => d,
            Err(poisoned) => poisoned.into_inner(),
        };
        *daemon = Some(DaemonView {
            id,
            dispatcher,
            save_failures,
            load,
        });
    }

    /// The text exposition of every metric.
    pub fn render(&self) -> String {
        let mut out = String::new();
        self.write_daemon(&mut out);
        self.write_fleet(&mut out);
        header(
            &mut out,
            "twind_estimator_update_seconds",
            "histogram",
            "Time one estimator update took (wall clock), by input: a GNSS fix or shaft speeds.",
        );
        let updates = [
            ("fix", &self.0.fix_update),
            ("propellers", &self.0.propeller_update),
        ];
        for (input, h) in updates {
            h.write(
                &mut out,
                "twind_estimator_update_seconds",
                &format!("input=\"{input}\""),
            );
        }
        out
    }

    fn write_daemon(&self, out: &mut String) {
        let daemon = match self.0.daemon.lock() {
            Ok(d) => d,
            Err(poisoned) => poisoned.into_inner(),
        };
        let Some(d) = daemon.as_ref() else {
            return;
        };
        let stats = d.dispatcher.daemon_stats(&d.id, d.save_failures.count());
        let queues = d.dispatcher.queues();
        header(out, "twind_info", "gauge", "The daemon's id and version.");
        let _ = writeln!(
            out,
            "twind_info{{daemon=\"{}\",version=\"{}\"}} 1",
            escape(&d.id),
            env!("CARGO_PKG_VERSION")
        );
        let counts = [
            (
                "twind_messages_received_total",
                "Messages received on the daemon's input subscription.",
                stats.received,
            ),
            (
                "twind_messages_routed_total",
                "Messages handed to a vessel's twin.",
                stats.routed,
            ),
            (
                "twind_calibration_save_failures_total",
                "Calibration saves that failed.",
                stats.save_failures,
            ),
            (
                "twind_ros2_missed_total",
                "ROS 2 input messages their publishers numbered but that never arrived.",
                stats.ros2_missed,
            ),
        ];
        for (name, help, value) in counts {
            counter(out, name, help, value);
        }
        labelled(
            out,
            "twind_messages_refused_total",
            "counter",
            "Messages the daemon refused before any vessel's twin saw them, by reason (admission_rate and too_many_vessels are admissions refused).",
            "reason",
            &stats.refused,
        );
        let gauges = [
            (
                "twind_vessels",
                "Vessels admitted and running.",
                stats.vessels as u64,
            ),
            (
                "twind_vessels_max",
                "The most vessels served at once ([vessels] max_vessels).",
                stats.max_vessels as u64,
            ),
            (
                "twind_queued_events",
                "Events waiting in the vessels' queues, in all.",
                queues.queued,
            ),
            (
                "twind_queued_events_max",
                "Events waiting in the fullest vessel queue.",
                queues.deepest,
            ),
            (
                "twind_queue_capacity",
                "Events one vessel's queue holds ([vessels] queue_depth).",
                queues.capacity,
            ),
            (
                "twind_events_in_flight",
                "Events routed to the vessels and not yet handled.",
                d.load.in_flight(),
            ),
        ];
        for (name, help, value) in gauges {
            header(out, name, "gauge", help);
            let _ = writeln!(out, "{name} {value}");
        }
    }

    fn write_fleet(&self, out: &mut String) {
        let fleet = &self.0.fleet;
        let by_topic = |counts: &[AtomicU64; INPUTS.len()]| -> BTreeMap<String, u64> {
            INPUTS
                .iter()
                .zip(counts)
                .map(|(t, n)| (t.suffix().to_string(), n.load(Ordering::Relaxed)))
                .collect()
        };
        labelled(
            out,
            "twind_vessel_messages_received_total",
            "counter",
            "Messages the vessels' twins received, by input topic (summed over the fleet).",
            "topic",
            &by_topic(&fleet.received),
        );
        labelled(
            out,
            "twind_vessel_messages_accepted_total",
            "counter",
            "Messages the vessels' twins used, by input topic (summed over the fleet).",
            "topic",
            &by_topic(&fleet.accepted),
        );
        let rejected = match fleet.rejected.lock() {
            Ok(r) => r.clone(),
            Err(poisoned) => poisoned.into_inner().clone(),
        };
        labelled(
            out,
            "twind_vessel_messages_rejected_total",
            "counter",
            "Messages the vessels' twins refused, by reason (summed over the fleet).",
            "reason",
            &rejected,
        );
    }
}

/// The vessels' queues when scraped.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Queues {
    /// Events waiting, in all.
    pub queued: u64,
    /// In the fullest queue.
    pub deepest: u64,
    /// One queue's capacity.
    pub capacity: u64,
}

/// A label value escaped as the text format wants: `\`, `"` and newlines.
fn escape(value: &str) -> String {
    let mut out = String::with_capacity(value.len());
    for c in value.chars() {
        match c {
            '\\' => out.push_str("\\\\"),
            '"' => out.push_str("\\\""),
            '\n' => out.push_str("\\n"),
            c => out.push(c),
        }
    }
    out
}

fn header(out: &mut String, name: &str, kind: &str, help: &str) {
    let _ = writeln!(out, "# HELP {name} {help}");
    let _ = writeln!(out, "# TYPE {name} {kind}");
}

/// Writes a counter without labels, with its `HELP` and `TYPE` lines.
pub fn counter(out: &mut String, name: &str, help: &str, value: u64) {
    header(out, name, "counter", help);
    let _ = writeln!(out, "{name} {value}");
}

fn labelled(
    out: &mut String,
    name: &str,
    kind: &str,
    help: &str,
    label: &str,
    values: &BTreeMap<String, u64>,
) {
    header(out, name, kind, help);
    for (value, n) in values {
        let _ = writeln!(out, "{name}{{{label}=\"{}\"}} {n}", escape(value));
    }
}

/// The `/metrics` handler for an axum router whose state holds [`Metrics`].
pub async fn handler(
    axum::extract::State(metrics): axum::extract::State<Metrics>,
) -> axum::response::Response {
    use axum::response::IntoResponse;
    (
        [
            (axum::http::header::CONTENT_TYPE, CONTENT_TYPE),
            (axum::http::header::CACHE_CONTROL, "no-store"),
        ],
        metrics.render(),
    )
        .into_response()
}

/// A server of `/metrics` alone on `listen` (`[metrics] listen`), until
/// `shutdown`; the address it listens on.
pub async fn serve(
    listen: SocketAddr,
    metrics: Metrics,
    shutdown: CancellationToken,
) -> anyhow::Result<(SocketAddr, tokio::task::JoinHandle<()>)> {
    let listener = tokio::net::TcpListener::bind(listen)
        .await
        .map_err(|e| anyhow::anyhow!("cannot serve the metrics on {listen}: {e}"))?;
    let local = listener.local_addr()?;
    let app = axum::Router::new()
        .route("/metrics", axum::routing::get(handler))
        .with_state(metrics);
    let task = tokio::spawn(async move {
        let serve = axum::serve(listener, app).with_graceful_shutdown(shutdown.cancelled_owned());
        if let Err(e) = serve.await {
            tracing::warn!("metrics server: {e}");
        }
    });
    tracing::info!(%local, "metrics served");
    Ok((local, task))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fleet_counts_and_the_histogram_are_written_with_their_labels() {
        let m = Metrics::default();
        let fleet = m.fleet();
        fleet.receive(Topic::Gnss);
        fleet.receive(Topic::Gnss);
        fleet.accept(Topic::Gnss);
        fleet.reject("bad \"json\"");
        m.observe(Update::Fix, Duration::from_micros(30));
        m.observe(Update::Fix, Duration::from_millis(200));
        let text = m.render();
        for line in [
            "twind_vessel_messages_received_total{topic=\"gnss\"} 2",
            "twind_vessel_messages_accepted_total{topic=\"gnss\"} 1",
            "twind_vessel_messages_rejected_total{reason=\"bad \\\"json\\\"\"} 1",
            "twind_estimator_update_seconds_bucket{input=\"fix\",le=\"0.00005\"} 1",
            "twind_estimator_update_seconds_bucket{input=\"fix\",le=\"0.1\"} 1",
            "twind_estimator_update_seconds_bucket{input=\"fix\",le=\"+Inf\"} 2",
            "twind_estimator_update_seconds_count{input=\"fix\"} 2",
        ] {
            assert!(text.lines().any(|l| l == line), "no {line:?} in\n{text}");
        }
    }
}
