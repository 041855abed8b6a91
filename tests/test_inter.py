"""Inter coding: rigid motion (the gears of dynmesh.synth.gears, resampled every frame) and reference choice."""

import numpy as np
import pytest

import dynmesh
import dynmesh.defaults
from dynmesh.synth import gear_sequence


def _encode(frames, **options):
    r = dynmesh.encode_frames(frames, keep_reconstructions=True, **options)
    return r, dynmesh.metrics(frames, r.reconstructions, grid_size=512)["d1_psnr"]


def test_gear_sequence_changes_connectivity_every_frame():
    frames = gear_sequence(4)
    assert len({len(m.faces) for m in frames}) == 3
    assert [len(m.positions) for m in frames] == [2 * (3 * (144 + f % 3) + 2) for f in range(4)]


def test_turning_gears_are_predicted_once_their_parts_are_aligned_rigidly():
    frames = gear_sequence(6, turn_degrees=5.0, samples=600)
    intra, d1_intra = _encode(frames, intra_period=1)
    rigid, d1_rigid = _encode(frames)
    loose, _ = _encode(frames, rigid_align=False)
    # Without the rigid fit the anchor slides along the rims, so its teeth miss and every
    # predicted candidate costs more than intra; with it, predicted frames pay.
    assert "".join(f["type"] for f in loose.frames) == "IIIIII"
    assert "".join(f["type"] for f in rigid.frames) == "IPPPPP"
    assert len(rigid.data) < 0.5 * len(intra.data)
    assert d1_rigid > d1_intra - 1.5


def test_gears_turning_20_degrees_a_frame_are_predicted_from_an_intra_frame():
    # Coarse base rims turned by 20 degrees: ICP from no motion stalls or turns the wrong way,
    # and an intra reference has no previous motion to start from, so only the screened
    # turned starts (anchor::rigid) find the turn. Before them every frame was coded intra.
    frames = gear_sequence(4, turn_degrees=20.0, samples=600)
    intra, d1_intra = _encode(frames, intra_period=1)
    inter, d1_inter = _encode(frames)
    assert "".join(f["type"] for f in inter.frames) == "IPPP"
    assert len(inter.data) < 0.6 * len(intra.data)
    assert d1_inter > d1_intra - 1.0


def test_gears_turned_by_about_a_tooth_refer_to_the_previous_frame():
    # Turned 24 degrees, a gear with teeth every 30 degrees lies closer to itself unturned
    # than to its last frame (12 degrees back), but the turn is known only from the last frame.
    frames = gear_sequence(3, turn_degrees=12.0, samples=600)
    r = dynmesh.encode_frames(frames, qp=28)
    assert [f["reference_distance"] for f in r.frames] == [0, 1, 1]


def _warped(frames):
    from dynmesh.synth import synth_sequence

    m = synth_sequence(frames=40, resolution=14)[0]
    out = []
    for f in range(frames):
        p = m.positions.copy()
        p[:, 0] += 0.08 * f * np.sin(2.0 * p[:, 1])
        out.append(dynmesh.Mesh(p, m.faces.copy()))
    return out


def test_reference_choice_refers_back_to_a_repeated_frame_and_decodes_bit_exactly():
    a, b, c = _warped(3)
    frames = [a, b, c, b, c]
    r = dynmesh.encode_frames(frames, keep_reconstructions=True, references=3, rd_slope=100.0, qp=30)
    distances = [f["reference_distance"] for f in r.frames]
    assert distances[0] == 0 and distances[1] == 1
    assert distances[3] == 2, distances  # frame 3 repeats frame 1
    decoded = list(dynmesh.decode(r.data))
    for rec, dec in zip(r.reconstructions, decoded):
        assert np.array_equal(rec.positions, dec.positions) and np.array_equal(rec.faces, dec.faces)
    # Without reference choice every predicted frame refers to the previous one.
    off = dynmesh.encode_frames(frames, references=1, intra_reference=False, rd_slope=100.0, qp=30)
    assert [f["reference_distance"] for f in off.frames][1:] == [1] * 4


def test_a_frame_that_returns_to_the_intra_frames_pose_refers_to_it_by_default():
    a, b, c = _warped(3)
    r = dynmesh.encode_frames([a, b, c, a], rd_slope=100.0, qp=30)
    assert [f["reference_distance"] for f in r.frames] == [0, 1, 1, 3]
    off = dynmesh.encode_frames([a, b, c, a], intra_reference=False, rd_slope=100.0, qp=30)
    assert [f["reference_distance"] for f in off.frames] == [0, 1, 1, 1]
    assert len(r.data) < len(off.data)


def test_references_out_of_range_is_a_clear_error():
    import pytest

    for bad in (0, dynmesh.defaults.MAX_REFERENCES + 1):
        with pytest.raises(ValueError, match="references"):
            dynmesh.encode_frames(_warped(2), references=bad)


def test_a_part_no_reference_covers_is_refreshed_inside_a_predicted_frame():
    from dynmesh.conformance import appearing
    from dynmesh.synth import synth_sequence

    frames = appearing(synth_sequence(frames=40, resolution=14)[:3])
    options = dict(qp=30, subdiv=2, base_bits=8, bits=11)
    r = dynmesh.encode_frames(frames, keep_reconstructions=True, **options)
    assert [f["type"] for f in r.frames] == ["I", "P", "P"]
    assert r.frames[1]["refreshed_faces"] > 0 and r.frames[2]["refreshed_faces"] == 0
    # The refreshed frame has the new part's faces besides the moved base's.
    assert r.frames[1]["base_faces"] > r.frames[0]["base_faces"]
    refresh_bytes = [f["refresh_bytes"] for f in dynmesh.info(r.data)["frames"]]
    assert refresh_bytes[0] == 0 and refresh_bytes[1] > 0 and refresh_bytes[2] == 0
    decoded = list(dynmesh.decode(r.data))
    for rec, dec in zip(r.reconstructions, decoded):
        assert np.array_equal(rec.positions, dec.positions) and np.array_equal(rec.faces, dec.faces)
    # Without the refresh the frame where the part appears is coded intra, and costs more.
    off = dynmesh.encode_frames(frames, refresh=False, **options)
    assert off.frames[1]["type"] == "I" and all(f["refreshed_faces"] == 0 for f in off.frames)
    assert r.frames[1]["bytes"] < off.frames[1]["bytes"]


def test_intra_check_codes_predicted_frames_intra_too_when_they_stray_from_the_last_intra():
    # A threshold below any loss sends every predicted frame through the intra check (each
    # then reports the candidate it rejected); an infinite one, none beyond the shortcut.
    frames = gear_sequence(5, turn_degrees=5.0, samples=600)
    never = dynmesh.encode_frames(frames, intra_check_db=float("inf"))
    assert any(f["rejected_bytes"] == 0 for f in never.frames if f["type"] == "P")
    checked = dynmesh.encode_frames(frames, keep_reconstructions=True, intra_check_db=-100.0)
    predicted = [f for f in checked.frames if f["type"] == "P"]
    assert predicted and all(f["rejected_bytes"] > 0 for f in predicted)
    for r, d in zip(checked.reconstructions, dynmesh.decode(checked.data)):
        assert np.array_equal(r.positions, d.positions) and np.array_equal(r.faces, d.faces)
    with pytest.raises(ValueError, match="intra check"):
        dynmesh.encode_frames(frames, intra_check_db=float("nan"))


def test_always_try_intra_codes_every_predicted_frame_intra_too_and_decodes_bit_exactly():
    # By default a predicted frame that beats the last intra frame is kept without coding
    # this frame intra (its stats then report no rejected candidate); with always_try_intra
    # each one is weighed against its own intra frame, whose bytes it reports.
    frames = gear_sequence(5, turn_degrees=5.0, samples=600)
    quick = dynmesh.encode_frames(frames)
    thorough = dynmesh.encode_frames(frames, keep_reconstructions=True, always_try_intra=True)
    predicted = [f for f in quick.frames if f["type"] == "P"]
    assert predicted and any(f["rejected_bytes"] == 0 for f in predicted)
    thorough_predicted = [f for f in thorough.frames if f["type"] == "P"]
    assert thorough_predicted and all(f["rejected_bytes"] > 0 for f in thorough_predicted)
    for r, d in zip(thorough.reconstructions, dynmesh.decode(thorough.data)):
        assert np.array_equal(r.positions, d.positions) and np.array_equal(r.faces, d.faces)
