"""Inter coding on sequences the codec was not tuned on: the defaults against ``--inter none``.

collision (shared data, synthetic: two objects that collide and merge) frames 0-5 and 24-29,
metric grid 256, peak 4.00 (shared/data/README.md); the gears of ``dynmesh.synth.gear_sequence``
(600 samples per rim, resampled every frame) turning 6, 12 and 20 degrees per frame, metric
grid 512, peak the largest side of their box. First 6 frames of each, QP 20-36 in steps of 4,
D1 BD-rate (PCHIP, ``dynmesh.eval.report.bd_rate``) of the defaults and of ``--no-refresh``, and
the defaults' frame types at each QP.

    python experiments/unseen_sequences.py [--data ../shared/data]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

import dynmesh
from dynmesh.eval.report import bd_rate
from dynmesh.io import resolve_sequence
from dynmesh.synth import gear_sequence

QPS = (20, 24, 28, 32, 36)


def curve(frames: list, options: dict, peak: float, grid: int) -> list[tuple[float, float, str]]:
    """(Mbit/s at 30 fps, D1 PSNR, frame types) per QP of the encoder with ``options``."""
    points = []
    for qp in QPS:
        r = dynmesh.encode_frames(frames, qp=qp, **options)
        m = dynmesh.metrics(frames, list(dynmesh.decode(r.data)), peak=peak, grid_size=grid)
        points.append((len(r.data) * 8 * 30 / len(frames) / 1e6, m["d1_psnr"], "".join(f["type"] for f in r.frames)))
    return points


def cases(data: Path):
    collision = [dynmesh.read_mesh(p) for p in resolve_sequence(data / "collision", 0, 30)]
    yield "collision 0-5", collision[0:6], 4.0, 256
    yield "collision 24-29", collision[24:30], 4.0, 256
    for degrees in (6.0, 12.0, 20.0):
        frames = gear_sequence(6, degrees, 600)
        lo = np.min([f.positions.min(0) for f in frames], 0)
        hi = np.max([f.positions.max(0) for f in frames], 0)
        yield f"gears {degrees:g} degrees/frame", frames, float(np.max(hi - lo)), 512


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2] / "shared" / "data")
    a = ap.parse_args()
    if not (a.data / "collision").is_dir():
        print(f"no collision sequence under {a.data}", file=sys.stderr)
        return 1
    for name, frames, peak, grid in cases(a.data):
        anchor = curve(frames, {"inter": "none"}, peak, grid)
        test, without = curve(frames, {}, peak, grid), curve(frames, {"refresh": False}, peak, grid)
        r, w = (bd_rate([p[:2] for p in anchor], [p[:2] for p in c]) for c in (test, without))
        value, plain = ("n/a" if x["bd_rate"] is None else f"{x['bd_rate']:+.1f} %" for x in (r, w))
        print(f"{name}: D1 BD-rate {value} (overlap {float(r['overlap']):.2f}; {plain} with --no-refresh), "
              f"types {' '.join(p[2] for p in test)}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
