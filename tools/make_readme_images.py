"""Makes the README's picture, docs/img/player_textured.png: the web player showing a decoded
textured frame of the built-in synthetic sequence (metaballs that merge and split, with a
checker-and-colour texture coded as AV1), screenshotted in headless Chromium the way
tests/test_player.py drives the page (web/test/helpers/browser-check.js).

Needs what the browser test needs: the dev virtualenv, Debian's chromium
(web/tools/ensure-chromium.sh) and `npm ci` in web/. Deterministic input and encoder;
the pixels depend only on Chromium's software renderer.

    python tools/make_readme_images.py [OUT_DIR]      # default docs/img

The README's rate-distortion plot is not made here: it is one that `dynmesh eval --report`
writes (docs/results/tm14_intra/, see docs/results.md).
"""

from __future__ import annotations

import io
import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

import numpy as np
from PIL import Image

from dynmesh import api
from dynmesh.mesh import Mesh
from dynmesh.player import make_server
from dynmesh.synth import synth_sequence

ROOT = Path(__file__).resolve().parents[1]
MAX_BYTES = 200_000  # the README's pictures stay small
FIRST = 14  # frames 14-19 of 40: the two blobs close to each other


def texture(size: int = 512, cells: int = 12) -> np.ndarray:
    """A colour field with a bold checker and dark grid lines: a texture one sees at a glance."""
    y, x = np.mgrid[0:size, 0:size] / size
    rgb = np.stack([0.55 + 0.4 * np.sin(2 * np.pi * (x + 0.6 * y) + p) for p in (0.0, 2.1, 4.2)], -1)
    check = (np.floor(x * cells) + np.floor(y * cells)) % 2
    line = (np.minimum((x * cells) % 1, (y * cells) % 1) < 0.08)
    rgb = rgb * (0.6 + 0.4 * check)[..., None] * np.where(line, 0.25, 1.0)[..., None]
    return np.clip(rgb * 255, 0, 255).astype(np.uint8)


def stream() -> bytes:
    """Six frames of the synthetic sequence, textured, AV1: what the player plays textured."""
    meshes = synth_sequence(frames=40, resolution=40)[FIRST:FIRST + 6]
    lo = np.min([m.positions.min(0) for m in meshes], 0)
    side = float(np.max([m.positions.max(0) for m in meshes] - lo))
    image = texture()
    frames = []
    for m in meshes:
        # Planar UVs over the sequence's box (x, y): no seam, the same texel follows a point.
        uv = (m.positions[:, :2] - lo[:2]) / side
        frames.append(Mesh(m.positions, m.faces, uvs=uv, uv_faces=m.faces.copy(), image=image))
    return api.encode(frames, qp=28, texture_size=512, texture_codec="av1", texture_qp=24)


def screenshot(data: bytes, out: Path) -> dict:
    """Serves ``data`` with the player, screenshots its last frame into ``out``; the page's state."""
    node = shutil.which("node")
    if node is None:
        raise SystemExit("make_readme_images: Node.js is missing: install Node.js 18+ and run `npm ci` in web/")
    server = make_server(data, "synthetic_textured.dmsh")
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        with tempfile.TemporaryDirectory() as tmp:
            url = f"http://127.0.0.1:{server.server_address[1]}/"
            p = subprocess.run([node, str(ROOT / "web" / "test" / "helpers" / "browser-check.js"), url, tmp],
                               capture_output=True, text=True, cwd=ROOT / "web")
            if p.returncode != 0:
                raise SystemExit(f"make_readme_images: the browser run failed: {p.stderr.strip()[-2000:]}\n"
                                 "Is Chromium installed? Run web/tools/ensure-chromium.sh (and `npm ci` in web/).")
            result = json.loads(p.stdout.strip().splitlines()[-1])
            if result.get("error") or result.get("console"):
                raise SystemExit(f"make_readme_images: the page reported {result.get('error') or result['console']}")
            status = result["final"]["status"]
            if "AV1 texture" not in status:
                raise SystemExit(f"make_readme_images: the frame is not shown textured (status: {status!r})")
            # Palette PNG: the player's flat background and shading need few colours, and the
            # file stays well under MAX_BYTES.
            img = Image.open(Path(tmp) / "frame_last.png").convert("RGB")
            buf = io.BytesIO()
            img.quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE).save(
                buf, "PNG", optimize=True)
            if len(buf.getvalue()) > MAX_BYTES:
                raise SystemExit(f"make_readme_images: {out.name} would be {len(buf.getvalue())} bytes (> {MAX_BYTES})")
            part = out.with_name(out.name + ".part")
            part.write_bytes(buf.getvalue())
            os.replace(part, out)
            return result
    finally:
        server.shutdown()


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    out_dir = Path(argv[0]) if argv else ROOT / "docs" / "img"
    out_dir.mkdir(parents=True, exist_ok=True)
    data = stream()
    out = out_dir / "player_textured.png"
    result = screenshot(data, out)
    print(f"wrote {out} ({out.stat().st_size} bytes): {result['final']['status']}; stream {len(data)} bytes")
    return 0


if __name__ == "__main__":
    sys.exit(main())
