//! Closest points of a triangle surface for a walk of queries that lie close together.
//!
//! [`Bvh::closest_point`] answers one query from the root of the hierarchy. Texture transfer
//! asks millions, each next to the one before; a `Finder` keeps a shortlist of the source
//! triangles near the last queries, with distance bounds (`Bound`) that prove which one is
//! closest, and renews it from a uniform grid of the triangles (`FaceGrid`: the query for
//! all triangles near a ball, which the Bvh does not offer). Its answers are exactly the
//! Bvh's, tie-breaking included, with the barycentrics of the closest point.

use std::ops::Range;

use rayon::prelude::*;

use crate::geom::bvh::{closest_on_triangle, Bvh};
use crate::geom::mesh::{add, cross, dot, norm, normalize, scale, sub, Mesh};

/// The closest point of the source to a query: source face, barycentrics there, and squared
/// distance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Hit {
    pub triangle: u32,
    pub bary: [f64; 3],
    pub dist2: f64,
}

/// The source surface, prepared for closest-point queries.
pub(crate) struct Source {
    bvh: Bvh,
    grid: FaceGrid,
    /// Corners of each face.
    tris: Vec<[[f64; 3]; 3]>,
    bounds: Vec<Bound>,
    /// Bounding sphere (centre, radius) of each face: a yet cheaper first test.
    spheres: Vec<[f64; 4]>,
    /// Mean edge length.
    pub edge: f64,
    /// Absolute slack on distance comparisons, against rounding (whose error grows with the
    /// coordinates' magnitude).
    eps: f64,
}

impl Source {
    /// Prepares `mesh` for queries from points whose coordinates are at most `magnitude`
    /// (together with the mesh's own, this sets the slack against rounding).
    pub fn new(mesh: &Mesh, magnitude: f64) -> Self {
        let tris: Vec<[[f64; 3]; 3]> = mesh.faces.par_iter().map(|f| f.map(|v| mesh.positions[v as usize])).collect();
        let bounds = tris.par_iter().map(|&t| Bound::new(t)).collect();
        let spheres = tris.par_iter().map(|&t| bounding_sphere(t)).collect();
        let edge = mean_edge(&tris);
        let (bvh, grid) = rayon::join(|| Bvh::new(&mesh.positions, &mesh.faces), || FaceGrid::new(&tris, edge));
        let eps = 1e-12 * (1.0 + magnitude.max(largest_coordinate(&mesh.positions)));
        Self { bvh, grid, tris, bounds, spheres, edge, eps }
    }

    /// The closest point to `q` of source face `face`.
    fn hit(&self, q: [f64; 3], face: u32) -> Hit {
        let (_, dist2, bary) = closest_on_triangle(q, self.tris[face as usize]);
        Hit { triangle: face, bary, dist2 }
    }

    /// A lower bound on the distance from `q` to source face `face`.
    fn lower(&self, face: u32, q: [f64; 3]) -> f64 {
        self.bounds[face as usize].lower(q)
    }

    /// Replaces `out` with the faces that may lie within `reach` of `c`, nearest first (all
    /// those that do are there); `false` if there are too many.
    fn shortlist(&self, seen: &mut Seen, c: [f64; 3], reach: f64, out: &mut Vec<Entry>) -> bool {
        out.clear();
        let complete = self.grid.visit(c, reach, seen, |f| {
            let [x, y, z, r] = self.spheres[f as usize];
            let d = sub(c, [x, y, z]);
            if dot(d, d) <= (reach + r).powi(2) {
                let (lower, plane) = self.bounds[f as usize].farthest(c);
                if lower <= reach {
                    out.push(Entry { lower, face: f, plane });
                }
            }
            out.len() <= MAX_SHORTLIST
        });
        out.sort_unstable_by(|a, b| a.lower.total_cmp(&b.lower).then(a.face.cmp(&b.face)));
        complete
    }
}

pub(crate) fn largest_coordinate(points: &[[f64; 3]]) -> f64 {
    points.par_iter().map(|p| p[0].abs().max(p[1].abs()).max(p[2].abs())).reduce(|| 0.0, f64::max)
}

fn bounding_sphere(t: [[f64; 3]; 3]) -> [f64; 4] {
    let c = scale(add(add(t[0], t[1]), t[2]), 1.0 / 3.0);
    let r = t.iter().map(|&p| norm(sub(p, c))).fold(0.0, f64::max);
    [c[0], c[1], c[2], r]
}

/// Finds the closest source points of queries one after another, exploiting that consecutive
/// queries lie close together (texels of a band, in transfer).
///
/// It keeps a shortlist: every source triangle within `radius` of a `centre`, with a lower
/// bound on its distance from the centre, nearest first. For a query `q` at `delta` from the
/// centre, a triangle as close to `q` as the best one found (at `d`) lies within `delta + d`
/// of the centre; so if that is within the radius, the shortlist holds every candidate, and
/// the scan may stop at the first bound beyond `delta + d`. Otherwise the shortlist is made
/// anew around `q`, from the source grid. The answers are those of [`Bvh::closest_point`] on
/// the whole source, tie-breaking included: the same distance code runs over every triangle
/// that could win.
pub(crate) struct Finder<'a> {
    source: &'a Source,
    span: f64,
    /// Ascending by lower bound.
    shortlist: Vec<Entry>,
    centre: [f64; 3],
    radius: f64,
    /// The source face of the last answer, tried first.
    hint: Option<u32>,
    /// Queries left to send straight to the whole source's Bvh, after listing failed.
    cooldown: u32,
    seen: Seen,
}

/// Queries sent straight to the Bvh after a failed listing, before listing is tried again:
/// where the queries are far from the source, every one would otherwise list in vain.
const COOLDOWN: u32 = 64;

impl<'a> Finder<'a> {
    pub fn new(source: &'a Source, span: f64) -> Self {
        let (shortlist, hint, seen) = (Vec::new(), None, Seen::new(source.tris.len()));
        let (centre, radius, cooldown) = ([0.0; 3], f64::NEG_INFINITY, 0);
        Self { source, span, shortlist, centre, radius, hint, cooldown, seen }
    }

    /// The closest point of the source to `q`; `None` only for an empty source.
    pub fn closest(&mut self, q: [f64; 3]) -> Option<Hit> {
        if self.cooldown == 0 {
            let (hit, certain) = self.scan(q);
            if certain {
                return hit;
            }
            let upper = match hit {
                Some(h) => h.dist2.sqrt(),
                None => self.source.bvh.closest_point(q)?.dist2.sqrt(),
            };
            if self.renew(q, upper) {
                return self.scan(q).0;
            }
            self.cooldown = COOLDOWN;
        }
        self.cooldown -= 1;
        let hit = self.source.hit(q, self.source.bvh.closest_point(q)?.triangle);
        self.hint = Some(hit.triangle);
        Some(hit)
    }

    /// The best of the shortlist for `q`, and whether it is sure to be the best of all. The
    /// last answer is tried first: the next query mostly has the same, and its distance then
    /// rules out most other triangles of the list by their bounds alone.
    fn scan(&mut self, q: [f64; 3]) -> (Option<Hit>, bool) {
        let (source, eps) = (self.source, self.source.eps);
        let delta = norm(sub(q, self.centre));
        let mut best: Option<Hit> = self.hint.map(|h| source.hit(q, h));
        let mut best_dist = best.map_or(f64::INFINITY, |b| b.dist2.sqrt());
        for e in &self.shortlist {
            if e.lower - delta > best_dist + eps {
                break;
            }
            let f = e.face;
            let beyond = |d: f64| d > best_dist + eps;
            if Some(f) == self.hint || beyond(plane_side(e.plane, q)) || beyond(source.lower(f, q)) {
                continue;
            }
            let hit = source.hit(q, f);
            if best.map_or(true, |b| hit.dist2 < b.dist2 || (hit.dist2 == b.dist2 && f < b.triangle)) {
                best = Some(hit);
                best_dist = hit.dist2.sqrt();
            }
        }
        self.hint = best.map(|b| b.triangle);
        (best, !self.shortlist.is_empty() && delta + best_dist <= self.radius - eps)
    }

    /// Lists the triangles within `upper + span` of `q`, `upper` being the distance from `q`
    /// to some source triangle (so that one at least is listed). Where the source is dense,
    /// lists less far; `false` if even that is too many.
    fn renew(&mut self, q: [f64; 3], upper: f64) -> bool {
        for span in [self.span, self.span / 8.0] {
            let radius = upper + span;
            let eps = self.source.eps;
            if self.source.shortlist(&mut self.seen, q, radius + eps, &mut self.shortlist) {
                (self.centre, self.radius) = (q, radius);
                return true;
            }
        }
        self.radius = f64::NEG_INFINITY;
        false
    }
}

/// A triangle of a `Finder`'s shortlist.
struct Entry {
    /// A lower bound on its distance from the shortlist's centre.
    lower: f64,
    face: u32,
    /// The plane of its `Bound` farthest from the centre: one plane, a yet cheaper bound
    /// for points nearby.
    plane: [f64; 4],
}

/// Shortlisted triangles beyond which listing costs more than it saves: the queries then go
/// to the whole source's Bvh.
const MAX_SHORTLIST: usize = 1024;
/// Grid cells a listing may visit, for the same reason.
const MAX_LIST_CELLS: usize = 4096;

/// Marks the faces already met during one listing, without clearing between listings.
struct Seen {
    stamp: Vec<u32>,
    now: u32,
}

impl Seen {
    fn new(n: usize) -> Self {
        Self { stamp: vec![0; n], now: 0 }
    }

    fn next(&mut self) {
        self.now = self.now.wrapping_add(1);
        if self.now == 0 {
            self.stamp.fill(0);
            self.now = 1;
        }
    }

    /// Whether `f` is met for the first time in this listing.
    fn first(&mut self, f: u32) -> bool {
        std::mem::replace(&mut self.stamp[f as usize], self.now) != self.now
    }
}

/// Half-spaces that hold a triangle: the two sides of a slab around its plane and the three
/// half-spaces of its edges (unit normals). The farthest of their planes from a point is a
/// lower bound on the distance to the triangle, about as tight as the distance itself except
/// off the corners, for a fifth of its cost. Built from the triangle's own corners, so that it
/// holds for degenerate triangles too (where it is only weaker).
struct Bound {
    /// `(n, o)`: the half-space `n · x <= o`.
    planes: [[f64; 4]; 5],
}

impl Bound {
    fn new(t: [[f64; 3]; 3]) -> Self {
        let normal = normalize(cross(sub(t[1], t[0]), sub(t[2], t[0])));
        let holding = |n: [f64; 3]| {
            let o = t.iter().map(|&p| dot(n, p)).fold(f64::NEG_INFINITY, f64::max);
            [n[0], n[1], n[2], o]
        };
        let edge = |i: usize| holding(normalize(cross(sub(t[(i + 1) % 3], t[i]), normal)));
        Self { planes: [holding(normal), holding(scale(normal, -1.0)), edge(0), edge(1), edge(2)] }
    }

    /// The plane of half-space `k` as seen from `q`: positive outside.
    fn side(&self, k: usize, q: [f64; 3]) -> f64 {
        plane_side(self.planes[k], q)
    }

    fn lower(&self, q: [f64; 3]) -> f64 {
        (1..5).fold(self.side(0, q), |d, k| d.max(self.side(k, q)))
    }

    /// The half-space whose plane is farthest from `q`, and that distance (the bound).
    fn farthest(&self, q: [f64; 3]) -> (f64, [f64; 4]) {
        let sides = [0, 1, 2, 3, 4].map(|k| self.side(k, q));
        let k = (1..5).fold(0, |b, k| if sides[k] > sides[b] { k } else { b });
        (sides[k], self.planes[k])
    }
}

fn plane_side(p: [f64; 4], q: [f64; 3]) -> f64 {
    p[0] * q[0] + p[1] * q[1] + p[2] * q[2] - p[3]
}

fn mean_edge(tris: &[[[f64; 3]; 3]]) -> f64 {
    let total: f64 = tris.par_iter().map(|[a, b, c]| norm(sub(*b, *a)) + norm(sub(*c, *b)) + norm(sub(*a, *c))).sum();
    total / (3 * tris.len().max(1)) as f64
}

type Aabb = ([f64; 3], [f64; 3]);

fn box_dist2((lo, hi): &Aabb, q: [f64; 3]) -> f64 {
    (0..3).map(|k| (lo[k] - q[k]).max(q[k] - hi[k]).max(0.0).powi(2)).sum()
}

/// Cells a grid may have (and entries beyond 16 per triangle): enough for triangle-sized
/// cells on meshes of a few 100k triangles, few enough to build in milliseconds whatever the
/// mesh's shape.
const MAX_CELLS: f64 = 4_000_000.0;

/// The source triangles bucketed by the cells of a uniform grid that their bounding boxes
/// overlap: the query for all triangles near a ball, which the `Finder` needs and [`Bvh`]
/// does not offer.
struct FaceGrid {
    lo: [f64; 3],
    cell: f64,
    dims: [usize; 3],
    /// Cell `i` holds `faces[starts[i]..starts[i + 1]]`.
    starts: Vec<u32>,
    faces: Vec<u32>,
    /// Bounding box of each source face.
    boxes: Vec<Aabb>,
}

impl FaceGrid {
    /// A grid over triangles `tris`, with cells about `edge` across.
    fn new(tris: &[[[f64; 3]; 3]], edge: f64) -> Self {
        let boxes: Vec<Aabb> = tris.iter().map(|&t| triangle_box(t)).collect();
        let (lo, hi) = boxes.iter().fold(([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]), |(lo, hi), b| {
            ([0, 1, 2].map(|k| lo[k].min(b.0[k])), [0, 1, 2].map(|k| hi[k].max(b.1[k])))
        });
        let extent = [0, 1, 2].map(|k| (hi[k] - lo[k]).max(0.0));
        let largest = extent.iter().fold(0.0f64, |m, &e| m.max(e));
        // Cells about a triangle across, but at most ~1000 along an axis and MAX_CELLS in
        // all, so a mesh of tiny triangles spread far apart cannot blow up the grid.
        let mut cell = edge.max(largest / 1024.0);
        if cell.is_nan() || cell <= 0.0 {
            cell = 1.0;
        }
        // Nor may a few huge triangles among many small ones fill the cells with entries.
        let cells = |cell: f64| extent.iter().map(|e| (e / cell).floor() + 1.0).product::<f64>();
        let entries = |cell: f64| -> f64 {
            boxes.iter().map(|(lo, hi)| (0..3).map(|k| (hi[k] - lo[k]) / cell + 2.0).product::<f64>()).sum()
        };
        let budget = MAX_CELLS + 16.0 * tris.len() as f64;
        while cells(cell) > MAX_CELLS || entries(cell) > budget {
            cell *= 1.25;
        }
        let dims = extent.map(|e| (e / cell) as usize + 1);
        let mut grid = Self { lo, cell, dims, starts: Vec::new(), faces: Vec::new(), boxes };
        grid.fill();
        grid
    }

    /// Buckets the faces by cell (counting sort: count, prefix sums, place).
    fn fill(&mut self) {
        let mut starts = vec![0u32; self.dims.iter().product::<usize>() + 1];
        for b in &self.boxes {
            self.for_cells(b, |c| starts[c + 1] += 1);
        }
        for c in 1..starts.len() {
            starts[c] += starts[c - 1];
        }
        let mut next = starts.clone();
        let mut faces = vec![0u32; *starts.last().unwrap_or(&0) as usize];
        for (f, b) in self.boxes.iter().enumerate() {
            self.for_cells(b, |c| {
                faces[next[c] as usize] = f as u32;
                next[c] += 1;
            });
        }
        (self.starts, self.faces) = (starts, faces);
    }

    /// The cell range along each axis that the box `[lo, hi]` overlaps (clamped to the grid).
    fn cell_range(&self, lo: [f64; 3], hi: [f64; 3]) -> [Range<usize>; 3] {
        let at = |k: usize, x: f64| (((x - self.lo[k]) / self.cell).floor().max(0.0) as usize).min(self.dims[k] - 1);
        [0, 1, 2].map(|k| at(k, lo[k])..at(k, hi[k]) + 1)
    }

    fn for_cells(&self, b: &Aabb, mut visit: impl FnMut(usize)) {
        let [xs, ys, zs] = self.cell_range(b.0, b.1);
        for z in zs {
            for y in ys.clone() {
                for x in xs.clone() {
                    visit((z * self.dims[1] + y) * self.dims[0] + x);
                }
            }
        }
    }

    /// Calls `visit` once on each face whose bounding box comes within `radius` of `centre`,
    /// while it returns `true`; `false` if it returned `false` or there were too many cells to
    /// visit.
    fn visit(&self, centre: [f64; 3], radius: f64, seen: &mut Seen, mut visit: impl FnMut(u32) -> bool) -> bool {
        let b = (centre.map(|c| c - radius), centre.map(|c| c + radius));
        let count: usize = self.cell_range(b.0, b.1).iter().map(|r| r.len()).product();
        if count > MAX_LIST_CELLS {
            return false;
        }
        seen.next();
        let mut going = true;
        self.for_cells(&b, |c| {
            for &f in &self.faces[self.starts[c] as usize..self.starts[c + 1] as usize] {
                if going && seen.first(f) && box_dist2(&self.boxes[f as usize], centre) <= radius * radius {
                    going = visit(f);
                }
            }
        });
        going
    }
}

fn triangle_box(c: [[f64; 3]; 3]) -> Aabb {
    let lo = [0, 1, 2].map(|k| c[0][k].min(c[1][k]).min(c[2][k]));
    let hi = [0, 1, 2].map(|k| c[0][k].max(c[1][k]).max(c[2][k]));
    (lo, hi)
}


#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::testmesh::{grid, uv_sphere, Rng};
    use crate::geom::mesh::interpolate;

    #[test]
    fn closest_points_and_barycentrics_of_proper_and_degenerate_triangles() {
        let tri = [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]];
        let (p, d2, w) = closest_on_triangle([0.5, 1.0, 3.0], tri);
        assert_eq!((p, d2), ([0.5, 1.0, 0.0], 9.0));
        assert!((w[0] - 0.25).abs() < 1e-12 && (w[1] - 0.25).abs() < 1e-12 && (w[2] - 0.5).abs() < 1e-12);
        assert_eq!(closest_on_triangle([3.0, 3.0, 0.0], tri).2, [0.0, 0.5, 0.5]);
        assert_eq!(closest_on_triangle([-1.0, -1.0, 0.0], tri).2, [1.0, 0.0, 0.0]);
        let line = [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.0, 0.0, 0.0]];
        let (p, _, w) = closest_on_triangle([0.5, 1.0, 0.0], line);
        assert_eq!(p, [0.5, 0.0, 0.0]);
        assert_eq!(interpolate(line, w), p);
        assert_eq!(closest_on_triangle([1.0, 2.0, 1.0], [[1.0; 3]; 3]).2, [1.0, 0.0, 0.0]);
        // The bound never exceeds the distance, for proper and degenerate triangles.
        let mut rng = Rng(17);
        for t in [tri, line, [[1.0; 3]; 3], [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [0.3, -2.0, 0.5]]] {
            let b = Bound::new(t);
            for _ in 0..1000 {
                let q = rng.point(-3.0, 3.0);
                assert!(b.lower(q) <= closest_on_triangle(q, t).1.sqrt() + 1e-12, "{t:?} {q:?}");
            }
        }
    }

    #[test]
    fn finder_agrees_with_the_bvh_near_and_far() {
        // A dense patch (more triangles than a gathering may hold) inside a coarse sphere, and
        // queries that walk near the patch, then jump far off (where gathering fails too).
        let (mut pos, mut faces) = uv_sphere(12, 24, |th, ph| 1.0 + 0.05 * (4.0 * th).sin() * (6.0 * ph).cos());
        let (p2, f2) = grid(60, 60, 0.004, [0.2, 0.2, 0.0]);
        let n = pos.len() as u32;
        pos.extend(p2);
        faces.extend(f2.iter().map(|f| f.map(|v| v + n)));
        let source = Source::new(&Mesh::new(pos, faces), 10.0);
        let mut finder = Finder::new(&source, 0.02);
        let mut rng = Rng(29);
        let mut q = [0.3, 0.3, 0.01];
        for i in 0..20_000 {
            q = match i % 4000 {
                0 => [0.3, 0.3, 0.001],
                1999 => rng.point(-3.0, 3.0),
                _ => add(q, rng.point(-0.01, 0.01)),
            };
            let got = finder.closest(q).unwrap();
            let want = source.hit(q, source.bvh.closest_point(q).unwrap().triangle);
            assert_eq!(got, want, "query {i} at {q:?}");
        }
    }
}
