//! The generated blocks of the documentation (`cargo xtask docs`): each
//! table or figure that a command prints sits in its doc between
//! `<!-- BEGIN name -->` and `<!-- END name -->`, under a line naming the
//! command, and is replaced by that command's output when regenerated.
//! Prose around the blocks is written by hand; nothing here writes any.

use std::path::Path;

/// How a command's output becomes a block.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shape {
    /// Markdown as printed.
    Markdown,
    /// Plain text, put in a `text` code fence.
    Fenced,
    /// The web fleet test's JSON measurement line, made a table
    /// ([`fleet_table`]).
    FleetMeasurement,
}

/// One generated block.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Block {
    /// The name in its markers.
    pub name: &'static str,
    /// The file that holds it, from the repository root.
    pub file: &'static str,
    /// The shell command (run at the repository root) whose standard output
    /// is the block.
    pub command: &'static str,
    /// How the output becomes the block.
    pub shape: Shape,
}

/// Every generated block, in the order `cargo xtask docs` makes them.
pub const BLOCKS: &[Block] = &[
    Block {
        name: "demo",
        file: "README.md",
        command: "cargo run --release -q -p twind -- --demo --no-web --demo-rate 50 2>/dev/null",
        shape: Shape::Fenced,
    },
    Block {
        name: "seed-cases",
        file: "docs/accuracy.md",
        command: "cargo test --release -q -p twin-core --test seed_cases -- --nocapture --test-threads=1 2>/dev/null \
                  | grep -E '^[.]?(case|authors|zero)' | sed 's/^[.]//'",
        shape: Shape::Fenced,
    },
    Block {
        name: "trials",
        file: "docs/accuracy.md",
        command: "cargo xtask trials --seeds 3",
        shape: Shape::Markdown,
    },
    Block {
        name: "prediction",
        file: "docs/accuracy.md",
        command: "cargo xtask prediction --seeds 3",
        shape: Shape::Markdown,
    },
    Block {
        name: "trust",
        file: "docs/accuracy.md",
        command: "cargo run --release -q -p twin-tests --example trust_matrix 2>/dev/null",
        shape: Shape::Markdown,
    },
    Block {
        name: "analyze-real",
        file: "docs/accuracy.md",
        command: "cargo xtask real-logs",
        shape: Shape::Markdown,
    },
    Block {
        name: "diagnose-real",
        file: "docs/accuracy.md",
        command: "cargo xtask diagnose-real",
        shape: Shape::Markdown,
    },
    Block {
        name: "diagnose-perturbed",
        file: "docs/accuracy.md",
        command: "cargo test -q -p twin-cli --test hidden_effects_perturbed hidden_effects_on_vessels -- --nocapture 2>/dev/null | grep -E '^(draw|diagnose-perturbed)'",
        shape: Shape::Fenced,
    },
    Block {
        name: "diagnose-perturbed-othersim",
        file: "docs/accuracy.md",
        command: "cargo test -q -p twin-cli --test hidden_effects_othersim hidden_effects_on_changed -- --nocapture 2>/dev/null | grep -E '^(draw|diagnose-perturbed-othersim)'",
        shape: Shape::Fenced,
    },
    Block {
        name: "diagnose-gyro",
        file: "docs/accuracy.md",
        command: "cargo test -q -p twin-cli --test hidden_effects_perturbed a_rate_gyros -- --nocapture 2>/dev/null | grep -E '^(draw|diagnose-gyro)'",
        shape: Shape::Fenced,
    },
    Block {
        name: "diagnose-gyro-othersim",
        file: "docs/accuracy.md",
        command: "cargo test -q -p twin-cli --test hidden_effects_othersim a_rate_gyros -- --nocapture 2>/dev/null | grep -E '^(draw|diagnose-gyro-othersim)'",
        shape: Shape::Fenced,
    },
    Block {
        name: "diagnose-without-propellers",
        file: "docs/accuracy.md",
        command: "cargo test -q -p twin-cli --test without_propellers -- --nocapture 2>/dev/null | grep -E '^draw'",
        shape: Shape::Fenced,
    },
    Block {
        name: "diagnose-without-propellers-othersim",
        file: "docs/accuracy.md",
        command: "cargo test -q -p twin-cli --test hidden_effects_othersim the_hulls_drift -- --nocapture 2>/dev/null | grep -E '^draw'",
        shape: Shape::Fenced,
    },
    Block {
        name: "identify-workboat",
        file: "docs/identification.md",
        command: "cargo build --release -q -p twin-cli && r=$PWD && t=$r/target/release/twin && cd \"$(mktemp -d)\" \
                  && $t simulate --scenario $r/config/scenarios/identify_workboat.toml --out trial.nmea >/dev/null 2>&1 \
                  && $t identify trial.nmea --profile $r/config/profiles/workboat-start.toml --name workboat --out workboat.toml 2>/dev/null \
                  && $t simulate --scenario $r/config/scenarios/identify_workboat_port-loss.toml --out loss.nmea >/dev/null 2>&1 \
                  && echo && echo 'twin analyze loss.nmea --profile workboat.toml' \
                  && $t analyze loss.nmea --profile workboat.toml | grep -E '^  (profile|thrusters) |^    (port|starboard) '",
        shape: Shape::Fenced,
    },
    Block {
        name: "bench-core",
        file: "docs/performance.md",
        command: "cargo run --release -q -p twin-bench -- core",
        shape: Shape::Markdown,
    },
    Block {
        name: "bench-numpy",
        file: "docs/performance.md",
        command: "cargo run --release -q -p twin-bench -- numpy",
        shape: Shape::Markdown,
    },
    Block {
        name: "bench-analyze",
        file: "docs/performance.md",
        command: "cargo bench -q -p twin-cli --bench analyze 2>/dev/null | grep -E '^analyze/|time:'",
        shape: Shape::Fenced,
    },
    Block {
        name: "bench-diagnose",
        file: "docs/performance.md",
        command: "cargo bench -q -p twin-cli --bench diagnose 2>/dev/null | grep -E '^diagnose/|time:'",
        shape: Shape::Fenced,
    },
    Block {
        name: "bench-identify",
        file: "docs/performance.md",
        command: "cargo bench -q -p twin-cli --bench identify 2>/dev/null | grep -E '^identify/|time:'",
        shape: Shape::Fenced,
    },
    Block {
        name: "bench-daemon",
        file: "docs/performance.md",
        command: "cargo run --release -q -p twin-bench -- daemon 2>/dev/null",
        shape: Shape::Markdown,
    },
    Block {
        name: "soak",
        file: "docs/deploy.md",
        command: "cargo run --release -q -p twin-bench -- soak 2>/dev/null",
        shape: Shape::Markdown,
    },
    Block {
        name: "web-fleet",
        file: "web/README.md",
        command: "cd web && node --test tests/fleet.test.js 2>/dev/null | grep -o 'fleet page measurement: .*'",
        shape: Shape::FleetMeasurement,
    },
];

/// Why a block could not be made.
#[derive(Debug, thiserror::Error)]
pub enum BlockError {
    /// No block of that name.
    #[error("no generated block named {0:?} (cargo xtask docs --list)")]
    Unknown(String),
    /// The file has no markers for the block.
    #[error("{file} has no block {name:?} (<!-- BEGIN {name} --> ... <!-- END {name} -->)")]
    NoMarkers {
        /// The file.
        file: String,
        /// The block.
        name: String,
    },
    /// The web fleet test printed no measurement line, or one that is not
    /// the JSON it should be.
    #[error("the fleet test's measurement line is unreadable: {0}")]
    FleetLine(String),
}

/// The block named `name`.
pub fn block(name: &str) -> Result<&'static Block, BlockError> {
    BLOCKS
        .iter()
        .find(|b| b.name == name)
        .ok_or_else(|| BlockError::Unknown(name.to_string()))
}

/// The block's text between its markers, made from the command's output.
pub fn body(block: &Block, output: &str) -> Result<String, BlockError> {
    let output = output.trim_end();
    let content = match block.shape {
        Shape::Markdown => format!("{output}\n"),
        Shape::Fenced => format!("```text\n{output}\n```\n"),
        Shape::FleetMeasurement => fleet_table(output)?,
    };
    Ok(format!("Generated by `{}`:\n\n{content}\n", block.command))
}

/// `text` with the body of block `name` replaced by `body`.
pub fn replace(text: &str, name: &str, body: &str, file: &str) -> Result<String, BlockError> {
    let begin = format!("<!-- BEGIN {name} -->\n");
    let end = format!("<!-- END {name} -->");
    let no_markers = || BlockError::NoMarkers {
        file: file.to_string(),
        name: name.to_string(),
    };
    let start = text.find(&begin).ok_or_else(no_markers)? + begin.len();
    let stop = start + text[start..].find(&end).ok_or_else(no_markers)?;
    Ok(format!("{}{body}{}", &text[..start], &text[stop..]))
}

/// The names of the blocks whose markers `text` holds, in order.
pub fn names_in(text: &str) -> Vec<String> {
    text.match_indices("<!-- BEGIN ")
        .filter_map(|(i, m)| {
            let rest = &text[i + m.len()..];
            rest.find(" -->").map(|j| rest[..j].to_string())
        })
        .collect()
}

/// Runs the block's command at `root` and writes its output into its file.
pub fn regenerate(root: &Path, block: &Block) -> anyhow::Result<()> {
    use anyhow::Context;
    let output = std::process::Command::new("sh")
        .arg("-c")
        .arg(block.command)
        .current_dir(root)
        .stderr(std::process::Stdio::inherit())
        .output()
        .with_context(|| format!("running {}", block.command))?;
    anyhow::ensure!(
        output.status.success(),
        "{} failed ({})",
        block.command,
        output.status
    );
    let body = body(block, &String::from_utf8_lossy(&output.stdout))?;
    let path = root.join(block.file);
    let text =
        std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
    let text = replace(&text, block.name, &body, block.file)?;
    std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// The fleet test's measurement line (`fleet page measurement: {json}`) as
/// a markdown table.
pub fn fleet_table(line: &str) -> Result<String, BlockError> {
    let bad = |why: &str| BlockError::FleetLine(format!("{why}: {line}"));
    let json = line
        .split_once("fleet page measurement:")
        .ok_or_else(|| bad("no measurement"))?
        .1;
    let m: serde_json::Value = serde_json::from_str(json).map_err(|e| bad(&e.to_string()))?;
    let f = &m["frame_interval_ms"];
    let long_tasks = match &m["long_tasks"] {
        serde_json::Value::Object(o) => format!(
            "{}, the longest {} ms",
            o.get("count").unwrap_or(&serde_json::Value::Null),
            o.get("longest_ms").unwrap_or(&serde_json::Value::Null)
        ),
        other => other.to_string(),
    };
    let follow: Vec<String> = m["follow_ms"]
        .as_array()
        .map(|a| a.iter().map(|x| format!("{x} ms")).collect())
        .unwrap_or_default();
    let events = m["events_per_s"]
        .as_f64()
        .map_or("-".to_string(), |e| format!("{e:.0}"));
    let rows = [
        ("vessels on the page", m["vessels"].to_string()),
        ("events reaching the page", format!("{events} per s")),
        (
            "frame interval (measured, not asserted)",
            format!(
                "median {} ms, p95 {} ms, p99 {} ms, longest {} ms ({} frames)",
                f["median"], f["p95"], f["p99"], f["max"], m["frames"]
            ),
        ),
        (
            "the page's scripts, share of the main thread (asserted <= 0.25)",
            m["script_busy_fraction"].to_string(),
        ),
        (
            "script time per event / per frame",
            format!(
                "{} ms / {} ms",
                m["ingest_ms_per_event"], m["render_ms_per_frame"]
            ),
        ),
        ("long tasks", long_tasks),
        (
            "click on another vessel -> page shows it",
            follow.join(", "),
        ),
        ("events skipped", m["skipped_events"].to_string()),
    ];
    let mut table = String::from("| measurement | value |\n|---|---|\n");
    for (name, value) in rows {
        table.push_str(&format!("| {name} | {value} |\n"));
    }
    Ok(table)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_block_is_replaced_between_its_markers_only() {
        let text = "intro\n<!-- BEGIN a -->\nold\n<!-- END a -->\nmiddle\n<!-- BEGIN b -->\nkept\n<!-- END b -->\n";
        let out = replace(text, "a", "new\n", "f.md").unwrap();
        assert_eq!(
            out,
            "intro\n<!-- BEGIN a -->\nnew\n<!-- END a -->\nmiddle\n<!-- BEGIN b -->\nkept\n<!-- END b -->\n"
        );
        assert!(matches!(
            replace(text, "c", "x", "f.md"),
            Err(BlockError::NoMarkers { .. })
        ));
        assert_eq!(names_in(text), ["a", "b"]);
    }

    #[test]
    fn a_body_names_its_command_and_no_date() {
        let b = block("trials").unwrap();
        let body = body(b, "| a |\n|---|\n\n").unwrap();
        assert_eq!(
            body,
            "Generated by `cargo xtask trials --seeds 3`:\n\n| a |\n|---|\n\n"
        );
        let fenced = super::body(block("demo").unwrap(), "line\n").unwrap();
        assert!(fenced.ends_with("```text\nline\n```\n\n"), "{fenced}");
    }

    #[test]
    fn the_fleet_line_becomes_a_table() {
        let line = r#"fleet page measurement: {"vessels":100,"events_per_s":1608.4,"frame_interval_ms":{"median":16.7,"p95":50,"p99":83.2,"max":150},"frames":934,"script_busy_fraction":0.131,"ingest_ms_per_event":0.0194,"render_ms_per_frame":2.17,"long_tasks":{"count":5,"longest_ms":69},"follow_ms":[54,183],"skipped_events":0}"#;
        let t = fleet_table(line).unwrap();
        assert!(
            t.contains("| events reaching the page | 1608 per s |"),
            "{t}"
        );
        assert!(t.contains("| long tasks | 5, the longest 69 ms |"), "{t}");
        assert!(
            t.contains("| click on another vessel -> page shows it | 54 ms, 183 ms |"),
            "{t}"
        );
        assert!(fleet_table("nothing").is_err());
    }
}
