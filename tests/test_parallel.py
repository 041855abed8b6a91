"""Groups of frames encoded apart, in local processes and on a Ray cluster: the same stream
byte for byte as the sequential encoder, and no output file when a worker fails."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dynmesh import _core, api, parallel
from dynmesh.io import write_mesh
from dynmesh.mesh import Mesh

from conftest import wobbly_sequence
from test_texture import SIZE, checker_image, with_spherical_uvs

PERIOD = 4

# The Ray tests kill workers on purpose; Ray's driver then prints a screenful per death
# ("(raylet) A worker died or was killed ..." and "Task ... failed. There are N retries
# remaining ..."), which floods the log of a run that does not capture output and buries a
# real failure's report. Ray drops the lines that match RAY_DEDUP_LOGS_SKIP_REGEX (its log
# deduplication option, read when ray is imported: this module is collected before any
# fixture starts Ray). Only these two notices of a retried task are dropped: a worker death
# that matters still fails the test, as the error the command reports (WorkerError), and
# every other Ray message is printed. Set the variable yourself to see them again ("^$").
os.environ.setdefault("RAY_DEDUP_LOGS_SKIP_REGEX",
                      r"A worker died or was killed while executing a task"
                      r"|Task encode_group failed\. There are \d+ retries remaining")


@pytest.fixture(scope="module")
def frames() -> list[Mesh]:
    return wobbly_sequence(12, 12, 16)


@pytest.fixture(scope="module")
def sequential(frames) -> api.EncodeResult:
    return api.encode_frames(frames, intra_period=PERIOD)


@pytest.fixture(scope="module")
def frames_dir(tmp_path_factory, frames):
    d = tmp_path_factory.mktemp("frames")
    for i, m in enumerate(frames):
        write_mesh(d / f"f{i:02d}.obj", m)
    return d


def run(*args, check=True):
    p = subprocess.run([sys.executable, "-m", "dynmesh", *map(str, args)], capture_output=True, text=True)
    if check and p.returncode != 0:
        raise AssertionError(f"exit {p.returncode}: {p.stderr}")
    return p


def test_groups_encoded_in_two_processes_are_the_sequential_stream(frames, sequential):
    types = [f["type"] for f in sequential.frames]
    assert types.count("P") >= 6, types  # predicted frames, whose references must not cross groups
    result = api.encode_frames(frames, intra_period=PERIOD, jobs=2)
    assert result.data == sequential.data
    assert [f["type"] for f in result.frames] == types
    assert [f["bytes"] for f in result.frames] == [f["bytes"] for f in sequential.frames]


def test_a_group_encoder_refuses_to_start_inside_a_group(frames):
    lo, hi = api.sequence_bounds(frames)
    enc = _core.Encoder(12, lo.tolist(), hi.tolist(), {**api.DEFAULTS, "intra_period": PERIOD})
    with pytest.raises(ValueError, match="frame 6 does not start a group"):
        enc.start_group(6)
    with pytest.raises(ValueError, match="does not start a group"):
        enc.start_group(12)


def test_textured_groups_in_two_processes_are_the_sequential_stream():
    image = checker_image()
    frames = [with_spherical_uvs(m, image) for m in wobbly_sequence(6, 12, 16)]
    options = dict(intra_period=2, texture_size=SIZE, keep_reconstructions=True)
    one, two = api.encode_frames(frames, **options), api.encode_frames(frames, jobs=2, **options)
    assert one.texture_bytes > 0 and two.data == one.data and two.texture_bytes == one.texture_bytes
    assert all(np.array_equal(a.image, b.image) and np.array_equal(a.uvs, b.uvs)
               for a, b in zip(one.reconstructions, two.reconstructions))


def test_cli_jobs_2_writes_the_stream_of_jobs_1(tmp_path, frames_dir, sequential):
    one, two = tmp_path / "one.dmsh", tmp_path / "two.dmsh"
    run("encode", frames_dir, "-o", one, "--intra-period", PERIOD, "--jobs", "1", "-q")
    out = json.loads(run("encode", frames_dir, "-o", two, "--intra-period", PERIOD, "--jobs", "2", "--json", "-q").stdout)
    assert two.read_bytes() == one.read_bytes() == sequential.data
    assert out["bytes"] == len(sequential.data) and [f["frame"] for f in out["frames"]] == list(range(12))


def test_cli_default_jobs_are_one_per_core_and_at_most_one_per_group(tmp_path, frames_dir, sequential, monkeypatch):
    from dynmesh import cli

    monkeypatch.setattr(os, "cpu_count", lambda: 8)
    assert cli._encode_jobs("auto", 12, PERIOD) == 3  # three groups
    assert cli._encode_jobs("auto", 100, 1) == 8  # all intra: one group per frame
    assert cli._encode_jobs("auto", 6, 32) == 1  # one group: coded in the command's process
    assert cli._encode_jobs(5, 6, 32) == 5
    monkeypatch.setattr(os, "cpu_count", lambda: None)
    assert cli._encode_jobs("auto", 12, PERIOD) == 1
    out = tmp_path / "default.dmsh"
    run("encode", frames_dir, "-o", out, "--intra-period", PERIOD, "-q")
    assert out.read_bytes() == sequential.data


def test_bad_parallel_options_are_refused(tmp_path, frames_dir):
    p = run("encode", frames_dir, "-o", tmp_path / "s.dmsh", "--jobs", "0", check=False)
    assert p.returncode == 1 and "--jobs must be at least 1 or auto, got 0" in p.stderr
    p = run("encode", frames_dir, "-o", tmp_path / "s.dmsh", "--jobs", "all", check=False)
    assert p.returncode == 1 and "expected a number of processes or auto, got 'all'" in p.stderr  # README: status 1
    p = run("encode", frames_dir, "-o", tmp_path / "s.dmsh", "--jobs", "2", "--ray", "auto", check=False)
    assert p.returncode == 1 and "not allowed with argument" in p.stderr
    assert not list(tmp_path.iterdir())
    with pytest.raises(ValueError, match="jobs must be a positive integer"):
        api.encode_frames(wobbly_sequence(2, 8, 8), jobs=0)


def test_a_failing_group_leaves_no_output_file(tmp_path, frames_dir):
    bad = tmp_path / "in"
    bad.mkdir()
    for f in sorted(frames_dir.iterdir()):
        (bad / f.name).write_bytes(f.read_bytes())
    m = wobbly_sequence(1, 12, 16)[0]
    write_mesh(bad / "f09.obj", Mesh(np.zeros_like(m.positions) + 0.5, m.faces))  # every face collapses
    p = run("encode", bad, "-o", tmp_path / "s.dmsh", "--intra-period", PERIOD, "--jobs", "2", check=False)
    assert p.returncode == 1 and "frame 9: every face is degenerate" in p.stderr
    assert sorted(f.name for f in tmp_path.iterdir()) == ["in"]


class DiesInWorker(Mesh):
    """A frame that kills the process encoding it, unless that is the process that made it
    or the file ``marker`` exists (it is made before dying: the frame kills one worker)."""

    maker: int | None = None  # None while the constructor runs
    marker: str | None = None

    def __getattribute__(self, name):
        get = super().__getattribute__
        if name == "positions" and get("maker") not in (None, os.getpid()):
            if get("marker") is None or not os.path.exists(get("marker")):
                if get("marker") is not None:
                    open(get("marker"), "w").close()
                os._exit(3)
        return get(name)


def dying(m: Mesh, marker=None) -> DiesInWorker:
    d = DiesInWorker(m.positions, m.faces)
    d.maker, d.marker = os.getpid(), None if marker is None else str(marker)
    return d


def test_a_worker_that_dies_is_a_clear_error_and_no_output_file(tmp_path, frames):
    out = tmp_path / "s.dmsh"
    frames = frames[:6] + [dying(frames[6])] + frames[7:]
    lo, hi = api.sequence_bounds(frames)
    with pytest.raises(parallel.WorkerError, match=r"a worker process died .* with frames (\S+, )*4-7\b"):
        parallel.encode_to_file(out, frames, sequence=(12, lo, hi), texture=False, jobs=2, intra_period=PERIOD)
    assert not list(tmp_path.iterdir())


@pytest.fixture(scope="module")
def ray_cluster(ray_cluster):
    # The Ray workers cannot import this file: send its classes (DiesInWorker) by value.
    ray_cluster.cloudpickle.register_pickle_by_value(sys.modules[__name__])
    return ray_cluster


def test_cli_ray_writes_the_stream_of_jobs_1(ray_cluster, tmp_path, frames_dir, sequential):
    address = ray_cluster.get_runtime_context().gcs_address
    run("encode", frames_dir, "-o", tmp_path / "s.dmsh", "--intra-period", PERIOD, "--ray", address, "-q")
    assert (tmp_path / "s.dmsh").read_bytes() == sequential.data


def test_ray_sends_the_frames_when_its_workers_cannot_read_the_paths(ray_cluster, frames_dir, frames, sequential,
                                                                      monkeypatch, tmp_path):
    # Paths relative to a folder the workers do not work in: files the cluster does not share.
    monkeypatch.chdir(frames_dir)
    sent = []
    monkeypatch.setattr(parallel, "_with_meshes", lambda job, send=parallel._with_meshes: sent.append(job.first) or send(job))
    lo, hi = api.sequence_bounds(frames)
    out = tmp_path / "s.dmsh"
    parallel.encode_to_file(out, sorted(Path(".").glob("*.obj")), sequence=(12, lo, hi), texture=False, ray="auto",
                            intra_period=PERIOD)
    assert out.read_bytes() == sequential.data and sent == [0, 4, 8]


def test_a_ray_worker_that_dies_has_its_group_run_again(ray_cluster, tmp_path, frames, sequential):
    frames = frames[:5] + [dying(frames[5], marker=tmp_path / "died")] + frames[6:]
    assert api.encode_frames(frames, intra_period=PERIOD, ray="auto").data == sequential.data
    assert (tmp_path / "died").exists()  # a worker did die


def test_a_ray_worker_that_keeps_dying_is_a_clear_error_and_no_output_file(ray_cluster, tmp_path, frames):
    out = tmp_path / "s.dmsh"
    frames = frames[:6] + [dying(frames[6])] + frames[7:]
    lo, hi = api.sequence_bounds(frames)
    with pytest.raises(parallel.WorkerError, match=r"with frames (\S+, )*4-7\b"):
        parallel.encode_to_file(out, frames, sequence=(12, lo, hi), texture=False, ray="auto", intra_period=PERIOD)
    assert not list(tmp_path.iterdir())
