"""The ``dynmesh synth`` and ``dynmesh demo`` commands: built-in sequences, and the demo that
codes one at a few QPs, predicted and all-intra, and says what prediction saved."""

from __future__ import annotations

import time
from pathlib import Path

from .cli_output import table
from .cli_paths import check_output_directory


def cmd_synth(a) -> dict:
    from . import synth

    a.output = _synth_output(a.output, a.output_option)
    check_output_directory(a.output)
    resolution = {} if a.resolution is None else {"resolution": a.resolution}
    meshes = {
        "metaballs": lambda: synth.synth_sequence(frames=a.frames, seed=a.seed, **resolution),
        "fused-gears": lambda: synth.fused_gear_sequence(frames=a.frames, **resolution),
        "cloth": lambda: synth.cloth_sequence(frames=a.frames, **resolution),
    }[a.kind]()
    paths = synth.write_sequence(meshes, a.output)
    if not a.json:
        print(f"wrote {len(paths)} frames to {a.output}")
    return {"frames": [str(p) for p in paths]}


def _synth_output(positional: str | None, option: str | None) -> str:
    """The output directory of ``synth``, given either way but once."""
    if positional is None and option is None:
        raise ValueError("no output directory: give one, as in `dynmesh synth frames/` or `dynmesh synth -o frames/`")
    if positional is not None and option is not None and positional != option:
        raise ValueError(f"two output directories ({positional} and -o {option}); give one")
    return positional if positional is not None else option


def cmd_demo(a) -> dict:
    import tempfile

    from .eval.report import bd_rate
    from .synth import synth_sequence, write_sequence

    if a.workdir:
        check_output_directory(a.workdir, what="work directory")
    work = Path(a.workdir) if a.workdir else Path(tempfile.mkdtemp(prefix="dynmesh-demo-"))
    meshes = synth_sequence(frames=a.frames, cycle=min(1.0, DEMO_STEP * max(a.frames - 1, 1)))
    paths = write_sequence(meshes, work / "input")
    raw = sum(p.stat().st_size for p in paths)
    rows = [_demo_rate(meshes, raw, qp, work) for qp in a.qps]
    saving = bd_rate([(r["intra_bytes"], r["intra_d1"]) for r in rows], [(r["bytes"], r["d1_psnr"]) for r in rows])
    if not a.json:
        print(f"synthetic sequence: {len(meshes)} frames, {min(m.vertex_count for m in meshes)}-"
              f"{max(m.vertex_count for m in meshes)} vertices, every frame with its own connectivity, "
              f"raw OBJ {raw} bytes; files in {work}")
        print(table(rows, [("qp", "QP", "d"), ("bytes", "bytes", "d"), ("ratio", "vs OBJ", ".0f"), ("types", "frame types", "s"),
                            ("d1_psnr", "D1 PSNR", ".2f"), ("d2_psnr", "D2 PSNR", ".2f"),
                            ("intra_bytes", "all-intra bytes", "d"), ("intra_d1", "all-intra D1", ".2f"),
                            ("enc_ms", "enc ms/frame", ".1f"), ("dec_ms", "dec ms/frame", ".1f")]))
        value = saving["bd_rate"]
        verdict = "n/a" if value is None else f"{value:+.1f} %"
        print(f"predicted (P) frames against all-intra coding of the same frames: D1 BD-rate {verdict}"
              f"{' (' + saving['note'] + ')' if saving['note'] else ''}; negative = fewer bits for the same quality")
    return {"workdir": str(work), "raw_bytes": raw, "rates": rows, "bd_rate_vs_all_intra": saving}


# The demo's share of the synthetic motion per frame: 8 frames over a quarter of it move
# about as much per frame as a 30 fps capture, where predicted frames pay.
DEMO_STEP = 0.25 / 7


def _demo_rate(meshes, raw: int, qp: int, work: Path) -> dict:
    """One QP of the demo: the default encoder and all-intra, decoded, measured and kept."""
    from . import api
    from .io import write_mesh

    t0 = time.perf_counter()
    result = api.encode_frames(meshes, qp=qp)
    enc_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    decoded = list(api.decode(result.data))
    dec_s = time.perf_counter() - t0
    m = api.metrics(meshes, decoded)
    intra = api.encode_frames(meshes, qp=qp, intra_period=1, keep_reconstructions=True)
    mi = api.metrics(meshes, intra.reconstructions)
    api.write_bytes_atomic(work / f"demo_qp{qp}.dmsh", result.data)
    (work / f"decoded_qp{qp}").mkdir(exist_ok=True)
    for i, mesh in enumerate(decoded):
        write_mesh(work / f"decoded_qp{qp}" / f"frame_{i:04d}.obj", mesh)
    return {"qp": qp, "bytes": len(result.data), "ratio": raw / len(result.data),
            "types": "".join(f["type"] for f in result.frames), "d1_psnr": m["d1_psnr"], "d2_psnr": m["d2_psnr"],
            "intra_bytes": len(intra.data), "intra_d1": mi["d1_psnr"],
            "enc_ms": 1000 * enc_s / len(meshes), "dec_ms": 1000 * dec_s / len(meshes)}
