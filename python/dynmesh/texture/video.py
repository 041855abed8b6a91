"""Video coding of the texture sequence with PyAV's bundled FFmpeg.

A group of frames' atlas images becomes one video: 10-bit YUV 4:2:0, HEVC (libx265) by
default or AV1 (libsvtav1, decoded with libdav1d), at a fixed QP, low delay (no B-frames,
so that frame k of the stream is frame k of the group). The colour conversion is done by
the core (``_core.rgb_to_yuv420`` / ``_core.yuv420_to_rgb``), not by FFmpeg, so that it is
exactly BT.709 full range on both sides, the colour space of the texture PSNR.
"""

from __future__ import annotations

import io
import os

import numpy as np

from .. import _core
from ..defaults import TEXTURE_CODECS

#: Codec names as the stream signals them (the index is the code).
CODECS = TEXTURE_CODECS

#: libx265 preset: "ultrafast" keeps a 2048 x 2048 frame near half a second on two cores
#: (``bench/bench_texture.py`` measures the presets).
HEVC_PRESET = "ultrafast"

def _container(codec: str) -> str:
    return {"hevc": "hevc", "av1": "ivf"}[codec]


def encode_video(images: list[np.ndarray], codec: str = "hevc", qp: int = 32) -> bytes:
    """Codes equally sized (H, W, 3) uint8 images (H, W even) as one video; returns its bytes
    (an HEVC Annex B elementary stream, or AV1 in IVF)."""
    if codec not in CODECS:
        raise ValueError(f"unknown texture codec {codec!r} (expected {' or '.join(CODECS)})")
    import av  # here, not at module level: PyAV takes a third of a second to import

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
            frame = av.VideoFrame.from_ndarray(_core.rgb_to_yuv420(image), format="yuv420p10le")
            frame.pts = k
            for packet in stream.encode(frame):
                out.mux(packet)
        for packet in stream.encode():
            out.mux(packet)
    return buf.getvalue()


def decode_video(data: bytes, codec: str = "hevc"):
    """Yields the decoded images of a video from ``encode_video``, in order.

    Raises ValueError when FFmpeg cannot decode the data."""
    import av

    try:
        with av.open(io.BytesIO(data), "r", format=_container(codec)) as inp:
            for frame in inp.decode(video=0):
                yield _core.yuv420_to_rgb(frame.to_ndarray(format="yuv420p10le"))
    except (av.error.FFmpegError, IndexError) as e:
        raise ValueError(f"texture video does not decode: {e}") from None
