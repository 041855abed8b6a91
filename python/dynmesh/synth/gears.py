"""A synthetic mechanical sequence: toothed gears turning rigidly, sampled anew each frame.

Each frame holds two closed toothed discs side by side that turn in opposite directions
by a fixed angle per frame, which may exceed the spacing of their teeth (the hard case
for nearest-neighbour matching: every vertex lies nearer a neighbouring tooth than its
own). As a capture would, every frame samples the surfaces at angles fixed in space and
with a ring size that changes from frame to frame, so vertex count and connectivity
change every frame and no vertex follows the material. Needs only numpy.
"""

from __future__ import annotations

import numpy as np

from ..mesh import Mesh

__all__ = ["gear_sequence"]

# (centre x, teeth, turning direction) of each gear.
_GEARS = ((-1.15, 12, 1.0), (1.15, 9, -1.0))
_RADIUS, _TOOTH, _HALF_THICKNESS = 1.0, 0.12, 0.2


def gear_sequence(frames: int = 8, turn_degrees: float = 40.0, samples: int = 144) -> list[Mesh]:
    """``frames`` meshes of two gears turned by ``turn_degrees`` more in each frame.

    The first gear has 12 teeth (30 degrees apart), the second 9, turning the other way.
    A frame samples each rim at ``samples + frame % 3`` angles, so consecutive frames
    differ in vertex count and connectivity. Closed and outward-oriented; deterministic.
    """
    if frames < 1 or samples < 24:
        raise ValueError("need frames >= 1 and samples >= 24")
    meshes = []
    for f in range(frames):
        parts = [_gear(x, teeth, np.radians(direction * turn_degrees * f), samples + f % 3) for x, teeth, direction in _GEARS]
        meshes.append(_joined(parts))
    return meshes


def _gear(x: float, teeth: int, angle: float, n: int) -> Mesh:
    """A toothed disc around (x, 0, 0), turned by ``angle``: rims at three heights, capped."""
    theta = np.arange(n) * (2 * np.pi / n)
    radius = _RADIUS + _TOOTH * np.tanh(3.0 * np.cos(teeth * (theta - angle)))
    heights = np.linspace(-_HALF_THICKNESS, _HALF_THICKNESS, 3)
    rims = [np.stack([x + radius * np.cos(theta), radius * np.sin(theta), np.full(n, z)], axis=1) for z in heights]
    centres = np.array([[x, 0.0, heights[0]], [x, 0.0, heights[-1]]])
    positions = np.concatenate(rims + [centres])
    i = np.arange(n)
    j = (i + 1) % n
    faces = []
    for level in range(len(heights) - 1):
        lo, hi = level * n, (level + 1) * n
        faces += [np.stack([lo + i, lo + j, hi + j], 1), np.stack([lo + i, hi + j, hi + i], 1)]
    bottom, top = 3 * n, 3 * n + 1
    faces += [np.stack([np.full(n, bottom), j, i], 1), np.stack([np.full(n, top), 2 * n + i, 2 * n + j], 1)]
    return Mesh(positions, np.concatenate(faces).astype(np.int64))


def _joined(parts: list[Mesh]) -> Mesh:
    offsets = np.cumsum([0] + [len(p.positions) for p in parts[:-1]])
    return Mesh(np.concatenate([p.positions for p in parts]), np.concatenate([p.faces + o for p, o in zip(parts, offsets)]))
