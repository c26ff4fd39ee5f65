//! The `daemon` subcommand: the live daemon under load, side by side with
//! raw Zenoh pub/sub, in one run, as the project's speed targets ask (docs/performance.md)
//! ("1,000 vessels at 10 Hz each through Zenoh on loopback with p99
//! GNSS-in to fault-out latency under 5 ms; its maximum sustained rate at
//! least a quarter of raw Zenoh pub/sub on the same payloads").
//!
//! # What is measured
//! A load generator publishes, for `N` vessels at `R` Hz each, a GNSS fix on
//! `asv/<id>/gnss` and the shaft speeds on `asv/<id>/actuators` (the
//! contract's JSON, encoded by `twin_wire::messages` as `twin-replay` does;
//! the fleet follows the simulated Otter's steady turn at 1.5 m/s, each
//! vessel on its own circle and phase, see [`motion`]), spread evenly over
//! each period. twind runs in the same process (`twind::run`, its own tokio
//! runtime with a worker per core, default settings but the live diagnose
//! off) on its own Zenoh session; a third session subscribes to
//! `asv/*/twin/fault`. Per point:
//! - throughput: fixes sent per second, faults received per second, and
//!   fixes whose fault never came back within a grace period ("lost");
//! - latency from the instant the generator stamped a fix to the instant
//!   the subscriber received the fault that fix produced (the fault echoes
//!   the fix's time, which is the stamp): p50, p99, max over every fix of
//!   the window (see [`load`] for the details);
//! - CPU time of the process over the window (`/proc/self/stat`), as % of
//!   one core, and split by thread (daemon runtime, generator, Zenoh's
//!   runtimes);
//! - RSS before the first message and at the window's end; memory per
//!   vessel is their difference over `N`.
//!
//! The same generator then publishes the same payloads to a subscriber with
//! no daemon in between (raw Zenoh: one hop, where the daemon path has two
//! and the daemon's work between them).
//!
//! # How
//! Every point runs in a fresh child process (this binary, hidden
//! subcommand `daemon-point`, one JSON line back), so that RSS and CPU
//! belong to that point alone and a saturated daemon does not drain into
//! the next one. A point warms up (at least `--warmup-s`, and until every
//! vessel has been heard from), measures one window, waits the grace
//! period, and shuts down (each wait bounded, see [`load`]). The full run
//! warms up at least 5 s: near the daemon's limit the start (a task, a twin
//! and a first forecast per vessel) lasts seconds, and a shorter warm-up
//! puts it into the window (at 5,600 vessels x 10 Hz, p99 73-128 ms after
//! 1.5 s against 17-47 ms after 8 s). Three sets of runs:
//! 1. scaling: 10, 100, 1,000, 10,000 vessels at 10 Hz, daemon and raw;
//! 2. the maximum sustained rate of each path at 10 Hz per vessel: a run
//!    is sustained when at least 95 % of the plan was sent, the generator
//!    never more than 100 ms behind its schedule in the window, at least
//!    95 % of the fixes sent came back within the grace period and p99
//!    latency stayed under 100 ms;
//!    between the largest sustained fleet of the scaling runs and the
//!    smallest that was not, the fleet is bisected (geometric mean, a few
//!    steps). The largest delivered rate of a sustained run is the path's
//!    maximum sustained rate; the daemon's over raw Zenoh's is the ratio
//!    the targets set at >= 0.25;
//! 3. capacity: each path flat out (1,000 vessels, no pacing, the
//!    publishers' back-pressure setting the pace), the received rate.
//!
//! Figures are single measurements of one window each in one run (the
//! latency percentiles are over every fix of the window), on a shared
//! machine whose load is printed beside them. Nothing here is asserted in a
//! test: the test (`tests/daemon_load.rs`) checks the plumbing only.

pub mod cold_start;
pub mod flood;
mod generator;
pub mod histogram;
pub mod load;
pub mod motion;
pub mod procstat;
mod receiver;

use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::Instant;

use anyhow::Context;

use crate::core::thousands;
use crate::machine;
use load::{Path, PointResult, PointSpec};

/// Target (docs/performance.md): p99 GNSS-in to fault-out at 1,000 vessels x 10 Hz, ms.
pub const TARGET_P99_MS: f64 = 5.0;
/// Target (docs/performance.md): the daemon's maximum sustained rate over raw Zenoh's.
pub const TARGET_RATIO: f64 = 0.25;
/// The headline fleet.
pub const HEADLINE_VESSELS: usize = 1000;
/// A run is sustained when at least this fraction of the plan is sent and
/// of what was sent delivered...
pub const SUSTAINED_DELIVERED: f64 = 0.95;
/// ... and p99 latency is under this, ms...
pub const SUSTAINED_P99_MS: f64 = 100.0;
/// ... and the generator, all through the window, no further than this
/// behind its schedule, ms: a generator seconds behind is working off a
/// backlog flat out, not keeping to the plan. Latency is stamped when a fix
/// is published, so a backlog waiting in the generator is not in it, while
/// one waiting in the daemon's queues is: without this bound a path whose
/// start-up debt waits in the generator (raw Zenoh's) could count as
/// sustained at a rate it never caught up with. The same bound as p99: a
/// fix published this late is already at the edge of the latency budget.
pub const SUSTAINED_GENERATOR_LAG_MS: f64 = SUSTAINED_P99_MS;

/// How to run `daemon`.
#[derive(Debug, Clone)]
pub struct DaemonOptions {
    /// Fleet sizes of the scaling table.
    pub vessels: Vec<usize>,
    /// Fixes per second per vessel in the scaling table.
    pub rate_hz: f64,
    /// Measurement window of the scaling runs, s.
    pub window_s: f64,
    /// Least warm-up, s.
    pub warmup_s: f64,
    /// Grace period after a window, s.
    pub grace_s: f64,
    /// Bisection steps of the sustained-rate search, per path.
    pub ramp_steps: usize,
    /// Measurement window of the sustained-rate search, s.
    pub ramp_window_s: f64,
    /// Fleet of the flat-out runs.
    pub saturation_vessels: usize,
    /// Measurement window of the flat-out runs, s.
    pub saturation_window_s: f64,
    /// Fewer sizes and shorter windows: a smoke test, not a measurement.
    pub quick: bool,
    /// The binary that runs one point (`daemon-point`): this one.
    pub exe: PathBuf,
    /// The daemon's `publish.vessel_liveliness` (default true, the contract).
    pub vessel_liveliness: bool,
    /// The tokens outside the data prefix
    /// ([`load::OUTSIDE_PREFIX_LIVELINESS_KEY`]).
    pub liveliness_outside_prefix: bool,
}

impl DaemonOptions {
    /// The full run, or with `quick` the short one.
    pub fn new(quick: bool, exe: PathBuf) -> Self {
        if quick {
            Self {
                vessels: vec![10, 1000],
                rate_hz: 10.0,
                window_s: 3.0,
                warmup_s: 1.0,
                grace_s: 1.0,
                ramp_steps: 1,
                ramp_window_s: 2.0,
                saturation_vessels: HEADLINE_VESSELS,
                saturation_window_s: 2.0,
                quick,
                exe,
                vessel_liveliness: true,
                liveliness_outside_prefix: false,
            }
        } else {
            Self {
                vessels: vec![10, 100, 1000, 10_000],
                rate_hz: 10.0,
                window_s: 10.0,
                warmup_s: 5.0,
                grace_s: 1.0,
                ramp_steps: 5,
                ramp_window_s: 4.0,
                saturation_vessels: HEADLINE_VESSELS,
                saturation_window_s: 3.0,
                quick,
                exe,
                vessel_liveliness: true,
                liveliness_outside_prefix: false,
            }
        }
    }
}

impl DaemonOptions {
    /// A point of this run: `vessels` on `path` at `rate_hz` per vessel
    /// (`None`: flat out), measured over `window_s`.
    pub fn spec(
        &self,
        path: Path,
        vessels: usize,
        rate_hz: Option<f64>,
        window_s: f64,
    ) -> PointSpec {
        PointSpec {
            path,
            vessels,
            rate_hz,
            warmup_s: self.warmup_s,
            window_s,
            grace_s: self.grace_s,
            vessel_liveliness: self.vessel_liveliness,
            liveliness_outside_prefix: self.liveliness_outside_prefix,
        }
    }
}

/// What `daemon` measured.
#[derive(Debug, Clone)]
pub struct DaemonReport {
    /// The options it ran with.
    pub options: DaemonOptions,
    /// Scaling runs, daemon and raw, in run order.
    pub scaling: Vec<PointResult>,
    /// The sustained-rate search's runs (bisecting the fleet), in run order.
    pub ramp: Vec<PointResult>,
    /// Flat-out runs, daemon then raw.
    pub capacity: Vec<PointResult>,
    /// Load average before.
    pub load_before: String,
    /// Load average after.
    pub load_after: String,
    /// Wall time of the whole run, s.
    pub elapsed_s: f64,
}

/// Whether a paced run counts as sustained: the plan was sent, on
/// schedule, and what was sent came back, in time.
pub fn sustained(r: &PointResult) -> bool {
    r.spec.rate_hz.is_some()
        && r.fixes_sent > 0
        && r.offered_fraction() >= SUSTAINED_DELIVERED
        && on_schedule(r)
        && r.delivered_fraction() >= SUSTAINED_DELIVERED
        && r.latency
            .p99_ns
            .is_some_and(|p| p as f64 / 1e6 <= SUSTAINED_P99_MS)
}

/// Whether the generator stayed within [`SUSTAINED_GENERATOR_LAG_MS`] of
/// its schedule through the window (a run without a lag figure, flat out,
/// counts as on schedule).
pub fn on_schedule(r: &PointResult) -> bool {
    r.generator_max_lag_ms
        .is_none_or(|lag| lag <= SUSTAINED_GENERATOR_LAG_MS)
}

/// Whether a paced run failed only because the generator could not send
/// its plan (or not on schedule), with each of the generator's threads near
/// a full core: what was sent came back in time.
pub fn limited_by_generator(r: &PointResult) -> bool {
    !sustained(r)
        && (r.offered_fraction() < SUSTAINED_DELIVERED || !on_schedule(r))
        && r.delivered_fraction() >= SUSTAINED_DELIVERED
        && r.latency
            .p99_ns
            .is_some_and(|p| p as f64 / 1e6 <= SUSTAINED_P99_MS)
        && r.generator_cpu_pct()
            .is_some_and(|c| c >= 80.0 * r.generator_threads as f64)
}

/// Runs one point in a child process (`exe daemon-point ...`) and reads
/// its JSON line.
pub fn run_point_in_child(exe: &std::path::Path, spec: &PointSpec) -> anyhow::Result<PointResult> {
    let mut cmd = Command::new(exe);
    cmd.arg("daemon-point")
        .arg("--path")
        .arg(match spec.path {
            Path::Daemon => "daemon",
            Path::Raw => "raw",
        })
        .arg("--vessels")
        .arg(spec.vessels.to_string())
        .arg("--warmup-s")
        .arg(spec.warmup_s.to_string())
        .arg("--window-s")
        .arg(spec.window_s.to_string())
        .arg("--grace-s")
        .arg(spec.grace_s.to_string());
    if !spec.vessel_liveliness {
        cmd.arg("--no-vessel-liveliness");
    }
    if spec.liveliness_outside_prefix {
        cmd.arg("--liveliness-outside-prefix");
    }
    match spec.rate_hz {
        Some(r) => cmd.arg("--rate-hz").arg(r.to_string()),
        None => cmd.arg("--flat-out"),
    };
    let out = cmd
        .stdin(Stdio::null())
        .stderr(Stdio::inherit())
        .output()
        .with_context(|| format!("running {}", exe.display()))?;
    let stdout = String::from_utf8_lossy(&out.stdout);
    anyhow::ensure!(
        out.status.success(),
        "the point {spec:?} failed ({}): {stdout}",
        out.status
    );
    let line = stdout
        .lines()
        .find_map(|l| l.strip_prefix(POINT_PREFIX))
        .ok_or_else(|| anyhow::anyhow!("the point {spec:?} printed no result: {stdout}"))?;
    let result: PointResult = serde_json::from_str(line).context("reading a point's result")?;
    // A setting lost on the way to the child would label its figures wrongly.
    anyhow::ensure!(
        result.spec == *spec,
        "the point ran {:?}, not the {spec:?} asked for",
        result.spec
    );
    Ok(result)
}

/// The prefix of the result line a `daemon-point` child prints.
pub const POINT_PREFIX: &str = "twin-bench-point ";

/// The result line of a point, as `daemon-point` prints it.
pub fn point_line(r: &PointResult) -> anyhow::Result<String> {
    Ok(format!("{POINT_PREFIX}{}", serde_json::to_string(r)?))
}

fn progress(start: Instant, what: &str) {
    eprintln!("[{:6.1} s] {what}", start.elapsed().as_secs_f64());
}

fn brief(r: &PointResult) -> String {
    format!(
        "{} fixes/s offered, {} /s received, {} lost, p99 {}",
        thousands(r.offered_fixes_per_s.round() as u64),
        thousands(r.received_per_s.round() as u64),
        thousands(r.lost()),
        ms_text(r.latency.p99_ns),
    )
}

/// Runs every point with `point` (in child processes in the binary; the
/// caller chooses) and collects the report.
pub fn run_with(
    opts: &DaemonOptions,
    mut point: impl FnMut(&PointSpec) -> anyhow::Result<PointResult>,
) -> anyhow::Result<DaemonReport> {
    let start = Instant::now();
    let load_before = machine::load_average_text();
    let mut scaling = Vec::new();
    for &n in &opts.vessels {
        for path in [Path::Daemon, Path::Raw] {
            let spec = opts.spec(path, n, Some(opts.rate_hz), opts.window_s);
            let r = point(&spec)?;
            progress(
                start,
                &format!("{path:?}, {n} vessels x {} Hz: {}", opts.rate_hz, brief(&r)),
            );
            scaling.push(r);
        }
    }
    let ramp = search(opts, &scaling, &mut point, start)?;
    let mut capacity = Vec::new();
    for path in [Path::Daemon, Path::Raw] {
        let n = opts.saturation_vessels;
        let flat = point(&opts.spec(path, n, None, opts.saturation_window_s))?;
        progress(
            start,
            &format!("{path:?}, {n} vessels flat out: {}", brief(&flat)),
        );
        capacity.push(flat);
    }
    Ok(DaemonReport {
        options: opts.clone(),
        scaling,
        ramp,
        capacity,
        load_before,
        load_after: machine::load_average_text(),
        elapsed_s: start.elapsed().as_secs_f64(),
    })
}

/// The next fleet of `path`'s sustained-rate search: between the largest
/// sustained fleet tried and the smallest unsustained one (geometric
/// mean), twice the largest if every one was sustained; `None` when the
/// search has nothing new to try.
fn next_search_fleet(tried: &[&PointResult], path: Path) -> Option<usize> {
    let (mut lo, mut hi) = (None::<usize>, None::<usize>);
    for r in tried.iter().filter(|r| r.spec.path == path) {
        let n = r.spec.vessels;
        if sustained(r) {
            lo = Some(lo.map_or(n, |l| l.max(n)));
        } else {
            hi = Some(hi.map_or(n, |h| h.min(n)));
        }
    }
    let n = match (lo, hi) {
        (Some(l), Some(h)) if l < h => ((l as f64) * (h as f64)).sqrt().round() as usize,
        (None, Some(h)) => ((h as f64).sqrt().round() as usize).max(1),
        // Every fleet tried was sustained: try twice the largest.
        (Some(l), None) => (2 * l).min(99_999),
        _ => return None,
    };
    let new = !tried
        .iter()
        .any(|r| r.spec.path == path && r.spec.vessels == n);
    new.then_some(n)
}

/// The sustained-rate search: for each path, bisect the fleet between the
/// largest sustained scaling run and the smallest one that was not.
fn search(
    opts: &DaemonOptions,
    scaling: &[PointResult],
    point: &mut impl FnMut(&PointSpec) -> anyhow::Result<PointResult>,
    start: Instant,
) -> anyhow::Result<Vec<PointResult>> {
    let mut ramp: Vec<PointResult> = Vec::new();
    for path in [Path::Daemon, Path::Raw] {
        for _ in 0..opts.ramp_steps {
            let tried: Vec<&PointResult> = scaling.iter().chain(&ramp).collect();
            let Some(n) = next_search_fleet(&tried, path) else {
                break;
            };
            let r = point(&opts.spec(path, n, Some(opts.rate_hz), opts.ramp_window_s))?;
            progress(
                start,
                &format!(
                    "{path:?}, {n} vessels x {} Hz (sustained-rate search): {}; {}",
                    opts.rate_hz,
                    brief(&r),
                    if sustained(&r) {
                        "sustained"
                    } else {
                        "not sustained"
                    }
                ),
            );
            ramp.push(r);
        }
    }
    Ok(ramp)
}

/// Runs every point in a child process of `opts.exe`.
pub fn run(opts: &DaemonOptions) -> anyhow::Result<DaemonReport> {
    let exe = opts.exe.clone();
    run_with(opts, |spec| run_point_in_child(&exe, spec))
}

/// Milliseconds with a readable precision, from nanoseconds.
pub fn ms_text(ns: Option<u64>) -> String {
    match ns {
        None => "-".into(),
        Some(ns) => {
            let ms = ns as f64 / 1e6;
            if ms < 1.0 {
                format!("{ms:.3} ms")
            } else if ms < 100.0 {
                format!("{ms:.2} ms")
            } else {
                format!("{ms:.0} ms")
            }
        }
    }
}

fn mb_text(kib: Option<u64>) -> String {
    kib.map_or("-".into(), |k| format!("{:.1} MB", k as f64 * 1024.0 / 1e6))
}

fn per_vessel_text(r: &PointResult) -> String {
    r.kib_per_vessel()
        .map_or("-".into(), |k| format!("{:.1} KB", k * 1024.0 / 1e3))
}

/// Forecasts per second in the window, and how often that makes one per
/// vessel: "9,870 (every 1.01 s)"; "-" for raw Zenoh.
fn forecasts_text(r: &PointResult) -> String {
    match r.forecasts_per_s {
        Some(f) if f > 0.0 => format!(
            "{} (every {:.1} s)",
            rate_text(f),
            r.spec.vessels as f64 / f
        ),
        Some(_) => "0".into(),
        None => "-".into(),
    }
}

fn cpu_text(r: &PointResult) -> String {
    r.cpu_pct_of_core
        .map_or("-".into(), |c| format!("{c:.0} %"))
}

fn rate_text(per_s: f64) -> String {
    thousands(per_s.round().max(0.0) as u64)
}

/// A p99 that is only a lower bound when much was not delivered.
fn p99_text(r: &PointResult) -> String {
    let t = ms_text(r.latency.p99_ns);
    if r.delivered_fraction() < 0.99 && r.latency.p99_ns.is_some() {
        format!(">= {t}")
    } else {
        t
    }
}

fn fleet_text(r: &PointResult) -> String {
    match r.spec.rate_hz {
        Some(hz) => {
            format!("{} x {hz:.4} Hz", thousands(r.spec.vessels as u64)).replace(".0000 Hz", " Hz")
        }
        None => format!("{} flat out", thousands(r.spec.vessels as u64)),
    }
}

/// A point's CPU by thread group, `group N %`, the groups under half a
/// percent left out.
fn cpu_groups_text(r: &PointResult) -> String {
    let parts: Vec<String> = r
        .cpu_pct_by_group
        .iter()
        .filter(|(_, v)| **v >= 0.5)
        .map(|(g, v)| format!("{g} {v:.0} %"))
        .collect();
    parts.join(", ")
}

fn path_text(p: Path) -> &'static str {
    match p {
        Path::Daemon => "daemon",
        Path::Raw => "raw Zenoh",
    }
}

impl DaemonReport {
    /// The scaling run of `path` at `vessels`, if it ran.
    pub fn scaling_point(&self, path: Path, vessels: usize) -> Option<&PointResult> {
        self.scaling
            .iter()
            .find(|r| r.spec.path == path && r.spec.vessels == vessels)
    }

    /// The sustained run with the largest delivered rate, of `path`.
    pub fn max_sustained(&self, path: Path) -> Option<&PointResult> {
        self.paced(path)
            .filter(|r| sustained(r))
            .max_by(|a, b| a.delivered_per_s().total_cmp(&b.delivered_per_s()))
    }

    fn paced(&self, path: Path) -> impl Iterator<Item = &PointResult> {
        self.scaling
            .iter()
            .chain(&self.ramp)
            .filter(move |r| r.spec.path == path && r.spec.rate_hz.is_some())
    }

    /// True when `path`'s maximum sustained rate is only a lower bound:
    /// the largest fleet tried was sustained, or the runs above it failed
    /// only because the generator could not send the plan.
    pub fn sustained_is_lower_bound(&self, path: Path) -> bool {
        let best = self.max_sustained(path).map_or(0, |r| r.spec.vessels);
        let mut above = self
            .paced(path)
            .filter(|r| r.spec.vessels > best)
            .peekable();
        above.peek().is_none() || above.all(limited_by_generator)
    }

    /// The daemon's maximum sustained rate over raw Zenoh's.
    pub fn ratio(&self) -> Option<f64> {
        let d = self.max_sustained(Path::Daemon)?.delivered_per_s();
        let r = self.max_sustained(Path::Raw)?.delivered_per_s();
        (r > 0.0).then(|| d / r)
    }

    /// True if every judged target is met.
    pub fn all_met(&self) -> bool {
        self.headline_p99_met() == Some(true) && self.ratio_judged().1 == "met"
    }

    /// The ratio as printed (with `<=` or `>=` when one side is only a
    /// bound) and its verdict: `met`, `missed`, or `unknown` when a bound
    /// cannot decide.
    pub fn ratio_judged(&self) -> (String, &'static str) {
        let Some(ratio) = self.ratio() else {
            return ("not measured".into(), "missed");
        };
        let d_low = self.sustained_is_lower_bound(Path::Daemon);
        let r_low = self.sustained_is_lower_bound(Path::Raw);
        let met = ratio >= TARGET_RATIO;
        match (d_low, r_low) {
            (false, false) => (format!("{ratio:.3}"), if met { "met" } else { "missed" }),
            // Raw Zenoh could do more: the true ratio is smaller.
            (false, true) => (
                format!("<= {ratio:.3}"),
                if met { "unknown" } else { "missed" },
            ),
            // The daemon could do more: the true ratio is larger.
            (true, false) => (
                format!(">= {ratio:.3}"),
                if met { "met" } else { "unknown" },
            ),
            (true, true) => (format!("~ {ratio:.3} (both lower bounds)"), "unknown"),
        }
    }

    fn headline_p99_met(&self) -> Option<bool> {
        let r = self.scaling_point(Path::Daemon, HEADLINE_VESSELS)?;
        Some(
            r.delivered_fraction() >= 0.99
                && r.latency
                    .p99_ns
                    .is_some_and(|p| (p as f64 / 1e6) < TARGET_P99_MS),
        )
    }

    /// The run's tables as Markdown: the machine, the headline figures with
    /// the targets, the scaling and search points, the flat-out runs, and
    /// notes on this run's points (capped warm-ups, unattributable
    /// messages, CPU by thread). How the benchmark measures is in
    /// docs/performance.md, written by hand.
    pub fn table(&self) -> String {
        let o = &self.options;
        let mut s = format!(
            "machine: {} cores ({}), load average (1/5/15 min) {} before, {} after; `twin-bench daemon{}{}`, whole run {:.0} s.\n\n",
            machine::cores(),
            machine::cpu_model(),
            self.load_before,
            self.load_after,
            if o.quick { " --quick" } else { "" },
            liveliness_flag(o),
            self.elapsed_s
        );
        s.push_str(&self.headline_table());
        s.push('\n');
        s.push_str(&self.points_table());
        if !self.capacity.is_empty() {
            s.push('\n');
            s.push_str(&self.flat_out_table());
        }
        s.push('\n');
        for n in self.notes() {
            s.push_str(&n);
            s.push('\n');
        }
        s
    }

    /// The headline figures beside the targets.
    fn headline_table(&self) -> String {
        let mut s =
            String::from("| measurement | figure | target | verdict |\n|---|---:|---|---|\n");
        let hz = self.options.rate_hz;
        match self.scaling_point(Path::Daemon, HEADLINE_VESSELS) {
            Some(d) => s.push_str(&self.headline_rows(d, hz)),
            None => {
                let _ = writeln!(
                    s,
                    "| daemon, 1,000 vessels: p99 GNSS publish -> fault receive | not run | < {TARGET_P99_MS} ms | missed |"
                );
            }
        }
        if let Some(r) = self.max_sustained(Path::Daemon) {
            let _ = writeln!(
                s,
                "| memory per vessel, daemon, at its largest sustained fleet ({}) | {} | | |",
                fleet_text(r),
                per_vessel_text(r)
            );
        }
        if let Some(r) = self.scaling_point(Path::Raw, HEADLINE_VESSELS) {
            let _ = writeln!(
                s,
                "| raw Zenoh, same fleet and payloads, no daemon: p50 / p99 / max | {} / {} / {} | | |",
                ms_text(r.latency.p50_ns),
                p99_text(r),
                ms_text(r.latency.max_ns)
            );
        }
        s.push_str(&self.rate_rows());
        s
    }

    /// The headline fleet's rows: latency against the target, throughput,
    /// CPU, memory and forecasts.
    fn headline_rows(&self, d: &PointResult, hz: f64) -> String {
        let mut s = String::new();
        let what = format!(
            "daemon, {} vessels x {hz} Hz ({} fixes/s + as many shaft-speed messages)",
            thousands(HEADLINE_VESSELS as u64),
            rate_text(HEADLINE_VESSELS as f64 * hz)
        );
        let _ = writeln!(
            s,
            "| {what}: p99 GNSS publish -> fault receive | {} | < {TARGET_P99_MS} ms{} | {} |",
            p99_text(d),
            if hz == 10.0 { "" } else { " (set for 10 Hz)" },
            verdict(self.headline_p99_met().unwrap_or(false))
        );
        let _ = writeln!(
            s,
            "| same: p50 / max latency | {} / {} | | |",
            ms_text(d.latency.p50_ns),
            ms_text(d.latency.max_ns)
        );
        let _ = writeln!(
            s,
            "| same: fixes sent / faults received per s; lost | {} / {}; {} of {} | | |",
            rate_text(d.offered_fixes_per_s),
            rate_text(d.received_per_s),
            thousands(d.lost()),
            thousands(d.fixes_sent)
        );
        let _ = writeln!(
            s,
            "| same: CPU of the process (daemon + generator + subscriber + Zenoh) | {} of one core | | |",
            cpu_text(d)
        );
        let _ = writeln!(
            s,
            "| same: RSS before the first message -> at the end; per vessel | {} -> {}; {} | | |",
            mb_text(d.rss_base_kib),
            mb_text(d.rss_end_kib),
            per_vessel_text(d)
        );
        let _ = writeln!(
            s,
            "| same: forecasts computed per s (each vessel's, every) | {} | | |",
            forecasts_text(d)
        );
        s
    }

    /// Each path's maximum sustained rate, their ratio against the target,
    /// and the flat-out capacity.
    fn rate_rows(&self) -> String {
        let mut s = String::new();
        let sustained_text = |p: Path| {
            self.max_sustained(p).map_or("none sustained".into(), |r| {
                format!(
                    "{}{}/s ({})",
                    if self.sustained_is_lower_bound(p) {
                        ">= "
                    } else {
                        ""
                    },
                    rate_text(r.delivered_per_s()),
                    fleet_text(r)
                )
            })
        };
        let _ = writeln!(
            s,
            "| maximum sustained rate, daemon (fixes in -> faults out) | {} | | |",
            sustained_text(Path::Daemon)
        );
        let _ = writeln!(
            s,
            "| maximum sustained rate, raw Zenoh (fixes) | {} | | |",
            sustained_text(Path::Raw)
        );
        let (ratio_text, ratio_verdict) = self.ratio_judged();
        let _ = writeln!(
            s,
            "| daemon / raw Zenoh, maximum sustained rate | {ratio_text} | >= {TARGET_RATIO} | {ratio_verdict} |"
        );
        if let (Some(d), Some(r)) = (
            self.capacity.iter().find(|r| r.spec.path == Path::Daemon),
            self.capacity.iter().find(|r| r.spec.path == Path::Raw),
        ) && r.received_per_s > 0.0
        {
            let _ = writeln!(
                s,
                "| flat-out capacity, daemon / raw Zenoh ({} vessels, back-pressure sets the pace) | {} / {} per s = {:.3} | | |",
                thousands(d.spec.vessels as u64),
                rate_text(d.received_per_s),
                rate_text(r.received_per_s),
                d.received_per_s / r.received_per_s
            );
        }
        s
    }

    /// Every paced point, scaling and search, daemon first, by fleet.
    fn points_table(&self) -> String {
        let mut s = String::from(
            "| vessels | path | run | fixes/s planned | sent | faults (raw: fixes) received/s | lost | p50 | p99 | max | CPU | warm-up | generator lag (max, window) | RSS before -> end | per vessel | forecasts/s | sustained |\n\
             |---:|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|\n",
        );
        let mut paced: Vec<(&str, &PointResult)> = self
            .scaling
            .iter()
            .map(|r| ("scaling", r))
            .chain(self.ramp.iter().map(|r| ("search", r)))
            .collect();
        paced.sort_by_key(|(_, r)| (r.spec.path == Path::Raw, r.spec.vessels));
        for (run, r) in paced {
            let _ = writeln!(
                s,
                "| {} | {} | {run} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} -> {} | {} | {} | {} |",
                thousands(r.spec.vessels as u64),
                path_text(r.spec.path),
                rate_text(r.planned_fixes_per_s.unwrap_or(0.0)),
                rate_text(r.offered_fixes_per_s),
                rate_text(r.received_per_s),
                lost_text(r),
                ms_text(r.latency.p50_ns),
                p99_text(r),
                ms_text(r.latency.max_ns),
                cpu_text(r),
                warmup_text(r),
                lag_text(r),
                mb_text(r.rss_base_kib),
                mb_text(r.rss_end_kib),
                per_vessel_text(r),
                forecasts_text(r),
                sustained_text(r)
            );
        }
        s
    }

    /// The flat-out runs.
    fn flat_out_table(&self) -> String {
        let mut s = String::from(
            "| path | fleet | fixes/s sent | received/s | p50 | p99 | CPU |\n|---|---|---:|---:|---:|---:|---:|\n",
        );
        for r in &self.capacity {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} | {} |",
                path_text(r.spec.path),
                fleet_text(r),
                rate_text(r.offered_fixes_per_s),
                rate_text(r.received_per_s),
                ms_text(r.latency.p50_ns),
                p99_text(r),
                cpu_text(r)
            );
        }
        s
    }

    /// Notes on this run's points: the load's sizes, CPU by thread, capped
    /// warm-ups, unattributable messages, generator-bound runs.
    fn notes(&self) -> Vec<String> {
        let mut notes = Vec::new();
        if let Some(r) = self.scaling.first().or(self.capacity.first()) {
            notes.push(format!(
                "Payloads: shaft speeds {:.0} B, fix {:.0} B, fault {:.0} B. Fleet: the simulated Otter's steady turn at {:.2} m/s (radius {:.0} m, shafts {:.0}/{:.0} rpm).",
                r.actuators_bytes_mean,
                r.gnss_bytes_mean,
                self.scaling
                    .iter()
                    .find(|r| r.spec.path == Path::Daemon)
                    .map_or(0.0, |r| r.received_bytes_mean),
                r.circle_speed_mps,
                r.circle_radius_m,
                r.circle_rpm[0],
                r.circle_rpm[1],
            ));
        }
        notes.extend(self.cpu_by_thread_note());
        for r in self.scaling.iter().chain(&self.ramp).chain(&self.capacity) {
            notes.extend(point_notes(r));
        }
        let generator_bound: Vec<String> = self
            .scaling
            .iter()
            .chain(&self.ramp)
            .filter(|r| limited_by_generator(r))
            .map(|r| {
                format!(
                    "{} {} (generator threads {:.0} % of a core)",
                    path_text(r.spec.path),
                    fleet_text(r),
                    r.generator_cpu_pct().unwrap_or(0.0)
                )
            })
            .collect();
        if !generator_bound.is_empty() {
            notes.push(format!(
                "Generator-bound (all sent was delivered in time, the plan not sent): {}; the path's maximum sustained rate is a lower bound (>=).",
                generator_bound.join("; ")
            ));
        }
        notes
    }

    /// CPU by thread group of the headline and flat-out points.
    fn cpu_by_thread_note(&self) -> Option<String> {
        let daemon = self.scaling.iter().chain(&self.capacity).filter(|r| {
            r.spec.path == Path::Daemon
                && (r.spec.vessels == HEADLINE_VESSELS || r.spec.rate_hz.is_none())
        });
        let raw = self.capacity.iter().filter(|r| r.spec.path == Path::Raw);
        let groups: Vec<String> = daemon
            .map(|r| format!("{}: {}", fleet_text(r), cpu_groups_text(r)))
            .chain(raw.map(|r| format!("raw Zenoh, {}: {}", fleet_text(r), cpu_groups_text(r))))
            .collect();
        (!groups.is_empty()).then(|| {
            format!(
                "CPU by thread (% of one core, live threads): {}.",
                groups.join("; ")
            )
        })
    }
}

/// The flag a run of `twin-bench daemon` had for the liveliness tokens.
fn liveliness_flag(o: &DaemonOptions) -> &'static str {
    if !o.vessel_liveliness {
        " --no-vessel-liveliness"
    } else if o.liveliness_outside_prefix {
        " --liveliness-outside-prefix"
    } else {
        ""
    }
}

fn verdict(ok: bool) -> &'static str {
    if ok { "met" } else { "missed" }
}

fn sustained_text(r: &PointResult) -> &'static str {
    if sustained(r) {
        "yes"
    } else if limited_by_generator(r) {
        "no: generator-bound"
    } else if !on_schedule(r) {
        "no: behind schedule"
    } else {
        "no"
    }
}

/// A point's own notes: a warm-up that reached its cap, messages the
/// subscriber could not attribute.
fn point_notes(r: &PointResult) -> Vec<String> {
    let mut notes = Vec::new();
    if r.warmup_capped {
        notes.push(format!(
            "{} {}: the warm-up reached its cap of {:.1} s with {} of the {} vessels heard from ({} by the end) and the generator {} behind its schedule; measured anyway.",
            path_text(r.spec.path),
            fleet_text(r),
            r.warmup_used_s,
            thousands(r.vessels_heard_at_start as u64),
            thousands(r.spec.vessels as u64),
            thousands(r.vessels_heard as u64),
            r.generator_lag_at_start_ms
                .map_or("-".into(), |l| format!("{l:.0} ms"))
        ));
    }
    if r.unparsable > 0 {
        notes.push(format!(
            "{} {}: {} messages the subscriber could not attribute{} (docs/known-issues.md).",
            path_text(r.spec.path),
            fleet_text(r),
            r.unparsable,
            r.unparsable_first
                .as_deref()
                .map_or(String::new(), |f| format!(" (the first: {f})"))
        ));
    }
    notes
}

fn warmup_text(r: &PointResult) -> String {
    format!(
        "{:.1} s{}",
        r.warmup_used_s,
        if r.warmup_capped { " (cap)" } else { "" }
    )
}

fn lag_text(r: &PointResult) -> String {
    r.generator_max_lag_ms.map_or("-".into(), |l| {
        if l < 1000.0 {
            format!("{l:.1} ms")
        } else {
            format!("{:.1} s", l / 1e3)
        }
    })
}

fn lost_text(r: &PointResult) -> String {
    if r.fixes_sent == 0 {
        return "-".into();
    }
    let lost = r.lost();
    if lost == 0 {
        "0".into()
    } else {
        format!(
            "{} ({:.1} %)",
            thousands(lost),
            100.0 * lost as f64 / r.fixes_sent as f64
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A raw Zenoh point as `daemon-point` prints it (4 vessels, 2 generator
    /// threads), with what it sent and the generator's CPU replaced.
    fn raw_point(sent_per_s: f64, generator_cpu_pct: f64) -> PointResult {
        let mut v: serde_json::Value = serde_json::from_str(
            r#"{"spec":{"path":"raw","vessels":4,"rate_hz":10.0,"warmup_s":0.5,"window_s":1.0,"grace_s":0.5,"vessel_liveliness":true},"circle_speed_mps":1.5,"circle_radius_m":16.2,"circle_rpm":[714.0,673.5],"warmup_used_s":0.5,"warmup_capped":false,"window_s":1.0,"fixes_sent":40,"actuators_sent":40,"planned_fixes_per_s":40.0,"offered_fixes_per_s":40.0,"received_per_s":40.0,"delivered":40,"repeats":0,"unparsable":0,"vessels_delivered":4,"vessels_heard":4,"vessels_heard_at_start":4,"per_vessel_delivered":[10,10,10,10],"latency":{"count":40,"min_ns":74554,"p50_ns":159232,"p90_ns":186880,"p99_ns":396288,"p999_ns":396288,"max_ns":396574,"mean_ns":161295.75},"generator_max_lag_ms":0.001,"cpu_pct_of_core":1.0,"cpu_pct_by_group":{"load generator":0.0},"rss_base_kib":15872,"rss_end_kib":15928,"gnss_bytes_mean":195.5,"actuators_bytes_mean":100.7,"received_bytes_mean":195.5,"daemon":null,"generator_threads":2,"forecasts_per_s":null}"#,
        )
        .unwrap();
        let sent = (sent_per_s as u64).into();
        v["fixes_sent"] = sent;
        v["delivered"] = (sent_per_s as u64).into();
        v["offered_fixes_per_s"] = sent_per_s.into();
        v["received_per_s"] = sent_per_s.into();
        v["latency"]["count"] = (sent_per_s as u64).into();
        v["cpu_pct_by_group"]["load generator"] = generator_cpu_pct.into();
        serde_json::from_value(v).unwrap()
    }

    /// With two generator threads, a run that could not send its plan is
    /// the generator's limit only when both threads were near a full core;
    /// with spare generator CPU it is the path's own limit.
    #[test]
    fn generator_bound_needs_every_generator_thread_busy() {
        assert!(sustained(&raw_point(40.0, 10.0)));
        // Sent 70 % of the plan, all delivered in time.
        assert!(limited_by_generator(&raw_point(28.0, 190.0)));
        assert!(!limited_by_generator(&raw_point(28.0, 98.0)));
        // Sent the plan but lost in the path: never the generator's limit.
        let mut lossy = raw_point(40.0, 190.0);
        lossy.delivered = 20;
        assert!(!sustained(&lossy) && !limited_by_generator(&lossy));
    }

    /// A run whose generator was seconds behind its schedule (working off a
    /// start-up backlog flat out, its fixes stamped only when published) is
    /// not sustained, however much it sent and delivered in the window; one
    /// a few milliseconds behind is. When its threads were busy it is the
    /// generator's limit.
    #[test]
    fn a_generator_behind_its_schedule_is_not_sustained() {
        let mut behind = raw_point(41.0, 10.0);
        behind.generator_max_lag_ms = Some(10_000.0);
        assert!(!sustained(&behind) && !limited_by_generator(&behind));
        behind
            .cpu_pct_by_group
            .insert("load generator".into(), 190.0);
        assert!(limited_by_generator(&behind));
        let mut on_time = raw_point(40.0, 10.0);
        on_time.generator_max_lag_ms = Some(SUSTAINED_GENERATOR_LAG_MS);
        assert!(sustained(&on_time));
        on_time.generator_max_lag_ms = Some(SUSTAINED_GENERATOR_LAG_MS + 1.0);
        assert!(!sustained(&on_time));
    }
}
