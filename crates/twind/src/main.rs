//! `twind`: parses the command line, starts tracing, loads the settings and
//! Zenoh's configuration, opens the session, and runs the daemon (or the
//! demo) until SIGINT or SIGTERM; the Zenoh session is closed last.

use std::path::PathBuf;

use anyhow::Context;
use clap::Parser;
use tokio_util::sync::CancellationToken;
use twin_replay::zenoh_cli::ZenohArgs;
use twind::settings::Settings;

/// The live digital twin of unmanned surface vessels, over Zenoh.
#[derive(Debug, Parser)]
#[command(name = "twind", version, about)]
struct Cli {
    /// twind's own settings (TOML); default: config/twind.toml when it
    /// exists, else built-in defaults.
    #[arg(long, value_name = "FILE")]
    settings: Option<PathBuf>,
    /// Keep calibrations in this directory (overrides the settings).
    #[arg(long, value_name = "DIR")]
    state_dir: Option<PathBuf>,
    /// Run the demo: an embedded Zenoh peer, two bundled trials replayed
    /// through it, live per-thruster estimates printed.
    #[arg(long)]
    demo: bool,
    /// Demo: replay pace, times the recorded pace.
    #[arg(long, default_value_t = 5.0, requires = "demo")]
    demo_rate: f64,
    /// Demo: replay the trials over and over until stopped.
    #[arg(long, requires = "demo")]
    demo_loop: bool,
    #[command(flatten)]
    zenoh: ZenohArgs,
}

fn settings(cli: &Cli) -> anyhow::Result<Settings> {
    let default = PathBuf::from("config/twind.toml");
    let mut s = match &cli.settings {
        Some(path) => Settings::from_file(path)?,
        None if default.exists() => Settings::from_file(&default)?,
        None => Settings::default(),
    };
    if let Some(dir) = &cli.state_dir {
        s.persistence.dir = Some(dir.clone());
    }
    Ok(s)
}

fn zenoh_config(cli: &Cli) -> anyhow::Result<zenoh::Config> {
    let mut args = cli.zenoh.clone();
    if cli.demo {
        // The demo's peer is embedded and private: no scouting, no listening
        // unless asked.
        args.no_multicast_scouting = true;
    } else if args.config.is_none() {
        let default = PathBuf::from("config/zenoh.json5");
        if default.exists() {
            args.config = Some(default);
        }
    }
    args.to_config().context("Zenoh configuration")
}

async fn shutdown_signal(token: CancellationToken) {
    let ctrl_c = tokio::signal::ctrl_c();
    #[cfg(unix)]
    {
        let mut term =
            match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
                Ok(t) => t,
                Err(e) => {
                    tracing::error!("cannot listen for SIGTERM: {e}");
                    let _ = ctrl_c.await;
                    token.cancel();
                    return;
                }
            };
        tokio::select! {
            _ = ctrl_c => tracing::info!("SIGINT: shutting down"),
            _ = term.recv() => tracing::info!("SIGTERM: shutting down"),
        }
    }
    #[cfg(not(unix))]
    {
        let _ = ctrl_c.await;
    }
    token.cancel();
}

#[tokio::main]
async fn main() -> anyhow::Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info,zenoh=warn")),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    let settings = settings(&cli)?;
    let config = zenoh_config(&cli)?;
    let session = zenoh::open(config)
        .await
        .map_err(|e| anyhow::anyhow!("cannot open the Zenoh session: {e}"))?;
    let token = CancellationToken::new();
    tokio::spawn(shutdown_signal(token.clone()));
    let result = if cli.demo {
        let options = twind::demo::DemoOptions {
            rate: cli.demo_rate,
            looping: cli.demo_loop,
        };
        twind::demo::run(
            settings,
            session.clone(),
            options,
            None,
            Default::default(),
            token.clone(),
        )
        .await
        .map(|_| ())
    } else {
        twind::run(settings, session.clone(), token.clone())
            .await
            .map(|_| ())
    };
    // The session closes last, after every vessel has said its last words.
    if let Err(e) = session.close().await {
        tracing::warn!("closing the Zenoh session: {e}");
    }
    result
}
