"""`dynmesh decode` through the core (`_core.decode_to_files`): the files and hashes are
those of the Python path, bit for bit, and the command imports no numpy."""

import subprocess
import sys

import pytest

import dynmesh
from dynmesh import _core, api
from dynmesh.conformance import frame_hash
from dynmesh.io import write_mesh
from dynmesh.mesh import Mesh

from conftest import wobbly_sequence


@pytest.fixture(scope="module", params=[1, 3], ids=["all-intra", "intra-period-3"])
def stream(request):
    frames = wobbly_sequence(5, 12, 16)
    return api.encode_frames(frames, qp=24, intra_period=request.param, subdiv=2).data


@pytest.mark.parametrize("fmt", ["obj", "ply"])
@pytest.mark.parametrize("lod", [None, 1])
def test_files_and_hashes_are_those_of_the_python_writer(tmp_path, stream, fmt, lod):
    core_dir, api_dir = tmp_path / "core", tmp_path / "api"
    core_dir.mkdir()
    api_dir.mkdir()
    results = _core.decode_to_files(stream, str(core_dir), fmt, lod, False, True)
    decoded = list(api.decode(stream, lod=lod))
    assert [(i, h, e) for i, h, e in results] == [(i, frame_hash(m), None) for i, m in enumerate(decoded)]
    for i, m in enumerate(decoded):
        write_mesh(api_dir / f"frame_{i:04d}.{fmt}", m)
    names = sorted(p.name for p in core_dir.iterdir())
    assert names == sorted(p.name for p in api_dir.iterdir()) == [f"frame_{i:04d}.{fmt}" for i in range(5)]
    for name in names:
        assert (core_dir / name).read_bytes() == (api_dir / name).read_bytes(), name


def test_without_a_directory_only_hashes(stream):
    results = _core.decode_to_files(stream, None, "obj", None, False, True)
    assert [h for _, h, _ in results] == [frame_hash(m) for m in api.decode(stream)]
    assert all(h is None for _, h, _ in _core.decode_to_files(stream, None, "ply"))


def test_damaged_frames_fail_as_in_the_api(tmp_path):
    data = bytearray(api.encode_frames(wobbly_sequence(4, 12, 16), qp=24, intra_period=2, subdiv=1).data)
    units = [f["bytes"] for f in api.info(bytes(data))["frames"]]
    data[len(data) - sum(units[1:]) + 20] ^= 0x08  # inside frame 1, a predicted frame
    data = bytes(data)
    results = _core.decode_to_files(data, str(tmp_path), "obj", None, True, False)
    expected = list(api.decode_each(data))
    assert [e is None for _, _, e in results] == [not isinstance(m, api.DecodeError) for _, m in expected]
    for (_, _, e), (_, m) in zip(results, expected):
        if e is not None:
            assert isinstance(e, _core.DecodeError) and (e.args[0], e.args[2]) == (str(m), m.offset)
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"frame_{i:04d}.obj" for i, (_, _, e) in enumerate(results) if e is None]


def test_an_unwritable_directory_is_an_os_error_naming_the_file(tmp_path, stream):
    missing = tmp_path / "missing"
    results = _core.decode_to_files(stream, str(missing), "obj")
    e = results[0][2]
    assert isinstance(e, FileNotFoundError) and e.filename == str(missing / "frame_0000.obj")


def test_the_package_and_the_decode_command_import_no_numpy(tmp_path, stream):
    path = tmp_path / "s.dmsh"
    path.write_bytes(stream)
    script = (
        "import sys\n"
        "import dynmesh\n"
        "from dynmesh import cli\n"
        f"assert cli.main(['decode', {str(path)!r}, '-o', {str(tmp_path / 'out')!r}, '-q']) == 0\n"
        "assert 'numpy' not in sys.modules, 'numpy imported'\n"
        "dynmesh.encode_frames, dynmesh.Mesh, dynmesh.read_mesh, dynmesh.DEFAULTS, dynmesh.api.info\n"
        "assert 'numpy' in sys.modules\n"
    )
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    assert len(list((tmp_path / "out").glob("frame_*.obj"))) == 5


def test_lazy_names_are_the_api_s():
    assert dynmesh.encode_frames is api.encode_frames and dynmesh.Mesh is Mesh
    assert set(dynmesh.__all__) <= set(dir(dynmesh))
    with pytest.raises(AttributeError):
        dynmesh.no_such_name
