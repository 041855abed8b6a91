"""Our closest-point BVH and QEM decimation against parry3d and meshoptimizer (issue 48: keep
ours only where the library is not as fast and as good).

Runs the Rust example ``core/examples/library_comparison.rs`` (release build, feature
``compare-libraries``) ``--repeat`` times and reports the median milliseconds of each
measurement, with the example's note (how far the answers differ, how far each decimation
lies from its input):

- ``bvh build`` and ``closest point``: a bumpy 40k-triangle sphere, 160k queries in parallel;
- ``qem decimation``: the first frame of dancer and of basketball_player (``../shared/data``;
  skipped when absent) to 6 % of its faces, the base ratio at the default QP; each result's
  distance to the input as decimated, and refitted and subdivided as the codec uses it.

    python bench/bench_libraries.py [--repeat 3] [--print-only]
"""

from __future__ import annotations

import argparse

from common import SHARED_DATA, example_table, write_section

COLUMNS = [("measurement", "measurement", "s"), ("size", "size", "s"), ("implementation", "implementation", "s"),
           ("ms", "median ms", ".1f"), ("note", "note", "s")]
CAPTURES = ["dancer", "basketball_player"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--print-only", action="store_true", help="do not write docs/benchmarks.md")
    a = ap.parse_args()
    meshes = [sorted((SHARED_DATA / c).glob("*.obj"))[0] for c in CAPTURES if (SHARED_DATA / c).is_dir()]
    table, load = example_table("library_comparison", meshes, ("compare-libraries",), ["ms"], COLUMNS, a.repeat)
    if not a.print_only:
        write_section("our kernels against libraries", (
            f"`core/examples/library_comparison.rs` (release build, feature `compare-libraries`), median of {a.repeat} "
            "runs. `bvh`: parry3d-f64 0.17's `TriMesh` (its QBVH) and `project_local_point` against `geom::bvh::Bvh` on a "
            "bumpy 40k-triangle sphere, 160k closest-point queries in parallel on the rayon pool. `qem`: meshoptimizer 0.4's "
            "`simplify` (target error unbounded, so that it reaches the face count) against `base::decimate` on the first "
            f"frame of {', '.join(CAPTURES)} (`../shared/data`), to 6 % of the faces; distance: RMS of the larger direction's "
            "area-weighted squared distance at face centroids (as the encoder's decision measures it), in units of the "
            "input box's largest side, of the decimated mesh and of the surface the codec predicts from it (refitted by "
            "`base::refit`, subdivided midpoint, midpoint, Loop; before displacements). "
            f"The machine is shared (load average {load:.1f} at the start).\n\n" + table))


if __name__ == "__main__":
    main()
