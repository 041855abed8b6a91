"""A user's first day with the command line (issue 47): outputs checked before any work,
decodes that never mix old and new frames, quiet closed pipes, `metrics --count` on both
sides, a message for an unquoted pattern, ranges in words, one exit status for errors, and
progress that a terminal and a log can both read."""

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import dynmesh
from dynmesh.io import write_mesh

from conftest import one_line_error, wobbly_sequence

ROOT = Path(__file__).resolve().parents[1]
TEXTURED = ROOT / "tests" / "vectors" / "textured_mixed.dmsh"


def run(*args, **kwargs):
    return subprocess.run([sys.executable, "-m", "dynmesh", *map(str, args)], capture_output=True, text=True, **kwargs)


@pytest.fixture(scope="module")
def frames(tmp_path_factory):
    d = tmp_path_factory.mktemp("frames")
    for i, m in enumerate(wobbly_sequence(3, 10, 14)):
        write_mesh(d / f"f{i}.obj", m)
    return d


@pytest.fixture(scope="module")
def stream(frames, tmp_path_factory):
    s = tmp_path_factory.mktemp("stream") / "s.dmsh"
    assert run("encode", frames, "-o", s, "-q").returncode == 0
    return s


@pytest.fixture
def broken_frames(tmp_path):
    """A sequence whose last frame cannot be read: a command that reads it before checking
    its output fails on the frame, not on the output."""
    d = tmp_path / "broken"
    d.mkdir()
    for i, m in enumerate(wobbly_sequence(2, 8, 10)):
        write_mesh(d / f"f{i}.obj", m)
    (d / "f2.obj").write_text("v 0 0 0\nf 1 2 3\n")
    return d


# --------------------------------------------------------------------------- outputs checked first


def test_encode_into_a_missing_folder_fails_before_reading_a_frame(tmp_path, broken_frames):
    out = tmp_path / "no" / "such" / "s.dmsh"
    p = run("encode", broken_frames, "-o", out)
    one_line_error(p, f"the folder {out.parent}", "does not exist", "mkdir -p")
    assert "f2.obj" not in p.stderr  # no frame was read
    assert not (tmp_path / "no").exists()


def test_encode_onto_a_directory_fails_before_reading_a_frame(tmp_path, broken_frames):
    (tmp_path / "adir").mkdir()
    p = run("encode", broken_frames, "-o", tmp_path / "adir")
    one_line_error(p, "is a directory", "give a file name")
    assert "f2.obj" not in p.stderr and list((tmp_path / "adir").iterdir()) == []


def test_an_output_folder_that_takes_no_new_files_is_refused_first(tmp_path, broken_frames, monkeypatch, capsys):
    # As root, permissions do not stop a write; a read-only folder is what the probe finds.
    from dynmesh import cli, cli_paths

    real_open = os.open

    def read_only(path, *args, **kwargs):
        if ".dynmesh-probe." in os.fspath(path):
            raise PermissionError(13, "Permission denied", os.fspath(path))
        return real_open(path, *args, **kwargs)

    monkeypatch.setattr(cli_paths.os, "open", read_only)
    assert cli.main(["encode", str(broken_frames), "-o", str(tmp_path / "s.dmsh"), "-q"]) == 1
    err = capsys.readouterr().err
    assert "does not take new files (Permission denied)" in err and "f2.obj" not in err
    assert cli.main(["decode", str(TEXTURED), "-o", str(tmp_path / "out"), "-q"]) == 1
    assert "does not take new files" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["broken"]


def test_a_bad_encoder_option_fails_before_reading_a_frame(tmp_path, broken_frames):
    p = run("encode", broken_frames, "-o", tmp_path / "s.dmsh", "--qp", "500")
    one_line_error(p, "qp 500", "from -24 to 63")
    p = run("encode", broken_frames, "-o", tmp_path / "s.dmsh", "--texture-qp", "99")
    one_line_error(p, "texture_qp", "from 0 to 51")
    assert not (tmp_path / "s.dmsh").exists()


@pytest.mark.parametrize("command", [["synth"], ["demo", "--workdir"]])
def test_a_directory_output_that_is_a_file_is_refused_at_once(tmp_path, command):
    target = tmp_path / "a_file"
    target.write_text("mine")
    p = run(*command, target, "--frames", "2")
    one_line_error(p, str(target), "is not a directory")
    assert target.read_text() == "mine"


# --------------------------------------------------------------------------- decode never mixes


def test_decode_refuses_a_directory_that_holds_files(tmp_path, stream):
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    p = run("decode", stream, "-o", out)
    one_line_error(p, "is not empty", "notes.txt", "--force")
    assert [f.name for f in out.iterdir()] == ["notes.txt"]
    # An empty directory, or a new one under new folders, is fine.
    (tmp_path / "empty").mkdir()
    assert run("decode", stream, "-o", tmp_path / "empty", "-q").returncode == 0
    assert run("decode", stream, "-o", tmp_path / "new" / "deeper", "-q").returncode == 0
    assert len(list((tmp_path / "new" / "deeper").glob("frame_*.obj"))) == 3


def test_decode_force_replaces_every_frame_of_a_previous_decode(tmp_path, frames, stream):
    out = tmp_path / "out"
    assert run("decode", TEXTURED, "-o", out, "-q").returncode == 0  # frame_000N.obj/.mtl/.png
    assert run("decode", stream, "-o", out, "--format", "ply", "-q").returncode == 1  # refused: not empty
    # Stale frames a longer, older decode left, in every format, and files that are not the
    # decoder's: only the former go.
    for name in ("frame_0007.obj", "frame_0007.mtl", "frame_0007.png", "frame_0009.glb", "frame_12345.ply"):
        (out / name).write_text("old")
    kept = ["frame_7.obj", "frame_0001.obj.bak", "notes.txt", "my_frame_0000.obj"]
    for name in kept:
        (out / name).write_text("mine")
    (out / "frame_0003.obj").mkdir()  # a folder, whatever its name, is not a frame file
    assert run("decode", stream, "-o", out, "--format", "ply", "--force", "-q").returncode == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == sorted(["frame_0000.ply", "frame_0001.ply", "frame_0002.ply", "frame_0003.obj", *kept]), names
    for name in kept:
        assert (out / name).read_text() == "mine"


def test_a_forced_decode_that_fails_leaves_the_previous_decode(tmp_path, stream):
    out = tmp_path / "out"
    assert run("decode", stream, "-o", out, "-q").returncode == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    data = bytearray(stream.read_bytes())
    data[-10] ^= 0x40
    bad = tmp_path / "bad.dmsh"
    bad.write_bytes(bytes(data))
    one_line_error(run("decode", bad, "-o", out, "--force"), "frame 2")
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_a_forced_decode_never_removes_its_own_stream(tmp_path, stream):
    out = tmp_path / "out"
    out.mkdir()
    (out / "frame_0005.obj").write_bytes(stream.read_bytes())
    one_line_error(run("decode", out / "frame_0005.obj", "-o", out, "--force"), "refusing")
    assert (out / "frame_0005.obj").read_bytes() == stream.read_bytes()
    # A stream in the output directory under another name stays beside the frames.
    (out / "frame_0005.obj").rename(out / "s.dmsh")
    assert run("decode", out / "s.dmsh", "-o", out, "--force", "-q").returncode == 0
    assert sorted(p.name for p in out.iterdir()) == ["frame_0000.obj", "frame_0001.obj", "frame_0002.obj", "s.dmsh"]


# --------------------------------------------------------------------------- closed pipes


@pytest.mark.parametrize("args", [["decode", "{stream}", "--hash"], ["info", "{stream}"],
                                  ["info", "{stream}", "--json"]])
def test_a_closed_pipe_ends_the_command_quietly(stream, args):
    # The reader is gone before the command writes (as `| head -1` is, soon after its line).
    read, write = os.pipe()
    os.close(read)
    try:
        p = subprocess.run([sys.executable, "-m", "dynmesh", *[a.format(stream=stream) for a in args]],
                           stdout=write, stderr=subprocess.PIPE, text=True, timeout=60)
    finally:
        os.close(write)
    assert p.stderr == "" and p.returncode == 141, (p.returncode, p.stderr)


def test_head_of_a_hash_listing(stream):
    p = subprocess.run(f"{sys.executable} -m dynmesh decode {stream} --hash | head -1", shell=True,
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 0 and p.stdout.startswith("frame 0 sha256 ") and p.stderr == "", p.stderr


# --------------------------------------------------------------------------- metrics --count


def test_metrics_count_applies_to_both_sides(tmp_path, frames, stream):
    out = tmp_path / "out"
    assert run("decode", stream, "-o", out, "-q").returncode == 0
    m = json.loads(run("metrics", frames, out, "--count", "2", "--json", "-q").stdout)
    assert len(m["frames"]) == 2 and m["d1_psnr"] > 40
    m1 = json.loads(run("metrics", frames, out, "--start", "1", "--count", "1", "--json", "-q").stdout)
    assert len(m1["frames"]) == 1
    # Sides of different lengths fail before a mesh is read, saying what to give.
    (out / "frame_0002.obj").unlink()
    one_line_error(run("metrics", frames, out), "3 reference frames but 2 decoded frames", "--count 2")


def test_metrics_per_frame_figures_are_the_apis(frames):
    """The command measures frame by frame (for its progress) as api.metrics does at once."""
    from dynmesh import api, cli
    from dynmesh.io import read_mesh

    refs = [read_mesh(p) for p in sorted(frames.iterdir())]
    decs = list(reversed(refs))
    assert cli._metrics(refs, decs, None, 64, lambda i, f: None) == api.metrics(refs, decs, grid_size=64)
    textured = list(api.decode(TEXTURED.read_bytes()))
    coarse = list(api.decode(TEXTURED.read_bytes(), lod=0))
    seen = []
    got = cli._metrics(textured, coarse, 3.0, 64, lambda i, f: seen.append(i))
    assert got == api.metrics(textured, coarse, peak=3.0, grid_size=64) and "y_psnr" in got
    assert seen == list(range(len(textured)))


# --------------------------------------------------------------------------- an unquoted pattern


def test_an_unquoted_pattern_gets_a_message_that_says_to_quote_it(tmp_path, frames):
    files = sorted(str(p) for p in frames.glob("*.obj"))  # what the shell makes of frames/*.obj
    p = run("encode", *files, "-o", tmp_path / "s.dmsh")
    one_line_error(p, "3 paths were given where one input was expected", "shell expanded",
                   f"'{frames}/*.obj'", f"({frames}/)")
    assert not (tmp_path / "s.dmsh").exists()
    p = run("metrics", *files, frames)
    one_line_error(p, "4 paths were given where two (reference and decoded) were expected", f"'{frames}/*.obj'")
    # Other stray arguments are named as such.
    one_line_error(run("encode", frames, "-o", tmp_path / "s.dmsh", "--bogus"), "unrecognized arguments: --bogus")


# --------------------------------------------------------------------------- ranges in words


def test_messages_say_ranges_in_words(tmp_path, frames):
    for args, words in ((["--references", "9"], "from 1 to 8"), (["--bits", "30"], "from 8 to 20"),
                        (["--bits", "10", "--base-bits", "12"], "from 8 to 10")):
        p = run("encode", frames, "-o", tmp_path / "s.dmsh", *args)
        one_line_error(p, words)
        assert ".." not in p.stderr
    p = run("metrics", frames, frames, "--grid-size", "1")
    one_line_error(p, "grid size must be a whole number from 2 to 16384")


def test_no_rust_message_shows_range_syntax():
    """A string literal with `..=`, or a range constant printed with {:?}, reads as code."""
    literal = re.compile(r'"(?:[^"\\]|\\.)*\.\.=(?:[^"\\]|\\.)*"')
    debug_range = re.compile(r'\{:\?\}.*_RANGE\b')
    found = []
    for folder in ("core/src", "meshio/src", "bindings/src"):
        for path in sorted((ROOT / folder).rglob("*.rs")):
            for n, line in enumerate(path.read_text().splitlines(), 1):
                if literal.search(line) or debug_range.search(line):
                    found.append(f"{path.relative_to(ROOT)}:{n}: {line.strip()}")
    assert found == []


def test_the_grid_size_limit_is_the_apis():
    from dynmesh import api, cli_args

    assert cli_args.MAX_GRID_SIZE == api.MAX_GRID_SIZE


# --------------------------------------------------------------------------- exit status


def test_bad_options_exit_with_the_status_readme_and_help_state(tmp_path, frames):
    from dynmesh import cli_args

    for args, words in ((["encode", frames], "required: -o/--output"),
                        (["encode", frames, "-o", tmp_path / "s.dmsh", "--qp", "abc"], "invalid int value"),
                        (["decode", "s.dmsh", "--format", "stl"], "invalid choice"),
                        (["nonsense"], "invalid choice")):
        p = run(*args)
        one_line_error(p, words, "--help)")
    assert run().returncode == 1
    readme = " ".join((ROOT / "README.md").read_text().split())
    stated = re.search(r"Exit status: (.*?)`--help` says the same\.", readme)
    assert stated, "README.md has an 'Exit status:' paragraph"
    for status, what in ((0, "when the command did its work"), (cli_args.EXIT_ERROR, "for any error"),
                         (cli_args.EXIT_INTERRUPTED, "when interrupted"),
                         (cli_args.EXIT_PIPE_CLOSED, "when the reader of the standard output went away")):
        assert re.search(rf"(^|; ){status} ([^;]* )?{what}", stated.group(1)), (status, what)
    for command in ([], ["encode"], ["decode"], ["metrics"], ["eval"]):
        helped = " ".join(run(*command, "--help").stdout.split())
        assert " ".join(cli_args.EXIT_STATUS_HELP.split()) in helped, command
    for status in (1, 130, 141):
        assert f"{status} " in cli_args.EXIT_STATUS_HELP


# --------------------------------------------------------------------------- progress


LINE = re.compile(r"dynmesh encode: encoding (\d+)/3: frame (\d+): ([IP]), (\d+) bytes, [\d.]+ s(, about .* left)?$")


def test_progress_in_a_log_is_one_line_per_frame(tmp_path, frames):
    p = run("encode", frames, "-o", tmp_path / "s.dmsh", "--json")
    assert p.returncode == 0 and "\r" not in p.stderr
    lines = p.stderr.splitlines()
    assert len(lines) == 3, p.stderr
    matches = [LINE.match(line) for line in lines]
    assert all(matches), lines
    coded = json.loads(p.stdout)["frames"]
    assert [(int(m[1]), int(m[2]), m[3], int(m[4])) for m in matches] == \
        [(i + 1, i, f["type"], f["bytes"]) for i, f in enumerate(coded)]
    # decode and metrics: one line per frame as well; a textured stream's frames are named
    out = tmp_path / "out"
    p = run("decode", TEXTURED, "-o", out)
    assert p.returncode == 0 and "\r" not in p.stderr
    info = dynmesh.info(TEXTURED.read_bytes())["frames"]
    assert [re.sub(r", about .* left$", "", line) for line in p.stderr.splitlines()] == \
        [f"dynmesh decode: decoding {i + 1}/2: frame {i}: {f['type']}, {f['bytes']} bytes" for i, f in enumerate(info)]
    p = run("decode", tmp_path / "s.dmsh", "-o", tmp_path / "out2")  # decoded by the core, frames counted
    assert [re.sub(r", about .* left$", "", line) for line in p.stderr.splitlines()] == \
        [f"dynmesh decode: decoding {i}/3" for i in (1, 2, 3)], p.stderr
    p = run("metrics", frames, frames, "--grid-size", "64")
    assert p.returncode == 0
    assert [re.sub(r", about .* left$", "", line) for line in p.stderr.splitlines()] == \
        [f"dynmesh metrics: measuring {i + 1}/3: frame {i}: D1 inf dB, D2 inf dB" for i in range(3)]


def test_quiet_means_nothing_on_stderr(tmp_path, frames):
    assert run("encode", frames, "-o", tmp_path / "s.dmsh", "-q").stderr == ""
    assert run("decode", tmp_path / "s.dmsh", "-o", tmp_path / "out", "-q").stderr == ""
    assert run("metrics", frames, tmp_path / "out", "-q", "--grid-size", "64").stderr == ""


def test_eval_reports_one_line_per_run(tmp_path, frames):
    pytest.importorskip("DracoPy")
    pytest.importorskip("matplotlib")
    config = tmp_path / "exp.toml"
    config.write_text(f'anchor = "dm"\ngrid_size = 64\n[[sequences]]\nname = "w"\npath = "{frames}"\ncount = 2\n'
                      'peak = 2.5\n[[variants]]\nname = "dm"\ncodec = "dynmesh"\n'
                      '[variants.rates]\nR1 = { qp = 40 }\nR2 = { qp = 30 }\n')
    blocker = tmp_path / "results"
    blocker.write_text("a file")
    one_line_error(run("eval", config, "--out", blocker), "results directory", "is not a directory")
    p = run("eval", config, "--out", tmp_path / "res")
    assert p.returncode == 0, p.stderr
    lines = [re.sub(r", about .* left$", "", line) for line in p.stderr.splitlines()]
    assert len(lines) == 2 and all(re.fullmatch(r"dynmesh eval: runs [12]/2: w/dm/R[12]: \d+ bytes, D1 [\d.]+ dB "
                                                r"\(measured\)", line) for line in lines), p.stderr
    p = run("eval", config, "--out", tmp_path / "res")
    assert p.stderr.count("(saved result reused)") == 2


def test_progress_on_a_terminal_is_a_bar_naming_the_frame(tmp_path, frames):
    pty, termios = pytest.importorskip("pty"), pytest.importorskip("termios")
    main, side = pty.openpty()
    termios.tcsetwinsize(side, (24, 160))
    proc = subprocess.Popen([sys.executable, "-m", "dynmesh", "encode", str(frames), "-o", str(tmp_path / "s.dmsh")],
                            stdout=subprocess.DEVNULL, stderr=side)
    os.close(side)
    shown = b""
    while True:
        try:
            chunk = os.read(main, 65536)
        except OSError:  # the terminal's other side is closed
            break
        if not chunk:
            break
        shown += chunk
    os.close(main)
    assert proc.wait(timeout=60) == 0
    text = shown.decode("utf-8", "replace")
    assert "\r" in text and "encoding:" in text and "3/3" in text, text
    assert re.search(r"frame 2: [IP], \d+ bytes", text), text
    assert re.search(r"<\d\d:\d\d", text), text  # tqdm's time left
    assert "dynmesh encode: encoding" not in text  # no log lines on a terminal
