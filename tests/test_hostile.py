"""Hostile streams: every failure is a DecodeError naming the frame and offset."""

import random

import pytest

import dynmesh

from conftest import uv_sphere


@pytest.fixture(scope="module")
def small_stream() -> bytes:
    frames = [uv_sphere(5, 6), uv_sphere(6, 6, radius=0.9)]
    return dynmesh.encode(frames, subdiv=1, qp=30)


def decode_all(data: bytes) -> list:
    return list(dynmesh.decode(data))


def test_every_truncation_is_a_decode_error(small_stream):
    assert len(decode_all(small_stream)) == 2
    for cut in range(len(small_stream)):
        with pytest.raises(dynmesh.DecodeError) as e:
            decode_all(small_stream[:cut])
        assert e.value.offset >= 0
        assert "offset" in str(e.value)


def test_random_bit_flips_are_decode_errors(small_stream):
    rng = random.Random(1)
    frames_named = 0
    for _ in range(1000):
        data = bytearray(small_stream)
        for _ in range(rng.randint(1, 3)):
            i = rng.randrange(len(data) * 8)
            data[i // 8] ^= 1 << (i % 8)
        with pytest.raises(dynmesh.DecodeError) as e:
            decode_all(bytes(data))
        frames_named += e.value.frame is not None
    assert frames_named > 0


def test_garbage_and_empty_input_are_decode_errors():
    for data in (b"", b"DMSH", b"not a stream at all", bytes(range(256)) * 4):
        with pytest.raises(dynmesh.DecodeError):
            decode_all(data)
