"""Cloth sliding over a body, re-meshed as ONE surface: a loose wrinkled sleeve on an arm.

A capsule (the arm) stays still while a loose sleeve (a thick-walled tube with ring-shaped
wrinkles) slides along it. The sleeve hangs lower than the arm, so its inner side rests on the
arm's top along a strip, where the two fuse: every frame polygonizes the union of the two
implicit solids anew (marching tetrahedra, as ``metaballs.polygonize``) into one connected
closed surface (with a tunnel between the arm's underside and the sleeve). The sleeve's
material, its wrinkles and the seam where it touches the arm move along the arm while the
arm's own surface does not: surface sliding over surface, the case an inter coder
that follows the nearest surface point gets wrong. The grid resolution changes from frame to
frame, so vertex count and connectivity differ in every frame. Needs only numpy.
"""

from __future__ import annotations

import numpy as np

from ..mesh import Mesh
from .fused_gears import smooth_max
from .metaballs import polygonize

__all__ = ["cloth_sequence"]

# Arm: a capsule of this radius around the x axis between x = -0.7 and 0.7.
_ARM_RADIUS, _ARM_HALF_LENGTH = 0.3, 0.7
# Sleeve: wall thickness (two grid cells at the default resolution, so that the wall does not
# thin into holes at the wrinkles' troughs), length, and the wrinkles' wavelength and amplitude.
_WALL, _SLEEVE_HALF_LENGTH = 0.1, 0.4
_WRINKLE_LENGTH, _WRINKLE = 0.2, 0.015
# The sleeve hangs this much below the arm's axis; its inner side overlaps the arm's top by
# _CONTACT, so the two touch all along the sleeve.
_SAG, _CONTACT = 0.08, 0.05
_BLEND = 0.03
_EXTENT = 1.1


def cloth_sequence(frames: int = 10, slide: float = 0.03, resolution: int = 44, start: float = -0.25) -> list[Mesh]:
    """``frames`` closed, outward-oriented meshes of a sleeve sliding ``slide`` further along an
    arm (a capsule 2.0 long along x, of radius 0.3) in each frame.

    The sleeve (0.8 long) is centred at x = ``start`` in the first frame and must stay on the
    arm: ``start`` and the last frame's centre within [-0.6, 0.6]. Frame f is polygonized on a
    grid of ``resolution + f % 3`` cells per axis over [-1.1, 1.1]^3 (about 12k vertices a frame
    at the defaults). Every frame is one connected surface. Deterministic.
    """
    if frames < 1 or resolution < 32:
        raise ValueError("need frames >= 1 and resolution >= 32")
    centres = start + slide * np.arange(frames)
    if np.abs(centres).max() > 0.6 + 1e-9:
        raise ValueError(f"the sleeve leaves the arm: centres {centres.min():.2f} .. {centres.max():.2f} outside [-0.6, 0.6]")
    return [_frame(c, resolution + f % 3) for f, c in enumerate(centres)]


def _frame(centre: float, resolution: int) -> Mesh:
    axis = np.linspace(-_EXTENT, _EXTENT, resolution + 1)
    x, y, z = np.meshgrid(axis, axis, axis, indexing="ij", sparse=True)
    return polygonize(smooth_max(_arm(x, y, z), _sleeve(x - centre, y, z + _SAG), _BLEND), axis, iso=0.0)


def _arm(x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Signed distance (positive inside) to the capsule."""
    along = np.clip(x, -_ARM_HALF_LENGTH, _ARM_HALF_LENGTH)
    return _ARM_RADIUS - np.sqrt((x - along) ** 2 + y**2 + z**2)


def _sleeve(u: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Approximate signed distance to the sleeve, ``u`` along it from its centre: a tube wall
    with the wrinkles on its outer side, so that they travel with the sleeve, cut to its length.

    The inner side stays a plain cylinder: wrinkles there would touch the arm beside the
    contact strip and close off air pockets, each a component of its own."""
    rho = np.hypot(y, z)
    inner = _ARM_RADIUS + _SAG - _CONTACT
    outer = inner + _WALL + _WRINKLE * np.sin(2 * np.pi * u / _WRINKLE_LENGTH)
    return np.minimum(np.minimum(rho - inner, outer - rho), _SLEEVE_HALF_LENGTH - np.abs(u))
