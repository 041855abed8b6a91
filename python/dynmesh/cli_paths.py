"""Where the command line writes, checked before any work.

Every command that writes checks its outputs first, so that a mistake in a path costs a
second, not an encode: a file's folder must exist and take a new file, a file must not
be a directory nor one of the inputs, and a directory must be one (or be creatable: its
nearest existing ancestor takes new entries). ``dynmesh decode`` also refuses a directory
that already holds something unless ``--force``, and then replaces the frames of the
previous decode (``decoded_files``: only the names the decoder writes), so that old and
new frames never mix.

Standard library only: every command imports this.
"""

from __future__ import annotations

import os
import re
import shlex
from collections.abc import Iterable
from pathlib import Path

from .io import refuse_inputs
from .io.safety import same_file


class OutputError(ValueError):
    """An output path that the command cannot or must not write."""


#: The files ``dynmesh decode`` writes: frame_0000.obj (with .mtl and .png for a textured
#: stream), .ply or .glb, numbered as ``cli._frame_name`` numbers them (four digits at least).
DECODED_FILE = re.compile(r"frame_(?:\d{4}|[1-9]\d{4,})\.(?:obj|mtl|png|ply|glb)")


def check_output_file(path: str | os.PathLike, inputs: Iterable[str | os.PathLike] = (), *,
                      what: str = "output", example: str = "stream.dmsh") -> None:
    """Raises OutputError (InputClobberError for an input) unless a file can be written at
    ``path``: not one of ``inputs``, not a directory, in an existing folder that takes new
    files."""
    refuse_inputs(path, inputs, what)
    p = Path(path)
    if p.is_dir():
        raise OutputError(f"{what} {path} is a directory; give a file name, such as {p / example}")
    folder = p.parent
    if not folder.exists():
        raise OutputError(f"the folder {folder} of {what} {path} does not exist; create it first "
                          f"(mkdir -p {shlex.quote(str(folder))}) or choose another {what}")
    if not folder.is_dir():
        raise OutputError(f"{folder} is not a folder, so {what} {path} cannot be written there; choose another {what}")
    _check_writable(folder, what, path)


def check_output_directory(path: str | os.PathLike, inputs: Iterable[str | os.PathLike] = (), *,
                           what: str = "output directory") -> None:
    """Raises OutputError (InputClobberError for an input) unless a directory can be written
    at ``path``: an existing directory that takes new files, or a path whose nearest
    existing ancestor is such a directory (the command makes the missing folders)."""
    refuse_inputs(path, inputs, what)
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise OutputError(f"{what} {path} exists and is not a directory; give a directory, or remove the file")
    existing = next(a for a in [p, *p.absolute().parents] if a.exists() or a == a.parent)
    if not existing.is_dir():
        raise OutputError(f"{existing} is not a folder, so {what} {path} cannot be made; choose another {what}")
    _check_writable(existing, what, path)


def _check_writable(folder: Path, what: str, path) -> None:
    """Makes and removes an empty file in ``folder``: permissions, a read-only mount, a full
    inode table, whatever would make the real write fail, is found before the work."""
    # os.urandom is what secrets.token_hex draws from, without importing hmac and random.
    probe = folder / f".dynmesh-probe.{os.getpid()}.{os.urandom(4).hex()}.tmp"
    try:
        os.close(os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
    except OSError as e:
        raise OutputError(f"cannot write {what} {path}: the folder {folder} does not take new files "
                          f"({e.strerror}); choose another {what}") from None
    try:
        os.unlink(probe)
    except OSError:
        pass


def decoded_files(directory: str | os.PathLike) -> list[Path]:
    """The files in ``directory`` named as ``dynmesh decode`` names its frames (sorted)."""
    try:
        entries = list(os.scandir(directory))
    except (FileNotFoundError, NotADirectoryError):
        return []
    return sorted(Path(e.path) for e in entries
                  if DECODED_FILE.fullmatch(e.name) and (e.is_symlink() or e.is_file(follow_symlinks=False)))


def check_decode_directory(path: str | os.PathLike, stream: str | os.PathLike, force: bool) -> None:
    """``dynmesh decode -o path``: as ``check_output_directory``; a directory that holds
    anything is refused unless ``force``, and never when one of the frame files a forced
    decode replaces is the stream itself."""
    check_output_directory(path, [stream])
    if not Path(path).is_dir():
        return
    for f in decoded_files(path):
        if same_file(f, stream):
            raise OutputError(f"output directory {path} holds the input stream as {f.name}, a frame file that decoding "
                              f"replaces; refusing to overwrite it (rename the stream or choose another directory)")
    entries = sorted(os.listdir(path))
    if entries and not force:
        shown = ", ".join(entries[:3]) + (", ..." if len(entries) > 3 else "")
        count = "1 entry" if len(entries) == 1 else f"{len(entries)} entries"
        raise OutputError(f"output directory {path} is not empty ({count}: {shown}); choose a new "
                          f"or empty directory, or pass --force to replace the frames of a previous decode "
                          f"(its frame_NNNN.* files are removed, other files are kept)")


def remove_stale_frames(directory: str | os.PathLike, keep: Iterable[str]) -> list[Path]:
    """Removes the decoder's frame files in ``directory`` whose names are not in ``keep``
    (the frames just written); returns them."""
    keep = set(keep)
    stale = [f for f in decoded_files(directory) if f.name not in keep]
    for f in stale:
        try:
            f.unlink()
        except FileNotFoundError:
            pass
    return stale
