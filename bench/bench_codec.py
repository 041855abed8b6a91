"""Rate, quality and speed of the all-intra codec on the sequences in ../shared/data.

For each sequence it encodes the first frames at several QPs (other options at their
defaults), decodes, measures D1/D2 PSNR (grid over the sequence box, peak = its largest
side, as the MPEG test conditions do) and reports bytes per frame, the compression ratio
against the input OBJ files, Mbit/s at 30 fps and encode/decode seconds per frame. In the
same run it codes the frames with Draco (per frame, 11 quantization bits, compression level
7) as a baseline, and reports dynmesh's times as ratios to Draco's.
The first sequence gets its own section (the headline table); all of them share a second.

    python bench/bench_codec.py [--frames 10] [--qps 22 28 34] [--sequences basketball_player dancer ...]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import dynmesh
from dynmesh.eval.baselines import Draco
from dynmesh.io import resolve_sequence

from common import SHARED_DATA, check_data, markdown_table, write_section

SEQUENCES = ["basketball_player", "dancer", "mitch", "thomas", "collision", "horse_gallop"]
COLUMNS = [("codec", "codec", "s"), ("bytes", "bytes/frame", ".0f"), ("ratio", "OBJ bytes / coded", ".0f"),
           ("mbps", "Mbit/s @30fps", ".3f"), ("d1", "D1 PSNR", ".2f"), ("d2", "D2 PSNR", ".2f"),
           ("enc", "encode s/frame", ".3f"), ("dec", "decode s/frame", ".4f"),
           ("enc_ratio", "encode / Draco", ".1f"), ("dec_ratio", "decode / Draco", ".1f")]


def measure(frames, obj_bytes: float, qp: int | None) -> dict:
    """One rate point: per-frame figures of dynmesh at ``qp``, or of Draco if ``qp`` is None."""
    t0 = time.perf_counter()
    coded = Draco.encode(frames) if qp is None else dynmesh.encode(frames, qp=qp, intra_period=1)
    enc = (time.perf_counter() - t0) / len(frames)
    t0 = time.perf_counter()
    decoded = Draco.decode(coded.payload) if qp is None else list(dynmesh.decode(coded))
    dec = (time.perf_counter() - t0) / len(frames)
    m = dynmesh.metrics(frames, decoded)
    per_frame = (coded.total_bytes if qp is None else len(coded)) / len(frames)
    codec = f"draco {Draco.DEFAULTS['quantization_bits']} bits" if qp is None else f"dynmesh QP {qp}"
    return {"codec": codec, "bytes": per_frame, "ratio": obj_bytes / per_frame, "mbps": per_frame * 8 * 30 / 1e6,
            "d1": m["d1_psnr"], "d2": m["d2_psnr"], "enc": enc, "dec": dec}


def sequence_rows(name: str, count: int, qps: list[int]) -> tuple[list[dict], str]:
    """Rows for one sequence and a line describing its input."""
    paths = resolve_sequence(SHARED_DATA / name, 0, count)
    frames = [dynmesh.read_mesh(p) for p in paths]
    obj_bytes = sum(Path(p).stat().st_size for p in paths) / len(paths)
    draco = measure(frames, obj_bytes, None)
    rows = [{"sequence": name, **measure(frames, obj_bytes, qp)} for qp in qps] + [{"sequence": name, **draco}]
    for r in rows:
        r["enc_ratio"], r["dec_ratio"] = r["enc"] / draco["enc"], r["dec"] / draco["dec"]
    verts = sum(f.vertex_count for f in frames) / len(frames)
    faces = sum(f.face_count for f in frames) / len(frames)
    for r in rows:
        print(f"{name:18s} {r['codec']:15s}: {r['bytes']:8.0f} B/frame  D1 {r['d1']:6.2f}  D2 {r['d2']:6.2f}  "
              f"enc {r['enc']:.3f} s  dec {r['dec']:.4f} s", flush=True)
    return rows, f"{name}: first {len(frames)} frames, ~{verts:.0f} vertices / {faces:.0f} faces, {obj_bytes / 1e6:.2f} MB OBJ per frame"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sequences", nargs="+", default=SEQUENCES)
    ap.add_argument("--frames", type=int, default=10)
    ap.add_argument("--qps", type=int, nargs="+", default=[22, 28, 34])
    ap.add_argument("--no-write", action="store_true", help="print only; leave docs/benchmarks.md alone")
    a = ap.parse_args()
    if not check_data(a.sequences):
        return 1
    results = [sequence_rows(s, a.frames, a.qps) for s in a.sequences]
    if a.no_write:
        return 0
    options = ", ".join(f"{k} {v:g}" if isinstance(v, float) else f"{k} {v}" for k, v in dynmesh.DEFAULTS.items()
                        if k in ("base_ratio", "subdiv", "scheme", "bits", "base_bits", "normal_only", "aq"))
    note = (f"All-intra (intra_period 1), other options at their defaults ({options}); D1/D2 with the grid over the sequence box and peak = its "
            "largest side; times are wall-clock per frame in one process, including the Python wrapper "
            "and excluding file I/O; the Draco row and the ratio columns come from the same run. The machine "
            "is shared, so treat absolute times as +-20 %.\n\n")
    head_rows, head_desc = results[0]
    write_section(f"all-intra codec on {a.sequences[0]}", note + head_desc + "\n\n" + markdown_table(head_rows, COLUMNS))
    all_rows = [r for rows, _ in results for r in rows]
    descs = "\n".join(f"- {d}" for _, d in results)
    write_section("all-intra codec on every sequence",
                  note + descs + "\n\n" + markdown_table(all_rows, [("sequence", "sequence", "s"), *COLUMNS]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
