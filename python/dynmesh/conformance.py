"""Conformance vectors: small streams and the hash of every decoded frame, which the Rust
and JavaScript decoders are both tested against (``tests/vectors``).

``python -m dynmesh.conformance [DIR]`` (default ``tests/vectors`` of the current directory:
run it from the repository root) encodes a handful of
short streams from the built-in synthetic sequence, one per coding tool (intra and predicted
frames, predicted through constant topology and through the anchor mesh, each subdivision
scheme, AQ on and off, normal-only and all-component coefficients, a refreshed region, a
textured stream), and
writes them with ``manifest.txt``: one line ``STREAM lod K frame N sha256 HEX`` per frame and
level of detail, the hash of ``frame_hash`` (and for textured frames a ``uvsha256`` line, the
hash of their UVs, ``uv_hash``); and ``scales.txt``, the quantization scale of
every bit depth and QP (the decoders' one libm call). Rerun it whenever the bitstream changes; the
files are written to temporary names and renamed, so an interrupted run leaves the old set.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from . import api
from .api import write_bytes_atomic
from .mesh import Mesh
from .synth import synth_sequence

DEFAULT_DIR = Path("tests") / "vectors"


def _warped(m: Mesh, frames: int) -> list[Mesh]:
    """``m`` and smooth deformations of it with the same connectivity (constant topology)."""
    out = []
    for f in range(frames):
        p = m.positions.copy()
        p[:, 0] += 0.08 * f * np.sin(2.0 * p[:, 1])
        p[:, 2] += 0.05 * f * p[:, 0] ** 2
        out.append(Mesh(p, m.faces.copy()))
    return out


def _jittered(m: Mesh, frames: int) -> list[Mesh]:
    """``m`` and strong deformations of it with the same connectivity: large enough that a
    predicted frame codes its coefficients directly rather than as differences (mode 0)."""
    rng = np.random.default_rng(1)
    out = [m]
    for f in range(1, frames):
        p = m.positions + 0.04 * rng.standard_normal(m.positions.shape) + 0.1 * f * np.sin(3 * m.positions)
        out.append(Mesh(p, m.faces.copy()))
    return out


def appearing(frames: list[Mesh], offset=(1.6, 0.0, 0.0)) -> list[Mesh]:
    """``frames`` with a second, smaller copy of the first appearing beside them from the second
    frame on (moving by 0.05 in y per frame): a part no reference base covers, which a predicted
    frame codes by refreshing that region."""
    first = frames[0]
    out = [first]
    for f, m in enumerate(frames[1:], 1):
        small = first.positions * 0.35 + np.array(offset) + np.array([0.0, 0.05 * (f - 1), 0.0])
        out.append(Mesh(np.vstack([m.positions, small]), np.vstack([m.faces, first.faces + len(m.positions)])))
    return out


def _image(size: int = 64) -> np.ndarray:
    """A smooth colour field with a checker on it."""
    y, x = np.mgrid[0:size, 0:size] / size
    rgb = [0.5 + 0.4 * np.sin(2 * np.pi * (x + 0.7 * y) + p) for p in (0.0, 2.0, 4.0)]
    check = ((np.floor(x * 8) + np.floor(y * 8)) % 2) * 0.15
    return np.clip(np.stack(rgb, -1) * 255 * (0.85 + check[..., None]), 0, 255).astype(np.uint8)


def _textured(meshes: list[Mesh]) -> list[Mesh]:
    """The meshes with per-vertex spherical UVs and one texture image."""
    image = _image()
    out = []
    for m in meshes:
        d = m.positions - m.positions.mean(axis=0)
        d /= np.linalg.norm(d, axis=1, keepdims=True) + 1e-12
        uv = np.stack([0.5 + np.arctan2(d[:, 1], d[:, 0]) / (2 * np.pi), np.arccos(np.clip(d[:, 2], -1, 1)) / np.pi], 1)
        out.append(Mesh(m.positions, m.faces, uvs=uv, uv_faces=m.faces.copy(), image=image))
    return out


def vector_specs() -> list[tuple[str, str, list[Mesh], dict]]:
    """(name, what it covers, frames, encoder options) of every vector."""
    # Frames close in time (the first 3 of 40): small changes, so predicted frames pay.
    changing = synth_sequence(frames=40, resolution=14)[:3]
    constant = _warped(changing[0], 3)
    small = dict(qp=30, subdiv=2, base_bits=8, bits=11)
    return [
        ("anchor_mixed_aq", "I + P through the anchor mesh (topology changes), mixed schemes, AQ, normal only",
         changing, dict(small, scheme="mixed", aq=True, rd_slope=100.0)),
        ("constant_midpoint_all", "I + P on constant topology, midpoint, no AQ, all three components",
         constant, dict(small, scheme="midpoint", aq=False, normal_only=False)),
        ("intra_loop_aq_all", "all intra, Loop on every iteration, AQ with a lattice offset, all components",
         changing[:2], dict(small, scheme="loop", intra_period=1, aq=True, aq_delta=0.25, normal_only=False)),
        ("constant_loop_noaq", "I + P on constant topology, Loop, no AQ, normal only, three iterations, "
         "constant lifting update (1/8, no valence division)",
         constant, dict(small, subdiv=3, scheme="loop", aq=False, lifting="constant")),
        ("constant_jitter_mode0", "I + P on constant topology with strong motion: the last P frame codes its "
         "coefficients directly (coefficient mode 0), the other as differences (mode 1)",
         _jittered(changing[0], 3), dict(small, scheme="midpoint", rd_slope=100.0)),
        ("far_reference", "I + P on constant topology with reference choice: the last frame repeats frame 1 "
         "and refers to it, two frames back (reference distance 2)",
         constant + constant[1:2], dict(small, scheme="midpoint", references=3, intra_reference=True, rd_slope=100.0)),
        ("anchor_refresh", "I + P through the anchor mesh where a second part appears: frame 1 refreshes "
         "that region (refresh block, §6.6), frame 2 refers to the refreshed frame",
         appearing(changing), dict(small, scheme="mixed")),
        ("textured_mixed", "textured (UV atlas, AV1 texture video), I + P, mixed schemes",
         _textured(constant[:2]), dict(small, scheme="mixed", texture_size=64, texture_codec="av1", texture_qp=40)),
    ]


def frame_hash(mesh) -> str:
    """SHA-256 of a decoded frame: positions as little-endian float64, then faces as
    little-endian uint32 (the ``--hash`` line of both decoders)."""
    import hashlib

    h = hashlib.sha256(np.ascontiguousarray(mesh.positions, "<f8").tobytes())
    h.update(np.ascontiguousarray(mesh.faces, "<u4").tobytes())
    return h.hexdigest()


def uv_hash(mesh) -> str:
    """SHA-256 of a textured frame's UVs: the UVs as little-endian float64, then the UV faces
    as little-endian uint32."""
    import hashlib

    h = hashlib.sha256(np.ascontiguousarray(mesh.uvs, "<f8").tobytes())
    h.update(np.ascontiguousarray(mesh.uv_faces, "<u4").tobytes())
    return h.hexdigest()


def hash_lines(name: str, data: bytes) -> list[str]:
    """The manifest lines of one stream: every frame at every level of detail (and, for a
    textured stream, a ``uvsha256`` line per frame: its UVs)."""
    levels = int(api.info(data)["header"]["subdiv_iterations"])
    lines = []
    for lod in range(levels + 1):
        for i, m in enumerate(api.decode(data, lod=lod)):
            lines.append(f"{name} lod {lod} frame {i} sha256 {frame_hash(m)}")
            if m.uvs is not None:
                lines.append(f"{name} lod {lod} frame {i} uvsha256 {uv_hash(m)}")
    return lines


def scale_lines() -> list[str]:
    """``bits qp HEX`` for every position bit depth and QP the format allows: the coarsest
    level's quantization scale ``2^(16 - bits + (4 - qp) / 6)`` as the bits of its float64.
    It is the decoder's one libm call (``powf``), so every decoder checks its own ``pow``
    against this table."""
    import struct

    return [f"{bits} {qp} {struct.pack('>d', 2.0 ** (16.0 - bits + (4.0 - qp) / 6.0)).hex()}"
            for bits in range(8, 21) for qp in range(-24, 64)]


def make_vectors(out: Path) -> dict:
    """Writes every vector and the manifests into ``out``; returns the description."""
    out.mkdir(parents=True, exist_ok=True)
    lines, described = [], []
    for name, what, frames, options in vector_specs():
        result = api.encode_frames(frames, **options)
        write_bytes_atomic(out / f"{name}.dmsh", result.data)
        lines += hash_lines(f"{name}.dmsh", result.data)
        described.append({"stream": f"{name}.dmsh", "covers": what, "bytes": len(result.data),
                          "types": "".join(f["type"] for f in result.frames), "options": options})
    write_bytes_atomic(out / "manifest.txt", ("\n".join(lines) + "\n").encode())
    write_bytes_atomic(out / "scales.txt", ("\n".join(scale_lines()) + "\n").encode())
    write_bytes_atomic(out / "vectors.json", (json.dumps(described, indent=1) + "\n").encode())
    return {"dir": str(out), "vectors": described}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m dynmesh.conformance", description=__doc__.split("\n\n")[0])
    p.add_argument("dir", nargs="?", default=str(DEFAULT_DIR), help=f"output directory (default {DEFAULT_DIR})")
    a = p.parse_args(argv)
    result = make_vectors(Path(a.dir))
    for v in result["vectors"]:
        print(f"{v['stream']:28s} {v['bytes']:6d} bytes  {v['types']:6s} {v['covers']}")
    print(f"wrote {len(result['vectors'])} vectors and manifest.txt into {result['dir']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
