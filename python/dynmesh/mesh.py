"""The mesh value that the Python surface takes and returns: plain numpy arrays."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


@dataclass
class Mesh:
    """A triangle mesh.

    positions: (N, 3) float64 vertex positions.
    faces:     (M, 3) int64 vertex indices per triangle, counter-clockwise.
    uvs:       optional (K, 2) float64 texture coordinates.
    uv_faces:  optional (M, 3) int64 indices into ``uvs`` per triangle corner; OBJ keeps
               positions and UVs in separate index lists and so does this class.
    texture:   optional path of the texture image (from the OBJ's material).
    image:     optional (H, W, 3) uint8 RGB texture pixels, rows from the top (a decoded
               frame's texture; writers save it as PNG beside the mesh).
    """

    positions: np.ndarray
    faces: np.ndarray
    uvs: np.ndarray | None = None
    uv_faces: np.ndarray | None = None
    texture: Path | None = None
    image: np.ndarray | None = None
    metadata: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.positions = np.ascontiguousarray(self.positions, dtype=np.float64).reshape(-1, 3)
        self.faces = np.ascontiguousarray(self.faces, dtype=np.int64).reshape(-1, 3)
        if self.uvs is not None:
            self.uvs = np.ascontiguousarray(self.uvs, dtype=np.float64).reshape(-1, 2)
        if self.uv_faces is not None:
            self.uv_faces = np.ascontiguousarray(self.uv_faces, dtype=np.int64).reshape(-1, 3)

    @property
    def vertex_count(self) -> int:
        return len(self.positions)

    @property
    def face_count(self) -> int:
        return len(self.faces)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(min, max) corners of the axis-aligned bounding box."""
        return self.positions.min(axis=0), self.positions.max(axis=0)
