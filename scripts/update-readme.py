#!/usr/bin/env python3
"""Regenerates the figures and tables of README.md (and web/README.md) from
the commands that produce them, so nothing in a README is typed by hand.

Each generated block sits between `<!-- BEGIN name -->` and `<!-- END name -->`
markers; the block records the command that produced it. Usage (from the
repository root):

    python3 scripts/update-readme.py            # every block
    python3 scripts/update-readme.py trials     # one block
"""
import datetime
import json
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"

# name -> the shell command whose standard output is the block's body
# (markdown as printed). Blocks in FENCED are plain text, put in a code fence.
FENCED = {"seed-cases", "demo", "bench-diagnose", "bench-analyze"}
BLOCKS = {
    "seed-cases": "cargo test --release -q -p twin-core --test seed_cases -- --nocapture --test-threads=1 2>/dev/null"
    " | grep -E '^[.]?(case|authors|zero)' | sed 's/^[.]//'",
    "demo": "cargo run --release -q -p twind -- --demo --no-web --demo-rate 50 2>/dev/null",
    "trials": "cargo run --release -q -p twin-cli -- report trials --seeds 3",
    "bench-numpy": "cargo run --release -q -p twin-bench -- numpy",
    "bench-core": "cargo run --release -q -p twin-bench -- core",
    "analyze-real": "cargo run --release -q -p twin-cli -- report real-logs",
    "diagnose-real": "cargo run --release -q -p twin-cli -- report diagnose-real",
    "bench-diagnose": "cargo bench -q -p twin-cli --bench diagnose 2>/dev/null | grep -E '^diagnose/|time:'",
    "bench-analyze": "cargo bench -q -p twin-cli --bench analyze 2>/dev/null | grep -E '^analyze/|time:'",
    "bench-daemon": "cargo run --release -q -p twin-bench -- daemon 2>/dev/null",
    "bench-daemon-no-liveliness": "cargo run --release -q -p twin-bench -- daemon --no-vessel-liveliness 2>/dev/null",
    "bench-daemon-liveliness-outside": "cargo run --release -q -p twin-bench -- daemon --liveliness-outside-prefix 2>/dev/null",
    # The 100-vessel page test (needs Chromium and `npm ci` in web/); its
    # measurement line, made a table by `fleet_table` below.
    "web-fleet": "cd web && node --test tests/fleet.test.js 2>/dev/null | grep -o 'fleet page measurement: .*'",
}

# Blocks that live in another file than README.md.
FILES = {"web-fleet": ROOT / "web" / "README.md"}


def fleet_table(output: str) -> str:
    """The fleet test's JSON measurement line as a markdown table."""
    m = json.loads(output.split("fleet page measurement:", 1)[1])
    f = m["frame_interval_ms"]
    long_tasks = m["long_tasks"]
    if isinstance(long_tasks, dict):
        long_tasks = f"{long_tasks['count']}, the longest {long_tasks['longest_ms']} ms"
    rows = [
        ("vessels on the page", m["vessels"]),
        ("events reaching the page", f"{m['events_per_s']:,} per s"),
        ("frame interval (measured, not asserted)",
         f"median {f['median']} ms, p95 {f['p95']} ms, p99 {f['p99']} ms, longest {f['max']} ms ({m['frames']} frames)"),
        ("the page's scripts, share of the main thread (asserted <= 0.25)", m["script_busy_fraction"]),
        ("script time per event / per frame", f"{m['ingest_ms_per_event']} ms / {m['render_ms_per_frame']} ms"),
        ("long tasks", long_tasks),
        ("click on another vessel -> page shows it", ", ".join(f"{x} ms" for x in m["follow_ms"])),
        ("events skipped", m["skipped_events"]),
    ]
    lines = ["| measurement | value |", "|---|---|"]
    lines += [f"| {name} | {value} |" for name, value in rows]
    return "\n".join(lines) + "\n"


FORMATTERS = {"web-fleet": fleet_table}


def run(command: str) -> str:
    result = subprocess.run(command, shell=True, cwd=ROOT, capture_output=True, text=True)
    if result.returncode != 0:
        sys.stderr.write(result.stderr)
        raise SystemExit(f"command failed ({result.returncode}): {command}")
    return result.stdout.rstrip() + "\n"


def main() -> None:
    texts = {README: README.read_text()}
    for path in FILES.values():
        texts.setdefault(path, path.read_text())
    wanted = sys.argv[1:] or [
        n for n in BLOCKS if f"<!-- BEGIN {n} -->" in texts[FILES.get(n, README)]
    ]
    for name in wanted:
        path = FILES.get(name, README)
        text = texts[path]
        command = BLOCKS[name]
        pattern = re.compile(rf"(<!-- BEGIN {re.escape(name)} -->\n)(.*?)(<!-- END {re.escape(name)} -->)", re.S)
        if not pattern.search(text):
            raise SystemExit(f"{path.relative_to(ROOT)} has no block '{name}'")
        today = datetime.date.today().isoformat()
        output = run(command)
        if name in FORMATTERS:
            output = FORMATTERS[name](output)
        if name in FENCED:
            output = "```text\n" + output + "```\n"
        body = f"Generated {today} by `{command}`:\n\n" + output + "\n"
        texts[path] = pattern.sub(lambda m: m.group(1) + body + m.group(3), text)
        print(f"updated {name}")
    for path, text in texts.items():
        path.write_text(text)


if __name__ == "__main__":
    main()
