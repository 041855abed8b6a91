"""Video coding of the texture sequence with PyAV's bundled FFmpeg.

A group of frames' atlas images becomes one video: 10-bit YUV 4:2:0, HEVC (libx265) by
default or AV1 (libsvtav1, decoded with libdav1d), at a fixed QP, low delay (no B-frames,
so that frame k of the stream is frame k of the group). The colour conversion is done here,
not by FFmpeg, so that it is exactly BT.709 full range on both sides, the colour space of
the texture PSNR.
"""

from __future__ import annotations

import io
import os

import av
import numpy as np

#: Codec names as the stream signals them (the index is the code).
CODECS = ("hevc", "av1")

#: libx265 preset: "ultrafast" keeps a 2048 x 2048 frame near half a second on two cores
#: (``bench/bench_texture.py`` measures the presets).
HEVC_PRESET = "ultrafast"

_PEAK = 1023.0
# BT.709: Y = KR R + KG G + KB B; Cb = (B - Y) / CB_SCALE, Cr = (R - Y) / CR_SCALE.
_KR, _KB = 0.2126, 0.0722
_KG = 1.0 - _KR - _KB
_CB_SCALE, _CR_SCALE = 2.0 * (1.0 - _KB), 2.0 * (1.0 - _KR)


def rgb_to_yuv420(rgb: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8 RGB -> the (3H/2, W) uint16 layout of FFmpeg's yuv420p10le:
    full-range 10-bit BT.709 Y, then Cb and Cr averaged over 2x2 texels. H and W even."""
    c = np.asarray(rgb, np.float32) / 255.0
    r, g, b = c[..., 0], c[..., 1], c[..., 2]
    y = _KR * r + _KG * g + _KB * b
    cb = (b - y) / _CB_SCALE + 0.5
    cr = (r - y) / _CR_SCALE + 0.5
    h, w = y.shape

    def half(p: np.ndarray) -> np.ndarray:
        return p.reshape(h // 2, 2, w // 2, 2).mean(axis=(1, 3)).reshape(h // 4, w)

    planes = [y, half(cb), half(cr)]
    return np.concatenate([np.clip(np.rint(p * _PEAK), 0, _PEAK).astype(np.uint16) for p in planes])


def yuv420_to_rgb(yuv: np.ndarray) -> np.ndarray:
    """The inverse of ``rgb_to_yuv420`` (chroma repeated over each 2x2 block), uint8 RGB."""
    h = yuv.shape[0] * 2 // 3
    w = yuv.shape[1]
    planes = np.asarray(yuv, np.float32) / _PEAK
    y = planes[:h]

    def full(p: np.ndarray) -> np.ndarray:
        return np.repeat(np.repeat(p.reshape(h // 2, w // 2), 2, axis=0), 2, axis=1) - 0.5

    cb, cr = full(planes[h : h + h // 4]), full(planes[h + h // 4 :])
    r = y + _CR_SCALE * cr
    b = y + _CB_SCALE * cb
    g = (y - _KR * r - _KB * b) / _KG
    return np.clip(np.rint(np.stack([r, g, b], axis=-1) * 255.0), 0, 255).astype(np.uint8)


def _container(codec: str) -> str:
    return {"hevc": "hevc", "av1": "ivf"}[codec]


def encode_video(images: list[np.ndarray], codec: str = "hevc", qp: int = 32) -> bytes:
    """Codes equally sized (H, W, 3) uint8 images (H, W even) as one video; returns its bytes
    (an HEVC Annex B elementary stream, or AV1 in IVF)."""
    if codec not in CODECS:
        raise ValueError(f"unknown texture codec {codec!r} (expected {' or '.join(CODECS)})")
    h, w = images[0].shape[:2]
    buf = io.BytesIO()
    with av.open(buf, "w", format=_container(codec)) as out:
        stream = out.add_stream({"hevc": "libx265", "av1": "libsvtav1"}[codec], rate=30)
        stream.width, stream.height, stream.pix_fmt = w, h, "yuv420p10le"
        if codec == "hevc":
            stream.options = {"preset": HEVC_PRESET, "x265-params": f"qp={qp}:bframes=0:log-level=error"}
        else:
            os.environ.setdefault("SVT_LOG", "1")  # errors only; its banner goes to stderr otherwise
            stream.options = {"crf": str(qp), "svtav1-params": "pred-struct=1"}
        for k, image in enumerate(images):
            frame = av.VideoFrame.from_ndarray(rgb_to_yuv420(image), format="yuv420p10le")
            frame.pts = k
            for packet in stream.encode(frame):
                out.mux(packet)
        for packet in stream.encode():
            out.mux(packet)
    return buf.getvalue()


def decode_video(data: bytes, codec: str = "hevc"):
    """Yields the decoded images of a video from ``encode_video``, in order.

    Raises ValueError when FFmpeg cannot decode the data."""
    try:
        with av.open(io.BytesIO(data), "r", format=_container(codec)) as inp:
            for frame in inp.decode(video=0):
                yield yuv420_to_rgb(frame.to_ndarray(format="yuv420p10le"))
    except (av.error.FFmpegError, IndexError) as e:
        raise ValueError(f"texture video does not decode: {e}") from None
