"""Video coding of the texture sequence with PyAV's bundled FFmpeg.

A group of frames' atlas images becomes one video: 10-bit YUV 4:2:0, HEVC (libx265) or AV1
(libsvtav1, decoded with libdav1d, carried in IVF), at a fixed quantizer, low delay (no
B-frames, no reordering, one key frame: frame k of the stream is frame k of the group). The
colour conversion is done by the core (``_core.rgb_to_yuv420`` / ``_core.yuv420_to_rgb``), not
by FFmpeg, so that it is exactly BT.709 full range on both sides, the colour space of the
texture PSNR.

``qp`` (the ``texture_qp`` option, 0-51) is in HEVC's QP scale for both codecs: libx265 takes
it as its constant QP; for AV1, ``av1_crf`` maps it to the SVT-AV1 quantizer that gives about
the same luma PSNR (``AV1_QP_KNOTS``), so that switching the codec keeps the quality and
changes the size.

Measured on real atlases, the encoder's own (``encode_frames(..., texture_qp=10,
keep_reconstructions=True)``: one intra frame, then predicted frames on its atlas): liam_textured
6 frames at 1024 x 1024 and basketball_textured 3 frames at 2048 x 2048 (the fit), liam_textured
12 frames at 2048 x 2048 and 15 frames at 1024 x 1024 (held out). Luma BD-rate against libx265
ultrafast over texture_qp 22-42 (PCHIP), seconds per frame on a shared 2-core machine (SVT-AV1
4.1.0, libx265 and libdav1d of PyAV 18.1, 2026-12; times +-20 %):

===============================  =========  ==========  ==========  =============================
setting                          liam       basketball  liam        encode / decode s per frame:
                                 6 frames   3 frames    12 frames   liam 12 frames at 2048
                                 at 1024    at 2048     at 2048     (basketball 3 frames at 2048)
===============================  =========  ==========  ==========  =============================
libx265 ultrafast (the anchor)   0          0           0           0.29-0.36 / 0.09 (0.33 / 0.10)
libsvtav1 preset 8, low delay    -1.3 %     +3.6 %      -4.3 %      0.14 / 0.06 (0.21 / 0.08)
  + hierarchical-levels=2        -6.8 %     +1.1 %      -9.4 %      0.15 / 0.06 (0.19 / 0.08)
libsvtav1 preset 7, h.-levels=2  -10.6 %    -3.8 %      -14.6 %     0.20 / 0.07 (0.26 / 0.07)
libsvtav1 preset 6, h.-levels=2  -16.5 %    -10.3 %     -21.5 %     0.25 / 0.06 (0.34 / 0.08)
libsvtav1 preset 5, h.-levels=2                         -22.4 %     0.36 / 0.07
===============================  =========  ==========  ==========  =============================

(AV1 rows: crf 16-60 in steps of 4.) Preset 6 with two hierarchical levels was the first
choice; preset 4 (``AV1_PRESET``) replaced it: on the encoder's own atlases at geometry QP 28,
texture_qp 26-42, it takes 6.5 % (basketball) and 7.3 % (liam) fewer texture bytes at the same
luma PSNR (Y BD-rate at total rate -5.4 % and -4.5 %, Cb and Cr -3 to -8 %), for 1.9x the
video's encode time (liam 6 frames: 0.52 -> 1.0 s, basketball 3 frames: 1.0 -> 2.0 s, one run
on the shared machine); preset 5 gave -0.6 % for 1.3x. With the QP mapping (fitted at preset
6), through this module at the same
texture_qp 22-42, it takes -18.0 % (liam 6 frames), -11.7 % (basketball), -22.2 % (liam 12
frames at 2048) and -25.0 % (liam 15 frames at 1024) Y BD-rate against libx265 ultrafast, and
-26 % to -37 % in Cb and Cr. Presets 10 to 13 cost +17 % to +74 % (12 and 13 are mapped to 11
outside SVT-AV1's real-time mode); real-time mode (``rtc=1``) costs 3-9 % more than the same
preset without it; ``crf`` (adaptive quantization on) and fixed QP (``aq-mode=0``) give the
same stream in low delay (no TPL); ``enable-tf``, ``film-grain`` and ``tune`` change nothing
in low delay; ``enable-qm=1`` -1 %; ``fast-decode=1`` +3 %. Atlases that change layout at
every frame of a group (which the encoder does not make: predicted frames keep their intra
frame's atlas) gain less: -6.5 %, and AV1 is then 0.1-1.9 dB below HEVC at the same
texture_qp. ``bench/bench_texture.py`` measures the chosen settings on basketball_textured.
"""

from __future__ import annotations

import io
import os

import numpy as np

from .. import _core
from ..defaults import TEXTURE_CODECS

#: Codec names as the stream signals them (the index is the code).
CODECS = TEXTURE_CODECS

#: libx265 preset: "ultrafast" keeps a 2048 x 2048 frame near a third of a second on two
#: cores (``bench/bench_texture.py`` measures the presets).
HEVC_PRESET = "ultrafast"

#: libx265 parameters besides the preset and the QP: no B-frames (low delay), neither lookahead
#: nor frame threads, so that each picture's packet comes out of the ``add`` that gives it, as
#: SVT-AV1's do in low delay (at a constant QP the lookahead decides nothing: the same bytes
#: on liam_textured's atlases), and no settings SEI.
HEVC_PARAMS = "bframes=0:rc-lookahead=0:frame-threads=1:info=0:log-level=error"

#: libsvtav1 preset (0 slowest to 13): 4, about 7 % fewer texture bytes than 6 at the same
#: luma PSNR for twice the video's encode time (the module's docstring); the texture is most
#: of a textured stream's bytes, its video a small part of the encode time.
AV1_PRESET = 4

#: SVT-AV1 parameters besides the preset, the quantizer and ``keyint`` (``AV1_ONE_KEY_FRAME``:
#: the first picture is the only key frame): low delay
#: (``pred-struct=1``: no reordering, so the player's WebCodecs decoder gives picture k for IVF
#: frame k), two hierarchical levels (4-picture mini-GOPs with the upper layers' QP offsets:
#: 2.5-5.5 % fewer bytes than the three of preset 8), no scene-change detection, constant QP
#: (``rc=0`` with ``aq-mode=0``: the same stream as the default adaptive quantization in low
#: delay, which disables TPL, but written out so that a later SVT-AV1 does not drift), no
#: temporal filtering and no film grain synthesis (the decoded image is the texture).
AV1_PARAMS = {"pred-struct": 1, "hierarchical-levels": 2, "scd": 0, "rc": 0, "aq-mode": 0, "enable-tf": 0,
              "film-grain": 0}

#: ``texture_qp`` (HEVC scale) -> SVT-AV1 ``crf`` (0-70 in quarter steps; 0 the finest, above
#: 63 SVT-AV1's extended range): linear between these (qp, crf) knots, rounded to a quarter.
#: Fitted so that libsvtav1 at preset 6 with ``AV1_PARAMS`` gives the luma PSNR of
#: libx265 ultrafast at the same QP on liam_textured and basketball_textured atlases (1.8 crf
#: steps per QP from 20 to 41; above crf 61, into SVT-AV1's extended range, each crf step
#: costs more PSNR, so the last segment is flatter). Residual luma PSNR of AV1 minus HEVC at
#: the same texture_qp, over 22-42: see ``AV1_QP_MISMATCH``. Below QP 20 the knots are
#: rougher: the fitted atlases had been coded by libx265 at QP 10, which flatters libx265 near
#: QP 10 (checked against atlases from the texture transfer, not coded before).
AV1_QP_KNOTS = ((0, 2.5), (12, 8.5), (20, 23.5), (41, 61.5), (51, 67.75))

#: Measured luma PSNR of AV1 minus HEVC at the same texture_qp (dB), every QP of 22-42 through
#: ``encode_video``, over the four sets of atlases of the module's docstring (fit and held out):
#: mean, extremes, and each set's range (liam 6 frames at 1024, basketball 3 frames at 2048,
#: liam 12 frames at 2048, liam 15 frames at 1024). A group of one frame (``intra_period`` 1)
#: is the exception: AV1 is then 0.7-2.8 dB above HEVC (more at low QPs; Y BD-rate -25 %).
AV1_QP_MISMATCH = {"mean": +0.08, "min": -0.40, "max": +0.38,
                   "per set": {"liam": (-0.22, +0.18), "basketball": (+0.04, +0.38),
                               "liam 2048": (-0.40, +0.06), "liam 15 frames": (+0.06, +0.27)}}


def av1_crf(qp: float) -> float:
    """The SVT-AV1 ``crf`` for a ``texture_qp`` in HEVC's scale (``AV1_QP_KNOTS``)."""
    qs, crfs = zip(*AV1_QP_KNOTS)
    crf = float(np.interp(qp, qs, crfs))
    return min(max(round(crf * 4) / 4, 0.0), 70.0)


def _container(codec: str) -> str:
    return {"hevc": "hevc", "av1": "ivf"}[codec]


def _options(codec: str, qp: float, preset) -> dict:
    """The FFmpeg encoder options for one group's video."""
    if codec == "hevc":
        return {"preset": str(preset or HEVC_PRESET), "x265-params": f"qp={qp}:{HEVC_PARAMS}"}
    params = {**AV1_PARAMS, "keyint": AV1_ONE_KEY_FRAME, "crf": f"{av1_crf(qp):g}"}
    return {"preset": str(AV1_PRESET if preset is None else preset),
            "svtav1-params": ":".join(f"{k}={v}" for k, v in params.items())}


#: SVT-AV1's ``keyint`` for "no key frame after the first": the encoder codes a group's
#: pictures as they come, before it knows how many there will be. (Checked against
#: ``keyint`` = the group's length + 1, what it knew before: the same bytes.)
AV1_ONE_KEY_FRAME = -1


class VideoEncoder:
    """Codes equally sized (H, W, 3) uint8 images (H, W even), given one at a time, as one
    video; ``finish`` returns its bytes (an HEVC Annex B elementary stream, or AV1 in IVF).

    Each ``add`` codes its picture (low delay, no lookahead: ``AV1_PARAMS``, ``HEVC_PARAMS``),
    and ``sizes`` then holds the bytes of every picture coded so far, in order. ``qp`` is in
    HEVC's QP scale for both codecs (``av1_crf``); ``preset`` overrides ``HEVC_PRESET`` or
    ``AV1_PRESET``."""

    def __init__(self, codec: str = "hevc", qp: int = 32, *, preset=None):
        if codec not in CODECS:
            raise ValueError(f"unknown texture codec {codec!r} (expected {' or '.join(CODECS)})")
        self.codec, self.qp, self.preset = codec, qp, preset
        self.frames = 0
        #: Bytes of each picture's packet, in order, as they come out of the codec.
        self.sizes: list[int] = []
        self._buf = io.BytesIO()
        self._out = self._stream = None

    def add(self, image: np.ndarray) -> None:
        if self._stream is None:
            self._open(*image.shape[:2])
        import av

        frame = av.VideoFrame.from_ndarray(_core.rgb_to_yuv420(image), format="yuv420p10le")
        frame.pts = self.frames
        self.frames += 1
        self._mux(self._stream.encode(frame))

    def finish(self) -> bytes:
        """The video's bytes; the encoder takes no more images."""
        if self._stream is None:
            raise ValueError("a video needs at least one image")
        self._mux(self._stream.encode())
        self._out.close()
        self._stream = None
        return self._buf.getvalue()

    def _mux(self, packets) -> None:
        for packet in packets:
            self.sizes.append(packet.size)
            self._out.mux(packet)

    def _open(self, h: int, w: int) -> None:
        import av  # here, not at module level: PyAV takes a third of a second to import

        self._out = av.open(self._buf, "w", format=_container(self.codec))
        stream = self._out.add_stream({"hevc": "libx265", "av1": "libsvtav1"}[self.codec], rate=30)
        stream.width, stream.height, stream.pix_fmt = w, h, "yuv420p10le"
        if self.codec == "av1":
            os.environ.setdefault("SVT_LOG", "1")  # errors only; its banner goes to stderr otherwise
        stream.options = _options(self.codec, self.qp, self.preset)
        self._stream = stream


def encode_video(images: list[np.ndarray], codec: str = "hevc", qp: int = 32, *, preset=None) -> bytes:
    """``images`` coded as one video by a ``VideoEncoder``: its bytes."""
    enc = VideoEncoder(codec, qp, preset=preset)
    for image in images:
        enc.add(image)
    return enc.finish()


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
