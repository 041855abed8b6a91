"""dynmesh: a fast codec for dynamic 3D meshes with time-varying topology.

>>> import dynmesh
>>> data = dynmesh.encode(frames, qp=28)          # frames: Mesh or (positions, faces)
>>> decoded = list(dynmesh.decode(data))
>>> dynmesh.metrics(frames, decoded)["d1_psnr"]
"""

from __future__ import annotations

import importlib

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


def __getattr__(name: str):
    home = _HOMES.get(name)
    if home is not None:
        value = getattr(importlib.import_module(f".{home}", __name__), name)
        globals()[name] = value
        return value
    # Submodules (dynmesh.api, ...) were attributes once the package was imported: still so.
    try:
        return importlib.import_module(f".{name}", __name__)
    except ModuleNotFoundError as e:
        if e.name != f"{__name__}.{name}":
            raise
    raise AttributeError(f"module 'dynmesh' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_HOMES))
