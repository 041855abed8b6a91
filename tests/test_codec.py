"""The codec through its Python surface: round trips, rate-distortion behaviour, errors."""

import numpy as np
import pytest

import dynmesh
from dynmesh import Mesh
from dynmesh.synth import fused_gear_sequence

from conftest import uv_sphere, wobbly_sequence


def test_decoder_reproduces_the_encoder_reconstruction_bit_for_bit(sequence):
    result = dynmesh.encode_frames(sequence, keep_reconstructions=True, qp=22)
    decoded = list(dynmesh.decode(result.data))
    assert len(decoded) == len(sequence)
    for rec, dec in zip(result.reconstructions, decoded):
        assert np.array_equal(rec.faces, dec.faces)
        assert np.array_equal(rec.positions.view(np.uint64), dec.positions.view(np.uint64))


@pytest.mark.parametrize("options", [dict(scheme="loop"), dict(scheme="midpoint"), dict(subdiv=2, scheme="loop,midpoint"),
                                     dict(normal_only=False), dict(subdiv=0), dict(bits=16, subdiv=2),
                                     dict(base_bits=8), dict(bits=11, base_bits=11), dict(aq=False),
                                     dict(aq_alpha=1.5, aq_delta=0.3, aq_h=5), dict(intra_period=1)])
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


def frame_types(data: bytes) -> list[str]:
    return [f["type"] for f in dynmesh.info(data)["frames"]]


def test_constant_topology_is_predicted_within_the_intra_period(sequence):
    frames = sequence + sequence[::-1]
    result = dynmesh.encode_frames(frames, keep_reconstructions=True, qp=22, intra_period=4)
    assert frame_types(result.data)[0] == "I" and frame_types(result.data)[4] == "I"
    assert frame_types(result.data).count("P") >= 3
    assert [s["type"] for s in result.frames] == frame_types(result.data)
    for rec, dec in zip(result.reconstructions, dynmesh.decode(result.data)):
        assert np.array_equal(rec.positions, dec.positions) and np.array_equal(rec.faces, dec.faces)
    all_intra = dynmesh.encode(frames, qp=22, intra_period=1)
    assert set(frame_types(all_intra)) == {"I"}
    assert len(result.data) < len(all_intra)


@pytest.mark.parametrize("inter", ["none", "nns", "nns+me", "nns+me+qem", "nns+me+proj"])
def test_changing_topology_is_predicted_only_through_an_anchor(inter):
    frames = [uv_sphere(16, 24), uv_sphere(18, 22, center=(0.02, 0, 0)), uv_sphere(17, 26, center=(0.04, 0, 0))]
    result = dynmesh.encode_frames(frames, keep_reconstructions=True, qp=22, inter=inter, rd_slope=100)
    types = frame_types(result.data)
    assert types == (["I", "I", "I"] if inter == "none" else ["I", "P", "P"])
    assert not any(s["same_topology"] for s in result.frames)
    for rec, dec in zip(result.reconstructions, dynmesh.decode(result.data)):
        assert np.array_equal(rec.positions, dec.positions)


def test_frames_with_changing_topology_are_coded_independently():
    frames = [uv_sphere(12, 16), uv_sphere(18, 20, center=(0.1, 0, 0)), uv_sphere(9, 30, radius=0.8)]
    decoded = list(dynmesh.decode(dynmesh.encode(frames, qp=16, inter="none")))
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
    assert 0 < header_bytes < 100


@pytest.mark.parametrize("options", [dict(qp=200), dict(base_ratio=0), dict(base_ratio=1.5), dict(subdiv=9), dict(bits=3), dict(base_bits=13), dict(bits=10, base_bits=11), dict(scheme="cubic"),
                                     dict(subdiv=3, scheme="loop,loop"), dict(intra_period=0), dict(inter="octree"), dict(aq_h=0), dict(aq_delta=1.5), dict(qp="high")])
def test_bad_options_raise_value_error(options, sphere):
    with pytest.raises(ValueError):
        dynmesh.encode([sphere], **options)


def test_the_header_names_each_iteration_s_scheme(sphere):
    assert dynmesh.info(dynmesh.encode([sphere], subdiv=3))["header"]["schemes"] == ["midpoint", "midpoint", "loop"]
    assert dynmesh.info(dynmesh.encode([sphere], subdiv=2, scheme="loop,midpoint"))["header"]["schemes"] == ["loop", "midpoint"]


def test_unknown_option_is_refused(sphere):
    with pytest.raises(ValueError, match="qpp"):
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


def test_a_thin_disc_whose_caps_decimate_only_into_slivers_codes_as_well_as_its_neighbour():
    # On the 53-cell grid the caps' plane passes close to grid nodes, so polygonizing leaves
    # needles there and every cap collapse makes a sliver; the decimator must not meet its
    # target by collapsing the discs' rims through the discs instead (it did: 40 dB, not 75).
    frames = fused_gear_sequence(2, gap=0.1)
    psnr = [dynmesh.metrics([f], list(dynmesh.decode(dynmesh.encode([f], inter="none"))))["d1_psnr"] for f in frames]
    assert psnr[1] > psnr[0] - 3, psnr
