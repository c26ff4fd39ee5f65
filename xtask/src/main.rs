//! `cargo xtask`: the repository's tooling. Parses the command line and
//! calls the library; every table goes to standard output as markdown.

use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::{Parser, Subcommand};
use twin_cli::analyze::AnalyzeOptions;
use xtask::generated::{self, BLOCKS};

/// The repository's tooling: the documentation's tables.
#[derive(Debug, Parser)]
#[command(name = "cargo xtask", about)]
struct Cli {
    #[command(subcommand)]
    command: Task,
}

#[derive(Debug, Subcommand)]
enum Task {
    /// The seed's sea-trial matrix re-run in the simulator: the seed's
    /// published peaks, the seed's method and the extended twin.
    Trials {
        /// Noise seeds per cell.
        #[arg(long, default_value_t = 3)]
        seeds: u64,
    },
    /// Prediction after calibration, as the seed's Table 4.9.
    Prediction {
        /// Noise seeds per horizon.
        #[arg(long, default_value_t = 3)]
        seeds: u64,
    },
    /// `twin analyze` over every real log of a directory.
    RealLogs {
        /// The directory of logs.
        #[arg(long, default_value = xtask::real_logs::DEFAULT_DIR)]
        dir: PathBuf,
    },
    /// `twin diagnose` over every real log of a directory, with the
    /// instrument's own current beside the twin's where a log has it.
    DiagnoseReal {
        /// The directory of logs.
        #[arg(long, default_value = xtask::real_logs::DEFAULT_DIR)]
        dir: PathBuf,
    },
    /// Regenerates the generated blocks of the docs from their commands
    /// (all of them, or those named). Benchmarks among them take minutes.
    Docs {
        /// Only these blocks.
        names: Vec<String>,
        /// List the blocks, their files and commands, and run nothing.
        #[arg(long)]
        list: bool,
    },
    /// Writes the JSON Schema of every payload to docs/schemas/ (from the
    /// payload types, `twin_wire::schema`).
    Schemas,
}

/// The repository root: where `cargo xtask` was run from, or above it.
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map_or_else(|| PathBuf::from("."), Path::to_path_buf)
}

fn diagnose_config() -> twin_core::diagnose::DiagnoseConfig {
    twin_core::diagnose::DiagnoseConfig {
        threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
        ..Default::default()
    }
}

fn docs(names: Vec<String>, list: bool) -> anyhow::Result<()> {
    if list {
        for b in BLOCKS {
            println!("{:<16} {:<22} {}", b.name, b.file, b.command);
        }
        return Ok(());
    }
    let wanted: Vec<&generated::Block> = if names.is_empty() {
        BLOCKS.iter().collect()
    } else {
        names
            .iter()
            .map(|n| generated::block(n))
            .collect::<Result<_, _>>()?
    };
    let root = root();
    for b in wanted {
        eprintln!("xtask docs: {} ({})", b.name, b.command);
        generated::regenerate(&root, b)?;
    }
    Ok(())
}

/// Writes every payload's schema to `docs/schemas/`, removing schema
/// files no payload has any more.
fn schemas() -> anyhow::Result<()> {
    let dir = root().join(xtask::SCHEMA_DIR);
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let schemas = twin_wire::schema::all();
    for entry in std::fs::read_dir(&dir)? {
        let path = entry?.path();
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if name.ends_with(".schema.json") && !schemas.iter().any(|s| s.file_name() == name) {
            std::fs::remove_file(&path)?;
            eprintln!("xtask schemas: removed {}", path.display());
        }
    }
    for s in &schemas {
        let path = dir.join(s.file_name());
        std::fs::write(&path, s.file_text())
            .with_context(|| format!("writing {}", path.display()))?;
        eprintln!("xtask schemas: {}", path.display());
    }
    Ok(())
}

fn main() -> anyhow::Result<()> {
    match Cli::parse().command {
        Task::Trials { seeds } => print!("{}", xtask::trials::matrix_markdown(seeds)),
        Task::Prediction { seeds } => print!("{}", xtask::trials::prediction_markdown(seeds)),
        Task::RealLogs { dir } => {
            let dir = root().join(dir);
            let logs = xtask::real_logs::analyze_dir(&dir, &AnalyzeOptions::default())
                .with_context(|| format!("analysing the logs in {}", dir.display()))?;
            print!("{}", xtask::real_logs::markdown_table(&logs));
        }
        Task::DiagnoseReal { dir } => {
            let dir = root().join(dir);
            let config = diagnose_config();
            let logs = xtask::diagnose_real::diagnose_dir(&dir, &config)
                .with_context(|| format!("diagnosing the logs of {}", dir.display()))?;
            print!("{}", xtask::diagnose_real::markdown(&logs));
            let yaw_rate = xtask::diagnose_real::yaw_rate_comparison(&dir, &logs, &config)
                .with_context(|| {
                    format!(
                        "diagnosing the logs of {} without their yaw rates",
                        dir.display()
                    )
                })?;
            println!();
            print!("{}", xtask::diagnose_real::yaw_rate_markdown(&yaw_rate));
        }
        Task::Docs { names, list } => docs(names, list)?,
        Task::Schemas => schemas()?,
    }
    Ok(())
}
