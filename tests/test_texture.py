"""Textured sequences: atlas, texture transfer, video, colour metrics, and their stream."""

from __future__ import annotations

import time

import numpy as np
import pytest

import dynmesh
from dynmesh import _core, api, texture
from dynmesh.cli import main
from dynmesh.io import read_image, read_mesh, write_image, write_mesh
from dynmesh.mesh import Mesh
from dynmesh.synth import synth_sequence
from dynmesh.texture import video

from conftest import shared_sequence, wobbly_sequence

SIZE = 256  # atlas side in the tests: small, so a test sequence codes in a second or two


def checker_image(size: int = 128, seed: int = 0) -> np.ndarray:
    """A smooth colour field with a coarse checker on top: something a transfer can get wrong."""
    y, x = np.mgrid[0:size, 0:size] / size
    rng = np.random.default_rng(seed)
    phase = rng.uniform(0, 2 * np.pi, 3)
    rgb = [0.5 + 0.4 * np.sin(2 * np.pi * (x + 0.7 * y) + p) for p in phase]
    check = ((np.floor(x * 8) + np.floor(y * 8)) % 2) * 0.15
    return np.clip(np.stack(rgb, -1) * 255 * (0.85 + check[..., None]), 0, 255).astype(np.uint8)


def with_spherical_uvs(m: Mesh, image: np.ndarray) -> Mesh:
    """``m`` with per-vertex UVs from the direction of each vertex around the mesh's centre."""
    d = m.positions - m.positions.mean(axis=0)
    d /= np.linalg.norm(d, axis=1, keepdims=True) + 1e-12
    uv = np.stack([0.5 + np.arctan2(d[:, 1], d[:, 0]) / (2 * np.pi), np.arccos(np.clip(d[:, 2], -1, 1)) / np.pi], 1)
    return Mesh(m.positions, m.faces, uvs=uv, uv_faces=m.faces.copy(), image=image)


@pytest.fixture(scope="module")
def textured_sequence() -> list[Mesh]:
    image = checker_image()
    return [with_spherical_uvs(m, image) for m in wobbly_sequence(3, rings=16, segments=24)]


@pytest.fixture(scope="module")
def changing_textured_sequence() -> list[Mesh]:
    image = checker_image(seed=1)
    return [with_spherical_uvs(m, image) for m in synth_sequence(frames=3, resolution=32)]


@pytest.fixture(scope="module")
def coded(textured_sequence):
    return api.encode_frames(textured_sequence, keep_reconstructions=True, texture_size=SIZE, texture_qp=22)


def test_decoder_reproduces_the_textured_reconstruction_bit_for_bit(coded):
    decoded = list(api.decode(coded.data))
    assert len(decoded) == len(coded.reconstructions)
    for r, d in zip(coded.reconstructions, decoded):
        assert np.array_equal(r.positions, d.positions) and np.array_equal(r.faces, d.faces)
        assert np.array_equal(r.uvs, d.uvs) and np.array_equal(r.uv_faces, d.uv_faces)
        assert d.image.shape == (SIZE, SIZE, 3) and d.image.dtype == np.uint8
        assert np.array_equal(r.image, d.image)


def test_predicted_frames_inherit_the_atlas_and_carry_no_texture_unit(coded):
    types = [f["type"] for f in coded.frames]
    assert types[0] == "I" and "P" in types, types
    frames = api.info(coded.data)["frames"]
    decoded = list(api.decode(coded.data))
    for i, (t, f) in enumerate(zip(types, frames)):
        assert (f["texture_bytes"] > 0) == (t == "I"), (i, t, f)
        if t == "P":
            assert np.array_equal(decoded[i].uv_faces, decoded[i - 1].uv_faces)
            assert np.array_equal(decoded[i].uvs, decoded[i - 1].uvs)
    assert coded.texture_bytes == sum(f["texture_bytes"] + 9 for f in frames if f["texture_bytes"])


def test_reconstructed_uvs_lie_in_the_atlas_and_cover_every_face(coded):
    r = coded.reconstructions[0]
    assert r.uv_faces.shape == r.faces.shape
    assert r.uvs.min() >= 0 and r.uvs.max() <= 1
    assert r.uv_faces.max() < len(r.uvs)


def test_texture_psnr_rises_with_rate_and_is_high_at_the_top(textured_sequence):
    figures = []
    for qp in (44, 30, 18):
        result = api.encode_frames(textured_sequence, keep_reconstructions=True, texture_size=SIZE, texture_qp=qp)
        m = api.metrics(textured_sequence, result.reconstructions)
        figures.append((result.texture_bytes, m["y_psnr"], m["cb_psnr"], m["cr_psnr"]))
    rates, luma = [f[0] for f in figures], [f[1] for f in figures]
    assert rates == sorted(rates) and luma == sorted(luma), figures
    assert luma[-1] > 28, figures
    assert all(np.isfinite(f[2]) and np.isfinite(f[3]) for f in figures)


def test_changing_topology_keeps_the_atlas_through_anchor_frames(changing_textured_sequence):
    result = api.encode_frames(changing_textured_sequence, keep_reconstructions=True, texture_size=SIZE)
    decoded = list(api.decode(result.data))
    for r, d in zip(result.reconstructions, decoded):
        assert np.array_equal(r.image, d.image) and np.array_equal(r.uvs, d.uvs)
    m = api.metrics(changing_textured_sequence, decoded)
    assert m["y_psnr"] > 20


def test_colour_metric_of_identical_textured_meshes_is_top_and_of_a_shifted_texture_matches_the_offset(textured_sequence):
    m = textured_sequence[0]
    same = api.metrics(m, m)
    assert same["y_psnr"] > 90 or same["y_psnr"] == float("inf")
    brighter = Mesh(m.positions, m.faces, uvs=m.uvs, uv_faces=m.uv_faces,
                    image=np.clip(m.image.astype(int) + 10, 0, 255).astype(np.uint8))
    # +10 on every channel of colours that never clip is +10/255 in Y and nothing in Cb, Cr.
    assert m.image.max() <= 245
    shifted = api.metrics(m, brighter)
    assert shifted["y_psnr"] == pytest.approx(20 * np.log10(255 / 10), abs=0.05)
    assert shifted["cb_psnr"] > 60 and shifted["cr_psnr"] > 60


def test_untextured_input_gives_a_stream_without_texture_units(sequence):
    result = api.encode_frames(sequence)
    assert result.texture_bytes == 0
    assert all(f["texture_bytes"] == 0 for f in api.info(result.data)["frames"])
    assert all(d.image is None for d in api.decode(result.data))


def test_texture_can_be_switched_off(textured_sequence):
    result = api.encode_frames(textured_sequence, texture=False)
    assert result.texture_bytes == 0


@pytest.mark.parametrize("options", [{"texture_qp": 60}, {"texture_size": 100.5}, {"texture_size": 17},
                                     {"texture_codec": "mpeg2"}, {"texture": "sometimes"}])
def test_bad_texture_options_raise_value_error(options, textured_sequence):
    with pytest.raises(ValueError):
        api.encode_frames(textured_sequence, **options)


def test_texture_on_untextured_input_is_refused(sequence):
    with pytest.raises(ValueError, match="UVs and a texture"):
        api.encode_frames(sequence, texture=True)


def test_corrupt_texture_data_is_a_decode_error(coded):
    data = coded.data
    dec = _core.Decoder(data)
    payload, offset = dec.texture_payload(0)
    # A flipped byte fails the unit's CRC.
    broken = bytearray(data)
    broken[offset + len(payload) // 2] ^= 0x40
    with pytest.raises(api.DecodeError):
        list(api.decode(bytes(broken)))
    # A unit with a valid CRC around damaged content: truncated video, garbage atlas, bad size.
    group = texture.unpack_group(payload)
    for bad in (texture.GroupHeader(**{**group.__dict__, "video": group.video[: len(group.video) // 3]}),
                texture.GroupHeader(**{**group.__dict__, "atlas": bytes(len(group.atlas))}),
                texture.GroupHeader(**{**group.__dict__, "frames": 99})):
        unit = _core.texture_unit(texture.pack_group(bad))
        start = offset - 5  # unit type byte and length before the payload
        end = offset + len(payload) + 4
        stream = data[:start] + unit + data[end:]
        with pytest.raises(api.DecodeError):
            list(api.decode(stream))
    for cut in (0, 5, len(payload) - 1):
        with pytest.raises(ValueError):
            texture.unpack_group(payload[:cut])


def test_video_round_trip_of_colour_is_close():
    image = checker_image(128)
    moved = np.roll(image, 3, axis=1)
    for codec in video.CODECS:
        out = list(video.decode_video(video.encode_video([image, moved], codec, 10), codec))
        assert len(out) == 2
        # Most of the error is 4:2:0 chroma on the checker's edges.
        assert np.abs(out[0].astype(int) - image).mean() < 4, codec
        assert np.abs(out[1].astype(int) - moved).mean() < 4, codec


def test_yuv420_conversion_is_bt709_full_range_and_checks_shapes():
    grey = np.full((2, 4, 3), 128, np.uint8)
    planes = _core.rgb_to_yuv420(grey)
    assert planes.shape == (3, 4) and planes.dtype == np.uint16
    assert (planes[:2] == round(128 / 255 * 1023)).all() and (planes[2] == 512).all()
    image = checker_image(32).repeat(2, axis=0).repeat(2, axis=1)
    back = _core.yuv420_to_rgb(_core.rgb_to_yuv420(image))
    assert back.shape == image.shape and np.abs(back.astype(int) - image).max() <= 1  # flat 2x2 blocks
    with pytest.raises(ValueError, match="even"):
        _core.rgb_to_yuv420(np.zeros((3, 4, 3), np.uint8))
    with pytest.raises(ValueError, match="3H/2"):
        _core.yuv420_to_rgb(np.zeros((4, 4), np.uint16))


def test_textures_on_some_frames_only_are_dropped_with_a_warning_naming_the_first_without(
        tmp_path, textured_sequence, capsys):
    plain = Mesh(textured_sequence[1].positions, textured_sequence[1].faces)
    frames = [textured_sequence[0], plain, textured_sequence[2]]
    with pytest.warns(api.TextureWarning, match=r"frame 1 \(1 of 3 frames\) has no UVs or texture image"):
        result = api.encode_frames(frames, texture_size=SIZE)
    assert result.texture_bytes == 0 and result.texture_options is None
    # On the command line: the same warning, as one line in the command's voice.
    src = tmp_path / "in"
    src.mkdir()
    write_image(src / "skin.png", textured_sequence[0].image)
    for i, m in enumerate(frames):
        textured = m.uvs is not None
        write_mesh(src / f"f{i}.obj", Mesh(m.positions, m.faces, uvs=m.uvs, uv_faces=m.uv_faces,
                                           texture=src / "skin.png" if textured else None))
    capsys.readouterr()
    assert main(["encode", str(src), "-o", str(tmp_path / "s.dmsh"), "--texture-size", str(SIZE), "-q"]) == 0
    err = capsys.readouterr().err.splitlines()
    assert [line for line in err if "warning" in line] == [
        "dynmesh encode: warning: frame 1 (1 of 3 frames) has no UVs or texture image: the stream carries the geometry "
        "only (--texture / texture=True refuses such input, --no-texture / texture=False drops the textures without "
        "this warning)"]
    assert main(["encode", str(src), "-o", str(tmp_path / "t.dmsh"), "--no-texture", "-q"]) == 0
    assert "warning" not in capsys.readouterr().err


def test_obj_with_texture_round_trips_through_the_command_line(tmp_path, textured_sequence):
    src = tmp_path / "in"
    src.mkdir()
    write_image(src / "skin.png", textured_sequence[0].image)
    for i, m in enumerate(textured_sequence):
        write_mesh(src / f"f{i}.obj", Mesh(m.positions, m.faces, uvs=m.uvs, uv_faces=m.uv_faces, texture=src / "skin.png"))
    stream, out = tmp_path / "s.dmsh", tmp_path / "out"
    assert main(["encode", str(src), "-o", str(stream), "--texture-size", str(SIZE), "-q"]) == 0
    assert main(["decode", str(stream), "-o", str(out), "-q"]) == 0
    frame = read_mesh(out / "frame_0000.obj")
    assert frame.uvs is not None and frame.texture.name == "frame_0000.png"
    assert read_image(frame.texture).shape == (SIZE, SIZE, 3)
    assert main(["metrics", str(src), str(out), "--json", "-q"]) == 0


def test_basketball_textured_codes_with_a_good_texture(tmp_path):
    folder = shared_sequence("basketball_textured")
    frames = [read_mesh(p) for p in sorted(folder.glob("*.obj"))[:2]]
    result = api.encode_frames(frames, keep_reconstructions=True, texture_size=1024, texture_qp=22)
    m = api.metrics(frames, result.reconstructions, peak=1876.1)
    assert m["y_psnr"] > 30, m
    decoded = list(dynmesh.decode(result.data))
    assert all(np.array_equal(r.image, d.image) for r, d in zip(result.reconstructions, decoded))


def _through_every_inter_tool() -> list:
    """(name, textured frames, options) that drive a textured stream through each inter tool:
    the refresh (a part appears), reference choice (a frame repeats an older one), fold
    repair and the anchor's stages (changing topology), rigid alignment (turning gears)."""
    from dynmesh.conformance import appearing
    from dynmesh.synth import gear_sequence

    image = checker_image(seed=2)
    textured = lambda frames: [with_spherical_uvs(m, image) for m in frames]
    blobs = synth_sequence(frames=40, resolution=14)
    warped = [Mesh(blobs[0].positions + [0.06 * f, 0, 0] * np.sin(2 * blobs[0].positions[:, 1:2]), blobs[0].faces)
              for f in range(3)]
    small = dict(qp=30, subdiv=2, base_bits=8, bits=11)
    merging = synth_sequence(frames=10, resolution=24)[:3]
    return [
        ("refresh", textured(appearing(blobs[:3])), small),
        ("refresh, older references", textured(appearing(blobs[:3]) + appearing(blobs[:3])[1:2]),
         dict(small, references=3, rd_slope=100.0)),
        ("repeated poses", textured([warped[0], warped[1], warped[2], warped[1]]), dict(references=3, rd_slope=100.0, qp=30)),
        ("anchor, no fold repair", textured(merging), dict(fold_repair=False)),
        ("anchor nns+me", textured(merging), dict(inter="nns+me")),
        ("rigid gears", textured(gear_sequence(3, turn_degrees=12.0, samples=300)), dict(qp=28)),
    ]


@pytest.mark.parametrize("name, frames, options", _through_every_inter_tool(), ids=lambda v: v if isinstance(v, str) else "")
def test_every_inter_tool_gives_textured_frames_uvs_and_decodes_bit_for_bit(name, frames, options):
    result = api.encode_frames(frames, keep_reconstructions=True, texture_size=64, **options)
    assert "P" in [f["type"] for f in result.frames], name
    decoded = list(api.decode(result.data))
    for i, (r, d) in enumerate(zip(result.reconstructions, decoded)):
        assert r.uv_faces.shape == r.faces.shape, (name, i)
        assert np.array_equal(r.positions, d.positions) and np.array_equal(r.faces, d.faces), (name, i)
        assert np.array_equal(r.uvs, d.uvs) and np.array_equal(r.uv_faces, d.uv_faces), (name, i)
        assert np.array_equal(r.image, d.image), (name, i)


def test_a_refreshed_frame_starts_a_texture_group_of_its_own():
    # Weighed with its texture, this refresh loses to intra (both start a texture group);
    # coded on geometry alone (a texture stage that estimates no costs) it is kept.
    name, frames, options = _through_every_inter_tool()[0]
    opts = {**api.DEFAULTS, **options}
    enc = api._encoder(len(frames), *api.sequence_bounds(frames), opts)
    tex = texture.TextureEncoder(opts["subdiv"], {"texture_size": 64, "texture_qp": 30}, keep_images=True)
    result = api.encode_units(enc, tex, frames, 0, len(frames), True, None)
    assert [f["type"] for f in result.frames] == ["I", "P", "P"] and result.frames[1]["refreshed_faces"] > 0
    data = enc.header_bytes() + result.data
    # Frame 1's base has faces frame 0's atlas has no UVs for: it carries an atlas of its
    # own, which frame 2 (moved from frame 1's base) shares.
    assert [f["texture_bytes"] > 0 for f in api.info(data)["frames"]] == [True, True, False]
    # The geometry encoder's statistic says where the groups start; the texture stage follows it.
    assert [f["starts_texture_group"] for f in result.frames] == [True, True, False]
    assert np.array_equal(result.reconstructions[2].uv_faces, result.reconstructions[1].uv_faces)
    for r, d in zip(result.reconstructions, api.decode(data)):
        assert np.array_equal(r.uvs, d.uvs) and np.array_equal(r.uv_faces, d.uv_faces) and np.array_equal(r.image, d.image)


def test_texture_size_and_qp_follow_the_source_and_the_geometry_qp(textured_sequence):
    assert texture.atlas_size_for(1024, 1024) == 1024 and texture.atlas_size_for(2048, 2048) == 2048
    assert texture.atlas_size_for(2048, 1024) == 1456 and texture.atlas_size_for(3, 5) == 16
    # The test sequence's texture is 128 x 128: so is its atlas, unless told otherwise.
    for options, side in (({}, 128), ({"texture_size": 96}, 96)):
        result = api.encode_frames(textured_sequence, keep_reconstructions=True, **options)
        assert result.reconstructions[0].image.shape == (side, side, 3)
    opts = texture.resolve_options({}, 30, textured_sequence[0])
    assert opts["texture_qp"] == dynmesh.defaults.texture_qp_for(30)
    assert texture.resolve_options({"texture_qp": 40}, 30, textured_sequence[0])["texture_qp"] == 40
    assert [dynmesh.defaults.texture_qp_for(q) for q in (20, 28, 36)] == sorted(dynmesh.defaults.texture_qp_for(q) for q in (20, 28, 36))


def test_the_encoder_reports_the_texture_options_it_chose_and_the_atlas_texels_used(tmp_path, textured_sequence):
    result = api.encode_frames(textured_sequence)
    assert result.texture_options["texture_size"] == 128
    assert result.texture_options["texture_qp"] == dynmesh.defaults.texture_qp_for(api.DEFAULTS["qp"])
    assert all(0 < f["texture_coverage"] < 1 for f in result.frames)
    assert api.encode_frames(textured_sequence, texture=False).texture_options is None


def _frame_types(frames, cost) -> str:
    lo, hi = api.sequence_bounds(frames)
    enc = _core.Encoder(len(frames), lo.tolist(), hi.tolist(), dict(api.DEFAULTS))
    types = []
    for m in frames:
        types.append(enc.encode_frame(m.positions, m.faces, cost)[1]["type"])
    return "".join(types)


def test_frame_decisions_weigh_what_a_texture_restart_costs():
    frames = synth_sequence(frames=10, resolution=24)
    geometry = _frame_types(frames, None)
    assert "I" in geometry[1:], geometry  # merging blobs: some frames lose as predicted ones
    assert _frame_types(frames, (0.0, 0.0)) == geometry
    # An atlas and an intra video frame that cost far more than a predicted video frame
    # make every frame that can be predicted a predicted one.
    textured = _frame_types(frames, (100.0, 1e7))
    assert textured.count("P") > geometry.count("P") and textured[0] == "I", (geometry, textured)
    # A callable is asked during the frame's coding; what it raises comes through.
    assert _frame_types(frames, lambda: (100.0, 1e7)) == textured
    m, (lo, hi) = frames[0], api.sequence_bounds(frames)
    for bad in ((-1.0, 5.0), (float("nan"), 1.0), lambda: (-1.0, 5.0)):
        with pytest.raises(ValueError, match="texture costs"):
            _core.Encoder(2, lo.tolist(), hi.tolist(), dict(api.DEFAULTS)).encode_frame(m.positions, m.faces, bad)

    def failing():
        raise KeyError("the texture stage failed")

    with pytest.raises(KeyError, match="texture stage failed"):
        _core.Encoder(2, lo.tolist(), hi.tolist(), dict(api.DEFAULTS)).encode_frame(m.positions, m.faces, failing)


def test_textured_streams_decide_with_texture_and_still_decode_bit_for_bit():
    image = checker_image(seed=3)
    frames = [with_spherical_uvs(m, image) for m in synth_sequence(frames=10, resolution=24)]
    textured = api.encode_frames(frames, keep_reconstructions=True, texture_size=64)
    geometry = api.encode_frames(frames, texture=False)
    types = lambda r: "".join(f["type"] for f in r.frames)
    assert types(textured).count("P") >= types(geometry).count("P"), (types(geometry), types(textured))
    for r, d in zip(textured.reconstructions, api.decode(textured.data)):
        assert np.array_equal(r.positions, d.positions) and np.array_equal(r.image, d.image)


def test_a_texture_that_fails_on_its_thread_names_its_frame_and_stops_the_thread(textured_sequence, capfd):
    # The texture stage runs a frame behind the geometry on a thread of its own: a frame
    # whose texture cannot be transferred still fails the encode, naming that frame.
    frames = list(textured_sequence)
    bad = frames[2]
    frames[2] = Mesh(bad.positions, bad.faces, uvs=bad.uvs, uv_faces=bad.uv_faces[:-1], image=bad.image)
    with pytest.raises(ValueError, match=r"^frame 2: .*uv_faces"):
        api.encode_frames(frames, texture_size=SIZE)
    import threading

    assert not [t for t in threading.enumerate() if t.name.startswith("dynmesh-texture")]
    assert capfd.readouterr().err == ""  # the video of the unfinished group was ended quietly


def test_steps_that_hold_the_gil_wait_until_the_caller_is_in_the_geometry_core(textured_sequence):
    # xatlas holds the GIL for all of an atlas: made while the caller runs Python between
    # frames, it would stall the caller. The texture thread waits until the caller enters
    # the geometry core (or waits for the thread) to make it.
    m = textured_sequence[0]
    tex = texture.TextureEncoder(0, {"texture_size": 64, "texture_qp": 30})  # no subdivision: base = surface
    try:
        tex.add(True, m, m, m)
        time.sleep(0.3)
        assert tex._group is None  # the atlas waits ...
        with tex.geometry():
            tex._coded.result(timeout=60)  # ... and is made once the caller is away
        assert tex._group is not None
        [(first, unit)] = tex.finish()
        assert first == 0 and texture.unpack_group(unit).frames == 1
    finally:
        tex.close()
