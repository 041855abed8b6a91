"""Mesh file reading and writing: round trips, hand-written files, errors, atomic writes."""

from __future__ import annotations

import struct
import time
import warnings

import numpy as np
import pytest

from dynmesh.io import meshio as mesh_io
from dynmesh.io import MeshError, MeshWarning, read_mesh, write_mesh
from dynmesh.mesh import Mesh

from conftest import shared_sequence, uv_sphere


def write_text(path, text: str):
    path.write_bytes(text.encode("utf-8"))
    return path


def read_quietly(path) -> Mesh:
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # an unexpected warning fails the test
        return read_mesh(path)


def hard_positions(n: int = 500, seed: int = 0) -> np.ndarray:
    """Positions whose decimal forms need all 17 digits, plus awkward special values."""
    rng = np.random.default_rng(seed)
    pos = rng.standard_normal((n, 3)) * 10.0 ** rng.integers(-30, 30, (n, 3))
    pos[0] = [-0.0, 5e-324, 1.7976931348623157e308]
    pos[1] = [0.1, 1 / 3, -2.0 / 3]
    return pos


def textured_mesh(tmp_path) -> Mesh:
    """A sphere whose UVs have their own index list (a seam: 2 UVs for some positions)."""
    sphere = uv_sphere(6, 8)
    rng = np.random.default_rng(1)
    uvs = rng.random((sphere.vertex_count + 7, 2))
    uv_faces = (sphere.faces + 7 * (sphere.faces % 2)) % len(uvs)
    texture = tmp_path / "skin.png"
    texture.write_bytes(b"not really a png")
    return Mesh(sphere.positions, sphere.faces, uvs, uv_faces, texture)


def bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, np.float64).view(np.uint64)


# --------------------------------------------------------------------------- round trips


def test_obj_round_trip_is_bit_exact(tmp_path):
    positions = hard_positions()
    mesh = Mesh(positions, np.arange(len(positions) - len(positions) % 3).reshape(-1, 3))
    write_mesh(tmp_path / "m.obj", mesh)
    back = read_quietly(tmp_path / "m.obj")
    assert np.array_equal(bits(back.positions), bits(positions))
    assert np.array_equal(back.faces, mesh.faces)
    assert back.uvs is None and back.uv_faces is None and back.texture is None


def test_obj_round_trip_keeps_uv_indices_and_texture(tmp_path):
    mesh = textured_mesh(tmp_path)
    write_mesh(tmp_path / "m.obj", mesh)
    assert "map_Kd skin.png" in (tmp_path / "m.mtl").read_text()
    back = read_quietly(tmp_path / "m.obj")
    assert np.array_equal(back.faces, mesh.faces)
    assert np.array_equal(back.uv_faces, mesh.uv_faces)
    assert not np.array_equal(back.uv_faces, back.faces)
    assert np.array_equal(bits(back.uvs), bits(mesh.uvs))
    assert back.texture == tmp_path / "skin.png"


@pytest.mark.parametrize("ascii", [False, True])
def test_ply_round_trip_is_exact(tmp_path, ascii):
    positions = hard_positions(300)
    mesh = Mesh(positions, np.arange(300).reshape(-1, 3)[::-1])
    write_mesh(tmp_path / "m.ply", mesh, ascii=ascii)
    assert (tmp_path / "m.ply").read_bytes().startswith(b"ply\nformat " + (b"ascii" if ascii else b"binary_little_endian"))
    back = read_quietly(tmp_path / "m.ply")
    assert np.array_equal(bits(back.positions), bits(positions))
    assert np.array_equal(back.faces, mesh.faces)


@pytest.mark.parametrize("ascii", [False, True])
def test_ply_round_trip_keeps_per_vertex_and_per_corner_uvs(tmp_path, ascii):
    sphere = uv_sphere(5, 7)
    per_vertex = Mesh(sphere.positions, sphere.faces, sphere.positions[:, :2] * 0.5 + 0.5, sphere.faces)
    write_mesh(tmp_path / "v.ply", per_vertex, ascii=ascii)
    back = read_quietly(tmp_path / "v.ply")
    assert np.array_equal(back.uvs, per_vertex.uvs) and np.array_equal(back.uv_faces, back.faces)

    seam = textured_mesh(tmp_path)
    write_mesh(tmp_path / "c.ply", seam, ascii=ascii)
    back = read_quietly(tmp_path / "c.ply")
    assert np.array_equal(back.faces, seam.faces)
    assert np.array_equal(back.uvs[back.uv_faces], seam.uvs[seam.uv_faces])  # same UV at every corner
    assert back.texture == tmp_path / "skin.png"


def test_big_files_round_trip_in_every_format(tmp_path):
    sphere = uv_sphere(80, 120)  # more rows than one write chunk holds
    for name, ascii in [("a.obj", False), ("b.ply", False), ("c.ply", True)]:
        write_mesh(tmp_path / name, sphere, ascii=ascii)
        back = read_quietly(tmp_path / name)
        assert np.array_equal(back.positions, sphere.positions) and np.array_equal(back.faces, sphere.faces)



def test_floats_are_written_as_python_repr():
    """The Rust writer's text is Python's repr, so files match what the %r writer produced."""
    rng = np.random.default_rng(3)
    values = rng.integers(0, 2**64, (4000, 3), dtype=np.uint64).view(np.float64)
    values[~np.isfinite(values)] = 0.5
    values[:4] = [[0.0001, 1e-05, 1e16], [1e15, -0.0, 123456789.0], [5e-324, 0.1, 2.5e-5], [1e22, 1.5, -7.0]]
    expected = "".join("v %r %r %r\n" % tuple(row) for row in values.tolist())
    assert mesh_io._core.format_rows(values, "v").decode() == expected
    assert mesh_io._core.format_rows(values, "").decode() == expected.replace("v ", "")


def test_obj_text_is_what_the_format_says(tmp_path):
    mesh = Mesh([[0.1, 1e-05, 1e16], [1.0, -0.0, 2.5], [3.0, 4.0, 5.0]], [[0, 1, 2]], [[0.5, 0.25], [1.0, 0.0]], [[1, 0, 1]])
    write_mesh(tmp_path / "m.obj", mesh)
    assert (tmp_path / "m.obj").read_text() == (
        "# written by dynmesh\nv 0.1 1e-05 1e+16\nv 1.0 -0.0 2.5\nv 3.0 4.0 5.0\nvt 0.5 0.25\nvt 1.0 0.0\nf 1/2 2/1 3/2\n")


@pytest.mark.parametrize("ascii", [False, True])
def test_ply_text_is_what_the_format_says(tmp_path, ascii):
    mesh = Mesh([[0.1, 1e-05, 1e16], [1.0, -0.0, 2.5], [3.0, 4.0, 5.0]], [[0, 1, 2]])
    write_mesh(tmp_path / "m.ply", mesh, ascii=ascii)
    header = (f"ply\nformat {'ascii' if ascii else 'binary_little_endian'} 1.0\ncomment written by dynmesh\n"
              "element vertex 3\nproperty double x\nproperty double y\nproperty double z\n"
              "element face 1\nproperty list uchar int vertex_indices\nend_header\n").encode()
    if ascii:
        body = b"0.1 1e-05 1e+16\n1.0 -0.0 2.5\n3.0 4.0 5.0\n3 0 1 2\n"
    else:
        body = mesh.positions.astype("<f8").tobytes() + struct.pack("<B3i", 3, 0, 1, 2)
    assert (tmp_path / "m.ply").read_bytes() == header + body


# --------------------------------------------------------------------------- hand-written OBJ

CUBE_QUADS = """# a cube made of quads
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
v 1 0 1
v 1 1 1
v 0 1 1
f 1 4 3 2
f 5 6 7 8
f 1 2 6 5
f 2 3 7 6
f 3 4 8 7
f 4 1 5 8
"""


def test_quads_are_fan_triangulated_with_one_warning(tmp_path):
    path = write_text(tmp_path / "cube.obj", CUBE_QUADS + "f 1 2 3 4 5\n")
    with pytest.warns(MeshWarning) as caught:
        mesh = read_mesh(path)
    assert len(caught) == 1
    assert "7 polygon" in str(caught[0].message) and str(path) in str(caught[0].message)
    assert mesh.face_count == 6 * 2 + 3
    assert mesh.faces[:2].tolist() == [[0, 3, 2], [0, 2, 1]]
    assert mesh.faces[-3:].tolist() == [[0, 1, 2], [0, 2, 3], [0, 3, 4]]


def test_negative_indices_count_back_from_the_face_line(tmp_path):
    path = write_text(tmp_path / "neg.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 0 0 1\nf -4 -1 -2\n")
    mesh = read_quietly(path)
    assert mesh.faces.tolist() == [[0, 1, 2], [0, 3, 2]]



def test_uv_index_lists_are_kept_separate_and_may_be_negative(tmp_path):
    text = ("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0.25 0.5\nvt 0.75 0.5\n"
            "f 1/2 2/1 3/2\nvt 0 1\nf 4/-1 3/-2 2/-3\n")
    mesh = read_quietly(write_text(tmp_path / "uv.obj", text))
    assert mesh.faces.tolist() == [[0, 1, 2], [3, 2, 1]]
    assert mesh.uv_faces.tolist() == [[1, 0, 1], [2, 1, 0]]
    assert mesh.uvs.tolist() == [[0.25, 0.5], [0.75, 0.5], [0.0, 1.0]]


def test_corners_without_uvs_drop_the_uvs_with_a_warning(tmp_path):
    path = write_text(tmp_path / "some.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1\nf 1 2 3\n")
    with pytest.warns(MeshWarning, match="some face corners have texture coordinates"):
        mesh = read_mesh(path)
    assert mesh.uvs is None and mesh.uv_faces is None and mesh.face_count == 2


def test_python_number_forms_bom_and_unicode_spaces_are_read(tmp_path):
    text = "\ufeffv 1_000.5 +2 .5\nv 1e2\u00a00 -0.0\nv 0 1 0\nf +1 2 3\n"
    mesh = read_quietly(write_text(tmp_path / "forms.obj", text))
    assert mesh.positions.tolist() == [[1000.5, 2.0, 0.5], [100.0, 0.0, -0.0], [0.0, 1.0, 0.0]]
    assert mesh.faces.tolist() == [[0, 1, 2]]


def test_all_face_corner_forms_agree(tmp_path):
    head = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvt 0 0\nvt 1 0\nvt 0 1\nvt 1 1\nvn 0 0 1\n"
    plain = read_quietly(write_text(tmp_path / "a.obj", head + "f 1 2 3\nf 1 3 4\n"))
    normals = read_quietly(write_text(tmp_path / "b.obj", head + "f 1//1 2//1 3//1\nf 1//1 3//1 4//1\n"))
    full = read_quietly(write_text(tmp_path / "c.obj", head + "f 1/4/1 2/3/1 3/2/1\nf 1/4/1 3/2/1 4/1/1\n"))
    mixed = read_quietly(write_text(tmp_path / "d.obj", head + "f 1/4 2/3/1 3/2/1\nf 1/4/1 3/2 4/1\n"))
    assert plain.faces.tolist() == normals.faces.tolist() == full.faces.tolist() == [[0, 1, 2], [0, 2, 3]]
    assert normals.uvs is None
    assert full.uv_faces.tolist() == mixed.uv_faces.tolist() == [[3, 2, 1], [3, 1, 0]]
    assert np.array_equal(mixed.faces, full.faces)


def test_extra_vertex_values_comments_crlf_and_odd_spacing_are_tolerated(tmp_path):
    text = "# colours after xyz\r\nv 0 0 0 1 0 0\r\n  v\t1 0 0 0.5 0.5 0.5\r\nv 0 1 0\r\n\r\no thing\r\ng group\r\ns 1\r\nf 1 2 3\r\n"
    mesh = read_quietly(write_text(tmp_path / "odd.obj", text))
    assert mesh.positions.tolist() == [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
    assert mesh.faces.tolist() == [[0, 1, 2]]


def test_inline_comments_and_line_continuations_give_the_same_mesh(tmp_path):
    sphere = uv_sphere(6, 8)
    write_mesh(tmp_path / "plain.obj", sphere)
    lines = (tmp_path / "plain.obj").read_text().split("\n")
    first_v = next(i for i, line in enumerate(lines) if line.startswith("v "))
    first_f = next(i for i, line in enumerate(lines) if line.startswith("f "))
    lines[first_v] += "  # an inline comment"
    lines[first_f] = lines[first_f].replace("f ", "f \\\n", 1)  # a continued line
    slow = read_quietly(write_text(tmp_path / "odd.obj", "\n".join(lines)))
    assert np.array_equal(slow.positions, sphere.positions) and np.array_equal(slow.faces, sphere.faces)


def test_texture_of_the_used_material_is_resolved_relative_to_the_mtl(tmp_path):
    (tmp_path / "materials" / "images").mkdir(parents=True)
    write_text(tmp_path / "materials" / "lib.mtl",
               "newmtl skin\nKd 1 1 1\nmap_Kd images/skin.png\n\nnewmtl cloth\nmap_Kd -s 1 1 1 -bm 0.5 images/cloth.png\n")
    (tmp_path / "materials" / "images" / "cloth.png").write_bytes(b"x")
    path = write_text(tmp_path / "m.obj", "mtllib materials/lib.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nusemtl cloth\nf 1/1 2/1 3/1\n")
    mesh = read_quietly(path)
    assert mesh.texture == tmp_path / "materials" / "images" / "cloth.png"
    assert mesh.uv_faces.tolist() == [[0, 0, 0]]


def test_missing_material_library_or_texture_is_a_warning(tmp_path):
    body = "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n"
    with pytest.warns(MeshWarning, match="nowhere.mtl"):
        mesh = read_mesh(write_text(tmp_path / "a.obj", "mtllib nowhere.mtl\n" + body))
    assert mesh.texture is None and mesh.face_count == 1
    write_text(tmp_path / "b.mtl", "newmtl a\nmap_Kd gone.png\n")
    with pytest.warns(MeshWarning, match="gone.png"):
        mesh = read_mesh(write_text(tmp_path / "b.obj", "mtllib b.mtl\n" + body))
    assert mesh.texture == tmp_path / "gone.png"


# --------------------------------------------------------------------------- hand-written PLY

def ply_header(fmt: str, nv: int, nf: int, vertex_props: str, face_prop: str) -> bytes:
    return (f"ply\nformat {fmt} 1.0\ncomment hand made\nelement vertex {nv}\n{vertex_props}"
            f"element face {nf}\n{face_prop}\nend_header\n").encode()


def test_big_endian_ply_with_odd_types_and_quads(tmp_path):
    props = "property float x\nproperty float y\nproperty float z\nproperty uchar red\nproperty float s\nproperty float t\n"
    header = ply_header("binary_big_endian", 4, 2, props, "property list ushort uint vertex_index")
    body = b"".join(struct.pack(">fffBff", *p, 7, p[0], p[1]) for p in [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)])
    body += struct.pack(">HIIII", 4, 0, 1, 2, 3) + struct.pack(">HIII", 3, 2, 1, 0)
    path = tmp_path / "be.ply"
    path.write_bytes(header + body)
    with pytest.warns(MeshWarning, match="1 polygon"):
        mesh = read_mesh(path)
    assert mesh.positions.tolist() == [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]
    assert mesh.faces.tolist() == [[0, 1, 2], [0, 2, 3], [2, 1, 0]]
    assert np.array_equal(mesh.uvs, mesh.positions[:, :2]) and np.array_equal(mesh.uv_faces, mesh.faces)


def test_ascii_ply_with_mixed_polygons_and_extra_elements(tmp_path):
    text = ("ply\nformat ascii 1.0\nelement vertex 5\nproperty double x\nproperty double y\nproperty double z\n"
            "element face 2\nproperty uchar flags\nproperty list uchar int vertex_indices\n"
            "element edge 1\nproperty int a\nproperty int b\nend_header\n"
            "0 0 0\n1 0 0\n1 1 0\n\n0 1 0\n0 0 1\n9 4 0 1 2 3\n9 3 0 1 4\n0 1\n")
    with pytest.warns(MeshWarning):
        mesh = read_mesh(write_text(tmp_path / "a.ply", text))
    assert mesh.faces.tolist() == [[0, 1, 2], [0, 2, 3], [0, 1, 4]]


# --------------------------------------------------------------------------- errors

TRIANGLE = "v 0 0 0\nv 1 0 0\nv 0 1 0\n"


@pytest.mark.parametrize("text, line, fragment", [
    (TRIANGLE + "v 1 x 3\nf 1 2 3\n", 4, "bad number"),
    (TRIANGLE + "f 1 2 4\n", 4, "out of range"),
    (TRIANGLE + "f 1 2 0\n", 4, "is 0"),
    (TRIANGLE + "f -1 -2 -4\n", 4, "out of range"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 3.5\n", 5, "bad index"),
    (TRIANGLE + "f 1 2\n", 4, "at least 3 corners"),
    ("v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", 2, "not finite"),
    ("v 0 0 0\nv 1 0 0\nv 0 1e999 0\nf 1 2 3\n", 3, "not finite"),
    (TRIANGLE + "vt 0 0\nf 1/1 2/1 3/2\n", 5, "texture index"),
    (TRIANGLE + "v 1 2\nf 1 2 3\n", 4, "needs at least 3 numbers"),
    (TRIANGLE + "f 1/2/3/4 2 3\n", 4, "bad face corner '1/2/3/4'"),
    (TRIANGLE + "f /1 2 3\n", 4, "bad face corner '/1'"),
    (TRIANGLE + "vt 0 0\nf 1/1 2/x 3/1\n", 5, "bad index 'x'"),
    (TRIANGLE + "f 1 2 \\\n 3 4\n", 4, "vertex index 4 is out of range (1..3 or -1..-3)"),
    ("v 0 0 0 # ok\nv 1 0 0\nv 0 1 0\nvt 0 nan\nf 1/1 2/1 3/1\n", 4, "texture coordinate is not finite: [0.0, nan]"),
])
def test_obj_errors_name_file_and_line(tmp_path, text, line, fragment):
    path = write_text(tmp_path / "bad.obj", text)
    with pytest.raises(MeshError) as e:
        read_mesh(path)
    assert e.value.line == line
    assert str(path) in str(e.value) and f"line {line}" in str(e.value) and fragment in str(e.value)


def test_error_line_is_exact_deep_in_a_big_file(tmp_path):
    sphere = uv_sphere(40, 60)
    write_mesh(tmp_path / "big.obj", sphere)
    lines = (tmp_path / "big.obj").read_text().split("\n")
    lines[1500] = "v 0.5 0.25 0.5.5"
    with pytest.raises(MeshError) as e:
        read_mesh(write_text(tmp_path / "bad.obj", "\n".join(lines)))
    assert e.value.line == 1501 and "0.5.5" in str(e.value)



def _outcome(path):
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            m = read_mesh(path)
    except MeshError as e:
        return ("error", e.reason, e.line)
    arrays = [None if a is None else a.tobytes() for a in (m.positions, m.faces, m.uvs, m.uv_faces)]
    return ("ok", arrays, m.texture, [str(w.message).removeprefix(f"{path}: ") for w in caught])


def test_big_files_parse_in_pieces_as_in_one_pass(tmp_path):
    """Files of several MB are cut into pieces parsed in parallel; a backslash anywhere keeps
    the one-pass parse, so each variant is read both ways and must come out the same."""
    rng = np.random.default_rng(5)
    n = 40000
    lines = ["mtllib lib.mtl"]
    for i in range(n):  # interleaved, with relative indices reaching back across pieces
        lines += [f"v {x!r} {y!r} {z!r}" for x, y, z in rng.random((3, 3)).tolist()]
        lines += [f"vt {rng.random()!r} {rng.random()!r}", f"usemtl m{i % 3}"]
        lines.append(f"f -3/-1 -2/-1 {-3 - int(rng.integers(0, 3 * i + 1))}/-1" if i else "f -3/-1 -2/-1 -1/-1")
    write_text(tmp_path / "lib.mtl", "newmtl m1\nmap_Kd one.png\n")
    bad_number, bad_index, not_finite = list(lines), list(lines), list(lines)
    bad_number[len(lines) * 3 // 4] = "v 1 2 0.5.5"
    bad_index[len(lines) // 2 + 3] = "f 1 2 999999"
    not_finite[len(lines) * 2 // 3] = "v 1 nan 2"
    for variant in (lines, bad_number, bad_index, not_finite):
        text = "\n".join(variant) + "\n"
        assert len(text) > 4 << 20
        pieces = _outcome(write_text(tmp_path / "pieces.obj", text))
        one_pass = _outcome(write_text(tmp_path / "one_pass.obj", text + "# one pass: \\\n"))
        assert pieces == one_pass
    assert pieces[0] == "error" and pieces[2] == len(lines) * 2 // 3 + 1


@pytest.mark.parametrize("name, content, fragment", [
    ("none.obj", None, "cannot read"),
    ("mesh.stl", "solid x", "unknown mesh format"),
    ("empty.obj", TRIANGLE, "no faces"),
    ("empty.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                  "property float z\nend_header\n0 0 0\n", "no faces"),
])
def test_file_level_errors_name_the_file(tmp_path, name, content, fragment):
    path = tmp_path / name
    if content is not None:
        write_text(path, content)
    with pytest.raises(MeshError, match=fragment) as e:
        read_mesh(path)
    assert str(path) in str(e.value) and e.value.line is None


@pytest.mark.parametrize("header, line", [
    ("plx\nformat ascii 1.0\nend_header\n", 1),
    ("ply\nformat ascii 1.0\nelement vertex 3\nproperty floaty x\nend_header\n", 4),
    ("ply\nformat ascii 1.0\nelement vertex three\nend_header\n", 3),
    ("ply\nformat ascii 1.0\nelement face 1\nproperty list float int vertex_indices\nend_header\n", 4),
    ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n", None),
])
def test_bad_ply_header_is_an_error_with_its_line(tmp_path, header, line):
    path = write_text(tmp_path / "bad.ply", header)
    with pytest.raises(MeshError, match="PLY") as e:
        read_mesh(path)
    assert e.value.line == line and str(path) in str(e.value)


@pytest.mark.parametrize("body, line, fragment", [
    ("0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 3\n", 15, "out of range"),
    ("0 0 0\n1 0 oops\n0 1 0\n3 0 1 2\n3 0 1 2\n", 12, "bad number"),
    ("0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1\n", 15, "values, expected"),
    ("0 0 0\n1 0 inf\n0 1 0\n3 0 1 2\n3 0 1 2\n", 12, "not finite"),
])
def test_ascii_ply_errors_name_the_line(tmp_path, body, line, fragment):
    header = ply_header("ascii", 3, 2, "property float x\nproperty float y\nproperty float z\n", "property list uchar int vertex_indices")
    path = tmp_path / "bad.ply"
    path.write_bytes(header + body.encode())
    with pytest.raises(MeshError, match=fragment) as e:
        read_mesh(path)
    assert e.value.line == line and f"line {line}" in str(e.value)


def test_every_truncation_of_a_binary_ply_is_an_error(tmp_path):
    sphere = uv_sphere(4, 5)
    write_mesh(tmp_path / "full.ply", sphere)
    data = (tmp_path / "full.ply").read_bytes()
    body = data.index(b"end_header\n") + len(b"end_header\n")
    for cut in range(body, len(data), 7):
        (tmp_path / "cut.ply").write_bytes(data[:cut])
        with pytest.raises(MeshError, match="truncated binary PLY"):
            read_mesh(tmp_path / "cut.ply")


def test_truncated_ragged_binary_ply_is_an_error(tmp_path):
    header = ply_header("binary_little_endian", 3, 2, "property float x\nproperty float y\nproperty float z\n", "property list uchar int vertex_indices")
    body = struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0) + struct.pack("<B3i", 3, 0, 1, 2) + struct.pack("<B2i", 4, 0, 1)
    (tmp_path / "t.ply").write_bytes(header + body)
    with pytest.raises(MeshError, match="truncated binary PLY.*face"):
        read_mesh(tmp_path / "t.ply")


def test_binary_ply_index_error_names_the_face(tmp_path):
    header = ply_header("binary_little_endian", 3, 1, "property float x\nproperty float y\nproperty float z\n", "property list uchar int vertex_indices")
    (tmp_path / "i.ply").write_bytes(header + struct.pack("<9f", *range(9)) + struct.pack("<B3i", 3, 0, 1, 3))
    with pytest.raises(MeshError, match="face 0: vertex index 3 is out of range"):
        read_mesh(tmp_path / "i.ply")



def test_ply_list_length_errors(tmp_path):
    header = ply_header("ascii", 3, 1, "property float x\nproperty float y\nproperty float z\n", "property list uchar int vertex_indices")
    (tmp_path / "a.ply").write_bytes(header + b"0 0 0\n1 0 0\n0 1 0\n2.5 0 1 2\n")
    with pytest.raises(MeshError, match="bad list length in 'face'") as e:
        read_mesh(tmp_path / "a.ply")
    assert e.value.line == 14
    header = ply_header("binary_little_endian", 3, 1, "property float x\nproperty float y\nproperty float z\n", "property list char int vertex_indices")
    (tmp_path / "b.ply").write_bytes(header + struct.pack("<9f", *range(9)) + struct.pack("<b3i", -3, 0, 1, 2))
    with pytest.raises(MeshError, match="negative list length in 'face' record 0") as e:
        read_mesh(tmp_path / "b.ply")
    assert e.value.line is None


def test_ply_ragged_binary_lists_and_per_corner_uvs(tmp_path):
    header = ply_header("binary_little_endian", 4, 2, "property double x\nproperty double y\nproperty double z\n",
                        "property list uchar int vertex_indices\nproperty list uchar float texcoord")
    body = struct.pack("<12d", 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0)
    body += struct.pack("<B4iB8f", 4, 0, 1, 2, 3, 8, 0, 0, 1, 0, 1, 1, 0, 1)
    body += struct.pack("<B3iB6f", 3, 2, 1, 0, 6, 1, 1, 1, 0, 0.5, 0.5)
    (tmp_path / "r.ply").write_bytes(header + body)
    with pytest.warns(MeshWarning, match="1 polygon"):
        mesh = read_mesh(tmp_path / "r.ply")
    assert mesh.faces.tolist() == [[0, 1, 2], [0, 2, 3], [2, 1, 0]]
    assert mesh.uvs.tolist() == [[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]]  # first use order, shared where equal
    assert mesh.uv_faces.tolist() == [[0, 1, 2], [0, 2, 3], [2, 1, 4]]


def test_parser_errors_carry_message_and_line():
    with pytest.raises(mesh_io._core.MeshFormatError) as e:
        mesh_io._core.read_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n")
    assert e.value.args == ("bad index 'x'", 4)
    with pytest.raises(mesh_io._core.MeshFormatError) as e:
        mesh_io._core.read_ply(b"ply\nformat ascii 1.0\nend_header\n")
    assert e.value.args == ("PLY has no 'vertex' element", None)


def test_mesh_errors_survive_pickling():
    import pickle

    error = pickle.loads(pickle.dumps(MeshError("a.obj", "bad number", 3)))
    assert isinstance(error, MeshError) and error.line == 3 and str(error) == "a.obj: line 3: bad number"


# --------------------------------------------------------------------------- texture images


def noisy_image(h: int = 37, w: int = 53, seed: int = 2) -> np.ndarray:
    """RGB that is smooth in places and noisy in others (every row filter gets used)."""
    rng = np.random.default_rng(seed)
    ramp = (np.arange(w)[None, :, None] * 4 + np.arange(h)[:, None, None] * 3 + [0, 60, 120]) % 256
    return np.where(rng.random((h, w, 1)) < 0.3, rng.integers(0, 256, (h, w, 3)), ramp).astype(np.uint8)


def pillow_rgb(path) -> np.ndarray:
    from PIL import Image

    with Image.open(path) as im:
        return np.asarray(im.convert("RGB"))


def test_written_images_are_lossless_pngs_that_pillow_and_our_reader_read(tmp_path):
    image = noisy_image()
    mesh_io.write_image(tmp_path / "t.png", image)
    assert (tmp_path / "t.png").read_bytes().startswith(b"\x89PNG\r\n\x1a\n")
    assert np.array_equal(pillow_rgb(tmp_path / "t.png"), image)
    assert np.array_equal(mesh_io.read_image(tmp_path / "t.png"), image)
    # Any array layout and a plain list of rows give the same file.
    mesh_io.write_image(tmp_path / "f.png", np.asfortranarray(image))
    mesh_io.write_image(tmp_path / "l.png", image.tolist())
    assert (tmp_path / "f.png").read_bytes() == (tmp_path / "l.png").read_bytes() == (tmp_path / "t.png").read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.png", "l.png", "t.png"]  # no temporary file left


def test_image_write_failures_name_the_file_and_leave_nothing(tmp_path):
    target = tmp_path / "missing" / "t.png"
    with pytest.raises(FileNotFoundError) as e:
        mesh_io.write_image(target, noisy_image())
    assert e.value.filename == str(target)
    (tmp_path / "old.png").write_bytes(b"old")
    with pytest.raises(ValueError, match="H, W, 3"):
        mesh_io.write_image(tmp_path / "old.png", np.zeros((4, 4), np.uint8))
    assert (tmp_path / "old.png").read_bytes() == b"old" and [p.name for p in tmp_path.iterdir()] == ["old.png"]


@pytest.mark.parametrize("mode", ["RGB", "RGBA", "L", "LA", "P", "P+transparency", "1", "JPEG"])
def test_read_image_gives_what_pillow_gives(tmp_path, mode):
    """8-bit PNGs are decoded by the core, the rest by Pillow: the pixels are Pillow's either way."""
    from PIL import Image

    rgb = Image.fromarray(noisy_image())
    path = tmp_path / ("t.jpg" if mode == "JPEG" else "t.png")
    if mode == "JPEG":
        rgb.save(path, quality=90)
    elif mode == "P+transparency":
        rgb.quantize(37).save(path, transparency=3)
    elif mode == "RGBA":
        a = rgb.copy()
        a.putalpha(Image.fromarray(noisy_image(seed=5)[..., 0]))
        a.save(path)
    elif mode == "P":
        rgb.quantize(200).save(path)
    else:
        rgb.convert(mode).save(path)
    got = mesh_io.read_image(path)
    assert got.dtype == np.uint8 and got.flags.c_contiguous and got.flags.writeable
    assert np.array_equal(got, pillow_rgb(path))


def test_16_bit_grey_images_are_scaled_to_8_bits_not_clipped(tmp_path):
    """Pillow opens a 16-bit grey PNG in a mode whose conversion to RGB clips at 255, which
    made a dark texture white; the values are scaled instead (and 16-bit colour, which
    Pillow reduces itself, agrees)."""
    from PIL import Image

    grey16 = (np.arange(64 * 48, dtype=np.uint32).reshape(48, 64) * 21).astype(np.uint16)
    Image.fromarray(grey16).save(tmp_path / "g.png")
    got = mesh_io.read_image(tmp_path / "g.png")
    expected = np.rint(grey16 / 257.0).astype(np.uint8)
    assert got.shape == (48, 64, 3) and got.dtype == np.uint8
    assert all(np.array_equal(got[..., k], expected) for k in range(3))
    with pytest.raises(MeshError, match="floating-point"):
        Image.fromarray(grey16.astype(np.float32)).save(tmp_path / "f.tif")
        mesh_io.read_image(tmp_path / "f.tif")


def test_unreadable_images_are_mesh_errors_naming_the_file(tmp_path):
    for name, data in [("bad.png", b"\x89PNG\r\n\x1a\nnot a png at all"), ("bad.jpg", b"neither"), ("empty.png", b"")]:
        (tmp_path / name).write_bytes(data)
        with pytest.raises(MeshError, match="cannot read texture image") as e:
            mesh_io.read_image(tmp_path / name)
        assert e.value.path == tmp_path / name
    with pytest.raises(MeshError, match="No such file") as e:
        mesh_io.read_image(tmp_path / "gone.png")
    assert e.value.path == tmp_path / "gone.png"
    # A PNG cut short: Pillow's verdict, as before the core read PNGs.
    mesh_io.write_image(tmp_path / "cut.png", noisy_image())
    data = (tmp_path / "cut.png").read_bytes()
    (tmp_path / "cut.png").write_bytes(data[: len(data) // 2])
    with pytest.raises(MeshError, match="cannot read texture image"):
        mesh_io.read_image(tmp_path / "cut.png")


def test_glb_embeds_the_texture_losslessly():
    import io
    import json
    import struct

    from dynmesh.io import glb_bytes

    sphere = uv_sphere(6, 8)
    image = noisy_image(16, 24)
    mesh = Mesh(sphere.positions, sphere.faces, np.random.default_rng(3).random((sphere.vertex_count, 2)), image=image)
    data = glb_bytes(mesh)
    (n,) = struct.unpack_from("<I", data, 12)
    doc, binary = json.loads(data[20:20 + n]), data[28 + n:]
    view = doc["bufferViews"][doc["images"][0]["bufferView"]]
    png = binary[view["byteOffset"]:view["byteOffset"] + view["byteLength"]]
    assert np.array_equal(pillow_rgb(io.BytesIO(png)), image)


# --------------------------------------------------------------------------- atomic writes


def test_write_leaves_no_temporary_file(tmp_path):
    for name in ("a.obj", "b.ply"):
        write_mesh(tmp_path / name, textured_mesh(tmp_path))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.mtl", "a.obj", "b.ply", "skin.png"]


def test_failed_write_keeps_the_old_file_and_cleans_up(tmp_path, monkeypatch):
    target = tmp_path / "m.obj"
    write_mesh(target, uv_sphere(4, 5))
    before = target.read_bytes()
    written = []

    def failing_faces(*args):
        written.extend(p.stat().st_size for p in tmp_path.iterdir() if p.name.endswith(".tmp"))
        raise RuntimeError("disk on fire")

    monkeypatch.setattr(mesh_io, "_obj_face_text", failing_faces)
    with pytest.raises(RuntimeError, match="disk on fire"):
        write_mesh(target, uv_sphere(40, 60))  # big enough for the vertices to reach the disk
    assert written and written[0] > 0  # the failure really came mid-write, vertices already out
    assert target.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["m.obj"]


def test_invalid_mesh_is_refused_before_anything_is_written(tmp_path):
    bad = Mesh(np.zeros((3, 3)), np.array([[0, 1, 3]]))
    with pytest.raises(MeshError, match="out of range"):
        write_mesh(tmp_path / "bad.ply", bad)
    with pytest.raises(MeshError, match="non-finite"):
        write_mesh(tmp_path / "bad.obj", Mesh(np.full((3, 3), np.nan), np.array([[0, 1, 2]])))
    with pytest.raises(MeshError, match="unknown mesh format"):
        write_mesh(tmp_path / "bad.off", uv_sphere(4, 5))
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------- real data


def test_reads_the_shared_textured_basketball_frame():
    path = shared_sequence("basketball_textured") / "basketball_player_00000001.obj"
    start = time.perf_counter()
    mesh = read_quietly(path)
    print(f"\nread {path.name}: {mesh.vertex_count} vertices, {mesh.face_count} faces in {time.perf_counter() - start:.3f} s")
    assert mesh.uvs is not None and mesh.uv_faces.shape == mesh.faces.shape
    assert mesh.texture == path.with_suffix(".png") and mesh.texture.is_file()
    # This export already splits positions along UV seams, so every corner's vt index
    # equals its v index: check the UV indices against the file itself instead.
    corners = [c.split("/") for line in path.read_text().splitlines() if line.startswith("f ") for c in line.split()[1:]]
    assert np.array_equal(mesh.uv_faces.reshape(-1), [int(c[1]) - 1 for c in corners])
    assert np.array_equal(mesh.faces.reshape(-1), [int(c[0]) - 1 for c in corners])
    assert len(np.unique(mesh.positions, axis=0)) < mesh.vertex_count  # seam copies are kept


def test_a_fortran_ordered_texture_is_written_pixel_for_pixel(tmp_path):
    # The core's PNG writer reads its array as a C-ordered slice: write_image hands it one.
    from dynmesh.io import read_image, write_image

    image = np.random.default_rng(5).integers(0, 256, (6, 10, 3), dtype=np.uint8)
    write_image(tmp_path / "f.png", np.asfortranarray(image))
    assert np.array_equal(read_image(tmp_path / "f.png"), image)


def test_the_core_reads_fortran_ordered_arrays_row_by_row():
    # A Fortran-ordered array is contiguous in memory too, but column by column: the core
    # must read it by rows (it once borrowed the memory as it lay and scrambled the rows).
    from dynmesh import _core

    rng = np.random.default_rng(6)
    rows = rng.random((5, 3))
    faces = rng.integers(0, 5, (4, 3))
    assert bytes(_core.format_rows(np.asfortranarray(rows), "v")) == bytes(_core.format_rows(rows, "v"))
    assert bytes(_core.format_obj_faces(np.asfortranarray(faces), None)) == bytes(_core.format_obj_faces(faces, None))
    image = rng.integers(0, 256, (6, 10, 3), dtype=np.uint8)
    assert bytes(_core.encode_png(np.asfortranarray(image))) == bytes(_core.encode_png(image))
