"""What the texture path costs per 2048 x 2048 frame, stage by stage, against geometry alone.

Encodes the frames of basketball_textured twice in the same run, with and without texture,
and times each texture stage on its own: atlas (xatlas on the decoded base mesh + UV coding),
transfer (closest point + bilinear lookup + padding), video encode and decode per codec and
preset (libx265 ultrafast, superfast, veryfast; libsvtav1 at ``video.AV1_PRESET`` and 8, the
texture QP mapped to AV1's scale by ``video.av1_crf``), and the whole decode. Also renders a
snapshot of the last decoded frame to ``docs/results/textured_snapshot.png``.

    python bench/bench_texture.py [--size 2048] [--qp 32]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

import dynmesh
from dynmesh import _core
from dynmesh.io import read_image, write_image
from dynmesh.texture import atlas, video

from common import SHARED_DATA, check_data, markdown_table, write_section

SNAPSHOT = Path(__file__).resolve().parents[1] / "docs" / "results" / "textured_snapshot.png"


def _timed(f, *args, **kw):
    t0 = time.perf_counter()
    out = f(*args, **kw)
    return out, time.perf_counter() - t0


def stage_rows(frames, size: int, qp: int) -> list[dict]:
    """Seconds per frame of each texture stage, measured on the frames' own reconstructions."""
    geometry = dynmesh.encode_frames(frames, keep_reconstructions=True, texture=False)
    enc = _core.Encoder(len(frames), *[b.tolist() for b in dynmesh.api.sequence_bounds(frames)], dict(dynmesh.api.DEFAULTS))
    rows, images = [], []
    group = None  # (base faces, UVs, UV faces) of the group's atlas
    for i, m in enumerate(frames):
        _, _, (pos, faces), (base_pos, base_faces) = enc.encode_frame(m.positions, m.faces)
        (data, uv_faces, uv), t_atlas = _timed(atlas.coded_atlas, base_pos, base_faces, size)
        (uv_s, uv_faces_s), t_sub = _timed(_core.subdivide_uv, uv, uv_faces, dynmesh.api.DEFAULTS["subdiv"])
        # Every frame's atlas is timed, but, as in the encoder (texture/coder.py), a frame on
        # its group's base connectivity keeps the group's atlas: the video rows below then
        # code a group as the encoder makes it, whose pictures are alike.
        if group is None or not np.array_equal(base_faces, group[0]):
            group = (base_faces, uv_s, uv_faces_s)
        source = read_image(m.texture)
        (image, covered), t_transfer = _timed(_core.transfer_texture, pos, faces, group[1], group[2], m.positions, m.faces,
                                              m.uvs, m.uv_faces, source, size, size)
        images.append(image)
        kept = " (the group's atlas is kept)" if group[1] is not uv_s else ""
        rows.append({"stage": f"frame {i}: atlas + UV coding", "seconds": t_atlas,
                     "note": f"{len(data)} bytes, {len(base_faces)} base faces{kept}"})
        rows.append({"stage": f"frame {i}: UV subdivision", "seconds": t_sub, "note": f"{len(uv_faces_s)} faces"})
        rows.append({"stage": f"frame {i}: texture transfer + padding", "seconds": t_transfer, "note": f"{100 * covered:.1f} % of texels covered"})
    # The texture QP is in HEVC's scale for both codecs (video.av1_crf maps it for AV1), so
    # the rows compare sizes at about the same luma PSNR. Each codec's default preset is marked.
    codecs = [("hevc", p) for p in ("ultrafast", "superfast", "veryfast")] + [("av1", p) for p in (video.AV1_PRESET, 8)]
    for codec, preset in codecs:
        data, t_enc = _timed(video.encode_video, images, codec, qp, preset=preset)
        decoded, t_dec = _timed(lambda: list(video.decode_video(data, codec)))
        luma = [10 * np.log10(255**2 / np.mean(((d.astype(float) - s) @ [0.2126, 0.7152, 0.0722]) ** 2))
                for d, s in zip(decoded, images)]
        default = preset == {"hevc": video.HEVC_PRESET, "av1": video.AV1_PRESET}[codec]
        name = f"{codec} preset {preset}" + (" (default)" if default else "")
        quantizer = f"QP {qp}" if codec == "hevc" else f"QP {qp} = crf {video.av1_crf(qp):g}"
        rows.append({"stage": f"video encode ({name})", "seconds": t_enc / len(images),
                     "note": f"{len(data) // len(images)} bytes/frame, Y PSNR {np.mean(luma):.2f} dB at {quantizer}"})
        rows.append({"stage": f"video decode ({name})", "seconds": t_dec / len(images), "note": ""})
    return rows, geometry


def whole_rows(frames, size: int, qp: int, geometry) -> list[dict]:
    textured, t_tex = _timed(dynmesh.encode_frames, frames, texture_size=size, texture_qp=qp)
    _, t_geo = _timed(dynmesh.encode_frames, frames, texture=False)
    decoded, t_dec_tex = _timed(lambda: list(dynmesh.decode(textured.data)))
    _, t_dec_geo = _timed(lambda: list(dynmesh.decode(geometry.data)))
    n = len(frames)
    m = dynmesh.metrics(frames, decoded, peak=1876.1)
    snapshot = _core.render(decoded[-1].positions, decoded[-1].faces, decoded[-1].uvs, decoded[-1].uv_faces,
                            decoded[-1].image, 768, 1024, azimuth=180.0)
    SNAPSHOT.parent.mkdir(parents=True, exist_ok=True)
    write_image(SNAPSHOT, snapshot)
    note = (f"{len(textured.data) // n} bytes/frame ({textured.texture_bytes // n} texture), "
            f"Y {m['y_psnr']:.2f} dB, D1 {m['d1_psnr']:.2f} dB")
    return [
        {"stage": "whole encode, textured (s/frame)", "seconds": t_tex / n, "note": note},
        {"stage": "whole encode, geometry only (s/frame)", "seconds": t_geo / n, "note": f"texture adds {(t_tex - t_geo) / n:.2f} s/frame"},
        {"stage": "whole decode, textured (s/frame)", "seconds": t_dec_tex / n, "note": ""},
        {"stage": "whole decode, geometry only (s/frame)", "seconds": t_dec_geo / n, "note": f"texture adds {(t_dec_tex - t_dec_geo) / n:.3f} s/frame"},
    ]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=2048)
    ap.add_argument("--qp", type=int, default=32)
    ap.add_argument("--no-write", action="store_true", help="print only; leave docs/benchmarks.md alone")
    a = ap.parse_args()
    if not check_data(["basketball_textured"]):
        return 1
    frames = [dynmesh.read_mesh(p) for p in sorted((SHARED_DATA / "basketball_textured").glob("*.obj"))]
    rows, geometry = stage_rows(frames, a.size, a.qp)
    rows += whole_rows(frames, a.size, a.qp, geometry)
    for r in rows:
        print(f"{r['stage']:45s} {r['seconds']:8.3f} s  {r['note']}", flush=True)
    if not a.no_write:
        note = (f"basketball_textured, {len(frames)} frames, {a.size} x {a.size} atlas, texture QP {a.qp}, default geometry "
                "options. Stage times are per frame and measured one at a time; the whole-codec rows compare encoding "
                "and decoding with and without texture in the same run. Snapshot of the last decoded frame: "
                "`docs/results/textured_snapshot.png`. The machine is shared: treat times as +-20 %.\n\n")
        write_section("texture path", note + markdown_table(rows, [("stage", "stage", "s"), ("seconds", "seconds", ".3f"),
                                                                   ("note", "", "s")]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
