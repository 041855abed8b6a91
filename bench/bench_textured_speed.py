"""What textures cost a whole ``dynmesh encode`` and ``dynmesh decode``, as commands.

On the first frames of each textured capture (default: 6 frames of liam_textured, 1024 x 1024
textures, where the geometry is the larger part of the work; and 3 frames of
basketball_textured, 2048 x 2048 textures on a lighter mesh), ``dynmesh encode`` is run with
textures and with ``--no-texture``, then ``dynmesh decode`` of each stream into a new directory
(frames, and for the textured stream their UVs, .mtl and .png files), each as a whole process
from start to exit (Python start-up, reading and writing files included). The two variants of
a command run in turn, A B A B ..., ``--repeat`` times each, so that a drift of the shared
machine's speed hits both; the table gives each one's wall-clock seconds (minimum and median),
its CPU seconds (user + system of the process and its threads, median) and the median per
frame, and the ratios textured / untextured of the medians. The package's bytecode is compiled
first, as ``pip install`` compiles it (a machine with PYTHONDONTWRITEBYTECODE would otherwise
compile the command's modules in every process).

    python bench/bench_textured_speed.py [--sequences liam_textured:6,basketball_textured:3] [--repeat 5] [--print-only]
"""

from __future__ import annotations

import argparse
import compileall
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import SHARED_DATA, check_data, markdown_table, write_section

COLUMNS = [("sequence", "sequence", "s"), ("command", "command", "s"), ("wall_min", "wall min s", ".2f"), ("wall", "wall median s", ".2f"),
           ("cpu", "CPU median s", ".2f"), ("per_frame", "wall s/frame", ".3f"), ("ratio", "textured / untextured", "s")]


def run(args: list[str]) -> tuple[float, float]:
    """(wall seconds, CPU seconds) of one ``dynmesh`` process; raises if it fails."""
    before = os.times()
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "dynmesh", *args, "-q"], check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    after = os.times()
    return wall, (after.children_user - before.children_user) + (after.children_system - before.children_system)


def timed_pair(textured: list[str], plain: list[str], repeat: int, after=None) -> tuple[list, list]:
    """Each command ``repeat`` times, in turn; ``after(kind)`` runs after each run, untimed."""
    times = {"textured": [], "plain": []}
    for _ in range(repeat):
        for kind, args in (("textured", textured), ("plain", plain)):
            times[kind].append(run(args))
            if after is not None:
                after(kind)
    return times["textured"], times["plain"]


def rows_of(sequence: str, name: str, textured: list, plain: list, frames: int) -> list[dict]:
    rows = []
    for label, runs in ((f"{name}, textured", textured), (f"{name} --no-texture", plain)):
        walls = [w for w, _ in runs]
        rows.append({"sequence": sequence, "command": label, "wall_min": min(walls), "wall": statistics.median(walls),
                     "cpu": statistics.median(c for _, c in runs), "per_frame": statistics.median(walls) / frames,
                     "ratio": ""})
    wall = rows[0]["wall"] / rows[1]["wall"]
    cpu = rows[0]["cpu"] / rows[1]["cpu"]
    rows[0]["ratio"] = f"{wall:.2f} (wall), {cpu:.2f} (CPU)"
    return rows


def measure(sequence: str, frames: int, repeat: int) -> tuple[list[dict], str]:
    """The table rows of one capture's first ``frames`` frames, and a sentence on them."""
    from dynmesh.io import read_image, read_mesh, resolve_sequence

    source = str(SHARED_DATA / sequence / "*.obj")
    first = read_mesh(resolve_sequence(source, None, 1)[0])
    height, width, _ = read_image(first.texture).shape
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        streams = {"textured": tmp / "textured.dmsh", "plain": tmp / "plain.dmsh"}
        encode = ["encode", source, "--count", str(frames), "-o"]
        enc = timed_pair(encode + [str(streams["textured"])], encode + [str(streams["plain"]), "--no-texture"], repeat)
        out = {"textured": tmp / "textured", "plain": tmp / "plain"}
        dec = timed_pair(["decode", str(streams["textured"]), "-o", str(out["textured"])],
                         ["decode", str(streams["plain"]), "-o", str(out["plain"])], repeat,
                         after=lambda kind: shutil.rmtree(out[kind]))  # each decode writes a new directory
        sizes = {k: v.stat().st_size for k, v in streams.items()}
    rows = rows_of(sequence, "encode", *enc, frames) + rows_of(sequence, "decode", *dec, frames)
    return rows, (f"the first {frames} frames of {sequence} ({width} x {height} textures; {sizes['textured']} bytes "
                  f"with textures, {sizes['plain']} without)")


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sequences", default="liam_textured:6,basketball_textured:3",
                   help="captures and their frame counts, SEQUENCE:FRAMES joined by commas")
    p.add_argument("--repeat", type=int, default=5, help="runs of each command (default 5)")
    p.add_argument("--print-only", action="store_true", help="print the table, do not write docs/benchmarks.md")
    a = p.parse_args()
    runs = [(name, int(frames)) for name, frames in (item.split(":") for item in a.sequences.split(","))]
    if not check_data([name for name, _ in runs]):
        return 1
    import dynmesh

    compileall.compile_dir(Path(dynmesh.__file__).parent, quiet=1)
    rows, what = [], []
    for name, frames in runs:
        r, w = measure(name, frames, a.repeat)
        rows += r
        what.append(w)
    table = markdown_table(rows, COLUMNS)
    print(table)
    if a.print_only:
        return 0
    body = (f"`dynmesh encode` of {' and of '.join(what)}, with textures and with `--no-texture`, other options at "
            f"their defaults, and `dynmesh decode` of each stream to OBJ in a new directory (with the textured stream's "
            f".mtl and .png files), timed as whole processes, the two variants in turn, {a.repeat} runs of each. "
            "CPU is the process's user + system time, its threads included. The machine is shared: quote the "
            "medians and the ratios.\n\n" + table)
    write_section("textured commands against geometry only", body)
    return 0


if __name__ == "__main__":
    sys.exit(main())
