"""Shared pieces of the benchmark scripts: machine description and the benchmarks page."""

from __future__ import annotations

import datetime
import json
import statistics
import subprocess
import os
import platform
import re
import sys
from pathlib import Path

from dynmesh.api import write_bytes_atomic

DOCS = Path(__file__).resolve().parents[1] / "docs" / "benchmarks.md"
SHARED_DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def machine() -> str:
    cpu = platform.processor() or "unknown CPU"
    try:
        text = Path("/proc/cpuinfo").read_text()
        cpu = re.search(r"model name\s*:\s*(.*)", text).group(1)
    except (OSError, AttributeError):
        pass
    return f"{cpu}, {os.cpu_count()} cores, {platform.system()} {platform.release()}, Python {platform.python_version()}"


def command() -> str:
    return "python " + " ".join([str(Path(sys.argv[0]).relative_to(Path.cwd())) if Path(sys.argv[0]).is_absolute() else sys.argv[0], *sys.argv[1:]])


def write_section(name: str, body: str) -> None:
    """Replaces (or appends) the section between the markers for ``name`` in docs/benchmarks.md."""
    start, end = f"<!-- {name}:start -->", f"<!-- {name}:end -->"
    stamp = f"Command: `{command()}`  \nDate: {datetime.date.today().isoformat()}  \nMachine: {machine()}\n\n"
    block = f"{start}\n{stamp}{body.rstrip()}\n{end}"
    text = DOCS.read_text() if DOCS.exists() else "# Benchmarks\n\nEvery figure here was measured by a script in `bench/`; rerun the command to refresh its section.\n"
    if start in text and end in text:
        text = text[: text.index(start)] + block + text[text.index(end) + len(end):]
    else:
        text = text.rstrip() + f"\n\n## {name}\n\n{block}\n"
    write_bytes_atomic(DOCS, text.encode())


def markdown_table(rows: list[dict], columns: list[tuple[str, str, str]]) -> str:
    """A table of ``rows`` with (key, heading, format) ``columns``; a None value is an empty cell."""
    head = "| " + " | ".join(h for _, h, _ in columns) + " |"
    rule = "|" + "|".join("---:" for _ in columns) + "|"
    body = ["| " + " | ".join("" if r[k] is None else format(r[k], f) for k, _, f in columns) + " |" for r in rows]
    return "\n".join([head, rule, *body])


def check_data(sequences: list[str]) -> bool:
    """True when every sequence folder is present under ../shared/data; else says which are not."""
    missing = [s for s in sequences if not (SHARED_DATA / s).is_dir()]
    if missing:
        print(f"no data for {', '.join(missing)} under {SHARED_DATA}", file=sys.stderr)
    return not missing


def example_lines(example: str, args: list, features: tuple[str, ...] = ()) -> list[dict]:
    """One run of the core's Rust example ``example`` (release build, with ``features``):
    the JSON objects it prints, one per line, in order."""
    root = Path(__file__).resolve().parents[1]
    extra = ["--features", ",".join(features)] if features else []
    out = subprocess.run(["cargo", "run", "--quiet", "--release", "-p", "dynmesh", *extra, "--example", example, "--",
                          *map(str, args)], cwd=root, check=True, capture_output=True, text=True).stdout
    return [json.loads(line) for line in out.splitlines() if line.strip()]


def median_rows(runs: list[list[dict]], keys: list[str]) -> list[dict]:
    """Rows of the first run with each of ``keys`` replaced by its median over the runs (the
    runs print the same measurements in the same order, so rows line up by position)."""
    return [{**lines[0], **{k: statistics.median(r[k] for r in lines) for k in keys}} for lines in zip(*runs)]


def example_table(example: str, args: list, features: tuple[str, ...], keys: list[str],
                  columns: list[tuple[str, str, str]], repeat: int) -> tuple[str, float]:
    """Runs the core's Rust example ``example`` ``repeat`` times (``example_lines``) and prints
    the markdown table of the medians of ``keys`` (``median_rows``): the table, and the load
    average before the runs, which the section's text quotes."""
    load = os.getloadavg()[0]
    rows = median_rows([example_lines(example, args, features) for _ in range(repeat)], keys)
    table = markdown_table(rows, columns)
    print(table)
    return table, load
