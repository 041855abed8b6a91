"""External codecs that the evaluation harness measures next to dynmesh.

Every codec adapter here (and the dynmesh one in :mod:`dynmesh.eval.evaluate`) offers the
same three things, so the harness treats them alike:

- ``DEFAULTS``: every option the codec takes, with its default value. Options outside
  it are rejected before anything runs; the defaults are merged into each run's
  options so that the cache key names every setting that shapes the stream.
- ``encode(meshes, **options) -> Encoded``: the whole sequence, with per-frame sizes.
- ``decode(payload) -> list[Mesh]``: the frames as the decoder returns them.
- ``version() -> str``: identifies the codec build (part of the cache key).
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import metadata

import numpy as np

from ..mesh import Mesh


@dataclass
class Encoded:
    """A coded sequence: ``payload`` is what ``decode`` takes; ``frame_bytes`` the size of
    each frame's unit; ``total_bytes`` all bytes of the stream (headers included), of which
    ``texture_bytes`` carry textures."""

    payload: object
    frame_bytes: list[int]
    total_bytes: int
    texture_bytes: int = 0


class Draco:
    """Google Draco (through DracoPy), one independent Draco mesh per frame.

    Positions are quantized over each frame's own bounding box (Draco's default: the
    cube of the frame's largest side); rate points sweep ``quantization_bits``.
    Draco reorders and may merge vertices and drops degenerate faces; the harness
    measures what it decodes, like any other decoder output. Per-frame streams are
    concatenated without any container, so the rate is the sum of the Draco buffers.
    """

    name = "draco"
    # compression_level 7 is the default of Draco's own draco_encoder tool (DracoPy's is 1).
    DEFAULTS = dict(quantization_bits=11, compression_level=7)

    @staticmethod
    def version() -> str:
        return f"DracoPy {metadata.version('DracoPy')}"

    @staticmethod
    def encode(meshes: list[Mesh], **options) -> Encoded:
        import DracoPy

        opts = {**Draco.DEFAULTS, **options}
        bits, level = int(opts["quantization_bits"]), int(opts["compression_level"])
        if not 1 <= bits <= 30:
            raise ValueError(f"draco quantization_bits must be 1..30, got {bits}")
        if not 0 <= level <= 10:
            raise ValueError(f"draco compression_level must be 0..10, got {level}")
        buffers = []
        for i, m in enumerate(meshes):
            try:
                buffers.append(DracoPy.encode(m.positions, m.faces.astype(np.uint32),
                                              quantization_bits=bits, compression_level=level))
            except Exception as e:  # DracoPy raises its own exception types
                raise ValueError(f"frame {i}: draco could not encode: {e}") from None
        sizes = [len(b) for b in buffers]
        return Encoded(buffers, sizes, sum(sizes))

    @staticmethod
    def decode(payload: list[bytes]) -> list[Mesh]:
        import DracoPy

        out = []
        for buf in payload:
            d = DracoPy.decode(buf)
            out.append(Mesh(np.asarray(d.points, dtype=np.float64), np.asarray(d.faces, dtype=np.int64)))
        return out
