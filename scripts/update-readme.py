#!/usr/bin/env python3
"""Regenerates the figures and tables of README.md from the commands that
produce them, so nothing in the README is typed by hand.

Each generated block sits between `<!-- BEGIN name -->` and `<!-- END name -->`
markers; the block records the command that produced it. Usage (from the
repository root):

    python3 scripts/update-readme.py            # every block
    python3 scripts/update-readme.py trials     # one block
"""
import datetime
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
}


def run(command: str) -> str:
    result = subprocess.run(command, shell=True, cwd=ROOT, capture_output=True, text=True)
    if result.returncode != 0:
        sys.stderr.write(result.stderr)
        raise SystemExit(f"command failed ({result.returncode}): {command}")
    return result.stdout.rstrip() + "\n"


def main() -> None:
    text = README.read_text()
    wanted = sys.argv[1:] or [n for n in BLOCKS if f"<!-- BEGIN {n} -->" in text]
    for name in wanted:
        command = BLOCKS[name]
        pattern = re.compile(rf"(<!-- BEGIN {re.escape(name)} -->\n)(.*?)(<!-- END {re.escape(name)} -->)", re.S)
        if not pattern.search(text):
            raise SystemExit(f"README.md has no block '{name}'")
        today = datetime.date.today().isoformat()
        output = run(command)
        if name in FENCED:
            output = "```text\n" + output + "```\n"
        body = f"Generated {today} by `{command}`:\n\n" + output + "\n"
        text = pattern.sub(lambda m: m.group(1) + body + m.group(3), text)
        print(f"updated {name}")
    README.write_text(text)


if __name__ == "__main__":
    main()
