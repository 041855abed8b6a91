"""Rigid parts in contact, re-meshed as ONE surface: two meshing gears whose teeth fuse.

Two toothed discs (a 2D tooth profile extruded to a slab) turn rigidly in opposite directions
with their teeth meshing, set so close that the teeth overlap: the solid is the union of the
two gears, and every frame polygonizes its implicit field anew (marching tetrahedra, as
``metaballs.polygonize``), as a capture that merges whatever touches does. The result is one
connected closed surface per frame whose parts move differently (the hard case for an inter
coder that aligns each connected component rigidly), with a grid resolution that changes from
frame to frame so that vertex count and connectivity differ in every frame. A positive ``gap``
parts the gears: the same generator then gives two components per frame. Needs only numpy.
"""

from __future__ import annotations

import numpy as np

from ..mesh import Mesh
from .metaballs import polygonize

__all__ = ["fused_gear_sequence", "smooth_max"]

# (teeth, pitch radius) of each gear: the same tooth pitch (radius / teeth), so that the teeth
# mesh at the pitch circles when the gears turn at speeds inversely proportional to the teeth.
_GEARS = ((10, 0.56), (8, 0.448))
_TOOTH, _HALF_THICKNESS = 0.07, 0.16
# Teeth narrower than the gaps (where cos > 0.3: 40 % of the pitch), so that meshing teeth keep
# some backlash and a positive gap parts the gears at every angle.
_NARROW = 0.3
# Fillet radius of the smooth union: the fused teeth meet in a small rounded seam, not a crease.
_BLEND = 0.02
# Space left around the gears inside the grid, whose boundary polygonize treats as outside.
_MARGIN = 0.1


def fused_gear_sequence(frames: int = 10, turn_degrees: float = 7.0, resolution: int = 52,
                        gap: float = -0.06) -> list[Mesh]:
    """``frames`` closed, outward-oriented meshes of two meshing gears, the 10-tooth one turned
    ``turn_degrees`` more in each frame and the 8-tooth one 10/8 as far the other way.

    ``gap`` is the clearance between a tooth tip and the root of the other gear on the line of
    centres (0: the pitch circles touch). Negative, the teeth overlap and every frame is one
    connected surface; above about 0.02 the solids are apart at every angle, and the frames
    are two components once the gap also spans two grid cells (0.08 at the default
    resolution). Frame f is polygonized on a cubic grid of ``resolution + f % 3`` cells per
    axis around the pair (side 2.3 at the default gap, about 12k vertices a frame at the
    defaults), so vertex count and connectivity change every frame. The gears come back to
    where they started after 36 degrees of the first one's turn (five teeth of the second);
    the default 7 degrees repeats no frame within 36. Deterministic.
    """
    if frames < 1 or resolution < 16:
        raise ValueError("need frames >= 1 and resolution >= 16")
    return [_frame(np.radians(turn_degrees) * f, resolution + f % 3, gap) for f in range(frames)]


def _frame(angle: float, resolution: int, gap: float) -> Mesh:
    (n1, r1), (n2, r2) = _GEARS
    distance = r1 + r2 + gap
    half_span = (distance + r1 + r2) / 2 + _TOOTH
    c1, c2 = r1 + _TOOTH - half_span, half_span - r2 - _TOOTH  # the pair centred on the origin
    axis = np.linspace(-1.0, 1.0, resolution + 1) * (half_span + _MARGIN)
    x, y, z = np.meshgrid(axis, axis, axis, indexing="ij", sparse=True)
    # The second gear turns the other way, n1 / n2 as fast; the offset puts one of its gaps in
    # front of a tooth of the first on the line of centres.
    offset = np.pi - np.pi / n2
    slab = _HALF_THICKNESS - np.abs(z)
    g1 = np.minimum(_profile(x - c1, y, n1, r1, angle), slab)
    g2 = np.minimum(_profile(x - c2, y, n2, r2, offset - angle * n1 / n2), slab)
    return polygonize(smooth_max(g1, g2, _BLEND), axis, iso=0.0)


def _profile(x: np.ndarray, y: np.ndarray, teeth: int, radius: float, angle: float) -> np.ndarray:
    """Approximate signed distance (positive inside) to a toothed outline turned by ``angle``.

    The outline is a radius modulated by a squared-off cosine; dividing by the gradient's norm
    keeps the field's slope near 1 on the steep tooth flanks, so linear interpolation along grid
    edges places vertices there as accurately as on the flat tips.
    """
    rho = np.hypot(x, y)
    wave = teeth * (np.arctan2(y, x) - angle)
    shape = 3.0 * (np.cos(wave) - _NARROW)
    outline = radius + _TOOTH * np.tanh(shape)
    slope = -_TOOTH * 3.0 * teeth * np.sin(wave) / np.cosh(shape) ** 2  # d outline / d theta
    # Far inside, the field only has to stay positive: near the centre the flank slope over rho
    # would press it towards 0 and dent the caps there.
    return (outline - rho) / np.sqrt(1.0 + (slope / np.maximum(rho, radius / 2)) ** 2)


def smooth_max(a: np.ndarray, b: np.ndarray, k: float) -> np.ndarray:
    """Polynomial smooth maximum (union of solids): max(a, b) where they differ by more than k."""
    h = np.clip(0.5 + 0.5 * (a - b) / k, 0.0, 1.0)
    return b + (a - b) * h + k * h * (1.0 - h)
