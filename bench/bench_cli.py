"""Whole command-line processes against the MPEG test model's times.

For each capture sequence, the first 6 frames (as the test model's points in
../shared/anchors/tm14_geometry_anchor.csv were measured) are encoded all-intra by
``dynmesh encode`` at QPs 36, 28 and 20, which land near the test model's rate points r1,
r3 and r5 in D1, and decoded by ``dynmesh decode`` to OBJ files (the command's default
output). Each process is timed from start to exit, Python start-up, reading and writing
files included, and divided by the frame count (the best of ``--repeat`` runs); the ratios are the test model's seconds
per frame at the matching rate point (single-threaded encoder on a machine of this kind)
over ours. The test model's times come from its table, not from this run.

The package's bytecode is compiled first, as ``pip install`` compiles it: a machine that sets
PYTHONDONTWRITEBYTECODE (this one does) would otherwise compile every module of the command
line in every process, 10-17 ms that no installed copy pays.

    python bench/bench_cli.py [--sequences basketball_player dancer mitch thomas] [--repeat 3]
"""

from __future__ import annotations

import argparse
import compileall
import csv
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import SHARED_DATA, check_data, markdown_table, write_section

ANCHORS = SHARED_DATA.parent / "anchors" / "tm14_geometry_anchor.csv"
POINTS = [(36, "r1"), (28, "r3"), (20, "r5")]
FRAMES = 6
COLUMNS = [("sequence", "sequence", "s"), ("qp", "QP", "d"), ("rate", "TM point", "s"),
           ("enc", "encode s/frame", ".3f"), ("tm_enc", "TM encode s/frame", ".2f"), ("enc_x", "TM / ours", ".1f"),
           ("dec", "decode s/frame", ".3f"), ("tm_dec", "TM decode s/frame", ".3f"), ("dec_x", "TM / ours", ".1f")]


def seconds(args: list[str]) -> float:
    """Wall-clock seconds of one ``dynmesh`` process; raises if it fails."""
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "dynmesh", *args], check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def test_model_times() -> dict:
    """(sequence, rate point) -> (encode, decode) seconds per frame of the test model, all-intra."""
    with open(ANCHORS, newline="") as f:
        return {(r["seq"], r["rate"]): (float(r["enc_s_per_frame"]), float(r["dec_s_per_frame"]))
                for r in csv.DictReader(f) if r["cond"] == "AI"}


def rows_of(sequence: str, tm: dict, work: Path, repeat: int) -> list[dict]:
    rows = []
    for qp, rate in POINTS:
        stream, out = work / f"{sequence}_{qp}.dmsh", work / f"{sequence}_{qp}"
        enc = min(seconds(["encode", str(SHARED_DATA / sequence), "--count", str(FRAMES), "--intra-period", "1",
                           "--qp", str(qp), "-o", str(stream), "-q"]) for _ in range(repeat)) / FRAMES
        dec = min(seconds(["decode", str(stream), "-o", f"{out}_{k}", "-q"]) for k in range(repeat)) / FRAMES
        tm_enc, tm_dec = tm[(sequence, rate)]
        rows.append({"sequence": sequence, "qp": qp, "rate": rate, "enc": enc, "tm_enc": tm_enc, "enc_x": tm_enc / enc,
                     "dec": dec, "tm_dec": tm_dec, "dec_x": tm_dec / dec})
        print(f"{sequence} QP {qp}: encode {enc:.3f} s/frame ({tm_enc / enc:.1f}x faster than TM), "
              f"decode {dec:.3f} s/frame ({tm_dec / dec:.1f}x)", flush=True)
    return rows


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sequences", nargs="+", default=["basketball_player", "dancer", "mitch", "thomas"])
    p.add_argument("--repeat", type=int, default=3, help="runs of each command; the fastest counts")
    a = p.parse_args()
    if not check_data(a.sequences) or not ANCHORS.is_file():
        return 1
    import dynmesh

    compileall.compile_dir(Path(dynmesh.__file__).parent, quiet=1)
    tm = test_model_times()
    with tempfile.TemporaryDirectory() as tmp:
        rows = [r for s in a.sequences for r in rows_of(s, tm, Path(tmp), a.repeat)]
    body = (f"Whole `dynmesh encode` / `dynmesh decode` processes (Python start-up, OBJ reading and writing "
            f"included; the package's bytecode compiled, as an installed copy has it; best of {a.repeat} runs) on the "
            f"first {FRAMES} frames, all-intra, other options at their defaults, against the test "
            "model v14's all-intra times at the rate point of similar D1 (from "
            "`../shared/anchors/tm14_geometry_anchor.csv`: its single-threaded encoder, not rerun here).\n\n"
            + markdown_table(rows, COLUMNS))
    write_section("command line against the MPEG test model", body)
    return 0


if __name__ == "__main__":
    sys.exit(main())
