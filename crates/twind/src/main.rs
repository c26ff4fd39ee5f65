//! `twind`: parses the command line, starts tracing, loads the settings and
//! Zenoh's configuration, opens the session, starts the web page when asked
//! (`--web`, `--web-listen`, `[web]` in the settings; on by default in
//! `--demo` unless `--no-web`) and the metrics' own port when asked
//! (`--metrics-listen`, `[metrics] listen`), and runs the daemon (or the
//! demo, which tells systemd nothing) until
//! SIGINT or SIGTERM (a demo at a terminal keeps its page up after the
//! trials, until Ctrl-C); the web page stops with the daemon, and the Zenoh
//! session is closed last.

use std::io::IsTerminal;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context;
use clap::Parser;
use tokio_util::sync::CancellationToken;
use twin_zenoh::ZenohArgs;
use twind::settings::Settings;
use twind::web;

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
    /// The daemon's id, in its statistics key `{prefix}/@twind/{ID}/stats`
    /// (overrides `[daemon] id`; default: its Zenoh session id). Behind an
    /// access-controlled router, its log-in name.
    #[arg(long, value_name = "ID")]
    id: Option<String>,
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
    /// Serve the web page (live track, forecast, thruster health) on the
    /// settings' `web.listen` address (default 127.0.0.1:8080).
    #[arg(long)]
    web: bool,
    /// Serve the web page on this address (implies --web); port 0 picks a
    /// free one. The page's URL is printed.
    #[arg(long, value_name = "ADDR")]
    web_listen: Option<SocketAddr>,
    /// No web page, not even in --demo or with `web.enabled` in the settings.
    #[arg(long, conflicts_with_all = ["web", "web_listen"])]
    no_web: bool,
    /// Record the owned vessels' inputs and the twin's outputs into this
    /// MCAP file (JSON channels, a Foxglove location; docs/deploy.md),
    /// finished when the daemon stops.
    #[arg(long, value_name = "FILE", conflicts_with = "demo")]
    record: Option<PathBuf>,
    /// Serve the Prometheus metrics (`/metrics`) alone on this address
    /// (overrides `[metrics] listen`); they are also on the web page's port.
    #[arg(long, value_name = "ADDR")]
    metrics_listen: Option<SocketAddr>,
    #[command(flatten)]
    zenoh: ZenohArgs,
}

/// Events the daemon may be ahead of the web page's pump before the pump
/// skips some (the daemon never waits for the page).
const WEB_TAP_CAPACITY: usize = 16_384;

/// Where the web page is served, if it is.
fn web_listen(cli: &Cli, settings: &Settings) -> anyhow::Result<Option<SocketAddr>> {
    let enabled =
        !cli.no_web && (cli.web || cli.web_listen.is_some() || cli.demo || settings.web.enabled);
    if !enabled {
        return Ok(None);
    }
    match cli.web_listen {
        Some(a) => Ok(Some(a)),
        None => settings
            .web
            .listen
            .parse()
            .map(Some)
            .with_context(|| format!("web.listen {:?}", settings.web.listen)),
    }
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
    if let Some(listen) = cli.metrics_listen {
        s.metrics.listen = Some(listen);
    }
    if let Some(id) = &cli.id {
        twin_wire::keys::validate_vessel_id(id).with_context(|| format!("--id {id:?}"))?;
        s.daemon.id = Some(id.clone());
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

/// The web page, when asked for: the output tap the daemon copies into and
/// the running server.
async fn start_page(
    cli: &Cli,
    settings: &Settings,
    session: &zenoh::Session,
    latest: &twind::LatestStates,
    metrics: &twind::metrics::Metrics,
    token: &CancellationToken,
) -> anyhow::Result<(twind::OutputTap, Option<web::WebServer>)> {
    Ok(match web_listen(cli, settings)? {
        Some(listen) => {
            let (tx, _) = tokio::sync::broadcast::channel(WEB_TAP_CAPACITY);
            let sources = web::Sources {
                tap: tx.clone(),
                latest: latest.clone(),
                inputs: Some(web::InputFeed {
                    session: session.clone(),
                    keys: settings.keys.clone(),
                    own: settings.vessels.own.clone(),
                    max_payload_bytes: settings.max_payload_bytes,
                }),
                info: web::WebInfo::new(settings),
                metrics: metrics.clone(),
            };
            match web::start(listen, sources, token.clone()).await {
                Ok(page) => {
                    println!("twind web page: {}", page.url());
                    (Some(tx), Some(page))
                }
                // The demo's page is a default, not a request: without it
                // the demo still runs.
                Err(e) if cli.demo && cli.web_listen.is_none() && !cli.web => {
                    tracing::warn!(
                        "{e:#}; the demo runs without its page (--web-listen ADDR picks another address)"
                    );
                    (None, None)
                }
                Err(e) => return Err(e),
            }
        }
        None => (None, None),
    })
}

#[tokio::main]
async fn main() -> anyhow::Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info,zenoh=warn")),
        )
        .with_writer(std::io::stderr)
        // Colour only for a person at a terminal: a log file or a
        // journal gets plain text.
        .with_ansi(std::io::stderr().is_terminal())
        .init();
    let cli = Cli::parse();
    let settings = settings(&cli)?;
    let config = zenoh_config(&cli)?;
    let session = zenoh::open(config)
        .await
        .map_err(|e| anyhow::anyhow!("cannot open the Zenoh session: {e}"))?;
    let token = CancellationToken::new();
    tokio::spawn(shutdown_signal(token.clone()));
    let latest = twind::LatestStates::default();
    let metrics = twind::metrics::Metrics::default();
    let metrics_server = match settings.metrics.listen {
        Some(listen) => {
            let (local, task) =
                twind::metrics::serve(listen, metrics.clone(), token.clone()).await?;
            println!("twind metrics: http://{local}/metrics");
            Some(task)
        }
        None => None,
    };
    let (tap, page) = start_page(&cli, &settings, &session, &latest, &metrics, &token).await?;
    let result = if cli.demo {
        let options = twind::demo::DemoOptions {
            rate: cli.demo_rate,
            looping: cli.demo_loop,
        };
        let r = twind::demo::run(
            settings,
            session.clone(),
            options,
            tap,
            latest,
            metrics,
            token.clone(),
        )
        .await
        .map(|_| ());
        // Someone at a terminal may still be looking at the page: keep it
        // up. A script (no terminal) gets the demo's exit as before.
        if let Some(page) = &page
            && !token.is_cancelled()
            && std::io::stdout().is_terminal()
        {
            println!(
                "twind demo: the trials are over; the page stays up at {} until Ctrl-C",
                page.url()
            );
            token.cancelled().await;
        }
        r
    } else {
        twind::run(twind::RunConfig {
            tap,
            latest,
            metrics,
            notify: twind::notify::Notifier::from_env(),
            record: cli.record.clone(),
            ..twind::RunConfig::new(settings, session.clone(), token.clone())
        })
        .await
        .map(|summary| {
            if let Some(r) = summary.record {
                let messages: u64 = r.counts.values().sum();
                tracing::info!(
                    file = %r.path.display(),
                    messages,
                    dropped = r.dropped,
                    "recording finished"
                );
            }
        })
    };
    if let Some(page) = page {
        if page.skipped() > 0 {
            tracing::info!(
                skipped = page.skipped(),
                "web page: events skipped for slow pages"
            );
        }
        page.stopped(Duration::from_secs(2)).await;
    }
    if let Some(task) = metrics_server {
        let _ = tokio::time::timeout(Duration::from_secs(2), task).await;
    }
    // The session closes last, after every vessel has said its last words.
    if let Err(e) = session.close().await {
        tracing::warn!("closing the Zenoh session: {e}");
    }
    result
}
