"""Fingerprints of the encoder's output: the sha256 of the default stream of every shared
sequence at three QPs, one line each, for checking that a change leaves every byte alone.

    python tools/stream_hashes.py > before.txt     # on the old code
    python tools/stream_hashes.py | diff before.txt -   # on the new: no output, no change

Frames: the first ``--frames`` (4) of each sequence in ``../shared/data`` (textured ones
coded with their texture, as the encoder's defaults do). Exits 1 when that folder is absent.
"""

from __future__ import annotations

import argparse
import hashlib
import sys
from pathlib import Path

import dynmesh
from dynmesh import api

SHARED_DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--frames", type=int, default=4)
    p.add_argument("--qp", type=int, nargs="+", default=[20, 28, 36])
    a = p.parse_args()
    if not SHARED_DATA.is_dir():
        print(f"no shared data at {SHARED_DATA}", file=sys.stderr)
        return 1
    for seq in sorted(d.name for d in SHARED_DATA.iterdir() if d.is_dir()):
        frames = [dynmesh.read_mesh(f) for f in sorted((SHARED_DATA / seq).glob("*.obj"))[:a.frames]]
        for qp in a.qp:
            data = api.encode_frames(frames, qp=qp).data
            print(seq, qp, len(data), hashlib.sha256(data).hexdigest()[:16], flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
