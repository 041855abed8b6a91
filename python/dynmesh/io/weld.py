"""One vertex per position again, for formats that split vertices at UV seams.

glTF and Draco keep one index list for every attribute, so a vertex with two UVs (on a
chart seam) is stored twice, and a mesh read as it is would fall apart into its UV charts.
``weld`` merges vertices whose positions are equal (bit for bit, after the file's own
rounding), keeping the UVs in their own list with per-corner indices, as OBJ does and as
:class:`~dynmesh.mesh.Mesh` holds them.
"""

from __future__ import annotations

import numpy as np

from ..mesh import Mesh


def first_occurrence_unique(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(distinct rows in the order they first appear, index of each row's distinct row).

    Rows are compared by value: -0.0 equals 0.0."""
    rows = np.ascontiguousarray(rows, np.float64) + 0.0  # -0.0 + 0.0 is 0.0: one key for both
    if len(rows) == 0:
        return rows, np.zeros(0, np.int64)
    keys = rows.view(np.dtype((np.void, rows.dtype.itemsize * rows.shape[1]))).ravel()
    _, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
    # np.unique orders by key; renumber the distinct rows by first appearance instead, so a
    # file whose vertices are already distinct keeps its vertex order.
    order = np.argsort(first, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return rows[first[order]], rank[inverse.ravel()].astype(np.int64)


def weld(positions: np.ndarray, faces: np.ndarray, uvs: np.ndarray | None = None, **mesh_fields) -> Mesh:
    """A Mesh of ``positions`` and ``faces`` (and per-vertex ``uvs``) with equal positions
    merged into one vertex and equal UVs into one UV; ``mesh_fields`` go to the Mesh."""
    faces = np.asarray(faces, np.int64).reshape(-1, 3)
    unique_positions, vertex = first_occurrence_unique(positions)
    if uvs is None:
        return Mesh(unique_positions, vertex[faces], **mesh_fields)
    unique_uvs, uv = first_occurrence_unique(uvs)
    return Mesh(unique_positions, vertex[faces], unique_uvs, uv[faces], **mesh_fields)
