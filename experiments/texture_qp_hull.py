"""The one-knob mapping of textured streams: which texture QP goes with each geometry QP.

Sweeps (geometry QP, texture QP) pairs on the shared textured captures, measured as the
test conditions do (total rate; D1 and Y PSNR, each a mean of per-frame PSNRs), and scores
every mapping ``texture QP = slope x geometry QP + offset`` by its total-rate BD-rates of D1 and Y
against the MPEG test model's all-intra textured rows (``shared/anchors``). The geometry of
a geometry QP is coded once; each texture QP codes the same transferred images again, so a
pair costs a video encode and a metric, not a whole encode.

    python experiments/texture_qp_hull.py [--sequences liam_textured basketball_textured] [--codec av1]

Prints the pairs and the mappings ranked by the worse of their D1 and Y BD-rates (mean over
the sequences), then per sequence the bound no mapping can pass (the hull of all pairs, D1
and Y each on its own), and writes all of it as JSON to ``docs/results/texture_qp_hull.json``;
``--rescore`` ranks the pairs of that file again without coding.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np

import dynmesh
from dynmesh import _core, api, texture
from dynmesh.eval.report import bd_rate
from dynmesh.io import image_of
from dynmesh.mesh import Mesh

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"
OUT = ROOT / "docs" / "results" / "texture_qp_hull.json"

#: (frames, fps, peak) of each sequence as the test model's rows were measured.
SEQUENCES = {"basketball_textured": (3, 30, 1876.07788), "liam_textured": (6, 6, 1770.15149)}
GEOMETRY_QPS = (20, 24, 28, 32, 36)
TEXTURE_QPS = tuple(range(20, 47, 2))


def anchor_points(seq: str) -> list[dict]:
    with open(SHARED / "anchors" / "tm14_textured_anchor.csv") as f:
        return [r for r in csv.DictReader(f) if r["seq"] == seq and r["cond"] == "AI"]


def geometry_pass(frames: list[Mesh], qp: int, options: dict) -> tuple[int, list[tuple]]:
    """(geometry bytes incl. the header, per frame: what the texture stage takes)."""
    lo, hi = api.sequence_bounds(frames)
    enc = api._encoder(len(frames), lo, hi, {**api.DEFAULTS, **options, "qp": qp})
    nbytes, kept = len(enc.header_bytes()), []
    for m in frames:
        unit, stats, (pos, faces), (base_pos, base_faces) = enc.encode_frame(m.positions, m.faces)
        nbytes += len(unit)
        source = dataclasses.replace(m, image=image_of(m))  # read once, for every texture pass
        kept.append((stats["starts_texture_group"], Mesh(base_pos, base_faces), Mesh(pos, faces), source))
    return nbytes, kept


def texture_pass(kept: list[tuple], subdiv: int, tex_options: dict) -> tuple[int, list[Mesh]]:
    """(texture unit bytes, the reconstructions with UVs and decoded images)."""
    tex = texture.TextureEncoder(subdiv, tex_options, keep_images=True)
    for k in kept:
        tex.add(*k)
    nbytes = sum(len(_core.texture_unit(unit)) for _, unit in tex.finish())
    out = [Mesh(r.positions, r.faces, uvs=uv, uv_faces=uvf, image=img)
           for (_, _, r, _), (uv, uvf), img in zip(kept, tex.uvs, tex.images)]
    return nbytes, out


def sweep(seq: str, codec: str, options: dict) -> list[dict]:
    count, fps, peak = SEQUENCES[seq]
    paths = sorted((SHARED / "data" / seq).glob("*.obj"))[:count]
    frames = [dynmesh.read_mesh(p) for p in paths]
    size = texture.atlas_size_for(*texture.coder._texture_shape(frames[0]))
    rows = []
    for gqp in GEOMETRY_QPS:
        t0 = time.perf_counter()
        geom_bytes, kept = geometry_pass(frames, gqp, options)
        for tqp in TEXTURE_QPS:
            tex_bytes, recon = texture_pass(kept, api.DEFAULTS["subdiv"],
                                            {"texture_size": size, "texture_qp": tqp, "texture_codec": codec})
            m = api.metrics(frames, recon, peak=peak)
            total = geom_bytes + tex_bytes
            rows.append({"seq": seq, "qp": gqp, "texture_qp": tqp, "bytes": total, "tex_bytes": tex_bytes,
                         "mbps": 8 * total / count * fps / 1e6, "d1": m["d1_psnr"], "d2": m["d2_psnr"],
                         "y": m["y_psnr"], "cb": m["cb_psnr"], "cr": m["cr_psnr"]})
            r = rows[-1]
            print(f"{seq} qp {gqp} tqp {tqp}: {r['mbps']:.3f} Mbit/s ({100 * tex_bytes / total:.0f} % texture) "
                  f"D1 {r['d1']:.2f} Y {r['y']:.2f}", flush=True)
        print(f"  ({time.perf_counter() - t0:.0f} s)", flush=True)
    return rows


def mapping_scores(rows: list[dict], seq: str) -> list[dict]:
    """Total-rate BD-rates against the test model of each mapping texture QP = slope x
    geometry QP + offset (each point the swept texture QP nearest the mapping's)."""
    tm = anchor_points(seq)
    scores = []
    for slope in SLOPES:
        for offset in range(-30, 31):
            pts = []
            for gqp in GEOMETRY_QPS:
                want = slope * gqp + offset
                near = min(TEXTURE_QPS, key=lambda t: abs(t - want))
                if abs(near - want) <= 1:
                    pts += [r for r in rows if r["seq"] == seq and r["qp"] == gqp and r["texture_qp"] == near]
            if len(pts) < len(GEOMETRY_QPS):
                continue
            score = {"seq": seq, "slope": slope, "offset": offset}
            for key in ("d1", "y"):
                score[key] = bd_rate([(float(a["mbps"]), float(a[key])) for a in tm], [(p["mbps"], p[key]) for p in pts])["bd_rate"]
            scores.append(score)
    return scores


#: Slopes of the mappings scored (texture QP steps per geometry QP step).
SLOPES = (0.5, 0.75, 1.0, 1.25, 1.5)


def best(scores: list[dict]) -> list[dict]:
    """The mappings by the worse of their D1 and Y BD-rates, averaged over the sequences."""
    by_mapping: dict[tuple, list[dict]] = {}
    for s in scores:
        by_mapping.setdefault((s["slope"], s["offset"]), []).append(s)
    n = len({s["seq"] for s in scores})
    ranked = []
    for (slope, offset), group in by_mapping.items():
        if len(group) == n and all(g["d1"] is not None and g["y"] is not None for g in group):
            ranked.append({"slope": slope, "offset": offset, "worst": float(np.mean([max(g["d1"], g["y"]) for g in group])),
                           **{f"{g['seq']} {k}": g[k] for g in group for k in ("d1", "y")}})
    return sorted(ranked, key=lambda r: r["worst"])


def bounds(rows: list[dict], seq: str) -> dict:
    """The best any mapping could do: per measure, the BD-rate against the test model of the
    upper hull of every swept pair (each rate's best PSNR, whatever its QPs), so no rule
    that picks one pair per rate point can do better on these pairs."""
    tm = anchor_points(seq)
    out = {}
    for key in ("d1", "y"):
        front, top = [], -np.inf
        for r in sorted((r for r in rows if r["seq"] == seq), key=lambda r: r["mbps"]):
            if r[key] > top:
                front.append((r["mbps"], r[key]))
                top = r[key]
        out[key] = bd_rate([(float(a["mbps"]), float(a[key])) for a in tm], front)["bd_rate"]
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sequences", nargs="+", default=list(SEQUENCES))
    ap.add_argument("--codec", default=texture.TEXTURE_DEFAULTS["texture_codec"])
    ap.add_argument("--rescore", action="store_true", help="score the pairs of the last run again, without coding")
    a = ap.parse_args()
    if a.rescore:
        results = json.loads(OUT.read_text())
    else:
        if not (SHARED / "data").is_dir():
            print(f"no shared data under {SHARED / 'data'}", file=sys.stderr)
            return 1
        results = {"codec": a.codec, "rows": []}
        for seq in a.sequences:
            results["rows"] += sweep(seq, a.codec, {})
    results["scores"] = [s for seq in dict.fromkeys(r["seq"] for r in results["rows"]) for s in mapping_scores(results["rows"], seq)]
    results["best"] = best(results["scores"])
    for r in results["best"][:12]:
        print(" ".join(f"{k} {v:.2f}" if isinstance(v, float) else f"{k} {v}" for k, v in r.items()))
    for seq in dict.fromkeys(r["seq"] for r in results["rows"]):
        b = bounds(results["rows"], seq)
        print(f"{seq}: the best of all pairs, measure by measure: D1 {b['d1']:+.1f} %, Y {b['y']:+.1f} %")
    api.write_bytes_atomic(OUT, json.dumps(results, indent=1).encode())
    return 0


if __name__ == "__main__":
    sys.exit(main())
