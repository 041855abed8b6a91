"""dynmesh play: the server's routes, and the page in headless Chromium (Debian's chromium,
driven by playwright-core from web/node_modules; .ci/run installs both): it decodes a stream
of the built-in synthetic sequence in the browser, and its screenshots show frames that
render (pixels off the background) and change while it plays."""

from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import subprocess
import sys
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from dynmesh import api
from dynmesh.player import make_server, web_root
from dynmesh.conformance import _textured
from dynmesh.mesh import Mesh
from dynmesh.synth import polygonize, synth_sequence

ROOT = Path(__file__).resolve().parents[1]
CHECK = ROOT / "web" / "test" / "helpers" / "browser-check.js"
CHROMIUM = os.environ.get("CHROMIUM", "/usr/bin/chromium")
BACKGROUND = np.array([32, 36, 43])  # the renderer's clear colour
VIEW_ROWS = 384  # of the 480-row screenshot; the panel is below


@pytest.fixture(scope="module")
def stream(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("play") / "synth.dmsh"
    path.write_bytes(api.encode(synth_sequence(frames=40, resolution=20)[:8], qp=30))
    return path


def textured_stream(tmp_path: Path, codec: str | None) -> Path:
    """Six frames of the synthetic sequence with spherical UVs and a texture, coded with
    ``codec`` (av1 or hevc; None: every texture option at its default)."""
    path = tmp_path / f"textured_{codec}.dmsh"
    frames = _textured(synth_sequence(frames=40, resolution=20)[:6])
    options = {} if codec is None else dict(texture_size=128, texture_codec=codec, texture_qp=30)
    path.write_bytes(api.encode(frames, qp=30, **options))
    return path


def test_the_server_serves_the_page_the_decoder_and_the_stream_and_nothing_else(stream):
    import threading

    server = make_server(stream.read_bytes(), stream.name)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    base = f"http://127.0.0.1:{server.server_address[1]}"
    try:
        get = lambda p: urllib.request.urlopen(base + p, timeout=10)  # noqa: E731
        assert get("/stream.dmsh").read() == stream.read_bytes()
        assert json.loads(get("/info.json").read())["fps"] == 30.0
        page = get("/").read().decode()  # redirected to the page
        assert "player.js" in page
        js = get("/src/decoder.js")
        assert js.headers["Content-Type"].startswith("text/javascript")
        assert b"export class RangeDecoder" in get("/src/ec.js").read()
        assert b"export const INTRA" in get("/src/stream/bitstream.js").read()  # modules in folders
        for bad in ("/src/../../pyproject.toml", "/player/", "/web/src/decoder.js", "/src/%2e%2e/package.json",
                    "/src/x/../../../pyproject.toml", "/src//decoder.js", "/src/./decoder.js", "/src"):
            with pytest.raises(urllib.error.HTTPError) as e:
                get(bad)
            assert e.value.code == 404, bad
    finally:
        server.shutdown()
        server.server_close()
    assert (web_root() / "player" / "index.html").is_file()


def test_play_reports_a_damaged_stream_in_one_line(tmp_path):
    # The magic and version of a valid stream (a conformance vector), so that the header's
    # CRC is what fails, whatever the current format version.
    good = (Path(__file__).parent / "vectors" / "far_reference.dmsh").read_bytes()
    bad = tmp_path / "bad.dmsh"
    bad.write_bytes(good[:5] + bytes(80))
    r = subprocess.run([sys.executable, "-m", "dynmesh", "play", str(bad), "--no-browser"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 1 and r.stderr.count("\n") == 1 and "CRC" in r.stderr, r.stderr


def view_pixels(path: Path) -> np.ndarray:
    return np.asarray(Image.open(path).convert("RGB"), np.int16)[:VIEW_ROWS]


def drawn_fraction(img: np.ndarray) -> float:
    return float(np.mean(np.abs(img - BACKGROUND).sum(axis=2) > 30))


def needs_browser() -> None:
    """Skips without a browser, except in CI (``CI`` set, as ``.ci/run`` runs), which installs
    one: there a missing browser is a failure, not a green run that tested nothing."""
    missing = pytest.fail if os.environ.get("CI") else pytest.skip
    if not Path(CHROMIUM).exists():
        missing(f"no Chromium at {CHROMIUM}: run web/tools/ensure-chromium.sh (.ci/run does)")
    if not (ROOT / "web" / "node_modules" / "playwright-core").is_dir():
        missing("playwright-core is not installed: run `npm ci` in web/")


@contextlib.contextmanager
def serving(command: list[str]):
    """Runs a server command that prints its http://127.0.0.1:PORT/ address first; yields the address."""
    server = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = server.stdout.readline()
        found = re.search(r"http://127\.0\.0\.1:\d+/", line)
        assert found, line + server.stderr.read()
        yield found.group(0)
    finally:
        server.terminate()
        server.wait(timeout=30)


def play_server(stream: Path) -> list[str]:
    return [sys.executable, "-m", "dynmesh", "play", str(stream), "--no-browser", "--port", "0"]


def static_server(directory: Path) -> list[str]:
    """Python's plain static file server (unbuffered, so that its address line arrives)."""
    return [sys.executable, "-u", "-m", "http.server", "0", "--bind", "127.0.0.1", "--directory", str(directory)]


def in_browser(stream: Path, out: Path, *extra: str, server: list[str] | None = None) -> dict:
    """Serves ``stream`` with ``dynmesh play --no-browser`` (or runs ``server``) and runs
    browser-check.js on the page."""
    needs_browser()
    with serving(server or play_server(stream)) as url:
        run = subprocess.run([shutil.which("node"), str(CHECK), url, str(out), *extra], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    result = json.loads(run.stdout.splitlines()[-1])
    assert "error" not in result, result
    return result


# A page driver: opens argv[2], waits until the expression argv[5] holds in the page, then runs
# argv[3], the body of an async function in the page, and prints its JSON.
PROBE = """
import { createRequire } from 'node:module';
const { chromium } = createRequire(process.argv[4])('playwright-core');
const [url, body, , wait] = process.argv.slice(2);
const browser = await chromium.launch({ executablePath: process.env.CHROMIUM || '/usr/bin/chromium', headless: true,
  args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist',
    '--disable-background-networking', '--disable-component-update', '--no-first-run'] });
const out = { console: [] };
try {
  const page = await browser.newPage({ viewport: { width: 640, height: 480 } });
  page.on('console', (m) => { if (m.type() === 'error') out.console.push(m.text()); });
  page.on('pageerror', (e) => out.console.push(String(e)));
  await page.goto(url);
  await page.waitForFunction(wait, null, { timeout: 120000 });
  out.result = await page.evaluate(new Function(`return (async () => { ${body} })()`));
} catch (e) {
  out.error = String(e);
} finally {
  await browser.close();
}
console.log(JSON.stringify(out));
"""


DECODED = ("window.dynmeshPlayer && (window.dynmeshPlayer.state.error || (window.dynmeshPlayer.state.frames > 0"
           " && window.dynmeshPlayer.state.decoded === window.dynmeshPlayer.state.frames))")


def probe(url: str, body: str, tmp_path: Path, wait: str = DECODED):
    """What the async function ``body`` returns in the page at ``url`` once ``wait`` holds
    there (by default: the player page has decoded the stream)."""
    script = tmp_path / "probe.mjs"
    script.write_text(PROBE)
    run = subprocess.run([shutil.which("node"), str(script), url, body, str(ROOT / "web" / "package.json"), wait],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    out = json.loads(run.stdout.splitlines()[-1])
    assert "error" not in out and out["console"] == [], out
    return out["result"]


def colourfulness(img: np.ndarray) -> float:
    """Mean channel spread of the drawn pixels: the untextured shading is grey (near 0)."""
    drawn = np.abs(img - BACKGROUND).sum(axis=2) > 30
    return float((img.max(axis=2) - img.min(axis=2))[drawn].mean())


def test_the_page_plays_the_stream_in_headless_chromium(stream, tmp_path):
    result = in_browser(stream, tmp_path)
    assert result["loaded"]["error"] is None and result["loaded"]["decoded"] == 8
    assert result["console"] == [], result["console"]
    assert result["paused"]["advanced"] >= 2 and not result["paused"]["playing"]
    assert result["pausedLater"]["frame"] == result["paused"]["frame"]  # paused means paused
    assert result["final"]["frame"] == 7
    # Level of detail 0: the base meshes, 4^subdiv times fewer faces than the full level.
    assert result["lod0"]["lod"] == 0 and result["lod0"]["error"] is None
    subdiv = len(api.info(stream.read_bytes())["header"]["schemes"])
    assert result["lod0"]["faces"] * 4 ** subdiv == result["final"]["faces"]
    assert drawn_fraction(view_pixels(tmp_path / "frame_lod0.png")) > 0.02
    first, played, last = (view_pixels(tmp_path / f"frame_{n}.png") for n in ("first", "played", "last"))
    for img in (first, played, last):
        assert drawn_fraction(img) > 0.02  # the mesh covers part of the view
    # The blobs move and merge: the frames differ where the mesh is (the played one when
    # playing stopped elsewhere than frame 0: 30 fps may have wrapped the 8 frames round).
    changed = lambda a, b: np.mean(np.abs(a - b).sum(axis=2) > 30) > 0.005  # noqa: E731
    assert changed(first, last)
    assert changed(first, played) == (result["pausedLater"]["shown"] != 0)
    # 30 fps: two frame changes take a few tenths of a second, not seconds.
    assert result["playSeconds"] < 5


@pytest.mark.parametrize("codec", ["av1", None], ids=["av1", "defaults"])
def test_an_av1_textured_stream_plays_with_its_texture(tmp_path, codec):
    result = in_browser(textured_stream(tmp_path, codec), tmp_path)
    assert result["final"]["textured"] and result["final"]["textureNote"] == "AV1 texture", result["final"]
    assert result["console"] == []
    for name in ("first", "last"):
        img = view_pixels(tmp_path / f"frame_{name}.png")
        assert drawn_fraction(img) > 0.02
        assert colourfulness(img) > 25, name


def test_an_hevc_textured_stream_says_so_and_plays_the_geometry(tmp_path):
    result = in_browser(textured_stream(tmp_path, "hevc"), tmp_path, "--wireframe")
    final = result["final"]
    assert not final["textured"] and "HEVC texture cannot be decoded by this browser" in final["textureNote"]
    assert "HEVC texture cannot be decoded" in final["status"]
    img = view_pixels(tmp_path / "frame_last.png")
    assert drawn_fraction(img) > 0.02 and final["frame"] == 5


def test_an_exported_page_plays_a_textured_stream_from_a_plain_static_server(tmp_path):
    stream = textured_stream(tmp_path, "av1")
    page = tmp_path / "page"
    play = [sys.executable, "-m", "dynmesh", "play", str(stream), "--export", str(page)]
    assert subprocess.run(play, capture_output=True, text=True, timeout=60).returncode == 0
    assert (page / "stream.dmsh").read_bytes() == stream.read_bytes()
    assert not [p for p in page.rglob("*") if p.is_symlink()]  # copies: the folder can be moved or uploaded
    result = in_browser(stream, tmp_path / "shots", server=static_server(page))  # the page's root, redirected
    assert result["loaded"]["decoded"] == 6 and result["console"] == []
    assert result["paused"]["advanced"] >= 2
    assert result["final"]["textured"] and result["final"]["textureNote"] == "AV1 texture", result["final"]
    img = view_pixels(tmp_path / "shots" / "frame_last.png")
    assert drawn_fraction(img) > 0.02 and colourfulness(img) > 25


def test_export_refuses_a_non_empty_directory_unless_forced(stream, tmp_path):
    page = tmp_path / "page"
    page.mkdir()
    (page / "mine.txt").write_text("keep")
    play = [sys.executable, "-m", "dynmesh", "play", str(stream), "--export", str(page)]
    r = subprocess.run(play, capture_output=True, text=True, timeout=60)
    assert r.returncode == 1 and r.stderr.count("\n") == 1 and "--force" in r.stderr, r.stderr
    assert (page / "mine.txt").read_text() == "keep"
    r = subprocess.run([*play, "--force"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert not (page / "mine.txt").exists() and (page / "player" / "index.html").is_file()
    assert "player/index.html" in (page / "index.html").read_text()
    assert json.loads((page / "info.json").read_text()) == {"name": stream.name, "bytes": stream.stat().st_size, "fps": 30.0}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["page"]  # no staging folder left beside it


def tall(meshes):
    """The frames stretched to four times their height: a standing figure's proportions."""
    return [Mesh(m.positions * [1.0, 4.0, 1.0], m.faces) for m in meshes]


def facing_minus_x(meshes):
    """Each frame's faces whose normals point to -x: an open relief that faces -x."""
    out = []
    for m in meshes:
        p = m.positions[m.faces]
        normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        out.append(Mesh(m.positions, m.faces[normal[:, 0] < 0]))
    return out


CAMERA = """
const p = window.dynmeshPlayer, r = p.renderer;
return { corners: p.boxCorners(), yaw: r.yaw, view: p.state.view };
"""


@pytest.mark.parametrize("shape", [tall, facing_minus_x], ids=["tall", "facing -x"])
def test_the_default_camera_frames_the_whole_sequence_from_its_front(tmp_path, shape):
    needs_browser()
    frames = shape(synth_sequence(frames=40, resolution=20)[::5][:8])  # frames far apart: the blobs travel
    stream = tmp_path / "s.dmsh"
    stream.write_bytes(api.encode(frames, qp=30))
    with serving(play_server(stream)) as url:
        camera = probe(url, CAMERA, tmp_path)
    corners = np.array(camera["corners"])
    assert np.all(np.abs(corners) < 1), corners  # the box of the sequence, whole, with a margin
    assert np.abs(corners[:, 1]).max() > 0.7 or np.abs(corners[:, 0]).max() > 0.7  # and not tiny
    # The box (around the grid's centre, as the page's positions) holds the first frame and
    # is as tall as the tallest frame.
    h = api.info(stream.read_bytes())["header"]
    centre = np.array(h["origin"]) + (2 ** h["bits"] - 1) / 2 * h["step"]
    lo, hi = (np.array(camera["view"][k]) + centre for k in ("lo", "hi"))
    used = [m.positions[m.faces].reshape(-1, 3) for m in frames]
    slack = 0.02 * np.ptp(used[0][:, 1])
    assert np.all(lo - slack <= used[0].min(axis=0)) and np.all(used[0].max(axis=0) <= hi + slack)
    assert hi[1] - lo[1] >= 0.9 * max(np.ptp(p[:, 1]) for p in used)
    # The camera looks from the side the surface faces: +z (glTF's front) for a closed surface
    # that is no standing figure (the blobs' round bottoms have no feet).
    direction = (np.sin(camera["yaw"]), np.cos(camera["yaw"]))
    expected = (-1.0, 0.0) if shape is facing_minus_x else (0.0, 1.0)
    assert np.dot(direction, expected) > 0.95, camera["yaw"]


def standing_figure(toes: float, turn: float = 0.0, resolution: int = 64) -> Mesh:
    """A closed figure standing on y = -0.9 (legs, hips wider than deep, a body, a head) whose
    feet point to z = ``toes`` (-1 or 1), toes 0.2 ahead of the legs and heels 0.06 behind;
    then turned by ``turn`` radians about y (z toward x)."""
    axis = np.linspace(-1, 1, resolution)
    x, y, z = np.meshgrid(axis, axis, axis, indexing="ij")

    def capsule(a, b, r):
        a, b = np.array(a, float), np.array(b, float)
        t = np.clip(((x - a[0]) * (b - a)[0] + (y - a[1]) * (b - a)[1] + (z - a[2]) * (b - a)[2]) / ((b - a) @ (b - a)), 0, 1)
        return np.sqrt((x - a[0] - t * (b - a)[0]) ** 2 + (y - a[1] - t * (b - a)[1]) ** 2 + (z - a[2] - t * (b - a)[2]) ** 2) - r

    def box(c, half):
        q = np.stack([np.abs(v - cv) - hv for v, cv, hv in zip((x, y, z), c, half)])
        return np.linalg.norm(np.maximum(q, 0), axis=0) + np.minimum(q.max(axis=0), 0)

    parts = [capsule((-0.25, 0.1, 0), (0.25, 0.1, 0), 0.12), capsule((0, 0.1, 0), (0, 0.5, 0), 0.15), box((0, 0.75, 0), (0.1, 0.12, 0.1))]
    for side in (-1, 1):
        parts += [capsule((0.12 * side, -0.8, 0), (0.12 * side, 0.1, 0), 0.06), box((0.12 * side, -0.86, 0.07 * toes), (0.06, 0.04, 0.13))]
    m = polygonize(-np.min(parts, axis=0), axis, iso=0.0)
    c, s = np.cos(turn), np.sin(turn)
    return Mesh(m.positions @ np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]]), m.faces)  # (x, z) -> (c x + s z, c z - s x)


@pytest.mark.parametrize("toes, turn", [(-1, 0.0), (1, 0.0), (-1, 0.7)], ids=["toes -z", "toes +z", "toes -z turned"])
def test_the_default_camera_looks_at_a_standing_figure_from_the_way_its_feet_point(tmp_path, toes, turn):
    # A closed surface's normals cancel; a standing person's feet tell the front (worker.js,
    # standingFront): the toes reach further ahead of the legs than the heels behind.
    needs_browser()
    figure = standing_figure(toes, turn)
    p = figure.positions[figure.faces]
    assert np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]).sum(axis=0)) < 1e-6 * len(p)  # closed
    stream = tmp_path / "figure.dmsh"
    stream.write_bytes(api.encode([figure, figure], qp=30))
    with serving(play_server(stream)) as url:
        camera = probe(url, CAMERA, tmp_path)
    direction = (np.sin(camera["yaw"]), np.cos(camera["yaw"]))  # (x, z) of the camera's side
    expected = (np.sin(turn) * toes, np.cos(turn) * toes)  # (0, toes) turned with the figure
    assert np.dot(direction, expected) > 0.98, (camera["yaw"], camera["view"]["front"])


EMBED = """<!doctype html>
<meta charset="utf-8"><link rel="icon" href="data:,">
<canvas id="view" style="width: 320px; height: 240px"></canvas>
<script type="module">
import { createPlayer } from './player/api.js';
window.embedded = createPlayer(document.getElementById('view'), { loop: false });
</script>
"""

SEEK = """
const p = window.embedded, events = [];
for (const name of ['frame', 'ended', 'error']) p.addEventListener(name, (e) => events.push([name, e.detail ? (e.detail.index ?? e.detail.message) : null]));
await p.load('stream.dmsh');
const shown = new Promise((resolve) => p.addEventListener('frame', (e) => e.detail.index === K && resolve(e.detail)));
p.seek(K);
const detail = await shown;
const atSeek = { ...p.state };
p.play();
await new Promise((resolve) => p.addEventListener('ended', resolve));
return { detail, atSeek, events, end: { ...p.state } };
"""


def test_the_module_api_loads_seeks_to_a_predicted_frame_with_its_texture_and_plays_to_the_end(tmp_path):
    needs_browser()
    frames = _textured(synth_sequence(frames=40, resolution=20)[:8])
    stream = tmp_path / "s.dmsh"
    stream.write_bytes(api.encode(frames, qp=30, intra_period=4, texture_size=128, texture_codec="av1", texture_qp=30))
    types = [f["type"] for f in api.info(stream.read_bytes())["frames"]]
    k = 6  # a predicted frame of the second texture group: decoded from intra frame 4
    assert types[4] == "I" and types[k] == "P", types
    page = tmp_path / "page"
    assert subprocess.run([sys.executable, "-m", "dynmesh", "play", str(stream), "--export", str(page)], timeout=60).returncode == 0
    (page / "embed.html").write_text(EMBED)
    with serving(static_server(page)) as url:
        out = probe(url + "embed.html", SEEK.replace("K", str(k)), tmp_path, wait="window.embedded")
    assert out["detail"] == {"index": k, "type": "P"}
    assert out["atSeek"]["shown"] == k and out["atSeek"]["textured"] and out["atSeek"]["error"] is None
    # Played from k to the last frame, each shown once, then `ended` (no loop).
    # (Frame 0, the one on screen at load, shows first if it was decoded before the seek came.)
    shown = [i for name, i in out["events"] if name == "frame"]
    assert shown[shown.index(k):] == list(range(k, 8)) and set(shown[:shown.index(k)]) <= {0}, shown
    assert out["events"][-1] == ["ended", None], out["events"]
    assert out["end"]["frame"] == 7 and not out["end"]["playing"]


class SlowServer:
    """A static server (threads, in this process) for an exported page whose ``stream.dmsh``
    arrives slowly: with its Content-Length, in ``pieces`` parts ``pause`` seconds apart, the
    last part held back until the page asks for ``/release`` (or ``hold`` seconds pass)."""

    def __init__(self, directory: Path, pieces: int = 10, pause: float = 0.15, hold: float = 30.0):
        import http.server
        import threading
        import time

        self.released = threading.Event()
        self.released_by_page = None  # whether the page asked for the tail, before `hold` ran out
        self.finished = False  # the stream's last byte was sent
        outer = self

        class Handler(http.server.SimpleHTTPRequestHandler):
            def __init__(self, *args, **kwargs):
                super().__init__(*args, directory=str(directory), **kwargs)

            def log_message(self, *args):
                pass

            def do_GET(self):
                if self.path == "/release":
                    outer.released.set()
                    self.send_response(204)
                    self.end_headers()
                elif self.path == "/stream.dmsh":
                    data = (directory / "stream.dmsh").read_bytes()
                    self.send_response(200)
                    self.send_header("Content-Type", "application/octet-stream")
                    self.send_header("Content-Length", str(len(data)))
                    self.end_headers()
                    cuts = [len(data) * k // pieces for k in range(pieces + 1)]
                    for k in range(pieces):
                        if k == pieces - 1:
                            outer.released_by_page = outer.released.wait(hold)
                        self.wfile.write(data[cuts[k]:cuts[k + 1]])
                        self.wfile.flush()
                        time.sleep(pause)
                    outer.finished = True
                else:
                    super().do_GET()

        self.server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.server.daemon_threads = True
        self.url = f"http://127.0.0.1:{self.server.server_address[1]}/"
        threading.Thread(target=self.server.serve_forever, daemon=True).start()

    def close(self):
        self.released.set()
        self.server.shutdown()
        self.server.server_close()


STREAMING = """
const p = window.dynmeshPlayer.player, shown = [];
const until = (f) => new Promise((resolve, reject) => {
  const end = performance.now() + 60000;
  const t = () => (f() ? resolve() : performance.now() > end ? reject(new Error(`timed out: ${f}`)) : setTimeout(t, 10));
  t();
});
p.addEventListener('frame', (e) => shown.push([e.detail.index, p.state.textured, p.texture.groups.length]));
await until(() => p.state.shown >= 0 || p.state.error);
const first = { ...p.state, groupsIn: p.texture ? p.texture.groups.length : 0, infosIn: p.infos.filter(Boolean).length };
p.play();
await until(() => p.state.error || p.state.shown > first.shown);  // plays on while the stream arrives
p.pause();
p.seek(LAST);  // not in yet: shown once it arrives
await new Promise((resolve) => setTimeout(resolve, 300));
const waiting = { ...p.state };
await fetch('/release');  // the server sends the rest only now
await until(() => p.state.error || p.state.shown === LAST);
await until(() => p.state.error || p.state.complete && p.state.decoded === p.state.frames);
const complete = { ...p.state };
const seeked = new Promise((resolve) => p.addEventListener('frame', (e) => e.detail.index === K && resolve(e.detail)));
p.seek(K);
const detail = await seeked;
return { first, waiting, complete, detail, atSeek: { ...p.state }, shown };
"""


def test_the_exported_page_plays_a_textured_stream_before_its_download_ends_and_seeks(tmp_path):
    """The page shows the first frame (with its texture) and plays on while the server still
    holds back the end of the stream, which it sends only when the page asks for it: a page
    that waited for the whole download would never ask (the server gives up waiting after
    `hold` seconds, and the test fails)."""
    needs_browser()
    frames = _textured(synth_sequence(frames=40, resolution=20)[:12])
    stream = tmp_path / "s.dmsh"
    stream.write_bytes(api.encode(frames, qp=30, intra_period=4, texture_size=128, texture_codec="av1", texture_qp=30))
    info = api.info(stream.read_bytes())
    types = [f["type"] for f in info["frames"]]
    k = 6  # a predicted frame of the second texture group
    assert types[::4] == ["I", "I", "I"] and types[k] == "P", types
    page = tmp_path / "page"
    play = [sys.executable, "-m", "dynmesh", "play", str(stream), "--export", str(page)]
    assert subprocess.run(play, capture_output=True, text=True, timeout=60).returncode == 0
    server = SlowServer(page)
    try:
        body = STREAMING.replace("LAST", "11").replace("K", str(k))
        out = probe(server.url + "player/index.html", body, tmp_path, wait="window.dynmeshPlayer")
    finally:
        server.close()
    first, complete = out["first"], out["complete"]
    assert server.released_by_page, "the page showed no frame until the whole stream had arrived"
    assert server.finished and first["error"] is None and complete["error"] is None
    # On screen with the first part of the stream: the header (frame count), some frames, and
    # the texture of the first group, not the whole stream.
    assert first["frames"] == 12 and not first["complete"] and first["arrived"] < 12
    assert first["infosIn"] == first["arrived"] and first["bytes"] < stream.stat().st_size
    assert first["textured"] and first["textureNote"] == "AV1 texture" and first["groupsIn"] < 3
    # A seek to a frame still on its way waits for it (and then shows it: see `shown`).
    waiting = out["waiting"]
    assert waiting["frame"] == 11 and waiting["shown"] != 11 and waiting["arrived"] < 12, waiting
    starts = [i for i, f in enumerate(info["frames"]) if f["texture_bytes"] > 0]  # of texture groups
    assert [11, True, len(starts)] in out["shown"] and len(out["shown"]) >= 4, out["shown"]
    # Every frame shown with its texture group in and the texture on.
    assert all(textured and groups >= sum(s <= i for s in starts) for i, textured, groups in out["shown"]), out["shown"]
    assert complete["complete"] and complete["arrived"] == complete["decoded"] == 12 and complete["bytes"] == stream.stat().st_size
    # Seeking once the stream is in: the predicted frame, with its texture.
    assert out["detail"] == {"index": k, "type": "P"}
    assert out["atSeek"]["shown"] == k and out["atSeek"]["textured"] and out["atSeek"]["error"] is None
