"""Texture-stage variants on one geometry pass: what each would give at total rate.

Codes the first frames of a shared textured capture once at one geometry QP (as
``texture_qp_hull.py`` does), then runs the texture stage (atlas, transfer, video) in each
variant over a range of texture QPs, and prints each variant's Y, Cb and Cr BD-rates against
the first, at total rate and at texture rate. Variants, joined with ``+``:

- ``default``: the encoder's texture stage as it is;
- ``ss``: supersampled transfer (the atlas transferred at twice its side, then 2 x 2 box-averaged);
- ``blurS``, ``cblurS``: the transferred (padded) atlas blurred by a Gaussian of S texels,
  all of it or its chroma only;
- ``fullpack``: xatlas packing on the atlas's full resolution instead of half;
- ``pN``: SVT-AV1 preset N;
- ``sN``: an atlas of side N;
- ``mcN``, ``itN``: xatlas charting with ``max_cost`` N (default 2: larger charts above) or
  ``max_iterations`` N (default 1);
- ``svt:KEY=VALUE``: an SVT-AV1 parameter besides ``video.AV1_PARAMS`` (``svt:enable-qm=1``).

    python experiments/texture_stage_variants.py liam_textured 28 default,ss,fullpack,p4 [26,30,34,38,42]
"""

from __future__ import annotations

import sys
import time

import numpy as np

import dynmesh
from dynmesh import _core, api, texture
from dynmesh.eval.report import bd_rate
from dynmesh.texture import atlas, coder, video

import texture_qp_hull as hull


def supersampled_transfer(transfer, k: int = 2):
    def run(rp, rf, uv, uvf, sp, sf, suv, suvf, img, w, h):
        t, covered = transfer(rp, rf, uv, uvf, sp, sf, suv, suvf, img, w * k, h * k)
        t = t.reshape(h, k, w, k, -1).astype(np.float32).mean(axis=(1, 3))
        return np.clip(np.rint(t), 0, 255).astype(np.uint8), covered
    return run


#: RGB -> BT.709 Y, Cb, Cr (full range, as the video's conversion).
BT709 = np.array([[0.2126, 0.7152, 0.0722], [-0.1146, -0.3854, 0.5], [0.5, -0.4542, -0.0458]])


def blurred_transfer(transfer, sigma: float, planes=(0, 1, 2)):
    """The transfer, then a Gaussian blur of ``sigma`` texels over the whole padded image, of
    its BT.709 ``planes`` (0 = Y, 1 = Cb, 2 = Cr; all three blur the image itself)."""
    from scipy.ndimage import gaussian_filter

    def run(*args):
        t, covered = transfer(*args)
        ycc = t.astype(np.float64) @ BT709.T
        for k in planes:
            ycc[..., k] = gaussian_filter(ycc[..., k], sigma=sigma, mode="nearest")
        return np.clip(np.rint(ycc @ np.linalg.inv(BT709).T), 0, 255).astype(np.uint8), covered
    return run


def configure(variant: str, size: int, originals: dict) -> int:
    """Sets the texture stage up for ``variant``; returns its atlas side."""
    tokens = variant.split("+")
    coder._core.transfer_texture = supersampled_transfer(originals["transfer"]) if "ss" in tokens else originals["transfer"]
    for t in tokens:
        if t.startswith("blur"):
            coder._core.transfer_texture = blurred_transfer(coder._core.transfer_texture, float(t[4:]))
        elif t.startswith("cblur"):
            coder._core.transfer_texture = blurred_transfer(coder._core.transfer_texture, float(t[5:]), (1, 2))

    def full(side):
        pack = originals["pack"](side)
        pack.resolution = side
        return pack

    atlas._packing = full if "fullpack" in tokens else originals["pack"]

    def charting():
        options = originals["chart"]()
        for t in tokens:
            if t.startswith("mc"):
                options.max_cost = float(t[2:])
            elif t.startswith("it"):
                options.max_iterations = int(t[2:])
        return options

    atlas._charting = charting
    video.AV1_PRESET = next((int(t[1:]) for t in tokens if t[0] == "p" and t[1:].isdigit()), originals["preset"])
    video.AV1_PARAMS = {**originals["params"], **dict(t[4:].split("=", 1) for t in tokens if t.startswith("svt:"))}
    return next((int(t[1:]) for t in tokens if t[0] == "s" and t[1:].isdigit()), size)


def main() -> int:
    seq, gqp, variants = sys.argv[1], int(sys.argv[2]), sys.argv[3].split(",")
    tqps = [int(x) for x in sys.argv[4].split(",")] if len(sys.argv) > 4 else [26, 30, 34, 38, 42]
    count, _, peak = hull.SEQUENCES[seq]
    frames = [dynmesh.read_mesh(p) for p in sorted((hull.SHARED / "data" / seq).glob("*.obj"))[:count]]
    size = texture.atlas_size_for(*coder._texture_shape(frames[0]))
    geometry_bytes, kept = hull.geometry_pass(frames, gqp, {})
    originals = {"transfer": _core.transfer_texture, "pack": atlas._packing, "chart": atlas._charting,
                 "preset": video.AV1_PRESET, "params": video.AV1_PARAMS}
    results = {}
    for variant in variants:
        side = configure(variant, size, originals)
        results[variant] = []
        for tqp in tqps:
            t0 = time.perf_counter()
            tex_bytes, recon = hull.texture_pass(kept, api.DEFAULTS["subdiv"], {"texture_size": side, "texture_qp": tqp, "texture_codec": "av1"})
            m = api.metrics(frames, recon, peak=peak)
            results[variant].append((geometry_bytes + tex_bytes, tex_bytes, m["y_psnr"], m["cb_psnr"], m["cr_psnr"]))
            print(f"{variant} texture QP {tqp}: texture {tex_bytes} B, total {geometry_bytes + tex_bytes} B, "
                  f"Y {m['y_psnr']:.2f} Cb {m['cb_psnr']:.2f} Cr {m['cr_psnr']:.2f} ({time.perf_counter() - t0:.0f} s)", flush=True)
    base = results[variants[0]]
    for variant in variants[1:]:
        for i, name in ((2, "Y"), (3, "Cb"), (4, "Cr")):
            total = bd_rate([(p[0], p[i]) for p in base], [(p[0], p[i]) for p in results[variant]])["bd_rate"]
            tex = bd_rate([(p[1], p[i]) for p in base], [(p[1], p[i]) for p in results[variant]])["bd_rate"]
            print(f"{variant} against {variants[0]}: {name} BD-rate {total:+.1f} % at total rate, {tex:+.1f} % at texture rate")
    return 0


if __name__ == "__main__":
    sys.exit(main())
