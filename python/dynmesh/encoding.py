"""Frames to frame units and texture units: the loop that the sequential encoder
(``api.encode_frames``) and each group of a parallel encode (``parallel``) run, and what
they share (the options split and checked, the core encoder, the texture stage)."""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np

from . import _core
from . import texture as _texture
from .defaults import ENCODER, FrameType
from .io import read_image
from .mesh import Mesh

#: Encoder defaults, as the Rust core defines them; ``dynmesh encode --help`` documents each.
DEFAULTS: dict = ENCODER


@dataclass
class EncodeResult:
    """A whole stream with what the encoder measured per frame."""

    data: bytes
    frames: list[dict] = field(default_factory=list)
    reconstructions: list[Mesh] = field(default_factory=list)
    #: Bytes of the texture units (0 for an untextured stream); the rest is geometry.
    texture_bytes: int = 0
    #: The texture options the stream was coded with, those left to the encoder chosen
    #: (None for an untextured stream).
    texture_options: dict | None = None


def _place_texture_unit(parts: list[list[bytes]], closed: tuple[int, bytes] | None) -> None:
    """Puts a closed texture group's unit right after its first frame's unit (``parts[i]``
    is the ``i``-th frame coded by the texture encoder and what follows it)."""
    if closed:
        parts[closed[0]].append(_core.texture_unit(closed[1]))


def _image_of(m: Mesh) -> np.ndarray:
    return m.image if m.image is not None else read_image(m.texture)


def texture_encoder(opts: dict, texture_options: dict, keep: bool) -> _texture.TextureEncoder:
    """The texture stage of a stream coded with the geometry options ``opts``: it estimates
    texture costs for the frame decisions unless every frame is intra (no decision)."""
    return _texture.TextureEncoder(opts["subdiv"], texture_options, keep, estimate_costs=opts["intra_period"] > 1)


def _peek(meshes: Iterable[Mesh]) -> tuple[Mesh, Iterable[Mesh]]:
    """The first of ``meshes`` and all of them again (a generator is consumed once)."""
    it = iter(meshes)
    first = next(it, None)
    if first is None:
        raise ValueError("no frames")
    return first, itertools.chain([first], it)


def _split_options(options: dict) -> tuple[dict, dict]:
    """(geometry options with the defaults filled in, checked texture options) of the
    options ``encode_frames`` takes; raises ValueError for an unknown or bad one."""
    texture_options = _texture.check_options({k: v for k, v in options.items() if k in _texture.TEXTURE_DEFAULTS})
    geometry = {k: v for k, v in options.items() if k not in _texture.TEXTURE_DEFAULTS}
    unknown = set(geometry) - set(DEFAULTS)
    if unknown:
        raise ValueError(f"unknown encoder option(s): {', '.join(sorted(unknown))}")
    return {**DEFAULTS, **geometry}, texture_options


def _given_texture(texture) -> bool:
    """``texture`` for a sequence given beforehand, where "auto" cannot look at the frames."""
    if texture not in (True, False):
        raise ValueError("texture must be True or False when the sequence is given")
    return texture


def _encoder(count: int, lo, hi, opts: dict) -> _core.Encoder:
    try:
        return _core.Encoder(count, np.asarray(lo, float).tolist(), np.asarray(hi, float).tolist(), opts)
    except TypeError as e:
        raise ValueError(f"invalid encoder option: {e}") from None


def encode_units(enc: _core.Encoder, tex: _texture.TextureEncoder | None, meshes: Iterable[Mesh], first: int,
                 count: int, keep_reconstructions: bool, on_frame: Callable[[int, dict], None] | None) -> EncodeResult:
    """Codes ``meshes`` as frames ``first``, ``first + 1``, ... (below ``count``) of the
    stream with ``enc`` and ``tex``, which start there: the result's ``data`` is their
    units, texture units placed, without the sequence header."""
    parts: list[list[bytes]] = []
    result = EncodeResult(b"")
    for i, m in enumerate(meshes, first):
        if i >= count:
            raise ValueError(f"more than the {count} frames announced")
        try:
            if tex:
                enc.set_texture_cost(tex.cost())
            unit, stats, (pos, faces), (base_pos, base_faces) = enc.encode_frame(m.positions, m.faces)
            stats["type"] = FrameType(stats["type"])
            closed = tex and tex.add(stats["type"], Mesh(base_pos, base_faces), Mesh(pos, faces), m, _image_of(m))
            if tex:
                stats["texture_coverage"] = tex.coverage[-1]
        except ValueError as e:
            raise ValueError(f"frame {i}: {e}") from None
        _place_texture_unit(parts, closed)
        parts.append([unit])
        result.frames.append(stats)
        if keep_reconstructions:
            result.reconstructions.append(Mesh(pos, faces))
        if on_frame is not None:
            on_frame(i, stats)
    _place_texture_unit(parts, tex and tex.finish())
    if tex is not None and keep_reconstructions:
        for r, (uv, uv_faces), image in zip(result.reconstructions, tex.uvs, tex.images):
            r.uvs, r.uv_faces, r.image = uv, uv_faces, image
    result.texture_bytes = sum(len(u) for p in parts for u in p[1:])
    result.data = b"".join(u for p in parts for u in p)
    return result
