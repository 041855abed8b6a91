"""``dynmesh play``: a web player for a stream, served on 127.0.0.1.

The page (``web/player/``) fetches the stream and decodes it in the browser with the
JavaScript decoder (``web/src/``); this module only serves those plain files and the stream
bytes, so the player works from the installed package alone (the wheel carries the files as
``dynmesh/_web``; in a source checkout that folder holds symlinks to ``web/``). Routes: ``/`` redirects to the page,
``/stream.dmsh`` is the stream, ``/info.json`` its name and frame rate, ``/player/...`` and
``/src/...`` the files, at any depth; nothing else is served (no directory listings, no
paths outside). ``export`` writes the same files, the stream and ``info.json`` into a folder
that any static web server can host, laid out as the server's routes (the page fetches
``../stream.dmsh`` and ``../info.json`` relative to itself).
"""

from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile
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
    data = _read_stream(path)
    _check_fps(fps)
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


def _read_stream(path: str) -> bytes:
    try:
        data = Path(path).read_bytes()
    except OSError as e:
        raise ValueError(f"cannot read {path}: {e.strerror}") from None
    api.info(data)  # a damaged stream is reported here, in one line, before anything is written or served
    return data


def _check_fps(fps: float) -> None:
    if not fps > 0:
        raise ValueError(f"--fps must be positive, got {fps}")


def _page_files(root: Path):
    """(relative path, source) of every file the page needs: the player and the decoder's modules."""
    for source in sorted((root / "player").iterdir()):
        if source.is_file():
            yield Path("player") / source.name, source
    for source in sorted((root / "src").rglob("*.js")):
        yield source.relative_to(root), source


_REDIRECT = b'''<!doctype html>
<meta charset="utf-8"><meta http-equiv="refresh" content="0; url=player/index.html">
<link rel="icon" href="data:,">
<title>dynmesh player</title><a href="player/index.html">dynmesh player</a>
'''


def export(path: str, directory: str, force: bool = False, fps: float = DEFAULT_FPS) -> dict:
    """Writes a static page for the stream at ``path`` into ``directory``: ``index.html``
    (to the page), ``player/``, ``src/``, ``stream.dmsh`` and ``info.json``. A non-empty
    ``directory`` is refused unless ``force``. The files are written to a temporary folder
    beside it and renamed into place, so that a failed export leaves no half page."""
    data = _read_stream(path)
    _check_fps(fps)
    target = Path(directory)
    if target.exists() and not target.is_dir():
        raise ValueError(f"{directory} is a file: name a directory for the exported page")
    if target.is_dir() and any(target.iterdir()) and not force:
        raise ValueError(f"{directory} is not empty: name a new or empty directory, or add --force to replace it")
    parent = target.resolve().parent
    if not parent.is_dir():
        raise ValueError(f"the folder {parent} does not exist: make it first")
    root = web_root()
    staging = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=parent))
    try:
        for relative, source in _page_files(root):
            (staging / relative).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(source, staging / relative)
        (staging / "stream.dmsh").write_bytes(data)
        (staging / "info.json").write_text(json.dumps({"name": Path(path).name, "bytes": len(data), "fps": fps}))
        (staging / "index.html").write_bytes(_REDIRECT)
        os.chmod(staging, 0o755)  # mkdtemp's 0700 would hide the page from a server run as another user
        _replace(staging, target)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return {"directory": str(target), "files": sum(1 for f in target.rglob("*") if f.is_file()), "bytes": len(data)}


def _replace(staging: Path, target: Path) -> None:
    """Renames ``staging`` to ``target``, the previous ``target`` (empty, or replaced with
    --force) moved aside first and removed only once the new one is in place."""
    if not target.exists():
        staging.rename(target)
        return
    old = Path(tempfile.mkdtemp(prefix=f".{target.name}.old.", dir=staging.parent))
    old.rmdir()
    target.rename(old)
    try:
        staging.rename(target)
    except OSError:
        old.rename(target)
        raise
    shutil.rmtree(old)
