"""Reading and writing single meshes: Wavefront OBJ (+ MTL texture) and PLY.

``read_mesh`` parses OBJ and PLY (ASCII, binary little and big endian) into a
:class:`~dynmesh.mesh.Mesh`; ``write_mesh`` writes them back. Every problem with
the input is a :class:`MeshError` naming the file and, for text formats, the
1-based line number. Recoverable oddities (polygons that were triangulated, a
missing material library or texture) are reported as :class:`MeshWarning`.

Parsing works on the whole file at once with numpy: a byte-level table of lines
and tokens classifies lines by their first token, and each kind of line is
converted in bulk. Anything the bulk path does not handle (inline comments,
line continuations, mixed face-corner forms, bad numbers) falls back to a plain
line-by-line parser, which is the reference behaviour and locates errors.
"""

from __future__ import annotations

import os
import secrets
import struct
import warnings
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .mesh import Mesh

__all__ = ["MeshError", "MeshWarning", "read_mesh", "write_mesh", "read_image", "write_image"]


class MeshError(ValueError):
    """A mesh file that cannot be read or a mesh that cannot be written.

    ``path`` is the file, ``line`` the 1-based line number or None where no line
    applies (binary data, missing file).
    """

    def __init__(self, path: str | os.PathLike, message: str, line: int | None = None):
        self.path = Path(path)
        self.line = line
        self.reason = message
        where = f"{path}: line {line}" if line is not None else f"{path}"
        super().__init__(f"{where}: {message}")

    def __reduce__(self):
        # The default would call MeshError(str(self)); keep it picklable across processes.
        return type(self), (self.path, self.reason, self.line)


class MeshWarning(UserWarning):
    """Something in a mesh file was repaired or ignored while reading it."""


def read_mesh(path: str | os.PathLike) -> Mesh:
    """Read an OBJ or PLY file (chosen by extension) into a triangle Mesh.

    Polygons are fan-triangulated, with one MeshWarning per file. OBJ texture
    coordinates keep their own per-corner index list (``uv_faces``); the texture of
    the used material (``map_Kd``) is stored in ``Mesh.texture``, resolved relative
    to the .mtl file (a missing .mtl or image is a MeshWarning; a missing image's path
    is still stored). PLY reads per-vertex u,v (or s,t / texture_u,texture_v) with
    ``uv_faces == faces``, or MeshLab's per-corner ``texcoord`` lists, and the texture
    from ``comment TextureFile``. Raises MeshError naming the file (and line) on any error.
    """
    path = Path(path)
    reader = _READERS.get(path.suffix.lower())
    if reader is None:
        raise MeshError(path, f"unknown mesh format {path.suffix!r} (expected .obj or .ply)")
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


def read_image(path: str | os.PathLike) -> np.ndarray:
    """A texture image (PNG, JPEG, anything Pillow reads) as (H, W, 3) uint8 RGB, rows from
    the top. Raises MeshError naming the file when it cannot be read."""
    from PIL import Image, UnidentifiedImageError

    path = Path(path)
    try:
        with Image.open(path) as im:
            return np.asarray(im.convert("RGB"), dtype=np.uint8).copy()
    except (OSError, UnidentifiedImageError, ValueError) as e:
        raise MeshError(path, f"cannot read texture image: {e}") from None


def write_image(path: str | os.PathLike, image: np.ndarray) -> None:
    """Writes an (H, W, 3) uint8 RGB image as PNG, atomically."""
    import io as _io

    from PIL import Image

    buf = _io.BytesIO()
    Image.fromarray(np.ascontiguousarray(image, np.uint8), "RGB").save(buf, format="PNG", compress_level=1)
    _atomic_write(Path(path), [buf.getvalue()])


# --------------------------------------------------------------------------- shared helpers

_NO_LINES = np.zeros(0, np.int64)


class _Lines:
    """Line and token table of a byte buffer, computed with vectorized numpy."""

    def __init__(self, data: bytes):
        # Padding guarantees a final newline and lets keyword tests look two bytes ahead.
        self.buf = buf = np.frombuffer(data + b"\n\n\n", np.uint8)
        # Control bytes count as separators; a stray one makes the bulk number parse
        # fail, which hands the file to the line-by-line parser.
        self.ws = ws = buf <= 32
        self.ends = newlines = np.flatnonzero(buf == 10)
        token_start = ~ws
        token_start[1:] &= ws[:-1]
        tokens = np.flatnonzero(token_start)
        token_line = np.searchsorted(newlines, tokens)
        self.ntok = np.bincount(token_line, minlength=len(newlines))
        self.first = np.full(len(newlines), len(buf) - 1)  # blank lines point at a newline
        new = np.ones(len(tokens), bool)
        new[1:] = token_line[1:] != token_line[:-1]
        self.first[token_line[new]] = tokens[new]

    def keyword(self, word: bytes) -> np.ndarray:
        """Indices of lines whose first token is exactly ``word`` (1 or 2 bytes)."""
        hit = self.ws[np.minimum(self.first + len(word), len(self.buf) - 1)]
        for i, ch in enumerate(word):
            hit &= self.buf[np.minimum(self.first + i, len(self.buf) - 1)] == ch
        return np.flatnonzero(hit)

    def gather(self, lines: np.ndarray, skip: int) -> np.ndarray:
        """The bytes of ``lines`` (ascending) with their first ``skip`` bytes blanked out.

        Lines of one kind come in a few long runs, so slicing whole runs is far cheaper
        than masking line by line.
        """
        if len(lines) == 0:
            return np.zeros(0, np.uint8)
        bounds = np.r_[0, np.flatnonzero(np.diff(lines) != 1) + 1, len(lines)]
        begin = self.first[lines[bounds[:-1]]]
        end = self.ends[lines[bounds[1:] - 1]] + 1
        chars = np.concatenate([self.buf[a:b] for a, b in zip(begin.tolist(), end.tolist())])
        run_shift = np.cumsum(end - begin) - (end - begin) - begin
        keyword = self.first[lines] + np.repeat(run_shift, np.diff(bounds))
        for k in range(skip):
            chars[keyword + k] = ord(" ")
        return chars

    def text(self, line: int) -> str:
        start = self.ends[line - 1] + 1 if line > 0 else 0
        return self.buf[start : self.ends[line]].tobytes().decode("utf-8", "replace")


def _parse_numbers(chars: np.ndarray | bytes, dtype, expected: int) -> np.ndarray | None:
    """Whitespace-separated numbers, or None if any token is not a number of ``dtype``."""
    text = chars.tobytes() if isinstance(chars, np.ndarray) else chars
    try:
        with warnings.catch_warnings():
            # numpy < 2.3 warns and stops early instead of raising; the count check catches it.
            warnings.simplefilter("ignore", DeprecationWarning)
            values = np.fromstring(text, dtype=dtype, sep=" ")
    except ValueError:
        return None
    return values if len(values) == expected else None


def _take_columns(values: np.ndarray, counts: np.ndarray, width: int, fill: float = 0.0) -> np.ndarray:
    """The first ``width`` of each row's ``counts`` values; short rows are padded with ``fill``."""
    if len(counts) and (counts == counts[0]).all() and counts[0] >= width:
        return values.reshape(len(counts), counts[0])[:, :width].copy()
    offsets = np.cumsum(counts) - counts
    cols = np.arange(width)
    present = cols < counts[:, None]
    out = np.full((len(counts), width), fill)
    out[present] = values[(offsets[:, None] + cols)[present]]
    return out


def _fan(sizes: np.ndarray) -> np.ndarray:
    """(T, 3) corner numbers fan-triangulating polygons of ``sizes`` corners laid end to end."""
    if (sizes == 3).all():
        return np.arange(3 * len(sizes)).reshape(-1, 3)
    starts = np.cumsum(sizes) - sizes
    ntri = sizes - 2
    owner = np.repeat(np.arange(len(sizes)), ntri)
    step = np.arange(int(ntri.sum())) - np.repeat(np.cumsum(ntri) - ntri, ntri)
    base = starts[owner]
    return np.stack([base, base + 1 + step, base + 2 + step], axis=1)


def _note_polygons(sizes: np.ndarray, notes: list[str]) -> None:
    polygons = int((sizes > 3).sum())
    if polygons:
        notes.append(f"triangulated {polygons} polygon(s) with more than 3 corners")


def _first(mask: np.ndarray) -> int:
    return int(np.argmax(mask))


def _note_missing_texture(texture: Path | None, notes: list[str]) -> None:
    if texture is not None and not texture.is_file():
        notes.append(f"texture file {texture} not found")


# --------------------------------------------------------------------------- OBJ reading


@dataclass
class _ObjData:
    """What an OBJ file says, before index resolution: raw 1-based/negative indices."""

    positions: np.ndarray  # (n, 3)
    v_lines: np.ndarray  # line number of each position
    uvs: np.ndarray  # (k, 2)
    vt_lines: np.ndarray
    corner_v: np.ndarray  # (C,) raw index per face corner
    corner_vt: np.ndarray | None  # (C,) or None when faces carry no UVs
    sizes: np.ndarray  # corners per face
    face_lines: np.ndarray
    mtllibs: list[str]
    materials: list[str]  # usemtl names in order of first use


def _read_obj(data: bytes, path: Path, notes: list[str]) -> Mesh:
    data = data.removeprefix(b"\xef\xbb\xbf")
    obj = _scan_obj_fast(data) or _scan_obj_slow(data.decode("utf-8", "replace"), path, notes)
    _check_finite(path, obj.positions, obj.v_lines, "coordinate")
    _check_finite(path, obj.uvs, obj.vt_lines, "texture coordinate")
    if len(obj.sizes) == 0:
        raise MeshError(path, "no faces")
    owner = np.repeat(np.arange(len(obj.sizes)), obj.sizes)
    corner_lines = obj.face_lines[owner]
    tris = _fan(obj.sizes)
    _note_polygons(obj.sizes, notes)
    faces = _resolve(path, obj.corner_v, corner_lines, obj.v_lines, "vertex")[tris]
    uvs = uv_faces = None
    if obj.corner_vt is not None:
        uvs = obj.uvs
        uv_faces = _resolve(path, obj.corner_vt, corner_lines, obj.vt_lines, "texture")[tris]
    texture = _obj_texture(path, obj.mtllibs, obj.materials, notes)
    return Mesh(obj.positions, faces, uvs, uv_faces, texture)


def _check_finite(path: Path, values: np.ndarray, lines: np.ndarray, what: str) -> None:
    bad = ~np.isfinite(values).all(axis=1)
    if bad.any():
        i = _first(bad)
        raise MeshError(path, f"{what} is not finite: {values[i].tolist()}", int(lines[i]))


def _resolve(path: Path, raw: np.ndarray, lines: np.ndarray, defined: np.ndarray, what: str) -> np.ndarray:
    """0-based indices from OBJ indices: 1-based, or negative relative to the lines above."""
    n = len(defined)
    before = np.searchsorted(defined, lines)  # elements defined above each corner's line
    idx = np.where(raw > 0, raw - 1, before + raw)
    bad = (raw == 0) | (idx < 0) | (idx >= n)
    if bad.any():
        i = _first(bad)
        relative = f" or -1..-{before[i]}" if before[i] else ""
        reason = "is 0 (indices start at 1)" if raw[i] == 0 else f"is out of range (1..{n}{relative})"
        raise MeshError(path, f"{what} index {raw[i]} {reason}", int(lines[i]))
    return idx


def _scan_obj_fast(data: bytes) -> _ObjData | None:
    """Bulk parse of a well-formed OBJ; None when the slow parser must decide."""
    if b"\\\n" in data or b"\\\r\n" in data:
        return None  # line continuations
    t = _Lines(data)
    v, vt, f = t.keyword(b"v"), t.keyword(b"vt"), t.keyword(b"f")
    positions = _fast_rows(t, v, 1, 3, 3)
    uvs = _fast_rows(t, vt, 2, 2, 1)
    corners = _fast_corners(t, f)
    if positions is None or uvs is None or corners is None:
        return None
    mtllibs: list[str] = []
    materials: list[str] = []
    starts = t.buf[t.first]
    for line in np.flatnonzero((starts == ord("m")) | (starts == ord("u"))):
        _obj_directive(t.text(int(line)).split("#", 1)[0].split(None, 1), mtllibs, materials)
    corner_v, corner_vt = corners
    return _ObjData(positions, v + 1, uvs, vt + 1, corner_v, corner_vt, t.ntok[f] - 1, f + 1, mtllibs, materials)


def _fast_rows(t: _Lines, lines: np.ndarray, skip: int, width: int, minimum: int) -> np.ndarray | None:
    """``width`` floats per line after a ``skip``-byte keyword; extra values (colours) are ignored."""
    if len(lines) == 0:
        return np.zeros((0, width))
    counts = t.ntok[lines] - 1
    chars = t.gather(lines, skip)
    if counts.min() < minimum or (chars == ord("#")).any():
        return None
    values = _parse_numbers(chars, np.float64, int(counts.sum()))
    return None if values is None else _take_columns(values, counts, width)


def _fast_corners(t: _Lines, lines: np.ndarray) -> tuple[np.ndarray, np.ndarray | None] | None:
    """Vertex and UV indices of every face corner, when all corners share one form."""
    if len(lines) == 0:
        return _NO_LINES, None
    counts = t.ntok[lines] - 1
    chars = t.gather(lines, 1)
    if counts.min() < 3 or (chars == ord("#")).any():
        return None
    form = _corner_form(chars, int(counts.sum()))
    if form is None:
        return None
    width, has_vt = form
    chars[chars == ord("/")] = ord(" ")
    values = _parse_numbers(chars, np.int64, width * int(counts.sum()))
    if values is None:
        return None
    values = values.reshape(-1, width)
    return values[:, 0].copy(), (values[:, 1].copy() if has_vt else None)


def _corner_form(chars: np.ndarray, ncorners: int) -> tuple[int, bool] | None:
    """(numbers per corner, has UV) if every corner is written alike (v, v/vt, v//vn, v/vt/vn)."""
    slashes = np.flatnonzero(chars == ord("/"))
    if len(slashes) == 0:
        return 1, False
    if len(slashes) % ncorners:
        return None
    ws = chars <= 32
    starts = np.flatnonzero(~ws & np.r_[True, ws[:-1]])
    per_corner = np.bincount(np.searchsorted(starts, slashes, "right") - 1, minlength=ncorners)
    doubled = np.bincount(np.searchsorted(starts, slashes[chars[slashes + 1] == ord("/")], "right") - 1, minlength=ncorners)
    if per_corner.min() != per_corner.max() or doubled.min() != doubled.max() or len(starts) != ncorners:
        return None
    forms = {(1, 0): (2, True), (2, 0): (3, True), (2, 1): (2, False)}
    return forms.get((int(per_corner[0]), int(doubled[0])))


def _obj_directive(parts: list[str], mtllibs: list[str], materials: list[str]) -> None:
    if len(parts) < 2:
        return
    key, arg = parts[0], parts[1].strip()
    if key == "mtllib":
        mtllibs.append(arg)
    elif key == "usemtl" and arg not in materials:
        materials.append(arg)


def _logical_lines(text: str) -> Iterator[tuple[int, str]]:
    """(first line number, line) with backslash continuations joined.

    Comment lines never continue: a Windows path ending in a backslash in a comment
    must not swallow the next line.
    """
    pending, start = "", 0
    for number, line in enumerate(text.split("\n"), 1):
        stripped = line.rstrip()
        if stripped.endswith("\\") and not stripped.lstrip().startswith("#"):
            start = start or number
            pending += stripped[:-1] + " "
            continue
        yield (start or number), pending + line
        pending, start = "", 0
    if pending:
        yield start, pending


def _scan_obj_slow(text: str, path: Path, notes: list[str]) -> _ObjData:
    """Line-by-line OBJ parse; the reference behaviour, and the one that locates errors."""
    v, v_lines, vt, vt_lines = [], [], [], []
    corner_v, corner_vt, sizes, face_lines = [], [], [], []
    mtllibs: list[str] = []
    materials: list[str] = []
    for number, line in _logical_lines(text):
        parts = line.split("#", 1)[0].split()
        if not parts:
            continue
        key = parts[0]
        if key == "v":
            v.append(_floats(path, parts, 3, 3, number))
            v_lines.append(number)
        elif key == "vt":
            vt.append(_floats(path, parts, 1, 2, number))
            vt_lines.append(number)
        elif key == "f":
            for corner in _face_corners(path, parts, number):
                corner_v.append(corner[0])
                corner_vt.append(corner[1])
            sizes.append(len(parts) - 1)
            face_lines.append(number)
        elif key in ("mtllib", "usemtl"):
            _obj_directive(line.split("#", 1)[0].split(None, 1), mtllibs, materials)
    return _ObjData(
        np.array(v, np.float64).reshape(-1, 3), np.array(v_lines, np.int64),
        np.array(vt, np.float64).reshape(-1, 2), np.array(vt_lines, np.int64),
        np.array(corner_v, np.int64), _uv_corners(corner_vt, notes),
        np.array(sizes, np.int64), np.array(face_lines, np.int64), mtllibs, materials,
    )


def _floats(path: Path, parts: list[str], minimum: int, width: int, line: int) -> list[float]:
    if len(parts) - 1 < minimum:
        raise MeshError(path, f"'{parts[0]}' needs at least {minimum} numbers, found {len(parts) - 1}", line)
    out = [0.0] * width
    for i, token in enumerate(parts[1 : 1 + width]):
        try:
            out[i] = float(token)
        except ValueError:
            raise MeshError(path, f"bad number {token!r}", line) from None
    return out


def _face_corners(path: Path, parts: list[str], line: int) -> list[tuple[int, int]]:
    """(vertex, uv) raw indices per corner; uv 0 means the corner has none."""
    if len(parts) < 4:
        raise MeshError(path, f"face needs at least 3 corners, found {len(parts) - 1}", line)
    corners = []
    for token in parts[1:]:
        fields = token.split("/")
        if len(fields) > 3 or not fields[0]:
            raise MeshError(path, f"bad face corner {token!r}", line)
        numbers = [_index(path, x, line) if x else 0 for x in fields]
        corners.append((numbers[0], numbers[1] if len(numbers) > 1 else 0))
    return corners


def _index(path: Path, token: str, line: int) -> int:
    try:
        return int(token)
    except ValueError:
        raise MeshError(path, f"bad index {token!r}", line) from None


def _uv_corners(corner_vt: list[int], notes: list[str]) -> np.ndarray | None:
    uv = np.array(corner_vt, np.int64)
    has = uv != 0
    if has.all() and len(uv):
        return uv
    if has.any():
        notes.append("some face corners have texture coordinates and some do not; UVs dropped")
    return None


def _obj_texture(path: Path, mtllibs: list[str], materials: list[str], notes: list[str]) -> Path | None:
    """Texture (map_Kd) of the first used material that has one, relative to its .mtl."""
    textures: dict[str, Path] = {}
    for lib in mtllibs:
        # One mtllib line may list several libraries, or one name containing spaces.
        for name in [lib] if (path.parent / lib).is_file() else lib.split():
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
    except OSError:
        notes.append(f"material library {mtl} not found; texture ignored")
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


# --------------------------------------------------------------------------- PLY reading

_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
              "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
              "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}
_STRUCT_CODES = {"i1": "b", "u1": "B", "i2": "h", "u2": "H", "i4": "i", "u4": "I"}
_PLY_FORMATS = {"ascii": None, "binary_little_endian": "<", "binary_big_endian": ">"}
_UV_NAMES = [("u", "v"), ("s", "t"), ("texture_u", "texture_v"), ("texture_s", "texture_t")]


@dataclass
class _PlyProperty:
    name: str
    dtype: str  # numpy type code, e.g. "f4"
    count_dtype: str | None = None  # set for list properties


@dataclass
class _PlyElement:
    name: str
    count: int
    properties: list[_PlyProperty]


@dataclass
class _PlyHeader:
    byte_order: str | None  # None for ASCII
    elements: list[_PlyElement]
    comments: list[str]
    body: int  # byte offset of the body
    lines: int  # header lines, end_header included


@dataclass
class _PlyData:
    """One element's values: scalars as 1-D arrays, lists as (counts, flat values)."""

    columns: dict
    lines: np.ndarray | None  # line number per record (ASCII) or None


def _read_ply(data: bytes, path: Path, notes: list[str]) -> Mesh:
    header = _ply_header(data, path)
    read = _ply_ascii_body if header.byte_order is None else _ply_binary_body
    elements = read(data, header, path)
    vertex, face = elements.get("vertex"), elements.get("face")
    if vertex is None:
        raise MeshError(path, "PLY has no 'vertex' element")
    positions = _ply_positions(path, vertex)
    sizes, corners = _ply_face_lists(path, face, len(positions))
    tris = _fan(sizes)
    _note_polygons(sizes, notes)
    faces = corners[tris]
    uvs, uv_faces = _ply_uvs(vertex, face, sizes, tris, faces)
    texture = _ply_texture(path, header.comments, notes)
    return Mesh(positions, faces, uvs, uv_faces, texture)


def _ply_header(data: bytes, path: Path) -> _PlyHeader:
    lines = _header_lines(data, path)
    if not lines or lines[0][1] != "ply":
        raise MeshError(path, "bad PLY header: first line is not 'ply'", 1)
    order, elements, comments = "", [], []
    for number, line, _ in lines[1:-1]:
        parts = line.split()
        if not parts or parts[0] in ("comment", "obj_info"):
            comments.append(line.split(None, 1)[1] if len(parts) > 1 else "")
        elif parts[0] == "format" and len(parts) == 3 and parts[1] in _PLY_FORMATS:
            order = _PLY_FORMATS[parts[1]]
        elif parts[0] == "element" and len(parts) == 3 and parts[2].isdigit():
            elements.append(_PlyElement(parts[1], int(parts[2]), []))
        elif parts[0] == "property" and elements:
            elements[-1].properties.append(_ply_property(path, parts, number))
        else:
            raise MeshError(path, f"bad PLY header line {line!r}", number)
    if order == "":
        raise MeshError(path, "bad PLY header: missing or unsupported 'format' line")
    body = lines[-1][2]
    return _PlyHeader(order, elements, comments, body, len(lines))


def _header_lines(data: bytes, path: Path) -> list[tuple[int, str, int]]:
    """(line number, text, offset after the line) up to and including end_header."""
    out, pos = [], 0
    while True:
        end = data.find(b"\n", pos)
        if end < 0 or len(out) > 10000:
            raise MeshError(path, "bad PLY header: no 'end_header' line")
        text = data[pos:end].decode("latin-1").strip()
        out.append((len(out) + 1, text, end + 1))
        pos = end + 1
        if text == "end_header" or (len(out) == 1 and text != "ply"):
            return out


def _ply_property(path: Path, parts: list[str], number: int) -> _PlyProperty:
    if len(parts) == 3 and parts[1] in _PLY_TYPES:
        return _PlyProperty(parts[2], _PLY_TYPES[parts[1]])
    if (len(parts) == 5 and parts[1] == "list" and parts[3] in _PLY_TYPES
            and _PLY_TYPES.get(parts[2], "f")[0] in "iu"):
        return _PlyProperty(parts[4], _PLY_TYPES[parts[3]], _PLY_TYPES[parts[2]])
    raise MeshError(path, f"bad PLY property {' '.join(parts)!r}", number)


def _ply_binary_body(data: bytes, header: _PlyHeader, path: Path) -> dict[str, _PlyData]:
    out, pos = {}, header.body
    for element in header.elements:
        read = _ply_binary_lists if any(p.count_dtype for p in element.properties) else _ply_binary_fixed
        out[element.name], pos = read(data, pos, element, header.byte_order, path)
    return out


def _truncated(path: Path, element: _PlyElement) -> MeshError:
    return MeshError(path, f"truncated binary PLY: data ends inside element '{element.name}' ({element.count} records)")


def _ply_binary_fixed(data, pos, element, order, path) -> tuple[_PlyData, int]:
    dtype = np.dtype([(f"p{i}", order + p.dtype) for i, p in enumerate(element.properties)])
    if dtype.itemsize == 0:
        return _PlyData({}, None), pos
    if pos + dtype.itemsize * element.count > len(data):
        raise _truncated(path, element)
    records = np.frombuffer(data, dtype, element.count, pos)
    columns = {p.name: records[f"p{i}"] for i, p in enumerate(element.properties)}
    return _PlyData(columns, None), pos + dtype.itemsize * element.count


def _ply_binary_lists(data, pos, element, order, path) -> tuple[_PlyData, int]:
    """Records with list properties: one fixed-size view when every list has the same length."""
    if element.count == 0:
        return _PlyData({p.name: _empty_column(p) for p in element.properties}, None), pos
    lengths = _ply_walk(data, pos, element, order, path, 1)[0][:, 0]
    fields = []
    for i, p in enumerate(element.properties):
        if p.count_dtype:
            fields.append((f"n{i}", order + p.count_dtype))
        fields.append((f"p{i}", order + p.dtype, (int(lengths[i]),)) if p.count_dtype else (f"p{i}", order + p.dtype))
    dtype = np.dtype(fields)
    if pos + dtype.itemsize * element.count <= len(data):
        records = np.frombuffer(data, dtype, element.count, pos)
        if all((records[f"n{i}"] == lengths[i]).all() for i, p in enumerate(element.properties) if p.count_dtype):
            return _PlyData(_fixed_columns(element, records), None), pos + dtype.itemsize * element.count
    return _ply_binary_ragged(data, pos, element, order, path)


def _empty_column(p: _PlyProperty):
    empty = np.zeros(0, p.dtype)
    return (np.zeros(0, np.int64), empty) if p.count_dtype else empty


def _fixed_columns(element: _PlyElement, records: np.ndarray) -> dict:
    columns = {}
    for i, p in enumerate(element.properties):
        values = records[f"p{i}"]
        if p.count_dtype:
            columns[p.name] = (np.full(len(values), values.shape[1], np.int64), values.reshape(-1))
        else:
            columns[p.name] = values
    return columns


def _ply_walk(data, pos, element, order, path, records) -> tuple[np.ndarray, np.ndarray, int]:
    """Per record and property: (count, byte offset of the values), walking ``records`` records."""
    layout = [(struct.Struct(order + _STRUCT_CODES[p.count_dtype]), np.dtype(p.dtype).itemsize) if p.count_dtype
              else (None, np.dtype(p.dtype).itemsize) for p in element.properties]
    # A header may claim any count; refuse before allocating tables for it.
    smallest = sum(count.size if count else size for count, size in layout)
    if smallest * records > len(data) - pos:
        raise _truncated(path, element)
    counts = np.ones((len(element.properties), records), np.int64)
    starts = np.zeros((len(element.properties), records), np.int64)
    try:
        for r in range(records):
            for i, (count_struct, size) in enumerate(layout):
                if count_struct is not None:
                    (n,) = count_struct.unpack_from(data, pos)
                    if n < 0:
                        raise MeshError(path, f"negative list length in '{element.name}' record {r}")
                    pos += count_struct.size
                    counts[i, r] = n
                    size *= n
                starts[i, r] = pos
                pos += size
    except struct.error:
        raise _truncated(path, element) from None
    if pos > len(data):
        raise _truncated(path, element)
    return counts, starts, pos


def _ply_binary_ragged(data, pos, element, order, path) -> tuple[_PlyData, int]:
    counts, starts, end = _ply_walk(data, pos, element, order, path, element.count)
    raw = np.frombuffer(data, np.uint8)
    columns = {}
    for i, p in enumerate(element.properties):
        values = _gather_binary(raw, starts[i], counts[i], np.dtype(order + p.dtype))
        columns[p.name] = (counts[i], values) if p.count_dtype else values
    return _PlyData(columns, None), end


def _gather_binary(raw: np.ndarray, starts: np.ndarray, counts: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """Values of ``dtype`` at ``counts`` consecutive slots from each byte offset in ``starts``."""
    size = dtype.itemsize
    within = np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)
    offsets = np.repeat(starts, counts) + within * size
    return raw[offsets[:, None] + np.arange(size)].reshape(-1).view(dtype)


def _ply_ascii_body(data: bytes, header: _PlyHeader, path: Path) -> dict[str, _PlyData]:
    table = _Lines(data[header.body:])
    records = np.flatnonzero(table.ntok > 0)
    out, used = {}, 0
    for element in header.elements:
        lines = records[used : used + element.count]
        used += element.count
        if len(lines) < element.count:
            raise MeshError(path, f"PLY ends early: element '{element.name}' needs {element.count} lines, found {len(lines)}")
        out[element.name] = _ply_ascii_element(table, lines, element, path, header.lines + 1)
    return out


def _ply_ascii_element(table: _Lines, lines: np.ndarray, element: _PlyElement, path: Path, first_line: int) -> _PlyData:
    ntok = table.ntok[lines]
    numbers = lines + first_line
    values = _parse_numbers(table.gather(lines, 0), np.float64, int(ntok.sum()))
    if values is None:
        _raise_bad_ascii_number(table, lines, path, first_line)
    offsets = np.cumsum(ntok) - ntok
    counts, starts = _ply_ascii_layout(values, offsets, ntok, element, path, numbers)
    columns = {}
    for i, p in enumerate(element.properties):
        flat = _gather_ascii(values, starts[i], counts[i])
        columns[p.name] = (counts[i], flat) if p.count_dtype else flat
    return _PlyData(columns, numbers)


def _ply_ascii_layout(values, offsets, ntok, element, path, numbers):
    """Per property and record: (count, index of the first value) in ``values``."""
    nprops = len(element.properties)
    counts = np.ones((nprops, len(offsets)), np.int64)
    starts = np.zeros((nprops, len(offsets)), np.int64)
    pos = offsets.copy()
    for i, p in enumerate(element.properties):
        if p.count_dtype:
            inside = pos < offsets + ntok
            n = np.full(len(pos), -1.0)
            n[inside] = values[pos[inside]]
            bad = (n < 0) | (n != np.round(n))
            if bad.any():
                raise MeshError(path, f"bad list length in '{element.name}'", int(numbers[_first(bad)]))
            counts[i] = n
            pos = pos + 1
        starts[i] = pos
        pos = pos + counts[i]
    wrong = pos != offsets + ntok
    if wrong.any():
        r = _first(wrong)
        raise MeshError(path, f"'{element.name}' record has {ntok[r]} values, expected {pos[r] - offsets[r]}", int(numbers[r]))
    return counts, starts


def _gather_ascii(values: np.ndarray, starts: np.ndarray, counts: np.ndarray) -> np.ndarray:
    within = np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)
    return values[np.repeat(starts, counts) + within]


def _raise_bad_ascii_number(table: _Lines, lines: np.ndarray, path: Path, first_line: int) -> None:
    for line in lines:
        for token in table.text(int(line)).split():
            if not _is_number(token):
                raise MeshError(path, f"bad number {token!r}", int(line) + first_line)
    raise MeshError(path, "bad number", int(lines[0]) + first_line)


def _record_name(data: _PlyData, index: int, what: str) -> tuple[str, int | None]:
    """How to point at record ``index``: its line for ASCII, its number for binary."""
    if data.lines is not None:
        return what, int(data.lines[index])
    return f"{what} {index}", None


def _ply_positions(path: Path, vertex: _PlyData) -> np.ndarray:
    missing = [c for c in "xyz" if c not in vertex.columns or isinstance(vertex.columns[c], tuple)]
    if missing:
        raise MeshError(path, f"PLY vertex element lacks property {missing[0]!r}")
    positions = np.stack([vertex.columns[c].astype(np.float64) for c in "xyz"], axis=1)
    bad = ~np.isfinite(positions).all(axis=1)
    if bad.any():
        what, line = _record_name(vertex, _first(bad), "vertex")
        raise MeshError(path, f"{what} has a coordinate that is not finite", line)
    return positions


def _ply_face_lists(path: Path, face: _PlyData | None, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(corners per face, vertex index per corner), validated."""
    column = None
    if face is not None:
        column = face.columns.get("vertex_indices", face.columns.get("vertex_index"))
    if column is None or not isinstance(column, tuple) or len(column[0]) == 0:
        raise MeshError(path, "no faces (PLY needs a 'face' element with a 'vertex_indices' list)")
    sizes, flat = column
    if (sizes < 3).any():
        what, line = _record_name(face, _first(sizes < 3), "face")
        raise MeshError(path, f"{what} has fewer than 3 corners", line)
    bad = (flat < 0) | (flat >= n) | (flat != np.floor(flat))
    if bad.any():
        owner = np.repeat(np.arange(len(sizes)), sizes)
        what, line = _record_name(face, int(owner[_first(bad)]), "face")
        raise MeshError(path, f"{what}: vertex index {flat[_first(bad)]} is out of range (0..{n - 1})", line)
    return sizes.astype(np.int64), flat.astype(np.int64)


def _ply_uvs(vertex: _PlyData, face: _PlyData, sizes, tris, faces):
    """Per-corner ``texcoord`` lists if present, else per-vertex u,v (uv_faces = faces)."""
    texcoord = face.columns.get("texcoord")
    if isinstance(texcoord, tuple) and np.array_equal(texcoord[0], 2 * sizes):
        corners = texcoord[1].astype(np.float64).reshape(-1, 2)[tris.reshape(-1)]
        uvs, first, inverse = np.unique(corners, axis=0, return_index=True, return_inverse=True)
        order = np.argsort(first, kind="stable")  # keep first-use order, as a writer would
        rank = np.empty_like(order)
        rank[order] = np.arange(len(order))
        return uvs[order], rank[inverse.reshape(-1)].reshape(-1, 3)
    for u, v in _UV_NAMES:
        cu, cv = vertex.columns.get(u), vertex.columns.get(v)
        if cu is not None and cv is not None and not isinstance(cu, tuple) and not isinstance(cv, tuple):
            return np.stack([cu, cv], axis=1).astype(np.float64), faces.copy()
    return None, None


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

_ROWS_PER_CHUNK = 65536


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
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp")
    # os.open with mode 0o666 lets the umask decide permissions, as a plain open() would.
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666)
    try:
        with os.fdopen(fd, "wb") as f:
            for chunk in chunks:
                f.write(chunk)
            f.flush()
            os.fsync(f.fileno())  # the rename must not become visible before the data
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def _format_rows(template: str, values: np.ndarray) -> Iterator[bytes]:
    """``template`` % row for every row, in chunks; %r gives Python's shortest exact repr."""
    for start in range(0, len(values), _ROWS_PER_CHUNK):
        block = values[start : start + _ROWS_PER_CHUNK]
        yield ((template * len(block)) % tuple(block.reshape(-1).tolist())).encode("ascii")


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
    yield from _format_rows("v %r %r %r\n", mesh.positions)
    if mesh.uvs is not None:
        yield from _format_rows("vt %r %r\n", mesh.uvs)
    if material is not None:
        yield b"usemtl material0\n"
    yield from _obj_face_text(mesh.faces, None if mesh.uvs is None else _uv_faces(path, mesh))


def _obj_face_text(faces: np.ndarray, uv_faces: np.ndarray | None) -> Iterator[bytes]:
    if uv_faces is None:
        return _format_rows("f %d %d %d\n", faces + 1)
    corners = np.stack([faces + 1, uv_faces + 1], axis=2).reshape(-1, 6)
    return _format_rows("f %d/%d %d/%d %d/%d\n", corners)


def _write_ply(path: Path, mesh: Mesh, ascii: bool) -> None:
    if len(mesh.positions) > np.iinfo(np.int32).max:
        raise MeshError(path, "too many vertices for PLY int indices")
    per_vertex_uv, texcoord = _ply_uv_layout(path, mesh)
    header = _ply_header_text(mesh, ascii, per_vertex_uv, texcoord is not None)
    vertex = mesh.positions if not per_vertex_uv else np.hstack([mesh.positions, mesh.uvs])
    if ascii:
        body = _ply_ascii_chunks(vertex, mesh.faces, texcoord)
    else:
        body = _ply_binary_chunks(vertex, mesh.faces, texcoord)
    _atomic_write(path, _prepend(header.encode("utf-8"), body))


def _prepend(first: bytes, rest: Iterable[bytes]) -> Iterator[bytes]:
    yield first
    yield from rest


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


def _ply_ascii_chunks(vertex: np.ndarray, faces: np.ndarray, texcoord: np.ndarray | None) -> Iterator[bytes]:
    yield from _format_rows(" ".join(["%r"] * vertex.shape[1]) + "\n", vertex)
    if texcoord is None:
        yield from _format_rows("3 %d %d %d\n", faces)
    else:
        # float64 holds the indices exactly, so one float row formats both kinds of value.
        rows = np.hstack([faces.astype(np.float64), texcoord])
        yield from _format_rows("3 %d %d %d 6" + " %r" * 6 + "\n", rows)


def _ply_binary_chunks(vertex: np.ndarray, faces: np.ndarray, texcoord: np.ndarray | None) -> Iterator[bytes]:
    yield np.ascontiguousarray(vertex, "<f8").tobytes()
    fields = [("n", "u1"), ("v", "<i4", (3,))]
    if texcoord is not None:
        fields += [("tn", "u1"), ("tc", "<f8", (6,))]
    for start in range(0, len(faces), _ROWS_PER_CHUNK):
        block = faces[start : start + _ROWS_PER_CHUNK]
        records = np.zeros(len(block), np.dtype(fields))
        records["n"] = 3
        records["v"] = block
        if texcoord is not None:
            records["tn"] = 6
            records["tc"] = texcoord[start : start + _ROWS_PER_CHUNK]
        yield records.tobytes()


_READERS = {".obj": _read_obj, ".ply": _read_ply}
_WRITERS = {".obj": _write_obj, ".ply": _write_ply}
