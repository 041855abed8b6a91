"""Peak memory of long sequences: ``dynmesh encode`` and ``dynmesh decode`` processes on 10,
100 and 300 frames, made by looping a shared capture sequence (symbolic links in a temporary
directory, so nothing is copied). Memory that does not depend on the length is the claim:
the encoder reads its frames twice, one at a time (once for the sequence box, once to code
them), and the decoder writes each frame as it decodes it.

Peak resident set size of each process (``ru_maxrss`` from ``wait4``), Python included.

    python bench/bench_memory.py [--sequence basketball_player] [--frames 10 100 300]
                                 [--options="--subdiv 1"] [--write]

``--options`` are passed to ``dynmesh encode`` (cheaper settings make the long runs shorter;
what is measured is whether memory grows with the length).

Skips (exit 0, a message on stderr) when ../shared/data is absent.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import SHARED_DATA, check_data, markdown_table, write_section

COLUMNS = [("frames", "frames", "d"), ("enc_mb", "encode peak RSS MB", ".0f"), ("enc_s", "encode s", ".1f"),
           ("dec_mb", "decode peak RSS MB", ".0f"), ("dec_s", "decode s", ".1f"), ("bytes", "stream bytes", "d")]


def peak_rss(args: list[str]) -> tuple[float, float]:
    """(peak RSS in MB, wall seconds) of one ``dynmesh`` process; raises if it fails."""
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "dynmesh", *args], stdout=subprocess.DEVNULL)
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise SystemExit(f"dynmesh {' '.join(args)} failed with status {proc.returncode}")
    return usage.ru_maxrss / 1024, time.perf_counter() - t0


def looped(source: Path, frames: int, into: Path) -> Path:
    """A directory of ``frames`` links to the source frames, in order, over and over."""
    files = sorted(p for p in source.iterdir() if p.suffix in (".obj", ".ply"))
    into.mkdir()
    for i in range(frames):
        (into / f"frame_{i:04d}{files[i % len(files)].suffix}").symlink_to(files[i % len(files)])
    return into


def measure(sequence: str, counts: list[int], options: list[str]) -> list[dict]:
    rows = []
    with tempfile.TemporaryDirectory(prefix="dynmesh-memory-") as tmp:
        for n in counts:
            frames = looped(SHARED_DATA / sequence, n, Path(tmp) / f"in{n}")
            stream = Path(tmp) / f"s{n}.dmsh"
            enc_mb, enc_s = peak_rss(["encode", frames, "-o", stream, "-q", *options])
            dec_mb, dec_s = peak_rss(["decode", stream, "-o", Path(tmp) / f"out{n}", "-q"])
            rows.append({"frames": n, "enc_mb": enc_mb, "enc_s": enc_s, "dec_mb": dec_mb, "dec_s": dec_s,
                         "bytes": stream.stat().st_size})
            print(rows[-1], file=sys.stderr)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sequence", default="basketball_player")
    ap.add_argument("--frames", type=int, nargs="+", default=[10, 100, 300])
    ap.add_argument("--options", default="", help="dynmesh encode options, one string")
    ap.add_argument("--write", action="store_true", help="write the table into docs/benchmarks.md")
    a = ap.parse_args()
    if not check_data([a.sequence]):
        return
    rows = measure(a.sequence, a.frames, a.options.split())
    table = markdown_table(rows, COLUMNS)
    print(table)
    if a.write:
        what = f"options `{a.options}`" if a.options else "default options"
        write_section("long sequences in bounded memory", f"`{a.sequence}` looped, {what}.\n\n{table}")


if __name__ == "__main__":
    main()
