"""The command line: each command end to end, JSON output, and clean failures."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dynmesh.io import read_mesh, write_mesh

from conftest import shared_sequence, wobbly_sequence


def run(*args, check=True):
    p = subprocess.run([sys.executable, "-m", "dynmesh", *map(str, args)], capture_output=True, text=True)
    if check and p.returncode != 0:
        raise AssertionError(f"exit {p.returncode}: {p.stderr}")
    return p


@pytest.fixture
def frames_dir(tmp_path):
    d = tmp_path / "in"
    d.mkdir()
    for i, m in enumerate(wobbly_sequence(3, 12, 16)):
        write_mesh(d / f"f{i}.obj", m)
    return d


def test_encode_decode_info_metrics_round_trip(tmp_path, frames_dir):
    stream = tmp_path / "s.dmsh"
    enc = json.loads(run("encode", frames_dir, "-o", stream, "--qp", "20", "--json").stdout)
    assert enc["bytes"] == stream.stat().st_size
    assert [f["frame"] for f in enc["frames"]] == [0, 1, 2]
    info = json.loads(run("info", stream, "--json").stdout)
    assert info["header"]["frame_count"] == 3
    out = tmp_path / "out"
    run("decode", stream, "-o", out, "--format", "ply")
    files = sorted(out.iterdir())
    assert [f.name for f in files] == ["frame_0000.ply", "frame_0001.ply", "frame_0002.ply"]
    assert read_mesh(files[0]).face_count > 0
    m = json.loads(run("metrics", frames_dir, out, "--json").stdout)
    assert len(m["frames"]) == 3 and m["d1_psnr"] > 50


def test_human_output_has_a_per_frame_table(tmp_path, frames_dir):
    out = run("encode", frames_dir, "-o", tmp_path / "s.dmsh", "-q").stdout
    assert "base faces" in out and "Mbit/s" in out
    assert len([l for l in out.splitlines() if l.strip().startswith(("0 ", "1 ", "2 "))]) == 3


def test_start_and_count_select_frames(tmp_path, frames_dir):
    enc = json.loads(run("encode", frames_dir, "-o", tmp_path / "s.dmsh", "--start", "1", "--count", "2", "--json").stdout)
    assert [f["input"].endswith(n) for f, n in zip(enc["frames"], ["f1.obj", "f2.obj"])] == [True, True]
    out = tmp_path / "out"
    run("decode", tmp_path / "s.dmsh", "-o", out, "-q")
    mismatch = run("metrics", frames_dir, out, check=False)
    assert mismatch.returncode == 1 and "3 reference frames but 2 decoded" in mismatch.stderr
    m = json.loads(run("metrics", frames_dir, out, "--start", "1", "--count", "2", "--json").stdout)
    assert len(m["frames"]) == 2 and m["d1_psnr"] > 50


def test_every_command_has_help():
    for cmd in ["encode", "decode", "info", "metrics", "synth", "demo", "eval", "play"]:
        assert "usage" in run(cmd, "--help").stdout


def test_base_ratio_help_states_the_encoders_rule():
    # The rule is read from the core: each run it names holds the ratio the core takes there,
    # and the help and the README state it in the same words.
    from pathlib import Path

    from dynmesh import _core
    from dynmesh.defaults import QP_RANGE, base_ratio_rule

    rule = base_ratio_rule()
    runs = rule.split(", ")
    assert len(runs) >= 2 and runs[0].split()[1:3] == ["up", "to"] and runs[-1].split()[1] == "from"
    last_qp = QP_RANGE[0] - 1
    for words in runs[:-1]:
        ratio, end = float(words.split()[0]), int(words.split()[-1])
        assert {_core.base_ratio_for_qp(q) for q in range(last_qp + 1, end + 1)} == {ratio}
        assert _core.base_ratio_for_qp(end + 1) != ratio
        last_qp = end
    ratio, start = float(runs[-1].split()[0]), int(runs[-1].split()[-1])
    assert start == last_qp + 1 and {_core.base_ratio_for_qp(q) for q in range(start, QP_RANGE[1] + 1)} == {ratio}
    assert rule in " ".join(run("encode", "--help").stdout.split())
    readme = Path(__file__).resolve().parents[1] / "README.md"
    assert rule in " ".join(readme.read_text().split())


def test_encode_flags_are_the_encoder_options():
    # Every option the core names has a flag, and the flags' defaults are the core's defaults.
    from dynmesh import cli
    from dynmesh.defaults import ENCODER, TEXTURE

    a = cli.parser().parse_args(["encode", "in", "-o", "out.dmsh"])
    assert cli._encoder_options(a) == {**ENCODER, **TEXTURE, "texture": "auto"}
    a = cli.parser().parse_args(["encode", "in", "-o", "o", "--all-components", "--no-aq", "--inter", "nns", "--base-ratio", "0.1"])
    options = cli._encoder_options(a)
    assert (options["normal_only"], options["aq"], options["inter"], options["base_ratio"]) == (False, False, "nns", 0.1)


@pytest.mark.parametrize("args, message", [
    (["encode", "missing_dir", "-o", "x.dmsh"], "missing_dir"),
    (["info", "missing.dmsh"], "missing.dmsh"),
])
def test_missing_inputs_fail_with_a_message(tmp_path, args, message):
    p = run(*args, check=False)
    assert p.returncode == 1
    assert message in p.stderr and "Traceback" not in p.stderr


def test_bad_option_fails_cleanly_and_writes_nothing(tmp_path, frames_dir):
    out = tmp_path / "s.dmsh"
    p = run("encode", frames_dir, "-o", out, "--qp", "500", check=False)
    assert p.returncode == 1 and "qp" in p.stderr and "Traceback" not in p.stderr
    assert not out.exists() and list(tmp_path.glob("*.tmp")) == []


def test_corrupt_stream_fails_naming_the_frame(tmp_path, frames_dir):
    stream = tmp_path / "s.dmsh"
    run("encode", frames_dir, "-o", stream, "-q")
    data = bytearray(stream.read_bytes())
    data[-10] ^= 0x40
    stream.write_bytes(bytes(data))
    p = run("decode", stream, "-o", tmp_path / "out", check=False)
    assert p.returncode == 1
    assert "frame 2" in p.stderr and "byte offset" in p.stderr


def test_malformed_mesh_fails_naming_file_and_line(tmp_path):
    d = tmp_path / "bad"
    d.mkdir()
    (d / "a.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n")
    p = run("encode", d, "-o", tmp_path / "s.dmsh", check=False)
    assert p.returncode == 1 and "a.obj" in p.stderr and "4" in p.stderr


def test_synth_and_demo_run(tmp_path):
    run("synth", tmp_path / "syn", "--frames", "3", "--resolution", "24")
    assert len(list((tmp_path / "syn").glob("frame_*.obj"))) == 3
    demo = json.loads(run("demo", "--frames", "3", "--qps", "26", "34", "--workdir", tmp_path / "demo", "--json").stdout)
    rates = demo["rates"]
    assert rates[0]["d1_psnr"] > rates[1]["d1_psnr"] and rates[0]["bytes"] > rates[1]["bytes"]
    # The demo shows inter coding: its sequence moves little enough per frame to predict.
    assert all(r["types"][0] == "I" and "P" in r["types"] for r in rates), rates
    assert all(r["bytes"] < r["intra_bytes"] for r in rates)
    assert "bd_rate" in demo["bd_rate_vs_all_intra"]


@pytest.mark.parametrize("kind", ["fused-gears", "cloth"])
def test_synth_writes_one_surface_kinds(tmp_path, kind):
    run("synth", tmp_path / kind, "--kind", kind, "--frames", "2", "--resolution", "32")
    frames = [read_mesh(p) for p in sorted((tmp_path / kind).glob("frame_*.obj"))]
    assert len(frames) == 2 and len(frames[0].positions) != len(frames[1].positions)
    assert run("synth", tmp_path / "x", "--kind", "teapot", check=False).returncode == 1


def test_synth_takes_its_output_as_encode_does_or_positional_but_once(tmp_path):
    run("synth", "-o", tmp_path / "o", "--frames", "2", "--resolution", "16")
    assert len(list((tmp_path / "o").glob("frame_*.obj"))) == 2
    for args, words in [((), "no output directory"), ((tmp_path / "a", "-o", tmp_path / "b"), "two output directories")]:
        p = run("synth", *args, "--frames", "2", check=False)
        assert p.returncode == 1 and words in p.stderr, p.stderr
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_shared_sequence_quality_rises_as_qp_falls(tmp_path):
    folder = shared_sequence("basketball_player")
    psnr = []
    for qp in (34, 22):
        stream = tmp_path / f"q{qp}.dmsh"
        run("encode", folder, "-o", stream, "--count", "2", "--qp", qp, "-q")
        run("decode", stream, "-o", tmp_path / f"d{qp}", "-q")
        m = json.loads(run("metrics", folder / "basketball_player_fr0011.obj", tmp_path / f"d{qp}" / "frame_0000.obj",
                           "--peak", "18.75", "--json").stdout)
        psnr.append(m["d1_psnr"])
        raw = sum(p.stat().st_size for p in sorted(folder.iterdir())[:2])
        assert stream.stat().st_size * 50 < raw
    assert psnr[1] > psnr[0] + 2


def test_decode_hash_and_lod_options(tmp_path, frames_dir):
    stream = tmp_path / "s.dmsh"
    run("encode", frames_dir, "-o", stream, "-q", "--subdiv", "2")
    full = run("decode", stream, "--hash").stdout.splitlines()
    assert [line.split()[:3] for line in full] == [["frame", str(i), "sha256"] for i in range(3)]
    assert all(len(line.split()[3]) == 64 for line in full)
    assert run("decode", stream, "--hash", "--lod", "2").stdout.splitlines() == full  # 2 = all iterations
    coarse = run("decode", stream, "--hash", "--lod", "0").stdout.splitlines()
    assert coarse != full
    # --hash beside -o writes the files and prints the same lines; JSON carries them too.
    out = tmp_path / "out"
    assert run("decode", stream, "--hash", "-o", out, "-q").stdout.splitlines() == full
    assert len(list(out.glob("frame_*.obj"))) == 3
    doc = json.loads(run("decode", stream, "--hash", "--json", "--lod", "0").stdout)
    assert [f"frame {i} sha256 {h}" for i, h in enumerate(doc["sha256"])] == coarse
    lod0 = read_mesh(next(iter(sorted(out.glob("*.obj")))))
    run("decode", stream, "-o", tmp_path / "lod0", "--lod", "0", "-q")
    assert len(read_mesh(tmp_path / "lod0" / "frame_0000.obj").faces) * 16 == len(lod0.faces)


@pytest.mark.parametrize("args, message", [
    (["--lod", "3"], "level of detail 3 out of range (the stream has 2 subdivision iterations)"),
    (["--lod", "-1"], "expected a non-negative integer"),
    ([], "give an output directory (-o) or --hash"),
])
def test_bad_decode_options_fail_in_one_line(tmp_path, frames_dir, args, message):
    stream = tmp_path / "s.dmsh"
    run("encode", frames_dir, "-o", stream, "-q", "--subdiv", "2")
    extra = ["--hash"] if args and args[0] == "--lod" else []
    p = run("decode", stream, *extra, *args, check=False)
    assert p.returncode != 0 and message in p.stderr and "Traceback" not in p.stderr, p.stderr


# --------------------------------------------------------------------------- textured decode

TEXTURED = Path(__file__).resolve().parent / "vectors" / "textured_mixed.dmsh"


def test_textured_decode_writes_what_write_mesh_writes(tmp_path):
    """The writer thread changes when the files are written, not what they hold: OBJ and MTL
    byte for byte write_mesh's, the PNG the decoded image exactly, as Pillow reads it."""
    from PIL import Image

    from dynmesh import api

    out, ref = tmp_path / "out", tmp_path / "ref"
    run("decode", TEXTURED, "-o", out, "-q")
    ref.mkdir()
    frames = list(api.decode(TEXTURED.read_bytes()))
    for i, mesh in enumerate(frames):
        write_mesh(ref / f"frame_{i:04d}.obj", mesh)
    names = sorted(p.name for p in out.iterdir())
    assert names == sorted(p.name for p in ref.iterdir()) and len(names) == 3 * len(frames)
    for name in names:
        assert (out / name).read_bytes() == (ref / name).read_bytes(), name
    for i, mesh in enumerate(frames):
        with Image.open(out / f"frame_{i:04d}.png") as im:
            assert im.format == "PNG" and np.array_equal(np.asarray(im.convert("RGB")), mesh.image)


def test_a_failed_frame_write_fails_the_decode_and_leaves_nothing(tmp_path, monkeypatch, capsys):
    from dynmesh import cli

    real_write, written = cli._write_frame, []

    def write_or_fail(path, mesh):
        if path.name == "frame_0001.obj":
            raise OSError(28, "No space left on device", str(path))
        written.append(real_write(path, mesh))

    monkeypatch.setattr(cli, "_write_frame", write_or_fail)
    out = tmp_path / "out"
    assert cli.main(["decode", str(TEXTURED), "-o", str(out), "-q"]) == 1
    assert "No space left on device" in capsys.readouterr().err
    assert written and list(tmp_path.iterdir()) == []  # neither the output nor the staged directory


def test_a_decode_that_fails_while_frames_are_written_leaves_nothing(tmp_path, monkeypatch, capsys):
    """The writer is stopped and waited for before the staged directory is removed."""
    import time

    from dynmesh import cli

    real_write, real_refuse = cli._write_frame, cli.refuse_inputs
    checked = []

    def slow_write(path, mesh):
        time.sleep(0.2)
        return real_write(path, mesh)

    def refuse_the_second(output, inputs, *args):
        checked.append(output)
        if len(checked) == 3:  # the output directory, then each frame's file
            raise ValueError(f"refusing to write {output}")
        return real_refuse(output, inputs, *args)

    monkeypatch.setattr(cli, "_write_frame", slow_write)
    monkeypatch.setattr(cli, "refuse_inputs", refuse_the_second)
    assert cli.main(["decode", str(TEXTURED), "-o", str(tmp_path / "out"), "-q"]) == 1
    assert "refusing to write" in capsys.readouterr().err
    time.sleep(0.5)  # a writer left running would write its frames now
    assert list(tmp_path.iterdir()) == []
