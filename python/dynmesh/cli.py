"""The ``dynmesh`` command line."""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import time
import warnings
from pathlib import Path

# Before numpy is first imported: its OpenBLAS starts a thread per core that spins on start-up
# (a tenth of a CPU second per process), and nothing the commands do calls BLAS. perf: 13 % of
# the CPU of `dynmesh decode` of basketball_textured's 3 frames; decode 7 % faster without.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

# The API, numpy and the file readers are imported by the commands that use them:
# `dynmesh decode` needs none of them, and importing them would cost it more than decoding.
from .cli_args import (EXIT_ERROR, EXIT_INTERRUPTED, EXIT_PIPE_CLOSED, EXIT_STATUS_HELP, MAX_GRID_SIZE, Parser,
                       common_args, grid_size, non_negative, parallel_args, parse, sequence_args)
from .cli_demo import cmd_demo, cmd_synth
from .cli_output import Progress, frame_text, metrics_text, run_text, table
from .cli_paths import check_decode_directory, check_output_directory, check_output_file, remove_stale_frames
from .defaults import ENCODER, INTER_MODES, LIFTINGS, MAX_REFERENCES, TEXTURE, TEXTURE_CODECS, base_ratio_rule, texture_qp_rule
from .io import StagedDirectory, mesh_inputs, refuse_inputs, resolve_sequence


class CliError(Exception):
    """An error to report to the user, without a traceback."""


#: Exit status of an internal error (``dynmesh.InternalError``, a bug in dynmesh): sysexits'
#: EX_SOFTWARE, apart from the user's errors (``EXIT_ERROR``), so that a script can tell them.
EXIT_INTERNAL = 70
#: What every command's --help adds to ``EXIT_STATUS_HELP`` (README.md, "Exit status", says it too).
INTERNAL_STATUS_HELP = ("Exit status 70 for an internal error, a bug in dynmesh: the one-line message says "
                        "\"internal error\" and asks you to report it.")


def _progress(a, total: int, desc: str, quiet: bool | None = None, **kwargs) -> Progress:
    """Progress of command ``a`` on stderr: a bar on a terminal, one line per frame
    otherwise, nothing with -q (``quiet`` overrides)."""
    return Progress(total, desc, command=a.command, quiet=a.quiet if quiet is None else quiet, **kwargs)


def _read_meshes(a, paths: list[Path], desc: str = "reading") -> list:
    from .io import read_mesh

    with _progress(a, len(paths), desc, per_item_lines=False) as bar:
        meshes = []
        for p in paths:
            meshes.append(read_mesh(p))
            bar.step()
    return meshes


def _encoder_options(a) -> dict:
    """The encoder and texture options of a parsed ``encode`` command line: each flag is the
    option's name with dashes (``--base-ratio`` sets ``base_ratio``)."""
    options = {k: getattr(a, k) for k in (*ENCODER, *TEXTURE)}
    return {**options, "texture": "auto" if a.texture is None else a.texture}


def _scan_sequence(a, paths: list[Path]) -> tuple[np.ndarray, np.ndarray, list[Path], list[bool]]:
    """First pass over the frames, one in memory at a time: the sequence box, the texture
    files they use, and which frames are textured."""
    import numpy as np

    from . import api
    from .io import read_mesh

    lo, hi, textures, textured = np.full(3, np.inf), np.full(3, -np.inf), [], []
    with _progress(a, len(paths), "reading", per_item_lines=False) as bar:
        for i, p in enumerate(paths):
            m = read_mesh(p)
            try:
                m_lo, m_hi = api.sequence_bounds([m])
            except ValueError as e:
                raise ValueError(f"frame {i}: {str(e).removeprefix('frame 0: ')}") from None
            lo, hi = np.minimum(lo, m_lo), np.maximum(hi, m_hi)
            textures += mesh_inputs([], [m])
            textured.append(api._has_texture(m))
            bar.step()
    return lo, hi, textures, textured


def cmd_encode(a) -> dict:
    # Two passes over the files: the header needs the sequence box before the first frame,
    # and holding every frame would make memory grow with the sequence.
    from . import api, parallel

    _check_jobs(a)
    paths = resolve_sequence(a.input, a.start, a.count)
    # Before any frame is read: where the stream goes, and the options.
    check_output_file(a.output, paths)
    options = _encoder_options(a)
    texture_option = options.pop("texture")
    _check_encoder_options(options, len(paths))
    lo, hi, textures, textured = _scan_sequence(a, paths)
    refuse_inputs(a.output, textures)
    use_texture = api.texture_choice(textured, texture_option)
    # With a Ray cluster its CPUs are the workers: no local processes.
    jobs = 1 if a.ray is not None else _encode_jobs(a.jobs, len(paths), options["intra_period"])
    with _progress(a, len(paths), "encoding") as bar:
        on_frame = lambda i, stats: bar.step(frame_text(i, stats))  # noqa: E731
        if jobs == 1 and a.ray is None:
            result = api.encode_frames((parallel.read_again(p) for p in paths), on_frame=on_frame,
                                       texture=use_texture, sequence=(len(paths), lo, hi), **options)
            api.write_bytes_atomic(a.output, result.data)
        else:  # the workers read the frames; the stream is written as their groups come
            result = parallel.encode_to_file(a.output, paths, sequence=(len(paths), lo, hi), texture=use_texture,
                                             jobs=jobs, ray=a.ray, on_frame=on_frame, **options)
    size = Path(a.output).stat().st_size
    frames = [{"frame": i, "input": str(p), **s} for i, (p, s) in enumerate(zip(paths, result.frames))]
    summary = {"output": str(a.output), "bytes": size, "texture_bytes": result.texture_bytes,
               "frames": frames, "options": {**_encoder_options(a), **(result.texture_options or {})}}
    if not a.json:
        print(table(frames, [("frame", "frame", "d"), ("type", "type", "s"), ("bytes", "bytes", "d"), ("base_bytes", "base B", "d"),
                              ("displacement_bytes", "disp B", "d"), ("base_faces", "base faces", "d"),
                              ("refreshed_faces", "refreshed", "d"), ("output_faces", "out faces", "d"), ("seconds", "seconds", ".3f")]))
        of_texture = f" ({result.texture_bytes} of them texture)" if result.texture_bytes else ""
        print(f"wrote {a.output}: {size} bytes{of_texture}, {len(frames)} frames, "
              f"{8 * size / len(frames) * 30 / 1e6:.3f} Mbit/s at 30 fps")
        if result.texture_options:
            t = result.texture_options
            used = sum(f["texture_coverage"] for f in frames) / len(frames)
            print(f"texture: {t['texture_size']} x {t['texture_size']} atlas, {t['texture_codec']} at texture QP "
                  f"{t['texture_qp']}, {100 * used:.0f} % of its texels used (mean over the frames)")
    return summary


def _check_encoder_options(options: dict, count: int) -> None:
    """Raises ValueError for an option the encoder refuses, before any frame is read: the
    encoder is made for a unit box (its options are checked as it is made)."""
    from . import api

    geometry, _ = api._split_options(options)  # the texture options are checked here
    api._encoder(count, [0.0, 0.0, 0.0], [1.0, 1.0, 1.0], geometry)


def cmd_decode(a) -> dict:
    from . import _core

    data = _read_bytes(a.input)
    if a.output is None and not a.hash:
        raise CliError("give an output directory (-o) or --hash")
    if a.output is not None:
        refuse_inputs(a.output, [a.input], "output directory")
    try:
        stream = _core.Decoder(data, True)
    except _core.DecodeError as e:
        raise CliError(e.args[0]) from None
    n, units = stream.frame_count, stream.damage()
    if units and not a.skip_damaged:
        frame, offset, _, reason = units[0]
        raise CliError(f"{a.input}: frame {frame}, byte offset {offset}: {reason} "
                       f"({len(units)} damaged frame(s); --skip-damaged decodes the others)")
    if a.output is not None:  # before any frame is decoded
        check_decode_directory(a.output, a.input, a.force)
    # Frames without textures, as OBJ or PLY, are decoded and written by the core in one call.
    by_core = a.format in ("obj", "ply") and not _textured(stream)
    written, damaged, hashes = [], [], []
    start = time.perf_counter()
    with contextlib.ExitStack() as stack:
        out = stack.enter_context(_staged_or_none(a.output))
        # --hash prints a line per frame on stdout: that is its progress.
        bar = stack.enter_context(_progress(a, n, "decoding", a.quiet or (a.hash and not a.json)))
        # Closed first on an error, so that no frame is still being written as the staged
        # directory is removed.
        frames = stack.enter_context(contextlib.closing(
            _decoded_by_core(data, a, out, bar) if by_core else _decoded_by_api(data, a, out, bar, stream)))
        for i, digest, failure in frames:
            if failure is not None:
                if not a.skip_damaged:
                    raise CliError(failure[1])
                damaged.append({"frame": i, "offset": failure[0], "reason": failure[1]})
                continue
            if a.hash:
                hashes.append(digest)
                if not a.json:
                    print(f"frame {i} sha256 {digest}", flush=True)
            if out is not None:
                final = out.final(_frame_name(i, a.format))
                refuse_inputs(final, [a.input])
                written.append(str(final))
        if not written and not hashes:
            raise CliError(f"no frame of {a.input} decodes" + (f" (first: {damaged[0]['reason']})" if damaged else ""))
        if out is not None:
            for extra in (".mtl", ".png"):  # textured frames' companions, beside them
                for w in written:
                    refuse_inputs(Path(w).with_suffix(extra), [a.input])
            new = os.listdir(out.stage)
            out.commit()
            if a.force:  # the frames of a previous decode that these did not replace
                remove_stale_frames(a.output, new)
    seconds = time.perf_counter() - start
    if not a.json and a.output is not None and not a.hash:
        print(f"decoded {len(written)} frames into {a.output} in {seconds:.2f} s")
    for d in damaged:
        print(f"dynmesh decode: frame {d['frame']} (byte {d['offset']}) skipped: {d['reason']}", file=sys.stderr)
    if damaged:
        a.failure = f"{len(damaged)} of {n} frames are damaged or depend on damaged data; decoded the other {len(written)}"
    return {"frames": written, "seconds": seconds, "damaged": damaged, **({"sha256": hashes} if a.hash else {})}


def _frame_name(index: int, extension: str) -> str:
    return f"frame_{index:04d}.{extension}"


def _textured(stream) -> bool:
    """Whether a stream carries textures: its first frame has a texture unit (as
    ``texture.TextureDecoder.textured`` decides, a damaged one included)."""
    try:
        return stream.texture_payload(0) is not None
    except ValueError:
        return True


def _decoded_by_core(data: bytes, a, out, bar):
    """(frame, sha256 or None, None or (offset, reason) of its DecodeError) per frame, in
    order, every frame decoded and written into ``out`` by ``_core.decode_to_files``; an
    error writing a frame is raised."""
    from . import _core

    on_frame = None if bar.off else bar.step  # called with no argument, as frames are done (in any order)
    results = _core.decode_to_files(data, None if out is None else str(out.stage), a.format, a.lod,
                                    a.skip_damaged, a.hash, on_frame)
    for i, digest, error in results:
        if error is not None and not isinstance(error, _core.DecodeError):
            raise error
        yield i, digest, None if error is None else (error.args[2], error.args[0])


def _decoded_by_api(data: bytes, a, out, bar, stream):
    """As ``_decoded_by_core``, through ``dynmesh.api`` (textured frames, glTF). Each frame
    is handed to a writer thread, which writes it into ``out`` while the next frame is
    decoded; an error writing a frame is raised by the time the generator ends, which is
    when every file is written."""
    from . import api

    frame_hash = None
    if a.hash:
        from .conformance import frame_hash

    frames = api.decode_each(data, lod=a.lod) if a.skip_damaged else enumerate(api.decode(data, lod=a.lod))
    with _FrameWriter() as writer:
        for i, mesh in frames:
            bar.step(_decoded_text(stream, i))
            if isinstance(mesh, api.DecodeError):
                yield i, None, (mesh.offset, str(mesh))
                continue
            digest = frame_hash(mesh) if frame_hash is not None else None
            if out is not None:
                writer.write(out.path(_frame_name(i, a.format)), mesh)
            yield i, digest, None


def _decoded_text(stream, i: int) -> str:
    """Frame ``i`` of ``stream`` for the progress: "frame 3: P, 864 bytes"."""
    try:
        f = stream.frame_info(i)
    except ValueError:  # a damaged unit: reported as such by the decode
        return f"frame {i}"
    return frame_text(i, {"type": f["type"], "bytes": f["bytes"]})


class _FrameWriter:
    """Writes decoded frames (``_write_frame``) on one thread behind the decoding, at most
    ``ahead`` frames behind it. The formatting, PNG encoding and syncing it runs are done by
    the core with the GIL released, so on two cores a textured frame's files are written
    while the next frame's geometry and texture video are decoded.

    Leaving the ``with`` block waits for the frames handed in and raises the first error
    one of them met (or, when the block is left by an exception, only waits: nothing is
    left writing into a directory its caller is about to remove)."""

    def __init__(self, ahead: int = 2):
        import queue
        import threading

        self._jobs = queue.Queue(maxsize=ahead)
        self._error: BaseException | None = None
        self._dropping = False  # set when the caller failed: the queued frames are not written
        self._thread = threading.Thread(target=self._run, name="dynmesh-writer", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while (job := self._jobs.get()) is not None:
            if self._error is None and not self._dropping:
                try:
                    _write_frame(*job)
                except BaseException as e:  # raised in the decoding thread
                    self._error = e

    def write(self, path: Path, mesh) -> None:
        """Queues ``mesh`` for ``path`` (waits while ``ahead`` frames are queued); raises a
        previous frame's error at once."""
        if self._error is not None:
            raise self._error
        self._jobs.put((path, mesh))

    def __enter__(self) -> _FrameWriter:
        return self

    def __exit__(self, kind, value, tb) -> None:
        self._dropping = kind is not None
        self._jobs.put(None)
        self._thread.join()
        if kind is None and self._error is not None:
            raise self._error


def _staged_or_none(output):
    """A staged output directory, or nothing to write into (``--hash`` alone)."""
    return contextlib.nullcontext() if output is None else StagedDirectory(output)


def _write_frame(path: Path, mesh) -> Path:
    from . import api
    from .io import write_mesh

    if path.suffix == ".glb":
        from .io import glb_bytes

        api.write_bytes_atomic(path, glb_bytes(mesh, path.stem))
    else:
        write_mesh(path, mesh)
    return path


def cmd_play(a) -> dict:
    from .player import export, serve

    if a.export:
        result = export(a.input, a.export, force=a.force, fps=a.fps)
        if not (a.quiet or a.json):
            print(f"wrote a static page for {a.input} to {a.export}/ ({result['files']} files): host the folder "
                  "with any web server and open index.html")
        return result
    return serve(a.input, port=a.port, open_browser=not a.no_browser, quiet=a.quiet or a.json, fps=a.fps)


def cmd_info(a) -> dict:
    from . import api

    result = api.info(_read_bytes(a.input))
    if not a.json:
        h = result["header"]
        print(f"{a.input}: {result['bytes']} bytes, {h['frame_count']} frames, {h['bits']}-bit positions "
              f"({h['base_bits']}-bit base mesh), "
              f"{h['subdiv_iterations']} subdivision(s) ({','.join(h['schemes']) or 'none'}), {h['components']} displacement component(s)")
        lost = {d["frame"]: d for d in result["damaged"]}
        rows = [{"frame": i, **f, "ref": "-" if f.get("reference") is None else str(f["reference"]),
                 "status": f"damaged at byte {lost[i]['offset']}" if i in lost else "ok"}
                for i, f in enumerate(result["frames"])]
        print(table(rows, [("frame", "frame", "d"), ("type", "type", "s"), ("ref", "ref", "s"), ("qp", "qp", "d"),
                            ("bytes", "bytes", "d"), ("base_bytes", "base B", "d"), ("refresh_bytes", "refresh B", "d"),
                            ("displacement_bytes", "disp B", "d"), ("texture_bytes", "texture B", "d"),
                            ("status", "status", "s")]))
    if result["damaged"]:
        first = result["damaged"][0]
        a.failure = (f"{len(result['damaged'])} damaged frame unit(s), first frame {first['frame']} at byte "
                     f"{first['offset']}: {first['reason']}")
    return result


def cmd_metrics(a) -> dict:
    # --start picks the reference frames a stream was encoded from (its decoded frames are
    # numbered from 0); --count is the number of frames compared on both sides.
    ref_paths = resolve_sequence(a.reference, a.start, a.count)
    dec_paths = resolve_sequence(a.decoded, None, a.count)
    if len(ref_paths) != len(dec_paths):  # before any mesh is read
        n = min(len(ref_paths), len(dec_paths))
        raise CliError(f"{len(ref_paths)} reference frames but {len(dec_paths)} decoded frames: --count {n} compares "
                       f"the first {n} of each side (--start picks the first reference frame)")
    refs = _read_meshes(a, ref_paths, "reading the reference")
    decs = _read_meshes(a, dec_paths, "reading the decoded")
    with _progress(a, len(refs), "measuring") as bar:
        result = _metrics(refs, decs, a.peak, a.grid_size, lambda i, f: bar.step(metrics_text(i, f)))
    if not a.json:
        rows = [{"frame": i, **f} for i, f in enumerate(result["frames"])]
        colour = [("y_psnr", "Y PSNR", ".3f"), ("cb_psnr", "Cb PSNR", ".3f"), ("cr_psnr", "Cr PSNR", ".3f")]
        colour = colour if "y_psnr" in result else []
        print(table(rows, [("frame", "frame", "d"), ("d1_psnr", "D1 PSNR", ".3f"), ("d2_psnr", "D2 PSNR", ".3f")] + colour))
        of_texture = (f", Y {result['y_psnr']:.3f} dB, Cb {result['cb_psnr']:.3f} dB, Cr {result['cr_psnr']:.3f} dB"
                      if colour else "")
        identical = " (infinite: the sampled geometry is identical)" if result["d1_psnr"] == float("inf") else ""
        print(f"mean D1 {result['d1_psnr']:.3f} dB, D2 {result['d2_psnr']:.3f} dB{of_texture} "
              f"(peak {result['peak']:.6g}){identical}")
    return result


def _metrics(refs: list, decs: list, peak: float | None, grid_size: int, on_frame) -> dict:
    """``api.metrics(refs, decs, peak=peak, grid_size=grid_size)``, frame by frame, with
    ``on_frame(index, figures)`` after each frame (``api.metrics`` has no such callback:
    this follows it step for step, and tests/test_cli_day.py checks that both agree)."""
    import numpy as np

    from . import api

    if len(refs) != len(decs):
        raise ValueError(f"{len(refs)} reference frames but {len(decs)} decoded frames")
    lo, hi = api.sequence_bounds(refs)
    peak = float(np.max(hi - lo)) if peak is None else float(peak)
    if not (peak > 0 and np.isfinite(peak)):
        raise ValueError(f"peak must be a positive finite number, not {peak}")
    textured = all(api._has_texture(m) for m in refs + decs)
    frames = []
    for i, (r, d) in enumerate(zip(refs, decs)):
        try:
            frames.append(api._frame_metrics(r, d, textured, lo, hi, peak, grid_size))
        except ValueError as e:
            raise ValueError(f"frame {i}: {e}") from None
        on_frame(i, frames[-1])
    keys = ("d1_psnr", "d2_psnr") + (("y_psnr", "cb_psnr", "cr_psnr") if textured else ())
    mean = {k: float(np.mean([f[k] for f in frames])) for k in keys}
    return {"peak": peak, "frames": frames, **mean}


#: What `dynmesh eval` needs beyond the codec (the `eval` extra): the Draco baseline and the
#: report's plots.
EVAL_MODULES = ("DracoPy", "matplotlib")


def _require_eval_extra() -> None:
    """Fails before any work when the `eval` extra is not installed, rather than midway."""
    import importlib.util

    missing = [name for name in EVAL_MODULES if importlib.util.find_spec(name) is None]
    if missing:
        raise CliError(f"needs {' and '.join(missing)}, which the codec itself does not: "
                       "pip install 'dynmesh[eval]'")


def cmd_eval(a) -> dict:
    from .eval import evaluate, report

    _require_eval_extra()
    exp = evaluate.load_experiment(a.config)
    out = Path(a.out) if a.out else Path("results") / exp.name
    _check_jobs(a)
    if not a.report_only:
        check_output_directory(out, [a.config], what="results directory")
    if a.report:
        check_output_directory(a.report, [a.config], what="report directory")
        refuse_inputs(Path(a.report) / a.report_file, [a.config], "report")
    counts = {"reused": 0, "measured": 0}
    start = time.perf_counter()
    if a.report_only:
        results = evaluate.load_results(out)
    else:
        running: list[str] = []
        with _progress(a, len(evaluate.plan_runs(exp)), "runs", unit="run") as bar:

            def started(run):
                running.append(run.id)
                bar.note("running " + ", ".join(running))

            def done(run, record, reused):
                counts["reused" if reused else "measured"] += 1
                if run.id in running:
                    running.remove(run.id)
                bar.step(run_text(run.id, record, reused))
                bar.note("running " + ", ".join(running) if running else "")

            records = evaluate.run_experiment(exp, out, jobs=a.jobs, ray=a.ray, force=a.force, on_start=started,
                                               on_done=done)
        results = evaluate.results_document(exp, records)
    seconds = time.perf_counter() - start
    rows = report.bd_rows(results)
    page = None
    if a.report:
        command = " ".join(["dynmesh eval", str(a.config)] + (["--out", str(a.out)] if a.out else [])
                           + (["--jobs", str(a.jobs)] if a.jobs != 1 else []) + (["--ray", a.ray] if a.ray else [])
                           + ["--report", str(a.report)] + (["--report-file", a.report_file]
                                                            if a.report_file != "results.md" else []))
        page = report.write_report(results, a.report, a.report_file, command=command)
    if not a.json:
        fmt = lambda v, f: "n/a" if v is None else format(v, f)  # noqa: E731
        bd_rows = [{"sequence": r["sequence"], "variant": r["variant"], "d1": fmt(r["d1_bd"], "+.2f"),
                  "d2": fmt(r["d2_bd"], "+.2f"), "enc": fmt(r["enc_ratio"] and 100 * r["enc_ratio"], ".1f"),
                  "dec": fmt(r["dec_ratio"] and 100 * r["dec_ratio"], ".1f")} for r in rows]
        print(f"BD-rate against {results['anchor']} (PCHIP; time = test/anchor, geometric mean over rates)")
        print(table(bd_rows, [("sequence", "sequence", "s"), ("variant", "variant", "s"), ("d1", "D1 BD-rate %", "s"),
                             ("d2", "D2 BD-rate %", "s"), ("enc", "enc time %", "s"), ("dec", "dec time %", "s")]))
        what = ("report rebuilt from saved results" if a.report_only else
                f"{len(results['runs'])} runs ({counts['measured']} measured, {counts['reused']} reused)")
        print(f"{what} in {seconds:.1f} s; results in {out}" + (f"; report {page}" if page else ""))
    return {"out": str(out), "report": str(page) if page else None, "seconds": seconds, **counts,
            "bd_rate": rows, "runs": results["runs"]}


def _check_jobs(a) -> None:
    if a.jobs != "auto" and a.jobs < 1:
        raise CliError(f"--jobs must be at least 1 or auto, got {a.jobs}")


def _encode_jobs(jobs: int | str, frames: int, intra_period: int) -> int:
    """Local processes for ``encode --jobs``: ``auto`` is one per core, but no more than there
    are groups (all-intra: one per frame), so a sequence of one group is coded in this process."""
    if jobs != "auto":
        return jobs
    groups = -(-frames // max(intra_period, 1))
    return max(1, min(os.cpu_count() or 1, groups))


def _read_bytes(path: str) -> bytes:
    try:
        return Path(path).read_bytes()
    except OSError as e:
        raise CliError(f"cannot read {path}: {e.strerror}") from None


def parser() -> argparse.ArgumentParser:
    d = ENCODER
    top = Parser(prog="dynmesh", description="Codec for dynamic 3D meshes with time-varying topology.",
                  epilog=f"{EXIT_STATUS_HELP} {INTERNAL_STATUS_HELP}")
    sub = top.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("encode", help="encode a mesh sequence", description="Encode a mesh sequence into a .dmsh stream.")
    p.add_argument("input", help="a directory of .obj/.ply frames, a glob, a printf pattern (frame_%%04d.obj) or one mesh")
    p.add_argument("-o", "--output", required=True,
                   help="output stream (.dmsh), in an existing folder; checked before any frame is read")
    sequence_args(p)
    p.add_argument("--qp", type=int, default=d["qp"], help=f"displacement quantization parameter; +6 doubles the step (default {d['qp']})")
    p.add_argument("--base-ratio", type=float, default=d["base_ratio"],
                   help=f"base mesh faces / input faces (default: follows --qp, {base_ratio_rule()})")
    p.add_argument("--subdiv", type=int, default=d["subdiv"], help=f"subdivision iterations (default {d['subdiv']})")
    p.add_argument("--scheme", default=d["scheme"],
                   help="subdivision scheme: mixed (midpoint on every iteration but the last, Loop on the last, as the "
                        "MPEG test model does), midpoint, loop, or a comma-separated list with one per iteration "
                        f"(default {d['scheme']})")
    p.add_argument("--bits", type=int, default=d["bits"], help=f"position bits over the sequence box (default {d['bits']})")
    p.add_argument("--base-bits", type=int, default=d["base_bits"],
                   help=f"base mesh position bits, at most --bits (default {d['base_bits']})")
    p.add_argument("--all-components", dest="normal_only", action="store_false",
                   help="code all three displacement components, not only the normal one")
    p.add_argument("--intra-period", type=int, default=d["intra_period"],
                   help=f"frames per group; each group starts with an intra frame, 1 = all intra (default {d['intra_period']})")
    p.add_argument("--inter", choices=INTER_MODES, default=d["inter"],
                   help="how predicted frames get their base mesh when the topology changes: none = never (intra); "
                        "the paper's stages: nns = nearest input vertex of each reference base vertex, "
                        "+me = searched from where the neighbours' motion predicts, "
                        "+qem = refined by the QEM edge collapse around each match; "
                        "nns+me+proj = ours: the predicted points projected onto the input surface instead "
                        f"(default {d['inter']})")
    p.add_argument("--fold-repair", action=argparse.BooleanOptionalAction, default=d["fold_repair"],
                   help="repair flipped or degenerate anchor triangles before coding (not in the paper; default: %(default)s)")
    p.add_argument("--rigid-align", action=argparse.BooleanOptionalAction, default=d["rigid_align"],
                   help="move each connected part of the reference base rigidly onto the input (ICP, predicted from the "
                        "previous frame's motion) before the anchor's matching (not in the paper; default: %(default)s)")
    p.add_argument("--motion-parts", action=argparse.BooleanOptionalAction, default=d["motion_parts"],
                   help="with --rigid-align, also cut each connected part of the reference base into the parts that "
                        "move apart inside it (bodies in contact meshed as one surface), each aligned by its own rigid "
                        "fit (ours, not in the paper; default: %(default)s)")
    p.add_argument("--refresh", action=argparse.BooleanOptionalAction, default=d["refresh"],
                   help="code the regions where a predicted frame's moved base fits worst (far from the input, or input it "
                        "does not cover) intra inside the predicted frame, from the frame's own base mesh; kept when the "
                        "rate-distortion cost says so (not in the paper; default: %(default)s)")
    p.add_argument("--references", type=int, default=d["references"], metavar="N",
                   help="reference choice: a predicted frame may refer to any of the last N coded frames of its group, "
                        "and is predicted from the one whose input lies closest to its own (an older one only if its input "
                        "has the frame's connectivity) "
                        f"(1 to {MAX_REFERENCES}; default {d['references']}: the previous frame)")
    p.add_argument("--intra-reference", action=argparse.BooleanOptionalAction, default=d["intra_reference"],
                   help="reference choice: the group's latest intra frame may be the reference too (default: %(default)s)")
    p.add_argument("--always-try-intra", action=argparse.BooleanOptionalAction, default=d["always_try_intra"],
                   help="intra/inter decision: code every predicted frame intra too and try its refresh before "
                        "choosing, whatever --intra-check-db says; on the shared captures no fewer bytes than the "
                        "default, for 1.1-1.9x its encode time (ours; default: %(default)s)")
    p.add_argument("--intra-check-db", type=float, default=d["intra_check_db"], metavar="DB",
                   help="intra/inter decision: a frame predicted through the anchor whose estimated distortion lies "
                        "more than DB above the last (or the group's best) intra frame's is also coded intra, and its "
                        "refresh tried, before choosing, even when its rate beats the last intra frame's; at 2, 4-7 %% "
                        "fewer bytes at the same D1 on mitch and thomas than inf (never), none on dancer, for 1.1-1.3x "
                        "the encode time (ours; default %(default)g)")
    p.add_argument("--rd-slope", type=float, default=d["rd_slope"],
                   help="intra/inter decision: dB of PSNR a predicted frame may lose per halving of its rate against "
                        f"intra (default {d['rd_slope']:g})")
    p.add_argument("--refit", action=argparse.BooleanOptionalAction, default=d["refit"],
                   help="least-squares refit of each base mesh (intra, and the anchor or tracked base of predicted frames) so that "
                        "its subdivision fits the input, before quantization (default: %(default)s)")
    p.add_argument("--lifting", choices=LIFTINGS, default=d["lifting"],
                   help="update weights of the lifting transform: valence = the test model's per-level weights "
                        "divided by each parent's valence, constant = 1/8 at every level (default %(default)s)")
    p.add_argument("--aq", action=argparse.BooleanOptionalAction, default=d["aq"],
                   help="adaptive displacement quantization by vertex valence (default: %(default)s)")
    p.add_argument("--aq-alpha", type=float, default=d["aq_alpha"], help=f"AQ step factor alpha (default {d['aq_alpha']:g})")
    p.add_argument("--aq-delta", type=float, default=d["aq_delta"], help=f"AQ lattice offset delta, |delta| < 1 (default {d['aq_delta']:g})")
    p.add_argument("--aq-h", type=float, default=d["aq_h"], help=f"AQ valence normalisation h (default {d['aq_h']:g})")
    t = TEXTURE
    p.add_argument("--texture", action=argparse.BooleanOptionalAction, default=None,
                   help="code the frames' textures (default: when every frame has UVs and a texture image; "
                        "a warning when only some have)")
    p.add_argument("--texture-size", type=int, default=t["texture_size"],
                   help="side of the texture atlas in texels (default: about the texel count of the first frame's "
                        "texture, to a multiple of 16: a 1024 x 1024 source gives 1024)")
    p.add_argument("--texture-qp", type=int, default=t["texture_qp"],
                   help="texture video QP, 0-51, on HEVC's scale whatever the codec (default: follows --qp, "
                        f"{texture_qp_rule()})")
    p.add_argument("--texture-codec", choices=list(TEXTURE_CODECS), default=t["texture_codec"],
                   help=f"texture video codec, 10-bit 4:2:0: AV1 (libsvtav1; browsers and `dynmesh play` decode it) or "
                        f"HEVC (libx265; browsers do not) (default {t['texture_codec']})")
    parallel_args(p, "groups of --intra-period frames encoded", default="auto")
    common_args(p)
    p.set_defaults(run=cmd_encode)

    p = sub.add_parser("decode", help="decode a stream into mesh files", description="Decode a .dmsh stream into frame_0000.obj, ...")
    p.add_argument("input")
    p.add_argument("-o", "--output",
                   help="output directory (optional with --hash), made if missing; it must be new or empty unless --force")
    p.add_argument("--force", action="store_true",
                   help="decode into a directory that already holds files: the frame files of a previous decode "
                        "(frame_NNNN.obj/.mtl/.png/.ply/.glb) are replaced or removed once the new frames are "
                        "decoded, so that no old frame remains; other files are kept")
    p.add_argument("--format", choices=["obj", "ply", "glb"], default="obj",
                   help="obj (with .mtl and .png when the stream is textured), ply (geometry only) or glb "
                        "(glTF 2.0 binary with normals, and UVs and the texture image when textured)")
    p.add_argument("--skip-damaged", action="store_true",
                   help="decode every frame whose reference chain is intact, report the others (frame number "
                        "and byte offset) and exit with status 1; without it a damaged stream is an error")
    p.add_argument("--hash", action="store_true",
                   help="print 'frame N sha256 HEX' per frame: SHA-256 of the positions as little-endian float64, "
                        "then the faces as little-endian uint32 (as web/bin/dynmesh-decode.js --hash)")
    p.add_argument("--lod", type=non_negative, metavar="K",
                   help="level of detail: stop after K subdivision iterations (default: all of the stream's)")
    common_args(p)
    p.set_defaults(run=cmd_decode)

    p = sub.add_parser("play", help="play a stream in the browser",
                       description="Serve a web player for a .dmsh stream on 127.0.0.1: the page decodes the stream "
                                   "in the browser with the JavaScript decoder and plays it.")
    p.add_argument("input")
    p.add_argument("--port", type=int, default=8765, help="port on 127.0.0.1 (default 8765; 0 = any free port)")
    p.add_argument("--no-browser", action="store_true", help="only serve; do not open a browser")
    p.add_argument("--fps", type=float, default=30.0, help="frame rate (the stream does not carry one; default 30)")
    p.add_argument("--export", metavar="DIR", help="write a static page (player, decoder, stream) into DIR for any "
                                                 "web server, instead of serving; DIR must be new or empty unless --force")
    p.add_argument("--force", action="store_true", help="with --export: replace a non-empty DIR")
    common_args(p)
    p.set_defaults(run=cmd_play)

    p = sub.add_parser("info", help="show headers and per-frame sizes of a stream")
    p.add_argument("input")
    common_args(p)
    p.set_defaults(run=cmd_info)

    p = sub.add_parser("metrics", help="D1/D2 PSNR between two meshes or sequences",
                       description="D1/D2 PSNR (MPEG grid sampling) of DEC against REF, per frame and mean.")
    p.add_argument("reference", help="reference mesh or sequence")
    p.add_argument("decoded", help="decoded mesh or sequence")
    p.add_argument("--start", type=int,
                   help="first reference frame (to match a stream encoded with --start; the decoded frames are "
                        "taken from their first)")
    p.add_argument("--count", type=int, help="number of frames compared, the same on both sides (default: all)")
    p.add_argument("--peak", type=float, help="PSNR peak (default: largest side of the reference sequence's bounding box)")
    p.add_argument("--grid-size", type=grid_size, default=1024, help=f"sampling grid size, 2 to {MAX_GRID_SIZE} (default 1024)")
    common_args(p)
    p.set_defaults(run=cmd_metrics)

    p = sub.add_parser("synth", help="write a synthetic sequence with time-varying topology")
    p.add_argument("output", nargs="?", help="output directory")
    p.add_argument("-o", "--output", dest="output_option", metavar="OUTPUT",
                   help="the output directory given as encode and decode take theirs")
    p.add_argument("--kind", choices=("metaballs", "fused-gears", "cloth"), default="metaballs",
                   help="metaballs that merge and split (default); two meshing gears whose teeth fuse into one "
                        "surface; a sleeve sliding along an arm (both: parts that move differently inside one surface)")
    p.add_argument("--frames", type=int, default=8)
    p.add_argument("--resolution", type=int, default=None,
                   help="polygonization grid cells per side (default: the kind's own, 48 for metaballs)")
    p.add_argument("--seed", type=int, default=0, help="metaballs' random paths")
    common_args(p)
    p.set_defaults(run=cmd_synth)

    p = sub.add_parser("demo", help="synth, encode, decode and measure a built-in sequence")
    p.add_argument("--frames", type=int, default=8)
    p.add_argument("--qps", type=int, nargs="+", default=[26, 30, 34, 38], help="QPs to try (default 26 30 34 38)")
    p.add_argument("--workdir", help="where to keep the files (default: a new temporary directory)")
    common_args(p)
    p.set_defaults(run=cmd_demo)

    p = sub.add_parser("eval", help="run a rate-distortion experiment (BD-rate, plots, report)",
                       description="Encode, decode and measure every sequence x variant x rate point of an "
                                   "experiment file (TOML), save the results, compute BD-rates against the anchor "
                                   "and optionally write a Markdown report with RD plots. Finished runs are reused.")
    p.add_argument("config", help="experiment file (.toml); paths in it are relative to its directory")
    p.add_argument("--out", help="results directory (default results/<config stem>)")
    parallel_args(p, "runs measured")
    p.add_argument("--force", action="store_true", help="measure every run again, even if saved results match")
    p.add_argument("--report", metavar="DIR", help="write a Markdown report with RD plots into DIR")
    p.add_argument("--report-file", default="results.md",
                   help="report file name in DIR; plots go to DIR/<its stem>/ (default results.md)")
    p.add_argument("--report-only", action="store_true",
                   help="measure nothing: rebuild tables and report from OUT/results.json")
    common_args(p)
    p.set_defaults(run=cmd_eval)
    for p in sub.choices.values():
        p.epilog = f"{EXIT_STATUS_HELP} {INTERNAL_STATUS_HELP}"
    return top


def _message(e: Exception) -> str:
    """One line for the user; an OSError names its file, not its errno."""
    if isinstance(e, OSError) and e.strerror:
        return f"{e.filename}: {e.strerror}" if e.filename else e.strerror
    return str(e)


def _reported_errors() -> tuple[type[BaseException], ...]:
    """The exceptions reported in one line rather than a traceback: the user's errors
    (MeshError, SequenceError and DecodeError are ValueErrors), and a worker's failure when
    the command used workers (a module it did not import raised nothing)."""
    parallel = sys.modules.get(f"{__package__}.parallel")
    return (CliError, ValueError, OSError, MemoryError) + ((parallel.WorkerError,) if parallel else ())


def _internal_errors() -> tuple[type[BaseException], ...]:
    """The core's InternalError (a bug in dynmesh), reported in one line with its own exit
    status (``EXIT_INTERNAL``); nothing when the command did not import the core (which then
    raised nothing)."""
    core = sys.modules.get(f"{__package__}._core")
    return (core.InternalError,) if core else ()


def main(argv: list[str] | None = None) -> int:
    """The ``dynmesh`` command; returns its exit status (``EXIT_STATUS_HELP``)."""
    try:
        status = _main(argv)
        sys.stdout.flush()  # here, where a closed pipe is caught, rather than at exit
        return status
    except BrokenPipeError:
        # The reader went away (`dynmesh decode s.dmsh --hash | head -1`): no error to report,
        # and, as the Python documentation recommends, stdout goes to devnull so that the
        # interpreter's last flush does not fail again.
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        except (OSError, ValueError, AttributeError):  # a stdout without a file (tests)
            pass
        return EXIT_PIPE_CLOSED


def _warning_line(command: str):
    """Shows a warning (a ``MeshWarning`` of a repaired input file, a ``TextureWarning``) as
    one line on stderr in the command's voice, not as Python's source location and line."""
    def show(message, category, filename, lineno, file=None, line=None):
        print(f"dynmesh {command}: warning: {message}", file=sys.stderr, flush=True)
    return show


def _main(argv: list[str] | None) -> int:
    args = parse(parser(), argv)
    args.failure = None  # set by a command that did its work but must still exit non-zero
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _warning_line(args.command)
            result = args.run(args)
    except BrokenPipeError:
        raise
    except _reported_errors() as e:
        print(f"dynmesh {args.command}: error: {_message(e)}", file=sys.stderr)
        return EXIT_ERROR
    except _internal_errors() as e:
        print(f"dynmesh {args.command}: {_message(e)}", file=sys.stderr)
        return EXIT_INTERNAL
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    if args.json:
        import json

        json.dump(result, sys.stdout, indent=1, default=str)
        print()
    if args.failure:
        print(f"dynmesh {args.command}: error: {args.failure}", file=sys.stderr)
        return EXIT_ERROR
    return 0


if __name__ == "__main__":
    sys.exit(main())
