"""dynmesh: a fast codec for dynamic 3D meshes with time-varying topology.

>>> import dynmesh
>>> data = dynmesh.encode(frames, qp=28)          # frames: Mesh or (positions, faces)
>>> decoded = list(dynmesh.decode(data))
>>> dynmesh.metrics(frames, decoded)["d1_psnr"]

Errors are exception classes by kind (also in ``dynmesh.api``):

- ``InputError`` (a ValueError): input the codec's core refuses: an encoder option out of
  range, a level of detail beyond the stream's, a malformed mesh (a face index out of range, a
  coordinate that is not finite, no face with an area); ``encode`` names the frame it refused.
- ``DecodeError`` (a ValueError): a stream that cannot be decoded (truncated, corrupted);
  ``frame`` (None for the sequence header) and ``offset`` (the byte offset in the stream)
  say where decoding stopped.
- ``UnsupportedError`` (a ValueError): a well-formed stream this build does not read, such as
  one of another format version or with a texture codec it does not know.
- ``InternalError`` (a RuntimeError): a bug in dynmesh; the message says so and where. Please
  report it.

Other mistakes (a wrong type, an unreadable file) raise Python's own exceptions (TypeError,
OSError, ``MeshError`` for a malformed mesh file).

Warnings: ``MeshWarning`` (``dynmesh.io``) when reading repaired or ignored something in a
mesh file; ``TextureWarning`` when ``encode`` drops the textures of a sequence whose frames
are not all textured (``texture="auto"``).
"""

from __future__ import annotations

from ._lazy import lazy_names as _lazy_names

# The names are loaded on first use (PEP 562): `python -m dynmesh decode` imports this
# package, and importing the API eagerly would import numpy (a quarter of a second) for a
# command that does not need it.
_HOMES = {
    "DEFAULTS": "api", "DecodeError": "api", "EncodeResult": "api", "decode": "api", "encode": "api",
    "encode_frames": "api", "info": "api", "metrics": "api",
    "InputError": "api", "InternalError": "api", "UnsupportedError": "api", "TextureWarning": "api",
    "MeshError": "io", "read_mesh": "io", "write_mesh": "io",
    "Mesh": "mesh",
    "FrameType": "defaults",
}

__all__ = sorted(_HOMES)
__version__ = "0.1.0"


# Submodules (dynmesh.api, ...) were attributes once the package was imported: still so.
__getattr__, __dir__ = _lazy_names(__name__, _HOMES, globals(), submodules=True)
