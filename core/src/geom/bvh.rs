//! Bounding volume hierarchy over the triangles of one mesh.
//!
//! Built once per frame and then only read, so one `Bvh` can serve queries from many rayon
//! workers at once. Two queries: the closest point on the surface to a point, and the nearest
//! crossing of a (two-sided) line with the surface. Both break ties on equal distance by the
//! lowest triangle index, so results do not depend on the shape of the tree.

use rayon::prelude::*;

use crate::geom::mesh::{add, cross, dot, norm, scale, sub};

/// Triangles per leaf: small leaves keep the number of exact triangle tests per query low.
const LEAF_SIZE: usize = 4;
/// Median splits halve the range at each level, so the depth is at most 31 for any `u32`
/// triangle count, and a query stack never holds more than depth + 1 entries.
const STACK: usize = 64;
/// Slack on barycentric coordinates, so a line through a shared edge is not lost between
/// the two triangles by rounding.
const BARY_SLACK: f64 = 1e-10;

/// The closest point of the surface to a query point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfacePoint {
    pub point: [f64; 3],
    /// Index of the triangle (in the face list given to [`Bvh::new`]) that holds `point`.
    pub triangle: u32,
    /// Squared distance from the query point to `point`.
    pub dist2: f64,
    /// Barycentric coordinates of `point` on the triangle's corners.
    pub bary: [f64; 3],
}

/// Where a line `p + t d` crosses the surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LineHit {
    /// Signed line parameter: the hit is `p + t d`.
    pub t: f64,
    pub point: [f64; 3],
    pub triangle: u32,
}

/// Two sibling nodes in one cache line: a visit compares both child boxes, and loads them in
/// one fetch. Boxes are `f32` (half the memory of `f64`), kept conservative by the padding
/// (see [`pad`]). Side `s` is a leaf holding triangles `link[s] .. link[s] + count[s]` of the
/// reordered arrays, or, when `count[s] == 0`, an inner node whose children are the two
/// sides of pair `link[s]`. A node is named `2 * pair + side`; the root is side 0 of pair 0.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C, align(64))]
struct Pair {
    /// `lo[axis][side]`: both sides of an axis side by side, so that the box tests of the
    /// two children run in the two lanes of one vector register.
    lo: [[f32; 2]; 3],
    hi: [[f32; 2]; 3],
    link: [u32; 2],
    count: [u32; 2],
}

const ROOT: u32 = 0;
const EMPTY_PAIR: Pair = Pair { lo: [[0.0; 2]; 3], hi: [[0.0; 2]; 3], link: [0; 2], count: [0; 2] };

/// Immutable BVH over a triangle soup (`Send + Sync`).
#[derive(Debug, Clone, Default)]
pub struct Bvh {
    pairs: Vec<Pair>,
    /// Triangle corners in leaf order, copied so that a leaf's triangles are contiguous.
    tris: Vec<[[f64; 3]; 3]>,
    /// Original face index of each entry of `tris`.
    ids: Vec<u32>,
    /// Inverse of `ids`: where each original face went in `tris`.
    slot: Vec<u32>,
}

impl Bvh {
    /// Builds the hierarchy over `faces` (indices into `positions`, which must be in range and
    /// finite; see `Mesh::validate`). Degenerate triangles are allowed: they are found by
    /// closest-point queries as segments or points and never hit by lines.
    pub fn new(positions: &[[f64; 3]], faces: &[[u32; 3]]) -> Self {
        Self::built(positions, faces, PARALLEL_BUILD)
    }

    /// [`Bvh::new`], building subtrees of `parallel_min` or more triangles on two threads.
    fn built(positions: &[[f64; 3]], faces: &[[u32; 3]], parallel_min: usize) -> Self {
        if faces.is_empty() {
            return Self::default();
        }
        let corners: Vec<[[f64; 3]; 3]> = faces.par_iter().map(|f| f.map(|v| positions[v as usize])).collect();
        let pad = pad(&corners);
        let boxes: Vec<Aabb> = corners.par_iter().map(|c| triangle_box(c, pad)).collect();
        let mut items: Vec<Item> = boxes
            .par_iter()
            .enumerate()
            .map(|(i, b)| Item { center: [0, 1, 2].map(|k| 0.5 * (b.0[k] + b.1[k])), id: i as u32 })
            .collect();
        let mut pairs = vec![EMPTY_PAIR];
        build(&mut pairs, ROOT, &mut items, 0, &Split { boxes: &boxes, parallel_min });
        let tris = items.iter().map(|it| corners[it.id as usize]).collect();
        let ids: Vec<u32> = items.iter().map(|it| it.id).collect();
        let mut slot = vec![0u32; ids.len()];
        for (k, &id) in ids.iter().enumerate() {
            slot[id as usize] = k as u32;
        }
        Self { pairs, tris, ids, slot }
    }

    /// The same hierarchy over the same `faces` (the list given to [`Bvh::new`]) at new
    /// `positions`: the tree is kept and its boxes are recomputed, which costs a fraction of a
    /// build. Queries answer exactly as on a new build (answers never depend on the tree's
    /// shape); they slow down only when the positions moved far. Panics if `faces` has
    /// another length than the indexed list.
    pub fn refitted(&self, positions: &[[f64; 3]], faces: &[[u32; 3]]) -> Self {
        assert_eq!(faces.len(), self.ids.len(), "Bvh::refitted: the face list it was built on");
        let tris: Vec<[[f64; 3]; 3]> = self.ids.par_iter().map(|&id| faces[id as usize].map(|v| positions[v as usize])).collect();
        let pad = pad(&tris);
        let mut pairs = self.pairs.clone();
        // The leaves, most of the work, on all threads; then the inner boxes, each the union
        // of its children's (min and max are exact, so the order does not matter to the bits).
        pairs.par_iter_mut().for_each(|pair| {
            for s in 0..2 {
                let (link, count) = (pair.link[s], pair.count[s]);
                if count > 0 {
                    let leaf = &tris[link as usize..(link + count) as usize];
                    set_box(pair, s, leaf.iter().skip(1).fold(triangle_box(&leaf[0], pad), |acc, t| union(acc, triangle_box(t, pad))));
                }
            }
        });
        // Children are pushed after their parents, so a reverse sweep meets them first.
        for p in (0..pairs.len()).rev() {
            for s in 0..2 {
                let (link, count) = (pairs[p].link[s], pairs[p].count[s]);
                if count > 0 || (p == 0 && s == 1) {
                    continue; // a leaf, done above, or the root pair's unused side
                }
                let c = &pairs[link as usize];
                let side = |k: usize, j: usize| (f64::from(c.lo[k][j]), f64::from(c.hi[k][j]));
                let lo = [0, 1, 2].map(|k| fmin(side(k, 0).0, side(k, 1).0));
                let hi = [0, 1, 2].map(|k| fmax(side(k, 0).1, side(k, 1).1));
                set_box(&mut pairs[p], s, (lo, hi));
            }
        }
        Self { pairs, tris, ids: self.ids.clone(), slot: self.slot.clone() }
    }

    /// Corners of triangle `id` (an index into the face list given to [`Bvh::new`]).
    pub fn triangle(&self, id: u32) -> Option<[[f64; 3]; 3]> {
        self.tris.get(*self.slot.get(id as usize)? as usize).copied()
    }

    /// Number of triangles indexed.
    pub fn len(&self) -> usize {
        self.ids.len()
    }

    pub fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }

    /// `(link, count)` of a node (see [`Pair`]).
    #[inline]
    fn node(&self, node: u32) -> (u32, u32) {
        let (p, s) = (&self.pairs[(node >> 1) as usize], (node & 1) as usize);
        (p.link[s], p.count[s])
    }

    /// The point of the surface nearest to `q`; `None` only for an empty hierarchy. On equal
    /// distance the lowest triangle index wins.
    pub fn closest_point(&self, q: [f64; 3]) -> Option<SurfacePoint> {
        self.closest_point_from(q, None)
    }

    /// For the triangle with corners `c`: its area (the cross product's length, twice the
    /// geometric area) times the squared distance from its centroid to this surface, and that
    /// area. Summed over a surface's triangles, their ratio is the mean squared distance
    /// weighted by area, which a surface's tessellation does not sway.
    pub fn area_weighted_dist2(&self, c: [[f64; 3]; 3]) -> (f64, f64) {
        let centroid = std::array::from_fn(|k| (c[0][k] + c[1][k] + c[2][k]) / 3.0);
        let area = norm(cross(sub(c[1], c[0]), sub(c[2], c[0])));
        (area * self.closest_point(centroid).map_or(0.0, |h| h.dist2), area)
    }

    /// Mean squared distance from the surface `(positions, faces)` to this one, sampled at
    /// face centroids and weighted by face area ([`Self::area_weighted_dist2`]; 0 for a
    /// surface without area).
    pub fn mean_squared_distance(&self, positions: &[[f64; 3]], faces: &[[u32; 3]]) -> f64 {
        // Summed in order after the parallel map: a parallel reduction's grouping depends on
        // the thread scheduling, and the encoder's decisions this feeds must not, or streams
        // would differ from run to run (and between a sequential and a parallel encode).
        let terms: Vec<(f64, f64)> = faces.par_iter().map(|f| self.area_weighted_dist2(f.map(|v| positions[v as usize]))).collect();
        let (weighted, area) = terms.iter().fold((0.0, 0.0), |x, y| (x.0 + y.0, x.1 + y.1));
        if area > 0.0 { weighted / area } else { 0.0 }
    }

    /// [`Bvh::closest_point`], searched from triangle `hint` (an index into the face list;
    /// out of range is ignored): the same answer, found faster when the hint is near it, as
    /// the closest triangle of a nearby query or of the previous round of an iteration is.
    pub fn closest_point_near(&self, q: [f64; 3], hint: u32) -> Option<SurfacePoint> {
        let start = self.triangle(hint).map(|tri| {
            let (point, dist2, bary) = closest_on_triangle(q, tri);
            SurfacePoint { point, triangle: hint, dist2, bary }
        });
        self.closest_point_from(q, start)
    }

    /// The traversal behind both closest-point queries, from a known surface point: every
    /// box that may hold a point at most as near is still visited (ties go to the lowest
    /// index), so the start changes the work, never the answer.
    fn closest_point_from(&self, q: [f64; 3], start: Option<SurfacePoint>) -> Option<SurfacePoint> {
        let mut best = start;
        let mut best_d2 = start.map_or(f64::INFINITY, |b| b.dist2);
        let mut stack = [(ROOT, 0.0f64); STACK];
        let mut sp = usize::from(!self.pairs.is_empty());
        while sp > 0 {
            sp -= 1;
            let (node, box_d2) = stack[sp];
            // `>` rather than `>=`: a box at exactly the best distance may hold a lower index.
            if box_d2 > best_d2 {
                continue;
            }
            let (link, count) = self.node(node);
            if count > 0 {
                for k in link as usize..(link + count) as usize {
                    if triangle_box_dist2(&self.tris[k], q) > best_d2 * (1.0 + 1e-9) {
                        continue;
                    }
                    let (point, dist2, bary) = closest_on_triangle(q, self.tris[k]);
                    let cand = SurfacePoint { point, triangle: self.ids[k], dist2, bary };
                    if better_point(&cand, best.as_ref()) {
                        best_d2 = cand.dist2;
                        best = Some(cand);
                    }
                }
                continue;
            }
            let [dl, dr] = box_dist2(&self.pairs[link as usize], q);
            let (l, r) = (2 * link, 2 * link + 1);
            // Nearer child on top, so it is searched first and tightens the bound early.
            let (near, far) = if dl <= dr { ((l, dl), (r, dr)) } else { ((r, dr), (l, dl)) };
            for item in [far, near] {
                if item.1 <= best_d2 {
                    stack[sp] = item;
                    sp += 1;
                }
            }
        }
        best
    }

    /// Whether some point of the surface lies strictly closer than `r` to `q`. Cheaper than
    /// [`Bvh::closest_point`] when the answer is yes (it stops at the first such triangle) or
    /// when `r` is small.
    pub fn any_within(&self, q: [f64; 3], r: f64) -> bool {
        if r.is_nan() || r <= 0.0 || self.pairs.is_empty() {
            return false;
        }
        let r2 = r * r;
        let mut stack = [ROOT; STACK];
        let mut sp = usize::from(box_dist2(&self.pairs[0], q)[0] < r2);
        while sp > 0 {
            sp -= 1;
            let (link, count) = self.node(stack[sp]);
            if count > 0 {
                let tris = &self.tris[link as usize..(link + count) as usize];
                if tris.iter().any(|&t| closest_on_triangle(q, t).1 < r2) {
                    return true;
                }
                continue;
            }
            let d2 = box_dist2(&self.pairs[link as usize], q);
            for s in [1, 0] {
                if d2[s] < r2 {
                    stack[sp] = 2 * link + s as u32;
                    sp += 1;
                }
            }
        }
        false
    }

    /// The crossing of the line `p + t d` with the surface that has the smallest `|t|`, looking
    /// both ways along the line up to `|t| <= t_max`; `None` when there is none. `d` need not
    /// be unit length (`t` is in units of `|d|`). Triangles seen edge-on and degenerate
    /// triangles are never hit. On equal `|t|` the lowest triangle index wins.
    pub fn intersect_line(&self, p: [f64; 3], d: [f64; 3], t_max: f64) -> Option<LineHit> {
        let mut best: Option<LineHit> = None;
        let mut best_abs = t_max;
        let line = Line::new(p, d);
        let mut stack = [(ROOT, 0.0f64); STACK];
        let mut sp = 0;
        if let (Some(root), true) = (self.pairs.first(), t_max >= 0.0) {
            let t = line.enters(root, t_max)[0];
            if t <= t_max {
                stack[0].1 = t;
                sp = 1;
            }
        }
        while sp > 0 {
            sp -= 1;
            let (node, box_t) = stack[sp];
            if box_t > best_abs {
                continue;
            }
            let (link, count) = self.node(node);
            if count > 0 {
                for k in link as usize..(link + count) as usize {
                    let Some(t) = line_triangle(p, d, self.tris[k]) else { continue };
                    let cand = LineHit { t, point: add(p, scale(d, t)), triangle: self.ids[k] };
                    if t.abs() <= best_abs && better_hit(&cand, best.as_ref()) {
                        best_abs = t.abs();
                        best = Some(cand);
                    }
                }
                continue;
            }
            let [tl, tr] = line.enters(&self.pairs[link as usize], best_abs);
            let (l, r) = (2 * link, 2 * link + 1);
            let (near, far) = if tr < tl { ((r, tr), (l, tl)) } else { ((l, tl), (r, tr)) };
            for item in [far, near] {
                // A missed box is NaN and fails this test.
                if item.1 <= best_abs {
                    stack[sp] = item;
                    sp += 1;
                }
            }
        }
        best
    }
}

fn better_point(c: &SurfacePoint, best: Option<&SurfacePoint>) -> bool {
    best.map_or(true, |b| c.dist2 < b.dist2 || (c.dist2 == b.dist2 && c.triangle < b.triangle))
}

fn better_hit(c: &LineHit, best: Option<&LineHit>) -> bool {
    best.map_or(true, |b| {
        let (ct, bt) = (c.t.abs(), b.t.abs());
        ct < bt || (ct == bt && c.triangle < b.triangle)
    })
}

/// Box padding: boxes a little larger than their triangles keep both queries conservative
/// when rounding puts a computed point or crossing an ulp outside the exact box, and when a
/// bound is rounded to `f32` (at most 2^-24 of the largest coordinate, well under this pad).
fn pad(corners: &[[[f64; 3]; 3]]) -> f64 {
    // A maximum is exact, so the parallel reduction's grouping cannot change it.
    let m = corners.par_iter().map(|t| t.iter().flatten().fold(0.0f64, |m, c| m.max(c.abs()))).reduce(|| 0.0, f64::max);
    1e-6 * (1.0 + m)
}

type Aabb = ([f64; 3], [f64; 3]);

fn triangle_box(c: &[[f64; 3]; 3], pad: f64) -> Aabb {
    let lo = [0, 1, 2].map(|k| fmin(fmin(c[0][k], c[1][k]), c[2][k]) - pad);
    let hi = [0, 1, 2].map(|k| fmax(fmax(c[0][k], c[1][k]), c[2][k]) + pad);
    (lo, hi)
}

fn union(a: Aabb, b: Aabb) -> Aabb {
    ([0, 1, 2].map(|k| fmin(a.0[k], b.0[k])), [0, 1, 2].map(|k| fmax(a.1[k], b.1[k])))
}

/// A triangle during the build, its box centre kept inline so that partitioning reads no
/// other array.
#[derive(Clone, Copy)]
struct Item {
    center: [f64; 3],
    id: u32,
}

/// Fills `node` with `items` (which start at `first` in the final order), splitting at the
/// median box centre along the widest extent of the centres, and returns its box. The median
/// keeps the tree balanced (depth <= 31, within the fixed query stacks) and needs no tuning;
/// boxes are merged bottom-up so each triangle box is read once.
/// What every level of a build reads: the triangles' boxes, and the subtree size from which
/// the two halves are built on two threads.
struct Split<'a> {
    boxes: &'a [Aabb],
    parallel_min: usize,
}

fn build(pairs: &mut Vec<Pair>, node: u32, items: &mut [Item], first: u32, split: &Split) -> Aabb {
    let (p, s) = ((node >> 1) as usize, (node & 1) as usize);
    let bx = if items.len() <= LEAF_SIZE {
        pairs[p].link[s] = first;
        pairs[p].count[s] = items.len() as u32;
        let b = |it: &Item| split.boxes[it.id as usize];
        items.iter().skip(1).fold(b(&items[0]), |acc, it| union(acc, b(it)))
    } else {
        let axis = widest_axis(items);
        let mid = items.len() / 2;
        items.select_nth_unstable_by(mid, |a, b| a.center[axis].total_cmp(&b.center[axis]));
        let (left, right) = items.split_at_mut(mid);
        let child = pairs.len() as u32;
        pairs.push(EMPTY_PAIR);
        pairs[p].link[s] = child;
        if left.len() + right.len() >= split.parallel_min {
            let right_first = first + mid as u32;
            let (l, r) = rayon::join(|| subtree(left, first, split), || subtree(right, right_first, split));
            let l = graft(pairs, 2 * child, l);
            let r = graft(pairs, 2 * child + 1, r);
            union(l, r)
        } else {
            let l = build(pairs, 2 * child, left, first, split);
            let r = build(pairs, 2 * child + 1, right, first + mid as u32, split);
            union(l, r)
        }
    };
    set_box(&mut pairs[p], s, bx);
    bx
}

/// Subtrees of at least this many triangles build their two halves on two threads.
const PARALLEL_BUILD: usize = 8192;

/// A subtree built on its own: its pairs in the order [`build`] pushes them, after a holder
/// pair whose side 0 is the subtree's root; and the subtree's box.
fn subtree(items: &mut [Item], first: u32, split: &Split) -> (Vec<Pair>, Aabb) {
    let mut pairs = vec![EMPTY_PAIR];
    let bx = build(&mut pairs, ROOT, items, first, split);
    (pairs, bx)
}

/// Appends a [`subtree`]'s pairs to `pairs` and makes `node` its root: the layout (and so
/// the order in which queries visit the tree) is exactly that of a sequential build.
fn graft(pairs: &mut Vec<Pair>, node: u32, (sub, bx): (Vec<Pair>, Aabb)) -> Aabb {
    // Inner links of `sub` index `sub`, whose entry 0 (the holder) is not appended.
    let offset = pairs.len() as u32;
    let relink = |q: &Pair, side: usize| if q.count[side] == 0 { q.link[side] - 1 + offset } else { q.link[side] };
    let (p, s) = ((node >> 1) as usize, (node & 1) as usize);
    pairs[p].count[s] = sub[0].count[0];
    pairs[p].link[s] = relink(&sub[0], 0);
    pairs.extend(sub[1..].iter().map(|q| Pair { link: [relink(q, 0), relink(q, 1)], ..*q }));
    set_box(&mut pairs[p], s, bx);
    bx
}

fn set_box(pair: &mut Pair, s: usize, bx: Aabb) {
    // Beyond the f32 range a bound saturates outward, so the box stays conservative.
    for k in 0..3 {
        pair.lo[k][s] = (bx.0[k] as f32).min(f32::MAX);
        pair.hi[k][s] = (bx.1[k] as f32).max(f32::MIN);
    }
}

fn widest_axis(items: &[Item]) -> usize {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for it in items {
        for k in 0..3 {
            lo[k] = fmin(lo[k], it.center[k]);
            hi[k] = fmax(hi[k], it.center[k]);
        }
    }
    let ext = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
    (0..3).fold(0, |b, k| if ext[k] > ext[b] { k } else { b })
}

/// `min` without NaN handling: it compiles to one instruction, where `f64::min` costs a
/// blend, on the hottest paths of the build and the queries. Inputs here are never NaN.
#[inline]
fn fmin(a: f64, b: f64) -> f64 {
    if a < b { a } else { b }
}

#[inline]
fn fmax(a: f64, b: f64) -> f64 {
    if a > b { a } else { b }
}

/// Squared distance from `q` to the bounding box of triangle `t`: a lower bound of its
/// distance to the triangle, far cheaper to compute.
#[inline(always)]
fn triangle_box_dist2(t: &[[f64; 3]; 3], q: [f64; 3]) -> f64 {
    let mut acc = 0.0;
    for k in 0..3 {
        let lo = fmin(fmin(t[0][k], t[1][k]), t[2][k]);
        let hi = fmax(fmax(t[0][k], t[1][k]), t[2][k]);
        let e = fmax(fmax(lo - q[k], q[k] - hi), 0.0);
        acc += e * e;
    }
    acc
}

/// Squared distances from `q` to the two boxes of `pair`. Indexed loops over the two sides, so
/// that the compiler pairs them into vector lanes.
#[inline]
#[allow(clippy::needless_range_loop)]
fn box_dist2(pair: &Pair, q: [f64; 3]) -> [f64; 2] {
    let mut acc = [0.0; 2];
    for k in 0..3 {
        for s in 0..2 {
            let (lo, hi) = (f64::from(pair.lo[k][s]), f64::from(pair.hi[k][s]));
            let e = fmax(fmax(lo - q[k], q[k] - hi), 0.0);
            acc[s] += e * e;
        }
    }
    acc
}

/// A line `p + t d` with the reciprocals its slab tests need.
struct Line {
    p: [f64; 3],
    d: [f64; 3],
    inv: [f64; 3],
    /// Some component of `d` is zero: the slab formula would give 0 * inf on that axis.
    parallel: bool,
}

impl Line {
    fn new(p: [f64; 3], d: [f64; 3]) -> Self {
        let inv = d.map(|c| if c != 0.0 { 1.0 / c } else { f64::INFINITY });
        Self { p, d, inv, parallel: d.contains(&0.0) }
    }

    /// For each box of `pair`, the smallest `|t|` at which the line is inside it within
    /// `|t| <= limit`, or NaN when it is not (NaN fails every comparison of the callers).
    #[inline(always)]
    fn enters(&self, pair: &Pair, limit: f64) -> [f64; 2] {
        let (mut t0, mut t1) = ([-limit; 2], [limit; 2]);
        let mut outside = [false; 2];
        for k in 0..3 {
            let lo = pair.lo[k].map(f64::from);
            let hi = pair.hi[k].map(f64::from);
            if self.parallel && self.d[k] == 0.0 {
                for s in 0..2 {
                    outside[s] |= self.p[k] < lo[s] || self.p[k] > hi[s];
                }
                continue;
            }
            for s in 0..2 {
                let a = (lo[s] - self.p[k]) * self.inv[k];
                let b = (hi[s] - self.p[k]) * self.inv[k];
                t0[s] = fmax(t0[s], fmin(a, b));
                t1[s] = fmin(t1[s], fmax(a, b));
            }
        }
        // On a non-empty [t0, t1] the smallest |t| is t0 if t0 > 0, -t1 if t1 < 0, else 0.
        [0, 1].map(|s| {
            if outside[s] || t0[s] > t1[s] { f64::NAN } else { fmax(fmax(t0[s], -t1[s]), 0.0) }
        })
    }
}

/// Möller-Trumbore for a two-sided line: the parameter `t` of the crossing, of either sign.
fn line_triangle(p: [f64; 3], d: [f64; 3], [a, b, c]: [[f64; 3]; 3]) -> Option<f64> {
    let e1 = sub(b, a);
    let e2 = sub(c, a);
    let pv = cross(d, e2);
    let det = dot(e1, pv);
    // Also rejects degenerate triangles (det == 0) and subnormal determinants whose inverse
    // would overflow.
    if det.abs() < f64::MIN_POSITIVE {
        return None;
    }
    let inv = 1.0 / det;
    let tv = sub(p, a);
    let u = dot(tv, pv) * inv;
    if !(-BARY_SLACK..=1.0 + BARY_SLACK).contains(&u) {
        return None;
    }
    let qv = cross(tv, e1);
    let v = dot(d, qv) * inv;
    if v < -BARY_SLACK || u + v > 1.0 + BARY_SLACK {
        return None;
    }
    let t = dot(e2, qv) * inv;
    t.is_finite().then_some(t)
}

/// Closest point of triangle `abc` to `p`, its squared distance and its barycentrics
/// (Ericson, Real-Time Collision Detection 5.1.5). Shared with `transfer`, whose exact
/// search must pick the same triangle as [`Bvh::closest_point`] on ties. Degenerate
/// triangles go to the segment fallback, where the region formulas would divide by zero.
pub(crate) fn closest_on_triangle(p: [f64; 3], tri: [[f64; 3]; 3]) -> ([f64; 3], f64, [f64; 3]) {
    let [a, b, c] = tri;
    let ab = sub(b, a);
    let ac = sub(c, a);
    let n = cross(ab, ac);
    let (point, bary) = if dot(n, n) <= 1e-20 * dot(ab, ab) * dot(ac, ac) {
        closest_on_edges(p, tri)
    } else {
        let r = closest_on_proper_triangle(p, a, b, c, ab, ac);
        if r.0.iter().all(|x| x.is_finite()) { r } else { closest_on_edges(p, tri) }
    };
    let d = sub(point, p);
    (point, dot(d, d), bary)
}

fn closest_on_proper_triangle(
    p: [f64; 3],
    a: [f64; 3],
    b: [f64; 3],
    c: [f64; 3],
    ab: [f64; 3],
    ac: [f64; 3],
) -> ([f64; 3], [f64; 3]) {
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

fn closest_on_edges(p: [f64; 3], [a, b, c]: [[f64; 3]; 3]) -> ([f64; 3], [f64; 3]) {
    let mut best = (a, f64::INFINITY, [1.0, 0.0, 0.0]);
    for (k, (s, e)) in [(a, b), (b, c), (c, a)].into_iter().enumerate() {
        let (x, t) = closest_on_segment(p, s, e);
        let d = sub(x, p);
        if dot(d, d) < best.1 {
            let mut bary = [0.0; 3];
            bary[k] = 1.0 - t;
            bary[(k + 1) % 3] = t;
            best = (x, dot(d, d), bary);
        }
    }
    (best.0, best.2)
}

fn closest_on_segment(p: [f64; 3], a: [f64; 3], b: [f64; 3]) -> ([f64; 3], f64) {
    let ab = sub(b, a);
    let len2 = dot(ab, ab);
    if len2 <= 0.0 {
        return (a, 0.0);
    }
    let t = (dot(sub(p, a), ab) / len2).clamp(0.0, 1.0);
    (add(a, scale(ab, t)), t)
}

#[cfg(test)]
mod tests;
