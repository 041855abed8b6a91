"""Frames to frame units and texture units: the loop that the sequential encoder
(``api.encode_frames``) and each group of a parallel encode (``parallel``) run, and what
they share (the options split and checked, the core encoder, the texture stage)."""

from __future__ import annotations

import contextlib
import itertools
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np

from . import _core
from . import texture as _texture
from .defaults import ENCODER, FrameType
from .errors import with_frame
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


def texture_encoder(opts: dict, texture_options: dict, keep: bool, first_frame: int = 0) -> _texture.TextureEncoder:
    """The texture stage of a stream coded with the geometry options ``opts``, from frame
    ``first_frame`` on: it estimates texture costs for the frame decisions unless every frame
    is intra (no decision)."""
    return _texture.TextureEncoder(opts["subdiv"], texture_options, keep, estimate_costs=opts["intra_period"] > 1,
                                   first_frame=first_frame)


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
    units, texture units placed, without the sequence header. A frame's texture is coded
    while the next frame's geometry is (``TextureEncoder``): the geometry encoder asks for
    the texture cost only once the frame's predicted candidate is built."""
    units: list[bytes] = []
    result = EncodeResult(b"")
    try:
        for i, m in enumerate(meshes, first):
            if i >= count:
                raise ValueError(f"more than the {count} frames announced")
            try:
                with tex.geometry() if tex else contextlib.nullcontext():
                    unit, stats, (pos, faces), (base_pos, base_faces) = enc.encode_frame(m.positions, m.faces,
                                                                                         tex and tex.cost)
                stats["type"] = FrameType(stats["type"])
            except ValueError as e:
                raise with_frame(e, i) from None
            if tex:  # its errors name their frame
                tex.add(stats["starts_texture_group"], Mesh(base_pos, base_faces), Mesh(pos, faces), m)
            units.append(unit)
            result.frames.append(stats)
            if keep_reconstructions:
                result.reconstructions.append(Mesh(pos, faces))
            if on_frame is not None:
                on_frame(i, stats)
        texture_units = tex.finish() if tex else []
    finally:
        if tex:
            tex.close()
    result.data, result.texture_bytes = _with_texture_units(units, texture_units)
    if tex:
        for stats, covered in zip(result.frames, tex.coverage):
            stats["texture_coverage"] = covered
        if keep_reconstructions:
            for r, (uv, uv_faces), image in zip(result.reconstructions, tex.uvs, tex.images):
                r.uvs, r.uv_faces, r.image = uv, uv_faces, image
    return result


def _with_texture_units(units: list[bytes], texture_units: list[tuple[int, bytes]]) -> tuple[bytes, int]:
    """The frame units with each texture group's unit right after its first frame's unit,
    and the texture units' bytes."""
    after = {k: _core.texture_unit(payload) for k, payload in texture_units}
    data = b"".join(u + after.get(k, b"") for k, u in enumerate(units))
    return data, sum(len(u) for u in after.values())
