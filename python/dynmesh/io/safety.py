"""What the command line promises about files: it never writes over one of its own inputs,
and a command that fails leaves nothing behind.

``refuse_inputs`` compares an output path with every input file by identity (``samefile``:
the same file through another path, a symlink or a hard link), and by resolved path for
outputs that do not exist yet. ``StagedDirectory`` is how ``dynmesh decode`` writes a
directory of frames: into a hidden temporary directory beside the files, moved into place
only when the command succeeds, and removed when it fails.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path


class InputClobberError(ValueError):
    """An output that would replace one of the command's inputs."""


def same_file(a: str | os.PathLike, b: str | os.PathLike) -> bool:
    """Whether ``a`` and ``b`` name the same file (through any link), or, when either does
    not exist, the same resolved path."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.realpath(a) == os.path.realpath(b)


def refuse_inputs(output: str | os.PathLike, inputs: Iterable[str | os.PathLike], what: str = "output") -> None:
    """Raises InputClobberError when ``output`` is one of ``inputs``."""
    for path in inputs:
        if path is not None and same_file(output, path):
            raise InputClobberError(f"{what} {output} is the input file {path}; refusing to overwrite it")


def mesh_inputs(paths: Iterable[Path], meshes: Iterable) -> list[Path]:
    """The files a sequence was read from: the frames, and the texture images they name."""
    files = list(paths)
    files += [Path(m.texture) for m in meshes if getattr(m, "texture", None) is not None]
    return files


class StagedDirectory:
    """Files written into a temporary directory and moved into ``target`` on ``commit``.

    ``path(name)`` gives where to write ``name`` now. Used as a context manager, a failure
    (any exception) removes the temporary directory and the parent directories this made;
    ``target`` itself only comes into being on ``commit``."""

    def __init__(self, target: str | os.PathLike):
        self.target = Path(target)
        if self.target.exists() and not self.target.is_dir():
            raise NotADirectoryError(20, "exists and is not a directory", str(self.target))
        self._created = not self.target.exists()
        parent = self.target.parent
        # Missing parents are made, and removed again if the command fails.
        missing = [p for p in [parent, *parent.parents] if not p.exists()]
        self._made_parents = missing[::-1]
        # os.urandom is what secrets.token_hex draws from, without importing hmac and random.
        self.stage = parent / f".{self.target.name}.{os.getpid()}.{os.urandom(4).hex()}.tmp"
        try:
            for p in self._made_parents:
                p.mkdir()
            self.stage.mkdir()
        except OSError as e:
            self._remove_made_parents()
            raise OSError(e.errno, e.strerror, str(self.target)) from None

    def path(self, name: str) -> Path:
        return self.stage / name

    def final(self, name: str) -> Path:
        return self.target / name

    def commit(self) -> None:
        """Moves every staged file into ``target`` (created if needed)."""
        if self._created:
            os.replace(self.stage, self.target)
            return
        for entry in sorted(os.listdir(self.stage)):
            os.replace(self.stage / entry, self.target / entry)
        self.stage.rmdir()

    def discard(self) -> None:
        import shutil  # only a failed command needs it

        shutil.rmtree(self.stage, ignore_errors=True)
        self._remove_made_parents()

    def _remove_made_parents(self) -> None:
        for p in reversed(self._made_parents):
            try:
                p.rmdir()
            except OSError:
                break

    def __enter__(self) -> StagedDirectory:
        return self

    def __exit__(self, kind, value, tb) -> None:
        if kind is not None:
            self.discard()
