"""Reading Draco frames (``.drc``, as Google's draco_encoder or DracoPy writes them) into a
:class:`~dynmesh.mesh.Mesh`, through DracoPy.

Draco, like glTF, stores one index list for every attribute, so vertices are split where
they carry several UVs; ``weld`` merges equal positions back into one vertex, UVs keeping
their own indices. UVs (the TEX_COORD attribute, when there is one) are taken as they are,
with V up as in OBJ, which is what draco_encoder keeps from an OBJ or PLY. A .drc names no
texture image, so its frames are read untextured (with UVs when it has them).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..mesh import Mesh
from .errors import MeshError
from .weld import weld

__all__ = ["read_draco", "dracopy_or_error"]


def dracopy_or_error(path: Path, what: str = "Draco (.drc) files"):
    """The DracoPy module, or a MeshError saying how to install it."""
    try:
        import DracoPy
    except ImportError:
        raise MeshError(path, f"reading {what} needs DracoPy, which is not installed; install it with "
                              "`pip install DracoPy` (a plain `pip install dynmesh` brings it)") from None
    return DracoPy


def read_draco(data: bytes, path: Path, notes: list[str]) -> Mesh:
    """The triangle mesh of a Draco file: positions, faces, and UVs when it has them. Raises
    MeshError for a file DracoPy cannot decode and for a point cloud (no faces)."""
    DracoPy = dracopy_or_error(path)
    try:
        decoded = DracoPy.decode(data)
    except MemoryError:
        raise
    except Exception as e:  # DracoPy raises its own exception types (FileTypeException, ...)
        raise MeshError(path, f"not a readable Draco file ({e}): it is truncated, corrupt or not Draco; "
                              "encode the frame again (draco_encoder -i frame.obj -o frame.drc)") from None
    faces = getattr(decoded, "faces", None)
    points = np.asarray(decoded.points, np.float64).reshape(-1, 3)
    if faces is None or len(faces) == 0:
        raise MeshError(path, f"no faces: the Draco file holds a point cloud of {len(points)} points, not a "
                              "triangle mesh; encode the mesh with its faces")
    faces = np.asarray(faces, np.int64).reshape(-1, 3)
    if faces.min() < 0 or faces.max() >= len(points):
        raise MeshError(path, f"corrupt Draco file: a face index is past its {len(points)} points; encode the "
                              "frame again")
    if not np.isfinite(points).all():
        raise MeshError(path, "the Draco file has non-finite positions (NaN or infinity); encode the frame again")
    uvs = getattr(decoded, "tex_coord", None)
    if uvs is not None and len(uvs):
        uvs = np.asarray(uvs, np.float64)
        if uvs.ndim != 2 or uvs.shape[1] < 2 or len(uvs) != len(points) or not np.isfinite(uvs).all():
            notes.append("its texture coordinates are not two finite numbers per point; they are ignored")
            uvs = None
        else:
            uvs = uvs[:, :2]
    else:
        uvs = None
    return weld(points, faces, uvs)
