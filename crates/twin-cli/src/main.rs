//! `twin`: the offline command-line tool of the USV twin. Parses the command
//! line and calls the library (`twin_cli`); errors leave as one line,
//! `error: context: cause: ...`, with exit status 1.

use std::io::Write;
use std::path::{Path, PathBuf};

use std::process::ExitCode;

use anyhow::Context;
use clap::{Parser, Subcommand};
use twin_cli::analyze::{AnalyzeOptions, analyze_path, load_truth, parse_source};
use twin_cli::simulate::{OutputFormat, SimulateRequest, simulate_to_files};
use twin_wire::profile::VesselProfile;

/// The USV twin, offline: simulate trials, analyse and diagnose logs.
#[derive(Debug, Parser)]
#[command(name = "twin", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Runs a simulator scenario and writes what its sensors measured as a
    /// log (NMEA 0183 or JSON lines), and optionally the true state.
    Simulate {
        /// The scenario file (TOML, see config/scenarios/README.md).
        #[arg(long)]
        scenario: PathBuf,
        /// The log to write: .nmea/.log/.txt for NMEA 0183, .jsonl for JSON lines.
        #[arg(long)]
        out: PathBuf,
        /// The true state as JSON lines (one sample per GNSS instant).
        #[arg(long)]
        truth: Option<PathBuf>,
        /// The log format, overriding the file name: nmea or jsonl.
        #[arg(long, value_parser = ["nmea", "jsonl"])]
        format: Option<String>,
    },
    /// Runs the twin over a log (NMEA 0183, canboat NMEA 2000 or JSON lines)
    /// and reports its estimates, their quality and the thruster faults.
    Analyze {
        /// The log.
        log: PathBuf,
        /// Print one JSON object (schema: twin_cli::analyze) instead of text.
        #[arg(long)]
        json: bool,
        /// Write SVG figures (track, faults, prediction) into this directory.
        #[arg(long)]
        plot: Option<PathBuf>,
        /// GNSS position source: best, an NMEA 2000 address, or an NMEA 0183 talker.
        #[arg(long, default_value = "best")]
        source: String,
        /// A truth file (from `twin simulate --truth`) to score the estimates.
        #[arg(long)]
        truth: Option<PathBuf>,
        /// The vessel's profile (TOML, docs/profiles.md); the Otter's by default.
        #[arg(long, value_name = "FILE")]
        profile: Option<PathBuf>,
        /// Record the inputs and the twin's outputs into this MCAP file
        /// (JSON channels, a Foxglove location; vessel `log`).
        #[arg(long, value_name = "FILE")]
        mcap: Option<PathBuf>,
    },
    /// Shows what the twin's model gets wrong on a log, names the cause,
    /// extends the model and measures the gain on held-out data.
    Diagnose {
        /// The log.
        log: PathBuf,
        /// Print one JSON object (schema: twin_cli::diagnose) instead of text.
        #[arg(long)]
        json: bool,
        /// Write SVG figures of the residuals before and after into this directory.
        #[arg(long)]
        plot: Option<PathBuf>,
        /// GNSS position source: best, an NMEA 2000 address, or an NMEA 0183 talker.
        #[arg(long, default_value = "best")]
        source: String,
        /// The vessel's profile (TOML, docs/profiles.md); the Otter's by default.
        #[arg(long, value_name = "FILE")]
        profile: Option<PathBuf>,
        /// Write the profile with the findings that describe the vessel
        /// carried into it (the antenna's position from a lever arm; the
        /// surge damping, yaw damping and mass scales) to this file, for the
        /// live twin and the next diagnosis.
        #[arg(long, value_name = "FILE")]
        out: Option<PathBuf>,
        /// The written profile's name (default: the profile's, ending in
        /// "-diagnosed").
        #[arg(long, requires = "out")]
        name: Option<String>,
    },
    /// Fits a vessel profile's mass and damping from a trial of the healthy
    /// vessel (steps of thrust, turns both ways; docs/identification.md),
    /// reports each with its uncertainty and the held-out gain, and writes
    /// the identified profile.
    Identify {
        /// The trial's log, with propeller speeds.
        log: PathBuf,
        /// The starting profile (TOML); the Otter's by default. Its thrust
        /// coefficients set the force scale and are kept.
        #[arg(long, value_name = "FILE")]
        profile: Option<PathBuf>,
        /// The identified profile's name.
        #[arg(long, default_value = "identified")]
        name: String,
        /// Where to write the identified profile (default: NAME.toml).
        #[arg(long, value_name = "FILE")]
        out: Option<PathBuf>,
        /// Print one JSON object (schema: twin_cli::identify) instead of text.
        #[arg(long)]
        json: bool,
        /// GNSS position source: best, an NMEA 2000 address, or an NMEA 0183 talker.
        #[arg(long, default_value = "best")]
        source: String,
    },
}

/// The profile at `path`, or the Otter's.
fn load_profile(path: Option<&Path>) -> anyhow::Result<VesselProfile> {
    match path {
        Some(p) => VesselProfile::from_file(p).with_context(|| format!("profile {}", p.display())),
        None => Ok(VesselProfile::otter()),
    }
}

/// The diagnosis settings of the command line: the defaults, on every core.
fn diagnose_config() -> twin_core::diagnose::DiagnoseConfig {
    twin_core::diagnose::DiagnoseConfig {
        threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
        ..Default::default()
    }
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", one_line(&e));
            ExitCode::FAILURE
        }
    }
}

/// The error and its causes on one line, each cause once (a library error
/// that quotes its source in its own message is not repeated).
fn one_line(e: &anyhow::Error) -> String {
    let mut line = e.to_string();
    for cause in e.chain().skip(1) {
        let text = cause.to_string();
        if !line.contains(&text) {
            line.push_str(": ");
            line.push_str(&text);
        }
    }
    line
}

/// `twin analyze`.
fn analyze(
    log: &Path,
    json: bool,
    plot: Option<PathBuf>,
    source: &str,
    truth: Option<PathBuf>,
    mcap: Option<PathBuf>,
    profile: Option<&Path>,
) -> anyhow::Result<()> {
    let mut options = AnalyzeOptions {
        source: parse_source(source)?,
        profile: load_profile(profile)?,
        keep_series: plot.is_some(),
        mcap,
        ..AnalyzeOptions::default()
    };
    if let Some(t) = &truth {
        options.truth = Some(load_truth(t)?);
    }
    let analysis =
        analyze_path(log, &options).with_context(|| format!("analysing {}", log.display()))?;
    let mut stdout = std::io::stdout().lock();
    if json {
        writeln!(stdout, "{}", analysis.to_json())?;
    } else {
        write!(stdout, "{}", analysis.to_text())?;
    }
    if let Some(dir) = plot {
        let paths = twin_cli::plots::write_plots(&analysis, &dir)
            .with_context(|| format!("writing figures into {}", dir.display()))?;
        for p in paths {
            eprintln!("wrote {}", p.display());
        }
    }
    Ok(())
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Simulate {
            scenario,
            out,
            truth,
            format,
        } => simulate(scenario, out, truth, format)?,
        Command::Analyze {
            log,
            json,
            plot,
            source,
            truth,
            profile,
            mcap,
        } => analyze(&log, json, plot, &source, truth, mcap, profile.as_deref())?,
        Command::Diagnose {
            log,
            json,
            plot,
            source,
            profile,
            out,
            name,
        } => {
            let profile = load_profile(profile.as_deref())?;
            let report = twin_cli::diagnose::diagnose_path(
                &log,
                parse_source(&source)?,
                &diagnose_config(),
                &profile,
            )
            .with_context(|| format!("diagnosing {}", log.display()))?;
            let mut stdout = std::io::stdout().lock();
            if json {
                writeln!(stdout, "{}", serde_json::to_string_pretty(&report)?)?;
            } else {
                write!(stdout, "{}", twin_cli::diagnose::render_text(&report))?;
            }
            if let Some(dir) = plot {
                let paths = twin_cli::diagnose::write_plots(&report, &dir)
                    .with_context(|| format!("writing figures into {}", dir.display()))?;
                for p in paths {
                    eprintln!("wrote {}", p.display());
                }
            }
            if let Some(out) = out {
                let name =
                    name.unwrap_or_else(|| twin_cli::diagnose::diagnosed_name(&profile.name));
                write_diagnosed_profile(&profile, &report, &name, &out)?;
            }
        }
        Command::Identify {
            log,
            profile,
            name,
            out,
            json,
            source,
        } => identify(&log, profile.as_deref(), &name, out, json, &source)?,
    }
    Ok(())
}

/// `twin diagnose --out`: the profile with the findings that describe the
/// vessel, written to `out`; what was and was not carried, on stderr.
fn write_diagnosed_profile(
    start: &VesselProfile,
    report: &twin_cli::diagnose::DiagnoseReport,
    name: &str,
    out: &Path,
) -> anyhow::Result<()> {
    let diagnosed =
        twin_cli::diagnose::profile_with_findings(start, &report.findings, &report.log, name);
    diagnosed
        .profile
        .validate()
        .with_context(|| format!("the profile with the findings of {}", report.log))?;
    std::fs::write(out, diagnosed.profile.to_toml())
        .with_context(|| format!("writing {}", out.display()))?;
    eprintln!("wrote {} (profile {})", out.display(), name);
    if diagnosed.carried.is_empty() {
        eprintln!("  carried      nothing: no finding describes the vessel itself");
    }
    for line in &diagnosed.carried {
        eprintln!("  carried      {line}");
    }
    if !diagnosed.not_carried.is_empty() {
        eprintln!(
            "  not carried  {} (a sensor, the water, a propeller, or off the hull: not the vessel's profile)",
            diagnosed.not_carried.join(", ")
        );
    }
    Ok(())
}

/// `twin identify`: fits, writes the profile, reports.
fn identify(
    log: &Path,
    profile: Option<&Path>,
    name: &str,
    out: Option<PathBuf>,
    json: bool,
    source: &str,
) -> anyhow::Result<()> {
    let start = load_profile(profile)?;
    let config = twin_core::diagnose::IdentifyConfig::default();
    let report =
        twin_cli::identify::identify_path(log, parse_source(source)?, &start, name, &config)
            .with_context(|| format!("identifying from {}", log.display()))?;
    report
        .identified
        .validate()
        .with_context(|| format!("the profile identified from {}", log.display()))?;
    let out = out.unwrap_or_else(|| PathBuf::from(format!("{name}.toml")));
    std::fs::write(&out, report.identified.to_toml())
        .with_context(|| format!("writing {}", out.display()))?;
    let mut stdout = std::io::stdout().lock();
    if json {
        writeln!(stdout, "{}", serde_json::to_string_pretty(&report)?)?;
    } else {
        write!(stdout, "{}", twin_cli::identify::render_text(&report))?;
    }
    eprintln!("wrote {}", out.display());
    Ok(())
}

/// `twin simulate`: writes the log (and the truth), says what it wrote.
fn simulate(
    scenario: PathBuf,
    out: PathBuf,
    truth: Option<PathBuf>,
    format: Option<String>,
) -> anyhow::Result<()> {
    let format = format
        .map(|f| f.parse::<OutputFormat>())
        .transpose()
        .context("--format")?;
    let request = SimulateRequest {
        scenario: scenario.clone(),
        out: out.clone(),
        format,
        truth: truth.clone(),
    };
    let summary = simulate_to_files(&request)
        .with_context(|| format!("simulating {}", scenario.display()))?;
    eprintln!(
        "wrote {} ({} lines: {} fixes, {} with heading, {} shaft-speed samples{}){}",
        out.display(),
        summary.lines,
        summary.fixes,
        summary.fixes_with_heading,
        summary.propeller_samples,
        if summary.fixes_without_course > 0 {
            format!(
                "; {} fixes without COG/SOG left out (JSON lines require them)",
                summary.fixes_without_course
            )
        } else {
            String::new()
        },
        truth
            .map(|t| format!(
                " and {} ({} truth samples)",
                t.display(),
                summary.truth_samples
            ))
            .unwrap_or_default()
    );
    Ok(())
}
