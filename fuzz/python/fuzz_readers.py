"""Atheris harnesses for the Python-side parsers: the OBJ, PLY and MTL readers
(``dynmesh.io.meshio``, whose per-line work is ``_core.read_obj`` / ``read_ply`` in
bindings/src/meshio.rs) and the texture unit payload (``dynmesh.texture.unpack_group``, then
the atlas it carries decoded on a small mesh).

    python fuzz/python/fuzz_readers.py TARGET [libFuzzer options] [corpus dirs]
    python fuzz/python/fuzz_readers.py seeds DIR    # DIR/<target>/: a valid input for each

TARGET is obj, ply, mtl or texture. A parser may refuse its input only with the error it
documents (MeshError for the readers, ValueError for the texture unit); any other exception
is a crash that atheris reports with the input that caused it.
"""

from __future__ import annotations

import os
import sys
import tempfile
import warnings
from pathlib import Path

import atheris

with atheris.instrument_imports():
    import numpy as np

    from dynmesh import texture
    from dynmesh.io import meshio
    from dynmesh.texture import atlas

WORK = Path(tempfile.mkdtemp(prefix="dynmesh-fuzz-"))
# A mesh for the atlas to be decoded on: two triangles of a unit square.
SQUARE = (np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float), np.array([[0, 1, 2], [0, 2, 3]]))


def read_obj(data: bytes) -> None:
    try:
        meshio._read_obj(data, WORK / "input.obj", [])
    except meshio.MeshError:
        pass


def read_ply(data: bytes) -> None:
    try:
        meshio._read_ply(data, WORK / "input.ply", [])
    except meshio.MeshError:
        pass


def read_mtl(data: bytes) -> None:
    # The MTL reader takes a file: the library an OBJ names, read from disk.
    (WORK / "input.mtl").write_bytes(data)
    meshio._read_mtl(WORK / "input.mtl", [])
    meshio._map_file_name(data.decode("utf-8", "replace"))


def read_texture_unit(data: bytes) -> None:
    try:
        header = texture.unpack_group(data)
    except ValueError:
        return
    try:
        atlas.decoded_atlas(header.atlas, *SQUARE, header.uv_bits)
    except ValueError:
        pass


def write_seeds(root: Path) -> None:
    from dynmesh.mesh import Mesh

    mesh = Mesh(SQUARE[0], SQUARE[1], uvs=SQUARE[0][:, :2].copy(), uv_faces=SQUARE[1].copy(), texture=WORK / "t.png")
    for suffix, ascii in ((".obj", False), (".ply", True), (".ply", False)):
        name = f"seed_{'ascii' if ascii else 'binary'}{suffix}"
        meshio.write_mesh(WORK / name, mesh, ascii=ascii)
        (root / suffix[1:]).mkdir(parents=True, exist_ok=True)
        (root / suffix[1:] / name).write_bytes((WORK / name).read_bytes())
    (root / "mtl").mkdir(parents=True, exist_ok=True)
    (root / "mtl" / "seed.mtl").write_bytes((WORK / "seed_binary.mtl").read_bytes() + b"newmtl b\nmap_Kd -s 1 2 3 -bm 0.5 x y.png\n")
    coded = atlas.coded_atlas(SQUARE[0], SQUARE[1], 64)[0]
    unit = texture.pack_group(texture.GroupHeader("hevc", 64, 64, atlas.UV_BITS, 1, coded, b"\0" * 16))
    (root / "texture").mkdir(parents=True, exist_ok=True)
    (root / "texture" / "seed").write_bytes(unit)


TARGETS = {"obj": read_obj, "ply": read_ply, "mtl": read_mtl, "texture": read_texture_unit}


def main() -> None:
    if len(sys.argv) == 3 and sys.argv[1] == "seeds":
        return write_seeds(Path(sys.argv[2]))
    if len(sys.argv) < 2 or sys.argv[1] not in TARGETS:
        sys.exit(f"usage: {sys.argv[0]} {{{','.join(TARGETS)}}} [libFuzzer options] [corpus dirs]")
    target = TARGETS[sys.argv.pop(1)]
    warnings.simplefilter("ignore")  # MeshWarnings about repaired input are expected
    atheris.Setup(sys.argv, target)
    atheris.Fuzz()


if __name__ == "__main__":
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    main()
