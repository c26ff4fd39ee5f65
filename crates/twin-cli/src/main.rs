//! `twin`: the offline command-line tool of the USV twin. Parses the command
//! line and calls the library (`twin_cli`).

use clap::{Parser, Subcommand};

/// The USV twin, offline: simulate trials, analyse and diagnose logs, report.
#[derive(Debug, Parser)]
#[command(name = "twin", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Reports generated from the simulator (the README's result tables).
    Report {
        #[command(subcommand)]
        what: Report,
    },
}

#[derive(Debug, Subcommand)]
enum Report {
    /// The seed's sea-trial matrix re-run in the simulator: the seed's
    /// published figures, the seed's method and the extended twin (markdown).
    Trials {
        /// Noise seeds per cell.
        #[arg(long, default_value_t = 3)]
        seeds: u64,
    },
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Report {
            what: Report::Trials { seeds },
        } => {
            print!("{}", twin_cli::trials::markdown_report(seeds));
        }
    }
    Ok(())
}
