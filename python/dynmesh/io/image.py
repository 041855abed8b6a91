"""Reading texture images: PNG through the core (``_core.read_png``), other formats (JPEG)
and PNGs it does not take (16-bit) through Pillow. Writing is ``meshio.write_image``."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .. import _core
from .errors import MeshError

__all__ = ["read_image", "decode_image", "image_of"]

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def image_of(mesh) -> np.ndarray:
    """The texture of a ``Mesh``: its ``image``, or else its ``texture`` file read."""
    return mesh.image if mesh.image is not None else read_image(mesh.texture)


def read_image(path: str | os.PathLike) -> np.ndarray:
    """A texture image (PNG, JPEG, anything Pillow reads) as (H, W, 3) uint8 RGB, rows from
    the top (an alpha channel is dropped). Raises MeshError naming the file when it cannot
    be read.

    8-bit PNGs are decoded by the core (``_core.read_png``, the GIL released, a third of
    Pillow's time); other files, and PNGs it leaves alone (16-bit, animated, malformed), by
    Pillow, so that those keep Pillow's result and its error message."""
    path = Path(path)
    try:
        with open(os.fspath(path), "rb") as f:
            data = f.read()
    except (OSError, ValueError) as e:
        raise MeshError(path, f"cannot read texture image: {e}") from None
    if data.startswith(_PNG_SIGNATURE):
        pixels = _core.read_png(data)
        if pixels is not None:
            return pixels
    return _pillow_image(path, path)


def decode_image(data: bytes, path: str | os.PathLike) -> np.ndarray:
    """As ``read_image``, for the bytes of an image held in another file (a glTF's texture):
    MeshError names ``path``."""
    if data.startswith(_PNG_SIGNATURE):
        pixels = _core.read_png(data)
        if pixels is not None:
            return pixels
    import io

    return _pillow_image(io.BytesIO(data), Path(path))


def _pillow_image(source, path: Path) -> np.ndarray:
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(source) as im:
            return _rgb8(im)
    except (OSError, UnidentifiedImageError, ValueError, Image.DecompressionBombError) as e:
        raise MeshError(path, f"cannot read texture image: {e}") from None


#: Pillow's modes of one integer channel wider than 8 bits: a 16-bit grey PNG opens as one of
#: them, and ``convert("RGB")`` would clip its values to 255 (a white texture).
_WIDE_GREY = ("I;16", "I;16B", "I;16L", "I;16N", "I")


def _rgb8(im) -> np.ndarray:
    """The pixels of a Pillow image as (H, W, 3) uint8 RGB: wide grey scaled from 16 bits
    (values beyond 0-65535 clipped), floating-point pixels refused (no range to scale from)."""
    if im.mode in _WIDE_GREY:
        grey = np.clip(np.asarray(im, dtype=np.float64), 0, 65535) / 257.0
        return np.repeat(np.rint(grey).astype(np.uint8)[..., None], 3, axis=2)
    if im.mode == "F":
        raise ValueError("its pixels are floating-point numbers, which have no range to scale to 8 bits; "
                         "save it with 8 or 16 bits per channel")
    return np.asarray(im.convert("RGB"), dtype=np.uint8).copy()
