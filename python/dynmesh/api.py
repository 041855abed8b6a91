"""The Python surface of the codec: plain numpy arrays in, bytes out, and back.

Exceptions, by kind (``dynmesh`` exports them too): ``InputError`` (a ValueError) for input
the core refuses, such as an encoder option out of range or a malformed mesh given to a core
function (``encode_frames`` names the frame it refused); ``DecodeError`` (a
ValueError, with ``frame`` and ``offset``) for a stream that cannot be decoded;
``UnsupportedError`` (a ValueError) for a well-formed stream this build does not read, such as
one of another format version or texture codec; ``InternalError`` (a RuntimeError) for a bug in dynmesh. Checks
made in Python (of ``texture``, ``jobs``, the frame count) raise plain ValueError.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

import numpy as np

from . import _core
from ._core import InputError, InternalError, UnsupportedError
from . import texture as _texture
from .defaults import FrameType
from .io.image import image_of
from .io.meshio import _atomic_write
from .mesh import Mesh
from .errors import with_frame
from .encoding import (DEFAULTS, EncodeResult, _encoder, _given_texture, _peek, _split_options,
                       encode_units, texture_encoder)


class DecodeError(ValueError):
    """A stream that cannot be decoded. ``frame`` is None while reading the header;
    ``offset`` is the byte offset in the stream where decoding stopped."""

    def __init__(self, message: str, frame: int | None, offset: int):
        super().__init__(message)
        self.frame = frame
        self.offset = offset


class TextureWarning(UserWarning):
    """Textures of the input that the stream will not carry: ``texture="auto"`` on a
    sequence where only some frames have UVs and a texture image codes the geometry only."""


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
    return texture_choice([_has_texture(m) for m in meshes], option)


def texture_choice(has: list[bool], option) -> bool:
    """Whether to code textures, given which frames have UVs and a texture image (``has``):
    ``option`` True/False, or "auto" (when every frame has them; when only some have, a
    ``TextureWarning`` names the first frame without, since their textures are dropped).
    Raises ValueError for True when a frame has none, or for another ``option``."""
    if option == "auto":
        if any(has) and not all(has):
            missing = has.count(False)
            warnings.warn(f"frame {has.index(False)} ({missing} of {len(has)} frames) has no UVs or texture image: "
                          "the stream carries the geometry only (--texture / texture=True refuses such input, "
                          "--no-texture / texture=False drops the textures without this warning)", TextureWarning, stacklevel=3)
        return all(has)
    if option is True and not all(has):
        raise ValueError(f"frame {has.index(False)}: texture coding asks for UVs and a texture image on every frame")
    if option not in (True, False):
        raise ValueError(f"texture must be True, False or 'auto', not {option!r}")
    return option


def encode_frames(
    frames: Iterable,
    *,
    keep_reconstructions: bool = False,
    on_frame: Callable[[int, dict], None] | None = None,
    texture: bool | str = "auto",
    sequence: tuple[int, np.ndarray, np.ndarray] | None = None,
    jobs: int = 1,
    ray: str | None = None,
    **options,
) -> EncodeResult:
    """Encodes a sequence (Mesh objects or (positions, faces) pairs) into one stream.

    ``sequence = (frame count, box min, box max)``, when the caller knows them, lets
    ``frames`` be any iterable (a generator reading one file at a time) consumed once, so
    that memory does not grow with the sequence: ``texture`` must then be True or False.

    Geometry options (see ``DEFAULTS``): qp, base_ratio, subdiv, scheme ("mixed" =
    midpoint then Loop on the last iteration, "midpoint", "loop", or a comma-separated list
    with one per iteration), bits (position grid), base_bits (base mesh positions, at most bits),
    base_ratio None follows the QP,
    normal_only, intra_period (1 = every frame intra), inter ("none", "nns", "nns+me",
    "nns+me+qem" the paper's stages, "nns+me+proj" ours), fold_repair, rigid_align, refresh (ours, all three), rd_slope (dB per rate doubling, for the intra/inter decision), intra_check_db (ours: a frame predicted through the anchor whose distortion lies this many dB above the last (or the group's best) intra frame's is coded intra too, and its refresh tried, before deciding), always_try_intra (ours: every predicted frame is), aq
    (adaptive quantization) with aq_alpha, aq_delta, aq_h.
    Textures (``texture``: "auto" codes them when every frame has UVs and a texture image,
    in ``Mesh.image`` or at ``Mesh.texture``, and warns, ``TextureWarning``, when only some
    frames have them): texture_size (atlas side in texels; None:
    about the texel count of the first frame's texture), texture_qp (video QP in HEVC's
    scale; None: follows ``qp``), texture_codec ("hevc" or "av1"); see ``dynmesh.texture``.
    ``jobs`` > 1 encodes the groups of ``intra_period`` frames in that many local processes,
    ``ray`` (a Ray cluster address or "auto") as tasks of a Ray cluster; the stream is the
    same byte for byte (see ``dynmesh.parallel``), and ``on_frame`` is then called for a
    group's frames when the group is done, in order. The local processes are spawned: a
    script that calls this needs the ``if __name__ == "__main__":`` guard.
    ``on_frame(index, stats)`` is called after each frame; ``stats["type"]`` is a ``FrameType``.
    Reconstructions of a textured stream carry their UVs and decoded texture image.
    Raises ValueError for an invalid mesh or option, naming the frame (InputError for an
    option the core refuses).
    """
    opts, texture_options = _split_options(options)
    count, lo, hi, meshes, textured = _sequence_of(frames, texture, sequence)
    enc = _encoder(count, lo, hi, opts)
    if textured:
        first, meshes = _peek(meshes)
        texture_options = _texture.resolve_options(texture_options, opts["qp"], first)
    if jobs != 1 or ray is not None:
        from . import parallel  # only when asked for: it imports multiprocessing

        groups = parallel.encoded_groups(meshes, (count, lo, hi), opts, texture_options if textured else None,
                                         keep_reconstructions, jobs, ray)
        result = EncodeResult(b"", texture_options=texture_options if textured else None)
        result.data = b"".join(parallel.stream_chunks(enc.header_bytes(), groups, result, on_frame))
        return result
    tex = texture_encoder(opts, texture_options, keep_reconstructions) if textured else None
    result = encode_units(enc, tex, meshes, 0, count, keep_reconstructions, on_frame)
    if len(result.frames) != count:
        raise ValueError(f"{len(result.frames)} frames where {count} were announced")
    result.data = enc.header_bytes() + result.data
    result.texture_options = texture_options if textured else None
    return result


def _sequence_of(frames: Iterable, texture, sequence) -> tuple[int, np.ndarray, np.ndarray, Iterable[Mesh], bool]:
    """(frame count, box min, box max, the frames as Mesh objects, whether to code
    textures): measured on the frames, or as ``sequence`` says (see ``encode_frames``)."""
    if sequence is None:
        meshes = [_as_mesh(f) for f in frames]
        return len(meshes), *sequence_bounds(meshes), meshes, _textured(meshes, texture)
    count, lo, hi = sequence
    return count, lo, hi, (_as_mesh(f) for f in frames), _given_texture(texture)


def encode(frames: Iterable, **options) -> bytes:
    """Encodes a sequence of meshes into a dynmesh stream (see ``encode_frames``)."""
    return encode_frames(frames, **options).data


def _open(data: bytes, tolerant: bool = False, lod: int | None = None) -> _core.Decoder:
    try:
        return _core.Decoder(bytes(data), tolerant, lod)
    except _core.DecodeError as e:
        raise DecodeError(*e.args) from None


def decode(data: bytes, lod: int | None = None) -> Iterator[Mesh]:
    """Yields the decoded frames of a stream, in order; frames of a textured stream carry
    their UVs and texture image. ``lod`` stops after that many subdivision iterations
    (default: all of the stream's). Raises DecodeError, UnsupportedError for a stream of
    another format version or a texture codec this build does not read, or ValueError
    (InputError) for a bad ``lod``."""
    for _, mesh in _decode_frames(_open(data, lod=lod), tolerant=False):
        if isinstance(mesh, (DecodeError, UnsupportedError)):
            raise mesh
        yield mesh


def decode_each(data: bytes, lod: int | None = None) -> Iterator[tuple[int, Mesh | DecodeError]]:
    """Yields ``(index, Mesh)`` for every frame of a possibly damaged stream whose reference
    chain (and texture unit) is intact, and ``(index, DecodeError)`` for the others (an
    ``UnsupportedError`` for a texture unit of a codec this build does not read), in order.
    Only the sequence header must be intact (else DecodeError is raised)."""
    return _decode_frames(_open(data, tolerant=True, lod=lod), tolerant=True)


def _decode_frames(dec: _core.Decoder, tolerant: bool) -> Iterator[tuple[int, Mesh | DecodeError | UnsupportedError]]:
    tex = _texture.TextureDecoder(dec, dec.lod, tolerant)
    textured = tex.textured()
    for i in range(dec.frame_count):
        try:
            pos, faces = dec.decode_frame(i)
        except _core.DecodeError as e:
            yield i, DecodeError(*e.args)
            continue
        mesh = Mesh(pos, faces)
        if textured:
            try:
                mesh.uvs, mesh.uv_faces, mesh.image = tex.texture_of(i)
            except UnsupportedError as e:  # a texture codec this build does not read
                yield i, e
                continue
            except ValueError as e:
                yield i, DecodeError(str(e), i, 0)
                continue
        yield i, mesh


def damage(data: bytes) -> list[dict]:
    """The damaged frame units of a stream: ``frame``, ``offset`` and ``end`` (bytes of the
    damaged stretch) and ``reason``; empty for an intact stream. Raises DecodeError when the
    sequence header itself is damaged."""
    dec = _open(data, tolerant=True)
    return [{"frame": f, "offset": start, "end": end, "reason": reason} for f, start, end, reason in dec.damage()]


def info(data: bytes) -> dict:
    """Sequence header and per-frame sizes of a stream (``texture_bytes``: the frame's
    texture unit, which an intra frame of a textured stream carries for its group).

    A stream with damaged frame units still gets its header and intact frames; ``damaged``
    lists the others (as :func:`damage` does) and their frame entries have ``type`` "?" and
    ``damaged`` True. Raises DecodeError when the sequence header is unreadable."""
    dec = _open(data, tolerant=True)
    damaged = [{"frame": f, "offset": start, "end": end, "reason": reason} for f, start, end, reason in dec.damage()]
    lost = {d["frame"]: d for d in damaged}
    frames = []
    for i in range(dec.frame_count):
        if i in lost:
            frames.append({"type": FrameType.UNKNOWN, "reference": None, "bytes": 0, "qp": 0, "base_bytes": 0, "refresh_bytes": 0,
                           "displacement_bytes": 0, "texture_bytes": 0, "damaged": True})
            continue
        try:
            f = dec.frame_info(i)
            t = dec.texture_payload(i)
        except _core.DecodeError as e:
            raise DecodeError(*e.args) from None
        frames.append({**f, "type": FrameType(f["type"]), "texture_bytes": 0 if t is None else len(t[0]), "damaged": False})
    return {"bytes": len(data), "header": dec.header(), "frames": frames, "damaged": damaged}


def _has_texture(m: Mesh) -> bool:
    return m.uvs is not None and (m.image is not None or m.texture is not None)


def metrics(reference, decoded, *, peak: float | None = None, grid_size: int = 1024) -> dict:
    """D1/D2 PSNR of ``decoded`` against ``reference`` (a Mesh or a list of them), and the
    texture's Y, Cb, Cr PSNR when both sides of every frame are textured.

    The sampling grid lies over the bounding box of the whole reference sequence; the
    peak defaults to the largest side of that box. Colour is sampled at the same grid
    points (bilinear lookup, each sample rounded to 8 bits as MPEG's mmetric does) and
    compared in BT.709 YCbCr with peak 1. Returns per-frame figures and
    their means (the sequence figure of the MPEG test conditions).
    """
    refs = [reference] if isinstance(reference, Mesh) else list(reference)
    decs = [decoded] if isinstance(decoded, Mesh) else list(decoded)
    if len(refs) != len(decs):
        raise ValueError(f"{len(refs)} reference frames but {len(decs)} decoded frames")
    lo, hi = sequence_bounds(refs)
    peak = float(np.max(hi - lo)) if peak is None else float(peak)
    if not (peak > 0 and np.isfinite(peak)):
        raise ValueError(f"peak must be a positive finite number, not {peak}")
    if not (isinstance(grid_size, (int, np.integer)) and 2 <= grid_size <= MAX_GRID_SIZE):
        raise ValueError(f"grid size must be an integer in 2..{MAX_GRID_SIZE}, not {grid_size}")
    textured = all(_has_texture(m) for m in refs + decs)
    frames = []
    for i, (r, d) in enumerate(zip(refs, decs)):
        try:
            frames.append(_frame_metrics(r, d, textured, lo, hi, peak, grid_size))
        except ValueError as e:
            raise with_frame(e, i) from None
    keys = ("d1_psnr", "d2_psnr") + (("y_psnr", "cb_psnr", "cr_psnr") if textured else ())
    mean = {k: float(np.mean([f[k] for f in frames])) for k in keys}
    return {"peak": peak, "frames": frames, **mean}


#: Largest metric grid size (the test conditions use 1024); the core also bounds the number
#: of samples a comparison may make, whatever the grid.
MAX_GRID_SIZE = 16384


def _frame_metrics(r: Mesh, d: Mesh, textured: bool, lo, hi, peak: float, grid_size: int) -> dict:
    """One frame's figures; ValueError when there is nothing to measure or too much to sample."""
    if textured:
        return dict(_core.textured_distortion(
            r.positions, r.faces, r.uvs, _uv_faces(r), image_of(r),
            d.positions, d.faces, d.uvs, _uv_faces(d), image_of(d),
            lo.tolist(), hi.tolist(), peak, grid_size))
    d1, d2, p1, p2 = _core.mesh_distortion(r.positions, r.faces, d.positions, d.faces,
                                           lo.tolist(), hi.tolist(), peak, grid_size)
    return {"d1_mse": d1, "d2_mse": d2, "d1_psnr": p1, "d2_psnr": p2}


def _uv_faces(m: Mesh) -> np.ndarray:
    return m.uv_faces if m.uv_faces is not None else m.faces


def write_bytes_atomic(path: str | os.PathLike, data: bytes) -> None:
    """Writes ``data`` to a temporary file beside ``path``, flushes it to disk and renames it
    into place (the mesh writers' atomic write)."""
    _atomic_write(Path(path), [data])
