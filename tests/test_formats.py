"""The formats people have: glTF 2.0 (.gltf with its buffers in files or data URIs, .glb)
and Draco (.drc) frames, read by ``read_mesh`` and so by ``encode`` and ``metrics``, and
JPEG textures beside PNG ones. Every file here is made by the test: glTFs by a small builder
below (the layouts exporters write: several primitives and meshes, a node hierarchy,
external and embedded buffers and images), by trimesh's exporter and by dynmesh's own
``decode --format glb``; Draco files by DracoPy."""

from __future__ import annotations

import base64
import io
import json
import struct
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from dynmesh import api
from dynmesh.io import MeshError, MeshWarning, read_image, read_mesh, resolve_sequence, write_mesh
from dynmesh.io.gltf import glb_bytes
from dynmesh.mesh import Mesh

from conftest import uv_sphere, wobbly_sequence

ROOT = Path(__file__).resolve().parents[1]
VECTORS = ROOT / "tests" / "vectors"


# --------------------------------------------------------------------------- making files


def colour_field(size: int = 64, seed: int = 0) -> np.ndarray:
    """A smooth colour image with a coarse checker: colours that tell UVs apart."""
    y, x = np.mgrid[0:size, 0:size] / size
    phase = np.random.default_rng(seed).uniform(0, 2 * np.pi, 3)
    rgb = [0.5 + 0.4 * np.sin(2 * np.pi * (x + 0.7 * y) + p) for p in phase]
    check = ((np.floor(x * 4) + np.floor(y * 4)) % 2) * 0.2
    return np.clip(np.stack(rgb, -1) * 255 * (0.8 + check[..., None]), 0, 255).astype(np.uint8)


def encoded_image(image: np.ndarray, kind: str) -> bytes:
    from PIL import Image

    out = io.BytesIO()
    Image.fromarray(image).save(out, format=kind, **({"quality": 95} if kind == "JPEG" else {}))
    return out.getvalue()


def decoded_image(data: bytes) -> np.ndarray:
    from PIL import Image

    with Image.open(io.BytesIO(data)) as im:
        return np.asarray(im.convert("RGB"))


def textured_sphere(rings: int = 10, segments: int = 14, image: np.ndarray | None = None) -> Mesh:
    """A sphere with one UV per vertex (an OBJ convention UV: V up)."""
    m = uv_sphere(rings, segments)
    d = m.positions / np.linalg.norm(m.positions, axis=1, keepdims=True)
    uv = np.stack([0.5 + np.arctan2(d[:, 1], d[:, 0]) / (2 * np.pi), 1 - np.arccos(np.clip(d[:, 2], -1, 1)) / np.pi], 1)
    return Mesh(m.positions, m.faces, uvs=0.05 + 0.9 * uv, uv_faces=m.faces.copy(),
                image=colour_field() if image is None else image)


class Gltf:
    """A glTF document and its binary buffer, built as exporters lay them out."""

    def __init__(self):
        self.doc: dict = {"asset": {"version": "2.0", "generator": "dynmesh tests"}, "buffers": [],
                          "bufferViews": [], "accessors": [], "meshes": [], "nodes": [], "scenes": [{"nodes": []}],
                          "scene": 0}
        self.data = bytearray()

    def view(self, raw: bytes) -> int:
        self.data += b"\0" * (-len(self.data) % 4)
        self.doc["bufferViews"].append({"buffer": 0, "byteOffset": len(self.data), "byteLength": len(raw)})
        self.data += raw
        return len(self.doc["bufferViews"]) - 1

    def accessor(self, array: np.ndarray, kind: str, component: int = 5126) -> int:
        dtype = {5126: "<f4", 5125: "<u4", 5123: "<u2", 5121: "u1"}[component]
        array = np.asarray(array).astype(dtype)
        a = {"bufferView": self.view(array.tobytes()), "componentType": component, "count": len(array), "type": kind}
        if kind == "VEC3":
            a["min"], a["max"] = array.min(0).tolist(), array.max(0).tolist()
        self.doc["accessors"].append(a)
        return len(self.doc["accessors"]) - 1

    def primitive(self, positions, faces=None, uvs=None, material: int | None = None, mode: int | None = None) -> dict:
        """A primitive with one vertex per row of ``positions``; ``uvs`` in OBJ's convention
        (V up), written as glTF's (V down)."""
        p: dict = {"attributes": {"POSITION": self.accessor(positions, "VEC3")}}
        if faces is not None:
            p["indices"] = self.accessor(np.asarray(faces).ravel(), "SCALAR", 5125)
        if uvs is not None:
            flipped = np.asarray(uvs, np.float64).copy()
            flipped[:, 1] = 1 - flipped[:, 1]
            p["attributes"]["TEXCOORD_0"] = self.accessor(flipped, "VEC2")
        if material is not None:
            p["material"] = material
        if mode is not None:
            p["mode"] = mode
        return p

    def textured_material(self, image: bytes, mime: str, where: str = "view", name: str = "skin") -> int:
        """A material whose base colour texture is ``image``: in a buffer view, a data URI or a
        file beside the glTF (``where="file"``; ``save`` writes it)."""
        d = self.doc
        entry: dict = {"mimeType": mime}
        if where == "view":
            entry["bufferView"] = self.view(image)
        elif where == "data":
            entry["uri"] = f"data:{mime};base64," + base64.b64encode(image).decode()
        else:
            entry = {"uri": name}
            self.files = {**getattr(self, "files", {}), name: image}
        d.setdefault("images", []).append(entry)
        d.setdefault("textures", []).append({"source": len(d["images"]) - 1})
        d.setdefault("materials", []).append(
            {"pbrMetallicRoughness": {"baseColorTexture": {"index": len(d["textures"]) - 1}, "metallicFactor": 0}})
        return len(d["materials"]) - 1

    def mesh(self, *primitives: dict) -> int:
        self.doc["meshes"].append({"primitives": list(primitives)})
        return len(self.doc["meshes"]) - 1

    def node(self, root: bool = True, **fields) -> int:
        self.doc["nodes"].append(fields)
        if root:
            self.doc["scenes"][0]["nodes"].append(len(self.doc["nodes"]) - 1)
        return len(self.doc["nodes"]) - 1

    def save(self, path: Path, buffer: str = "glb") -> Path:
        """As a .glb (``buffer="glb"``) or a .gltf whose buffer is a .bin file beside it
        (``"file"``) or a data URI (``"data"``)."""
        doc = json.loads(json.dumps(self.doc))
        data = bytes(self.data) + b"\0" * (-len(self.data) % 4)
        doc["buffers"] = [{"byteLength": len(data)}]
        for name, image in getattr(self, "files", {}).items():
            (path.parent / name).write_bytes(image)
        if buffer == "glb":
            text = json.dumps(doc).encode()
            text += b" " * (-len(text) % 4)
            body = struct.pack("<I4s", len(text), b"JSON") + text + struct.pack("<I4s", len(data), b"BIN\0") + data
            path.write_bytes(struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body)
        elif buffer == "file":
            doc["buffers"][0]["uri"] = path.stem + " data.bin"  # a space: URIs are percent-encoded
            doc["buffers"][0]["uri"] = doc["buffers"][0]["uri"].replace(" ", "%20")
            (path.parent / (path.stem + " data.bin")).write_bytes(data)
            path.write_text(json.dumps(doc))
        else:
            doc["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(data).decode()
            path.write_text(json.dumps(doc))
        return path


def single_mesh_gltf(m: Mesh, image: bytes | None = None, mime: str = "image/png", where: str = "view") -> Gltf:
    g = Gltf()
    material = None if image is None else g.textured_material(image, mime, where)
    g.node(mesh=g.mesh(g.primitive(m.positions, m.faces, None if image is None else m.uvs, material)))
    return g


def corner_colours(m: Mesh, image: np.ndarray | None = None) -> np.ndarray:
    """The texel (nearest) under each face's centre in UV space, as OBJ's convention reads it."""
    image = (m.image if m.image is not None else read_image(m.texture)) if image is None else image
    h, w = image.shape[:2]
    uv = m.uvs[m.uv_faces].mean(axis=1)
    x = np.clip((uv[:, 0] * w).astype(int), 0, w - 1)
    y = np.clip(((1 - uv[:, 1]) * h).astype(int), 0, h - 1)
    return image[y, x].astype(int)


def f32(a: np.ndarray) -> np.ndarray:
    return np.asarray(a, np.float32).astype(np.float64)


def read_quietly(path: Path) -> Mesh:
    with warnings.catch_warnings():
        warnings.simplefilter("error", MeshWarning)
        return read_mesh(path)


# --------------------------------------------------------------------------- glTF


def test_a_glb_written_by_decode_reads_back_as_the_decoded_frame(tmp_path):
    """`dynmesh decode --format glb`, then read_mesh: the same triangles (positions as the glb's
    float32 holds them), the texture pixel for pixel and the same colours under the UVs, although
    the glb splits vertices at UV seams and stores V flipped."""
    stream = VECTORS / "textured_mixed.dmsh"
    subprocess.run([sys.executable, "-m", "dynmesh", "decode", str(stream), "-o", str(tmp_path / "glb"),
                    "--format", "glb", "-q"], check=True, capture_output=True)
    decoded = list(api.decode(stream.read_bytes()))
    files = sorted((tmp_path / "glb").glob("frame_*.glb"))
    assert len(files) == len(decoded) > 1
    for file, frame in zip(files, decoded):
        back = read_quietly(file)
        assert back.face_count == frame.face_count
        np.testing.assert_array_equal(back.positions[back.faces], f32(frame.positions)[frame.faces])
        assert back.vertex_count == len(np.unique(f32(frame.positions), axis=0))  # seams welded again
        np.testing.assert_array_equal(back.image, frame.image)
        np.testing.assert_allclose(back.uvs[back.uv_faces], frame.uvs[frame.uv_faces], atol=2e-7)
        same = (corner_colours(back) == corner_colours(frame)).all(axis=1)
        assert same.mean() > 0.999


@pytest.mark.parametrize("buffer", ["glb", "file", "data"])
@pytest.mark.parametrize("kind, where", [("PNG", "view"), ("JPEG", "view"), ("JPEG", "data"), ("PNG", "file"),
                                         ("JPEG", "file")])
def test_gltf_and_glb_with_png_and_jpeg_textures(tmp_path, buffer, kind, where):
    m = textured_sphere()
    image = encoded_image(m.image, kind)
    mime = f"image/{kind.lower()}"
    name = "frame.glb" if buffer == "glb" else "frame.gltf"
    path = single_mesh_gltf(m, image, mime, where).save(tmp_path / name, buffer)
    back = read_quietly(path)
    np.testing.assert_array_equal(back.positions, f32(m.positions))
    np.testing.assert_array_equal(back.faces, m.faces)
    np.testing.assert_allclose(back.uvs[back.uv_faces], m.uvs[m.uv_faces], atol=1e-7)
    if where == "file":  # an image file beside the glTF stays a file, as an OBJ's map_Kd does
        assert back.image is None and back.texture == tmp_path / "skin"
    else:
        assert back.texture is None
    pixels = back.image if back.image is not None else read_image(back.texture)
    np.testing.assert_array_equal(pixels, decoded_image(image))
    if kind == "PNG":
        np.testing.assert_array_equal(corner_colours(back), corner_colours(m))
    else:
        assert np.abs(corner_colours(back) - corner_colours(m)).mean() < 4  # JPEG at quality 95


@pytest.mark.parametrize("kind", ["PNG", "JPEG"])
def test_a_glb_exported_by_trimesh_reads_back(tmp_path, kind):
    trimesh = pytest.importorskip("trimesh")
    from PIL import Image

    m = textured_sphere()
    texture = Image.open(io.BytesIO(encoded_image(m.image, kind)))
    visual = trimesh.visual.TextureVisuals(uv=m.uvs, image=texture)
    trimesh.Trimesh(m.positions, m.faces, visual=visual, process=False).export(tmp_path / "t.glb")
    back = read_quietly(tmp_path / "t.glb")
    np.testing.assert_array_equal(back.positions[back.faces], f32(m.positions)[m.faces])
    np.testing.assert_allclose(back.uvs[back.uv_faces], m.uvs[m.uv_faces], atol=1e-7)
    text = (tmp_path / "t.glb").read_bytes()
    assert f'"mimeType":"image/{kind.lower()}"'.encode() in text.replace(b" ", b"")
    if kind == "PNG":
        np.testing.assert_array_equal(back.image, m.image)
    else:  # trimesh encodes the JPEG again
        assert np.abs(back.image.astype(int) - m.image).mean() < 4


def test_a_draco_compressed_glb_reads_back(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    from PIL import Image

    m = textured_sphere()
    visual = trimesh.visual.TextureVisuals(uv=m.uvs, image=Image.fromarray(m.image))
    data = trimesh.Trimesh(m.positions, m.faces, visual=visual, process=False).export(file_type="glb",
                                                                                       extension_draco=True)
    assert b'"extensions":{"KHR_draco_mesh_compression"' in data.replace(b" ", b"")  # compressed primitives
    (tmp_path / "d.glb").write_bytes(data)
    back = read_quietly(tmp_path / "d.glb")
    assert back.face_count == m.face_count and back.vertex_count == m.vertex_count
    span = m.positions.max(0) - m.positions.min(0)
    # Draco reorders: every face's centre is one of the source's, within the quantization.
    centres, want = back.positions[back.faces].mean(1), m.positions[m.faces].mean(1)
    nearest = np.linalg.norm(centres[:, None] - want[None], axis=2).min(axis=1)
    assert nearest.max() < span.max() / 2 ** 12
    assert np.abs(corner_colours(back) - corner_colours(m)).mean() < 4


def test_a_draco_compressed_glb_whose_draco_data_is_damaged_is_refused(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    m = uv_sphere(6, 8)
    data = bytearray(trimesh.Trimesh(m.positions, m.faces, process=False).export(file_type="glb", extension_draco=True))
    assert b'"extensions":{"KHR_draco_mesh_compression"' in bytes(data).replace(b" ", b"")
    n = struct.unpack_from("<I", data, 12)[0]
    data[28 + n: 28 + n + 64] = bytes(64)  # the binary chunk's start: the Draco data's header
    (tmp_path / "d.glb").write_bytes(bytes(data))
    with pytest.raises(MeshError, match="Draco-compressed primitives .* cannot be decoded"):
        read_mesh(tmp_path / "d.glb")


def rotation_about_z(degrees: float) -> np.ndarray:
    t = np.radians(degrees)
    return np.array([[np.cos(t), -np.sin(t), 0], [np.sin(t), np.cos(t), 0], [0, 0, 1]])


def signed_volume(m: Mesh) -> float:
    p = m.positions[m.faces]
    return float(np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6)


def test_primitives_meshes_and_nodes_merge_into_one_mesh_in_the_world_frame(tmp_path):
    """Two halves of a sphere as two primitives of one mesh (their shared vertices welded back
    into one), placed by a child node under a rotated, translated and scaled parent; a second
    mesh mirrored by a negative scale keeps its faces pointing outwards; a node outside the
    scene is not read."""
    m = uv_sphere(8, 12)
    half = len(m.faces) // 2
    g = Gltf()
    both = g.mesh(*(g.primitive(m.positions, m.faces[s]) for s in (slice(0, half), slice(half, None))))
    small = uv_sphere(4, 6)
    mirror = g.mesh(g.primitive(small.positions, small.faces))
    child = g.node(root=False, mesh=both, matrix=np.eye(4).ravel().tolist())
    quarter = [0, 0, np.sin(np.pi / 4), np.cos(np.pi / 4)]  # 90 degrees about z, as (x, y, z, w)
    g.node(children=[child], translation=[1, 2, 3], rotation=quarter, scale=[2, 2, 2])
    g.node(mesh=mirror, translation=[10, 0, 0], scale=[-1, 1, 1])
    g.node(root=False, mesh=mirror)  # not in the scene
    back = read_quietly(g.save(tmp_path / "scene.glb"))

    big = f32(m.positions) @ (2 * rotation_about_z(90)).T + [1, 2, 3]
    mirrored = f32(small.positions) * [-1, 1, 1] + [10, 0, 0]
    assert back.vertex_count == m.vertex_count + small.vertex_count
    assert back.face_count == m.face_count + small.face_count
    np.testing.assert_allclose(back.positions[back.faces[:len(m.faces)]], big[m.faces], atol=1e-12)
    np.testing.assert_allclose(back.positions[back.faces[len(m.faces):]], mirrored[small.faces[:, ::-1]], atol=1e-12)
    head = Mesh(back.positions, back.faces[:len(m.faces)])
    tail = Mesh(back.positions - [10, 0, 0], back.faces[len(m.faces):])
    assert signed_volume(head) > 0 and signed_volume(tail) > 0  # outward, like the source


def test_a_gltf_without_a_scene_reads_each_mesh_once(tmp_path):
    m = uv_sphere(5, 7)
    g = Gltf()
    g.mesh(g.primitive(m.positions, m.faces))
    del g.doc["scenes"], g.doc["scene"], g.doc["nodes"]
    back = read_quietly(g.save(tmp_path / "lib.gltf", "data"))
    np.testing.assert_array_equal(back.faces, m.faces)


def test_unindexed_triangles_and_strips_are_read(tmp_path):
    corners = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], float)
    g = Gltf()
    g.node(mesh=g.mesh(g.primitive(corners[[0, 1, 2, 2, 1, 3]])))
    g.node(mesh=g.mesh(g.primitive(corners + [0, 0, 1], mode=5)))
    back = read_quietly(g.save(tmp_path / "flat.glb"))
    assert back.vertex_count == 8 and back.face_count == 4  # the duplicated corners are one vertex again
    np.testing.assert_array_equal(back.positions[back.faces[:2]], corners[[[0, 1, 2], [2, 1, 3]]])


def test_primitives_with_two_textures_keep_the_first_with_a_warning(tmp_path):
    m = textured_sphere()
    g = Gltf()
    first = g.textured_material(encoded_image(m.image, "PNG"), "image/png")
    second = g.textured_material(encoded_image(255 - m.image, "PNG"), "image/png")
    half = len(m.faces) // 2
    g.node(mesh=g.mesh(g.primitive(m.positions, m.faces[:half], m.uvs, first),
                       g.primitive(m.positions, m.faces[half:], m.uvs, second)))
    with pytest.warns(MeshWarning, match="materials use 2 textures; only the first"):
        back = read_mesh(g.save(tmp_path / "two.glb"))
    np.testing.assert_array_equal(back.image, m.image)
    assert back.vertex_count == m.vertex_count


def test_a_primitive_without_texture_makes_the_mesh_untextured_with_a_warning(tmp_path):
    m = textured_sphere()
    g = Gltf()
    skin = g.textured_material(encoded_image(m.image, "PNG"), "image/png")
    half = len(m.faces) // 2
    g.node(mesh=g.mesh(g.primitive(m.positions, m.faces[:half], m.uvs, skin), g.primitive(m.positions, m.faces[half:])))
    with pytest.warns(MeshWarning, match="1 of 2 primitives have no base colour texture"):
        back = read_mesh(g.save(tmp_path / "part.glb"))
    assert back.uvs is None and back.image is None and back.face_count == m.face_count


def test_a_missing_texture_file_is_a_warning_as_for_obj(tmp_path):
    m = textured_sphere()
    path = single_mesh_gltf(m, encoded_image(m.image, "PNG"), "image/png", "file").save(tmp_path / "f.gltf", "file")
    (tmp_path / "skin").unlink()
    with pytest.warns(MeshWarning, match="texture file .*skin not found"):
        back = read_mesh(path)
    assert back.texture == tmp_path / "skin" and back.uvs is not None


# --------------------------------------------------------------------------- Draco


def test_a_drc_written_by_dracopy_reads_back_with_its_uvs(tmp_path):
    DracoPy = pytest.importorskip("DracoPy")
    m = textured_sphere()
    data = DracoPy.encode(m.positions.astype(np.float32), m.faces.astype(np.uint32), quantization_bits=16,
                          preserve_order=True, tex_coord=m.uvs, tex_coord_quantization_bits=16)
    (tmp_path / "f.drc").write_bytes(data)
    back = read_quietly(tmp_path / "f.drc")
    np.testing.assert_array_equal(back.faces, m.faces)
    span = np.ptp(m.positions, axis=0).max()
    np.testing.assert_allclose(back.positions, m.positions, atol=span / 2 ** 15)
    np.testing.assert_allclose(back.uvs[back.uv_faces], m.uvs[m.uv_faces], atol=1 / 2 ** 15)
    assert back.image is None and back.texture is None  # a .drc names no texture


def test_a_drc_split_at_uv_seams_is_welded(tmp_path):
    DracoPy = pytest.importorskip("DracoPy")
    m = uv_sphere(6, 8)
    split = m.positions[m.faces.ravel()]  # one point per corner, as Draco stores per-corner UVs
    uvs = np.tile([[0.1, 0.1], [0.9, 0.1], [0.5, 0.9]], (m.face_count, 1))
    data = DracoPy.encode(split.astype(np.float32), np.arange(len(split)).reshape(-1, 3).astype(np.uint32),
                          preserve_order=True, tex_coord=uvs)
    (tmp_path / "s.drc").write_bytes(data)
    back = read_quietly(tmp_path / "s.drc")
    assert back.vertex_count == m.vertex_count and back.face_count == m.face_count
    assert len(back.uvs) == 3


def test_a_drc_without_uvs_reads_its_geometry(tmp_path):
    DracoPy = pytest.importorskip("DracoPy")
    m = uv_sphere(6, 8)
    (tmp_path / "g.drc").write_bytes(DracoPy.encode(m.positions, m.faces.astype(np.uint32), preserve_order=True))
    back = read_quietly(tmp_path / "g.drc")
    assert back.uvs is None and back.face_count == m.face_count and back.vertex_count == m.vertex_count


# --------------------------------------------------------------------------- JPEG for OBJ


def test_an_obj_with_a_jpeg_texture_reads_it(tmp_path):
    m = textured_sphere()
    (tmp_path / "skin.jpg").write_bytes(encoded_image(m.image, "JPEG"))
    write_mesh(tmp_path / "f.obj", Mesh(m.positions, m.faces, m.uvs, m.uv_faces, texture=tmp_path / "skin.jpg"))
    back = read_quietly(tmp_path / "f.obj")
    assert back.texture == tmp_path / "skin.jpg"
    np.testing.assert_array_equal(read_image(back.texture), decoded_image((tmp_path / "skin.jpg").read_bytes()))


# --------------------------------------------------------------------------- sequences and the command line


def cli(*args, check=True) -> subprocess.CompletedProcess:
    p = subprocess.run([sys.executable, "-m", "dynmesh", *map(str, args)], capture_output=True, text=True)
    if check and p.returncode != 0:
        raise AssertionError(f"exit {p.returncode}: {p.stderr}")
    assert "Traceback" not in p.stderr
    return p


def write_frames(folder: Path, frames: list[Mesh], suffix: str) -> Path:
    folder.mkdir()
    for i, m in enumerate(frames):
        path = folder / f"frame_{i:03d}{suffix}"
        if suffix == ".glb":
            path.write_bytes(glb_bytes(m))
        elif suffix == ".gltf":
            single_mesh_gltf(m).save(path, "file")
        elif suffix == ".drc":
            import DracoPy

            path.write_bytes(DracoPy.encode(m.positions, m.faces.astype(np.uint32), quantization_bits=20,
                                            preserve_order=True))
        else:
            write_mesh(path, m)
    return folder


def test_a_folder_or_a_glob_of_gltf_glb_and_drc_frames_is_a_sequence(tmp_path):
    for name in ["f2.glb", "f10.glb", "f1.gltf", "f1.bin", "f3.drc", "skin.png", "notes.txt"]:
        (tmp_path / name).write_bytes(b"")
    assert [p.name for p in resolve_sequence(tmp_path)] == ["f1.gltf", "f2.glb", "f3.drc", "f10.glb"]
    assert [p.name for p in resolve_sequence(str(tmp_path / "f*.glb"))] == ["f2.glb", "f10.glb"]


@pytest.mark.parametrize("suffix", [".glb", ".gltf", ".drc"])
def test_a_sequence_of_frames_encodes_and_decodes_through_the_command_line(tmp_path, suffix):
    frames = wobbly_sequence(3, 12, 16)
    source = write_frames(tmp_path / "in", frames, suffix)
    stream, out = tmp_path / "s.dmsh", tmp_path / "out"
    encoded = json.loads(cli("encode", source, "-o", stream, "--json", "-q").stdout)
    assert [Path(f["input"]).name for f in encoded["frames"]] == [f"frame_{i:03d}{suffix}" for i in range(3)]
    cli("decode", stream, "-o", out, "-q")
    assert len(list(out.glob("frame_*.obj"))) == 3
    measured = json.loads(cli("metrics", source, out, "--grid-size", "256", "--json", "-q").stdout)
    assert len(measured["frames"]) == 3 and measured["d1_psnr"] > 50


def test_metrics_between_a_glb_sequence_and_an_obj_one(tmp_path):
    frames = wobbly_sequence(3, 12, 16)
    glb = write_frames(tmp_path / "glb", frames, ".glb")
    obj = write_frames(tmp_path / "obj", [Mesh(f32(m.positions), m.faces) for m in frames], ".obj")
    same = json.loads(cli("metrics", glb, obj, "--grid-size", "256", "--json", "-q").stdout)
    assert len(same["frames"]) == 3 and same["d1_psnr"] > 100  # the same surfaces
    moved = write_frames(tmp_path / "moved", [Mesh(m.positions + [0.01, 0, 0], m.faces) for m in frames], ".obj")
    apart = json.loads(cli("metrics", glb, moved, "--grid-size", "256", "--json", "-q").stdout)
    assert 30 < apart["d1_psnr"] < same["d1_psnr"]


@pytest.mark.parametrize("layout", ["glb", "obj"])
def test_textured_frames_with_jpeg_textures_encode_with_their_texture(tmp_path, layout):
    image = colour_field(128)
    jpeg = encoded_image(image, "JPEG")
    source = tmp_path / "in"
    source.mkdir()
    (source / "skin.jpg").write_bytes(jpeg)
    for i, m in enumerate(wobbly_sequence(2, 12, 16)):
        t = textured_sphere(12, 16, image)
        frame = Mesh(m.positions, m.faces, t.uvs, t.uv_faces)
        if layout == "glb":
            single_mesh_gltf(frame, jpeg, "image/jpeg").save(source / f"f{i}.glb")
        else:
            write_mesh(source / f"f{i}.obj", Mesh(frame.positions, frame.faces, frame.uvs, frame.uv_faces,
                                                  texture=source / "skin.jpg"))
    stream, out = tmp_path / "s.dmsh", tmp_path / "out"
    encoded = json.loads(cli("encode", source, "-o", stream, "--texture-size", "256", "--json", "-q").stdout)
    assert encoded["texture_bytes"] > 0
    cli("decode", stream, "-o", out, "-q")
    assert read_mesh(out / "frame_0000.obj").texture.name == "frame_0000.png"
    measured = json.loads(cli("metrics", source, out, "--grid-size", "256", "--json", "-q").stdout)
    assert measured["y_psnr"] > 25


# --------------------------------------------------------------------------- what cannot be read


def points_only(tmp_path: Path) -> Path:
    g = Gltf()
    g.node(mesh=g.mesh(g.primitive(uv_sphere(4, 5).positions, mode=0)))
    return g.save(tmp_path / "points.glb")


def lines_beside_triangles(tmp_path: Path) -> Path:
    m = uv_sphere(4, 5)
    g = Gltf()
    g.node(mesh=g.mesh(g.primitive(m.positions, m.faces), g.primitive(m.positions[:4], mode=1)))
    return g.save(tmp_path / "lines.glb")


def empty_scene(tmp_path: Path) -> Path:
    g = Gltf()
    g.mesh(g.primitive(uv_sphere(4, 5).positions, uv_sphere(4, 5).faces))
    g.node(name="camera rig")
    return g.save(tmp_path / "empty.glb")


def missing_bin(tmp_path: Path) -> Path:
    m = uv_sphere(4, 5)
    path = single_mesh_gltf(m).save(tmp_path / "frame.gltf", "file")
    (tmp_path / "frame data.bin").unlink()
    return path


def truncated_glb(tmp_path: Path) -> Path:
    data = glb_bytes(uv_sphere(4, 5))
    (tmp_path / "cut.glb").write_bytes(data[: len(data) // 2])
    return tmp_path / "cut.glb"


def garbage(name: str):
    def make(tmp_path: Path) -> Path:
        (tmp_path / name).write_bytes(b"\x00\x01 this is not a mesh \xff" * 20)
        return tmp_path / name
    return make


def json_edit(name: str, edit):
    def make(tmp_path: Path) -> Path:
        m = uv_sphere(4, 5)
        g = single_mesh_gltf(m)
        edit(g.doc)
        return g.save(tmp_path / name, "data" if name.endswith(".gltf") else "glb")
    return make


def index_past_the_end(tmp_path: Path) -> Path:
    m = uv_sphere(4, 5)
    faces = m.faces.copy()
    faces[3, 1] = 1000
    g = Gltf()
    g.node(mesh=g.mesh(g.primitive(m.positions, faces)))
    return g.save(tmp_path / "index.glb")


def draco_point_cloud(tmp_path: Path) -> Path:
    import DracoPy

    (tmp_path / "cloud.drc").write_bytes(DracoPy.encode(uv_sphere(4, 5).positions))
    return tmp_path / "cloud.drc"


def truncated_drc(tmp_path: Path) -> Path:
    import DracoPy

    m = uv_sphere(6, 8)
    data = DracoPy.encode(m.positions, m.faces.astype(np.uint32))
    (tmp_path / "cut.drc").write_bytes(data[: len(data) // 2])
    return tmp_path / "cut.drc"


BAD_FILES = {
    "points only": (points_only, "mesh 0 primitive 0 holds points, not triangles"),
    "lines beside triangles": (lines_beside_triangles, "mesh 0 primitive 1 holds lines, not triangles"),
    "no mesh in the scene": (empty_scene, "no faces: the glTF holds no triangles"),
    "missing .bin": (missing_bin, "buffer 0's file frame%20data.bin cannot be read"),
    "truncated glb": (truncated_glb, "truncated glTF binary"),
    "garbage glb": (garbage("x.glb"), "not a glTF binary"),
    "garbage gltf": (garbage("x.gltf"), "its JSON cannot be parsed"),
    "glTF 1.0": (json_edit("old.gltf", lambda d: d["asset"].update(version="1.0")), "dynmesh reads glTF 2.0 only"),
    "required extension": (json_edit("x.glb", lambda d: d.update(extensionsRequired=["EXT_meshopt_compression"])),
                           "needs the glTF extension EXT_meshopt_compression"),
    "accessor past its list": (json_edit("x.glb", lambda d: d["meshes"][0]["primitives"][0].update(indices=99)),
                               "corrupt glTF"),
    "view past the buffer": (json_edit("x.glb", lambda d: d["bufferViews"][0].update(byteLength=10 ** 6)),
                             "past the end of buffer 0"),
    "index past the vertices": (index_past_the_end, "has a triangle index past its"),
    "garbage drc": (garbage("x.drc"), "not a readable Draco file"),
    "truncated drc": (truncated_drc, "not a readable Draco file"),
    "draco point cloud": (draco_point_cloud, "no faces: the Draco file holds a point cloud"),
}


@pytest.mark.parametrize("case", list(BAD_FILES))
def test_a_file_that_cannot_be_read_says_what_is_wrong_and_what_to_do(tmp_path, case):
    make, fragment = BAD_FILES[case]
    path = make(tmp_path)
    with pytest.raises(MeshError) as e:
        read_mesh(path)
    assert fragment in str(e.value) and str(e.value).startswith(str(path))
    # A sentence that says what to do: every message ends with an instruction.
    assert any(word in e.value.reason for word in ("export", "encode", "keep", "convert", "copy"))


@pytest.mark.parametrize("command", ["encode", "metrics"])
@pytest.mark.parametrize("case", ["points only", "missing .bin", "truncated glb", "garbage drc"])
def test_the_command_line_reports_an_unreadable_frame_in_one_line(tmp_path, command, case):
    make, fragment = BAD_FILES[case]
    path = make(tmp_path)
    args = [path, "-o", tmp_path / "s.dmsh"] if command == "encode" else [path, path]
    p = cli(command, *args, check=False)
    assert p.returncode == 1
    assert p.stderr.startswith(f"dynmesh {command}: error: ") and fragment in p.stderr
    assert not (tmp_path / "s.dmsh").exists()


def test_a_glb_with_random_json_damage_reads_or_fails_with_a_mesh_error(tmp_path):
    """Values of every JSON member replaced by values of other types or out of range: each
    read gives a mesh or a MeshError, never another exception (which the command line would
    show as a traceback)."""
    m = textured_sphere(5, 7)
    base = single_mesh_gltf(m, encoded_image(m.image, "PNG"), "image/png")
    rng = np.random.default_rng(47)
    values = [None, -1, 0, 7, 10 ** 12, 1.5, "x", [], {}, [0, 1], {"a": 1}, True]

    def members(node, where=()):
        if isinstance(node, dict):
            for k, v in node.items():
                yield where + (k,)
                yield from members(v, where + (k,))
        elif isinstance(node, list):
            for i, v in enumerate(node):
                yield where + (i,)
                yield from members(v, where + (i,))

    paths = list(members(base.doc))
    outcomes = {"read": 0, "refused": 0}
    for trial in range(300):
        g = Gltf()
        g.doc, g.data = json.loads(json.dumps(base.doc)), bytearray(base.data)
        target = paths[rng.integers(len(paths))]
        node = g.doc
        for key in target[:-1]:
            node = node[key]
        node[target[-1]] = values[rng.integers(len(values))]
        path = g.save(tmp_path / f"t{trial}.glb")
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", MeshWarning)
                read_mesh(path)
            outcomes["read"] += 1
        except MeshError:
            outcomes["refused"] += 1
    assert outcomes["read"] > 0 and outcomes["refused"] > 0
