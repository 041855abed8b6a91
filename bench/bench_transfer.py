"""What the texture transfer costs per frame, and what textures cost a whole encode.

Part 1, the transfer alone: the first frames (up to 6) of each textured capture present under
../shared/data (liam_textured, 1024 x 1024 textures; basketball_textured, 2048 x 2048) are
coded as ``encode_frames`` codes them with the default options, and each frame's inputs of
``_core.transfer_texture`` are kept: the reconstruction in the group's atlas (which
``TextureEncoder.add`` makes on the decoded base mesh, ``coded_atlas`` carried through
subdivision), and the input frame with its UVs and texture image. Then ``transfer_texture`` (transfer and push-pull padding, as the
encoder calls it) runs ``--repeat`` times per frame on all the machine's cores: the table gives
the minimum and median seconds per frame (each frame's minimum and median, then their median
over the frames) and the covered share of the atlas. A sequence whose data is missing is
skipped and named.

Part 2, the commands: ``dynmesh encode`` of liam_textured's first 6 frames with textures and
with ``--no-texture``, as whole processes (Python start-up and file reading included), the two
in turn ``--runs`` times each, so that a drift of the shared machine's speed hits both; wall
and CPU seconds (user + system of the process and its threads), minimum and median, and the
ratio textured / untextured of the medians.

    python bench/bench_transfer.py [--frames 6] [--repeat 5] [--runs 5] [--no-commands] [--print-only]
"""

from __future__ import annotations

import argparse
import compileall
import dataclasses
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import SHARED_DATA, markdown_table, write_section

SEQUENCES = ["liam_textured", "basketball_textured"]
COMMAND_SEQUENCE, COMMAND_FRAMES = "liam_textured", 6

TRANSFER_COLUMNS = [("sequence", "sequence", "s"), ("atlas", "atlas", "s"), ("faces", "target / source faces", "s"),
                    ("frames", "frames", "d"), ("min", "min s/frame", ".3f"), ("median", "median s/frame", ".3f"),
                    ("covered", "covered", ".1%")]
COMMAND_COLUMNS = [("command", "command", "s"), ("wall_min", "wall min s", ".2f"), ("wall", "wall median s", ".2f"),
                   ("cpu", "CPU median s", ".2f"), ("ratio", "textured / untextured", "s")]


def transfer_inputs(sequence: str, frames: int) -> list[tuple]:
    """The arguments of ``_core.transfer_texture`` for each of the first ``frames`` frames of
    ``sequence``, as ``encode_frames`` makes them with the default options: the same loop as
    ``api.encode_units`` (the texture stage's cost given to the geometry encoder, then
    ``TextureEncoder.add``, which makes the group's atlas), the atlas read back from it."""
    from dynmesh import api
    from dynmesh import texture as _texture
    from dynmesh.io import image_of, read_mesh, resolve_sequence
    from dynmesh.mesh import Mesh

    paths = resolve_sequence(str(SHARED_DATA / sequence / "*.obj"))[:frames]
    # Each texture read once, here: the texture stage and the timed transfers share it.
    meshes = [dataclasses.replace(m, image=image_of(m)) for m in map(read_mesh, paths)]
    opts, texture_options = api._split_options({})
    texture_options = _texture.resolve_options(texture_options, opts["qp"], meshes[0])
    size = texture_options["texture_size"]
    enc = api._encoder(len(meshes), *api.sequence_bounds(meshes), opts)
    tex = _texture.TextureEncoder(opts["subdiv"], texture_options, False, estimate_costs=opts["intra_period"] > 1)
    coded = []
    for m in meshes:
        with tex.geometry():
            _, stats, (pos, faces), (base_pos, base_faces) = enc.encode_frame(m.positions, m.faces, tex.cost)
        tex.add(stats["starts_texture_group"], Mesh(base_pos, base_faces), Mesh(pos, faces), m)
        coded.append((pos, faces, m))
    tex.finish()
    return [(pos, faces, uv, uv_faces, m.positions, m.faces, m.uvs, m.uv_faces, m.image, size, size)
            for (pos, faces, m), (uv, uv_faces) in zip(coded, tex.uvs)]


def time_transfer(sequence: str, frames: int, repeat: int) -> dict:
    from dynmesh import _core

    calls = transfer_inputs(sequence, frames)
    mins, medians, covered = [], [], []
    for args in calls:
        times = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            _, share = _core.transfer_texture(*args)
            times.append(time.perf_counter() - t0)
        mins.append(min(times))
        medians.append(statistics.median(times))
        covered.append(share)
    size = calls[0][-1]
    return {"sequence": sequence, "atlas": f"{size} x {size}", "faces": f"{len(calls[0][1])} / {len(calls[0][5])}",
            "frames": len(calls), "min": statistics.median(mins), "median": statistics.median(medians),
            "covered": statistics.median(covered)}


def run(args: list[str]) -> tuple[float, float]:
    """(wall seconds, CPU seconds) of one ``dynmesh`` process; raises if it fails."""
    before = os.times()
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "dynmesh", *args, "-q"], check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    after = os.times()
    return wall, (after.children_user - before.children_user) + (after.children_system - before.children_system)


def time_commands(runs: int) -> list[dict]:
    """Textured and untextured encodes of the command sequence's first frames, in turn."""
    import dynmesh

    compileall.compile_dir(Path(dynmesh.__file__).parent, quiet=1)
    source = str(SHARED_DATA / COMMAND_SEQUENCE / "*.obj")
    with tempfile.TemporaryDirectory() as tmp:
        encode = ["encode", source, "--count", str(COMMAND_FRAMES), "-o"]
        variants = {"textured": encode + [f"{tmp}/textured.dmsh"], "--no-texture": encode + [f"{tmp}/plain.dmsh", "--no-texture"]}
        times = {k: [] for k in variants}
        for _ in range(runs):
            for kind, args in variants.items():
                times[kind].append(run(args))
    rows = []
    for kind, samples in times.items():
        walls = [w for w, _ in samples]
        rows.append({"command": f"encode, {kind}", "wall_min": min(walls), "wall": statistics.median(walls),
                     "cpu": statistics.median(c for _, c in samples), "ratio": ""})
    rows[0]["ratio"] = f"{rows[0]['wall'] / rows[1]['wall']:.2f} (wall), {rows[0]['cpu'] / rows[1]['cpu']:.2f} (CPU)"
    return rows


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--frames", type=int, default=6, help="first frames of each sequence, at most (default 6)")
    p.add_argument("--repeat", type=int, default=5, help="transfers of each frame (default 5)")
    p.add_argument("--runs", type=int, default=5, help="runs of each encode command (default 5)")
    p.add_argument("--no-commands", action="store_true", help="time the transfer only")
    p.add_argument("--print-only", action="store_true", help="print the tables, do not write docs/benchmarks.md")
    a = p.parse_args()
    present = [s for s in SEQUENCES if (SHARED_DATA / s).is_dir()]
    missing = [s for s in SEQUENCES if s not in present]
    if missing:
        print(f"skipped (no data under {SHARED_DATA}): {', '.join(missing)}", file=sys.stderr)
    if not present:
        return 1
    rows = [time_transfer(s, a.frames, a.repeat) for s in present]
    table = markdown_table(rows, TRANSFER_COLUMNS)
    print(table)
    commands = None
    if not a.no_commands and COMMAND_SEQUENCE in present:
        commands = markdown_table(time_commands(a.runs), COMMAND_COLUMNS)
        print(commands)
    if a.print_only:
        return 0
    body = (f"`_core.transfer_texture` (transfer and padding, as the encoder calls it) on the first {a.frames} frames "
            f"(or all, if fewer) of each textured capture, its inputs made as the encoder makes them with the default options; "
            f"{a.repeat} calls per frame on {os.cpu_count()} cores. Per frame its minimum and median seconds, then "
            "their median over the frames." + (f" Skipped for want of data: {', '.join(missing)}." if missing else "")
            + "\n\n" + table)
    if commands:
        body += (f"\n\n`dynmesh encode` of the first {COMMAND_FRAMES} frames of {COMMAND_SEQUENCE} with textures and with "
                 f"`--no-texture`, other options at their defaults, as whole processes, the two in turn, {a.runs} runs "
                 "of each; CPU is user + system time of the process and its threads. The machine is shared: quote "
                 "the medians and the ratios.\n\n" + commands)
    write_section("texture transfer", body)
    return 0


if __name__ == "__main__":
    sys.exit(main())
