"""dynmesh: a fast codec for dynamic 3D meshes with time-varying topology.

>>> import dynmesh
>>> data = dynmesh.encode(frames, qp=28)          # frames: Mesh or (positions, faces)
>>> decoded = list(dynmesh.decode(data))
>>> dynmesh.metrics(frames, decoded)["d1_psnr"]
"""

from .api import DEFAULTS, DecodeError, EncodeResult, decode, encode, encode_frames, info, metrics
from .io import MeshError, read_mesh, write_mesh
from .mesh import Mesh

__all__ = [
    "DEFAULTS", "DecodeError", "EncodeResult", "Mesh", "MeshError",
    "decode", "encode", "encode_frames", "info", "metrics", "read_mesh", "write_mesh",
]
__version__ = "0.1.0"
