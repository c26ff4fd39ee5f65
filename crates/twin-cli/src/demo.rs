//! The bundled demo trial for the daemon's demo: the Otter doing repeated
//! S-turns for five minutes in harbour water with a 25 % loss on its port
//! propeller from the start (`config/scenarios/demo_broken-port.toml`), and
//! its simulated log as JSON lines (`data/demo/otter-broken-port.jsonl`),
//! written by
//!
//! ```sh
//! twin simulate --scenario config/scenarios/demo_broken-port.toml \
//!     --out data/demo/otter-broken-port.jsonl
//! ```
//!
//! run from the workspace root. A test regenerates the log in memory and
//! compares it byte for byte with the committed file, so the two cannot
//! drift apart.

use std::path::PathBuf;

/// The demo scenario, relative to the workspace root.
pub const SCENARIO: &str = "config/scenarios/demo_broken-port.toml";

/// The demo log, relative to the workspace root.
pub const LOG: &str = "data/demo/otter-broken-port.jsonl";

/// The true port loss of the demo.
pub const PORT_LOSS: f64 = 0.25;

/// The command that regenerates the demo log (from the workspace root).
pub const REGENERATE: &str = "cargo run --release -p twin-cli --bin twin -- simulate --scenario config/scenarios/demo_broken-port.toml --out data/demo/otter-broken-port.jsonl";

/// The workspace root this crate was built in.
pub fn workspace_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}
