"""Encoding one stream's groups of frames in parallel: in local processes or as Ray tasks.

A *group* is the ``intra_period`` frames from a multiple of the period on. Its first frame
is intra, and nothing the encoder keeps (the reference, the intra/inter decision's last
intra frame) reaches over an intra frame, so an encoder started there
(``_core.Encoder.start_group``) codes the group's frames into the units the sequential
encoder gives them. A texture group (``dynmesh.texture``) runs from an intra frame to the
next one and so never straddles two groups: each group's units, texture units in place,
are a piece of the sequential stream, and the header followed by the pieces in order is
that stream byte for byte. Only the ``same_topology`` statistic of a group's first frame
differs: its encoder has not seen the frame before it.

The driver hands groups (``encode_group``) to a *pool*, a ``ProcessPoolExecutor`` started
with spawn or a ``RayPool``, and takes the pieces back in stream order, with at most two
groups per worker submitted and not yet written: its memory depends on the group size and
the number of workers, not on the length of the sequence. Frames travel as file paths,
which the workers read themselves (a path is a few bytes, a frame megabytes), or as the
Mesh objects an API caller gave. A worker that cannot find a path returns None; the
driver then reads the group's frames (and texture images) itself and sends them, and does
so for every later group too.

Failures: an error in a group (an invalid mesh) is raised as it is, naming the frame; a
local worker process that dies breaks the pool, a WorkerError. A Ray worker that dies has
its task run again (``RAY_RETRIES``), and a task that keeps dying is a WorkerError.
``encode_to_file`` writes to a temporary file renamed at the end and removed on any
failure, so the output name never holds a partial stream.
"""

from __future__ import annotations

import collections
import dataclasses
import itertools
import multiprocessing
import os
import warnings
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

from . import encoding, texture
from .io import read_image, read_mesh
from .io.meshio import _atomic_write
from .mesh import Mesh

__all__ = ["WorkerError", "RayPool", "encode_to_file", "encode_group", "pool", "result_of"]

#: How many times Ray runs a group again whose worker died.
RAY_RETRIES = 3


class WorkerError(RuntimeError):
    """A worker that died, or a Ray task that failed for good, while encoding a group."""


@dataclasses.dataclass(frozen=True)
class GroupJob:
    """One group to encode: what a worker needs, and nothing of the other groups."""

    first: int
    frames: tuple  # paths (str or os.PathLike) or Mesh objects
    sequence: tuple  # (frame count, box min, box max) of the whole stream
    options: dict  # geometry options, defaults filled in
    texture: dict | None  # texture options, or None for an untextured stream
    keep: bool  # keep the reconstructions

    def span(self) -> str:
        return f"{self.first}-{self.first + len(self.frames) - 1}"


class _Unreachable(Exception):
    """A frame or texture file that this worker does not have."""


def encode_group(job: GroupJob) -> encoding.EncodeResult | None:
    """The group's piece of the stream (see the module documentation), or None when a frame
    or texture file it names is not there for this worker."""
    count, lo, hi = job.sequence
    enc = encoding._encoder(count, lo, hi, job.options)
    enc.start_group(job.first)
    tex = None if job.texture is None else encoding.texture_encoder(job.options, job.texture, job.keep, job.first)
    try:
        return encoding.encode_units(enc, tex, _frames_here(job), job.first, count, job.keep, None)
    except _Unreachable:
        return None


def _frames_here(job: GroupJob) -> Iterator[Mesh]:
    """The group's frames, read here if they are paths; raises _Unreachable for a file
    this worker does not have."""
    for f in job.frames:
        if not isinstance(f, Mesh) and not os.path.isfile(f):
            raise _Unreachable
        m = f if isinstance(f, Mesh) else read_again(f)
        if job.texture is not None and m.image is None and m.texture is not None and not os.path.isfile(m.texture):
            raise _Unreachable
        yield m


def read_again(path: str | os.PathLike) -> Mesh:
    """A frame read a second time, its MeshWarnings silenced: the first pass showed them."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return read_mesh(path)


def _with_meshes(job: GroupJob) -> GroupJob:
    """``job`` with its frames read here, texture pixels included, for a worker without the files."""
    meshes = (f if isinstance(f, Mesh) else read_again(f) for f in job.frames)
    loaded = (m if m.texture is None or m.image is not None else dataclasses.replace(m, image=read_image(m.texture))
              for m in meshes)
    return dataclasses.replace(job, frames=tuple(loaded))


class RayPool:
    """Ray tasks behind what the drivers use of ``concurrent.futures.Executor``: ``submit``
    (a Future) and the context manager. Connects to the cluster at ``address`` ("auto":
    the one this machine belongs to), unless this process is connected already, and then
    disconnects again on exit. ``workers`` is the cluster's CPU count, one task each."""

    def __init__(self, address: str):
        try:
            import ray
        except ImportError:
            raise WorkerError('a Ray cluster needs Ray: pip install "dynmesh[ray]"') from None
        self._ray, self._owned = ray, not ray.is_initialized()
        if self._owned:
            try:
                ray.init(address=address, logging_level="WARNING")
            except (ConnectionError, RuntimeError, ValueError) as e:
                raise WorkerError(f"cannot connect to the Ray cluster at {address}: {e}") from None
        self.workers = max(1, int(ray.cluster_resources().get("CPU", 1)))
        self._tasks: dict[Callable, object] = {}

    def submit(self, fn: Callable, *args) -> Future:
        task = self._tasks.get(fn)
        if task is None:
            # One core per task, so one thread per core's pool; a task whose worker dies is
            # run again, one that raises is not (its error is the input's).
            env = {"env_vars": {"RAYON_NUM_THREADS": "1"}}
            task = self._tasks[fn] = self._ray.remote(num_cpus=1, max_retries=RAY_RETRIES, runtime_env=env)(fn)
        return task.remote(*args).future()

    def __enter__(self) -> RayPool:
        return self

    def __exit__(self, *exc) -> None:
        if self._owned:
            self._ray.shutdown()


def pool(jobs: int, ray: str | None) -> tuple[ProcessPoolExecutor | RayPool, int]:
    """(pool, number of workers): ``jobs`` local processes, or the Ray cluster at ``ray``."""
    if ray is not None:
        if jobs != 1:
            raise ValueError("jobs and a Ray cluster exclude each other: the cluster's CPUs are its workers")
        p = RayPool(ray)
        return p, p.workers
    if not isinstance(jobs, int) or jobs < 1:
        raise ValueError(f"jobs must be a positive integer, not {jobs!r}")
    # spawn, not fork: the parent may already run the core's thread pool (rayon), which a
    # forked child would inherit in a broken state.
    return ProcessPoolExecutor(max_workers=jobs, mp_context=multiprocessing.get_context("spawn"),
                               initializer=_share_cores, initargs=(jobs,)), jobs


def _share_cores(jobs: int) -> None:
    """Gives a local worker's thread pool its share of the cores and one thread more: N pools
    of all cores each would spend the CPU they compete for on waking threads that find no
    work, while an exact share leaves a core idle whenever a worker is in a serial stage or
    alone with the last group (2 cores, 2 workers: 1 thread each took 0.80 of the
    sequential time on horse_gallop's 32 frames in groups of 8, 2 threads each 0.77; on 3
    all-intra frames 1.10 and 0.98). Runs before the worker's first group starts the pool;
    a RAYON_NUM_THREADS the user set stands."""
    if "RAYON_NUM_THREADS" not in os.environ:
        cores = os.cpu_count() or 1
        os.environ["RAYON_NUM_THREADS"] = str(min(cores, cores // jobs + 1))


def encoded_groups(frames: Iterable, sequence: tuple, options: dict, texture_options: dict | None, keep: bool,
                   jobs: int = 1, ray: str | None = None) -> Iterator[encoding.EncodeResult]:
    """The groups' pieces of the stream in order (the header is not among them), encoded
    by ``jobs`` local processes or on the Ray cluster at ``ray``; ``frames`` (paths or
    Mesh objects) are taken from the iterable a group at a time, as the workers need them.
    The pool is made at once, so that a bad ``jobs`` or an unreachable cluster fails
    before anything is written."""
    executor, workers = pool(jobs, ray)
    return _pieces(executor, _group_jobs(frames, sequence, options, texture_options, keep), 2 * workers)


def _pieces(executor, groups: Iterator[GroupJob], window: int) -> Iterator[encoding.EncodeResult]:
    with executor:
        yield from _in_order(executor, groups, window)


def _group_jobs(frames: Iterable, sequence: tuple, options: dict, texture_options: dict | None,
                keep: bool) -> Iterator[GroupJob]:
    count, period = sequence[0], options["intra_period"]
    it = iter(frames)
    for first in range(0, count, period):
        size = min(period, count - first)
        chunk = tuple(itertools.islice(it, size))
        if len(chunk) < size:
            raise ValueError(f"{first + len(chunk)} frames where {count} were announced")
        yield GroupJob(first, chunk, sequence, options, texture_options, keep)
    if next(it, None) is not None:
        raise ValueError(f"more than the {count} frames announced")


def _in_order(executor, groups: Iterator[GroupJob], window: int) -> Iterator[encoding.EncodeResult]:
    """Keeps up to ``window`` groups submitted and yields their pieces in stream order."""
    pending: collections.deque[tuple[GroupJob, Future]] = collections.deque()
    send_meshes = False

    def finished(job: GroupJob, future: Future) -> encoding.EncodeResult:
        nonlocal send_meshes
        # A dead process breaks every future of a local pool: name all the groups in flight.
        in_flight = "frames " + ", ".join(j.span() for j in [job, *(j for j, _ in pending)])
        result = result_of(future, in_flight)
        if result is None:  # the worker has no such files: from now on send the frames
            send_meshes = True
            result = result_of(executor.submit(encode_group, _with_meshes(job)), f"frames {job.span()}")
        return result

    try:
        for job in groups:
            job = _with_meshes(job) if send_meshes else job
            pending.append((job, executor.submit(encode_group, job)))
            if len(pending) >= window:
                yield finished(*pending.popleft())
        while pending:
            yield finished(*pending.popleft())
    finally:
        for _, future in pending:
            future.cancel()


def result_of(future: Future, what: str):
    """The future's result; its task's own error raised as it is (without Ray's wrapping),
    a worker's death as a WorkerError naming ``what``."""
    try:
        return future.result()
    except BrokenProcessPool:
        raise WorkerError(f"a worker process died (killed, or out of memory?) with {what} in flight") from None
    except Exception as e:
        cause = getattr(e, "cause", None)  # a Ray task's own error, without Ray's traceback text
        if isinstance(cause, Exception):
            raise cause from None
        if type(e).__module__ == "ray.exceptions":  # the worker died, and died again on every retry
            raise WorkerError(f"{type(e).__name__} with {what} in flight: {e}") from None
        raise


def stream_chunks(header: bytes, groups: Iterable[encoding.EncodeResult], result: encoding.EncodeResult,
                  on_frame: Callable[[int, dict], None] | None = None) -> Iterator[bytes]:
    """The stream: ``header``, then each group's piece as it comes. Each group's frame
    statistics, reconstructions and texture bytes are added to ``result`` on the way (not
    its data), and ``on_frame(index, stats)`` is called for its frames."""
    yield header
    for g in groups:
        for i, stats in enumerate(g.frames, len(result.frames)):
            if on_frame is not None:
                on_frame(i, stats)
        result.frames += g.frames
        result.reconstructions += g.reconstructions
        result.texture_bytes += g.texture_bytes
        yield g.data


def encode_to_file(path: str | os.PathLike, frames: Iterable, *, sequence: tuple, texture: bool, jobs: int = 1,
                   ray: str | None = None, on_frame: Callable[[int, dict], None] | None = None,
                   **options) -> encoding.EncodeResult:
    """Encodes ``frames`` (mesh file paths, which the workers read, or Mesh objects) into
    the stream file ``path``, written as the groups come in order, under a temporary name
    renamed when the stream is complete. ``sequence`` is (frame count, box min, box max),
    ``texture`` True or False; the rest as ``api.encode_frames`` with ``jobs`` or ``ray``.
    Returns the frames' statistics (``data`` stays empty: the stream is in the file)."""
    opts, texture_options = encoding._split_options(options)
    textured = encoding._given_texture(texture)
    header = encoding._encoder(*sequence, opts).header_bytes()
    if textured:
        first, frames = encoding._peek(frames)
        texture_options = texture.resolve_options(texture_options, opts["qp"], first if isinstance(first, Mesh) else read_again(first))
    groups = encoded_groups(frames, sequence, opts, texture_options if textured else None, False, jobs, ray)
    result = encoding.EncodeResult(b"", texture_options=texture_options if textured else None)
    _atomic_write(Path(path), stream_chunks(header, groups, result, on_frame))
    return result
