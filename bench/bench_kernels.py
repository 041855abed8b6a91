"""Speed of the geometry kernels (BVH, local frames, displacement fit) and the snapshot renderer.

Runs the Rust example ``core/examples/kernel_timings.rs`` (release build) ``--repeat``
times and reports, per measurement, the median wall and CPU milliseconds per run over the
repeats (CPU: the on-CPU time of all the example's threads, which says what the code costs
when other work on a shared machine inflates the wall time):

- ``bvh``: ``Bvh::new`` on a bumpy 40k-triangle sphere (mean of 10 builds), 160k
  closest-point and 160k line queries from points around it, in parallel;
- ``fit``: a 5k-triangle base on a bumpy 40k-triangle sphere subdivided flat three times
  (164k vertices): the target's ``Bvh::new``, ``local_frames`` and ``fit_displacements``
  (normal only), with the vertices' distance to the target before and after the fit;
- ``render``: a textured wavy sheet of a million faces at 1024 x 1024 (mean of 5 frames).

    python bench/bench_kernels.py [--only bvh fit render] [--repeat 3] [--print-only]
"""

from __future__ import annotations

import argparse

from common import example_table, write_section

MEASUREMENTS = ["bvh", "fit", "render"]
COLUMNS = [("kernel", "measurement", "s"), ("size", "size", "s"), ("threads", "threads", "d"),
           ("wall_ms", "wall ms", ".1f"), ("cpu_ms", "CPU ms", ".1f"), ("note", "note", "s")]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", nargs="+", choices=MEASUREMENTS, default=MEASUREMENTS)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--print-only", action="store_true", help="do not write docs/benchmarks.md")
    a = ap.parse_args()
    table, load = example_table("kernel_timings", a.only, ("internals",), ["wall_ms", "cpu_ms"], COLUMNS, a.repeat)
    if not a.print_only:
        write_section("geometry kernels and renderer", (
            f"`core/examples/kernel_timings.rs` ({', '.join(a.only)}; release build), median of {a.repeat} runs of the "
            "example; milliseconds per run of the measurement (the BVH build: mean of 10 builds; the render: mean of 5 "
            "frames after one untimed). Synthetic meshes of the codec's sizes: a 40k-triangle bumpy sphere as the BVH's "
            "and the fit's target, 160k query points at radius 480 to 520 around its radius of 500, a 5k-triangle base "
            "subdivided flat three times (164k vertices) fitted onto it, and a textured wavy sheet of a million faces. CPU "
            f"is the on-CPU time of all the example's threads. The machine is shared (load average {load:.1f} at the start): "
            "wall times vary with its load; for the parallel kernels, a wall time near the CPU time means the threads got one core between them.\n\n"
            + table))


if __name__ == "__main__":
    main()
