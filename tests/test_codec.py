"""The codec through its Python surface: round trips, rate-distortion behaviour, errors."""

import numpy as np
import pytest

import dynmesh
from dynmesh import Mesh

from conftest import uv_sphere, wobbly_sequence


def test_decoder_reproduces_the_encoder_reconstruction_bit_for_bit(sequence):
    result = dynmesh.encode_frames(sequence, keep_reconstructions=True, qp=22)
    decoded = list(dynmesh.decode(result.data))
    assert len(decoded) == len(sequence)
    for rec, dec in zip(result.reconstructions, decoded):
        assert np.array_equal(rec.faces, dec.faces)
        assert np.array_equal(rec.positions.view(np.uint64), dec.positions.view(np.uint64))


@pytest.mark.parametrize("options", [dict(scheme="loop"), dict(normal_only=False), dict(subdiv=0), dict(bits=16, subdiv=2), dict(base_bits=8), dict(bits=11, base_bits=11)])
def test_round_trip_holds_for_every_option(options, sequence):
    result = dynmesh.encode_frames(sequence[:2], keep_reconstructions=True, **options)
    for rec, dec in zip(result.reconstructions, dynmesh.decode(result.data)):
        assert np.array_equal(rec.positions, dec.positions) and np.array_equal(rec.faces, dec.faces)


def test_quality_rises_as_qp_falls_and_rate_rises(sequence):
    results = {}
    for qp in (16, 28, 40):
        data = dynmesh.encode(sequence, qp=qp)
        psnr = dynmesh.metrics(sequence, list(dynmesh.decode(data)))["d1_psnr"]
        results[qp] = (len(data), psnr)
    assert results[16][1] > results[28][1] > results[40][1]
    assert results[16][0] > results[28][0] > results[40][0]


def test_stream_is_far_smaller_than_the_raw_mesh(sequence):
    data = dynmesh.encode(sequence)
    raw = sum(m.positions.nbytes + m.faces.nbytes for m in sequence)
    assert len(data) * 10 < raw


def test_decoded_surface_is_close_to_the_input(sphere):
    decoded = next(dynmesh.decode(dynmesh.encode([sphere], qp=16)))
    radius = np.linalg.norm(decoded.positions, axis=1)
    assert np.abs(radius - 1).max() < 0.02


def test_encoding_is_deterministic(sequence):
    assert dynmesh.encode(sequence) == dynmesh.encode(sequence)


def test_frames_with_changing_topology_are_coded_independently():
    frames = [uv_sphere(12, 16), uv_sphere(18, 20, center=(0.1, 0, 0)), uv_sphere(9, 30, radius=0.8)]
    decoded = list(dynmesh.decode(dynmesh.encode(frames, qp=16)))
    for f, d in zip(frames, decoded):
        centre = (f.positions.max(axis=0) + f.positions.min(axis=0)) / 2
        radius = np.linalg.norm(d.positions - centre, axis=1)
        expected = np.linalg.norm(f.positions - centre, axis=1).max()
        assert np.abs(radius - expected).max() < 0.05 * expected


def test_info_reports_header_and_frame_sizes(sequence):
    data = dynmesh.encode(sequence, qp=30, bits=11)
    i = dynmesh.info(data)
    assert i["header"]["frame_count"] == len(sequence)
    assert i["header"]["bits"] == 11
    assert i["header"]["base_bits"] == dynmesh.DEFAULTS["base_bits"]
    assert [f["qp"] for f in i["frames"]] == [30] * len(sequence)
    header_bytes = len(data) - sum(f["bytes"] for f in i["frames"])
    assert 0 < header_bytes < 64


@pytest.mark.parametrize("options", [dict(qp=200), dict(base_ratio=0), dict(base_ratio=1.5), dict(subdiv=9), dict(bits=3), dict(base_bits=13), dict(bits=10, base_bits=11), dict(scheme="cubic")])
def test_bad_options_raise_value_error(options, sphere):
    with pytest.raises(ValueError):
        dynmesh.encode([sphere], **options)


def test_unknown_option_is_refused(sphere):
    with pytest.raises(TypeError, match="qpp"):
        dynmesh.encode([sphere], qpp=3)


def test_malformed_meshes_raise_value_error_naming_the_frame(sphere):
    bad = Mesh(sphere.positions.copy(), sphere.faces)
    bad.positions[3, 1] = np.nan
    with pytest.raises(ValueError, match="frame 1"):
        dynmesh.encode([sphere, bad])
    with pytest.raises(ValueError, match="frame 0"):
        dynmesh.encode([Mesh(sphere.positions, sphere.faces + 10_000)])
    with pytest.raises(ValueError):
        dynmesh.encode([Mesh(sphere.positions, np.zeros((0, 3)))])


def test_metrics_of_identical_meshes_are_infinite_and_of_shifted_ones_finite(sphere):
    same = dynmesh.metrics(sphere, sphere)
    assert same["d1_psnr"] == float("inf") or same["d1_psnr"] > 150
    shifted = Mesh(sphere.positions + [0.01, 0, 0], sphere.faces)
    m = dynmesh.metrics(sphere, shifted)
    assert 40 < m["d1_psnr"] < 100
    assert m["peak"] == pytest.approx(2.0, rel=1e-3)
    assert dynmesh.metrics(sphere, shifted, peak=4.0)["d1_psnr"] == pytest.approx(m["d1_psnr"] + 20 * np.log10(2), abs=1e-6)
