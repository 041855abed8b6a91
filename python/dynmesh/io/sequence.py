"""Turning a sequence specification into the ordered list of its frame files.

A specification is a directory (its mesh files: .obj, .ply, .gltf, .glb, .drc), a glob
pattern, or a printf pattern such as ``frames/frame_%04d.obj``. Names sort naturally:
``frame2`` comes before ``frame10``.
"""

from __future__ import annotations

import glob
import os
import re
from pathlib import Path

__all__ = ["SequenceError", "natural_key", "resolve_sequence"]

#: The files a directory's frames are: what ``meshio.read_mesh`` reads.
MESH_SUFFIXES = (".obj", ".ply", ".gltf", ".glb", ".drc")
_PRINTF = re.compile(r"%(0?)(\d*)d")
_GLOB_CHARS = re.compile(r"[*?\[]")


class SequenceError(ValueError):
    """A sequence specification that names no frames, or a frame that is missing."""


def natural_key(text: str) -> tuple:
    """Sort key comparing digit runs as numbers: "frame2" < "frame10"."""
    parts = re.split(r"(\d+)", str(text))
    return tuple(int(p) if i % 2 else p.casefold() for i, p in enumerate(parts)), str(text)


def resolve_sequence(spec: str | os.PathLike, start: int | None = None, count: int | None = None) -> list[Path]:
    """The frame files named by ``spec``, in order.

    - directory: its mesh files (``MESH_SUFFIXES``) in natural order;
    - glob pattern (``*``, ``?``, ``[``): the matching files in natural order;
    - printf pattern (one ``%d``/``%04d``): frames ``start``, ``start+1``, ...; with ``count``
      exactly that many (a missing one is an error), otherwise consecutive frames until the
      first missing one. ``start`` defaults to the smallest existing frame number;
    - an existing file: just that file.

    For directories and globs ``start`` is an index into the sorted list and ``count`` the
    number of files to take from there (all remaining ones by default).
    Raises SequenceError naming what was looked for when nothing or not enough is found.
    """
    if start is not None and start < 0:
        raise SequenceError(f"start must be >= 0, got {start}")
    if count is not None and count < 1:
        raise SequenceError(f"count must be >= 1, got {count}")
    text = os.fspath(spec)
    path = Path(text)
    if _printf_field(text) is not None:
        return _printf_frames(text, start, count)
    if path.is_dir():
        files = [p for p in path.iterdir() if p.suffix.lower() in MESH_SUFFIXES and p.is_file()]
        if not files:
            raise SequenceError(f"no .obj or .ply files (nor .gltf, .glb or .drc) in directory {path}: "
                                "give the folder that holds the frames, or a quoted glob or printf pattern")
        return _slice(sorted(files, key=natural_key), start, count, f"directory {path}")
    if _GLOB_CHARS.search(text):
        files = [Path(p) for p in glob.glob(text, recursive=True) if os.path.isfile(p)]
        if not files:
            raise SequenceError(f"no files match {text!r}")
        return _slice(sorted(files, key=natural_key), start, count, f"pattern {text!r}")
    if path.is_file():
        return _slice([path], start, count, f"file {path}")
    raise SequenceError(f"{text} is not a directory, glob or printf pattern, and no such file exists")


def _printf_field(text: str) -> re.Match | None:
    """The single %d field of a printf pattern (``%%`` is a literal percent sign)."""
    escaped = text.replace("%%", "\0\0")  # same length, so offsets stay valid
    fields = list(_PRINTF.finditer(escaped))
    if not fields:
        return None
    if len(fields) > 1 or "%" in _PRINTF.sub("", escaped):
        raise SequenceError(f"printf pattern {text!r} must have exactly one %d field and no other % field")
    return fields[0]


def _slice(files: list[Path], start: int | None, count: int | None, what: str) -> list[Path]:
    first = start or 0
    if first >= len(files):
        raise SequenceError(f"start index {first} is past the {len(files)} files of {what}")
    if count is not None and first + count > len(files):
        raise SequenceError(f"{what} has {len(files) - first} files from index {first}, {count} requested")
    return files[first : None if count is None else first + count]


def _printf_frames(pattern: str, start: int | None, count: int | None) -> list[Path]:
    if "%" in os.path.dirname(pattern.replace("%%", "")):
        raise SequenceError(f"printf pattern {pattern!r}: the frame number must be in the file name")
    if start is None:
        start = _smallest_frame(pattern)
    frame = lambda n: Path(pattern % n)  # noqa: E731 -- '%%' becomes '%' here as well
    if count is not None:
        missing = [frame(n) for n in range(start, start + count) if not frame(n).is_file()]
        if missing:
            raise SequenceError(f"missing frame {missing[0]} ({len(missing)} of {count} frames from {start} are missing)")
        return [frame(n) for n in range(start, start + count)]
    frames = []
    while frame(start + len(frames)).is_file():
        frames.append(frame(start + len(frames)))
    if not frames:
        raise SequenceError(f"missing frame {frame(start)}: first frame of {pattern!r} does not exist")
    return frames


def _smallest_frame(pattern: str) -> int:
    """The smallest number n for which ``pattern % n`` names an existing file."""
    directory, name = os.path.split(pattern)
    field = _printf_field(name)
    head, tail = name[: field.start()].replace("%%", "%"), name[field.end() :].replace("%%", "%")
    regex = re.compile(re.escape(head) + r"(-?\d+)" + re.escape(tail))
    numbers = []
    for entry in os.listdir(directory or ".") if os.path.isdir(directory or ".") else []:
        match = regex.fullmatch(entry)
        # Exact formatting check: "frame_%04d" must not pick up "frame_7".
        if match and name % int(match.group(1)) == entry:
            numbers.append(int(match.group(1)))
    if not numbers:
        raise SequenceError(f"no files match printf pattern {pattern!r}")
    return min(numbers)
