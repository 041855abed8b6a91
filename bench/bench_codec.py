"""Speed and rate-distortion of the all-intra codec on basketball_player.

Encodes the first frames of ../shared/data/basketball_player at several QPs, decodes,
measures D1/D2 PSNR (grid over the sequence box, peak = its largest side), and prints and
records bytes per frame, Mbit/s at 30 fps and encode/decode seconds per frame.

    python bench/bench_codec.py [--frames 6] [--qps 22 28 34]
"""

from __future__ import annotations

import argparse
import sys
import time

import dynmesh
from dynmesh.sequence import resolve_sequence

from common import SHARED_DATA, markdown_table, write_section

COLUMNS = [("qp", "QP", "d"), ("bytes", "bytes/frame", ".0f"), ("mbps", "Mbit/s @30fps", ".3f"),
           ("d1", "D1 PSNR", ".2f"), ("d2", "D2 PSNR", ".2f"), ("enc", "encode s/frame", ".3f"),
           ("dec", "decode s/frame", ".4f"), ("read", "OBJ read s/frame", ".3f")]


def measure(frames, qp: int, options: dict) -> dict:
    t0 = time.perf_counter()
    data = dynmesh.encode(frames, qp=qp, **options)
    enc = (time.perf_counter() - t0) / len(frames)
    t0 = time.perf_counter()
    decoded = list(dynmesh.decode(data))
    dec = (time.perf_counter() - t0) / len(frames)
    m = dynmesh.metrics(frames, decoded)
    per_frame = len(data) / len(frames)
    return {"qp": qp, "bytes": per_frame, "mbps": per_frame * 8 * 30 / 1e6, "d1": m["d1_psnr"], "d2": m["d2_psnr"],
            "enc": enc, "dec": dec}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sequence", default="basketball_player")
    ap.add_argument("--frames", type=int, default=6)
    ap.add_argument("--qps", type=int, nargs="+", default=[22, 28, 34])
    ap.add_argument("--base-ratio", type=float, default=dynmesh.DEFAULTS["base_ratio"])
    ap.add_argument("--subdiv", type=int, default=dynmesh.DEFAULTS["subdiv"])
    ap.add_argument("--no-write", action="store_true", help="print only; leave docs/benchmarks.md alone")
    a = ap.parse_args()
    folder = SHARED_DATA / a.sequence
    if not folder.is_dir():
        print(f"no data at {folder}", file=sys.stderr)
        return 1
    t0 = time.perf_counter()
    frames = [dynmesh.read_mesh(p) for p in resolve_sequence(folder, 0, a.frames)]
    read = (time.perf_counter() - t0) / len(frames)
    rows = [{**measure(frames, qp, dict(base_ratio=a.base_ratio, subdiv=a.subdiv)), "read": read} for qp in a.qps]
    table = markdown_table(rows, COLUMNS)
    print(table)
    if not a.no_write:
        verts = sum(f.vertex_count for f in frames) / len(frames)
        body = (f"{a.sequence}, first {len(frames)} frames (~{verts:.0f} vertices each), all-intra, "
                f"base ratio {a.base_ratio:g}, {a.subdiv} subdivisions; D1/D2 with the grid over the "
                f"sequence box and peak = its largest side.\n\n{table}\n")
        write_section(f"all-intra codec on {a.sequence}", body)
    return 0


if __name__ == "__main__":
    sys.exit(main())
