"""Encode speed against the number of workers: 1 and 2 local processes, a 2-worker Ray cluster.

The first ``--frames`` frames of a shared sequence (horse_gallop has 48) are encoded
with ``--intra-period`` frames per group, so that there are groups to share out:

- whole ``dynmesh encode`` processes with ``--jobs 1``, ``--jobs 1`` on one thread
  (``RAYON_NUM_THREADS=1``) and ``--jobs 2`` (Python start-up and the first pass over the
  files included: what a user waits for), alternated ``--repeat`` times in one run so that
  all see the same load, and the least time 2 processes can take on 2 cores given the CPU
  seconds ``--jobs 1`` spends;
- in this process, ``dynmesh.parallel.encode_to_file`` on a local Ray cluster of 2 CPUs
  started here (``ray.init(num_cpus=2)``; its start and the first run, which starts the
  workers, are not timed), beside the sequential encoder and 2 local processes in the same
  process, for the capacity figures: the compute per group (the sum of the core's
  per-frame seconds), the driver's CPU seconds per group, and the seconds per group that a
  worker spends not encoding (scheduling, moving frame paths and pieces, reading files).
Every stream is checked to be the sequential one, byte for byte.

    python bench/bench_scaling.py [--sequence horse_gallop] [--frames 32] [--intra-period 8] [--repeat 2]
"""

from __future__ import annotations

import argparse
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from dynmesh import api, parallel
from dynmesh.io import resolve_sequence

from common import SHARED_DATA, check_data, markdown_table, write_section

COLUMNS = [("how", "encoder", "s"), ("workers", "workers", "d"), ("seconds", "seconds", ".2f"),
           ("fps", "frames/s", ".2f"), ("speedup", "speed-up", ".2f"), ("efficiency", "efficiency", ".0%"),
           ("cores", "cores obtained", ".2f")]


def children_cpu() -> float:
    """CPU seconds of this process's finished (joined) child processes."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def command_seconds(args: list[str], env: dict | None = None) -> tuple[float, float]:
    """(wall seconds, CPU seconds of it and its children) of one ``dynmesh`` process, run
    with ``env`` added to this process's environment."""
    wall, cpu = time.perf_counter(), children_cpu()
    subprocess.run([sys.executable, "-m", "dynmesh", *args], check=True, stdout=subprocess.DEVNULL,
                   env={**os.environ, **(env or {})})
    return time.perf_counter() - wall, children_cpu() - cpu


def cli_rows(seq: Path, a, out: Path) -> tuple[list[dict], float, float]:
    """Rows for ``dynmesh encode --jobs 1``, ``--jobs 1`` on one thread and ``--jobs 2``, the
    ratio of the ``--jobs 2`` and ``--jobs 1`` times, and the least that ratio can be here."""
    one_thread = {"RAYON_NUM_THREADS": "1"}
    kinds = {"1": ("1", None), "1t": ("1", one_thread), "2": ("2", None)}
    runs = {kind: [] for kind in kinds}
    for _ in range(a.repeat):
        for kind, (jobs, env) in kinds.items():
            runs[kind].append(command_seconds(["encode", str(seq), "--count", str(a.frames), "--intra-period",
                                               str(a.intra_period), "--jobs", jobs, "-o", str(out / f"cli{kind}.dmsh"),
                                               "-q"], env))
    if len({(out / f"cli{kind}.dmsh").read_bytes() for kind in kinds}) != 1:
        raise SystemExit("--jobs 2 or one thread wrote another stream than --jobs 1")
    (one, cpu1), (thread, cpu1t), (two, cpu2) = (min(runs[kind]) for kind in kinds)
    print(f"dynmesh encode (wall, CPU s): {runs}", flush=True)
    how = "`dynmesh encode --jobs N`"
    # Two processes cannot use more than the 2 cores: at best they do --jobs 1's CPU work in
    # half its CPU seconds of wall time.
    floor = cpu1 / len(os.sched_getaffinity(0)) / one
    rows = [row(how, 1, one, one, a.frames, cpu1), row(f"{how}, one thread (`RAYON_NUM_THREADS=1`)", 1, thread, one,
                                                       a.frames, cpu1t), row(how, 2, two, one, a.frames, cpu2)]
    return rows, two / one, floor


def row(how: str, workers: int, seconds: float, one: float, frames: int, cpu: float) -> dict:
    """A table row: ``seconds`` (``cpu`` CPU seconds) with ``workers``, against ``one`` with one worker."""
    return {"how": how, "workers": workers, "seconds": seconds, "fps": frames / seconds, "speedup": one / seconds,
            "efficiency": one / seconds / workers, "cores": cpu / seconds}


def timed(run) -> tuple[float, float, api.EncodeResult, float]:
    """(wall seconds, this process's CPU seconds, result, CPU seconds of this process and
    its local workers, which the pool has joined when ``run`` returns) of ``run()``."""
    wall, cpu, cpu_children = time.perf_counter(), time.process_time(), children_cpu()
    result = run()
    driver = time.process_time() - cpu
    return time.perf_counter() - wall, driver, result, driver + children_cpu() - cpu_children


def in_process_runs(paths: list[Path], a, out: Path) -> dict:
    """Wall and driver CPU seconds, and the result, of the sequential encoder, 2 local
    processes and the 2-CPU Ray cluster (started here), each the best of ``--repeat``."""
    import ray

    sequence = (len(paths), *api.sequence_bounds(parallel.read_again(p) for p in paths))
    options = dict(intra_period=a.intra_period)

    def sequential():
        result = api.encode_frames((parallel.read_again(p) for p in paths), sequence=sequence, texture=False, **options)
        api.write_bytes_atomic(out / "seq.dmsh", result.data)
        return result

    def to_file(name, **how):
        return lambda: parallel.encode_to_file(out / name, paths, sequence=sequence, texture=False, **how, **options)

    ray.init(num_cpus=2, logging_level="WARNING")
    try:
        to_file("ray.dmsh", ray="auto")()  # starts the workers
        runs = {"sequential": sequential, "2 processes": to_file("jobs2.dmsh", jobs=2),
                "Ray, 2 workers": to_file("ray.dmsh", ray="auto")}
        measured = {name: min((timed(run) for _ in range(a.repeat)), key=lambda m: m[0]) for name, run in runs.items()}
    finally:
        ray.shutdown()
    reference = (out / "seq.dmsh").read_bytes()
    if any((out / f).read_bytes() != reference for f in ("jobs2.dmsh", "ray.dmsh")):
        raise SystemExit("a parallel stream differs from the sequential one")
    for name, (wall, cpu, _, _) in measured.items():
        print(f"{name}: {wall:.2f} s, driver CPU {cpu:.2f} s", flush=True)
    return measured


def capacity(measured: dict, groups: int, frames: int, stream_bytes: int) -> str:
    """The paragraph on what a large cluster would give, from the measured figures."""
    compute = sum(f["seconds"] for f in measured["sequential"][2].frames) / groups
    wall, cpu, _, _ = measured["Ray, 2 workers"]
    driver = cpu / groups
    besides = max(0.0, (2 * wall) / groups - compute)  # worker seconds per group spent not encoding
    workers = 100 * 32
    fastest, slowest = workers / compute, workers / (compute + besides)
    bound = min(slowest, 1 / driver)
    return (
        f"Capacity. Measured here, per group of {frames // groups} frames: {compute:.2f} s of encoding (the core's "
        f"seconds in the sequential encoder); at most {besides:.2f} s of a Ray worker's time besides (scheduling, "
        "reading the files, returning the piece: 2 x wall / groups - encoding, an upper bound, as on a loaded "
        f"machine it is mostly time a worker waited for a core); {1000 * driver:.1f} ms of the driver's CPU "
        f"(submitting, receiving and writing {stream_bytes / groups / 1e3:.0f} kB of stream). A 100-node cluster of "
        f"32-core machines (3200 workers, groups as above) would encode {slowest:.0f} to {fastest:.0f} groups/s, and "
        f"one driver keeps up with about {1 / driver:.0f} groups/s: at least {bound:.0f} groups/s, "
        f"{bound * frames / groups:.0f} frames/s, for a stream growing by {bound * stream_bytes / groups / 1e6:.1f} "
        "MB/s, which any disk takes. The driver, not the cluster, is then the limit: longer groups (the default "
        "intra period is 32 frames) or one driver per sequence, or per stretch of a long take, keep the workers "
        "busy. A sequence never runs on more workers than it has groups: a 30 fps hour at the default period is "
        "3375 groups, one round on 3200 workers, so it takes about the time of two groups and the driver's time "
        "for all of them."
    )


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sequence", default="horse_gallop")
    ap.add_argument("--frames", type=int, default=32)
    ap.add_argument("--intra-period", type=int, default=8)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--no-write", action="store_true", help="print only; leave docs/benchmarks.md alone")
    a = ap.parse_args()
    if not check_data([a.sequence]):
        return 1
    seq = SHARED_DATA / a.sequence
    paths = resolve_sequence(str(seq), None, a.frames)
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        cli, ratio, floor = cli_rows(seq, a, Path(tmp))
        measured = in_process_runs(paths, a, Path(tmp))
        stream_bytes = (Path(tmp) / "seq.dmsh").stat().st_size
    groups = -(-len(paths) // a.intra_period)
    one = measured["sequential"][0]
    # The Ray workers are not this process's children: their CPU time is not counted (nan).
    rows = cli + [row(f"in one process, {name}", 1 if name == "sequential" else 2, m[0], one, len(paths),
                      math.nan if name.startswith("Ray") else m[3]) for name, m in measured.items()]
    body = (f"{a.sequence}, the first {len(paths)} frames, `--intra-period {a.intra_period}` ({groups} groups), other "
            f"options at their defaults; every parallel stream is the sequential one byte for byte. Best of "
            f"{a.repeat} runs each, alternated; 1-minute load average {load:.1f} on 2 cores when the run started "
            "(the machine is shared: ratios within one run hold, absolute times +-20 %). Speed-up and efficiency "
            "are against one process of the same kind. The sequential encoder runs the core's thread pool over "
            "both cores; each of N local worker processes a pool of cores / N + 1 threads (at most the cores), each Ray worker one thread "
            "(one CPU per task). Cores obtained: CPU seconds of the "
            "encoder's processes over wall seconds, the share of the 2 cores the encode got; the kernel shares "
            "the CPU between sessions (autogroup), so on a machine busy with other sessions a second process "
            f"gets no more CPU, only a share of the same.\n\n`--jobs 2` takes {ratio:.2f} of the time of `--jobs 1`. "
            f"The sequential encoder already obtains {cli[0]['cores']:.2f} of the 2 cores, so 2 processes, doing the same "
            f"CPU work, can take no less than {floor:.2f} of its time here (its CPU seconds over 2, over its wall "
            f"seconds); on one thread it takes {cli[1]['seconds'] / cli[0]['seconds']:.2f} of --jobs 1's time, and "
            f"`--jobs 2` is {cli[1]['seconds'] / cli[2]['seconds'] / 2:.0%} efficient against it.\n\n"
            + markdown_table(rows, COLUMNS) + "\n\n" + capacity(measured, groups, len(paths), stream_bytes))
    print(body)
    if not a.no_write:
        write_section("scaling over workers", body)
    return 0


if __name__ == "__main__":
    sys.exit(main())
