"""The Python surface of the codec: plain numpy arrays in, bytes out, and back."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import _core
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


def encode_frames(
    frames: Iterable,
    *,
    keep_reconstructions: bool = False,
    on_frame: Callable[[int, dict], None] | None = None,
    **options,
) -> EncodeResult:
    """Encodes a sequence (Mesh objects or (positions, faces) pairs) into one stream.

    Options (see ``DEFAULTS``): qp, base_ratio, subdiv, scheme ("midpoint" or "loop"),
    bits (position grid), base_bits (base mesh positions, at most bits), normal_only,
    intra_period (1 = every frame intra), inter ("none", "nns", "nns+me", "nns+me+qem"),
    rd_slope (dB per rate doubling, for the intra/inter decision), aq (adaptive quantization) with aq_alpha, aq_delta, aq_h.
    ``on_frame(index, stats)`` is called after each frame; ``stats["type"]`` is "I" or "P".
    Raises ValueError for an invalid mesh or option, naming the frame.
    """
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
    parts = [enc.header_bytes()]
    result = EncodeResult(b"")
    for i, m in enumerate(meshes):
        try:
            unit, stats, (pos, faces) = enc.encode_frame(m.positions, m.faces)
        except ValueError as e:
            raise ValueError(f"frame {i}: {e}") from None
        parts.append(unit)
        result.frames.append(stats)
        if keep_reconstructions:
            result.reconstructions.append(Mesh(pos, faces))
        if on_frame is not None:
            on_frame(i, stats)
    result.data = b"".join(parts)
    return result


def encode(frames: Iterable, **options) -> bytes:
    """Encodes a sequence of meshes into a dynmesh stream (see ``encode_frames``)."""
    return encode_frames(frames, **options).data


def _open(data: bytes) -> _core.Decoder:
    try:
        return _core.Decoder(bytes(data))
    except _core.DecodeError as e:
        raise DecodeError(*e.args) from None


def decode(data: bytes) -> Iterator[Mesh]:
    """Yields the decoded frames of a stream, in order. Raises DecodeError."""
    dec = _open(data)
    for i in range(dec.frame_count):
        try:
            pos, faces = dec.decode_frame(i)
        except _core.DecodeError as e:
            raise DecodeError(*e.args) from None
        yield Mesh(pos, faces)


def info(data: bytes) -> dict:
    """Sequence header and per-frame sizes of a stream."""
    dec = _open(data)
    try:
        frames = [dec.frame_info(i) for i in range(dec.frame_count)]
    except _core.DecodeError as e:
        raise DecodeError(*e.args) from None
    return {"bytes": len(data), "header": dec.header(), "frames": frames}


def metrics(reference, decoded, *, peak: float | None = None, grid_size: int = 1024) -> dict:
    """D1/D2 PSNR of ``decoded`` against ``reference`` (a Mesh or a list of them).

    The sampling grid lies over the bounding box of the whole reference sequence; the
    peak defaults to the largest side of that box. Returns per-frame figures and their
    means (the sequence figure of the MPEG test conditions).
    """
    refs = [reference] if isinstance(reference, Mesh) else list(reference)
    decs = [decoded] if isinstance(decoded, Mesh) else list(decoded)
    if len(refs) != len(decs):
        raise ValueError(f"{len(refs)} reference frames but {len(decs)} decoded frames")
    lo, hi = sequence_bounds(refs)
    peak = float(np.max(hi - lo)) if peak is None else float(peak)
    if not peak > 0:
        raise ValueError("peak must be positive")
    frames = []
    for r, d in zip(refs, decs):
        d1, d2, p1, p2 = _core.mesh_distortion(r.positions, r.faces, d.positions, d.faces,
                                               lo.tolist(), hi.tolist(), peak, grid_size)
        frames.append({"d1_mse": d1, "d2_mse": d2, "d1_psnr": p1, "d2_psnr": p2})
    mean = {k: float(np.mean([f[k] for f in frames])) for k in ("d1_psnr", "d2_psnr")}
    return {"peak": peak, "frames": frames, **mean}


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_bytes_atomic(path: str | os.PathLike, data: bytes) -> None:
    """Writes ``data`` to a temporary file beside ``path`` and renames it into place."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent or ".")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
