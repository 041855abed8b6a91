"""dynmesh: a fast codec for dynamic 3D meshes with time-varying topology."""

from .mesh import Mesh

__all__ = ["Mesh"]
__version__ = "0.1.0"
