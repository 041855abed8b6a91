"""glTF 2.0 binary (.glb) export of decoded frames: one self-contained file per frame.

A frame becomes one mesh with one triangle primitive: POSITION (float32, with the min/max
glTF requires), NORMAL (area-weighted unit vertex normals; +z where a vertex has none, as the
core's local frames do), uint32 indices and, for a textured frame, TEXCOORD_0 with the
frame's texture embedded as a PNG and referenced by a metallic-roughness material. glTF
keeps one index list for every attribute, so a textured frame's vertices are split where a
vertex has several UVs (chart seams), and V is flipped (glTF's UV origin is the image's top
left, dynmesh's the bottom left as in OBJ). Positions go to float32, which glTF requires:
the .glb is for viewing, not for bit-exact comparison (use ``--hash`` for that).
"""

from __future__ import annotations

import json
import struct

import numpy as np

from .. import _core
from ..mesh import Mesh

_FLOAT, _UINT = 5126, 5125
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963


def vertex_normals(positions: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals; +z for vertices without one."""
    p = positions[faces]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    # Every corner's face normal added to its vertex, corners 0, 1, 2 of the faces in turn
    # (np.add.at's order, so the same sums), one bincount per axis.
    corners, m = faces.T.ravel(), len(positions)
    acc = np.stack([np.bincount(corners, np.tile(n[:, a], 3), minlength=m) for a in range(3)], 1)
    length = np.linalg.norm(acc, axis=1)
    out = np.tile([0.0, 0.0, 1.0], (len(positions), 1))
    ok = length > 1e-300
    out[ok] = acc[ok] / length[ok, None]
    return out


def _split_seams(mesh: Mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(positions, normals, uvs or None, faces) with one vertex per distinct (position, UV)
    corner pair, so that every attribute shares the index list."""
    normals = vertex_normals(mesh.positions, mesh.faces)
    if mesh.uvs is None:
        return mesh.positions, normals, None, mesh.faces
    uv_faces = mesh.uv_faces if mesh.uv_faces is not None else mesh.faces
    # Each (position, UV) pair as one integer sorts as the pairs do: np.unique on it gives
    # the pairs' order, ten times faster than on rows (axis=0).
    span = np.int64(len(mesh.uvs))
    keys, inverse = np.unique(mesh.faces.ravel().astype(np.int64) * span + uv_faces.ravel(), return_inverse=True)
    vertex, corner_uv = np.divmod(keys, span)
    uv = mesh.uvs[corner_uv].copy()
    uv[:, 1] = 1.0 - uv[:, 1]
    return mesh.positions[vertex], normals[vertex], uv, inverse.reshape(-1, 3)


class _Buffer:
    """The binary chunk, with its buffer views and accessors."""

    def __init__(self):
        self.data = bytearray()
        self.views: list[dict] = []
        self.accessors: list[dict] = []

    def view(self, raw: bytes, target: int | None = None) -> int:
        self.data += b"\0" * (-len(self.data) % 4)  # accessors need 4-byte alignment
        v = {"buffer": 0, "byteOffset": len(self.data), "byteLength": len(raw)}
        if target is not None:
            v["target"] = target
        self.data += raw
        self.views.append(v)
        return len(self.views) - 1

    def accessor(self, array: np.ndarray, kind: str, component: int, target: int, bounds: bool = False) -> int:
        a = {"bufferView": self.view(array.tobytes(), target), "componentType": component,
             "count": int(len(array)), "type": kind}
        if bounds:
            a["min"] = array.min(axis=0).tolist()
            a["max"] = array.max(axis=0).tolist()
        self.accessors.append(a)
        return len(self.accessors) - 1


def _png(image: np.ndarray) -> bytes:
    """The texture as a lossless PNG, encoded by the core (fdeflate, the GIL released)."""
    return _core.encode_png(np.ascontiguousarray(image, np.uint8))


def glb_bytes(mesh: Mesh, name: str = "frame") -> bytes:
    """The .glb file of one decoded frame (see the module documentation)."""
    positions, normals, uv, faces = _split_seams(mesh)
    buf = _Buffer()
    attributes = {
        "POSITION": buf.accessor(positions.astype("<f4"), "VEC3", _FLOAT, _ARRAY_BUFFER, bounds=True),
        "NORMAL": buf.accessor(normals.astype("<f4"), "VEC3", _FLOAT, _ARRAY_BUFFER),
    }
    doc: dict = {"asset": {"version": "2.0", "generator": "dynmesh"}, "scene": 0,
                 "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0, "name": name}]}
    primitive: dict = {"attributes": attributes, "mode": 4}
    textured = uv is not None and mesh.image is not None
    if textured:
        attributes["TEXCOORD_0"] = buf.accessor(uv.astype("<f4"), "VEC2", _FLOAT, _ARRAY_BUFFER)
        doc["images"] = [{"bufferView": buf.view(_png(mesh.image)), "mimeType": "image/png"}]
        doc["samplers"] = [{"magFilter": 9729, "minFilter": 9729, "wrapS": 33071, "wrapT": 33071}]
        doc["textures"] = [{"source": 0, "sampler": 0}]
        doc["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0,
                                                      "roughnessFactor": 1.0}}]
    else:
        doc["materials"] = [{"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1.0], "metallicFactor": 0.0}}]
    primitive["material"] = 0
    primitive["indices"] = buf.accessor(faces.astype("<u4").ravel(), "SCALAR", _UINT, _ELEMENT_ARRAY_BUFFER)
    doc["meshes"] = [{"primitives": [primitive], "name": name}]
    buf.data += b"\0" * (-len(buf.data) % 4)
    doc["buffers"] = [{"byteLength": len(buf.data)}]
    doc["bufferViews"], doc["accessors"] = buf.views, buf.accessors
    text = json.dumps(doc, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    total = 12 + 8 + len(text) + 8 + len(buf.data)
    return b"".join([struct.pack("<4sII", b"glTF", 2, total), struct.pack("<I4s", len(text), b"JSON"), text,
                     struct.pack("<I4s", len(buf.data), b"BIN\0"), bytes(buf.data)])
