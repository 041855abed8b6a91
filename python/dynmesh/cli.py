"""The ``dynmesh`` command line."""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

from tqdm import tqdm

from . import api
from .io import MeshError, read_mesh, write_mesh
from .sequence import SequenceError, resolve_sequence


class CliError(Exception):
    """An error to report to the user, without a traceback."""


def _progress(total: int, desc: str, quiet: bool):
    return tqdm(total=total, desc=desc, unit="frame", disable=quiet or None, file=sys.stderr, leave=False)


def _read_sequence(spec: str, start: int | None, count: int | None, quiet: bool) -> tuple[list[Path], list]:
    paths = resolve_sequence(spec, start, count)
    with _progress(len(paths), "reading", quiet) as bar:
        meshes = []
        for p in paths:
            meshes.append(read_mesh(p))
            bar.update()
    return paths, meshes


def _table(rows: list[dict], columns: list[tuple[str, str, str]]) -> str:
    """Fixed-width table; columns are (key, heading, format)."""
    cells = [[format(r[k], f) for k, _, f in columns] for r in rows]
    widths = [max([len(h)] + [len(c[i]) for c in cells]) for i, (_, h, _) in enumerate(columns)]
    line = lambda vals: "  ".join(v.rjust(w) for v, w in zip(vals, widths))
    return "\n".join([line([h for _, h, _ in columns])] + [line(c) for c in cells])


def _encoder_options(a) -> dict:
    return dict(qp=a.qp, base_ratio=a.base_ratio, subdiv=a.subdiv, scheme=a.scheme, bits=a.bits,
                normal_only=not a.all_components)


def cmd_encode(a) -> dict:
    paths, meshes = _read_sequence(a.input, a.start, a.count, a.quiet)
    with _progress(len(meshes), "encoding", a.quiet) as bar:
        result = api.encode_frames(meshes, on_frame=lambda i, s: bar.update(), **_encoder_options(a))
    api.write_bytes_atomic(a.output, result.data)
    frames = [{"frame": i, "input": str(p), **s} for i, (p, s) in enumerate(zip(paths, result.frames))]
    summary = {"output": str(a.output), "bytes": len(result.data), "frames": frames,
               "options": _encoder_options(a)}
    if not a.json:
        print(_table(frames, [("frame", "frame", "d"), ("bytes", "bytes", "d"), ("base_bytes", "base B", "d"),
                              ("displacement_bytes", "disp B", "d"), ("base_faces", "base faces", "d"),
                              ("output_faces", "out faces", "d"), ("seconds", "seconds", ".3f")]))
        print(f"wrote {a.output}: {len(result.data)} bytes, {len(frames)} frames, "
              f"{8 * len(result.data) / len(frames) * 30 / 1e6:.3f} Mbit/s at 30 fps")
    return summary


def cmd_decode(a) -> dict:
    data = _read_bytes(a.input)
    out = Path(a.output)
    out.mkdir(parents=True, exist_ok=True)
    n = api.info(data)["header"]["frame_count"]
    written = []
    start = time.perf_counter()
    with _progress(n, "decoding", a.quiet) as bar:
        for i, mesh in enumerate(api.decode(data)):
            path = out / f"frame_{i:04d}.{a.format}"
            write_mesh(path, mesh)
            written.append(str(path))
            bar.update()
    seconds = time.perf_counter() - start
    if not a.json:
        print(f"decoded {len(written)} frames into {out} in {seconds:.2f} s")
    return {"frames": written, "seconds": seconds}


def cmd_info(a) -> dict:
    result = api.info(_read_bytes(a.input))
    if not a.json:
        h = result["header"]
        print(f"{a.input}: {result['bytes']} bytes, {h['frame_count']} frames, {h['bits']}-bit positions, "
              f"{h['subdiv_iterations']} {h['scheme']} subdivision(s), {h['components']} displacement component(s)")
        rows = [{"frame": i, **f} for i, f in enumerate(result["frames"])]
        print(_table(rows, [("frame", "frame", "d"), ("type", "type", "s"), ("qp", "qp", "d"),
                            ("bytes", "bytes", "d"), ("base_bytes", "base B", "d"),
                            ("displacement_bytes", "disp B", "d")]))
    return result


def cmd_metrics(a) -> dict:
    _, refs = _read_sequence(a.reference, None, None, a.quiet)
    _, decs = _read_sequence(a.decoded, None, None, a.quiet)
    result = api.metrics(refs, decs, peak=a.peak, grid_size=a.grid_size)
    if not a.json:
        rows = [{"frame": i, **f} for i, f in enumerate(result["frames"])]
        print(_table(rows, [("frame", "frame", "d"), ("d1_psnr", "D1 PSNR", ".3f"), ("d2_psnr", "D2 PSNR", ".3f")]))
        print(f"mean D1 {result['d1_psnr']:.3f} dB, D2 {result['d2_psnr']:.3f} dB (peak {result['peak']:.6g})")
    return result


def cmd_synth(a) -> dict:
    from .synth import synth_sequence, write_sequence

    meshes = synth_sequence(frames=a.frames, resolution=a.resolution, seed=a.seed)
    paths = write_sequence(meshes, a.output)
    if not a.json:
        print(f"wrote {len(paths)} frames to {a.output}")
    return {"frames": [str(p) for p in paths]}


def cmd_demo(a) -> dict:
    from .synth import synth_sequence, write_sequence

    work = Path(a.workdir) if a.workdir else Path(tempfile.mkdtemp(prefix="dynmesh-demo-"))
    meshes = synth_sequence(frames=a.frames)
    paths = write_sequence(meshes, work / "input")
    raw = sum(p.stat().st_size for p in paths)
    rows = []
    for qp in a.qps:
        t0 = time.perf_counter()
        result = api.encode_frames(meshes, qp=qp)
        enc_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        decoded = list(api.decode(result.data))
        dec_s = time.perf_counter() - t0
        m = api.metrics(meshes, decoded)
        rows.append({"qp": qp, "bytes": len(result.data), "ratio": raw / len(result.data), "d1_psnr": m["d1_psnr"],
                     "d2_psnr": m["d2_psnr"], "enc_ms": 1000 * enc_s / len(meshes), "dec_ms": 1000 * dec_s / len(meshes)})
        api.write_bytes_atomic(work / f"demo_qp{qp}.dmsh", result.data)
        for i, mesh in enumerate(decoded):
            (work / f"decoded_qp{qp}").mkdir(exist_ok=True)
            write_mesh(work / f"decoded_qp{qp}" / f"frame_{i:04d}.obj", mesh)
    if not a.json:
        print(f"synthetic sequence: {len(meshes)} frames, {min(m.vertex_count for m in meshes)}-"
              f"{max(m.vertex_count for m in meshes)} vertices, raw OBJ {raw} bytes; files in {work}")
        print(_table(rows, [("qp", "QP", "d"), ("bytes", "bytes", "d"), ("ratio", "vs OBJ", ".0f"),
                            ("d1_psnr", "D1 PSNR", ".2f"), ("d2_psnr", "D2 PSNR", ".2f"),
                            ("enc_ms", "enc ms/frame", ".1f"), ("dec_ms", "dec ms/frame", ".1f")]))
    return {"workdir": str(work), "raw_bytes": raw, "rates": rows}


def _read_bytes(path: str) -> bytes:
    try:
        return Path(path).read_bytes()
    except OSError as e:
        raise CliError(f"cannot read {path}: {e.strerror}") from None


def _sequence_args(p):
    p.add_argument("--start", type=int, help="first frame (index into the sorted list, or number for a printf pattern)")
    p.add_argument("--count", type=int, help="number of frames")


def _common(p):
    p.add_argument("--json", action="store_true", help="print the result as JSON on stdout")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")


def parser() -> argparse.ArgumentParser:
    d = api.DEFAULTS
    top = argparse.ArgumentParser(prog="dynmesh", description="Codec for dynamic 3D meshes with time-varying topology.")
    sub = top.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("encode", help="encode a mesh sequence", description="Encode a mesh sequence into a .dmsh stream.")
    p.add_argument("input", help="a directory of .obj/.ply frames, a glob, a printf pattern (frame_%%04d.obj) or one mesh")
    p.add_argument("-o", "--output", required=True, help="output stream (.dmsh)")
    _sequence_args(p)
    p.add_argument("--qp", type=int, default=d["qp"], help=f"displacement quantization parameter; +6 doubles the step (default {d['qp']})")
    p.add_argument("--base-ratio", type=float, default=d["base_ratio"], help=f"base mesh faces / input faces (default {d['base_ratio']:g})")
    p.add_argument("--subdiv", type=int, default=d["subdiv"], help=f"subdivision iterations (default {d['subdiv']})")
    p.add_argument("--scheme", choices=["midpoint", "loop"], default=d["scheme"], help="subdivision scheme (default midpoint)")
    p.add_argument("--bits", type=int, default=d["bits"], help=f"base mesh position bits (default {d['bits']})")
    p.add_argument("--all-components", action="store_true", help="code all three displacement components, not only the normal one")
    _common(p)
    p.set_defaults(run=cmd_encode)

    p = sub.add_parser("decode", help="decode a stream into mesh files", description="Decode a .dmsh stream into frame_0000.obj, ...")
    p.add_argument("input")
    p.add_argument("-o", "--output", required=True, help="output directory")
    p.add_argument("--format", choices=["obj", "ply"], default="obj")
    _common(p)
    p.set_defaults(run=cmd_decode)

    p = sub.add_parser("info", help="show headers and per-frame sizes of a stream")
    p.add_argument("input")
    _common(p)
    p.set_defaults(run=cmd_info)

    p = sub.add_parser("metrics", help="D1/D2 PSNR between two meshes or sequences",
                       description="D1/D2 PSNR (MPEG grid sampling) of DEC against REF, per frame and mean.")
    p.add_argument("reference", help="reference mesh or sequence")
    p.add_argument("decoded", help="decoded mesh or sequence")
    p.add_argument("--peak", type=float, help="PSNR peak (default: largest side of the reference sequence's bounding box)")
    p.add_argument("--grid-size", type=int, default=1024, help="sampling grid size (default 1024)")
    _common(p)
    p.set_defaults(run=cmd_metrics)

    p = sub.add_parser("synth", help="write a synthetic sequence with time-varying topology")
    p.add_argument("output", help="output directory")
    p.add_argument("--frames", type=int, default=8)
    p.add_argument("--resolution", type=int, default=48, help="polygonization grid cells per side")
    p.add_argument("--seed", type=int, default=0)
    _common(p)
    p.set_defaults(run=cmd_synth)

    p = sub.add_parser("demo", help="synth, encode, decode and measure a built-in sequence")
    p.add_argument("--frames", type=int, default=8)
    p.add_argument("--qps", type=int, nargs="+", default=[22, 28, 34], help="QPs to try (default 22 28 34)")
    p.add_argument("--workdir", help="where to keep the files (default: a new temporary directory)")
    _common(p)
    p.set_defaults(run=cmd_demo)
    return top


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    try:
        result = args.run(args)
    except (CliError, MeshError, SequenceError, api.DecodeError, ValueError, OSError) as e:
        print(f"dynmesh {args.command}: error: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    if args.json:
        json.dump(result, sys.stdout, indent=1, default=str)
        print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
