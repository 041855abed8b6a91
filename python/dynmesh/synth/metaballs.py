"""A built-in synthetic mesh sequence whose topology changes from frame to frame.

Three Gaussian metaballs move on smooth paths inside the box [-1, 1]^3: two large
ones approach, merge into one body and separate again while a small one drifts
around them. Each frame is polygonized independently by marching tetrahedra, so
vertex count and connectivity differ in every frame, and the number of connected
components changes as the blobs merge and split. Needs only numpy.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..io import write_mesh
from ..mesh import Mesh

__all__ = ["polygonize", "synth_sequence", "write_sequence"]

ISO = 0.5
# Kuhn subdivision of a cube into 6 tetrahedra around the diagonal 0-7; corner c is
# (c & 1, c >> 1 & 1, c >> 2 & 1). Every cube uses the same diagonal, so the face
# diagonals of neighbouring cubes agree and the tetrahedra form one conforming mesh.
_TETS = np.array([[0, 1, 3, 7], [0, 2, 3, 7], [0, 2, 6, 7], [0, 4, 6, 7], [0, 4, 5, 7], [0, 1, 5, 7]])
_CORNERS = np.array([[c & 1, c >> 1 & 1, c >> 2 & 1] for c in range(8)])
# Surface triangles per case, as edges (pairs of tet corners) once the tet's corners
# are ordered inside-first: one inside corner, three inside corners, two (a quad).
_CASE_EDGES = {
    1: [np.array([(0, 1), (0, 2), (0, 3)])],
    3: [np.array([(3, 0), (3, 1), (3, 2)])],
    2: [np.array([(0, 2), (0, 3), (1, 3)]), np.array([(0, 2), (1, 3), (1, 2)])],
}


def synth_sequence(frames: int = 8, resolution: int = 48, seed: int = 0, cycle: float = 1.0) -> list[Mesh]:
    """``frames`` closed, consistently outward-oriented triangle meshes of merging blobs.

    Every frame is watertight (each edge shared by exactly two triangles) and lies in
    [-1, 1]^3; vertex count and connectivity change every frame. The frames cover the
    first ``cycle`` (in (0, 1]) of the blobs' motion, over which the whole sequence
    (``cycle`` 1) has two blobs merge into one and split again; a smaller share moves
    less from frame to frame, as a capture at a higher frame rate does. ``resolution`` is
    the number of grid cells per axis; the result is a deterministic function of the
    arguments.
    """
    if frames < 1 or resolution < 4:
        raise ValueError("need frames >= 1 and resolution >= 4")
    if not 0.0 < cycle <= 1.0:
        raise ValueError(f"cycle must be in (0, 1], got {cycle}")
    params = _path_parameters(np.random.default_rng(seed))
    times = np.linspace(0.0, cycle, frames) if frames > 1 else np.zeros(1)
    axis = np.linspace(-1.0, 1.0, resolution + 1)
    return [polygonize(_field(axis, *_blobs(t, params)), axis) for t in times]


def write_sequence(meshes: list[Mesh], outdir: str | os.PathLike, fmt: str = "obj") -> list[Path]:
    """Write ``meshes`` as ``outdir/frame_0000.<fmt>``, ... (fmt "obj" or "ply"); returns the paths."""
    if fmt not in ("obj", "ply"):
        raise ValueError(f"fmt must be 'obj' or 'ply', got {fmt!r}")
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    paths = [outdir / f"frame_{i:04d}.{fmt}" for i in range(len(meshes))]
    for path, mesh in zip(paths, meshes):
        write_mesh(path, mesh)
    return paths


def _path_parameters(rng: np.random.Generator) -> dict:
    """The seed's small variations: orientation, phases and sizes of the blob paths."""
    return {
        "heading": rng.uniform(0, 2 * np.pi),
        "tilt": rng.uniform(-0.3, 0.3),
        "phase": rng.uniform(0, 2 * np.pi),
        "radii": np.array([0.32, 0.32, 0.22]) * rng.uniform(0.95, 1.05, 3),
    }


def _blobs(t: float, p: dict) -> tuple[np.ndarray, np.ndarray]:
    """(centres (3, 3), radii (3,)) at time t in [0, 1]."""
    # Separation 1.2 -> 0.3 -> 1.2: the pair is apart at both ends and merged mid-way
    # (two equal Gaussians of radius r join below a separation of about 2.35 r).
    separation = 0.75 + 0.45 * np.cos(2 * np.pi * t)
    heading = p["heading"] + 0.9 * t
    axis = np.array([np.cos(heading), np.sin(heading), p["tilt"]])
    axis /= np.linalg.norm(axis)
    wobble = 0.08 * np.array([0.0, 0.0, np.sin(2 * np.pi * t + p["phase"])])
    angle = p["phase"] + 2 * np.pi * 0.8 * t
    small = np.array([0.55 * np.cos(angle), 0.55 * np.sin(angle), 0.45 * np.cos(np.pi * t)])
    centres = np.stack([-0.5 * separation * axis + wobble, 0.5 * separation * axis - wobble, small])
    breathing = 1 + 0.04 * np.sin(2 * np.pi * t + np.array([0.0, 2.0, 4.0]))
    return centres, p["radii"] * breathing


def _field(axis: np.ndarray, centres: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Sum of Gaussians on the grid axis^3; separable, so one outer product per blob."""
    field = np.zeros((len(axis),) * 3)
    for (cx, cy, cz), r in zip(centres, radii):
        ex, ey, ez = (np.exp(-((axis - c) ** 2) / r**2) for c in (cx, cy, cz))
        field += ex[:, None, None] * ey[None, :, None] * ez[None, None, :]
    return field


def polygonize(field: np.ndarray, axis: np.ndarray, iso: float = ISO) -> Mesh:
    """Closed surface {field = iso} of a cubic grid (field[i, j, k] at axis[i], axis[j], axis[k]).

    Marching tetrahedra: inside is field > iso; the grid boundary is treated as outside
    so the surface is always closed. Triangles face outward (towards lower field).
    """
    values = field - iso
    values[[0, -1], :, :] = values[:, [0, -1], :] = values[:, :, [0, -1]] = -1.0
    tets = _crossing_tets(values > 0)
    inside = values.reshape(-1)[tets] > 0
    order = np.argsort(~inside, axis=1, kind="stable")
    tets, n_inside = np.take_along_axis(tets, order, 1), inside.sum(axis=1)
    pieces = [(tets[n_inside == n], tri, n) for n, tris in _CASE_EDGES.items() for tri in tris]
    edges = np.concatenate([group[:, tri] for group, tri, _ in pieces])  # (F, 3 corners, 2 ends)
    owner = np.concatenate([group for group, _, _ in pieces])
    owner_inside = np.concatenate([np.full(len(group), n) for group, _, n in pieces])
    edges = _orient(edges, owner, owner_inside, axis)
    return _weld(edges, values.reshape(-1), axis)


def _crossing_tets(inside: np.ndarray) -> np.ndarray:
    """(T, 4) grid-point ids of the tetrahedra with corners on both sides of the surface."""
    n = inside.shape[0]
    corner_flags = [inside[dx : n - 1 + dx, dy : n - 1 + dy, dz : n - 1 + dz] for dx, dy, dz in _CORNERS]
    count = np.sum(corner_flags, axis=0)
    cells = np.argwhere((count > 0) & (count < 8))
    base = cells @ np.array([n * n, n, 1])
    corners = base[:, None] + _CORNERS @ np.array([n * n, n, 1])
    tets = corners[:, _TETS].reshape(-1, 4)
    n_in = inside.reshape(-1)[tets].sum(axis=1)
    return tets[(n_in > 0) & (n_in < 4)]


def _grid_points(ids: np.ndarray, axis: np.ndarray) -> np.ndarray:
    n = len(axis)
    return axis[np.stack([ids // (n * n), ids // n % n, ids % n], axis=-1)]


def _orient(edges: np.ndarray, tets: np.ndarray, n_inside: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Flip triangles whose normal points into the solid.

    Judged on edge midpoints rather than the interpolated vertices: the midpoint
    triangle is never degenerate and has the same winding as the real one.
    """
    mid = _grid_points(edges, axis).mean(axis=2)  # (F, 3 corners, 3)
    normal = np.cross(mid[:, 1] - mid[:, 0], mid[:, 2] - mid[:, 0])
    corners = _grid_points(tets, axis)
    is_in = (np.arange(4)[None, :] < n_inside[:, None])[..., None]  # corners are inside-first
    inside_centre = (corners * is_in).sum(1) / n_inside[:, None]
    outside_centre = (corners * ~is_in).sum(1) / (4 - n_inside)[:, None]
    flip = np.einsum("ij,ij->i", normal, outside_centre - inside_centre) < 0
    edges[flip] = edges[flip][:, [0, 2, 1]]
    return edges


def _weld(edges: np.ndarray, values: np.ndarray, axis: np.ndarray) -> Mesh:
    """One vertex per crossed grid edge, shared by every triangle that uses the edge."""
    a, b = edges.min(axis=2), edges.max(axis=2)
    keys, faces = np.unique(a * len(values) + b, return_inverse=True)
    a, b = keys // len(values), keys % len(values)
    t = values[a] / (values[a] - values[b])  # signs differ, so never 0/0
    pa, pb = _grid_points(a, axis), _grid_points(b, axis)
    return Mesh(pa + t[:, None] * (pb - pa), faces.reshape(-1, 3))
