"""Small meshes that the tests make themselves, and the optional shared data."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dynmesh.mesh import Mesh

SHARED_DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def uv_sphere(rings: int = 16, segments: int = 24, radius: float = 1.0, center=(0.0, 0.0, 0.0)) -> Mesh:
    """A closed, consistently oriented UV sphere."""
    theta = np.linspace(0, np.pi, rings + 1)[1:-1]
    phi = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    ring = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1).reshape(-1, 3)
    pos = np.vstack([[0, 0, 1], ring, [0, 0, -1]]) * radius + np.asarray(center)
    faces = []
    idx = lambda r, s: 1 + r * segments + s % segments
    for s in range(segments):
        faces.append([0, idx(0, s), idx(0, s + 1)])
        faces.append([len(pos) - 1, idx(rings - 2, s + 1), idx(rings - 2, s)])
    for r in range(rings - 2):
        for s in range(segments):
            a, b, c, d = idx(r, s), idx(r, s + 1), idx(r + 1, s), idx(r + 1, s + 1)
            faces += [[a, c, b], [b, c, d]]
    return Mesh(pos, np.array(faces))


def one_line_error(p, *words) -> None:
    """The command (a finished subprocess) failed with status 1 and said why in one line,
    with each of ``words``, and nothing else."""
    assert p.returncode == 1, (p.returncode, p.stderr)
    assert "Traceback" not in p.stderr and len(p.stderr.strip().splitlines()) == 1, p.stderr
    for w in words:
        assert w in p.stderr, p.stderr


def wobbly_sequence(frames: int = 3, rings: int = 20, segments: int = 30) -> list[Mesh]:
    """Spheres with a moving bump: same topology, changing shape."""
    out = []
    for f in range(frames):
        m = uv_sphere(rings, segments)
        bump = 1 + 0.15 * np.exp(-8 * ((m.positions[:, 0] - 0.3 * f) ** 2 + m.positions[:, 1] ** 2))
        out.append(Mesh(m.positions * bump[:, None], m.faces))
    return out


@pytest.fixture
def sphere() -> Mesh:
    return uv_sphere()


@pytest.fixture
def sequence() -> list[Mesh]:
    return wobbly_sequence()


def shared_sequence(name: str) -> Path:
    """Folder of a shared sequence, or a clean skip when the shared data is absent."""
    path = SHARED_DATA / name
    if not path.is_dir():
        pytest.skip(f"shared data not present ({path})")
    return path


@pytest.fixture(scope="session")
def ray_cluster():
    """A local Ray cluster of 2 CPUs, this process its driver; a clean skip without Ray."""
    ray = pytest.importorskip("ray", reason='the Ray back end needs pip install "dynmesh[ray]"')
    ray.init(num_cpus=2, logging_level="WARNING")
    yield ray
    ray.shutdown()
