"""Reading and writing single meshes: Wavefront OBJ (+ MTL texture) and PLY; reading glTF
2.0 (.gltf, .glb) and Draco (.drc) as well.

``read_mesh`` parses OBJ and PLY (ASCII, binary little and big endian) into a
:class:`~dynmesh.mesh.Mesh`, and hands .gltf/.glb to ``gltf_read`` (through trimesh) and
.drc to ``draco`` (through DracoPy); ``write_mesh`` writes OBJ and PLY. Every problem with
the input is a :class:`MeshError` naming the file and, for text formats, the
1-based line number. Recoverable oddities (polygons that were triangulated, a
missing material library or texture) are reported as :class:`MeshWarning`.

The per-line and per-value work (parsing, formatting floats as their shortest
round-trip repr) is done by the Rust core (``dynmesh._core.read_obj``, ``read_ply``,
``format_rows``, ``format_obj_faces``, ``ply_body``; see bindings/src/meshio.rs).
This module reads the file, resolves material libraries and texture paths, checks
a mesh before writing it, and writes files atomically.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Iterable, Iterator
from pathlib import Path

import numpy as np

from .. import _core
from ..mesh import Mesh
from .errors import MeshError
from .image import decode_image, read_image

__all__ = ["MeshError", "MeshWarning", "read_mesh", "write_mesh", "read_image", "write_image"]


class MeshWarning(UserWarning):
    """Something in a mesh file was repaired or ignored while reading it."""


def read_mesh(path: str | os.PathLike) -> Mesh:
    """Read an OBJ, PLY, glTF (.gltf, .glb) or Draco (.drc) file, chosen by extension, into a
    triangle Mesh.

    Polygons are fan-triangulated, with one MeshWarning per file. OBJ texture
    coordinates keep their own per-corner index list (``uv_faces``); the texture of
    the used material (``map_Kd``) is stored in ``Mesh.texture``, resolved relative
    to the .mtl file (a missing .mtl or image is a MeshWarning; a missing image's path
    is still stored). PLY reads per-vertex u,v (or s,t / texture_u,texture_v) with
    ``uv_faces == faces``, or MeshLab's per-corner ``texcoord`` lists, and the texture
    from ``comment TextureFile``. Texture images may be PNG or JPEG (anything Pillow reads).
    glTF and Draco: see ``dynmesh.io.gltf_read`` and ``dynmesh.io.draco`` (vertices split at
    UV seams are welded; glTF's flipped V is turned into OBJ's; a glb's embedded texture is
    decoded into ``Mesh.image``). Raises MeshError naming the file (and line) on any error.
    """
    path = Path(path)
    reader = _READERS.get(path.suffix.lower())
    if reader is None:
        raise MeshError(path, f"unknown mesh format {path.suffix!r}: dynmesh reads .obj, .ply, .gltf, .glb "
                              "and .drc files; convert the frame to one of them")
    try:
        data = path.read_bytes()
    except OSError as e:
        raise MeshError(path, f"cannot read file: {e.strerror or e}") from e
    notes: list[str] = []
    mesh = reader(data, path, notes)
    for note in notes:
        warnings.warn(f"{path}: {note}", MeshWarning, stacklevel=2)
    return mesh


def write_mesh(path: str | os.PathLike, mesh: Mesh, *, ascii: bool = False) -> None:
    """Write ``mesh`` as OBJ or PLY (chosen by extension), atomically.

    OBJ positions and UVs round-trip float64 exactly (shortest repr); UVs are written
    with their own indices (``f a/b``), and a texture becomes ``<stem>.mtl`` beside the
    file referencing the texture's file name (the image is not copied). A mesh carrying
    texture pixels (``image``) gets them written as ``<stem>.png``, referenced instead. PLY is binary
    little endian unless ``ascii``. Each file is written to a temporary file in the same
    directory and renamed into place, so a failure never leaves a partial file.
    Raises MeshError for an unknown extension or an invalid mesh (non-finite values,
    indices out of range); file-system errors propagate as OSError.
    """
    path = Path(path)
    writer = _WRITERS.get(path.suffix.lower())
    if writer is None:
        raise MeshError(path, f"unknown mesh format {path.suffix!r} (expected .obj or .ply)")
    _check_writable(path, mesh)
    writer(path, mesh, ascii)


def write_image(path: str | os.PathLike, image: np.ndarray) -> None:
    """Writes an (H, W, 3) uint8 RGB image as PNG (lossless), atomically: encoded by the
    core (``_core.write_png``: adaptive row filters and fdeflate, with the GIL released, so
    a writer thread overlaps it with other work), into a temporary file beside ``path``,
    synced, then renamed into place."""
    image = np.ascontiguousarray(image, np.uint8)
    if image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"expected an (H, W, 3) uint8 image, got shape {image.shape}")
    _core.write_png(Path(path), image)


# --------------------------------------------------------------------------- reading


def _parsed(parse, data: bytes, path: Path):
    """``parse(data)``, its (message, line) errors raised as MeshError naming ``path``."""
    try:
        return parse(data)
    except _core.MeshFormatError as e:
        message, line = e.args
        raise MeshError(path, message, line) from None


def _is_file(path: Path) -> bool:
    """``path.is_file()``, False also for names no file can have (too long, a NUL byte)."""
    try:
        return path.is_file()
    except (OSError, ValueError):
        return False


def _note_missing_texture(texture: Path | None, notes: list[str]) -> None:
    if texture is not None and not _is_file(texture):
        notes.append(f"texture file {texture!s:.200} not found")


def _read_obj(data: bytes, path: Path, notes: list[str]) -> Mesh:
    (positions, faces, uvs, uv_faces), mtllibs, materials, parse_notes = _parsed(_core.read_obj, data, path)
    notes += parse_notes
    return Mesh(positions, faces, uvs, uv_faces, _obj_texture(path, mtllibs, materials, notes))


def _obj_texture(path: Path, mtllibs: list[str], materials: list[str], notes: list[str]) -> Path | None:
    """Texture (map_Kd) of the first used material that has one, relative to its .mtl."""
    textures: dict[str, Path] = {}
    for lib in mtllibs:
        # One mtllib line may list several libraries, or one name containing spaces.
        for name in [lib] if _is_file(path.parent / lib) else lib.split():
            for material, texture in _read_mtl(path.parent / name, notes).items():
                textures.setdefault(material, texture)
    # Without usemtl the file still names a library; its first textured material is meant.
    used = [textures[m] for m in materials if m in textures] if materials else list(textures.values())[:1]
    if not used:
        return None
    if len(set(used)) > 1:
        notes.append(f"materials use {len(set(used))} textures; only the first ({used[0]}) is kept")
    _note_missing_texture(used[0], notes)
    return used[0]


def _read_mtl(mtl: Path, notes: list[str]) -> dict[str, Path]:
    """material name -> texture path for every material with a map_Kd."""
    try:
        text = mtl.read_text("utf-8", "replace")
    except (OSError, ValueError):  # ValueError: a name with a NUL byte, which no file has
        notes.append(f"material library {mtl!s:.200} not found; texture ignored")
        return {}
    textures: dict[str, Path] = {}
    material = None
    for line in text.splitlines():
        parts = line.split("#", 1)[0].split(None, 1)
        if len(parts) < 2:
            continue
        if parts[0] == "newmtl":
            material = parts[1].strip()
        elif parts[0] == "map_Kd" and material is not None and material not in textures:
            textures[material] = mtl.parent / _map_file_name(parts[1])
    return textures


# map_Kd options with a fixed number of arguments; -o, -s and -t take 1 to 3 numbers.
_MAP_OPTIONS = {"-blendu": 1, "-blendv": 1, "-bm": 1, "-boost": 1, "-cc": 1, "-clamp": 1,
                "-imfchan": 1, "-texres": 1, "-type": 1, "-mm": 2}


def _map_file_name(arg: str) -> str:
    """The file name of a map_Kd statement, after its options."""
    tokens = arg.split()
    while len(tokens) > 1 and (tokens[0] in _MAP_OPTIONS or tokens[0] in ("-o", "-s", "-t")):
        option, tokens = tokens[0], tokens[1:]
        take = _MAP_OPTIONS.get(option, 3)
        while take and len(tokens) > 1 and (option in _MAP_OPTIONS or _is_number(tokens[0])):
            tokens, take = tokens[1:], take - 1
    return " ".join(tokens).replace("\\", "/")


def _is_number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def _read_ply(data: bytes, path: Path, notes: list[str]) -> Mesh:
    (positions, faces, uvs, uv_faces), comments, parse_notes = _parsed(_core.read_ply, data, path)
    notes += parse_notes
    return Mesh(positions, faces, uvs, uv_faces, _ply_texture(path, comments, notes))


def _ply_texture(path: Path, comments: list[str], notes: list[str]) -> Path | None:
    """MeshLab convention: ``comment TextureFile <name>``, relative to the PLY."""
    for comment in comments:
        parts = comment.split(None, 1)
        if len(parts) == 2 and parts[0] == "TextureFile":
            texture = path.parent / parts[1].strip()
            _note_missing_texture(texture, notes)
            return texture
    return None


# --------------------------------------------------------------------------- writing


def _check_writable(path: Path, mesh: Mesh) -> None:
    if not np.isfinite(mesh.positions).all():
        raise MeshError(path, "cannot write a mesh with non-finite positions")
    if len(mesh.faces) and (mesh.faces.min() < 0 or mesh.faces.max() >= len(mesh.positions)):
        raise MeshError(path, "cannot write: a face index is out of range")
    if mesh.uvs is not None:
        uv_faces = _uv_faces(path, mesh)
        if len(uv_faces) and (uv_faces.min() < 0 or uv_faces.max() >= len(mesh.uvs)):
            raise MeshError(path, "cannot write: a UV index is out of range")
        if not np.isfinite(mesh.uvs).all():
            raise MeshError(path, "cannot write a mesh with non-finite UVs")


def _uv_faces(path: Path, mesh: Mesh) -> np.ndarray:
    """UV index per corner; without uv_faces, UVs must be per vertex."""
    if mesh.uv_faces is not None:
        if mesh.uv_faces.shape != mesh.faces.shape:
            raise MeshError(path, "cannot write: uv_faces and faces differ in shape")
        return mesh.uv_faces
    if len(mesh.uvs) != len(mesh.positions):
        raise MeshError(path, "cannot write: uvs without uv_faces must have one UV per vertex")
    return mesh.faces


def _atomic_write(path: Path, chunks: Iterable[bytes]) -> None:
    """Write ``chunks`` to a temporary file beside ``path``, then rename it into place."""
    # os.urandom is what secrets.token_hex draws from, without importing hmac and random.
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{os.urandom(4).hex()}.tmp")
    try:
        # os.open with mode 0o666 lets the umask decide permissions, as a plain open() would.
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666)
    except OSError as e:
        raise _named(e, path) from None
    try:
        with os.fdopen(fd, "wb") as f:
            for chunk in chunks:
                f.write(chunk)
            f.flush()
            os.fsync(f.fileno())  # the rename must not become visible before the data
        os.replace(tmp, path)
    except BaseException as e:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(e, OSError):
            raise _named(e, path) from None
        raise


def _named(e: OSError, path: Path) -> OSError:
    """``e`` naming the user's ``path`` rather than the temporary file."""
    if e.errno is None:
        return OSError(f"{path}: {e}")
    return type(e)(e.errno, e.strerror, str(path))


def _write_obj(path: Path, mesh: Mesh, ascii: bool) -> None:
    material = None
    texture = mesh.texture
    if mesh.image is not None:
        texture = path.with_suffix(".png")
        write_image(texture, mesh.image)
    if texture is not None:
        material = path.with_suffix(".mtl")
        texture_name = Path(texture).name
        mtl = f"newmtl material0\nKa 1 1 1\nKd 1 1 1\nKs 0 0 0\nmap_Kd {texture_name}\n"
        _atomic_write(material, [mtl.encode("utf-8")])
    _atomic_write(path, _obj_chunks(path, mesh, material))


def _obj_chunks(path: Path, mesh: Mesh, material: Path | None) -> Iterator[bytes]:
    yield b"# written by dynmesh\n"
    if material is not None:
        yield f"mtllib {material.name}\n".encode("utf-8")
    yield _core.format_rows(mesh.positions, "v")
    if mesh.uvs is not None:
        yield _core.format_rows(mesh.uvs, "vt")
    if material is not None:
        yield b"usemtl material0\n"
    yield _obj_face_text(mesh.faces, None if mesh.uvs is None else _uv_faces(path, mesh))


def _obj_face_text(faces: np.ndarray, uv_faces: np.ndarray | None) -> bytes:
    return _core.format_obj_faces(faces, uv_faces)


def _write_ply(path: Path, mesh: Mesh, ascii: bool) -> None:
    if len(mesh.positions) > np.iinfo(np.int32).max:
        raise MeshError(path, "too many vertices for PLY int indices")
    per_vertex_uv, texcoord = _ply_uv_layout(path, mesh)
    header = _ply_header_text(mesh, ascii, per_vertex_uv, texcoord is not None)
    vertex = mesh.positions if not per_vertex_uv else np.hstack([mesh.positions, mesh.uvs])
    _atomic_write(path, [header.encode("utf-8"), _core.ply_body(vertex, mesh.faces, texcoord, ascii)])


def _ply_uv_layout(path: Path, mesh: Mesh) -> tuple[bool, np.ndarray | None]:
    """(UVs as vertex properties?, per-face texcoord (M, 6) otherwise).

    PLY has no separate UV index list: UVs indexed like the vertices become u,v
    properties, any other UVs are written per corner as MeshLab's ``texcoord``.
    """
    if mesh.uvs is None:
        return False, None
    uv_faces = _uv_faces(path, mesh)
    if len(mesh.uvs) == len(mesh.positions) and np.array_equal(uv_faces, mesh.faces):
        return True, None
    return False, mesh.uvs[uv_faces].reshape(-1, 6)


def _ply_header_text(mesh: Mesh, ascii: bool, per_vertex_uv: bool, texcoord: bool) -> str:
    lines = ["ply", f"format {'ascii' if ascii else 'binary_little_endian'} 1.0", "comment written by dynmesh"]
    if mesh.texture is not None:
        lines.append(f"comment TextureFile {Path(mesh.texture).name}")
    lines.append(f"element vertex {len(mesh.positions)}")
    lines += [f"property double {c}" for c in ("x", "y", "z") + (("u", "v") if per_vertex_uv else ())]
    lines += [f"element face {len(mesh.faces)}", "property list uchar int vertex_indices"]
    if texcoord:
        lines.append("property list uchar double texcoord")
    return "\n".join(lines + ["end_header", ""])


def _read_gltf(data: bytes, path: Path, notes: list[str]) -> Mesh:
    from .gltf_read import read_gltf  # imports trimesh: only for glTF files

    return read_gltf(data, path, notes)


def _read_draco(data: bytes, path: Path, notes: list[str]) -> Mesh:
    from .draco import read_draco

    return read_draco(data, path, notes)


_READERS = {".obj": _read_obj, ".ply": _read_ply, ".gltf": _read_gltf, ".glb": _read_gltf, ".drc": _read_draco}
_WRITERS = {".obj": _write_obj, ".ply": _write_ply}
