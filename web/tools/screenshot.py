"""Writes docs/player_textured.png: the player showing a textured (AV1) stream of the built-in
synthetic sequence, in headless Chromium (needs what the browser test needs: Debian's
chromium and `npm ci` in web/).

    python web/tools/screenshot.py [OUT.png]
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

from dynmesh import api
from dynmesh.conformance import _image, _textured
from dynmesh.player import make_server
from dynmesh.synth import synth_sequence

ROOT = Path(__file__).resolve().parents[2]


def main() -> int:
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "docs" / "player_textured.png"
    frames = _textured(synth_sequence(frames=40, resolution=28)[:4])
    image = _image(256)
    for m in frames:
        m.image = image
    data = api.encode(frames, qp=28, texture_size=512, texture_codec="av1", texture_qp=24)
    server = make_server(data, "synthetic_textured.dmsh")
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        with tempfile.TemporaryDirectory() as tmp:
            url = f"http://127.0.0.1:{server.server_address[1]}/"
            subprocess.run([shutil.which("node"), str(ROOT / "web" / "test" / "helpers" / "browser-check.js"), url, tmp],
                           check=True, stdout=subprocess.DEVNULL)
            shot = Path(tmp) / "frame_last.png"
            part = out.with_name(out.name + ".part")
            shutil.copyfile(shot, part)
            os.replace(part, out)
    finally:
        server.shutdown()
    print(f"wrote {out} ({out.stat().st_size} bytes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
