//! `twin-replay LOG --vessel ID [--rate N|max] [--start S] [--duration S]
//! [--loop N] [--wait S] [--prefix asv]` plus Zenoh's usual flags: publishes a recorded
//! log as the contract's GNSS and actuator messages. Parses its arguments,
//! sets up tracing and calls [`twin_replay::run`]; progress goes to stderr
//! about once a second, the summary to stdout.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::Parser;
use twin_replay::{Rate, ReplayOptions};
use twin_wire::{AssemblerConfig, KeySpace, VesselId};
use twin_zenoh::ZenohArgs;

/// Publishes a recorded log (any format the twin reads, picked by content:
/// NMEA 0183, NMEA 2000 captures, MAVLink `.tlog`, gpsd JSON, JSON lines,
/// or an MCAP recording's input channels) over Zenoh as the twin's input
/// messages, with the original time stamps and `replay: true`.
#[derive(Debug, Parser)]
#[command(name = "twin-replay", version)]
struct Cli {
    /// The log file.
    log: PathBuf,
    /// The vessel id to publish as (letters, digits, `-`, `_`).
    #[arg(long, value_name = "ID")]
    vessel: VesselId,
    /// N times the recorded pace, or `max`: as fast as the receivers keep
    /// up, nothing dropped.
    #[arg(long, value_name = "N|max", default_value = "1")]
    rate: Rate,
    /// Start this many log seconds after the first record.
    #[arg(long, value_name = "S", default_value = "0", value_parser = non_negative_seconds, allow_negative_numbers = true)]
    start: f64,
    /// Publish this many log seconds from the start [default: to the end].
    #[arg(long, value_name = "S", value_parser = positive_seconds, allow_negative_numbers = true)]
    duration: Option<f64>,
    /// Passes over the log (0: until interrupted).
    #[arg(long = "loop", value_name = "N", default_value_t = 1)]
    loops: u32,
    /// Wait up to S seconds for a subscriber to the fixes before publishing
    /// anything (0: publish at once, even to nobody).
    #[arg(long, value_name = "S", default_value_t = twin_replay::replay::DEFAULT_WAIT_FOR_SUBSCRIBER_S, value_parser = non_negative_seconds, allow_negative_numbers = true)]
    wait: f64,
    /// The key prefix.
    #[arg(long, value_name = "PREFIX", default_value = "asv", value_parser = twin_zenoh::process::key_space)]
    prefix: KeySpace,
    #[command(flatten)]
    zenoh: ZenohArgs,
}

fn seconds(text: &str) -> Result<f64, String> {
    let s: f64 = text
        .parse()
        .map_err(|_| format!("{text:?} is not a number of seconds"))?;
    if s.is_finite() {
        Ok(s)
    } else {
        Err(format!("{text} is not a finite number of seconds"))
    }
}

fn non_negative_seconds(text: &str) -> Result<f64, String> {
    let s = seconds(text)?;
    if s >= 0.0 {
        Ok(s)
    } else {
        Err(format!("{text} is negative"))
    }
}

fn positive_seconds(text: &str) -> Result<f64, String> {
    let s = seconds(text)?;
    if s > 0.0 {
        Ok(s)
    } else {
        Err(format!("{text} is not greater than 0"))
    }
}

#[tokio::main]
async fn main() -> ExitCode {
    let cli = Cli::parse();
    twin_zenoh::process::init_logging("warn,twin_replay=info");
    match replay(cli).await {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("twin-replay: error: {error:#}");
            ExitCode::FAILURE
        }
    }
}

async fn replay(cli: Cli) -> anyhow::Result<()> {
    let config = cli.zenoh.to_config()?;
    let options = ReplayOptions {
        keys: cli.prefix,
        vessel: cli.vessel,
        rate: cli.rate,
        start_offset_s: cli.start,
        duration_s: cli.duration,
        loops: cli.loops,
        assembler: AssemblerConfig::default(),
        wait_for_subscriber_s: cli.wait,
    };
    let shutdown = async {
        if tokio::signal::ctrl_c().await.is_err() {
            // No signal handling: run to the end.
            std::future::pending::<()>().await;
        }
    };
    let summary = twin_replay::run(
        config,
        &cli.log,
        &options,
        |progress| eprintln!("{progress}"),
        shutdown,
    )
    .await
    .with_context(|| format!("replaying {}", cli.log.display()))?;
    println!("{summary}");
    Ok(())
}
