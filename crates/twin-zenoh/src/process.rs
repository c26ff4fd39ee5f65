//! What every binary of the twin does the same way at start: logging to
//! stderr with `RUST_LOG` (or the binary's default filter), colours only on
//! a terminal; and reading `--prefix` (the key prefix).

use std::io::IsTerminal;

use tracing_subscriber::EnvFilter;
use twin_wire::KeySpace;

/// Sets up logging to stderr: `RUST_LOG` when set, else `default_filter`
/// (e.g. `"warn,twin_bridge=info"`).
pub fn init_logging(default_filter: &str) {
    tracing_subscriber::fmt()
        .with_env_filter(
            EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new(default_filter)),
        )
        .with_writer(std::io::stderr)
        .with_ansi(std::io::stderr().is_terminal())
        .init();
}

/// The clap value parser of `--prefix`.
pub fn key_space(text: &str) -> Result<KeySpace, String> {
    KeySpace::new(text).map_err(|e| format!("{e}: chunks of letters, digits, '-', '_', '.'"))
}
