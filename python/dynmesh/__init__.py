"""dynmesh: a fast codec for dynamic 3D meshes with time-varying topology.

>>> import dynmesh
>>> data = dynmesh.encode(frames, qp=28)          # frames: Mesh or (positions, faces)
>>> decoded = list(dynmesh.decode(data))
>>> dynmesh.metrics(frames, decoded)["d1_psnr"]
"""

from __future__ import annotations

from ._lazy import lazy_names as _lazy_names

# The names are loaded on first use (PEP 562): `python -m dynmesh decode` imports this
# package, and importing the API eagerly would import numpy (a quarter of a second) for a
# command that does not need it.
_HOMES = {
    "DEFAULTS": "api", "DecodeError": "api", "EncodeResult": "api", "decode": "api", "encode": "api",
    "encode_frames": "api", "info": "api", "metrics": "api",
    "MeshError": "io", "read_mesh": "io", "write_mesh": "io",
    "Mesh": "mesh",
    "FrameType": "defaults",
}

__all__ = sorted(_HOMES)
__version__ = "0.1.0"


# Submodules (dynmesh.api, ...) were attributes once the package was imported: still so.
__getattr__, __dir__ = _lazy_names(__name__, _HOMES, globals(), submodules=True)
