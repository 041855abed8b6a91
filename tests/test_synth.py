"""The built-in synthetic sequence: closed, oriented meshes whose topology changes."""

from __future__ import annotations

import time

import numpy as np
import pytest

from dynmesh.io import read_mesh, resolve_sequence
from dynmesh.mesh import Mesh
from dynmesh.synth import synth_sequence, write_sequence


@pytest.fixture(scope="module")
def frames() -> list[Mesh]:
    start = time.perf_counter()
    meshes = synth_sequence()
    print(f"\nsynth_sequence(): {(time.perf_counter() - start) / len(meshes):.3f} s per frame, "
          f"vertices {[m.vertex_count for m in meshes]}, components {[components(m) for m in meshes]}")
    return meshes


def components(mesh: Mesh) -> int:
    """Connected components of the faces, by label propagation over the edges."""
    label = np.arange(mesh.vertex_count)
    a, b = np.concatenate([mesh.faces[:, [0, 1]], mesh.faces[:, [1, 2]]]).T
    while True:
        low = np.minimum(label[a], label[b])
        new = label.copy()
        np.minimum.at(new, a, low)
        np.minimum.at(new, b, low)
        new = new[new]
        if np.array_equal(new, label):
            return len(np.unique(label[mesh.faces]))
        label = new


def directed_edges(mesh: Mesh) -> np.ndarray:
    f = mesh.faces
    return np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])


def test_every_frame_is_closed(frames):
    for mesh in frames:
        undirected = np.sort(directed_edges(mesh), axis=1)
        _, uses = np.unique(undirected, axis=0, return_counts=True)
        assert (uses == 2).all()
        assert len(np.unique(mesh.faces)) == mesh.vertex_count  # no unused vertices


def test_every_frame_is_consistently_oriented_outward(frames):
    for mesh in frames:
        edges = directed_edges(mesh)
        assert len(np.unique(edges, axis=0)) == len(edges)  # each directed edge once
        p = mesh.positions[mesh.faces]
        volume = np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6
        assert volume > 0.05  # outward normals enclose a positive volume


def test_frames_fit_the_box_and_have_a_few_thousand_vertices(frames):
    for mesh in frames:
        assert np.abs(mesh.positions).max() < 1.0
        assert 1000 < mesh.vertex_count < 20000


def test_vertex_count_and_connectivity_change_every_frame(frames):
    counts = [m.vertex_count for m in frames]
    assert len(set(counts)) == len(counts)
    assert all(not np.array_equal(a.faces[:100], b.faces[:100]) for a, b in zip(frames, frames[1:]))


def test_blobs_merge_and_split(frames):
    counts = [components(m) for m in frames]
    assert max(counts) >= 2 and min(counts) == 1
    assert counts[0] > min(counts) and counts[-1] > min(counts)  # merge, then split again


def test_same_seed_same_sequence_other_seed_another(frames):
    again = synth_sequence(seed=0)
    for a, b in zip(frames, again):
        assert np.array_equal(a.positions, b.positions) and np.array_equal(a.faces, b.faces)
    other = synth_sequence(frames=2, seed=1)
    assert other[0].vertex_count != frames[0].vertex_count


def test_resolution_and_frame_count_are_honoured():
    coarse = synth_sequence(frames=3, resolution=24)
    assert len(coarse) == 3
    assert all(m.vertex_count < 3000 for m in coarse)
    assert len(synth_sequence(frames=1, resolution=16)) == 1
    with pytest.raises(ValueError):
        synth_sequence(frames=0)


@pytest.mark.parametrize("fmt", ["obj", "ply"])
def test_write_sequence_round_trips_in_frame_order(tmp_path, frames, fmt):
    paths = write_sequence(frames[:3], tmp_path / "out", fmt=fmt)
    assert [p.name for p in paths] == [f"frame_{i:04d}.{fmt}" for i in range(3)]
    assert resolve_sequence(tmp_path / "out") == paths
    for path, mesh in zip(paths, frames):
        back = read_mesh(path)
        assert np.array_equal(back.positions, mesh.positions) and np.array_equal(back.faces, mesh.faces)
    with pytest.raises(ValueError, match="fmt"):
        write_sequence(frames[:1], tmp_path, fmt="stl")
