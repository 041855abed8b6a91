"""The commands on meshes of many faces without surface: bounded work, or a clear refusal.

For each hostile mesh of tests/test_hostile.py, at 10^5 and 10^6 added faces (``--sizes``):
a strip of collinear faces, faces that repeat a vertex, copies of one triangle, and a UV
sphere of 39,600 faces with the degenerate faces added (a third of each kind), written as one
OBJ frame: ``dynmesh encode`` of it, ``dynmesh decode`` of the stream when one was written,
and ``dynmesh metrics`` of the mesh against the decoded frame (against itself when encode
refused it), each as a whole process with a timeout (``--timeout``), wall seconds. The
sphere alone is the yardstick. The outcome is the exit status and the stream's bytes or the
first words of the error.

    python bench/bench_degenerate.py [--sizes 100000 1000000] [--timeout 600] [--print-only]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from common import markdown_table, write_section  # noqa: E402
from conftest import uv_sphere  # noqa: E402
from test_hostile import collinear, duplicated, repeated_corners, with_degenerate  # noqa: E402

from dynmesh.io import write_mesh  # noqa: E402

SPHERE = (100, 200)
CASES = {
    "collinear strip": collinear,
    "repeated corners": repeated_corners,
    "copies of one triangle": duplicated,
    "sphere + degenerate": lambda n: with_degenerate(uv_sphere(*SPHERE), n),
}
COLUMNS = [("mesh", "mesh", "s"), ("faces", "faces", "d"), ("encode", "encode s", ".2f"), ("outcome", "encode outcome", "s"),
           ("decode", "decode s", "s"), ("metrics", "metrics s", "s"), ("metrics_outcome", "metrics outcome", "s")]


def timed(args: list, timeout: float) -> tuple[float, subprocess.CompletedProcess | None]:
    start = time.perf_counter()
    try:
        p = subprocess.run([sys.executable, "-m", "dynmesh", *map(str, args)], capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return time.perf_counter() - start, None
    return time.perf_counter() - start, p


def outcome(p: subprocess.CompletedProcess | None, timeout: float, ok: str) -> str:
    if p is None:
        return f"no answer in {timeout:.0f} s"
    if p.returncode == 0:
        return ok
    lines = [line for line in p.stderr.splitlines() if line.strip()]
    error = lines[-1] if lines else ""
    error = error.split(": error: ", 1)[-1]
    return f"exit {p.returncode}: {error[:70]}{'...' if len(error) > 70 else ''}"


def run_case(name: str, mesh, work: Path, timeout: float) -> dict:
    frames = work / "in"
    frames.mkdir()
    write_mesh(frames / "frame_0000.obj", mesh)
    stream, decoded = work / "s.dmsh", work / "out"
    t_enc, p = timed(["encode", frames, "-o", stream, "-q", "--jobs", "1"], timeout)
    row = {"mesh": name, "faces": len(mesh.faces), "encode": t_enc, "decode": "", "metrics": "", "metrics_outcome": ""}
    row["outcome"] = outcome(p, timeout, f"{stream.stat().st_size} bytes" if stream.exists() else "")
    if p is not None and p.returncode == 0:
        t_dec, d = timed(["decode", stream, "-o", decoded, "-q"], timeout)
        row["decode"] = f"{t_dec:.2f}" + ("" if d is not None and d.returncode == 0 else f" ({outcome(d, timeout, '')})")
        against = decoded
    else:
        against = frames
    t_met, m = timed(["metrics", frames, against, "-q"], timeout)
    row["metrics"] = f"{t_met:.2f}"
    row["metrics_outcome"] = outcome(m, timeout, (m.stdout.strip().splitlines() or [""])[-1] if m else "")
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[100_000, 1_000_000])
    ap.add_argument("--timeout", type=float, default=600.0)
    ap.add_argument("--print-only", action="store_true", help="do not write docs/benchmarks.md")
    a = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        cases = [("sphere alone", uv_sphere(*SPHERE))] + [(name, make(n)) for n in a.sizes for name, make in CASES.items()]
        for i, (name, mesh) in enumerate(cases):
            work = Path(tmp) / str(i)
            work.mkdir()
            rows.append(run_case(name, mesh, work, a.timeout))
            r = rows[-1]
            print(f"{r['mesh']:>24} {r['faces']:>8} faces: encode {r['encode']:7.2f} s  {r['outcome']}; "
                  f"decode {r['decode'] or '-'} s; metrics {r['metrics']} s  {r['metrics_outcome']}", flush=True)
    table = markdown_table(rows, COLUMNS)
    print(table)
    if not a.print_only:
        write_section("degenerate faces", (
            "`dynmesh encode` (`--jobs 1`), `dynmesh decode` of its stream and `dynmesh metrics` (default grid, 1024) "
            "of the mesh against the decoded frame (against itself when encode refused it), each a whole process, wall "
            "seconds, on one OBJ frame of each hostile mesh of tests/test_hostile.py: a strip of collinear faces, faces "
            "that repeat a vertex, copies of one triangle, and a UV sphere of 39,600 faces with that many faces added, a "
            "third of each kind. The encoder leaves out the faces without area or repeating another one (a warning when "
            "they are a tenth of the frame or more) and refuses a mesh left with none; before it did, 10^5 collinear faces "
            "took 28 s to encode (10^6: minutes, growing with the square), and the sphere with 10^5 of them 5.3 s. "
            "The machine is shared: the figures are single runs.\n\n" + table))


if __name__ == "__main__":
    main()
