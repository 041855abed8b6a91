"""The JavaScript decoder (web/) against the Rust core: identical frame hashes on every
conformance vector at every level of detail, on streams of the shared capture sequences, and
identical errors on damaged streams. Needs Node.js (the CI installs it; the machine has it)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest

from conftest import SHARED_DATA
from dynmesh import _core, api
from dynmesh.conformance import frame_hash, uv_hash
from dynmesh.io import read_mesh, resolve_sequence

ROOT = Path(__file__).resolve().parents[1]
WEB = ROOT / "web"
VECTORS = ROOT / "tests" / "vectors"
NODE = shutil.which("node")

pytestmark = pytest.mark.skipif(NODE is None, reason="Node.js is not installed")  # never in CI: .ci/run installs it


def js_decode(paths: list[Path], lod: int | None = None) -> list[dict]:
    """The JavaScript decoder's result for each stream: hashes, and the error if any."""
    extra = ["--lod", str(lod)] if lod is not None else []
    out = subprocess.run([NODE, str(WEB / "test" / "helpers" / "decode-batch.js"), *extra, *map(str, paths)],
                         capture_output=True, text=True, timeout=600, check=True)
    return [json.loads(line) for line in out.stdout.splitlines()]


def rust_decode(data: bytes, lod: int | None = None) -> dict:
    hashes = []
    try:
        for m in api.decode(data, lod=lod):
            hashes.append(frame_hash(m))
    except (api.DecodeError, ValueError) as e:  # ValueError: a level of detail beyond the stream's
        return {"hashes": hashes, "error": str(e)}
    return {"hashes": hashes}


def test_cli_hash_lines_are_identical_in_both_decoders():
    stream = VECTORS / "constant_loop_noaq.dmsh"
    for lod in (None, 1):
        extra = [] if lod is None else ["--lod", str(lod)]
        py = subprocess.run([sys.executable, "-m", "dynmesh", "decode", str(stream), "--hash", *extra],
                            capture_output=True, text=True, check=True).stdout
        js = subprocess.run([NODE, str(WEB / "bin" / "dynmesh-decode.js"), str(stream), "--hash", *extra],
                            capture_output=True, text=True, check=True).stdout
        assert py == js
        assert py.splitlines()[0].startswith("frame 0 sha256 ") and len(py.splitlines()) == 3


def test_every_level_of_detail_of_every_vector_matches():
    streams = sorted(VECTORS.glob("*.dmsh"))
    assert len(streams) >= 5
    for lod in range(4):
        js = js_decode(streams, lod)
        for path, j in zip(streams, js):
            r = rust_decode(path.read_bytes(), lod)
            assert j.get("error") == r.get("error") and j["hashes"] == r["hashes"], (path.name, lod)
    # A coarser level is a different, smaller mesh: the option does something.
    full, base = rust_decode((VECTORS / "anchor_mixed_aq.dmsh").read_bytes()), rust_decode((VECTORS / "anchor_mixed_aq.dmsh").read_bytes(), 0)
    assert full["hashes"] != base["hashes"]


def _with_crc(unit: bytearray) -> bytearray:
    """A frame unit with its CRC recomputed, so that damage inside reaches the payload parser."""
    unit[-4:] = zlib.crc32(bytes(unit[:-4])).to_bytes(4, "little")
    return unit


def damaged_streams(data: bytes, count: int, seed: int, unit_index: int = 0) -> list[bytes]:
    """Truncations, plain bit flips (caught by CRCs) and payload damage behind valid CRCs
    (in frame unit ``unit_index``)."""
    rng = np.random.default_rng(seed)
    header_len = 75 + 3 * data[43]  # docs/bitstream.md section 2
    out = [data[:n] for n in (0, 3, 10, header_len - 1, header_len + 4, len(data) // 2, len(data) - 1)]
    for _ in range(count):
        d = bytearray(data)
        d[int(rng.integers(len(d)))] ^= 1 << int(rng.integers(8))
        out.append(bytes(d))
    # Damage inside that frame unit's payload, CRC made valid again.
    start = header_len
    for _ in range(unit_index):
        start += 9 + int.from_bytes(data[start + 1:start + 5], "little")
    length = int.from_bytes(data[start + 1:start + 5], "little")
    for _ in range(count):
        unit = bytearray(data[start:start + 9 + length])
        for _ in range(int(rng.integers(1, 4))):
            unit[5 + int(rng.integers(length))] = int(rng.integers(256))
        out.append(data[:start] + bytes(_with_crc(unit)) + data[start + 9 + length:])
    return out


def test_damaged_streams_give_the_same_errors_in_both_decoders(tmp_path):
    cases = []
    # The last: damage in the refreshed predicted frame (unit 1) of anchor_refresh.
    streams = [("anchor_mixed_aq", 0), ("constant_midpoint_all", 0), ("intra_loop_aq_all", 0), ("anchor_refresh", 1)]
    for k, (name, unit) in enumerate(streams):
        for i, d in enumerate(damaged_streams((VECTORS / f"{name}.dmsh").read_bytes(), 40, k, unit)):
            path = tmp_path / f"{name}_{i}.dmsh"
            path.write_bytes(d)
            cases.append((path, d))
    js = js_decode([p for p, _ in cases])
    errors = 0
    for (path, d), j in zip(cases, js):
        r = rust_decode(d)
        assert (j.get("error"), j["hashes"]) == (r.get("error"), r["hashes"]), path.name
        errors += "error" in r
    assert errors > len(cases) // 2  # most damage is caught, and caught the same way


def test_texture_unit_payloads_read_alike_in_both_readers():
    # The core's reader (stream/texture_payload.rs) and web/src/texture/unit.js, on a payload
    # and on every way of damaging it: the same fields, or the same error.
    good = _core.pack_texture_payload(1, 1024, 512, 12, 3, b"atlas", b"video!")
    def with_byte(i, v):
        return good[:i] + bytes([v]) + good[i + 1:]
    cases = [good, good[:10], with_byte(0, 2), with_byte(1, 2), with_byte(2, 1), with_byte(5, 0x41), with_byte(6, 0),
             with_byte(6, 17), good[:7] + bytes(4) + good[11:], good[:13], good[:17], good[:-1], good + b"\0",
             with_byte(11, 0xFF)]
    script = (f"import {{ readTextureUnit }} from {json.dumps((WEB / 'src' / 'texture' / 'unit.js').as_uri())};"
              "for (const hex of JSON.parse(process.argv[1])) { try { const u = readTextureUnit(Buffer.from(hex, 'hex'));"
              " console.log(JSON.stringify([u.codec, u.width, u.height, u.uvBits, u.frames, Buffer.from(u.atlas).toString('hex'),"
              " Buffer.from(u.video).toString('hex')])); } catch (e) { console.log(JSON.stringify(e.message)); } }")
    out = subprocess.run([NODE, "--input-type=module", "-e", script, json.dumps([c.hex() for c in cases])],
                         capture_output=True, text=True, timeout=60, check=True)
    for case, line in zip(cases, out.stdout.splitlines(), strict=True):
        try:
            codec, w, h, bits, frames, atlas, video = _core.read_texture_payload(case)
            want = [_core.TEXTURE_CODECS[codec], w, h, bits, frames, atlas.hex(), video.hex()]
        except ValueError as e:
            want = str(e)
        assert json.loads(line) == want, case.hex()


# Two here (the Node tests, web/test/shared.test.js, take four others): constant face count
# with changing connectivity, and two components merging.
SHARED = ["mitch", "collision"]


@pytest.mark.skipif(not (SHARED_DATA / "basketball_textured").is_dir(), reason="../shared/data is absent")
def test_js_decodes_the_uv_atlas_of_a_textured_capture_as_rust_does(tmp_path):
    frames = [read_mesh(p) for p in resolve_sequence(str(SHARED_DATA / "basketball_textured"), None, 2)]
    data = api.encode(frames, qp=28, texture_size=256)
    path = tmp_path / "textured.dmsh"
    path.write_bytes(data)
    for lod in (None, 1):
        (j,) = js_decode([path], lod)
        decoded = list(api.decode(data, lod=lod))
        assert j["hashes"] == [frame_hash(m) for m in decoded]
        assert j["uvHashes"] == [uv_hash(m) for m in decoded]


@pytest.mark.skipif(not SHARED_DATA.is_dir(), reason="../shared/data is absent")
@pytest.mark.parametrize("name", SHARED)
def test_js_equals_rust_on_a_shared_capture_sequence(name, tmp_path):
    frames = [read_mesh(p) for p in resolve_sequence(str(SHARED_DATA / name), None, 3)]
    data = api.encode(frames, qp=28)
    path = tmp_path / f"{name}.dmsh"
    path.write_bytes(data)
    (j,) = js_decode([path])
    r = rust_decode(data)
    assert "error" not in j and j["hashes"] == r["hashes"] and len(r["hashes"]) == 3
