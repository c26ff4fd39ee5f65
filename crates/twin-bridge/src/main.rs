//! `twin-bridge --vessel ID --source SPEC [--source SPEC ...]` plus Zenoh's
//! usual flags: reads the boat's sources live and publishes them as the
//! contract's payloads of one vessel; `twin-bridge bench` measures how many
//! NMEA 0183 sentences a second it forwards. Parses the arguments, sets up
//! tracing, opens the Zenoh session and calls [`twin_bridge::run`]; the
//! counts go to stderr once a second.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::Context;
use clap::{Parser, Subcommand};
use twin_bridge::spec::{NmeaPublish, SourceSpec, Transport};
use twin_bridge::{BridgeConfig, output::ZenohOutputs};
use twin_wire::{KeySpace, VesselId};
use twin_zenoh::ZenohArgs;

/// Reads a boat's NMEA 0183, NMEA 2000, MAVLink and gpsd sources live and
/// publishes them over Zenoh as the twin's input messages of one vessel
/// (see docs/bridge.md).
#[derive(Debug, Parser)]
#[command(name = "twin-bridge", version, args_conflicts_with_subcommands = true)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    #[command(flatten)]
    run: RunArgs,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Measures the NMEA 0183 sentences forwarded per second, UDP in and
    /// Zenoh out on loopback; prints each run and the median.
    Bench {
        /// Epochs of traffic per run (6 sentences each).
        #[arg(long, default_value_t = 20_000)]
        epochs: usize,
        /// Runs; the median is reported.
        #[arg(long, default_value_t = 5)]
        runs: usize,
        /// Publish the sentences as they came (`sentences`) or assembled
        /// fixes (`fixes`).
        #[arg(long, default_value = "fixes", value_parser = publish_mode)]
        publish: NmeaPublish,
    },
}

#[derive(Debug, clap::Args)]
struct RunArgs {
    /// The vessel id to publish as (letters, digits, `-`, `_`).
    #[arg(long, value_name = "ID")]
    vessel: Option<VesselId>,
    /// A source: FORMAT:TRANSPORT[:ADDRESS][,KEY=VALUE...], e.g.
    /// nmea0183:udp:10110, nmea0183:tcp:192.168.1.10:10110,
    /// nmea0183:serial:/dev/ttyUSB0,baud=4800, candump:can:can0,
    /// ydraw:udp:1456, actisense:tcp:HOST:PORT, mavlink:udp:14550,
    /// mavlink:serial:/dev/ttyACM0,baud=115200, gpsd (repeatable).
    #[arg(long = "source", value_name = "SPEC")]
    sources: Vec<SourceSpec>,
    /// The key prefix.
    #[arg(long, value_name = "PREFIX", default_value = "asv", value_parser = twin_zenoh::process::key_space)]
    prefix: KeySpace,
    /// The MAVLink motors and PWM -> thrust map (TOML; example:
    /// config/mavlink-otter.toml) [default: outputs 1 and 3, the Otter's map].
    #[arg(long, value_name = "FILE")]
    mavlink_config: Option<PathBuf>,
    /// Seconds of data looked at to choose the position, course and heading
    /// sources when several send them.
    #[arg(long, value_name = "S", default_value_t = 1.0)]
    decision_window_s: f64,
    /// Milliseconds a source must be quiet before its pending fix is
    /// published.
    #[arg(long, value_name = "MS", default_value_t = 200)]
    idle_flush_ms: u64,
    /// No counts on stderr (they are still published on the stats key).
    #[arg(long)]
    quiet: bool,
    #[command(flatten)]
    zenoh: ZenohArgs,
}

fn publish_mode(text: &str) -> Result<NmeaPublish, String> {
    match text {
        "fixes" => Ok(NmeaPublish::Fixes),
        "sentences" => Ok(NmeaPublish::Sentences),
        _ => Err(format!("{text:?} is neither fixes nor sentences")),
    }
}

#[tokio::main]
async fn main() -> ExitCode {
    let cli = Cli::parse();
    twin_zenoh::process::init_logging("warn,twin_bridge=info");
    let result = match cli.command {
        Some(Command::Bench {
            epochs,
            runs,
            publish,
        }) => tokio::task::spawn_blocking(move || bench(epochs, runs, publish))
            .await
            .map_err(anyhow::Error::from)
            .and_then(|r| r),
        None => bridge(cli.run).await,
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("twin-bridge: error: {error:#}");
            ExitCode::FAILURE
        }
    }
}

fn bench(epochs: usize, runs: usize, publish: NmeaPublish) -> anyhow::Result<()> {
    anyhow::ensure!(
        epochs > 0 && runs > 0,
        "--epochs and --runs must be positive"
    );
    println!(
        "twin-bridge bench: NMEA 0183 over UDP -> Zenoh put on loopback, {} sentences a run, publishing {}",
        epochs * 6,
        match publish {
            NmeaPublish::Fixes => "fixes",
            NmeaPublish::Sentences => "sentences",
        }
    );
    println!("| run | sent | decoded | Zenoh messages received | sentences/s |");
    println!("|---|---|---|---|---|");
    let mut run = 0;
    let report = twin_bridge::bench::bench(epochs, runs, publish, |f| {
        run += 1;
        println!(
            "| {run} | {} | {} | {} | {:.0} |",
            f.sent, f.forwarded, f.received, f.sentences_per_s
        );
    })?;
    println!("median: {:.0} sentences/s", report.median_sentences_per_s());
    Ok(())
}

async fn bridge(args: RunArgs) -> anyhow::Result<()> {
    let vessel = args
        .vessel
        .context("--vessel ID is required (or a subcommand: bench)")?;
    anyhow::ensure!(
        !args.sources.is_empty(),
        "at least one --source is required (see --help)"
    );
    anyhow::ensure!(
        args.decision_window_s.is_finite() && args.decision_window_s >= 0.0,
        "--decision-window-s {} is not a number of seconds >= 0",
        args.decision_window_s
    );
    if !cfg!(target_os = "linux")
        && let Some(s) = args
            .sources
            .iter()
            .find(|s| matches!(s.transport, Transport::Can { .. }))
    {
        anyhow::bail!("--source {s}: SocketCAN interfaces can only be read on Linux");
    }
    let mut config = BridgeConfig::new(vessel.clone(), args.sources);
    config.keys = args.prefix;
    config.assembler.decision_window_s = args.decision_window_s;
    config.idle_flush = Duration::from_millis(args.idle_flush_ms);
    if let Some(path) = &args.mavlink_config {
        config.read.mavlink = twin_bridge::mavlink_config::load(path)?;
    }
    let zenoh_config = args.zenoh.to_config()?;
    let session = zenoh::open(zenoh_config)
        .await
        .map_err(|e| anyhow::anyhow!("cannot open the Zenoh session: {e}"))?;
    let outputs = ZenohOutputs::declare(&session, &config.keys, &vessel)
        .map_err(|e| anyhow::anyhow!("cannot declare the publishers: {e}"))?;
    let stop = Arc::new(AtomicBool::new(false));
    let signal = stop.clone();
    tokio::spawn(async move {
        shutdown_signal().await;
        signal.store(true, Ordering::Relaxed);
    });
    let quiet = args.quiet;
    let stats = tokio::task::spawn_blocking(move || {
        twin_bridge::run(&config, Arc::new(outputs), stop, |stats| {
            if !quiet {
                for source in &stats.sources {
                    eprintln!("{source}");
                }
            }
        })
    })
    .await??;
    let published: u64 = stats.sources.iter().map(|s| s.published.total()).sum();
    println!(
        "twin-bridge: published {published} messages from {} sources in {:.1} s",
        stats.sources.len(),
        stats.uptime_s
    );
    session
        .close()
        .await
        .map_err(|e| anyhow::anyhow!("closing the Zenoh session: {e}"))?;
    Ok(())
}

/// Ctrl-C or SIGTERM (what `docker stop` sends).
async fn shutdown_signal() {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{SignalKind, signal};
        match signal(SignalKind::terminate()) {
            Ok(mut term) => {
                tokio::select! {
                    _ = tokio::signal::ctrl_c() => {}
                    _ = term.recv() => {}
                }
            }
            Err(_) => {
                let _ = tokio::signal::ctrl_c().await;
            }
        }
    }
    #[cfg(not(unix))]
    {
        let _ = tokio::signal::ctrl_c().await;
    }
}
