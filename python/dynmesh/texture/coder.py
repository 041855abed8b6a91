"""The texture stage: atlas, texture transfer and video per group of frames, and back.

A *texture group* starts where the geometry encoder says (the frame statistic
``starts_texture_group``: an intra frame, or a predicted frame whose base faces are not the
previous frame's) and runs to the frame before the next start. Its first frame gets an atlas
made on its decoded base mesh (``atlas``); every frame of the group has that base mesh's
connectivity (predicted frames move it), so all of them share the atlas, subdivided with the
mesh (``_core.subdivide_uv``). Each frame's input texture is transferred onto the
reconstructed mesh in that atlas (``_core.transfer_texture``, padded), and the group's images
become one video (``video.VideoEncoder``, picture by picture). All of it runs on a thread
beside the geometry encoder, one frame behind it. The stream carries it in one texture unit
after the group's first frame, whose fields the core writes and reads
(``_core.pack_texture_payload``, ``_core.read_texture_payload``; ``docs/bitstream.md``,
texture unit payload).
"""

from __future__ import annotations

import bisect
import contextlib
import threading
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from .. import _core
from ..defaults import TEXTURE, texture_qp_for
from ..errors import with_frame
from ..io import image_of
from ..mesh import Mesh
from . import atlas, video

#: Defaults of the texture options (``encode_frames`` takes them beside the geometry ones).
TEXTURE_DEFAULTS: dict = TEXTURE

@dataclass
class GroupHeader:
    codec: str
    width: int
    height: int
    uv_bits: int
    frames: int
    atlas: bytes
    video: bytes


def pack_group(g: GroupHeader) -> bytes:
    """The texture unit payload of a group."""
    return _core.pack_texture_payload(video.CODECS.index(g.codec), g.width, g.height, g.uv_bits, g.frames,
                                      g.atlas, g.video)


def unpack_group(data: bytes) -> GroupHeader:
    """Parses a texture unit payload; raises ValueError naming what is wrong."""
    codec, width, height, uv_bits, frames, atlas_block, video_block = _core.read_texture_payload(data)
    return GroupHeader(video.CODECS[codec], width, height, uv_bits, frames, atlas_block, video_block)


def check_options(options: dict) -> dict:
    """The texture options with defaults filled in; raises ValueError for a bad one.
    ``texture_size`` and ``texture_qp`` may be None: chosen by ``resolve_options``."""
    opts = {**TEXTURE_DEFAULTS, **options}
    size, (low, high) = opts["texture_size"], _core.TEXTURE_SIDES
    if size is not None and (not isinstance(size, int) or not (low <= size <= high) or size % 2):
        raise ValueError(f"texture_size must be an even integer from {low} to {high}, not {size!r}")
    if opts["texture_codec"] not in video.CODECS:
        raise ValueError(f"texture_codec must be one of {', '.join(video.CODECS)}, not {opts['texture_codec']!r}")
    qp = opts["texture_qp"]
    if qp is not None and (not isinstance(qp, int) or not 0 <= qp <= 51):
        raise ValueError(f"texture_qp must be an integer from 0 to 51, not {qp!r}")
    return opts


def atlas_size_for(width: int, height: int) -> int:
    """The atlas side that holds about the texels of a ``width`` x ``height`` source texture:
    the square root of its texel count, to a multiple of 16 (the video's block size), within
    the sides the stream allows (16-16384). A 1024 x 1024 source gives 1024: an atlas of more texels
    than the source has only spends bits on upsampled texture."""
    side = 16 * round((width * height) ** 0.5 / 16)
    low, high = _core.TEXTURE_SIDES
    return int(min(high, max(low, side)))


def resolve_options(options: dict, qp: int, first: Mesh) -> dict:
    """Checked texture options with the ones left to the encoder chosen: ``texture_size``
    from the texel count of the first frame's texture (``atlas_size_for``), ``texture_qp``
    from the geometry QP (``texture_qp_for``). Every group of a stream uses them, so that
    a parallel encode agrees with a sequential one."""
    opts = check_options(options)
    if opts["texture_size"] is None:
        opts["texture_size"] = atlas_size_for(*_texture_shape(first))
    if opts["texture_qp"] is None:
        opts["texture_qp"] = texture_qp_for(qp)
    return opts


def _texture_shape(m: Mesh) -> tuple[int, int]:
    """(width, height) of a frame's texture, from its pixels or its file's header."""
    if m.image is not None:
        return m.image.shape[1], m.image.shape[0]
    from PIL import Image

    try:
        with Image.open(m.texture) as im:
            return im.size
    except OSError as e:
        raise ValueError(f"cannot read texture image {m.texture}: {e}") from None


@dataclass
class _Group:
    first: int
    atlas: bytes
    uv: np.ndarray
    uv_faces: np.ndarray
    video: video.VideoEncoder

#: A predicted video frame's bytes as a share of its group's intra frame, per codec, until
#: the group's second frame measures it (liam_textured at texture QP 32: AV1 0.03, HEVC 0.14;
#: the synthetic blobs' smooth texture, HEVC: 0.25).
PREDICTED_SHARE = {"av1": 0.05, "hevc": 0.2}


#: Seconds the texture thread waits for the caller to enter the geometry core before it runs
#: a step that holds the GIL anyway (between two frames the caller needs a few hundredths).
GIL_PATIENCE = 1.0


class TextureEncoder:
    """Builds the texture units of a stream frame by frame (see the module documentation).

    Call ``add`` after each geometry frame and ``finish`` after the last: it gives every
    group's ``(first frame, texture unit)``. ``add`` only queues the frame: its texture is
    transferred and coded on a thread of its own while the caller codes the next frame's
    geometry, and ``cost`` waits for it when the next decision needs what it measures. The
    core works without the GIL, but xatlas and PyAV hold it (xatlas for all of an atlas,
    a third of a second; PyAV while it opens and feeds the video encoder): the thread runs
    those steps only while the caller is in the geometry core (``geometry``) or waits for the
    thread, so that they do not stall the caller's own Python between frames.
    ``keep_images`` keeps the decoded texture of every frame (``images``), which costs
    decoding each video once. ``first_frame``, the stream index of the first frame added,
    names frames in error messages."""

    def __init__(self, subdiv: int, options: dict, keep_images: bool = False, estimate_costs: bool = False,
                 first_frame: int = 0):
        opts = check_options(options)
        if opts["texture_size"] is None or opts["texture_qp"] is None:
            raise ValueError("TextureEncoder needs a texture_size and texture_qp (resolve_options chooses them)")
        self.size, self.qp, self.codec = opts["texture_size"], opts["texture_qp"], opts["texture_codec"]
        self.subdiv = subdiv
        self.keep_images = keep_images
        self.images: list[np.ndarray] = []
        self.uvs: list[tuple[np.ndarray, np.ndarray]] = []
        #: Per frame, the share of the atlas's texels that the frame's surface covers (the
        #: rest is padding, which the video codes at little cost).
        self.coverage: list[float] = []
        self._estimate = estimate_costs
        self._first_frame = first_frame
        self._units: list[tuple[int, bytes]] = []
        # What the caller's thread knows of the current group: how many frames it has.
        self._length = 0
        self._frames = 0
        self._settled_cost: tuple[float, float] | None = None
        # Only the worker thread touches these.
        self._group: _Group | None = None
        self._worker = ThreadPoolExecutor(1, thread_name_prefix="dynmesh-texture")
        self._queued: list[Future] = []
        self._coded: Future | None = None  # the last frame's picture into its group's video
        self._closed = False
        # Set while the caller needs no GIL: it is in the geometry core or waits for us.
        self._caller_away = threading.Event()
        # PyAV takes a tenth of a second to import, holding the GIL: done at the first chance.
        self._queued.append(self._worker.submit(self._holding_gil, lambda: __import__("av")))

    @contextlib.contextmanager
    def geometry(self):
        """Wraps the caller's call into the geometry core (which releases the GIL): the
        texture thread's steps that hold the GIL run meanwhile."""
        self._caller_away.set()
        try:
            yield
        finally:
            self._caller_away.clear()

    def _holding_gil(self, step, *args, **kwargs):
        """``step(*args, **kwargs)``, a step that holds the GIL throughout, once the caller
        does not need it (or after ``GIL_PATIENCE`` seconds: a caller that never enters
        ``geometry`` only loses the overlap)."""
        self._caller_away.wait(GIL_PATIENCE)
        return step(*args, **kwargs)

    def cost(self) -> tuple[float, float] | None:
        """(bytes, bytes): what the texture of the next frame adds when the frame continues
        the current group, and when it starts a new one (an atlas and an intra video
        frame), for the geometry encoder's decisions (``Encoder.encode_frame``); None
        before a group has begun or without ``estimate_costs``. Read off the group's own
        video: the bytes of its first two pictures (``VideoEncoder.sizes``), each group
        apart, so a parallel encode decides as a sequential one does. Waits for the queued
        frames until both are coded."""
        if not self._estimate or self._length == 0:
            return None
        if self._settled_cost is not None:
            return self._settled_cost
        self._wait(until=self._coded)
        g = self._group
        intra, *predicted = g.video.sizes[:2]
        continued = predicted[0] if predicted else PREDICTED_SHARE[self.codec] * intra
        cost = float(continued), float(intra + len(g.atlas))
        if predicted:
            self._settled_cost = cost
        return cost

    def add(self, starts_group: bool, base: Mesh, reconstruction: Mesh, source: Mesh) -> None:
        """Queues a coded frame's texture: ``starts_group`` whether the frame starts a texture
        group (the geometry encoder decides it: the frame statistic ``starts_texture_group``),
        ``base`` its decoded base mesh, ``reconstruction`` the surface the decoder shows,
        ``source`` the input frame with its texture (``image``, or read from ``texture`` on
        the thread)."""
        self._raise_failure()
        starts = starts_group or self._length == 0
        if starts:
            self._length, self._settled_cost = 0, None
        self._length += 1
        transferred = self._worker.submit(self._add, self._frames, starts, base, reconstruction, source)
        self._coded = self._worker.submit(self._to_video, self._frames, transferred)
        self._queued += [transferred, self._coded]
        self._frames += 1

    def finish(self) -> list[tuple[int, bytes]]:
        """Every group's ``(index of its first frame among those added, texture unit)``, in
        order, once the queued frames are coded; ``uvs``, ``coverage`` and ``images`` then
        hold every frame's."""
        try:
            self._wait()
            self._queued.append(self._worker.submit(self._close))
            self._wait()
            return self._units
        finally:
            self.close()

    def close(self) -> None:
        """Drops the frames still queued and stops the worker thread (``finish`` does it;
        calling it again does nothing)."""
        if self._closed:
            return
        self._closed = True
        for f in self._queued:
            f.cancel()
        self._caller_away.set()  # for good: the caller codes no more geometry
        self._worker.submit(self._abandon)
        self._worker.shutdown(wait=True)

    def _abandon(self) -> None:
        """Ends the video of a group that will not be finished: SVT-AV1 complains on stderr
        when an encoder is dropped without its end of stream."""
        g, self._group = self._group, None
        if g is not None:
            g.video.finish()

    def _wait(self, until: Future | None = None) -> None:
        """Waits for the queued work (up to ``until``, in order) and raises its first error."""
        away = self._caller_away.is_set()
        self._caller_away.set()
        try:
            while self._queued:
                f = self._queued.pop(0)
                f.result()
                if f is until:
                    return
        finally:
            if not away:
                self._caller_away.clear()

    def _raise_failure(self) -> None:
        """Raises a queued frame's error as soon as it is known, rather than at the next wait."""
        if any(f.done() and f.exception() is not None for f in self._queued):
            self._wait()

    def _add(self, index: int, starts: bool, base: Mesh, reconstruction: Mesh, source: Mesh) -> np.ndarray:
        """The frame's texture in its group's atlas (a new group's atlas made first)."""
        try:
            image = image_of(source)
            if starts:
                self._close()
                data, uv_faces, uv = self._holding_gil(atlas.coded_atlas, base.positions, base.faces, self.size)
                uv, uv_faces = _core.subdivide_uv(uv, uv_faces, self.subdiv)
                self._group = _Group(index, data, uv, uv_faces, video.VideoEncoder(self.codec, self.qp))
            g = self._group
            texture, covered = _core.transfer_texture(
                reconstruction.positions, reconstruction.faces, g.uv, g.uv_faces,
                source.positions, source.faces, source.uvs, source.uv_faces, image, self.size, self.size)
            self.coverage.append(float(covered))
            self.uvs.append((g.uv, g.uv_faces))
            return texture
        except ValueError as e:
            raise with_frame(e, self._first_frame + index) from None

    def _to_video(self, index: int, transferred: Future) -> None:
        """The frame's texture (``_add``'s result) into its group's video."""
        texture = transferred.result()  # its error, already naming the frame, is raised first anyway
        try:
            self._holding_gil(self._group.video.add, texture)
        except ValueError as e:
            raise with_frame(e, self._first_frame + index) from None

    def _close(self) -> None:
        g, self._group = self._group, None
        if g is None:
            return
        data = self._holding_gil(g.video.finish)
        if self.keep_images:
            self.images.extend(self._holding_gil(list, video.decode_video(data, self.codec)))
        header = GroupHeader(self.codec, self.size, self.size, atlas.UV_BITS, g.video.frames, g.atlas, data)
        self._units.append((g.first, pack_group(header)))


@dataclass
class _OpenGroup:
    first: int
    frames: int
    uv: np.ndarray
    uv_faces: np.ndarray
    images: object  # iterator over the decoded video
    decoded: int = 0  # images taken from the iterator so far
    image: np.ndarray | None = None  # the last one taken


class TextureDecoder:
    """Gives each decoded frame its UVs and texture image. Decoding in order decodes each
    group's video once; going back inside a group decodes its video again from the start."""

    def __init__(self, decoder, subdiv: int, tolerant: bool = False):
        self._dec = decoder
        self._subdiv = subdiv
        self._open: _OpenGroup | None = None
        # A damaged stream may have lost group starts: then each group's own frame count
        # says how far it reaches, instead of the next start.
        self._tolerant = tolerant
        self._damaged: dict[int, str] = {}
        # First frames of the texture groups, found once: each lookup copies a payload.
        self._starts = [f for f in range(decoder.frame_count) if self._has_payload(f)]

    def _has_payload(self, frame: int) -> bool:
        try:
            return self._dec.texture_payload(frame) is not None
        except ValueError as e:  # a damaged texture unit, in a tolerant decoder
            self._damaged[frame] = str(e)
            return True

    def textured(self) -> bool:
        """Whether the stream carries textures (its first frame has a texture unit)."""
        return bool(self._starts) and self._starts[0] == 0

    def group_of(self, index: int) -> tuple[int, int]:
        """The first frame of the texture group of frame ``index``, and the group's length."""
        k = bisect.bisect_right(self._starts, index) - 1
        if k < 0:
            raise ValueError(f"frame {index}: no texture unit before it in a textured stream")
        end = self._starts[k + 1] if k + 1 < len(self._starts) else self._dec.frame_count
        return self._starts[k], end - self._starts[k]

    def texture_of(self, index: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(uv, uv_faces, image)`` of frame ``index``, whose geometry was decoded last.
        Raises ValueError when the texture data is corrupt."""
        first, length = self.group_of(index)
        g = self._open
        if g is None or g.first != first or g.decoded > index - first + 1:
            g = self._open = self._opened(first, length)
        if index - first >= g.frames:
            raise ValueError(f"frame {index}: beyond the {g.frames} frames of its texture group")
        while g.decoded <= index - first:
            g.image = next(g.images, None)
            if g.image is None:
                raise ValueError(f"frame {index}: the texture video ends early")
            g.decoded += 1
        return g.uv, g.uv_faces, g.image

    def _opened(self, first: int, length: int) -> _OpenGroup:
        if first in self._damaged:
            raise ValueError(f"the texture unit of its group (frame {first}) is damaged: {self._damaged[first]}")
        payload, offset = self._dec.texture_payload(first)
        try:
            header = unpack_group(payload)
        except ValueError as e:
            raise with_frame(e, first, f" (texture unit at byte {offset})") from None
        if header.frames > length or (header.frames != length and not self._tolerant):
            raise ValueError(f"frame {first}: texture unit claims {header.frames} frames, its group has {length}")
        # Every frame of the group has the intra frame's base connectivity, but only the
        # intra frame's own positions are those the atlas was coded on.
        last = self._dec.last_base()
        _, (positions, faces) = last if last is not None and last[0] == first else self._base_of(first)
        uv_faces, uv = atlas.decoded_atlas(header.atlas, positions, faces, header.uv_bits)
        uv, uv_faces = _core.subdivide_uv(uv, uv_faces, self._subdiv)
        return _OpenGroup(first, header.frames, uv, uv_faces, video.decode_video(header.video, header.codec))

    def _base_of(self, index: int):
        """Decodes frame ``index`` for its base mesh (the decoder keeps one frame's state, so
        the caller's frame is decoded again after this)."""
        self._dec.decode_frame(index)
        return self._dec.last_base()
