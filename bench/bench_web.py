"""Decode speed of the JavaScript decoder (Node) against the Rust core, per frame.

Each stream (the first frames of capture sequences from ../shared/data at the default QP,
and the built-in synthetic sequence) is decoded whole, in order, several times: by the core
through its Python binding (``_core.Decoder.decode_frame``, arrays handed to numpy, nothing
written), once with rayon's default threads and once with ``RAYON_NUM_THREADS=1`` (the JS
decoder is single-threaded), and by ``node bench/decode_js.mjs``. The figure is the best
repetition's mean milliseconds per frame (for JS also the first repetition's, which pays for
the JIT compiling the decoder); the ratio is JS's best over the core's. The issue's target
is a ratio of at most 3.

    python bench/bench_web.py [--frames 6] [--reps 5] [--sequences dancer horse_gallop]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from common import SHARED_DATA, markdown_table, write_section

from dynmesh import api
from dynmesh.io import read_mesh, resolve_sequence
from dynmesh.synth import synth_sequence

HERE = Path(__file__).resolve().parent
RUST = r"""
import json, sys, time
from dynmesh import _core
data = open(sys.argv[1], "rb").read()
best = []
for _ in range(int(sys.argv[2])):
    t0 = time.perf_counter()
    dec = _core.Decoder(data)
    for i in range(dec.frame_count):
        dec.decode_frame(i)
    best.append(1000 * (time.perf_counter() - t0) / dec.frame_count)
print(json.dumps({"ms": best}))
"""
COLUMNS = [("stream", "stream", "s"), ("frames", "frames", "d"), ("faces", "faces/frame", ".0f"),
           ("rust", "core ms/frame", ".1f"), ("rust1", "core 1 thread", ".1f"), ("js", "JS (Node) ms/frame", ".1f"), ("cold", "JS first pass", ".1f"),
           ("ratio", "JS / core", ".2f"), ("ratio1", "JS / core 1 thread", ".2f")]


def streams(work: Path, sequences: list[str], frames: int) -> list[tuple[str, Path]]:
    out = []
    for name in sequences:
        if not (SHARED_DATA / name).is_dir():
            print(f"skipping {name}: no {SHARED_DATA / name}", file=sys.stderr)
            continue
        meshes = [read_mesh(p) for p in resolve_sequence(str(SHARED_DATA / name), None, frames)]
        out.append((name, meshes))
    out.append(("synthetic", synth_sequence(frames=frames)))
    paths = []
    for name, meshes in out:
        path = work / f"{name}.dmsh"
        path.write_bytes(api.encode(meshes))
        paths.append((name, path))
    return paths


def rust_ms(path: Path, reps: int, threads: int | None) -> float:
    env = dict(os.environ, **({"RAYON_NUM_THREADS": str(threads)} if threads else {}))
    out = subprocess.run([sys.executable, "-c", RUST, str(path), str(reps)], capture_output=True, text=True, check=True, env=env)
    return min(json.loads(out.stdout)["ms"])


def js_ms(path: Path, reps: int) -> tuple[float, float]:
    """Best repetition, and the first (with the JIT warming up), in ms per frame."""
    out = subprocess.run([shutil.which("node"), str(HERE / "decode_js.mjs"), str(path), str(reps)],
                         capture_output=True, text=True, check=True)
    ms = json.loads(out.stdout)["ms"]
    return min(ms), ms[0]


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--frames", type=int, default=6)
    p.add_argument("--reps", type=int, default=5)
    p.add_argument("--sequences", nargs="+", default=["dancer", "basketball_player", "horse_gallop"])
    p.add_argument("--no-write", action="store_true", help="print only; leave docs/benchmarks.md alone")
    a = p.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, path in streams(Path(tmp), a.sequences, a.frames):
            faces = sum(len(m.faces) for m in api.decode(path.read_bytes())) / a.frames
            rust, rust1, (js, cold) = rust_ms(path, a.reps, None), rust_ms(path, a.reps, 1), js_ms(path, a.reps)
            rows.append({"stream": name, "frames": a.frames, "faces": faces, "rust": rust, "rust1": rust1, "js": js, "cold": cold,
                         "ratio": js / rust, "ratio1": js / rust1})
            print(rows[-1], flush=True)
    table = markdown_table(rows, COLUMNS)
    print(table)
    if not a.no_write:
        load = os.getloadavg()[0]
        node = subprocess.run([shutil.which("node"), "--version"], capture_output=True, text=True).stdout.strip()
        write_section("JavaScript decoder", f"Decode time per frame, in order, best of {a.reps} repetitions (default "
                      f"QP, {a.frames} frames per stream; the core through its binding; Node {node}; load average "
                      f"{load:.1f} when the run ended: other processes shared the cores, so single figures move by "
                      "tens of percent between runs).\n\n" + table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
