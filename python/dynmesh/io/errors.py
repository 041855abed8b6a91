"""The error of a mesh file that cannot be read or a mesh that cannot be written, which every
reader (``meshio``, ``gltf_read``, ``draco``, ``image``) raises."""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["MeshError"]


class MeshError(ValueError):
    """A mesh file that cannot be read or a mesh that cannot be written.

    ``path`` is the file, ``line`` the 1-based line number or None where no line
    applies (binary data, missing file).
    """

    def __init__(self, path: str | os.PathLike, message: str, line: int | None = None):
        self.path = Path(path)
        self.line = line
        self.reason = message
        where = f"{path}: line {line}" if line is not None else f"{path}"
        super().__init__(f"{where}: {message}")

    def __reduce__(self):
        # The default would call MeshError(str(self)); keep it picklable across processes.
        return type(self), (self.path, self.reason, self.line)
