"""Inter coding where parts that move differently are one connected surface (issue 46, item 4).

The baseline of the class: the default encoder against ``inter="none"`` on three synthetic
sequences re-meshed every frame by ``dynmesh.synth`` (about 11-13k vertices a frame):

- separate gears: ``fused_gear_sequence(gap=0.1)``, two components, the case rigid alignment
  of each connected component was built for;
- fused gears: ``fused_gear_sequence()`` (gap -0.06), the same gears with their teeth fused into
  one surface, as a capture merges whatever touches;
- cloth: ``cloth_sequence()``, a wrinkled sleeve sliding along an arm it rests on, one surface.

First 8 frames of each (so that the whole run stays within about 10 minutes on two busy cores),
QP 20-36 in steps of 4, D1 PSNR with ``dynmesh.metrics`` (metric grid 512, peak the largest side
of the sequence's box), rate at 30 frames/s, D1 BD-rate (PCHIP, ``dynmesh.eval.report.bd_rate``).
Streams that are byte for byte the same (the default coding every frame intra) are measured once.

    python experiments/one_surface_parts.py [--frames 8] [--grid 512] [--set motion_parts=true ...]
        [--common normal_only=false ...] [--out docs/results/one_surface_parts.json]

``--set`` changes options of the encoder compared with ``inter="none"`` (the defaults
otherwise), so that a new stage is measured on the same footing; ``--common`` changes options
of both encoders.

Prints the curves, the BD-rates and the default's frame types at QP 28, and writes all of it as
JSON to ``docs/results/one_surface_parts.json``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from pathlib import Path

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

import dynmesh
from dynmesh import _core
from dynmesh.eval.report import bd_rate
from dynmesh.mesh import Mesh
from dynmesh.synth import cloth_sequence, fused_gear_sequence

OUT = Path(__file__).resolve().parents[1] / "docs" / "results" / "one_surface_parts.json"
QPS = (20, 24, 28, 32, 36)
#: The two encoders compared: the default against no inter prediction (all intra).
CONFIGS = {"default": {}, "inter none": {"inter": "none"}}
FPS = 30


def sequences(frames: int) -> dict[str, list[Mesh]]:
    return {"separate gears (gap 0.1)": fused_gear_sequence(frames, gap=0.1),
            "fused gears": fused_gear_sequence(frames),
            "cloth": cloth_sequence(frames)}


def components(mesh: Mesh) -> int:
    """Connected components of the surface (faces linked through shared vertices)."""
    f = mesh.faces
    links = coo_matrix((np.ones(2 * len(f)), (np.concatenate([f[:, 0], f[:, 1]]), np.concatenate([f[:, 1], f[:, 2]]))),
                       shape=(mesh.vertex_count,) * 2)
    return connected_components(links, directed=False)[0]


def core_built() -> str:
    """When the Rust extension measured was built (others may rebuild it during a run)."""
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(Path(_core.__file__).stat().st_mtime))


def point(frames: list[Mesh], qp: int, options: dict, grid: int, measured: dict) -> dict:
    """One rate point; ``measured`` holds the D1 of streams already measured, by digest."""
    t0 = time.perf_counter()
    r = dynmesh.encode_frames(frames, qp=qp, **options)
    encode_s = time.perf_counter() - t0
    digest = hashlib.sha256(r.data).hexdigest()
    if digest not in measured:
        measured[digest] = dynmesh.metrics(frames, list(dynmesh.decode(r.data)), grid_size=grid)
    m = measured[digest]
    # Per frame too: one badly coded frame pulls the mean of the per-frame PSNRs far down.
    return {"qp": qp, "bytes": len(r.data), "mbps": len(r.data) * 8 * FPS / len(frames) / 1e6,
            "d1": m["d1_psnr"], "d1_frames": [round(f["d1_psnr"], 2) for f in m["frames"]],
            "types": "".join(f["type"] for f in r.frames), "encode_s": round(encode_s, 2)}


def measure(name: str, frames: list[Mesh], grid: int) -> dict:
    measured: dict[str, dict] = {}
    curves = {}
    for config, options in CONFIGS.items():
        curves[config] = [point(frames, qp, options, grid, measured) for qp in QPS]
        for p in curves[config]:
            print(f"{name} / {config} QP {p['qp']}: {p['mbps']:.4f} Mbit/s D1 {p['d1']:.2f} {p['types']} "
                  f"({p['encode_s']:.1f} s)", flush=True)
    bd = bd_rate(*[[(p["mbps"], p["d1"]) for p in curves[c]] for c in ("inter none", "default")])
    return {"vertices": [m.vertex_count for m in frames], "components": [components(m) for m in frames],
            "curves": curves, "bd_rate": bd["bd_rate"], "overlap": bd["overlap"], "note": bd["note"],
            "types_qp28": next(p["types"] for p in curves["default"] if p["qp"] == 28)}


def option(text: str) -> tuple[str, object]:
    """``key=value`` with value a JSON literal (true, 3, 0.5) or else a string."""
    key, _, value = text.partition("=")
    try:
        return key, json.loads(value)
    except json.JSONDecodeError:
        return key, value


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=8)
    ap.add_argument("--grid", type=int, default=512, help="metric grid size")
    ap.add_argument("--set", type=option, nargs="*", default=[], metavar="KEY=VALUE",
                    help="options of the encoder compared with inter none (default: the defaults)")
    ap.add_argument("--common", type=option, nargs="*", default=[], metavar="KEY=VALUE", help="options of both encoders")
    ap.add_argument("--out", type=Path, default=OUT)
    a = ap.parse_args()
    CONFIGS["default"] = {**dict(a.common), **dict(a.set)}
    CONFIGS["inter none"] = {**dict(a.common), "inter": "none"}
    start = time.perf_counter()
    results = {"frames": a.frames, "grid": a.grid, "qps": QPS, "fps": FPS, "configs": CONFIGS,
               "core_built": core_built(), "sequences": {}}
    for name, frames in sequences(a.frames).items():
        results["sequences"][name] = r = measure(name, frames, a.grid)
        print(f"{name}: vertices {min(r['vertices'])}-{max(r['vertices'])}, components {r['components']}", flush=True)
    print(f"\nD1 BD-rate, default against inter none, QP {QPS[0]}-{QPS[-1]}, first {a.frames} frames:")
    for name, r in results["sequences"].items():
        value = "n/a" if r["bd_rate"] is None else f"{r['bd_rate']:+.1f} %"
        print(f"  {name}: {value} (overlap {r['overlap']:.2f}{'; ' + r['note'] if r['note'] else ''}), "
              f"frame types at QP 28: {r['types_qp28']}")
    results["seconds"] = round(time.perf_counter() - start)
    if core_built() != results["core_built"]:
        print("the extension was rebuilt during the run: its figures mix two builds", file=sys.stderr)
        results["core_rebuilt"] = core_built()
    print(f"({results['seconds']} s)")
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(results, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
