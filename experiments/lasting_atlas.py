"""Would an atlas that outlives intra frames pay? (issue 45, item 4)

Today every intra geometry frame starts a texture group: a new xatlas atlas and a new key
picture of the texture video. Two ways to keep the texture video predicting across the new
base mesh, measured on a shared textured capture coded all-intra (``--inter none``, so that
every frame has a new base mesh, as on content like dancer):

- ``charts``: how much of each new base mesh lands inside ONE chart of the previous frame's
  atlas (each base vertex takes the chart of the nearest vertex of the previous reconstruction;
  a face can keep its place in the atlas only when its three corners agree). The rest would
  need new charts in the atlas's free space.
- ``ortho``: a projection atlas (each base face projected along the one of the six axis
  directions its normal is nearest to; connected faces of one direction form a patch; patches
  shelf-packed) made anew for every frame, each frame its own video (``ortho``), or with every
  patch put where the previous frame's overlapping patch of the same direction was, so that the
  same surface lands on the same texels, and all frames one video (``ortho-chain``). Against
  the encoder's own atlas, each frame its own video (``xatlas``): Y BD-rate at total rate.

    python experiments/lasting_atlas.py charts liam_textured 6
    python experiments/lasting_atlas.py rd liam_textured 6 xatlas,ortho,ortho-chain [26,32,38,44]
"""

from __future__ import annotations

import json
import sys

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

import dynmesh
from dynmesh.io import image_of
from dynmesh import _core, api, texture
from dynmesh.eval.report import bd_rate
from dynmesh.mesh import Mesh
from dynmesh.texture import atlas, video

import texture_qp_hull as hull

GEOMETRY_QP = 28


def all_intra_frames(seq: str, count: int):
    """Per frame: (input mesh, decoded base mesh, reconstruction, geometry bytes), coded
    all-intra at ``GEOMETRY_QP``."""
    frames = [dynmesh.read_mesh(f) for f in sorted((hull.SHARED / "data" / seq).glob("*.obj"))[:count]]
    lo, hi = api.sequence_bounds(frames)
    enc = api._encoder(len(frames), lo, hi, {**api.DEFAULTS, "qp": GEOMETRY_QP, "inter": "none"})
    out = []
    for m in frames:
        unit, _, (pos, faces), (bp, bf) = enc.encode_frame(m.positions, m.faces)
        out.append((m, Mesh(bp, bf), Mesh(pos, faces), len(unit)))
    return out


def atlas_side(first) -> int:
    """The encoder's default atlas side for a capture whose first frame is ``first``."""
    return texture.atlas_size_for(*texture.coder._texture_shape(first))


def charts(seq: str, count: int) -> None:
    coded = all_intra_frames(seq, count)
    size = atlas_side(coded[0][0])
    for i in range(1, len(coded)):
        base, rec = coded[i - 1][1], coded[i - 1][2]
        _, uv_faces, uv = atlas.coded_atlas(base.positions, base.faces, size)
        uv, uv_faces = _core.subdivide_uv(uv, uv_faces, api.DEFAULTS["subdiv"])
        chart_of_uv = _components(uv_faces, len(uv))
        chart_of_vertex = np.empty(len(rec.positions), np.int64)
        chart_of_vertex[rec.faces.ravel()] = chart_of_uv[uv_faces.ravel()]
        new = coded[i][1]
        _, nearest = cKDTree(rec.positions).query(new.positions)
        c = chart_of_vertex[nearest][new.faces]
        one = (c[:, 0] == c[:, 1]) & (c[:, 1] == c[:, 2])
        area = _areas(new.positions, new.faces)
        print(f"frame {i}: {len(new.faces)} base faces, {one.mean():.1%} of them ({area[one].sum() / area.sum():.1%} "
              f"of the area) inside one of the previous atlas's {len(np.unique(chart_of_uv))} charts", flush=True)


def _components(tris: np.ndarray, n: int) -> np.ndarray:
    rows = np.concatenate([tris[:, 0], tris[:, 1]])
    cols = np.concatenate([tris[:, 1], tris[:, 2]])
    return connected_components(coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n)), directed=False)[1]


def _areas(positions: np.ndarray, faces: np.ndarray) -> np.ndarray:
    p = np.asarray(positions, np.float64)[faces]
    return np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)


def _directions() -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(direction, t1, t2) for the six axis directions, t1 x t2 = direction, so that a face
    seen along its direction keeps its turning sense in the projection."""
    out, e = [], np.eye(3)
    for axis in range(3):
        for sign in (1.0, -1.0):
            t1, t2 = (e[a] for a in range(3) if a != axis)
            if np.dot(np.cross(t1, t2), sign * e[axis]) < 0:
                t1 = -t1
            out.append((sign * e[axis], t1, t2))
    return out


DIRECTIONS = _directions()


class OrthoAtlas:
    """Projection atlases of a sequence's base meshes at one texel density (fixed by the first
    frame: its projected area fills about half the atlas), optionally placed like the previous
    frame's."""

    def __init__(self, size: int, stabilize: bool, gutter: int = 4):
        self.size, self.stabilize, self.gutter = size, stabilize, gutter
        self.density: float | None = None
        self.previous: list = []  # (direction, low, high, offset) of the previous frame's patches
        self.matched: list[float] = []

    def make(self, positions: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        p, f = np.asarray(positions, np.float64), np.asarray(faces, np.int64)
        normals = np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]])
        direction = np.argmax(normals @ np.array([d for d, _, _ in DIRECTIONS]).T, axis=1)
        patch = _patches(f, direction)
        if self.density is None:
            self.density = np.sqrt(0.5 * self.size ** 2 / (0.5 * np.linalg.norm(normals, axis=1).sum()))
        while True:
            placed = self._place(p, f, direction, patch)
            if placed is not None:
                return placed
            self.density *= 0.93  # the patches do not fit: a lower density, and a fresh layout
            self.previous = []

    def _place(self, p, f, direction, patch):
        size, g = self.size, self.gutter
        items = []
        for k in range(patch.max() + 1):
            fs = np.nonzero(patch == k)[0]
            d = direction[fs[0]]
            vs, local = np.unique(f[fs], return_inverse=True)
            ab = np.column_stack([p[vs] @ DIRECTIONS[d][1], p[vs] @ DIRECTIONS[d][2]]) * self.density
            items.append((d, fs, local.reshape(-1, 3), ab, ab.min(0), ab.max(0)))
        items.sort(key=lambda t: -np.prod(t[5] - t[4]))
        used = np.zeros((size, size), bool)
        uv_faces, uvs, state, matched, count = np.zeros_like(f), [], [], 0, 0
        for d, fs, local, ab, low, high in items:
            w, h = int(np.ceil(high[0] - low[0])) + 1 + 2 * g, int(np.ceil(high[1] - low[1])) + 1 + 2 * g
            if w > size or h > size:
                return None
            offset = self._previous_offset(d, low, high, w, h, used)
            matched += offset is not None
            if offset is None:
                at = _free_block(used, w, h)
                if at is None:
                    return None
                offset = np.array([at[0] + g - np.floor(low[0]), at[1] + g - np.floor(low[1])])
            x, y = int(np.floor(low[0] + offset[0])) - g, int(np.floor(low[1] + offset[1])) - g
            used[max(0, y):y + h, max(0, x):x + w] = True
            state.append((d, low, high, offset))
            uv_faces[fs] = local + count
            uvs.append((ab + offset) / size)
            count += len(ab)
        self.previous = state
        self.matched.append(matched / len(items))
        return uv_faces, np.clip(np.vstack(uvs), 0.0, 1.0)

    def _previous_offset(self, d, low, high, w, h, used):
        """The offset of the previous frame's patch of direction ``d`` that overlaps this one
        most (intersection over union of their projected boxes above 0.3), if the patch fits
        there; else None."""
        if not self.stabilize:
            return None
        best, offset = 0.3, None
        for pd, plow, phigh, poffset in self.previous:
            if pd != d:
                continue
            inter = np.prod(np.clip(np.minimum(high, phigh) - np.maximum(low, plow), 0, None))
            union = np.prod(high - low) + np.prod(phigh - plow) - inter
            if union > 0 and inter / union > best:
                best, offset = inter / union, poffset
        if offset is None:
            return None
        x, y = int(np.floor(low[0] + offset[0])) - self.gutter, int(np.floor(low[1] + offset[1])) - self.gutter
        fits = x >= 0 and y >= 0 and x + w <= self.size and y + h <= self.size and not used[y:y + h, x:x + w].any()
        return offset if fits else None


def _patches(faces: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Connected components of the faces of one direction, joined across shared edges."""
    m = len(faces)
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    owner = np.tile(np.arange(m), 3)
    order = np.lexsort((edges[:, 1], edges[:, 0]))
    edges, owner = edges[order], owner[order]
    shared = np.all(edges[1:] == edges[:-1], axis=1)
    a, b = owner[:-1][shared], owner[1:][shared]
    keep = direction[a] == direction[b]
    graph = coo_matrix((np.ones(keep.sum()), (a[keep], b[keep])), shape=(m, m))
    return connected_components(graph, directed=False)[1]


def _free_block(used: np.ndarray, w: int, h: int) -> tuple[int, int] | None:
    """The top-left (x, y) of the first free w x h block, row by row."""
    table = np.zeros((used.shape[0] + 1, used.shape[1] + 1), np.int32)
    table[1:, 1:] = used.astype(np.int32).cumsum(0).cumsum(1)
    sums = table[h:, w:] - table[:-h, w:] - table[h:, :-w] + table[:-h, :-w]
    ys, xs = np.nonzero(sums == 0)
    return (int(xs[0]), int(ys[0])) if len(ys) else None


def rd(seq: str, count: int, modes: list[str], texture_qps: list[int]) -> None:
    peak = hull.SEQUENCES[seq][2]
    coded = all_intra_frames(seq, count)
    size = atlas_side(coded[0][0])
    frames = [c[0] for c in coded]
    curves = {}
    for mode in modes:
        ortho = OrthoAtlas(size, stabilize=mode == "ortho-chain")
        atlas_bytes, recs, images = 0, [], []
        for m, base, rec, _ in coded:
            if mode == "xatlas":
                data, uv_faces, uv = atlas.coded_atlas(base.positions, base.faces, size)
            else:
                uv_faces, uv = ortho.make(base.positions, base.faces)
                uv_faces, q = _core.canonical_uv(uv_faces, atlas.quantize_uv(uv))
                data = _core.encode_uv(base.faces, uv_faces, q, atlas.UV_BITS, positions=base.positions)
                uv = atlas.dequantize_uv(q)
            atlas_bytes += len(data)
            uv, uv_faces = _core.subdivide_uv(uv, uv_faces, api.DEFAULTS["subdiv"])
            image, _ = _core.transfer_texture(rec.positions, rec.faces, uv, uv_faces, m.positions, m.faces,
                                              m.uvs, m.uv_faces, image_of(m), size, size)
            r = Mesh(rec.positions, rec.faces)
            r.uvs, r.uv_faces = uv, uv_faces
            recs.append(r)
            images.append(image)
        geometry = sum(c[3] for c in coded)
        curves[mode] = []
        for qp in texture_qps:
            videos = [video.encode_video(images, "av1", qp)] if mode == "ortho-chain" else \
                [video.encode_video([im], "av1", qp) for im in images]
            for r, im in zip(recs, (im for v in videos for im in video.decode_video(v, "av1"))):
                r.image = im
            y = api.metrics(frames, recs, peak=peak)["y_psnr"]
            total = geometry + atlas_bytes + sum(len(v) for v in videos)
            curves[mode].append((total, y))
            print(json.dumps({"mode": mode, "texture_qp": qp, "bytes": total, "atlas_bytes": atlas_bytes,
                              "video_bytes": total - geometry - atlas_bytes, "y": round(y, 3)}), flush=True)
        if ortho.stabilize:
            print(f"{mode}: patches placed where the previous frame's were: "
                  + ", ".join(f"{m:.0%}" for m in ortho.matched[1:]), flush=True)
    for mode in modes[1:]:
        r = bd_rate(curves[modes[0]], curves[mode])
        value = "n/a" if r["bd_rate"] is None else f"{r['bd_rate']:+.1f} %"
        print(f"{mode}: Y BD-rate at total rate against {modes[0]}: {value} {r['note']}")

if __name__ == "__main__":
    what, seq, count = sys.argv[1], sys.argv[2], int(sys.argv[3])
    if what == "charts":
        charts(seq, count)
    else:
        rd(seq, count, sys.argv[4].split(","), [int(q) for q in (sys.argv[5] if len(sys.argv) > 5 else "26,32,38,44").split(",")])
