"""The exception classes of the core's errors: one per kind (bad input, a stream that cannot be
decoded, a stream this build does not read, a bug), each raised where it should be and each a
subclass of what callers caught before (ValueError), except the bug's (RuntimeError)."""

from __future__ import annotations

import pickle
import zlib

import numpy as np
import pytest

import dynmesh
from dynmesh import _core, api, cli

from conftest import uv_sphere

#: Byte offset of the format version in a stream (after the magic, docs/bitstream.md).
VERSION_AT = 4


@pytest.fixture(scope="module")
def small_stream() -> bytes:
    return dynmesh.encode([uv_sphere(5, 6), uv_sphere(6, 6, radius=0.9)], subdiv=1, qp=30)


def header_crc_at(data: bytes) -> int:
    """Where the sequence header's CRC is: the first 4 bytes that are the CRC-32 of all before."""
    return next(i for i in range(VERSION_AT + 1, len(data)) if zlib.crc32(data[:i]).to_bytes(4, "little") == data[i:i + 4])


def newer(data: bytes) -> bytes:
    """The stream as a next format version might write it: its version, and a header of
    another layout (here, a byte more after the version) ending with its CRC."""
    at = header_crc_at(data)
    header = data[:VERSION_AT] + bytes([data[VERSION_AT] + 1, 0]) + data[VERSION_AT + 1:at]
    return header + zlib.crc32(header).to_bytes(4, "little") + data[at + 4:]


def test_a_damaged_version_byte_is_a_decode_error_not_another_version(small_stream):
    # The header reads with a valid CRC once this version is put back: corruption.
    damaged = small_stream[:VERSION_AT] + bytes([small_stream[VERSION_AT] + 1]) + small_stream[VERSION_AT + 1:]
    with pytest.raises(dynmesh.DecodeError, match="unsupported format version") as e:
        list(dynmesh.decode(damaged))
    assert e.value.frame is None
    # Damaged beyond its version byte too: its header holds in no layout.
    garbled = bytearray(newer(small_stream))
    garbled[30] ^= 8
    with pytest.raises(dynmesh.DecodeError):
        list(dynmesh.decode(bytes(garbled)))


def test_the_classes_subclass_what_callers_caught_and_are_exported_everywhere():
    for name, base in (("InputError", ValueError), ("DecodeError", ValueError), ("UnsupportedError", ValueError),
                       ("InternalError", RuntimeError)):
        core_class = getattr(_core, name)
        assert issubclass(core_class, base), name
        assert getattr(dynmesh, name) is getattr(api, name), name
        assert name in dynmesh.__all__, name
    assert not issubclass(_core.InternalError, ValueError)
    for name in ("InputError", "UnsupportedError", "InternalError"):
        assert getattr(dynmesh, name) is getattr(_core, name)
    # dynmesh.DecodeError is the Python class with frame and offset that api raises (as before).
    assert dynmesh.DecodeError is api.DecodeError and issubclass(dynmesh.DecodeError, ValueError)
    assert len({_core.InputError, _core.DecodeError, _core.UnsupportedError, _core.InternalError}) == 4
    for cls in (_core.InputError, _core.DecodeError, _core.UnsupportedError, _core.InternalError):
        # Importable where they live, so that a worker process's exception pickles.
        assert type(pickle.loads(pickle.dumps(cls("x")))) is cls


def test_a_malformed_mesh_is_an_input_error(sphere):
    lo, hi = sphere.bounds()
    enc = _core.Encoder(1, lo.tolist(), hi.tolist(), {})
    bad = sphere.faces.copy()
    bad[3, 1] = len(sphere.positions)
    with pytest.raises(_core.InputError, match="face 3 refers to a vertex that does not exist"):
        enc.encode_frame(sphere.positions, bad)
    nan = sphere.positions.copy()
    nan[5, 2] = np.nan
    with pytest.raises(_core.InputError):
        enc.encode_frame(nan, sphere.faces)
    flat = np.zeros_like(sphere.positions)
    with pytest.raises(_core.InputError, match="no area"):
        enc.encode_frame(flat, sphere.faces)
    with pytest.raises(_core.InputError, match="shape"):
        enc.encode_frame(sphere.positions[:, :2].copy(), sphere.faces)
    # The encoder is still usable: the refused frames were not coded.
    unit, stats, _, _ = enc.encode_frame(sphere.positions, sphere.faces)
    assert stats["type"] == "I" and len(unit) > 0


def test_an_encoder_stops_after_a_frame_that_failed_half_way(sphere):
    # A texture cost that raises, asked once the frame's predicted candidate is built, leaves
    # a frame the caller never receives: the encoder refuses to code on after it.
    lo, hi = sphere.bounds()
    enc = _core.Encoder(3, lo.tolist(), hi.tolist(), {})
    enc.encode_frame(sphere.positions, sphere.faces)

    def broken():
        raise RuntimeError("texture thread failed")

    with pytest.raises(RuntimeError, match="texture thread failed"):
        enc.encode_frame(sphere.positions, sphere.faces, broken)
    with pytest.raises(_core.InputError, match="stopped at frame 1, whose texture cost raised"):
        enc.encode_frame(sphere.positions, sphere.faces)


def test_a_frame_the_stream_does_not_have_is_an_input_error_not_damage(small_stream):
    dec = _core.Decoder(small_stream)
    n = dec.frame_count
    for ask in (lambda: dec.decode_frame(n), lambda: dec.frame_info(n), lambda: dec.texture_payload(n)):
        with pytest.raises(_core.InputError, match=f"frame {n} does not exist: the stream has {n} frames?$"):
            ask()
    assert len(dec.decode_frame(n - 1)[0]) > 0  # the decoder goes on


def test_options_and_arguments_out_of_range_are_input_errors(sphere, small_stream):
    with pytest.raises(dynmesh.InputError):
        dynmesh.encode([sphere], qp=10_000)
    with pytest.raises(dynmesh.InputError):
        _core.Encoder(1, [0.0] * 3, [float("inf")] * 3, {})
    with pytest.raises(dynmesh.InputError, match="level of detail"):
        list(dynmesh.decode(small_stream, lod=9))
    with pytest.raises(dynmesh.InputError):
        _core.subdivide_uv(np.zeros((3, 2)), np.array([[0, 1, 2]]), 99)


def test_encode_names_the_frame_it_refuses_and_keeps_the_class(sphere):
    flat = dynmesh.Mesh(np.zeros_like(sphere.positions), sphere.faces)
    with pytest.raises(dynmesh.InputError, match="^frame 1: .*no area"):
        dynmesh.encode([sphere, flat], subdiv=1)


def test_a_textured_stream_of_an_unknown_texture_codec_is_unsupported_through_decode():
    m = uv_sphere(8, 12)
    uv = (m.positions[:, :2] + 1) / 2
    image = np.random.default_rng(1).integers(0, 256, (32, 32, 3), dtype=np.uint8)
    frames = [dynmesh.Mesh(m.positions, m.faces, uvs=uv, uv_faces=m.faces.copy(), image=image)] * 2
    data = bytearray(dynmesh.encode(frames, subdiv=1, texture_size=32))
    payload, at = _core.Decoder(bytes(data)).texture_payload(0)
    # The unit's codec byte set to one this build does not know, its CRC made to hold again.
    data[at + 1] = len(_core.TEXTURE_CODECS)
    end = at + len(payload)
    data[end:end + 4] = zlib.crc32(bytes(data[at - 5:end])).to_bytes(4, "little")
    with pytest.raises(dynmesh.UnsupportedError, match="^frame 0: .*unknown texture codec"):
        list(dynmesh.decode(bytes(data)))
    (_, unsupported), = [x for x in dynmesh.api.decode_each(bytes(data)) if x[0] == 0]
    assert isinstance(unsupported, dynmesh.UnsupportedError)


def test_a_truncated_stream_is_a_decode_error_with_frame_and_offset(small_stream):
    header_cut, unit_cut = 20, len(small_stream) - 5
    with pytest.raises(dynmesh.DecodeError) as e:
        list(dynmesh.decode(small_stream[:header_cut]))
    assert e.value.frame is None and e.value.offset >= 0
    with pytest.raises(dynmesh.DecodeError) as e:
        list(dynmesh.decode(small_stream[:unit_cut]))
    assert e.value.frame == 1 and e.value.offset > header_cut and "offset" in str(e.value)
    # The core's class, as the bindings raise it: args (message, frame, offset).
    with pytest.raises(_core.DecodeError) as e:
        _core.Decoder(small_stream[:unit_cut])
    message, frame, offset = e.value.args
    assert frame == 1 and f"frame 1, byte offset {offset}: " in message
    assert not isinstance(e.value, (_core.InputError, _core.UnsupportedError))


def test_a_corrupt_block_given_on_its_own_is_a_decode_error_with_its_message_alone():
    faces = np.array([[0, 1, 2]])
    data = _core.encode_uv(faces, faces, np.array([[0, 0], [5, 0], [0, 5]]), 4)
    with pytest.raises(_core.DecodeError) as e:
        _core.decode_uv(data[:1], faces, 3, 4)
    assert len(e.value.args) == 1 and str(e.value) == e.value.args[0]
    with pytest.raises(_core.DecodeError, match="truncated") as e:
        _core.read_texture_payload(b"\x01\x00\x40")
    assert str(e.value) == "texture unit is truncated"


def test_a_stream_of_another_format_version_is_unsupported(small_stream):
    data = newer(small_stream)
    for read in (lambda: list(dynmesh.decode(data)), lambda: dynmesh.info(data), lambda: dynmesh.api.damage(data),
                 lambda: _core.Decoder(data)):
        with pytest.raises(dynmesh.UnsupportedError, match="unsupported format version") as e:
            read()
        assert not isinstance(e.value, (_core.DecodeError, dynmesh.DecodeError))
        assert isinstance(e.value, ValueError)


def test_a_texture_unit_of_an_unknown_codec_or_version_is_unsupported():
    payload = _core.pack_texture_payload(0, 64, 32, 12, 2, b"\x01", b"\x02\x03")
    assert _core.read_texture_payload(payload)[:5] == (0, 64, 32, 12, 2)
    unknown_codec = payload[:1] + bytes([len(_core.TEXTURE_CODECS)]) + payload[2:]
    with pytest.raises(dynmesh.UnsupportedError, match="unknown texture codec"):
        _core.read_texture_payload(unknown_codec)
    with pytest.raises(dynmesh.UnsupportedError, match="texture unit version 9 is not supported"):
        _core.read_texture_payload(b"\x09" + payload[1:])


def test_a_panic_in_the_core_is_an_internal_error_that_says_it_is_a_bug():
    with pytest.raises(dynmesh.InternalError) as e:
        _core._panic_for_tests("something impossible")
    text = str(e.value)
    assert text.startswith("internal error (a bug in dynmesh, please report it): something impossible (at ")
    assert "errors.rs" in text
    assert not isinstance(e.value, ValueError)


def test_the_command_line_reports_each_kind_in_one_line(tmp_path, small_stream, monkeypatch, capsys):
    stream = tmp_path / "newer.dmsh"
    stream.write_bytes(newer(small_stream))
    assert cli.main(["decode", str(stream), "--hash"]) == 1
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "error: " in err and "unsupported format version" in err, err
    cut = tmp_path / "cut.dmsh"
    cut.write_bytes(small_stream[:30])
    assert cli.main(["info", str(cut)]) == 1
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "byte offset" in err, err

    def buggy(a):
        _core._panic_for_tests("a broken invariant")

    monkeypatch.setattr(cli, "cmd_info", buggy)
    assert cli.main(["info", str(cut)]) == cli.EXIT_INTERNAL == 70
    err = capsys.readouterr().err
    assert err.startswith("dynmesh info: internal error (a bug in dynmesh, please report it): a broken invariant"), err
    assert len(err.strip().splitlines()) == 1, err


def test_every_help_states_the_internal_error_status():
    helped = " ".join(cli.parser().format_help().split())
    assert " ".join(cli.INTERNAL_STATUS_HELP.split()) in helped
    assert "70 " in cli.INTERNAL_STATUS_HELP
