"""What reading and writing one decoded-size frame costs in each mesh format.

Builds a noisy grid of ~210k vertices / 420k faces (float64 positions with all 17
significant digits, as decoded frames have), with and without per-corner UVs (UVs
with their own index list, a seam down the middle), and times ``write_mesh`` and
``read_mesh`` for OBJ, binary PLY and ASCII PLY, checking that every file reads back
to the same values. Reports the best of ``--repeat`` runs.

    python bench/bench_io.py [--side 458] [--repeat 3] [--no-write]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from dynmesh.io import read_mesh, write_mesh
from dynmesh.mesh import Mesh

from common import markdown_table, write_section

COLUMNS = [("format", "format", "s"), ("uvs", "UVs", "s"), ("mb", "file MB", ".1f"),
           ("write", "write s", ".3f"), ("read", "read s", ".3f")]


def grid_mesh(side: int, uvs: bool, seed: int = 0) -> Mesh:
    """A (side+1)^2-vertex grid, 2 side^2 triangles, with noise on every coordinate."""
    rng = np.random.default_rng(seed)
    n = side + 1
    y, x = np.mgrid[0:n, 0:n].astype(np.float64) / side
    z = 0.1 * np.sin(6 * x) * np.cos(4 * y)
    positions = np.stack([x, y, z], -1).reshape(-1, 3) + rng.normal(0, 1e-4, (n * n, 3))
    a = (np.arange(side)[:, None] * n + np.arange(side)[None, :]).reshape(-1)
    faces = np.concatenate([np.stack([a, a + 1, a + n + 1], 1), np.stack([a, a + n + 1, a + n], 1)])
    if not uvs:
        return Mesh(positions, faces)
    # UVs per vertex plus a copy of the middle column: faces right of it use the copy,
    # so uv_faces differs from faces along the seam.
    uv = positions[:, :2] * 0.5 + rng.normal(0, 1e-5, (n * n, 2))
    mid = np.arange(n) * n + side // 2
    seam = np.full(n * n, -1)
    seam[mid] = n * n + np.arange(n)
    uv = np.vstack([uv, uv[mid] + [0.5, 0.0]])
    right = positions[faces].mean(axis=1)[:, 0] > (side // 2) / side
    uv_faces = faces.copy()
    moved = right[:, None] & (seam[faces] >= 0)
    uv_faces[moved] = seam[faces][moved]
    return Mesh(positions, faces, uv, uv_faces)


def _best(f, repeat: int) -> tuple[object, float]:
    best, out = float("inf"), None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = f()
        best = min(best, time.perf_counter() - t0)
    return out, best


def _same(a: Mesh, b: Mesh) -> bool:
    """Positions bit for bit, faces, and the UV at every corner."""
    same = np.array_equal(a.positions.view(np.uint64), b.positions.view(np.uint64)) and np.array_equal(a.faces, b.faces)
    if a.uvs is not None:
        uv_a, uv_b = a.uvs[a.uv_faces], b.uvs[b.uv_faces]
        same = same and np.array_equal(uv_a.view(np.uint64), uv_b.view(np.uint64))
    return same


def rows(side: int, repeat: int, folder: Path) -> list[dict]:
    out = []
    for uvs in (False, True):
        mesh = grid_mesh(side, uvs)
        for name, suffix, ascii in (("OBJ", "obj", False), ("PLY binary", "ply", False), ("PLY ASCII", "ply", True)):
            path = folder / f"frame.{suffix}"
            _, t_write = _best(lambda: write_mesh(path, mesh, ascii=ascii), repeat)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                back, t_read = _best(lambda: read_mesh(path), repeat)
            if not _same(mesh, back):
                raise SystemExit(f"{name} did not read back to the mesh written")
            row = {"format": name, "uvs": "per corner" if uvs else "none", "mb": path.stat().st_size / 1e6,
                   "write": t_write, "read": t_read}
            print(", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in row.items()), flush=True)
            out.append(row)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--side", type=int, default=458, help="grid cells per side (458: 210681 vertices, 419528 faces)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--no-write", action="store_true", help="print only; leave docs/benchmarks.md alone")
    a = ap.parse_args()
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        table = rows(a.side, a.repeat, Path(tmp))
    if not a.no_write:
        n = a.side + 1
        note = (f"One frame: a noisy {n} x {n} grid, {n * n} vertices / {2 * a.side ** 2} faces, float64 positions "
                f"with 17 significant digits; 'per corner' UVs have their own index list (a seam down the middle). "
                f"Seconds are the best of {a.repeat} runs of `write_mesh` / `read_mesh` (atomic write included, "
                f"files in the system temporary folder); every file read back to the values written. The machine "
                f"is shared (1-minute load average {load:.1f} when the run started, on {os.cpu_count()} cores): "
                f"treat times as +-20 % at a load below 1, and as upper bounds above.\n\n"
                f"Before the Rust reader and writer (the numpy/Python io.py of commit dbf2047, same machine, "
                f"2026-12-01): OBJ write 1.205 s / read 1.156 s, binary PLY 0.040 / 0.031 s, ASCII PLY 1.175 / 1.349 s; "
                f"with per-corner UVs OBJ 1.699 / 1.402 s, binary PLY 0.147 / 1.809 s, ASCII PLY 3.129 / 4.132 s.\n\n")
        write_section("mesh file reading and writing", note + markdown_table(table, COLUMNS))
    return 0


if __name__ == "__main__":
    sys.exit(main())
