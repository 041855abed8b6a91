"""The Python surface of the codec: plain numpy arrays in, bytes out, and back."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import _core
from . import texture as _texture
from .io import _atomic_write, read_image
from .mesh import Mesh

#: Encoder defaults, as the Rust core defines them; ``dynmesh encode --help`` documents each.
DEFAULTS: dict = dict(_core.default_options())


class DecodeError(ValueError):
    """A stream that cannot be decoded. ``frame`` is None while reading the header;
    ``offset`` is the byte offset in the stream where decoding stopped."""

    def __init__(self, message: str, frame: int | None, offset: int):
        super().__init__(message)
        self.frame = frame
        self.offset = offset


@dataclass
class EncodeResult:
    """A whole stream with what the encoder measured per frame."""

    data: bytes
    frames: list[dict] = field(default_factory=list)
    reconstructions: list[Mesh] = field(default_factory=list)
    #: Bytes of the texture units (0 for an untextured stream); the rest is geometry.
    texture_bytes: int = 0


def _as_mesh(frame) -> Mesh:
    if isinstance(frame, Mesh):
        return frame
    positions, faces = frame
    return Mesh(positions, faces)


def sequence_bounds(meshes: Iterable[Mesh]) -> tuple[np.ndarray, np.ndarray]:
    """(min, max) corners of the box around every vertex of every mesh.

    Raises ValueError naming the first frame with a NaN or infinite coordinate."""
    boxes = []
    for i, m in enumerate(meshes):
        bad = np.flatnonzero(~np.isfinite(np.asarray(m.positions, dtype=np.float64)).all(axis=1))
        if bad.size:
            raise ValueError(f"frame {i}: vertex {bad[0]} has a NaN or infinite coordinate")
        boxes.append(m.bounds())
    if not boxes:
        raise ValueError("no frames")
    return np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)


def _textured(meshes: list[Mesh], option) -> bool:
    """Whether to code textures: ``option`` True/False, or "auto" (when every frame has
    UVs and a texture)."""
    has = [_has_texture(m) for m in meshes]
    if option == "auto":
        return all(has)
    if option is True and not all(has):
        raise ValueError(f"frame {has.index(False)}: texture coding asks for UVs and a texture image on every frame")
    if option not in (True, False):
        raise ValueError(f"texture must be True, False or 'auto', not {option!r}")
    return option


def _place_texture_unit(parts: list[list[bytes]], closed: tuple[int, bytes] | None) -> None:
    """Puts a closed texture group's unit right after its first frame's unit (``parts[0]``
    is the header, ``parts[i + 1]`` frame ``i`` and what follows it)."""
    if closed:
        parts[closed[0] + 1].append(_core.texture_unit(closed[1]))


def _image_of(m: Mesh) -> np.ndarray:
    return m.image if m.image is not None else read_image(m.texture)


def encode_frames(
    frames: Iterable,
    *,
    keep_reconstructions: bool = False,
    on_frame: Callable[[int, dict], None] | None = None,
    texture: bool | str = "auto",
    **options,
) -> EncodeResult:
    """Encodes a sequence (Mesh objects or (positions, faces) pairs) into one stream.

    Geometry options (see ``DEFAULTS``): qp, base_ratio, subdiv, scheme ("mixed" =
    midpoint then Loop on the last iteration, "midpoint", "loop", or a comma-separated list
    with one per iteration), bits (position grid), base_bits (base mesh positions, at most bits),
    base_ratio None follows the QP,
    normal_only, intra_period (1 = every frame intra), inter ("none", "nns", "nns+me",
    "nns+me+qem"), rd_slope (dB per rate doubling, for the intra/inter decision), aq
    (adaptive quantization) with aq_alpha, aq_delta, aq_h.
    Textures (``texture``: "auto" codes them when every frame has UVs and a texture image,
    in ``Mesh.image`` or at ``Mesh.texture``): texture_size (atlas side in texels),
    texture_qp (video QP), texture_codec ("hevc" or "av1"); see ``dynmesh.texture``.
    ``on_frame(index, stats)`` is called after each frame; ``stats["type"]`` is "I" or "P".
    Reconstructions of a textured stream carry their UVs and decoded texture image.
    Raises ValueError for an invalid mesh or option, naming the frame.
    """
    texture_options = _texture.check_options({k: options.pop(k) for k in list(options) if k in _texture.TEXTURE_DEFAULTS})
    unknown = set(options) - set(DEFAULTS)
    if unknown:
        raise ValueError(f"unknown encoder option(s): {', '.join(sorted(unknown))}")
    opts = {**DEFAULTS, **options}
    meshes = [_as_mesh(f) for f in frames]
    lo, hi = sequence_bounds(meshes)
    try:
        enc = _core.Encoder(len(meshes), lo.tolist(), hi.tolist(), opts)
    except TypeError as e:
        raise ValueError(f"invalid encoder option: {e}") from None
    tex = _texture.TextureEncoder(opts["subdiv"], texture_options, keep_reconstructions) if _textured(meshes, texture) else None
    parts = [[enc.header_bytes()]]
    result = EncodeResult(b"")
    for i, m in enumerate(meshes):
        try:
            unit, stats, (pos, faces), (base_pos, base_faces) = enc.encode_frame(m.positions, m.faces)
            closed = tex and tex.add(stats["type"], Mesh(base_pos, base_faces), Mesh(pos, faces), m, _image_of(m))
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
    result.texture_bytes = sum(len(u) for p in parts[1:] for u in p[1:])
    result.data = b"".join(u for p in parts for u in p)
    return result


def encode(frames: Iterable, **options) -> bytes:
    """Encodes a sequence of meshes into a dynmesh stream (see ``encode_frames``)."""
    return encode_frames(frames, **options).data


def _open(data: bytes, lod: int | None = None) -> _core.Decoder:
    try:
        return _core.Decoder(bytes(data), lod)
    except _core.DecodeError as e:
        raise DecodeError(*e.args) from None


def decode(data: bytes, lod: int | None = None) -> Iterator[Mesh]:
    """Yields the decoded frames of a stream, in order; frames of a textured stream carry
    their UVs and texture image. ``lod`` stops after that many subdivision iterations
    (default: all of the stream's). Raises DecodeError, or ValueError for a bad ``lod``."""
    dec = _open(data, lod)
    tex = _texture.TextureDecoder(dec, dec.lod)
    textured = tex.textured()
    for i in range(dec.frame_count):
        try:
            pos, faces = dec.decode_frame(i)
        except _core.DecodeError as e:
            raise DecodeError(*e.args) from None
        mesh = Mesh(pos, faces)
        if textured:
            try:
                mesh.uvs, mesh.uv_faces, mesh.image = tex.texture_of(i)
            except ValueError as e:
                raise DecodeError(str(e), i, 0) from None
        yield mesh


def info(data: bytes) -> dict:
    """Sequence header and per-frame sizes of a stream (``texture_bytes``: the frame's
    texture unit, which an intra frame of a textured stream carries for its group)."""
    dec = _open(data)
    try:
        frames = [dec.frame_info(i) for i in range(dec.frame_count)]
        for i, f in enumerate(frames):
            t = dec.texture_payload(i)
            f["texture_bytes"] = 0 if t is None else len(t[0])
    except _core.DecodeError as e:
        raise DecodeError(*e.args) from None
    return {"bytes": len(data), "header": dec.header(), "frames": frames}


def _has_texture(m: Mesh) -> bool:
    return m.uvs is not None and (m.image is not None or m.texture is not None)


def metrics(reference, decoded, *, peak: float | None = None, grid_size: int = 1024) -> dict:
    """D1/D2 PSNR of ``decoded`` against ``reference`` (a Mesh or a list of them), and the
    texture's Y, Cb, Cr PSNR when both sides of every frame are textured.

    The sampling grid lies over the bounding box of the whole reference sequence; the
    peak defaults to the largest side of that box. Colour is sampled at the same grid
    points (bilinear lookup), in BT.709 YCbCr with peak 1. Returns per-frame figures and
    their means (the sequence figure of the MPEG test conditions).
    """
    refs = [reference] if isinstance(reference, Mesh) else list(reference)
    decs = [decoded] if isinstance(decoded, Mesh) else list(decoded)
    if len(refs) != len(decs):
        raise ValueError(f"{len(refs)} reference frames but {len(decs)} decoded frames")
    lo, hi = sequence_bounds(refs)
    peak = float(np.max(hi - lo)) if peak is None else float(peak)
    if not peak > 0:
        raise ValueError("peak must be positive")
    textured = all(_has_texture(m) for m in refs + decs)
    frames = []
    for r, d in zip(refs, decs):
        if textured:
            frames.append(dict(_core.textured_distortion(
                r.positions, r.faces, r.uvs, _uv_faces(r), _image_of(r),
                d.positions, d.faces, d.uvs, _uv_faces(d), _image_of(d),
                lo.tolist(), hi.tolist(), peak, grid_size)))
        else:
            d1, d2, p1, p2 = _core.mesh_distortion(r.positions, r.faces, d.positions, d.faces,
                                                   lo.tolist(), hi.tolist(), peak, grid_size)
            frames.append({"d1_mse": d1, "d2_mse": d2, "d1_psnr": p1, "d2_psnr": p2})
    keys = ("d1_psnr", "d2_psnr") + (("y_psnr", "cb_psnr", "cr_psnr") if textured else ())
    mean = {k: float(np.mean([f[k] for f in frames])) for k in keys}
    return {"peak": peak, "frames": frames, **mean}


def _uv_faces(m: Mesh) -> np.ndarray:
    return m.uv_faces if m.uv_faces is not None else m.faces


def write_bytes_atomic(path: str | os.PathLike, data: bytes) -> None:
    """Writes ``data`` to a temporary file beside ``path``, flushes it to disk and renames it
    into place (the mesh writers' atomic write)."""
    _atomic_write(Path(path), [data])
