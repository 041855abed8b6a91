"""The texture atlas of an intra frame: UV charts made on the decoded base mesh.

xatlas charts and packs the base mesh (a few thousand triangles; on a raw capture it takes
minutes, on the base mesh well under a second). The UVs are then quantized to a grid of
``2**bits`` steps so that encoder and decoder hold exactly the same atlas: the quantized
integers are what the stream codes (``_core.encode_uv``), and both sides derive every later
UV (the subdivided mesh's, through ``_core.subdivide_uv``) from them.
"""

from __future__ import annotations

import numpy as np

from .. import _core

#: Bits of the quantized UVs: 4096 steps, half a texel of a 2048 x 2048 atlas.
UV_BITS = 12


def _packing(size: int):
    """Packing on a grid of half the atlas side: charts land on even texels and the gutter is
    the same number of texels, in about half the packing time. (On basketball_textured it
    changed texture bytes by -1 % and luma PSNR by -0.02 dB; one charting iteration fewer,
    the other speed knob, cost 6-8 % texture bytes and was left alone.)"""
    import xatlas  # only textured streams need it; importing it costs every command time

    pack = xatlas.PackOptions()
    pack.resolution = max(1, int(size) // 2)
    pack.padding = max(1, size // 1024)
    pack.bilinear = True
    return pack


def _charting():
    """xatlas's charting: 4 iterations of chart growing instead of its default 1. Measured on
    the encoder's own atlases (``experiments/texture_stage_variants.py``, variants ``it1``,
    ``it2``, ...; geometry QP 28, texture QP 26-42, Y BD-rate at total rate against 1 iteration): 2, 4 and 8 iterations gave
    -1.3, -3.3 and -2.3 % on liam_textured and -2.4, -1.5 and -0.8 % on basketball_textured,
    for 0.03, 0.11 and 0.3 s more per atlas; a larger ``max_cost`` was no better (-2.2 and
    -0.5 %, with 4 iterations -4.5 and +7.5 %)."""
    import xatlas

    options = xatlas.ChartOptions()
    options.max_iterations = 4
    return options


def make_atlas(positions: np.ndarray, faces: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    """Charts and packs the mesh ``(positions, faces)`` into a ``size`` x ``size`` atlas.

    Returns ``(uv_faces (M, 3) int64, uv (K, 2) float64 in [0, 1])``, one UV triangle per
    face in face order. Charts are packed with a gutter of a few texels, so that bilinear
    lookups and the chroma subsampling of the video do not mix neighbouring charts.
    """
    import xatlas

    atlas = xatlas.Atlas()
    atlas.add_mesh(np.ascontiguousarray(positions, np.float32), np.ascontiguousarray(faces, np.uint32))
    atlas.generate(chart_options=_charting(), pack_options=_packing(size))
    vmapping, indices, uv = atlas[0]
    uv_faces = np.asarray(indices, np.int64).reshape(-1, 3)
    if len(uv_faces) != len(faces) or not np.array_equal(np.asarray(vmapping)[uv_faces], faces):
        raise RuntimeError("xatlas changed the faces of the base mesh")
    return uv_faces, np.asarray(uv, np.float64)


def quantize_uv(uv: np.ndarray, bits: int = UV_BITS) -> np.ndarray:
    """UVs in [0, 1] to integers in [0, 2**bits - 1] (clamped)."""
    top = (1 << bits) - 1
    return np.clip(np.rint(np.asarray(uv, np.float64) * top), 0, top).astype(np.int64)


def dequantize_uv(q: np.ndarray, bits: int = UV_BITS) -> np.ndarray:
    """The UVs that quantized integers stand for."""
    return np.asarray(q, np.float64) / ((1 << bits) - 1)


def coded_atlas(positions: np.ndarray, faces: np.ndarray, size: int, bits: int = UV_BITS) -> tuple[bytes, np.ndarray, np.ndarray]:
    """The atlas of a base mesh as the stream carries it.

    Returns ``(coded bytes, uv_faces, uv)`` where ``uv_faces`` and ``uv`` are exactly what
    ``decoded_atlas`` gives back from the bytes (canonical UV order, dequantized)."""
    uv_faces, uv = make_atlas(positions, faces, size)
    uv_faces, q = _core.canonical_uv(uv_faces, quantize_uv(uv, bits))
    data = _core.encode_uv(faces, uv_faces, q, bits, positions=positions)
    return bytes(data), uv_faces, dequantize_uv(q, bits)


def decoded_atlas(data: bytes, positions: np.ndarray, faces: np.ndarray, bits: int) -> tuple[np.ndarray, np.ndarray]:
    """``(uv_faces, uv)`` of a coded atlas on the decoded base mesh ``(positions, faces)``,
    which must be bit for bit the one it was coded on: the shapes of its triangles predict
    the UVs. Raises ValueError when the data is corrupt."""
    uv_faces, q = _core.decode_uv(data, faces, len(positions), bits, positions=positions)
    return uv_faces, dequantize_uv(q, bits)
