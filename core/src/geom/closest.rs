//! Closest points of a triangle surface for a walk of queries that lie close to it.
//!
//! [`Bvh::closest_point`] answers one query from the root of the hierarchy. Texture transfer
//! asks millions, each next to the one before and, the reconstruction being close to the input,
//! mostly within a small fraction of a triangle of the source surface. A `Finder` measures the
//! triangle of its last answer first: the distance `d` to it bounds the search to the cube of
//! half-side `d` around the query, which mostly lies within one cell of a uniform grid of the
//! triangles (`FaceGrid`). Each entry of a cell carries a mask of the 4 x 4 x 4 sub-cells that its
//! triangle's bounding box overlaps, so that only the triangles near that cube are bounded
//! (`Bound`), and only those that may be as near are measured. Where the cube spans more cells
//! (the walk jumped to another part of the surface, or the source is far), the search visits
//! ever larger cubes around the query, from one sub-cell; a query too far from the source for
//! that (and the next few, which mostly are too) is left to [`Source::closest_far`], which asks
//! a Bvh of the whole source.
//!
//! The answers are exactly the Bvh's, tie-breaking included (the nearest triangle, and the
//! lowest index among equally near ones), with the barycentrics of the closest point: the same
//! distance code runs over every triangle that could win, and the filters before it only skip
//! triangles that are provably farther.

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
pub(crate) struct Source<'a> {
    mesh: &'a Mesh,
    grid: FaceGrid,
    /// Each face, ready for measuring.
    tris: Vec<Triangle>,
    bounds: Vec<Bound>,
    /// Absolute slack on distance comparisons, against rounding (whose error grows with the
    /// coordinates' magnitude).
    eps: f64,
}

impl<'a> Source<'a> {
    /// Prepares `mesh` for queries from points whose coordinates are at most `magnitude`
    /// (together with the mesh's own, this sets the slack against rounding).
    pub fn new(mesh: &'a Mesh, magnitude: f64) -> Self {
        let corners = |f: usize| mesh.faces[f].map(|v| mesh.positions[v as usize]);
        let n = mesh.faces.len();
        // The grid's counting sort runs on one thread: beside the rest.
        let edge = mean_edge(n, corners);
        let ((tris, bounds), grid) = rayon::join(
            || (0..n).into_par_iter().map(|f| (Triangle::new(corners(f)), Bound::new(corners(f)))).unzip(),
            || FaceGrid::new(n, corners, edge),
        );
        let eps = 1e-12 * (1.0 + magnitude.max(largest_coordinate(&mesh.positions)));
        Self { mesh, grid, tris, bounds, eps }
    }

    /// The closest point to `q` of source face `face`.
    fn hit(&self, q: [f64; 3], face: u32) -> Hit {
        let (dist2, bary) = self.tris[face as usize].closest(q);
        Hit { triangle: face, bary, dist2 }
    }

    /// Whether face `face` must be measured against `best` for query `q`: it may be as near
    /// (bounds within the slack); `best.triangle` itself need not be.
    fn may_beat(&self, face: u32, q: [f64; 3], best: &Hit, reach: f64) -> bool {
        face != best.triangle && !self.bounds[face as usize].beyond(q, reach)
    }

    /// `best`, or the hit of `face` if that is nearer, or as near with a lower index.
    fn better(&self, q: [f64; 3], face: u32, best: &mut Hit) {
        let hit = self.hit(q, face);
        if hit.dist2 < best.dist2 || (hit.dist2 == best.dist2 && face < best.triangle) {
            *best = hit;
        }
    }

    /// The closest points of `queries` (those a [`Finder`] left, in any number), from a Bvh of
    /// the whole source built for them; `None` for an empty source.
    pub fn closest_far(&self, queries: &[[f64; 3]]) -> Vec<Option<Hit>> {
        if queries.is_empty() {
            return Vec::new();
        }
        let bvh = Bvh::new(&self.mesh.positions, &self.mesh.faces);
        queries.par_iter().map(|&q| Some(self.hit(q, bvh.closest_point(q)?.triangle))).collect()
    }
}

pub(crate) fn largest_coordinate(points: &[[f64; 3]]) -> f64 {
    points.par_iter().map(|p| p[0].abs().max(p[1].abs()).max(p[2].abs())).reduce(|| 0.0, f64::max)
}

/// Finds the closest source points of queries one after another, exploiting that consecutive
/// queries lie close together and close to the source (texels of a band, in transfer).
pub(crate) struct Finder<'a> {
    source: &'a Source<'a>,
    /// The source face of the last answer, measured first.
    hint: Option<u32>,
    /// Queries left to give up at once, after one was too far: the next ones mostly are too.
    cooldown: u32,
}

/// Queries given up after one too far for the grid, before the grid is tried again.
const COOLDOWN: u32 = 64;

/// Grid cells the cube around a query may span for the masked search; beyond, the cube is far
/// larger than the sub-cells and the masks would not pay.
const MAX_QUERY_CELLS: usize = 8;
/// Grid cells the widening search's cube may span before the query is given up to the Bvh: a
/// query this far (a few triangles) from the source is rare, and costs less there.
const MAX_SEARCH_CELLS: usize = 512;

impl<'a> Finder<'a> {
    pub fn new(source: &'a Source<'a>) -> Self {
        Self { source, hint: None, cooldown: 0 }
    }

    /// The closest point of the source to `q`, or `None` if `q` is too far from the source
    /// for the grid (or follows such a query closely, or its distance overflows):
    /// [`Source::closest_far`] then answers it.
    pub fn closest(&mut self, q: [f64; 3]) -> Option<Hit> {
        if self.cooldown > 0 {
            self.cooldown -= 1;
            return None;
        }
        let (source, grid) = (self.source, &self.source.grid);
        let start = self.hint.map(|t| source.hit(q, t));
        // Every triangle that may beat the last answer meets the cube of half-side `limit`:
        // when that cube spans few cells, one masked search settles the query.
        let limit = start.map_or(f64::INFINITY, |b| b.dist2.sqrt() + source.eps);
        let cube = grid.cube(q, limit);
        let found = match start {
            Some(start) if cells(&cube) <= MAX_QUERY_CELLS => self.masked(q, start, &cube),
            _ => match self.widening(q, start, limit) {
                Some(hit) => hit,
                None => {
                    self.cooldown = COOLDOWN;
                    return None;
                }
            },
        };
        self.hint = Some(found.triangle);
        // A distance that overflowed or is NaN (coordinates near the largest floats) settles
        // nothing here: the Bvh's own comparisons decide such a query.
        found.dist2.is_finite().then_some(found)
    }

    /// The best of `best` and the triangles whose boxes meet the sub-cells `cube` around `q`:
    /// the closest point if it lies in that cube.
    fn masked(&self, q: [f64; 3], mut best: Hit, cube: &Span) -> Hit {
        let source = self.source;
        let mut reach = best.dist2.sqrt() + source.eps;
        source.grid.for_entries(cube, |faces, masks, mask| {
            for (&f, &m) in faces.iter().zip(masks) {
                if m & mask != 0 && source.may_beat(f, q, &best, reach) {
                    source.better(q, f, &mut best);
                    reach = best.dist2.sqrt() + source.eps;
                }
            }
        });
        best
    }

    /// The first triangle whose box meets the sub-cells `cube`: a start for `masked`.
    fn first(&self, q: [f64; 3], cube: &Span) -> Option<Hit> {
        let mut first = None;
        self.source.grid.for_entries(cube, |faces, masks, mask| {
            if first.is_none() {
                first = faces.iter().zip(masks).find(|&(_, &m)| m & mask != 0).map(|(&f, _)| f);
            }
        });
        first.map(|f| self.source.hit(q, f))
    }

    /// The closest point by searches of ever larger cubes around `q`, from a sub-cell up to
    /// `limit` (`start`'s distance): it ends when the best found lies within the cube
    /// searched, so that every triangle as near met it. The first cube is searched with the
    /// masks; each later one visits the cells that no unmasked search visited before, measuring
    /// against the best so far (which only improves, so what it skipped stays beaten). `None`
    /// if the cube grows beyond `MAX_SEARCH_CELLS` cells first.
    fn widening(&self, q: [f64; 3], start: Option<Hit>, limit: f64) -> Option<Hit> {
        let (source, grid) = (self.source, &self.source.grid);
        let done = |best: &Option<Hit>, half: f64| best.is_some_and(|b| b.dist2.sqrt() + source.eps <= half);
        let half = grid.fine.min(limit);
        let cube = grid.cube(q, half);
        let mut best = start.or_else(|| self.first(q, &cube)).map(|b| self.masked(q, b, &cube));
        if half >= limit || done(&best, half) {
            return best;
        }
        let mut seen: Option<Span> = None;
        let mut side = 2.0 * half;
        loop {
            let half = side.min(limit);
            side *= 2.0;
            let cube = grid.cube(q, half);
            if cells(&cube) > MAX_SEARCH_CELLS {
                return None;
            }
            let span = cube.map(|[a, b]| [a / SUB, b / SUB]);
            for z in span[2][0]..=span[2][1] {
                for y in span[1][0]..=span[1][1] {
                    for x in span[0][0]..=span[0][1] {
                        let old = seen.is_some_and(|s| [x, y, z].iter().zip(&s).all(|(&c, r)| r[0] <= c && c <= r[1]));
                        if old {
                            continue;
                        }
                        for &f in grid.entries(grid.cell_index(x, y, z)) {
                            match &mut best {
                                Some(b) => {
                                    let reach = b.dist2.sqrt() + source.eps;
                                    if source.may_beat(f, q, b, reach) {
                                        source.better(q, f, b);
                                    }
                                }
                                None => best = Some(source.hit(q, f)),
                            }
                        }
                    }
                }
            }
            seen = Some(span);
            let whole = (0..3).all(|k| cube[k] == [0, grid.last[k]]);
            if half >= limit || whole || done(&best, half) {
                return best;
            }
        }
    }
}

/// A source triangle with what [`closest_on_triangle`] computes of it before looking at the
/// query, computed once: its answers, exactly.
struct Triangle {
    corners: [[f64; 3]; 3],
    ab: [f64; 3],
    ac: [f64; 3],
    /// Degenerate by `closest_on_triangle`'s test (which then measures the edges).
    degenerate: bool,
}

impl Triangle {
    fn new(corners: [[f64; 3]; 3]) -> Self {
        let [a, b, c] = corners;
        let (ab, ac) = (sub(b, a), sub(c, a));
        let n = cross(ab, ac);
        Self { corners, ab, ac, degenerate: dot(n, n) <= 1e-20 * dot(ab, ab) * dot(ac, ac) }
    }

    /// Squared distance from `p` and barycentrics of the closest point: those of
    /// [`closest_on_triangle`], whose proper case this repeats operation for operation (the
    /// region tests of Ericson's *Real-Time Collision Detection*, 5.1.5).
    fn closest(&self, p: [f64; 3]) -> (f64, [f64; 3]) {
        if !self.degenerate {
            let (point, bary) = self.closest_proper(p);
            if point.iter().all(|x| x.is_finite()) {
                let d = sub(point, p);
                return (dot(d, d), bary);
            }
        }
        let (_, dist2, bary) = closest_on_triangle(p, self.corners);
        (dist2, bary)
    }

    fn closest_proper(&self, p: [f64; 3]) -> ([f64; 3], [f64; 3]) {
        let ([a, b, c], ab, ac) = (self.corners, self.ab, self.ac);
        let ap = sub(p, a);
        let (d1, d2) = (dot(ab, ap), dot(ac, ap));
        if d1 <= 0.0 && d2 <= 0.0 {
            return (a, [1.0, 0.0, 0.0]);
        }
        let bp = sub(p, b);
        let (d3, d4) = (dot(ab, bp), dot(ac, bp));
        if d3 >= 0.0 && d4 <= d3 {
            return (b, [0.0, 1.0, 0.0]);
        }
        let vc = d1 * d4 - d3 * d2;
        if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
            let t = d1 / (d1 - d3);
            return (add(a, scale(ab, t)), [1.0 - t, t, 0.0]);
        }
        let cp = sub(p, c);
        let (d5, d6) = (dot(ab, cp), dot(ac, cp));
        if d6 >= 0.0 && d5 <= d6 {
            return (c, [0.0, 0.0, 1.0]);
        }
        let vb = d5 * d2 - d1 * d6;
        if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
            let t = d2 / (d2 - d6);
            return (add(a, scale(ac, t)), [1.0 - t, 0.0, t]);
        }
        let va = d3 * d6 - d5 * d4;
        if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
            let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
            return (add(b, scale(sub(c, b), w)), [0.0, 1.0 - w, w]);
        }
        let denom = 1.0 / (va + vb + vc);
        let (v, w) = (vb * denom, vc * denom);
        (add(a, add(scale(ab, v), scale(ac, w))), [1.0 - v - w, v, w])
    }
}

/// Half-spaces that hold a triangle: the two sides of a slab around its plane and the three
/// half-spaces of its edges (unit normals). The farthest of their planes from a point is a
/// lower bound on the distance to the triangle, about as tight as the distance itself except
/// off the corners, for a fifth of its cost. Built from the triangle's own corners, so that it
/// holds for degenerate triangles too (where it is only weaker).
struct Bound {
    /// Plane `i` is the half-space `n[0][i] x + n[1][i] y + n[2][i] z <= o[i]`; stored by
    /// coordinate, and the first repeated as a sixth, so that they are tested in pairs.
    n: [[f64; 6]; 3],
    o: [f64; 6],
}

impl Bound {
    fn new(t: [[f64; 3]; 3]) -> Self {
        let normal = normalize(cross(sub(t[1], t[0]), sub(t[2], t[0])));
        let holding = |n: [f64; 3]| {
            let o = t.iter().map(|&p| dot(n, p)).fold(f64::NEG_INFINITY, f64::max);
            [n[0], n[1], n[2], o]
        };
        let edge = |i: usize| holding(normalize(cross(sub(t[(i + 1) % 3], t[i]), normal)));
        let planes = [holding(normal), holding(scale(normal, -1.0)), edge(0), edge(1), edge(2), holding(normal)];
        Self { n: [0, 1, 2].map(|k| planes.map(|p| p[k])), o: planes.map(|p| p[3]) }
    }

    /// Whether `q` lies farther than `reach` outside one of the planes, so that the triangle
    /// is farther than `reach` from it. (Any NaN only keeps a triangle in.)
    #[inline]
    fn beyond(&self, q: [f64; 3], reach: f64) -> bool {
        let mut out = false;
        for i in 0..6 {
            out |= self.n[0][i] * q[0] + self.n[1][i] * q[1] + self.n[2][i] * q[2] - self.o[i] > reach;
        }
        out
    }

    /// The distance from `q` to the farthest of the planes, on their outer side: a lower
    /// bound on the distance to the triangle.
    #[cfg(test)]
    fn lower(&self, q: [f64; 3]) -> f64 {
        (0..6).map(|i| self.n[0][i] * q[0] + self.n[1][i] * q[1] + self.n[2][i] * q[2] - self.o[i]).fold(f64::NEG_INFINITY, f64::max)
    }
}

/// The mean edge length of the `n` triangles whose corners `corners` gives.
fn mean_edge(n: usize, corners: impl Fn(usize) -> [[f64; 3]; 3] + Sync) -> f64 {
    let total: f64 = (0..n).into_par_iter().map(&corners).map(|[a, b, c]| norm(sub(b, a)) + norm(sub(c, b)) + norm(sub(a, c))).sum();
    total / (3 * n.max(1)) as f64
}

type Aabb = ([f64; 3], [f64; 3]);

/// Cells a grid may have (and entries beyond 16 per triangle): enough for triangle-sized
/// cells on meshes of a few 100k triangles, few enough to build in milliseconds whatever the
/// mesh's shape.
const MAX_CELLS: f64 = 4_000_000.0;

/// Sub-cells of a grid cell along each axis: 4, so that a cell's 64 fit the bits of a `u64`.
const SUB: usize = 4;

/// The bits of the sub-cells (bit `x + 4 y + 16 z`) whose coordinate along `axis` lies in
/// `lo..=hi`, for every axis and range.
const AXIS_BITS: [[[u64; SUB]; SUB]; 3] = axis_bits();

const fn axis_bits() -> [[[u64; SUB]; SUB]; 3] {
    let mut table = [[[0u64; SUB]; SUB]; 3];
    let mut axis = 0;
    while axis < 3 {
        let mut lo = 0;
        while lo < SUB {
            let mut hi = lo;
            while hi < SUB {
                let mut bits = 0u64;
                let mut i = 0;
                while i < SUB * SUB * SUB {
                    let s = [i % SUB, i / SUB % SUB, i / (SUB * SUB)][axis];
                    if lo <= s && s <= hi {
                        bits |= 1 << i;
                    }
                    i += 1;
                }
                table[axis][lo][hi] = bits;
                hi += 1;
            }
            lo += 1;
        }
        axis += 1;
    }
    table
}

/// Inclusive ranges of sub-cells along each axis: `[first, last]`.
type Span = [[usize; 2]; 3];

/// Cells that the sub-cells `span` meet.
fn cells(span: &Span) -> usize {
    span.iter().map(|&[a, b]| b / SUB - a / SUB + 1).product()
}

/// The source triangles bucketed by the cells of a uniform grid that their bounding boxes
/// overlap, each entry with the mask of the cell's 4 x 4 x 4 sub-cells that the box overlaps.
/// Positions map to sub-cells by one monotone function (`FaceGrid::fine`) for the boxes and for
/// the queries, so a box that meets a query's cube always shares a sub-cell with it.
struct FaceGrid {
    lo: [f64; 3],
    /// Side of a sub-cell, and its inverse.
    fine: f64,
    per_fine: f64,
    /// Cells along each axis, and the last sub-cell index.
    dims: [usize; 3],
    last: [usize; 3],
    /// Cell `i` holds `faces[starts[i]..starts[i + 1]]`, with their `masks`.
    starts: Vec<u32>,
    faces: Vec<u32>,
    masks: Vec<u64>,
}

impl FaceGrid {
    /// A grid over the `n` triangles whose corners `corners` gives, with cells about `edge`
    /// across.
    fn new(n: usize, corners: impl Fn(usize) -> [[f64; 3]; 3] + Sync, edge: f64) -> Self {
        let bounds = |f: usize| triangle_box(corners(f));
        let (lo, hi) = (0..n).into_par_iter().map(bounds).reduce(
            || ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
            |a, b| ([0, 1, 2].map(|k| a.0[k].min(b.0[k])), [0, 1, 2].map(|k| a.1[k].max(b.1[k]))),
        );
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
            (0..n).into_par_iter().map(|f| {
                let (lo, hi) = bounds(f);
                (0..3).map(|k| (hi[k] - lo[k]) / cell + 2.0).product::<f64>()
            }).sum()
        };
        let budget = MAX_CELLS + 16.0 * n as f64;
        while cells(cell) > MAX_CELLS || entries(cell) > budget {
            cell *= 1.25;
        }
        let dims = extent.map(|e| (e / cell) as usize + 1);
        let fine = cell / SUB as f64;
        let (starts, faces, masks) = (Vec::new(), Vec::new(), Vec::new());
        let last = dims.map(|n| n * SUB - 1);
        let mut grid = Self { lo, fine, per_fine: 1.0 / fine, dims, last, starts, faces, masks };
        grid.fill(n, bounds);
        grid
    }

    /// Buckets the `n` faces with bounding boxes `bounds` by cell (counting sort: count, sum,
    /// place from the ends, the faces in reverse so that each cell lists its own in increasing
    /// order).
    fn fill(&mut self, n: usize, bounds: impl Fn(usize) -> Aabb) {
        let span = |f: usize| {
            let (lo, hi) = bounds(f);
            self.span(lo, hi)
        };
        let cells = self.dims.iter().product::<usize>();
        let mut starts = vec![0u32; cells + 1];
        for f in 0..n {
            let s = span(f);
            for z in s[2][0] / SUB..=s[2][1] / SUB {
                for y in s[1][0] / SUB..=s[1][1] / SUB {
                    let row = self.cell_index(0, y, z);
                    starts[row + s[0][0] / SUB..=row + s[0][1] / SUB].iter_mut().for_each(|c| *c += 1);
                }
            }
        }
        for c in 1..cells {
            starts[c] += starts[c - 1];
        }
        let total = starts[cells.saturating_sub(1)] as usize;
        starts[cells] = total as u32;
        let (mut faces, mut masks) = (vec![0u32; total], vec![0u64; total]);
        for f in (0..n).rev() {
            self.for_cells(&span(f), |c, mask| {
                starts[c] -= 1;
                faces[starts[c] as usize] = f as u32;
                masks[starts[c] as usize] = mask;
            });
        }
        (self.starts, self.faces, self.masks) = (starts, faces, masks);
    }

    /// The sub-cell index along axis `k` of coordinate `x`, clamped to the grid: a monotone
    /// function of `x` (truncation, not floor, and a NaN maps to 0), which is all the search
    /// needs, and cheaper than `f64::floor`'s library call on baseline x86-64.
    #[inline]
    fn fine(&self, k: usize, x: f64) -> usize {
        (((x - self.lo[k]) * self.per_fine) as i64).clamp(0, self.last[k] as i64) as usize
    }

    /// The sub-cells that the box `[lo, hi]` overlaps.
    #[inline]
    fn span(&self, lo: [f64; 3], hi: [f64; 3]) -> Span {
        [[self.fine(0, lo[0]), self.fine(0, hi[0])], [self.fine(1, lo[1]), self.fine(1, hi[1])], [self.fine(2, lo[2]), self.fine(2, hi[2])]]
    }

    /// The sub-cells of the cube of half-side `half` around `q`.
    #[inline]
    fn cube(&self, q: [f64; 3], half: f64) -> Span {
        self.span([q[0] - half, q[1] - half, q[2] - half], [q[0] + half, q[1] + half, q[2] + half])
    }

    /// Calls `visit` on each cell that the sub-cells `span` meet, with the mask of those of
    /// its sub-cells.
    #[inline]
    fn for_cells(&self, span: &Span, mut visit: impl FnMut(usize, u64)) {
        // The sub-cells of `span` along axis `k` within cell `c`, as bits.
        let bits = |k: usize, c: usize| {
            let [first, last] = span[k];
            let base = c * SUB;
            AXIS_BITS[k][first.max(base) - base][last.min(base + SUB - 1) - base]
        };
        for z in span[2][0] / SUB..=span[2][1] / SUB {
            let bz = bits(2, z);
            for y in span[1][0] / SUB..=span[1][1] / SUB {
                let byz = bits(1, y) & bz;
                for x in span[0][0] / SUB..=span[0][1] / SUB {
                    visit(self.cell_index(x, y, z), bits(0, x) & byz);
                }
            }
        }
    }

    fn cell_index(&self, x: usize, y: usize, z: usize) -> usize {
        (z * self.dims[1] + y) * self.dims[0] + x
    }

    fn entries(&self, c: usize) -> &[u32] {
        &self.faces[self.starts[c] as usize..self.starts[c + 1] as usize]
    }

    /// Calls `visit` on the entries (faces and masks) of each cell that the sub-cells `span`
    /// meet, with the mask of those of its sub-cells.
    #[inline]
    fn for_entries(&self, span: &Span, mut visit: impl FnMut(&[u32], &[u64], u64)) {
        self.for_cells(span, |c, mask| {
            let (a, b) = (self.starts[c] as usize, self.starts[c + 1] as usize);
            visit(&self.faces[a..b], &self.masks[a..b], mask);
        });
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
    use crate::geom::mesh::{add, interpolate};
    use crate::geom::testmesh::{grid, uv_sphere, Rng};

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
        // The bound never exceeds the distance, for proper and degenerate triangles, and
        // `beyond` says exactly whether it exceeds a reach; the prepared triangle measures
        // exactly as `closest_on_triangle` does, in every region of every kind of triangle.
        let mut rng = Rng(17);
        let sliver = [[0.0, 0.0, 0.0], [1.0, 1e-9, 0.0], [2.0, 0.0, 1e-12]];
        let far = [[1e6, 1e6, 1e6], [1e6 + 1e-3, 1e6, 1e6], [1e6, 1e6 + 1e-3, 1e6 + 1e-3]];
        let skew = [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [0.3, -2.0, 0.5]];
        for t in [tri, line, [[1.0; 3]; 3], skew, sliver, far] {
            let (b, prepared) = (Bound::new(t), Triangle::new(t));
            let centre = t[0];
            for _ in 0..2000 {
                let q = add(centre, rng.point(-3.0, 3.0));
                let (_, d2, bary) = closest_on_triangle(q, t);
                assert!(b.lower(q) <= d2.sqrt() + 1e-9, "{t:?} {q:?}");
                let reach = rng.range(0.0, 3.0);
                assert_eq!(b.beyond(q, reach), b.lower(q) > reach);
                assert_eq!(prepared.closest(q), (d2, bary), "{t:?} {q:?}");
            }
        }
    }

    /// The Bvh's answer to `q`, as a `Hit` of `source`.
    fn bvh_hit(source: &Source, bvh: &Bvh, q: [f64; 3]) -> Hit {
        source.hit(q, bvh.closest_point(q).unwrap().triangle)
    }

    #[test]
    fn finder_agrees_with_the_bvh_near_and_far() {
        // A dense patch inside a coarse sphere, and queries that walk near the patch and the
        // sphere, then jump far off (beyond the grid's reach: left to `closest_far`).
        let (mut pos, mut faces) = uv_sphere(12, 24, |th, ph| 1.0 + 0.05 * (4.0 * th).sin() * (6.0 * ph).cos());
        let (p2, f2) = grid(60, 60, 0.004, [0.2, 0.2, 0.0]);
        let n = pos.len() as u32;
        pos.extend(p2);
        faces.extend(f2.iter().map(|f| f.map(|v| v + n)));
        let mesh = Mesh::new(pos, faces);
        let source = Source::new(&mesh, 10.0);
        let bvh = Bvh::new(&mesh.positions, &mesh.faces);
        let mut finder = Finder::new(&source);
        let mut rng = Rng(29);
        // Walks near the patch (its side is 0.236) and near the sphere, each ending with a
        // jump far off, and walks far off.
        let (mut uv, mut q) = ([0.0, 0.0], [0.0; 3]);
        let (mut far, mut near) = (Vec::new(), 0);
        for i in 0..40_000 {
            let walk = i / 2000 % 4;
            uv = if i % 2000 == 0 { [rng.unit(), rng.unit()] } else { add([uv[0], uv[1], 0.0], rng.point(-0.003, 0.003))[..2].try_into().unwrap() };
            let (u, v) = (uv[0].rem_euclid(1.0), uv[1].rem_euclid(1.0));
            q = match (walk, i % 2000) {
                (_, 1999) => rng.point(-3.0, 3.0),
                (0, _) => [0.2 + 0.236 * u, 0.2 + 0.236 * v, rng.range(-0.002, 0.002)],
                (1, _) => {
                    let (th, ph) = (0.2 + 2.7 * v, 6.3 * u);
                    let r = 1.0 + 0.05 * (4.0 * th).sin() * (6.0 * ph).cos() + rng.range(-0.01, 0.01);
                    [r * th.sin() * ph.cos(), r * th.sin() * ph.sin(), r * th.cos()]
                }
                (2, _) => add(q, rng.point(-0.01, 0.01)),
                _ => [10.0 + u, v, 0.0],
            };
            match finder.closest(q) {
                Some(got) => {
                    assert_eq!(got, bvh_hit(&source, &bvh, q), "query {i} at {q:?}");
                    near += 1;
                }
                None => far.push(q),
            }
        }
        // Near the surface the grid answers; far off (walks 2 and 3), mostly the Bvh.
        assert!(near > 18_000 && far.len() > 15_000, "{near} near, {} far", far.len());
        let hits = source.closest_far(&far);
        for (q, got) in far.iter().zip(hits) {
            assert_eq!(got.unwrap(), bvh_hit(&source, &bvh, *q), "far query at {q:?}");
        }
    }

    #[test]
    fn queries_with_overflowing_distances_are_left_to_the_bvh() {
        let (pos, faces) = grid(6, 6, 0.25, [0.0, 0.0, 0.0]);
        let mesh = Mesh::new(pos, faces);
        let source = Source::new(&mesh, 10.0);
        let bvh = Bvh::new(&mesh.positions, &mesh.faces);
        let mut finder = Finder::new(&source);
        let queries = [[0.3, 0.2, 0.01], [1e200, 0.0, 0.0], [0.3, 0.2, 0.01], [f64::NAN, 0.0, 0.0], [f64::INFINITY, 1.0, 1.0]];
        let mut far = Vec::new();
        for q in queries {
            match finder.closest(q) {
                Some(got) => assert_eq!(got, bvh_hit(&source, &bvh, q), "{q:?}"),
                None => far.push(q),
            }
        }
        assert!(far.len() >= 3);
        for (q, got) in far.iter().zip(source.closest_far(&far)) {
            let want = bvh.closest_point(*q).map(|h| source.hit(*q, h.triangle));
            assert_eq!(format!("{got:?}"), format!("{want:?}"), "{q:?}");
        }
    }

    #[test]
    fn ties_go_to_the_lowest_face_as_in_the_bvh() {
        // A grid whose every triangle is listed twice (the copy after the original), queried on
        // its vertices, edges and faces, from above and in the plane: every query ties.
        let (pos, faces) = grid(8, 8, 0.25, [0.0, 0.0, 0.0]);
        let doubled: Vec<[u32; 3]> = faces.iter().chain(&faces).copied().collect();
        let mesh = Mesh::new(pos, doubled);
        let source = Source::new(&mesh, 10.0);
        let bvh = Bvh::new(&mesh.positions, &mesh.faces);
        let mut finder = Finder::new(&source);
        for i in 0..=32 {
            for j in 0..=32 {
                for z in [0.0, 0.1, -0.3] {
                    let q = [i as f64 / 16.0, j as f64 / 16.0, z];
                    let got = finder.closest(q).unwrap();
                    assert!((got.triangle as usize) < faces.len());
                    assert_eq!(got, bvh_hit(&source, &bvh, q), "{q:?}");
                }
            }
        }
    }

    #[test]
    fn boxes_that_meet_a_cube_share_a_masked_sub_cell_with_it() {
        // Random boxes and cubes on a grid of random triangles: whenever a box meets a cube,
        // the grid lists the box's face in a cell of the cube with a mask that meets the cube's.
        let mut rng = Rng(41);
        let tris: Vec<[[f64; 3]; 3]> = (0..300)
            .map(|_| {
                let a = rng.point(-2.0, 2.0);
                [a, add(a, rng.point(-0.3, 0.3)), add(a, rng.point(-0.3, 0.3))]
            })
            .collect();
        let grid = FaceGrid::new(tris.len(), |f| tris[f], 0.1);
        for _ in 0..3000 {
            let q = rng.point(-2.5, 2.5);
            let half = rng.range(0.0, 0.3);
            let cube = grid.cube(q, half);
            let mut met = vec![false; tris.len()];
            grid.for_entries(&cube, |faces, masks, mask| {
                for (&f, &m) in faces.iter().zip(masks) {
                    met[f as usize] |= m & mask != 0;
                }
            });
            for (f, &t) in tris.iter().enumerate() {
                let (lo, hi) = triangle_box(t);
                let meets = (0..3).all(|k| lo[k] <= q[k] + half && hi[k] >= q[k] - half);
                assert!(!meets || met[f], "face {f} at {q:?} half {half}");
            }
        }
    }
}
