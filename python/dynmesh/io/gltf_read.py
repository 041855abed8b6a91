"""Reading glTF 2.0 frames: ``.gltf`` (buffers in files beside it or in data URIs) and
``.glb``, into one triangle :class:`~dynmesh.mesh.Mesh`.

The glTF itself is read by trimesh (``trimesh.load_scene``): accessors, triangle lists and
strips, the node hierarchy's transforms, data URIs, and Draco-compressed primitives
(KHR_draco_mesh_compression, through DracoPy); the texture image is decoded as
``read_image`` decodes files (8-bit PNG by the core, JPEG and the rest by Pillow). This
module reads the file's JSON first, to refuse with a sentence what trimesh would read
wrongly or silently drop (points, lines and fans, quantized texture coordinates, sparse
accessors, extensions it cannot read, accessors past their data) and to check that every
buffer is there; then it merges what the default scene shows:

- every triangle primitive of every mesh that a node of the scene places, in the world
  frame (the node's matrix or translation, rotation and scale, and its parents'; a mirroring
  transform reverses the winding so that faces still point outwards);
- vertices that glTF splits where they carry several UVs are welded back into one
  (``weld``: equal positions, bit for bit, become one vertex; UVs keep their own indices);
- UVs from TEXCOORD_0, with V flipped by trimesh (glTF's origin is the image's top left,
  dynmesh's and OBJ's the bottom left; tests/test_formats.py reads back what ``decode
  --format glb`` writes), and the base colour texture of the primitives' material: an image
  in the file (a buffer view or a data URI, PNG or JPEG, decoded into ``Mesh.image``) or an
  image file beside it (``Mesh.texture``, read when needed, as an OBJ's ``map_Kd``).

One texture per mesh, as for OBJ: when primitives use several, the first is kept and a
warning says so; when some primitives have UVs and a texture and others do not, the mesh is
read without one (and a warning says so). A file with no scene reads each of its meshes
once, untransformed.
"""

from __future__ import annotations

import base64
import binascii
import io
import json
import logging
import struct
import urllib.parse
from pathlib import Path

import numpy as np

from ..mesh import Mesh
from .errors import MeshError
from .image import decode_image
from .weld import weld

__all__ = ["read_gltf"]

_GLB_MAGIC = b"glTF"
_JSON_CHUNK, _BIN_CHUNK = 0x4E4F534A, 0x004E4942
_TRIANGLES, _TRIANGLE_STRIP = 4, 5
_MODES = {0: "points", 1: "lines", 2: "line loops", 3: "line strips", 6: "triangle fans"}
_FLOAT = 5126
_COMPONENT_BYTES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
_WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
#: Extensions a file may require that this reader honours (material extensions change only
#: shading, which dynmesh does not code; the base colour texture is read whatever they say).
_REQUIRED_OK = ("KHR_draco_mesh_compression", "KHR_mesh_quantization", "EXT_texture_webp")
_REEXPORT = "export the frame again as plain glTF 2.0"


def read_gltf(data: bytes, path: Path, notes: list[str]) -> Mesh:
    """The triangle mesh of a .gltf or .glb file's default scene (see the module
    documentation). Raises MeshError with a sentence saying what is wrong and what to do."""
    try:
        return _read(data, path, notes)
    except (MeshError, MemoryError):
        raise
    except (KeyError, IndexError, TypeError, ValueError, AttributeError, OverflowError, struct.error) as e:
        # A JSON value of the wrong type or out of range that the checks below let through.
        what = _json_fault(e) if not isinstance(e, (ValueError, OverflowError, struct.error)) else str(e)
        raise MeshError(path, f"corrupt glTF: {what}; {_REEXPORT}") from None


def _read(data: bytes, path: Path, notes: list[str]) -> Mesh:
    doc, binary = _document(data, path)
    textures = _check_document(doc, path, notes)
    files = _buffer_files(doc, binary, path)
    scene = _trimesh_scene(_one_primitive_per_mesh(doc), binary, files, path)
    parts = _parts(scene, textures, path)
    if not parts or sum(len(p["faces"]) for p in parts) == 0:
        raise MeshError(path, "no faces: the glTF holds no triangles in its scene; export the frame as a "
                              "triangle mesh")
    return _merge(parts, doc, binary, files, path, notes)


# --------------------------------------------------------------------------- the document


def _document(data: bytes, path: Path) -> tuple[dict, bytes | None]:
    """(the glTF JSON, the .glb's binary chunk or None), by content: a file that starts with
    the .glb magic is read as a .glb, any other as glTF JSON (but a .glb must start so)."""
    if data[:4] == _GLB_MAGIC:
        text, binary = _glb_chunks(data, path)
    else:
        if path.suffix.lower() == ".glb":
            raise MeshError(path, "not a glTF binary: a .glb starts with the bytes 'glTF', this file does not; "
                                  "it is corrupt or not a .glb, so export the frame again")
        text, binary = data, None
    try:
        doc = json.loads(text.decode("utf-8-sig"))
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise MeshError(path, f"not glTF: its JSON cannot be parsed ({e}); the file is corrupt or not glTF, "
                              f"so {_REEXPORT}") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("asset"), dict):
        raise MeshError(path, f"not glTF: its JSON has no 'asset' object; {_REEXPORT}")
    version = str(doc["asset"].get("version", ""))
    if version.split(".")[0] != "2":
        raise MeshError(path, f"glTF version {version or 'unknown'}: dynmesh reads glTF 2.0 only; convert the "
                              "file to glTF 2.0")
    return doc, binary


def _glb_chunks(data: bytes, path: Path) -> tuple[bytes, bytes | None]:
    """The JSON chunk and the first BIN chunk of a .glb."""
    if len(data) < 20:
        raise MeshError(path, "truncated glTF binary: the file ends before its first chunk; copy or export it again")
    _, version, total = struct.unpack_from("<4sII", data)
    if version != 2:
        raise MeshError(path, f"glTF binary version {version}: dynmesh reads glTF 2.0 only; convert the file "
                              "to glTF 2.0")
    if total > len(data):
        raise MeshError(path, f"truncated glTF binary: its header says {total} bytes, the file has "
                              f"{len(data)}; copy or export it again")
    offset, chunks = 12, []
    while offset + 8 <= total:
        length, kind = struct.unpack_from("<II", data, offset)
        if offset + 8 + length > total:
            raise MeshError(path, f"truncated glTF binary: a chunk of {length} bytes at byte {offset} runs past "
                                  "the end of the file; copy or export it again")
        chunks.append((kind, data[offset + 8: offset + 8 + length]))
        offset += 8 + length
    if not chunks or chunks[0][0] != _JSON_CHUNK:
        raise MeshError(path, f"corrupt glTF binary: its first chunk is not JSON; {_REEXPORT}")
    return chunks[0][1], next((c for k, c in chunks[1:] if k == _BIN_CHUNK), None)


def _check_document(doc: dict, path: Path, notes: list[str]) -> list[list[int | None]]:
    """For every primitive of every mesh, the image index of its base colour texture (or
    None), after refusing what this reader would read wrongly: other primitives than
    triangles, quantized or sparse positions and UVs, a required extension it cannot read,
    and references to things the file does not have."""
    try:
        for name in doc.get("extensionsRequired", []):
            if name not in _REQUIRED_OK and not str(name).startswith("KHR_materials_"):
                raise MeshError(path, f"needs the glTF extension {name}, which dynmesh cannot read; export the "
                                      "frame without it")
        if "KHR_draco_mesh_compression" in doc.get("extensionsUsed", []):
            _require_dracopy(path, "its Draco-compressed primitives (KHR_draco_mesh_compression)")
        textures = []
        for mi, mesh in enumerate(doc.get("meshes", [])):
            textures.append([])
            for pi, p in enumerate(mesh["primitives"]):
                where = f"mesh {mi} primitive {pi}"
                mode = p.get("mode", _TRIANGLES)
                if mode not in (_TRIANGLES, _TRIANGLE_STRIP):
                    kind = _MODES.get(mode, f"primitives of unknown mode {mode}")
                    raise MeshError(path, f"{where} holds {kind}, not triangles: dynmesh codes triangle surfaces; "
                                          "export the frame as a triangle mesh (or delete that primitive)")
                attributes = p["attributes"]
                if "POSITION" not in attributes:
                    raise MeshError(path, f"{where} has no POSITION attribute; {_REEXPORT}")
                compressed = "KHR_draco_mesh_compression" in p.get("extensions", {})
                for attribute in ("POSITION", "TEXCOORD_0"):
                    if attribute in attributes:
                        _check_accessor(doc, attributes[attribute], attribute, where, compressed, path)
                if "indices" in p:
                    _check_accessor(doc, p["indices"], "indices", where, compressed, path)
                textures[mi].append(_base_colour_image(doc, p, where, notes))
    except (KeyError, IndexError, TypeError, AttributeError) as e:
        raise MeshError(path, f"corrupt glTF: {_json_fault(e)}; {_REEXPORT}") from None
    return textures


def _json_fault(e: Exception) -> str:
    """What a KeyError, IndexError, TypeError or AttributeError met in the JSON means."""
    if isinstance(e, IndexError):
        return "it refers to an accessor, buffer view, material, texture or image past the end of its list"
    if isinstance(e, KeyError):
        return f"a required member ({e}) is missing"
    return f"a member has a value of the wrong type ({e})"


def _base_colour_image(doc: dict, primitive: dict, where: str, notes: list[str]) -> int | None:
    """The index of the image of the primitive's base colour texture, or None."""
    if "material" not in primitive:
        return None
    info = doc["materials"][primitive["material"]].get("pbrMetallicRoughness", {}).get("baseColorTexture")
    if info is None:
        return None
    if info.get("texCoord", 0) != 0:
        notes.append(f"{where}'s base colour texture uses TEXCOORD_{info['texCoord']}; dynmesh reads "
                     "TEXCOORD_0 only, so the primitive is read without its texture")
        return None
    if "KHR_texture_transform" in info.get("extensions", {}):
        notes.append(f"{where}'s base colour texture has a KHR_texture_transform, which is ignored")
    texture = doc["textures"][info["index"]]
    source = texture.get("source")
    if source is None:
        source = texture.get("extensions", {}).get("EXT_texture_webp", {}).get("source")
    if source is None:
        notes.append(f"{where}'s base colour texture has no PNG or JPEG image (KTX2 or another compressed "
                     "format?), so the primitive is read without its texture")
        return None
    image = doc["images"][source]
    if "uri" not in image and "bufferView" not in image:
        raise KeyError(f"image {source} has neither a uri nor a bufferView")
    return source


def _check_accessor(doc: dict, index: int, attribute: str, where: str, compressed: bool, path: Path) -> None:
    """Refuses an accessor this reader would read wrongly, or whose data its buffer view
    does not hold (which could also ask for any amount of memory)."""
    accessor = doc["accessors"][index]
    if "sparse" in accessor:
        raise MeshError(path, f"{where}'s {attribute} uses a sparse accessor, which dynmesh does not read; "
                              f"{_REEXPORT}")
    component, count = accessor["componentType"], accessor["count"]
    if attribute == "TEXCOORD_0" and component != _FLOAT:
        raise MeshError(path, f"{where}'s texture coordinates are quantized integers (KHR_mesh_quantization), "
                              "which dynmesh does not read; export the frame with float texture coordinates")
    if attribute == "POSITION" and accessor.get("normalized", False):
        raise MeshError(path, f"{where}'s positions are normalized integers (KHR_mesh_quantization), which "
                              "dynmesh does not read; export the frame with float positions")
    if type(count) is not int or count < 0 or component not in _COMPONENT_BYTES or accessor["type"] not in _WIDTHS:
        raise MeshError(path, f"corrupt glTF: accessor {index} ({where}'s {attribute}) has an invalid count, "
                              f"component type or type; {_REEXPORT}")
    if "bufferView" not in accessor:
        if compressed:
            return  # filled by the Draco decoder
        raise MeshError(path, f"corrupt glTF: accessor {index} ({where}'s {attribute}) has no data; {_REEXPORT}")
    view = doc["bufferViews"][accessor["bufferView"]]
    size = _COMPONENT_BYTES[component] * _WIDTHS[accessor["type"]]
    end = accessor.get("byteOffset", 0) + (view.get("byteStride") or size) * (count - 1) + size if count else 0
    if end > view["byteLength"]:
        raise MeshError(path, f"corrupt glTF: accessor {index} ({where}'s {attribute}) needs {end} bytes, its "
                              f"buffer view holds {view['byteLength']}; {_REEXPORT}")


def _require_dracopy(path: Path, what: str) -> None:
    from .draco import dracopy_or_error

    dracopy_or_error(path, what)


def _buffer_files(doc: dict, binary: bytes | None, path: Path) -> dict[str, bytes]:
    """The external buffer files by URI (for trimesh's resolver), after checking that every
    buffer is there and as long as the JSON says."""
    files: dict[str, bytes] = {}
    for i, buffer in enumerate(doc.get("buffers", [])):
        uri, declared = buffer.get("uri"), buffer.get("byteLength", 0)
        if uri is None:
            if i != 0 or binary is None:
                raise MeshError(path, f"buffer {i} has no data: it names no file and the file has no binary "
                                      "chunk; export the frame again as a .glb or with its .bin file")
            size = len(binary)
        elif uri.startswith("data:"):
            size = len(_data_uri(uri, f"buffer {i}", path))
        else:
            file = path.parent / urllib.parse.unquote(uri)
            try:
                files[uri] = file.read_bytes()
            except (OSError, ValueError) as e:
                reason = getattr(e, "strerror", None) or e
                raise MeshError(path, f"buffer {i}'s file {uri} cannot be read ({reason}; looked for {file}): "
                                      "keep the .bin files beside the .gltf, or export a .glb, which holds "
                                      "them") from None
            size = len(files[uri])
        if size < declared:
            raise MeshError(path, f"buffer {i} holds {size} bytes, the glTF says {declared}: the data is "
                                  "truncated; copy or export the frame again")
    for i, view in enumerate(doc.get("bufferViews", [])):
        try:
            buffer = doc["buffers"][view["buffer"]]
            end = view.get("byteOffset", 0) + view["byteLength"]
        except (KeyError, IndexError, TypeError) as e:
            raise MeshError(path, f"corrupt glTF: buffer view {i} is malformed ({type(e).__name__}: {e}); "
                                  f"{_REEXPORT}") from None
        if end > buffer.get("byteLength", 0):
            raise MeshError(path, f"corrupt glTF: buffer view {i} ends at byte {end}, past the end of buffer "
                                  f"{view['buffer']}; {_REEXPORT}")
    return files


def _data_uri(uri: str, what: str, path: Path) -> bytes:
    head, _, payload = uri.partition(",")
    try:
        if head.endswith(";base64"):
            return base64.b64decode(payload, validate=True)
        return urllib.parse.unquote_to_bytes(payload)
    except (binascii.Error, ValueError):
        raise MeshError(path, f"corrupt glTF: {what}'s data URI is not valid base64; {_REEXPORT}") from None


def _one_primitive_per_mesh(doc: dict) -> dict:
    """A copy of ``doc`` in which every mesh has one primitive, tagged in its ``extras``
    with (mesh, primitive) of the original, and nodes that placed a mesh of several
    primitives place one child node per primitive: trimesh then tells which geometry
    is which primitive (its geometry names are its own)."""
    doc = dict(doc)
    new_meshes, of_mesh = [], []
    for mi, mesh in enumerate(doc.get("meshes", [])):
        of_mesh.append([])
        for pi, primitive in enumerate(mesh["primitives"]):
            of_mesh[mi].append(len(new_meshes))
            new_meshes.append({"primitives": [primitive], "name": f"dynmesh-{mi}-{pi}",
                               "extras": {"dynmesh_primitive": [mi, pi]}})
    nodes = [dict(n) for n in doc.get("nodes", [])]
    for node in list(nodes):
        if "mesh" not in node:
            continue
        placed = of_mesh[node.pop("mesh")]
        node["children"] = list(node.get("children", [])) + list(range(len(nodes), len(nodes) + len(placed)))
        nodes += [{"mesh": m} for m in placed]
    doc["meshes"], doc["nodes"] = new_meshes, nodes
    if not doc.get("scenes") and new_meshes:
        # No scene at all: each mesh once, where it stands.
        doc["scenes"], doc["scene"] = [{"nodes": list(range(len(nodes), len(nodes) + len(new_meshes)))}], 0
        doc["nodes"] = nodes + [{"mesh": m} for m in range(len(new_meshes))]
    return doc


def _trimesh_scene(doc: dict, binary: bytes | None, files: dict[str, bytes], path: Path):
    """The scene trimesh reads from ``doc`` (and the .glb's binary chunk)."""
    import trimesh

    text = json.dumps(doc).encode()
    if binary is None:
        source, kind = io.BytesIO(text), "gltf"
    else:
        text += b" " * (-len(text) % 4)
        chunks = [struct.pack("<II", len(text), _JSON_CHUNK), text,
                  struct.pack("<II", len(binary), _BIN_CHUNK), binary]
        total = 12 + sum(len(c) for c in chunks)
        source, kind = io.BytesIO(struct.pack("<4sII", _GLB_MAGIC, 2, total) + b"".join(chunks)), "glb"
    # trimesh reports what it skips through logging (which, with no handler, would print to
    # stderr); what matters is checked before and after, but for one thing: a Draco
    # primitive it could not decode, which it leaves as zeros.
    caught = _Records()
    log = logging.getLogger("trimesh")
    log.addHandler(caught)
    try:
        with np.errstate(all="ignore"):  # NaN from damaged data is refused after, not warned about
            scene = trimesh.load_scene(source, file_type=kind, resolver=files)
    except MemoryError:
        raise
    except Exception as e:  # trimesh raises what its parsing meets (assertions, KeyError, ValueError)
        raise MeshError(path, f"cannot be read as glTF ({type(e).__name__}: {e}); the file is corrupt or uses "
                              "something dynmesh does not read: check it with the Khronos glTF validator or "
                              "export it again") from None
    finally:
        log.removeHandler(caught)
    draco = [m for m in caught.messages if "KHR_draco_mesh_compression" in m or "placeholder zeros" in m]
    if any("no handler" in m for m in draco):
        raise MeshError(path, f"its Draco-compressed primitives (KHR_draco_mesh_compression) need trimesh 5.1 or "
                              f"later to be read, and trimesh {trimesh.__version__} is installed; upgrade it "
                              "(pip install -U trimesh)")
    if draco:
        raise MeshError(path, "its Draco-compressed primitives (KHR_draco_mesh_compression) cannot be decoded: "
                              "their data is corrupt; export the frame again")
    return scene


class _Records(logging.Handler):
    """A logging handler that keeps the messages of trimesh's warnings."""

    def __init__(self):
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        try:
            self.messages.append(record.getMessage())
        except Exception:  # a log call whose arguments do not fit its format
            self.messages.append(str(record.msg))


# --------------------------------------------------------------------------- the scene's parts


def _parts(scene, textures: list[list[int | None]], path: Path) -> list[dict]:
    """One dict per placed triangle primitive, in the order of meshes, primitives, then
    nodes: world positions, faces (winding kept outward), per-vertex UVs or None, and the
    image index of its base colour texture or None."""
    import trimesh

    from .sequence import natural_key

    placed = []
    for node in scene.graph.nodes_geometry:
        matrix, name = scene.graph[node]
        geometry = scene.geometry[name]
        if not isinstance(geometry, trimesh.Trimesh):
            continue
        mi, pi = geometry.metadata["dynmesh_primitive"]
        placed.append(((mi, pi, natural_key(str(node))), matrix, geometry))
    parts = []
    for (mi, pi, _), matrix, geometry in sorted(placed, key=lambda t: t[0]):
        where = f"mesh {mi} primitive {pi}"
        positions = np.asarray(geometry.vertices, np.float64)
        faces = np.asarray(geometry.faces, np.int64).reshape(-1, 3)
        if len(faces) and (faces.min() < 0 or faces.max() >= len(positions)):
            raise MeshError(path, f"corrupt glTF: {where} has a triangle index past its {len(positions)} "
                                  f"vertices; {_REEXPORT}")
        linear, shift = matrix[:3, :3], matrix[:3, 3]
        if not np.array_equal(matrix, np.eye(4)):
            with np.errstate(all="ignore"):  # a non-finite result is refused just below
                positions = positions @ linear.T + shift
            if np.linalg.det(linear) < 0:
                faces = faces[:, ::-1]
        if not np.isfinite(positions).all():
            raise MeshError(path, f"{where} has non-finite positions (NaN or infinity) in the scene's frame; "
                                  f"{_REEXPORT}")
        uvs = getattr(geometry.visual, "uv", None)
        texture = textures[mi][pi]
        if uvs is not None:
            uvs = np.asarray(uvs, np.float64).reshape(-1, 2)
            if len(uvs) != len(positions):
                raise MeshError(path, f"corrupt glTF: {where}'s TEXCOORD_0 has {len(uvs)} values for "
                                      f"{len(positions)} vertices; {_REEXPORT}")
            if not np.isfinite(uvs).all():
                raise MeshError(path, f"{where} has non-finite texture coordinates (NaN or infinity); {_REEXPORT}")
        parts.append({"where": where, "positions": positions, "faces": faces, "uvs": uvs, "texture": texture})
    return parts


def _merge(parts: list[dict], doc: dict, binary: bytes | None, files: dict[str, bytes], path: Path,
           notes: list[str]) -> Mesh:
    offsets = np.cumsum([0] + [len(p["positions"]) for p in parts])
    positions = np.concatenate([p["positions"] for p in parts])
    faces = np.concatenate([p["faces"] + o for p, o in zip(parts, offsets)])
    textured = [p for p in parts if p["uvs"] is not None and p["texture"] is not None]
    if not textured:
        return weld(positions, faces)
    if len(textured) < len(parts):
        plain = len(parts) - len(textured)
        notes.append(f"{plain} of {len(parts)} primitives have no base colour texture or no TEXCOORD_0; "
                     "the mesh is read without its texture")
        return weld(positions, faces)
    sources = list(dict.fromkeys(p["texture"] for p in parts))
    if len(sources) > 1:
        notes.append(f"materials use {len(sources)} textures; only the first (image {sources[0]}) is kept")
    uvs = np.concatenate([p["uvs"] for p in parts])
    return weld(positions, faces, uvs, **_image(doc, sources[0], binary, files, path, notes))


def _image(doc: dict, source: int, binary: bytes | None, files: dict[str, bytes], path: Path,
           notes: list[str]) -> dict:
    """``texture=`` (an image file beside the glTF, read when needed) or ``image=`` (the
    pixels of an image in the file: a buffer view or a data URI)."""
    image = doc["images"][source]
    uri = image.get("uri")
    if uri is not None and not uri.startswith("data:"):
        texture = path.parent / urllib.parse.unquote(uri)
        try:
            found = texture.is_file()
        except (OSError, ValueError):
            found = False
        if not found:
            notes.append(f"texture file {texture!s:.200} not found")
        return {"texture": texture}
    if uri is not None:
        data = _data_uri(uri, f"image {source}", path)
    else:
        view = doc["bufferViews"][image["bufferView"]]
        start = view.get("byteOffset", 0)
        data = _buffer_bytes(doc, view["buffer"], binary, files, path)[start: start + view["byteLength"]]
    try:
        return {"image": decode_image(data, path)}
    except MeshError as e:
        mime = image.get("mimeType", "of unknown type")
        raise MeshError(path, f"its base colour texture (image {source}, {mime}) cannot be decoded "
                              f"({e.reason.removeprefix('cannot read texture image: ')}): dynmesh reads PNG and "
                              "JPEG textures; export the frame with a PNG or JPEG texture") from None


def _buffer_bytes(doc: dict, index: int, binary: bytes | None, files: dict[str, bytes], path: Path) -> bytes:
    uri = doc["buffers"][index].get("uri")
    if uri is None:
        return binary or b""
    if uri.startswith("data:"):
        return _data_uri(uri, f"buffer {index}", path)
    return files[uri]
