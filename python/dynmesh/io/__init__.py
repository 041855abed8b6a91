"""Files in and out: mesh files and texture images (``meshio``: OBJ, MTL, PLY, atomic writes;
it reads glTF 2.0 frames through ``gltf_read`` and Draco frames through ``draco``, whose split
vertices ``weld`` joins again, and texture images (PNG, JPEG) through ``image``; all raise
``errors.MeshError``), glTF binaries for ``dynmesh decode
--format glb`` (``gltf``), a sequence argument to its frame files (``sequence``), and the
command line's promises about files (``safety``: no output over an input, a staged output
directory).

The names below are loaded on first use (PEP 562), as the package's own are: the command
line imports ``safety`` and ``sequence`` for every command, and ``meshio`` would import numpy.
"""

from __future__ import annotations

from .._lazy import lazy_names as _lazy_names

_HOMES = {
    "MeshError": "errors", "MeshWarning": "meshio", "read_mesh": "meshio", "write_mesh": "meshio",
    "read_image": "image", "image_of": "image", "write_image": "meshio",
    "glb_bytes": "gltf",
    "SequenceError": "sequence", "natural_key": "sequence", "resolve_sequence": "sequence",
    "InputClobberError": "safety", "StagedDirectory": "safety", "mesh_inputs": "safety", "refuse_inputs": "safety",
}

__all__ = sorted(_HOMES)


__getattr__, __dir__ = _lazy_names(__name__, _HOMES, globals())
