"""No input is ever lost, failed commands leave nothing behind, damaged streams still play."""

import os
import struct
import subprocess
import sys
import zlib

import numpy as np
import pytest

import dynmesh
from dynmesh.io import write_mesh

from conftest import one_line_error, wobbly_sequence


def run(*args):
    return subprocess.run([sys.executable, "-m", "dynmesh", *map(str, args)], capture_output=True, text=True)


@pytest.fixture(scope="module")
def frames_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("in")
    for i, m in enumerate(wobbly_sequence(4, 10, 14)):
        write_mesh(d / f"f{i}.obj", m)
    return d


def unit_starts(data: bytes) -> list[int]:
    """Start offset of every unit (frame and texture) after the header."""
    pos = 75 + 3 * data[43]  # the header length (docs/bitstream.md section 2)
    starts = []
    while pos < len(data):
        starts.append(pos)
        pos += 9 + struct.unpack_from("<I", data, pos + 1)[0]
    return starts


# --------------------------------------------------------------------------- inputs kept


@pytest.mark.parametrize("how", ["same path", "other spelling", "symlink", "hard link"])
def test_encode_never_overwrites_an_input_frame(tmp_path, frames_dir, how):
    frame = tmp_path / "frame.obj"
    frame.write_bytes((frames_dir / "f0.obj").read_bytes())
    before = frame.read_bytes()
    out = {"same path": frame, "other spelling": tmp_path / "." / ".." / tmp_path.name / "frame.obj",
           "symlink": tmp_path / "link.obj", "hard link": tmp_path / "hard.obj"}[how]
    if how == "symlink":
        out.symlink_to(frame)
    elif how == "hard link":
        os.link(frame, out)
    one_line_error(run("encode", frame, "-o", out), "refusing to overwrite")
    assert frame.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted({"frame.obj", out.name})


def test_encode_refuses_to_write_over_one_frame_of_a_sequence(tmp_path, frames_dir):
    before = (frames_dir / "f2.obj").read_bytes()
    one_line_error(run("encode", frames_dir, "-o", frames_dir / "f2.obj"), "f2.obj")
    assert (frames_dir / "f2.obj").read_bytes() == before


def test_decode_never_overwrites_its_stream(tmp_path, frames_dir):
    stream = tmp_path / "s.dmsh"
    assert run("encode", frames_dir, "-o", stream, "-q").returncode == 0
    before = stream.read_bytes()
    one_line_error(run("decode", stream, "-o", stream), "refusing")
    # A stream named like a decoded frame, inside the output directory.
    out = tmp_path / "out"
    out.mkdir()
    (out / "frame_0001.obj").write_bytes(before)
    one_line_error(run("decode", out / "frame_0001.obj", "-o", out), "refusing")
    assert stream.read_bytes() == before and (out / "frame_0001.obj").read_bytes() == before
    assert sorted(p.name for p in out.iterdir()) == ["frame_0001.obj"]


def test_a_failed_decode_leaves_no_directory_and_no_partial_frames(tmp_path, frames_dir):
    stream = tmp_path / "s.dmsh"
    assert run("encode", frames_dir, "-o", stream, "-q").returncode == 0
    data = bytearray(stream.read_bytes())
    data[unit_starts(bytes(data))[2] + 20] ^= 0x10
    stream.write_bytes(bytes(data))
    out = tmp_path / "new" / "deeper" / "out"
    one_line_error(run("decode", stream, "-o", out), "frame 2", "--skip-damaged")
    assert not (tmp_path / "new").exists()
    existing = tmp_path / "existing"
    existing.mkdir()
    (existing / "keep.txt").write_text("mine")
    one_line_error(run("decode", stream, "-o", existing), "frame 2")
    assert [p.name for p in existing.iterdir()] == ["keep.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["existing", "s.dmsh"]


def test_an_unwritable_output_is_reported_by_the_users_path(tmp_path, frames_dir):
    out = tmp_path / "missing_dir" / "s.dmsh"
    p = run("encode", frames_dir, "-o", out, "-q")
    one_line_error(p, str(out))
    assert ".tmp" not in p.stderr
    # A directory where the stream should go.
    (tmp_path / "adir").mkdir()
    p = run("encode", frames_dir, "-o", tmp_path / "adir", "-q")
    one_line_error(p, str(tmp_path / "adir"))
    assert ".tmp" not in p.stderr and list((tmp_path / "adir").iterdir()) == []


# --------------------------------------------------------------------------- damaged streams


@pytest.fixture(scope="module")
def predicted_stream(tmp_path_factory, frames_dir):
    """I P P P: the bump moves but the topology stays."""
    stream = tmp_path_factory.mktemp("s") / "s.dmsh"
    assert run("encode", frames_dir, "-o", stream, "-q", "--subdiv", "1").returncode == 0
    types = [f["type"] for f in dynmesh.info(stream.read_bytes())["frames"]]
    assert types[0] == "I" and "P" in types[1:], types
    return stream


def damaged_copy(path, tmp_path, frame: int, at: int = 20):
    data = bytearray(path.read_bytes())
    start = unit_starts(bytes(data))[frame]
    data[start + at] ^= 0x08
    out = tmp_path / "damaged.dmsh"
    out.write_bytes(bytes(data))
    return out, start


def test_info_lists_the_damaged_units(tmp_path, predicted_stream):
    stream, start = damaged_copy(predicted_stream, tmp_path, 2)
    p = run("info", stream)
    assert p.returncode == 1 and "Traceback" not in p.stderr
    assert f"damaged at byte {start}" in p.stdout
    assert "frame 2" in p.stderr and str(start) in p.stderr
    info = dynmesh.info(stream.read_bytes())
    assert [d["frame"] for d in info["damaged"]] == [2]
    assert [f["damaged"] for f in info["frames"]] == [False, False, True, False]


def test_skip_damaged_decodes_the_frames_whose_reference_chain_is_intact(tmp_path, predicted_stream):
    clean = list(dynmesh.decode(predicted_stream.read_bytes()))
    types = [f["type"] for f in dynmesh.info(predicted_stream.read_bytes())["frames"]]
    damaged_frame = 3 if types[3] == "P" else 2
    stream, start = damaged_copy(predicted_stream, tmp_path, damaged_frame)
    out = tmp_path / "out"
    p = run("decode", stream, "-o", out, "--skip-damaged", "-q")
    assert p.returncode == 1 and "Traceback" not in p.stderr
    assert f"frame {damaged_frame} (byte {start})" in p.stderr
    written = sorted(f.name for f in out.iterdir())
    assert written == [f"frame_{i:04d}.obj" for i in range(damaged_frame)]
    got = dict(dynmesh.api.decode_each(stream.read_bytes()))
    for i in range(damaged_frame):
        np.testing.assert_array_equal(got[i].positions, clean[i].positions)
    assert isinstance(got[damaged_frame], dynmesh.DecodeError)


def test_skip_damaged_after_a_lost_length_field_still_finds_later_intra_frames(tmp_path, frames_dir):
    stream = tmp_path / "s.dmsh"
    assert run("encode", frames_dir, "-o", stream, "-q", "--subdiv", "1", "--intra-period", "2").returncode == 0
    clean = list(dynmesh.decode(stream.read_bytes()))
    data = bytearray(stream.read_bytes())
    data[unit_starts(bytes(data))[1] + 3] ^= 0x20  # frame 1's length field
    got = dict(dynmesh.api.decode_each(bytes(data)))
    assert [i for i, m in got.items() if isinstance(m, dynmesh.DecodeError)] == [1]
    for i in (0, 2, 3):
        np.testing.assert_array_equal(got[i].positions, clean[i].positions)


def test_a_damaged_header_is_a_clear_error_even_with_skip_damaged(tmp_path, predicted_stream):
    data = bytearray(predicted_stream.read_bytes())
    data[12] ^= 1
    stream = tmp_path / "h.dmsh"
    stream.write_bytes(bytes(data))
    out = tmp_path / "out"
    one_line_error(run("decode", stream, "-o", out, "--skip-damaged"), "header CRC")
    assert not out.exists()


def test_crc_check_of_the_test_helper_matches_the_format(predicted_stream):
    data = predicted_stream.read_bytes()
    for s in unit_starts(data):
        n = struct.unpack_from("<I", data, s + 1)[0]
        assert struct.unpack_from("<I", data, s + 5 + n)[0] == zlib.crc32(data[s : s + 5 + n])


# --------------------------------------------------------------------------- bounded work


def write_obj(path, positions, faces):
    with open(path, "w") as f:
        f.write("".join(f"v {float(x)!r} {float(y)!r} {float(z)!r}\n" for x, y, z in positions))
        f.write("".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in faces))


def test_encoding_a_million_vertices_on_one_point_answers_at_once(tmp_path):
    path = tmp_path / "point.obj"
    with open(path, "w") as f:
        f.write("v 0.5 0.5 0.5\n" * 1_000_000)
        f.write("".join(f"f {3 * i + 1} {3 * i + 2} {3 * i + 3}\n" for i in range(333_333)))
    p = subprocess.run([sys.executable, "-m", "dynmesh", "encode", path, "-o", tmp_path / "p.dmsh"],
                       capture_output=True, text=True, timeout=60)
    one_line_error(p, "degenerate")
    assert not (tmp_path / "p.dmsh").exists()


def test_a_triangle_soup_and_a_dense_fan_are_refused(tmp_path):
    rng = np.random.default_rng(1)
    write_obj(tmp_path / "soup.obj", rng.random((30_000, 3)) * 1e-9, np.arange(30_000).reshape(-1, 3))
    n = 20_000
    fan = np.stack([np.zeros(n - 2, int), np.arange(1, n - 1), np.arange(2, n)], 1)
    # The fan's rim is a parabola, not a line: its faces have area (a collinear fan is now
    # refused earlier, for having none, which test_hostile covers).
    x = rng.random(n)
    write_obj(tmp_path / "fan.obj", np.c_[x, x * x, np.zeros(n)], fan)
    for name, words in (("soup", "pieces"), ("fan", "share a few vertices")):
        p = subprocess.run([sys.executable, "-m", "dynmesh", "encode", tmp_path / f"{name}.obj", "-o", tmp_path / "x.dmsh"],
                           capture_output=True, text=True, timeout=60)
        one_line_error(p, words)


def test_metrics_never_report_a_non_number(tmp_path, frames_dir):
    write_obj(tmp_path / "flat.obj", [(0, 0, 0), (1, 0, 0), (2, 0, 0)], [(0, 1, 2), (0, 2, 1)])
    one_line_error(run("metrics", frames_dir / "f0.obj", tmp_path / "flat.obj"), "frame 0", "no surface")
    one_line_error(run("metrics", tmp_path / "flat.obj", frames_dir / "f0.obj"), "reference mesh has no surface")
    with pytest.raises(ValueError, match="no surface"):
        dynmesh.metrics(wobbly_sequence(1)[0], dynmesh.Mesh(np.zeros((3, 3)), np.array([[0, 1, 2]])))
    p = run("metrics", frames_dir / "f0.obj", frames_dir / "f0.obj")
    assert p.returncode == 0 and "identical" in p.stdout and "inf" in p.stdout


@pytest.mark.parametrize("grid, words", [("100000000", "grid size must be"), ("-3", "grid size must be"),
                                         ("16000", "beyond the limit")])
def test_metric_grid_sizes_beyond_the_limits_are_refused_at_once(frames_dir, grid, words):
    p = subprocess.run([sys.executable, "-m", "dynmesh", "metrics", frames_dir / "f0.obj", frames_dir / "f1.obj",
                        "--grid-size", grid], capture_output=True, text=True, timeout=30)
    one_line_error(p, words)


# --------------------------------------------------------------------------- fuzz findings


def test_an_obj_naming_a_material_library_with_a_nul_byte_reads_with_a_warning(tmp_path):
    # Found by fuzz/python/fuzz_readers.py obj: open() raised "embedded null byte".
    path = tmp_path / "nul.obj"
    path.write_bytes(b"mtllib seed_\x00\x00.mtl\nusemtl m\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.warns(dynmesh.io.MeshWarning, match="not found"):
        m = dynmesh.read_mesh(path)
    assert m.texture is None and len(m.faces) == 1


def test_an_obj_naming_a_material_library_too_long_for_the_file_system_reads_with_a_warning(tmp_path):
    # Found by fuzz/python/fuzz_readers.py obj: is_file() raised "File name too long".
    path = tmp_path / "long.obj"
    path.write_bytes(b"mtllib " + b"x" * 5000 + b".mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.warns(dynmesh.io.MeshWarning, match="not found"):
        assert len(dynmesh.read_mesh(path).faces) == 1
