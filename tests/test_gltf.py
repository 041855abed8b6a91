"""dynmesh decode --format glb: one glTF 2.0 binary per frame, which the Khronos
glTF-Validator (npm gltf-validator, installed by `npm ci` in web/) accepts with zero errors,
and which holds the decoded frame (positions, triangles, unit normals, UVs and texture)."""

from __future__ import annotations

import json
import shutil
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dynmesh import api
from dynmesh.io.gltf import glb_bytes

ROOT = Path(__file__).resolve().parents[1]
VECTORS = ROOT / "tests" / "vectors"
VALIDATE = ROOT / "web" / "test" / "helpers" / "validate-gltf.js"
NODE = shutil.which("node")


def validate(paths: list[Path]) -> list[dict]:
    if not (ROOT / "web" / "node_modules" / "gltf-validator").is_dir():
        pytest.fail("gltf-validator is not installed: run `npm ci` in web/ (the README's test command does)")
    out = subprocess.run([NODE, str(VALIDATE), *map(str, paths)], capture_output=True, text=True, check=True, timeout=300)
    return [json.loads(line) for line in out.stdout.splitlines()]


def read_glb(data: bytes) -> tuple[dict, bytes]:
    magic, version, total = struct.unpack_from("<4sII", data)
    assert (magic, version, total) == (b"glTF", 2, len(data))
    n, kind = struct.unpack_from("<I4s", data, 12)
    assert kind == b"JSON"
    doc = json.loads(data[20:20 + n])
    m, kind = struct.unpack_from("<I4s", data, 20 + n)
    assert kind == b"BIN\0"
    return doc, data[28 + n:28 + n + m]


def accessor(doc: dict, binary: bytes, index: int) -> np.ndarray:
    a = doc["accessors"][index]
    v = doc["bufferViews"][a["bufferView"]]
    dtype = {5126: "<f4", 5125: "<u4"}[a["componentType"]]
    width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3}[a["type"]]
    return np.frombuffer(binary, dtype, a["count"] * width, v["byteOffset"]).reshape(a["count"], width)


@pytest.mark.skipif(NODE is None, reason="Node.js is not installed")  # never in CI: .ci/run installs it
@pytest.mark.parametrize("stream,lod", [("textured_mixed.dmsh", None), ("anchor_mixed_aq.dmsh", None), ("constant_loop_noaq.dmsh", 1)])
def test_glb_frames_pass_the_khronos_validator_and_hold_the_decoded_frame(stream, lod, tmp_path):
    extra = [] if lod is None else ["--lod", str(lod)]
    subprocess.run([sys.executable, "-m", "dynmesh", "decode", str(VECTORS / stream), "-o", str(tmp_path),
                    "--format", "glb", "-q", *extra], check=True, capture_output=True)
    files = sorted(tmp_path.glob("frame_*.glb"))
    decoded = list(api.decode((VECTORS / stream).read_bytes(), lod=lod))
    assert len(files) == len(decoded) > 0
    for report in validate(files):
        assert report["errors"] == 0, report["messages"]
    for path, mesh in zip(files, decoded):
        doc, binary = read_glb(path.read_bytes())
        prim = doc["meshes"][0]["primitives"][0]
        pos = accessor(doc, binary, prim["attributes"]["POSITION"])
        tris = accessor(doc, binary, prim["indices"]).reshape(-1, 3)
        normals = accessor(doc, binary, prim["attributes"]["NORMAL"])
        assert len(tris) == len(mesh.faces)
        # Same triangles, corner for corner, up to float32 rounding of the positions.
        assert np.allclose(pos[tris], mesh.positions[mesh.faces], rtol=0, atol=1e-5 * np.ptp(mesh.positions))
        assert np.allclose(np.linalg.norm(normals, axis=1), 1, atol=1e-5)
        assert ("TEXCOORD_0" in prim["attributes"]) == (mesh.uvs is not None)
        if mesh.uvs is not None:
            uv = accessor(doc, binary, prim["attributes"]["TEXCOORD_0"])
            want = mesh.uvs[mesh.uv_faces].reshape(-1, 2) * [1, -1] + [0, 1]
            assert np.allclose(uv[tris].reshape(-1, 2), want, atol=1e-6)
            assert doc["images"][0]["mimeType"] == "image/png"


def test_an_untextured_frame_has_no_texture_and_one_vertex_per_position():
    (mesh, *_) = api.decode((VECTORS / "constant_midpoint_all.dmsh").read_bytes())
    doc, binary = read_glb(glb_bytes(mesh))
    assert "images" not in doc and "textures" not in doc
    assert doc["accessors"][0]["count"] == len(mesh.positions)
    assert doc["accessors"][0]["min"] == pytest.approx(mesh.positions.min(axis=0).tolist(), rel=1e-6)
