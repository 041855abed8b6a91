//! The displacement field: local frames of the subdivided mesh, and the fitting of its
//! vertices onto the input surface.
//!
//! Frames must come out bit for bit the same in encoder and decoder, so they depend only on
//! the subdivided reconstructed mesh. The fitting is encoder-only: it may search as it likes,
//! as long as it is deterministic.

use rayon::prelude::*;

use crate::geom::bvh::{Bvh, SurfacePoint};
use crate::geom::mesh::{add, cross, dot, normalize, scale, sub, vertex_normals, Adjacency};

/// A vertex's local frame, rows `[n, t, b]`: unit normal, tangent, bitangent.
pub type Frame = [[f64; 3]; 3];

/// Normal given to vertices without one (isolated or only in zero-area faces), so that every
/// vertex still has a valid right-handed frame.
const DEFAULT_NORMAL: [f64; 3] = [0.0, 0.0, 1.0];

/// Local frame per vertex of `(positions, faces)`: `n` = area-weighted unit vertex normal
/// (+z when the vertex has none: isolated, or only in zero-area faces), `t` = the coordinate
/// axis least aligned with `n` (lowest axis on ties) made orthogonal to `n` and normalized,
/// `b = n x t`. The frames are orthonormal and right-handed; a vertex without a normal gets
/// `[z, x, y]`. Face indices must be in range.
pub fn local_frames(positions: &[[f64; 3]], faces: &[[u32; 3]]) -> Vec<Frame> {
    vertex_normals(positions, faces).into_iter().map(frame_from_normal).collect()
}

fn frame_from_normal(n: [f64; 3]) -> Frame {
    let n = if n == [0.0; 3] { DEFAULT_NORMAL } else { n };
    // The least aligned axis keeps |t| before normalization >= sqrt(2/3): well conditioned.
    let axis = (1..3).fold(0, |b, k| if n[k].abs() < n[b].abs() { k } else { b });
    let mut e = [0.0; 3];
    e[axis] = 1.0;
    let t = normalize(sub(e, scale(n, n[axis])));
    [n, t, cross(n, t)]
}

/// World vectors `d` expressed in `frames`: components `(n, t, b)`. Panics if the lengths
/// differ.
pub fn to_local(d: &[[f64; 3]], frames: &[Frame]) -> Vec<[f64; 3]> {
    assert_eq!(d.len(), frames.len(), "to_local: one frame per vector");
    d.iter().zip(frames).map(|(&v, f)| [dot(v, f[0]), dot(v, f[1]), dot(v, f[2])]).collect()
}

/// Inverse of [`to_local`] for orthonormal frames. Panics if the lengths differ.
pub fn to_world(l: &[[f64; 3]], frames: &[Frame]) -> Vec<[f64; 3]> {
    assert_eq!(l.len(), frames.len(), "to_world: one frame per vector");
    l.iter()
        .zip(frames)
        .map(|(c, f)| add(add(scale(f[0], c[0]), scale(f[1], c[1])), scale(f[2], c[2])))
        .collect()
}

/// Knobs of [`fit_displacements_with`]; both must be non-negative.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitParams {
    /// A crossing of the normal line is trusted up to `hit_ratio * c + hit_slack` away (`c` =
    /// distance to the closest surface point): farther ones are likely another sheet (the
    /// other side of a thin limb, another component). Fallback offsets keep to the same range.
    pub hit_ratio: f64,
    /// Grid units; lets a slightly tilted surface be hit when `c` is nearly zero.
    pub hit_slack: f64,
}

impl Default for FitParams {
    fn default() -> Self {
        Self { hit_ratio: 2.5, hit_slack: 0.5 }
    }
}

/// [`fit_displacements_with`] with the default [`FitParams`].
pub fn fit_displacements(
    sub_positions: &[[f64; 3]],
    sub_faces: &[[u32; 3]],
    frames: &[Frame],
    target: &Bvh,
    normal_only: bool,
) -> Vec<[f64; 3]> {
    let params = FitParams::default();
    fit_displacements_with(sub_positions, sub_faces, frames, target, normal_only, &params)
}

/// World displacement per vertex of the subdivided mesh `(sub_positions, sub_faces)` that
/// moves it onto the input surface `target` (grid units). `frames` are the vertex frames
/// (orthonormal, e.g. from [`local_frames`]), one per vertex.
///
/// Each vertex goes to where its normal line `v + s n` crosses the target nearest to it, if
/// that crossing is trusted (see [`FitParams::hit_ratio`]); the displacement is then `s n`.
/// Otherwise, with `normal_only`, it is `s n` for the `s` that leaves `v + s n` nearest to the
/// target among: the projection of the closest point on `n` (preferred on ties), the crossing
/// with the plane of the closest triangle, and the mean offset of the neighbours that have a
/// trusted crossing (a light smoothing where the data says nothing better); all kept within
/// the trusted range. Without `normal_only` it is the full vector to the closest point,
/// tangential components included. Zero vectors for an empty target. Deterministic whatever
/// the thread count. Panics if `frames` has another length.
pub fn fit_displacements_with(
    sub_positions: &[[f64; 3]],
    sub_faces: &[[u32; 3]],
    frames: &[Frame],
    target: &Bvh,
    normal_only: bool,
    params: &FitParams,
) -> Vec<[f64; 3]> {
    assert_eq!(sub_positions.len(), frames.len(), "fit_displacements: one frame per vertex");
    if target.is_empty() {
        return vec![[0.0; 3]; sub_positions.len()];
    }
    let first: Vec<FirstFit> = sub_positions
        .par_iter()
        .zip(frames)
        .map(|(&v, f)| first_fit(v, f[0], target, params))
        .collect();
    let means = if normal_only { neighbour_hit_means(&first, sub_faces) } else { Vec::new() };
    (0..sub_positions.len())
        .into_par_iter()
        .map(|i| {
            let (v, n) = (sub_positions[i], frames[i][0]);
            match &first[i] {
                FirstFit::Hit(s) => scale(n, *s),
                FirstFit::Miss { closest, .. } if !normal_only => sub(closest.point, v),
                FirstFit::Miss { closest, limit } => {
                    let mean = means.binary_search_by_key(&(i as u32), |m| m.0).ok();
                    let mean = mean.and_then(|k| means[k].1);
                    scale(n, fallback_offset(v, n, closest, *limit, mean, target))
                }
            }
        })
        .collect()
}

/// What a vertex learns from its own queries.
enum FirstFit {
    /// Offset of the trusted crossing.
    Hit(f64),
    /// No trusted crossing; `limit` is the largest `|s|` trusted for this vertex.
    Miss { closest: SurfacePoint, limit: f64 },
}

impl FirstFit {
    fn hit(&self) -> Option<f64> {
        match *self {
            FirstFit::Hit(s) => Some(s),
            FirstFit::Miss { .. } => None,
        }
    }
}

/// Non-empty target: checked by the callers.
fn closest_to(target: &Bvh, x: [f64; 3]) -> SurfacePoint {
    target.closest_point(x).unwrap_or(SurfacePoint { point: x, triangle: 0, dist2: 0.0, bary: [1.0, 0.0, 0.0] })
}

/// The nearest crossing is trusted when `|s| <= ratio * c + slack`, i.e. when no surface
/// point is nearer than `(|s| - slack) / ratio`: asking exactly that is cheaper than finding
/// `c`, and free when `|s| <= slack`. The closest point is computed only for the misses.
fn first_fit(v: [f64; 3], n: [f64; 3], target: &Bvh, p: &FitParams) -> FirstFit {
    if let Some(h) = target.intersect_line(v, n, f64::INFINITY) {
        if !target.any_within(v, (h.t.abs() - p.hit_slack) / p.hit_ratio) {
            return FirstFit::Hit(h.t);
        }
    }
    let closest = closest_to(target, v);
    FirstFit::Miss { closest, limit: p.hit_ratio * closest.dist2.sqrt() + p.hit_slack }
}

/// On a ridge, or beyond the rim of a hole, the projection of the closest point alone is
/// poor: on the bumpy surface of `timing_fit_160k` it takes these vertices from 2.23 units
/// off the surface (mean) to 2.00, the plane of the closest triangle to 0.65, and the
/// neighbours' mean, where it is nearer still, to 0.62.
fn fallback_offset(
    v: [f64; 3],
    n: [f64; 3],
    closest: &SurfacePoint,
    limit: f64,
    neighbour_mean: Option<f64>,
    target: &Bvh,
) -> f64 {
    // Beyond the trusted range the nearest surface may be another sheet. (Not `f64::clamp`,
    // which panics on a negative range from negative parameters.)
    let clamp = |s: f64| s.max(-limit).min(limit);
    let dist2 = |s: f64| closest_to(target, add(v, scale(n, s))).dist2;
    let first = clamp(dot(sub(closest.point, v), n));
    let others = [plane_offset(v, n, closest, target), neighbour_mean];
    let pick = |best: (f64, f64), s: f64| {
        let d = dist2(s);
        // Strictly nearer only: the projection wins ties.
        if d < best.1 { (s, d) } else { best }
    };
    let others = others.into_iter().flatten().filter(|s| s.is_finite()).map(clamp);
    others.fold((first, dist2(first)), pick).0
}

/// Offset at which the normal line crosses the plane of the closest triangle: where the
/// surface would be if it went on flat, as when `v` lies beyond the rim of a hole.
fn plane_offset(v: [f64; 3], n: [f64; 3], at: &SurfacePoint, target: &Bvh) -> Option<f64> {
    let [a, b, c] = target.triangle(at.triangle)?;
    let m = normalize(cross(sub(b, a), sub(c, a)));
    let den = dot(n, m);
    (den.abs() > 1e-12).then(|| dot(sub(at.point, v), m) / den)
}

/// For each vertex without a trusted crossing, ascending: the mean offset of its mesh
/// neighbours that have one. Only these few vertices get neighbour lists, so the cost is one
/// pass over the faces. Faces with an index out of range are skipped rather than trusted.
fn neighbour_hit_means(fits: &[FirstFit], faces: &[[u32; 3]]) -> Vec<(u32, Option<f64>)> {
    const NONE: u32 = u32::MAX;
    let mut slot = vec![NONE; fits.len()];
    let mut lists: Vec<(u32, Vec<u32>)> = Vec::new();
    for (i, f) in fits.iter().enumerate() {
        if f.hit().is_none() {
            slot[i] = lists.len() as u32;
            lists.push((i as u32, Vec::new()));
        }
    }
    if lists.is_empty() {
        return Vec::new();
    }
    for f in faces.iter().filter(|f| f.iter().all(|&v| (v as usize) < fits.len())) {
        for k in 0..3 {
            if let Some(list) = lists.get_mut(slot[f[k] as usize] as usize) {
                list.1.extend([f[(k + 1) % 3], f[(k + 2) % 3]]);
            }
        }
    }
    lists
        .into_iter()
        .map(|(i, mut nbrs)| {
            nbrs.sort_unstable();
            nbrs.dedup();
            let hits = nbrs.iter().filter_map(|&j| fits[j as usize].hit());
            let (sum, count) = hits.fold((0.0, 0usize), |(s, c), h| (s + h, c + 1));
            (i, (count > 0).then(|| sum / count as f64))
        })
        .collect()
}

/// Knobs of [`refine_normal_fit`]. The defaults were chosen on mitch (3 frames, base 6 and
/// 12 % of the faces, QP 20-36): see the commit that introduced them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RefineParams {
    /// Rounds of projection, reverse pull, flip repair and smoothing.
    pub rounds: usize,
    /// Laplacian smoothing weight of the offsets in the first round, in `[0, 1]`.
    pub smoothing: f64,
    /// Factor on the smoothing weight from one round to the next, in `[0, 1]`.
    pub decay: f64,
    /// Share of the reverse pull (input points towards the fitted surface) applied per
    /// round; 0 turns it off.
    pub reverse: f64,
}

impl Default for RefineParams {
    fn default() -> Self {
        Self { rounds: 3, smoothing: 0.5, decay: 0.75, reverse: 1.5 }
    }
}

/// The normal-only displacements: [`fit_displacements`] refined by [`refine_normal_fit`].
/// Same contract as `fit_displacements(.., true)`.
pub fn fit_normal_displacements(
    sub_positions: &[[f64; 3]],
    sub_faces: &[[u32; 3]],
    frames: &[Frame],
    target: &Bvh,
    params: &RefineParams,
) -> Vec<[f64; 3]> {
    let first = fit_displacements(sub_positions, sub_faces, frames, target, true);
    let offsets: Vec<f64> = first.iter().zip(frames).map(|(&d, f)| dot(d, f[0])).collect();
    let refined = refine_normal_fit(sub_positions, sub_faces, frames, target, &offsets, params);
    frames.iter().zip(refined).map(|(f, s)| scale(f[0], s)).collect()
}

/// Offsets along the frame normals (`frames[i][0]`) that refine `offsets` (e.g. the normal
/// components of [`fit_displacements`]). Each round moves every vertex along its normal to
/// the tangent plane of the input at its closest point; then pulls the vertices towards
/// the input points that the fitted surface leaves far (the ray fit leaves finger tips,
/// ridges and thin parts unreached, which D1's input-to-output half measures); re-centres
/// the vertices of faces that flipped; and smooths the offsets (Laplacian, weight
/// `smoothing * decay^round`; not in the last round, which ends on the projection and
/// pull). The offsets stay along the normals, so the tangential components stay zero.
/// Deterministic whatever the thread count. Unchanged offsets for an empty target or no
/// rounds. Panics if the lengths differ.
pub fn refine_normal_fit(
    sub_positions: &[[f64; 3]],
    sub_faces: &[[u32; 3]],
    frames: &[Frame],
    target: &Bvh,
    offsets: &[f64],
    params: &RefineParams,
) -> Vec<f64> {
    assert_eq!(sub_positions.len(), frames.len(), "refine_normal_fit: one frame per vertex");
    assert_eq!(offsets.len(), frames.len(), "refine_normal_fit: one offset per vertex");
    let mut s = offsets.to_vec();
    if target.is_empty() || params.rounds == 0 {
        return s;
    }
    let rings = Adjacency::new(sub_positions.len(), sub_faces);
    let initial = face_normals(sub_positions, sub_faces);
    let samples = if params.reverse > 0.0 { target_samples(target) } else { Vec::new() };
    let mut weight = params.smoothing;
    // Each round's closest triangles seed the next round's searches, and the fitted
    // surface's hierarchy is refitted rather than rebuilt: the answers stay those of plain
    // queries (see `Bvh::closest_point_near`), at a fraction of the cost.
    let mut input_hints = vec![u32::MAX; s.len()];
    let mut surface_hints = vec![u32::MAX; samples.len()];
    let mut surface: Option<Bvh> = None;
    for round in 0..params.rounds {
        let moved = deformed(sub_positions, frames, &s);
        let steps = projection_steps(&moved, sub_faces, frames, target, &mut input_hints);
        s.iter_mut().zip(&steps).for_each(|(s, t)| *s += t);
        if params.reverse > 0.0 {
            let moved = deformed(sub_positions, frames, &s);
            let bvh = match surface.take() {
                Some(b) => b.refitted(&moved, sub_faces),
                None => Bvh::new(&moved, sub_faces),
            };
            let pulls = reverse_pulls(&bvh, sub_faces, frames, &samples, &mut surface_hints);
            surface = Some(bvh);
            for (s, p) in s.iter_mut().zip(&pulls) {
                if let Some(p) = p {
                    *s += params.reverse * p;
                }
            }
        }
        let moved = deformed(sub_positions, frames, &s);
        for i in flipped_vertices(&moved, sub_faces, &initial) {
            if let Some(m) = ring_mean(&rings, i, &s) {
                s[i] = m;
            }
        }
        if round + 1 < params.rounds {
            s = ring_smoothed(&rings, &s, weight);
        }
        weight *= params.decay;
    }
    s
}

fn deformed(pos: &[[f64; 3]], frames: &[Frame], s: &[f64]) -> Vec<[f64; 3]> {
    pos.iter().zip(frames).zip(s).map(|((&p, f), &s)| add(p, scale(f[0], s))).collect()
}

/// Unit normal per face (zero for degenerate faces).
fn face_normals(pos: &[[f64; 3]], faces: &[[u32; 3]]) -> Vec<[f64; 3]> {
    faces
        .iter()
        .map(|f| {
            let [a, b, c] = f.map(|v| pos[v as usize]);
            normalize(cross(sub(b, a), sub(c, a)))
        })
        .collect()
}

/// Per vertex, the offset along its frame normal to the tangent plane of the input at the
/// point closest to `moved[i]` (the plane's normal is the deformed mesh's vertex normal, a
/// smoother estimate than the input triangle's); the plain projection of the closest point
/// where that plane is too steep to the line. `hints` (one per vertex) seed the closest-point
/// searches and are replaced by this round's closest triangles.
fn projection_steps(moved: &[[f64; 3]], faces: &[[u32; 3]], frames: &[Frame], target: &Bvh, hints: &mut [u32]) -> Vec<f64> {
    let normals = vertex_normals(moved, faces);
    hints
        .par_iter_mut()
        .enumerate()
        .map(|(i, hint)| {
            let (p, n) = (moved[i], frames[i][0]);
            let c = target.closest_point_near(p, *hint).unwrap_or(SurfacePoint { point: p, triangle: *hint, dist2: 0.0, bary: [1.0, 0.0, 0.0] });
            *hint = c.triangle;
            let d = sub(c.point, p);
            let m = if normals[i] == [0.0; 3] { n } else { normals[i] };
            let den = dot(n, m);
            if den > 0.5 { dot(d, m) / den } else { dot(d, n) }
        })
        .collect()
}

/// Vertices of the faces whose normal turned by more than 90 degrees from `initial`,
/// ascending, each once.
fn flipped_vertices(moved: &[[f64; 3]], faces: &[[u32; 3]], initial: &[[f64; 3]]) -> Vec<usize> {
    let now = face_normals(moved, faces);
    let mut out: Vec<usize> = faces
        .iter()
        .zip(now.iter().zip(initial))
        .filter(|(_, (a, b))| dot(**a, **b) < 0.0)
        .flat_map(|(f, _)| f.map(|v| v as usize))
        .collect();
    out.sort_unstable();
    out.dedup();
    out
}

/// Points spread over the input: its triangles' centroids.
fn target_samples(target: &Bvh) -> Vec<[f64; 3]> {
    (0..target.len() as u32)
        .filter_map(|t| target.triangle(t))
        .map(|[a, b, c]| scale(add(add(a, b), c), 1.0 / 3.0))
        .collect()
}

/// Per vertex, the mean normal component of the gaps from the fitted surface to the input
/// samples nearest to its faces, weighted by the barycentric weight of the vertex at the
/// foot of each gap; `None` for vertices no sample is nearest to. Samples the surface
/// reaches weigh in with a zero gap, so a vertex moves only as far as the samples it
/// carries agree. Summed in sample order: deterministic. `surface` indexes the fitted mesh
/// (`faces` at the moved positions); `hints` (one per sample) seed the searches and are
/// replaced by this round's nearest faces.
/// Where an input sample's gap to the fitted surface lands: the nearest fitted face, the gap
/// from the closest point to the sample, and the barycentric weights of that point.
type Foot = (u32, [f64; 3], [f64; 3]);

fn reverse_pulls(surface: &Bvh, faces: &[[u32; 3]], frames: &[Frame], samples: &[[f64; 3]], hints: &mut [u32]) -> Vec<Option<f64>> {
    let feet: Vec<Option<Foot>> = samples
        .par_iter()
        .zip(hints.par_iter_mut())
        .map(|(&q, hint)| {
            let c = surface.closest_point_near(q, *hint)?;
            *hint = c.triangle;
            Some((c.triangle, sub(q, c.point), c.bary))
        })
        .collect();
    let mut acc = vec![(0.0f64, 0.0f64); frames.len()];
    for (t, gap, w) in feet.into_iter().flatten() {
        for (k, &v) in faces[t as usize].iter().enumerate() {
            let a = &mut acc[v as usize];
            a.0 += w[k] * dot(gap, frames[v as usize][0]);
            a.1 += w[k];
        }
    }
    acc.into_iter().map(|(s, w)| (w > 1e-9).then(|| s / w)).collect()
}

/// The mean of `s` over the one-ring of vertex `i`; None for an isolated vertex.
fn ring_mean(rings: &Adjacency, i: usize, s: &[f64]) -> Option<f64> {
    let r = rings.of(i);
    (!r.is_empty()).then(|| r.iter().map(|&j| s[j as usize]).sum::<f64>() / r.len() as f64)
}

/// `s` moved by `weight` towards the mean of each vertex's ring.
fn ring_smoothed(rings: &Adjacency, s: &[f64], weight: f64) -> Vec<f64> {
    (0..s.len())
        .into_par_iter()
        .map(|i| ring_mean(rings, i, s).map_or(s[i], |m| s[i] + weight * (m - s[i])))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::testmesh::{grid, icosphere, midpoint, Rng, Soup};
    use crate::geom::mesh::norm;

    fn moved(pos: &[[f64; 3]], d: &[[f64; 3]]) -> Vec<[f64; 3]> {
        pos.iter().zip(d).map(|(&p, &d)| add(p, d)).collect()
    }

    fn close(a: [f64; 3], b: [f64; 3], tol: f64) -> bool {
        norm(sub(a, b)) <= tol
    }

    /// Distances of `points` to the target surface: (max, mean).
    fn surface_error(points: &[[f64; 3]], target: &Bvh) -> (f64, f64) {
        let d = points.iter().map(|&p| target.closest_point(p).unwrap().dist2.sqrt());
        let (max, sum) = d.fold((0.0f64, 0.0), |(m, s), d| (m.max(d), s + d));
        (max, sum / points.len() as f64)
    }

    const Z_FRAME: Frame = [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

    #[test]
    fn frames_are_orthonormal_and_right_handed() {
        let mut rng = Rng(5);
        let (mut pos, mut faces) = icosphere(2, 50.0);
        pos.iter_mut().for_each(|p| *p = add(*p, rng.point(-3.0, 3.0)));
        let n = pos.len() as u32;
        // An isolated vertex and one used only by a zero-area face.
        pos.extend([[1.0, 2.0, 3.0], [7.0, 7.0, 7.0]]);
        faces.push([n + 1, n + 1, n + 1]);
        let frames = local_frames(&pos, &faces);
        for f in &frames {
            for (i, j) in [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)] {
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((dot(f[i], f[j]) - want).abs() < 1e-12, "{f:?}");
            }
            assert!(close(cross(f[0], f[1]), f[2], 1e-12));
        }
        assert_eq!(frames[n as usize], Z_FRAME);
        assert_eq!(frames[n as usize + 1], Z_FRAME);
    }

    #[test]
    fn frame_normal_is_the_plane_normal() {
        let (pos, faces) = grid(4, 4, 1.0, [0.0; 3]);
        let frames = local_frames(&pos, &faces);
        assert!(frames.iter().all(|f| *f == Z_FRAME));
        // The same grid on a tilted plane spanned by u, w, normal m = u x w.
        let (u, w) = ([1.0, 0.0, -1.0], [-2.0, 3.0, 0.5]);
        let m = normalize(cross(u, w));
        let tilted: Vec<_> = pos.iter().map(|p| add(scale(u, p[0]), scale(w, p[1]))).collect();
        for f in local_frames(&tilted, &faces) {
            assert!(close(f[0], m, 1e-12));
            let least = (0..3).min_by(|&a, &b| m[a].abs().total_cmp(&m[b].abs())).unwrap();
            assert!(f[1][least] > 0.0 && dot(f[1], m).abs() < 1e-12);
        }
    }

    #[test]
    fn local_and_world_round_trip() {
        let mut rng = Rng(9);
        let (mut pos, faces) = icosphere(2, 20.0);
        pos.iter_mut().for_each(|p| *p = add(*p, rng.point(-2.0, 2.0)));
        let frames = local_frames(&pos, &faces);
        let d: Vec<[f64; 3]> = (0..pos.len()).map(|_| rng.point(-5.0, 5.0)).collect();
        let back = to_world(&to_local(&d, &frames), &frames);
        assert!(d.iter().zip(&back).all(|(a, b)| close(*a, *b, 1e-12)));
        assert_eq!(to_local(&[[0.0, 0.0, 2.0]], &[Z_FRAME]), vec![[2.0, 0.0, 0.0]]);
    }

    #[test]
    fn flat_grid_three_units_above_a_plane_moves_down_by_three() {
        let (sub_pos, sub_faces) = grid(10, 10, 1.0, [0.0, 0.0, 3.0]);
        let (tp, tf) = grid(21, 21, 1.0, [-5.0, -5.0, 0.0]);
        let target = Bvh::new(&tp, &tf);
        let frames = local_frames(&sub_pos, &sub_faces);
        for normal_only in [true, false] {
            let d = fit_displacements(&sub_pos, &sub_faces, &frames, &target, normal_only);
            assert!(d.iter().all(|&d| close(d, [0.0, 0.0, -3.0], 1e-9)), "{d:?}");
            for l in to_local(&d, &frames) {
                assert!(close(l, [-3.0, 0.0, 0.0], 1e-9));
            }
        }
    }

    /// A flat-faced coarse sphere (icosphere subdivided flat) fitted onto a fine one.
    fn sphere_case(radius: f64) -> (Soup, Bvh) {
        let coarse = midpoint(&icosphere(2, radius), 3);
        let (tp, tf) = icosphere(6, radius);
        (coarse, Bvh::new(&tp, &tf))
    }

    #[test]
    fn fitted_vertices_land_on_a_sphere() {
        let ((pos, faces), target) = sphere_case(500.0);
        let frames = local_frames(&pos, &faces);
        let d = fit_displacements(&pos, &faces, &frames, &target, true);
        let out = moved(&pos, &d);
        let worst = out.iter().map(|p| (norm(*p) - 500.0).abs()).fold(0.0, f64::max);
        assert!(worst < 0.05, "{worst}");
        assert!(surface_error(&out, &target).0 < 1e-6);
        // Normal-only means no tangential part.
        assert!(to_local(&d, &frames).iter().all(|l| l[1].abs() + l[2].abs() < 1e-9));
    }

    /// A small patch at z = 0 (|x|, |y| <= 10) and a large sheet at z = -100.
    fn two_sheets() -> Bvh {
        let (mut pos, mut faces) = grid(2, 2, 20.0, [-10.0, -10.0, 0.0]);
        let (p2, f2) = grid(2, 2, 200.0, [-100.0, -100.0, -100.0]);
        pos.extend(p2);
        faces.extend(f2.iter().map(|f| f.map(|v| v + 4)));
        Bvh::new(&pos, &faces)
    }

    #[test]
    fn a_far_sheet_on_the_normal_line_is_not_trusted() {
        let target = two_sheets();
        let pos = vec![[20.0, 0.0, 1.0], [21.0, 0.0, 1.0], [20.0, 1.0, 1.0]];
        let faces = vec![[0, 1, 2]];
        let frames = local_frames(&pos, &faces);
        let d = fit_displacements(&pos, &faces, &frames, &target, true);
        assert!(close(d[0], [0.0, 0.0, -1.0], 1e-12), "{:?}", d[0]);
        let d = fit_displacements(&pos, &faces, &frames, &target, false);
        assert!(close(d[0], [-10.0, 0.0, -1.0], 1e-12), "{:?}", d[0]);
        // Trusting any distance takes the far sheet instead.
        let p = FitParams { hit_ratio: 20.0, ..FitParams::default() };
        let d = fit_displacements_with(&pos, &faces, &frames, &target, true, &p);
        assert!(close(d[0], [0.0, 0.0, -101.0], 1e-9), "{:?}", d[0]);
    }

    #[test]
    fn a_grazing_normal_without_a_trusted_crossing_still_gets_nearer() {
        let (tp, tf) = grid(2, 2, 100.0, [-50.0, -50.0, 0.0]);
        let target = Bvh::new(&tp, &tf);
        let a = 80f64.to_radians();
        let frame = frame_from_normal([a.sin(), 0.0, a.cos()]);
        let v = [0.0, 0.0, 1.0];
        let d = fit_displacements(&[v], &[], &[frame], &target, true);
        // The crossing is at |s| = 1 / cos 80 = 5.8 > 2.5 * 1 + 0.5: the offset stops at the
        // trusted range, still nearer than the projection of the closest point (z = 0.97).
        let s = dot(d[0], frame[0]);
        assert!((s + 3.0).abs() < 1e-12, "{s}");
        assert!(add(v, d[0])[2] < 0.5);
    }

    #[test]
    fn fitting_is_deterministic_across_runs_and_thread_counts() {
        let ((mut pos, faces), target) = sphere_case(100.0);
        let mut rng = Rng(21);
        pos.iter_mut().for_each(|p| *p = add(*p, rng.point(-4.0, 4.0)));
        let frames = local_frames(&pos, &faces);
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| fit_displacements(&pos, &faces, &frames, &target, true))
        };
        let a = run(2);
        assert_eq!(a, run(2));
        assert_eq!(a, run(1));
        // The noise leaves some vertices to the fallback, so that path is covered too.
        let p = FitParams::default();
        let miss = |(&v, f): (&[f64; 3], &Frame)| first_fit(v, f[0], &target, &p).hit().is_none();
        assert!(pos.iter().zip(&frames).any(miss));
    }

    #[test]
    fn refinement_keeps_a_sphere_fit_on_the_sphere_and_normal() {
        let ((pos, faces), target) = sphere_case(100.0);
        let frames = local_frames(&pos, &faces);
        let d = fit_normal_displacements(&pos, &faces, &frames, &target, &RefineParams::default());
        let worst = moved(&pos, &d).iter().map(|p| (norm(*p) - 100.0).abs()).fold(0.0, f64::max);
        assert!(worst < 0.05, "{worst}");
        assert!(to_local(&d, &frames).iter().all(|l| l[1].abs() + l[2].abs() < 1e-9));
        let none = RefineParams { rounds: 0, ..RefineParams::default() };
        let plain = fit_displacements(&pos, &faces, &frames, &target, true);
        let unrefined = fit_normal_displacements(&pos, &faces, &frames, &target, &none);
        assert!(plain.iter().zip(&unrefined).all(|(a, b)| close(*a, *b, 1e-12)));
    }

    /// A flat input with a thin spike 6 units tall at the origin, and a coarser flat mesh
    /// on it whose vertices all sit on the flat part: no normal line meets the spike.
    fn spike_case() -> (Soup, Bvh) {
        let (mut tp, tf) = grid(21, 21, 1.0, [-10.0, -10.0, 0.0]);
        tp[10 * 21 + 10][2] = 6.0;
        (grid(10, 10, 2.0, [-9.0, -9.0, 0.0]), Bvh::new(&tp, &tf))
    }

    #[test]
    fn the_reverse_pull_lifts_the_surface_towards_a_thin_spike() {
        let ((pos, faces), target) = spike_case();
        let frames = local_frames(&pos, &faces);
        let apex_gap = |reverse: f64| {
            let p = RefineParams { reverse, ..RefineParams::default() };
            let d = fit_normal_displacements(&pos, &faces, &frames, &target, &p);
            Bvh::new(&moved(&pos, &d), &faces).closest_point([0.0, 0.0, 6.0]).unwrap().dist2.sqrt()
        };
        let (without, with) = (apex_gap(0.0), apex_gap(1.0));
        assert!((without - 6.0).abs() < 1e-9, "{without}");
        // The samples on the flat part hold the vertices back: about 0.9 of lift.
        assert!(with < without - 0.5, "{with} vs {without}");
    }

    #[test]
    fn a_vertex_started_off_the_surface_returns_to_it() {
        // One vertex of a flat grid on a plane starts in a pit 3 units deep; the projection
        // brings it back, and the smoothing does not leave its dent in the neighbours.
        let (pos, faces) = grid(7, 7, 1.0, [0.0; 3]);
        let (tp, tf) = grid(2, 2, 20.0, [-5.0, -5.0, 0.0]);
        let target = Bvh::new(&tp, &tf);
        let frames = local_frames(&pos, &faces);
        let mut start = vec![0.0; pos.len()];
        start[3 * 7 + 3] = -3.0;
        let p = RefineParams { reverse: 0.0, ..RefineParams::default() };
        let s = refine_normal_fit(&pos, &faces, &frames, &target, &start, &p);
        assert!(s.iter().all(|s| s.abs() < 1e-9), "{s:?}");
    }

    #[test]
    fn refinement_is_deterministic_across_thread_counts() {
        let ((mut pos, faces), target) = sphere_case(100.0);
        let mut rng = Rng(33);
        pos.iter_mut().for_each(|p| *p = add(*p, rng.point(-4.0, 4.0)));
        let frames = local_frames(&pos, &faces);
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let p = RefineParams::default();
            pool.install(|| fit_normal_displacements(&pos, &faces, &frames, &target, &p))
        };
        let a = run(2);
        assert_eq!(a, run(1));
        assert_eq!(a, run(3));
    }

    #[test]
    fn degenerate_inputs_do_not_panic() {
        let empty = Bvh::new(&[], &[]);
        let pos = vec![[0.0; 3], [1.0, 0.0, 0.0]];
        let frames = local_frames(&pos, &[[0, 0, 1]]);
        assert_eq!(fit_displacements(&pos, &[[0, 0, 1]], &frames, &empty, true), vec![[0.0; 3]; 2]);
        let flat = Bvh::new(&pos, &[[0, 0, 1]]);
        let d = fit_displacements(&pos, &[[0, 0, 1], [0, 1, 9]], &frames, &flat, true);
        assert!(d.iter().flatten().all(|c| c.is_finite()));
    }
}
