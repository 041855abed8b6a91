"""``dynmesh play``: a web player for a stream, served on 127.0.0.1.

The page (``web/player/``) fetches the stream and decodes it in the browser with the
JavaScript decoder (``web/src/``); this module only serves those plain files and the stream
bytes, so the player works from the installed package alone (the wheel carries the files as
``dynmesh/_web``; in a source checkout that folder holds symlinks to ``web/``). Routes: ``/`` redirects to the page,
``/stream.dmsh`` is the stream, ``/info.json`` its name and frame rate, ``/player/...`` and
``/src/...`` the files, at any depth; nothing else is served (no directory listings, no
paths outside).
"""

from __future__ import annotations

import json
import sys
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

from . import api

#: The format carries no frame rate; the player plays at this one unless told otherwise
#: (the rate at which the command line reports bit rates).
DEFAULT_FPS = 30.0
_TYPES = {".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8",
          ".css": "text/css; charset=utf-8", ".png": "image/png", ".svg": "image/svg+xml"}


def web_root() -> Path:
    """The directory holding ``src/`` and ``player/``: ``dynmesh/_web`` (in the wheel, copies;
    in a checkout, symlinks to the repository's ``web/``), else the repository's ``web/``."""
    here = Path(__file__).parent
    for root in (here / "_web", here.parents[1] / "web"):
        if (root / "src" / "decoder.js").is_file() and (root / "player" / "index.html").is_file():
            return root
    raise FileNotFoundError("the web player's files are missing from this installation (web/src, web/player)")


def make_server(stream: bytes, name: str, port: int = 0, fps: float = DEFAULT_FPS) -> ThreadingHTTPServer:
    """A server for ``stream`` bound to 127.0.0.1:``port`` (0: any free port), not yet running."""
    root = web_root()
    info = json.dumps({"name": name, "bytes": len(stream), "fps": fps}).encode()

    class Handler(BaseHTTPRequestHandler):
        def do_GET(self):  # noqa: N802 (the http.server interface)
            path = self.path.split("?", 1)[0]
            if path == "/":
                self.send_response(302)
                self.send_header("Location", "/player/index.html")
                self.end_headers()
            elif path == "/stream.dmsh":
                self._send(stream, "application/octet-stream")
            elif path == "/info.json":
                self._send(info, "application/json")
            elif path == "/favicon.ico":
                self.send_response(204)
                self.end_headers()
            else:
                self._file(path)

        def _file(self, path: str) -> None:
            # A file at any depth under src/ or player/ (the decoder's modules sit in folders),
            # named without empty, "." or ".." steps, that resolves to inside that folder.
            parts = path.strip("/").split("/")
            target = None
            if len(parts) >= 2 and parts[0] in ("src", "player") and not {"", ".", ".."} & set(parts):
                target = (root / "/".join(parts)).resolve()
            if target is None or not target.is_relative_to((root / parts[0]).resolve()) or not target.is_file():
                self.send_error(404)
                return
            self._send(target.read_bytes(), _TYPES.get(target.suffix, "application/octet-stream"))

        def _send(self, body: bytes, kind: str) -> None:
            self.send_response(200)
            self.send_header("Content-Type", kind)
            self.send_header("Content-Length", str(len(body)))
            self.send_header("Cache-Control", "no-store")
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args):  # quiet: the command prints its address once
            pass

    return ThreadingHTTPServer(("127.0.0.1", port), Handler)


def serve(path: str, port: int = 8765, open_browser: bool = True, quiet: bool = False, fps: float = DEFAULT_FPS) -> dict:
    """Serves the player for the stream at ``path`` until interrupted."""
    try:
        data = Path(path).read_bytes()
    except OSError as e:
        raise ValueError(f"cannot read {path}: {e.strerror}") from None
    api.info(data)  # a damaged stream is reported here, in one line, before anything is served
    if not fps > 0:
        raise ValueError(f"--fps must be positive, got {fps}")
    try:
        server = make_server(data, Path(path).name, port, fps)
    except OSError as e:
        raise ValueError(f"cannot listen on 127.0.0.1:{port}: {e.strerror}") from None
    url = f"http://127.0.0.1:{server.server_address[1]}/"
    if not quiet:
        print(f"playing {path} at {url} (Ctrl-C to stop)", flush=True)
    else:
        print(url, flush=True)
    if open_browser:
        import webbrowser

        threading.Timer(0.3, webbrowser.open, [url]).start()
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        print("stopped", file=sys.stderr)
    finally:
        server.server_close()
    return {"url": url}
