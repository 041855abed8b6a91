"""Whole command-line processes against the MPEG test model's times, at equal quality.

For each capture sequence, the first 6 frames (as the test model's points in
../shared/anchors/tm14_geometry_anchor.csv were measured) are first coded all-intra at QPs
20 to 36 in steps of 2 through the API, and D1 of each is measured at the table's peak.
Each of the test model's rate points r1-r5 is then matched with the highest of those QPs
(the fewest bits) whose D1 is at least the test model's there, so that no speed figure is
bought with quality; a point that no QP reaches is matched with QP 20 and marked. At the
matched QPs ``dynmesh encode`` (all-intra; at its default ``--jobs auto`` and with
``--jobs 1``, alternately) and ``dynmesh decode`` (to OBJ files, the
command's default output) are timed as whole processes from start to exit, Python
start-up, reading and writing files included, divided by the frame count (the best of
``--repeat`` runs); the ratios are the test model's seconds per frame at that rate point
(single-threaded encoder on a machine of this kind) over ours, and the last row of each
sequence compares the sums over r1-r5. The test model's times come from its table, not
from this run.

The package's bytecode is compiled first, as ``pip install`` compiles it: a machine that sets
PYTHONDONTWRITEBYTECODE (this one does) would otherwise compile every module of the command
line in every process, 10-17 ms that no installed copy pays.

    python bench/bench_cli.py [--sequences basketball_player dancer mitch thomas] [--repeat 3]
"""

from __future__ import annotations

import argparse
import compileall
import csv
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import SHARED_DATA, check_data, markdown_table, write_section

ANCHORS = SHARED_DATA.parent / "anchors" / "tm14_geometry_anchor.csv"
QPS = range(36, 19, -2)
FRAMES = 6
COLUMNS = [("sequence", "sequence", "s"), ("rate", "TM point", "s"), ("tm_d1", "TM D1", ".2f"), ("qp", "QP", "s"),
           ("d1", "D1", ".2f"), ("mbps", "Mbit/s", ".3f"), ("tm_mbps", "TM Mbit/s", ".3f"),
           ("enc", "encode s/frame", ".3f"), ("tm_enc", "TM encode s/frame", ".2f"), ("enc_x", "TM / ours", ".1f"),
           ("enc1", "encode --jobs 1", ".3f"), ("enc1_x", "TM / ours", ".1f"),
           ("dec", "decode s/frame", ".3f"), ("tm_dec", "TM decode s/frame", ".3f"), ("dec_x", "TM / ours", ".1f")]


def seconds(args: list[str]) -> float:
    """Wall-clock seconds of one ``dynmesh`` process; raises if it fails."""
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "dynmesh", *args], check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def test_model_points(sequence: str) -> list[dict]:
    """The test model's all-intra rate points of ``sequence``, r1 first."""
    with open(ANCHORS, newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["cond"] == "AI" and r["seq"] == sequence]
    return sorted(rows, key=lambda r: r["rate"])


def quality_by_qp(sequence: str, peak: float) -> dict:
    """QP -> (Mbit/s at 30 fps, D1) of the first frames coded all-intra at each of QPS."""
    import dynmesh
    from dynmesh.io.sequence import resolve_sequence

    frames = [dynmesh.read_mesh(p) for p in resolve_sequence(SHARED_DATA / sequence, 0, FRAMES)]
    out = {}
    for qp in QPS:
        data = dynmesh.encode_frames(frames, qp=qp, intra_period=1, texture=False).data
        d1 = dynmesh.metrics(frames, list(dynmesh.decode(data)), peak=peak)["d1_psnr"]
        out[qp] = (len(data) * 8 * 30 / FRAMES / 1e6, d1)
        print(f"  {sequence} QP {qp}: {out[qp][0]:.3f} Mbit/s, D1 {d1:.2f} dB", flush=True)
    return out


def matched_qp(quality: dict, d1: float) -> tuple[int, bool]:
    """The highest QP whose D1 reaches ``d1``, and whether one does (else the lowest QP)."""
    reached = [qp for qp, (_, q) in quality.items() if q >= d1]
    return (max(reached), True) if reached else (min(quality), False)


def timed(sequence: str, qp: int, work: Path, repeat: int) -> tuple[float, float, float]:
    """(encode, encode in one process, decode) seconds per frame of whole processes at ``qp``,
    best of ``repeat``; the two encodes alternate, and must write the same stream."""
    stream, out = work / f"{sequence}_{qp}.dmsh", work / f"{sequence}_{qp}"
    encode = ["encode", str(SHARED_DATA / sequence), "--count", str(FRAMES), "--intra-period", "1", "--qp", str(qp), "-q"]
    runs: dict = {"default": [], "one": []}
    for _ in range(repeat):
        runs["default"].append(seconds([*encode, "-o", str(stream)]))
        runs["one"].append(seconds([*encode, "--jobs", "1", "-o", str(work / "one.dmsh")]))
    if (work / "one.dmsh").read_bytes() != stream.read_bytes():
        raise SystemExit(f"{sequence} QP {qp}: --jobs 1 wrote another stream than the default")
    dec = min(seconds(["decode", str(stream), "-o", f"{out}_{k}", "-q"]) for k in range(repeat)) / FRAMES
    return min(runs["default"]) / FRAMES, min(runs["one"]) / FRAMES, dec


def rows_of(sequence: str, work: Path, repeat: int) -> list[dict]:
    points = test_model_points(sequence)
    quality = quality_by_qp(sequence, float(points[0]["peak"]))
    times: dict = {}
    rows = []
    for p in points:
        qp, reached = matched_qp(quality, float(p["d1"]))
        if qp not in times:
            times[qp] = timed(sequence, qp, work, repeat)
        (enc, enc1, dec), (tm_enc, tm_dec) = times[qp], (float(p["enc_s_per_frame"]), float(p["dec_s_per_frame"]))
        rows.append({"sequence": sequence, "rate": p["rate"], "tm_d1": float(p["d1"]), "qp": f"{qp}" + ("" if reached else " (below)"),
                     "d1": quality[qp][1], "mbps": quality[qp][0], "tm_mbps": float(p["mbps"]),
                     "enc": enc, "tm_enc": tm_enc, "enc_x": tm_enc / enc, "enc1": enc1, "enc1_x": tm_enc / enc1, "dec": dec, "tm_dec": tm_dec, "dec_x": tm_dec / dec})
        print(f"{sequence} {p['rate']} (QP {qp}): encode {enc:.3f} s/frame ({tm_enc / enc:.1f}x faster than TM), "
              f"decode {dec:.3f} s/frame ({tm_dec / dec:.1f}x)", flush=True)
    total = {k: sum(r[k] for r in rows) for k in ("enc", "enc1", "tm_enc", "dec", "tm_dec")}
    rows.append({"sequence": sequence, "rate": "r1-r5", "tm_d1": None, "qp": "sum", "d1": None, "mbps": None,
                 "tm_mbps": None, **total,
                 "enc_x": total["tm_enc"] / total["enc"], "enc1_x": total["tm_enc"] / total["enc1"], "dec_x": total["tm_dec"] / total["dec"]})
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
    with tempfile.TemporaryDirectory() as tmp:
        rows = [r for s in a.sequences for r in rows_of(s, Path(tmp), a.repeat)]
    body = (f"Whole `dynmesh encode` / `dynmesh decode` processes (Python start-up, OBJ reading and writing "
            f"included; the package's bytecode compiled, as an installed copy has it; best of {a.repeat} runs) on the "
            f"first {FRAMES} frames, all-intra, other options at their defaults (`--jobs auto`: here {os.cpu_count()} "
            "processes, one per core, as the frames of an all-intra stream are groups of their own; *encode --jobs 1* "
            "is one process, whose core runs its thread pool over the cores), against the test "
            "model v14's all-intra times (from `../shared/anchors/tm14_geometry_anchor.csv`: its single-threaded "
            "encoder, not rerun here), each rate point matched with the highest QP (of 20 to 36 in steps of 2) "
            "whose D1 is at least the test model's there; *sum* rows compare the totals over the five points.\n\n"
            + markdown_table(rows, COLUMNS))
    write_section("command line against the MPEG test model", body)
    return 0


if __name__ == "__main__":
    sys.exit(main())
