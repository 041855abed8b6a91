"""The built-in synthetic sequence: closed, oriented meshes whose topology changes."""

from __future__ import annotations

import time

import numpy as np
import pytest

from dynmesh.io import read_mesh, resolve_sequence
from dynmesh.mesh import Mesh
from dynmesh.synth import cloth_sequence, fused_gear_sequence, synth_sequence, write_sequence


@pytest.fixture(scope="module")
def frames() -> list[Mesh]:
    start = time.perf_counter()
    meshes = synth_sequence()
    print(f"\nsynth_sequence(): {(time.perf_counter() - start) / len(meshes):.3f} s per frame, "
          f"vertices {[m.vertex_count for m in meshes]}, components {[components(m) for m in meshes]}")
    return meshes


def components(mesh: Mesh) -> int:
    """Connected components of the faces, by label propagation over the edges."""
    a, b = np.concatenate([mesh.faces[:, [0, 1]], mesh.faces[:, [1, 2]]]).T
    return len(np.unique(connected_labels(mesh.vertex_count, a, b)[mesh.faces]))


def face_components(mesh: Mesh) -> int:
    """Connected components of the faces where faces meet only across shared edges (a closed
    mesh: every edge in two faces), so that faces touching at a vertex alone stay apart."""
    undirected = np.sort(directed_edges(mesh), axis=1)
    order = np.lexsort(undirected.T[::-1])
    face = (np.arange(len(undirected)) % len(mesh.faces))[order]
    return len(np.unique(connected_labels(len(mesh.faces), face[0::2], face[1::2])))


def connected_labels(n: int, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per node of 0..n-1, the smallest node it is linked to through the links (a[i], b[i])."""
    label = np.arange(n)
    while True:
        low = np.minimum(label[a], label[b])
        new = label.copy()
        np.minimum.at(new, a, low)
        np.minimum.at(new, b, low)
        new = new[new]
        if np.array_equal(new, label):
            return label
        label = new


def directed_edges(mesh: Mesh) -> np.ndarray:
    f = mesh.faces
    return np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])


def assert_closed(mesh: Mesh) -> None:
    undirected = np.sort(directed_edges(mesh), axis=1)
    _, uses = np.unique(undirected, axis=0, return_counts=True)
    assert (uses == 2).all()
    assert len(np.unique(mesh.faces)) == mesh.vertex_count  # no unused vertices


def assert_outward(mesh: Mesh) -> None:
    edges = directed_edges(mesh)
    assert len(np.unique(edges, axis=0)) == len(edges)  # each directed edge once
    p = mesh.positions[mesh.faces]
    volume = np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6
    assert volume > 0.05  # outward normals enclose a positive volume


def test_every_frame_is_closed(frames):
    for mesh in frames:
        assert_closed(mesh)


def test_every_frame_is_consistently_oriented_outward(frames):
    for mesh in frames:
        assert_outward(mesh)


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


# Rigid parts and cloth in contact, re-meshed as one surface (issue 46): small grids here.

@pytest.fixture(scope="module")
def fused() -> list[Mesh]:
    return fused_gear_sequence(5, turn_degrees=10.0, resolution=32)


@pytest.fixture(scope="module")
def sleeve() -> list[Mesh]:
    return cloth_sequence(5, slide=0.1, resolution=36)


@pytest.mark.parametrize("name", ["fused", "sleeve"])
def test_one_closed_outward_surface_every_frame_that_changes_every_frame(request, name):
    meshes = request.getfixturevalue(name)
    for mesh in meshes:
        assert_closed(mesh)
        assert_outward(mesh)
        assert face_components(mesh) == 1
    counts = [m.vertex_count for m in meshes]
    assert all(a != b for a, b in zip(counts, counts[1:]))


def test_face_components_count_parts_that_share_only_a_vertex_apart():
    tetra = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    two = Mesh(np.random.default_rng(0).random((7, 3)), np.concatenate([tetra, np.where(tetra == 0, 0, tetra + 3)]))
    assert components(two) == 1 and face_components(two) == 2


def test_gears_parted_by_a_gap_are_two_components_every_frame():
    parted = fused_gear_sequence(5, turn_degrees=10.0, resolution=32, gap=0.15)
    for mesh in parted:
        assert_closed(mesh)
        assert face_components(mesh) == 2


def test_gears_turn_at_the_speeds_of_meshing_teeth():
    # 36 degrees is a tooth of the 10-tooth gear and, at 10/8 of that the other way, of the
    # 8-tooth one too: three turns later, on the same grid, the frame is the first again.
    meshes = fused_gear_sequence(4, turn_degrees=36.0, resolution=32)
    assert np.array_equal(meshes[0].faces, meshes[3].faces)
    assert np.allclose(meshes[0].positions, meshes[3].positions, atol=1e-9)
    assert not np.array_equal(meshes[0].faces, meshes[1].faces)


def test_defaults_are_the_size_of_the_held_back_capture():
    for mesh in fused_gear_sequence(2) + cloth_sequence(2):
        assert 5000 < mesh.vertex_count < 15000


def test_the_sleeve_slides_along_the_arm(sleeve):
    # Beyond the arm's radius (0.3) lies only the sleeve, whose ends are 0.8 apart.
    for f, mesh in enumerate(sleeve):
        x, y, z = mesh.positions.T
        on_sleeve = x[np.hypot(y, z) > 0.36]
        centre = -0.25 + 0.1 * f
        assert abs(on_sleeve.min() - (centre - 0.4)) < 0.02 and abs(on_sleeve.max() - (centre + 0.4)) < 0.02


def test_new_generators_are_deterministic_and_check_their_arguments(fused):
    again = fused_gear_sequence(2, turn_degrees=10.0, resolution=32)
    assert all(np.array_equal(a.positions, b.positions) and np.array_equal(a.faces, b.faces) for a, b in zip(fused, again))
    with pytest.raises(ValueError):
        fused_gear_sequence(0)
    with pytest.raises(ValueError, match="leaves the arm"):
        cloth_sequence(20, slide=0.1)
