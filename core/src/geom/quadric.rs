//! The quadric error metric of Garland and Heckbert (1997).
//!
//! A quadric is the symmetric 4x4 matrix `Q` of a sum of squared distances to planes: the error
//! of a point `p` is `[p 1] Q [p 1]^T`. Quadrics add, so the quadric of a vertex after any number
//! of edge collapses is the sum of the quadrics of the vertices it absorbed. Used by
//! [`crate::base::decimate`] and meant for the anchor-mesh refinement of the inter path as well.

use std::ops::{Add, AddAssign, Mul};

use crate::geom::mesh::{cross, dist2, dot, norm, sub};

/// Relative determinant below which [`Quadric::optimal_point`] calls the 3x3 system singular.
/// It compares `det(A)` with `max(diag A)^3`, which is about `l2*l3/l1^2` for the eigenvalues
/// `l1 >= l2 >= l3` of `A`: a flat patch (rank 1) or a straight crease (rank 2) lands far below
/// it, any genuinely curved neighbourhood far above it.
const SINGULAR_DET: f64 = 1e-10;

/// How far from the midpoint of an edge, in edge lengths, [`Quadric::optimal_point_near`]
/// accepts the optimal point.
pub const TRUST_RADIUS: f64 = 2.0;

/// A symmetric 4x4 error quadric, stored as its upper triangle in row order:
/// `a00 a01 a02 a03 a11 a12 a13 a22 a23 a33`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Quadric {
    m: [f64; 10],
}

impl Quadric {
    /// The quadric whose error is zero everywhere.
    pub const ZERO: Quadric = Quadric { m: [0.0; 10] };

    /// Squared distance to the plane `n . p + d = 0`, multiplied by `|n|^2` (so pass a unit `n`
    /// for the plain squared distance, or scale `n` and `d` by `sqrt(w)` to weight it by `w`).
    pub fn from_plane(n: [f64; 3], d: f64) -> Self {
        let [x, y, z] = n;
        Quadric { m: [x * x, x * y, x * z, x * d, y * y, y * z, y * d, z * z, z * d, d * d] }
    }

    /// Squared distance to the plane of triangle `abc`, weighted by the triangle's area, so that
    /// a vertex's quadric measures error over the surface it stands for, independent of how
    /// finely that surface was tessellated. A degenerate triangle gives [`Quadric::ZERO`].
    pub fn from_triangle(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> Self {
        let n = cross(sub(b, a), sub(c, a));
        let twice_area = norm(n);
        if twice_area <= 0.0 || !twice_area.is_finite() {
            return Quadric::ZERO;
        }
        let unit = n.map(|v| v / twice_area);
        Quadric::from_plane(unit, -dot(unit, a)) * (0.5 * twice_area)
    }

    /// Constraint for the open-boundary edge `ab` of a face with normal `face_normal` (any
    /// length): squared distance to the plane that contains the edge and is perpendicular to the
    /// face, weighted by `weight * |b - a|^2`. The length factor keeps it commensurate with the
    /// area-weighted face quadrics, so `weight` alone says how strongly the boundary is held
    /// (the decimator uses a large one). Zero for a degenerate edge or normal.
    pub fn from_boundary_edge(
        a: [f64; 3],
        b: [f64; 3],
        face_normal: [f64; 3],
        weight: f64,
    ) -> Self {
        let e = sub(b, a);
        let m = cross(e, face_normal);
        let len = norm(m);
        if len <= 0.0 || !len.is_finite() {
            return Quadric::ZERO;
        }
        let unit = m.map(|v| v / len);
        Quadric::from_plane(unit, -dot(unit, a)) * (weight * dot(e, e))
    }

    /// The error `[p 1] Q [p 1]^T` of placing a vertex at `p`, clamped at zero (rounding can
    /// make a positive semi-definite form dip slightly below it); NaN stays NaN. The expanded
    /// form cancels large terms when `p` is far from the origin compared with the size of the
    /// features measured, so keep coordinates centred (the decimator works relative to the
    /// centre of the bounding box).
    pub fn error(&self, p: [f64; 3]) -> f64 {
        let [a00, a01, a02, a03, a11, a12, a13, a22, a23, a33] = self.m;
        let [x, y, z] = p;
        let e = x * (a00 * x + 2.0 * (a01 * y + a02 * z + a03))
            + y * (a11 * y + 2.0 * (a12 * z + a13))
            + z * (a22 * z + 2.0 * a23)
            + a33;
        if e < 0.0 {
            0.0
        } else {
            e
        }
    }

    /// The point of least error, solving `A p = -b` for the upper-left 3x3 block `A` and the
    /// last column `b`. `None` when `A` is singular or nearly so (flat or crease-like
    /// neighbourhoods, where the minimum is a plane or a line rather than a point; callers then
    /// pick among candidate points themselves) or when the result is not finite.
    pub fn optimal_point(&self) -> Option<[f64; 3]> {
        let [a00, a01, a02, a03, a11, a12, a13, a22, a23, _] = self.m;
        // Cofactors of the symmetric matrix; they also form its adjugate.
        let c00 = a11 * a22 - a12 * a12;
        let c01 = a02 * a12 - a01 * a22;
        let c02 = a01 * a12 - a02 * a11;
        let c11 = a00 * a22 - a02 * a02;
        let c12 = a01 * a02 - a00 * a12;
        let c22 = a00 * a11 - a01 * a01;
        let det = a00 * c00 + a01 * c01 + a02 * c02;
        let scale = a00.abs().max(a11.abs()).max(a22.abs());
        // Written so that a NaN anywhere also answers "singular".
        let regular = det.abs() > SINGULAR_DET * scale * scale * scale;
        if !regular {
            return None;
        }
        let inv = -1.0 / det;
        let p = [
            inv * (c00 * a03 + c01 * a13 + c02 * a23),
            inv * (c01 * a03 + c11 * a13 + c12 * a23),
            inv * (c02 * a03 + c12 * a13 + c22 * a23),
        ];
        p.iter().all(|v| v.is_finite()).then_some(p)
    }

    /// [`Quadric::optimal_point`] when it lies within [`TRUST_RADIUS`] edge lengths of the
    /// midpoint of edge `ab`. A nearly singular system can put the optimum far away, where it
    /// extrapolates the local surface rather than locating a feature.
    pub fn optimal_point_near(&self, a: [f64; 3], b: [f64; 3]) -> Option<[f64; 3]> {
        let mid = midpoint(a, b);
        let reach = TRUST_RADIUS * TRUST_RADIUS * dist2(a, b);
        self.optimal_point().filter(|&p| dist2(p, mid) <= reach)
    }

    /// Where to put the vertex that replaces edge `ab`, and its error: the point of
    /// [`Quadric::optimal_point_near`] when there is one, else the best of the midpoint and
    /// the two ends (the midpoint on ties, as it makes better shaped faces).
    #[cfg(test)]
    pub fn best_point_on_edge(&self, a: [f64; 3], b: [f64; 3]) -> ([f64; 3], f64) {
        if let Some(p) = self.optimal_point_near(a, b) {
            return (p, self.error(p));
        }
        let mid = midpoint(a, b);
        [a, b].into_iter().fold((mid, self.error(mid)), |best, p| {
            let e = self.error(p);
            if e < best.1 {
                (p, e)
            } else {
                best
            }
        })
    }

    /// The summed weights of its planes (`a00 + a11 + a22`): the area a sum of
    /// [`Quadric::from_triangle`] stands for, so that error / area is a mean squared distance.
    pub fn area(&self) -> f64 {
        self.m[0] + self.m[4] + self.m[7]
    }
}

fn midpoint(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1]), 0.5 * (a[2] + b[2])]
}

impl Add for Quadric {
    type Output = Quadric;
    fn add(mut self, rhs: Quadric) -> Quadric {
        self += rhs;
        self
    }
}

impl AddAssign for Quadric {
    fn add_assign(&mut self, rhs: Quadric) {
        for (a, b) in self.m.iter_mut().zip(rhs.m) {
            *a += b;
        }
    }
}

/// Scales every error by `w` (a weight).
impl Mul<f64> for Quadric {
    type Output = Quadric;
    fn mul(self, w: f64) -> Quadric {
        Quadric { m: self.m.map(|v| v * w) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-9 * (1.0 + a.abs().max(b.abs()))
    }

    #[test]
    fn point_on_plane_has_zero_error_and_error_grows_quadratically() {
        let n = [1.0 / 3f64.sqrt(); 3];
        let q = Quadric::from_plane(n, -2.0);
        // 2n lies on the plane, and (1, -1, 0) is parallel to it.
        let on = [2.0 * n[0] + 1.0, 2.0 * n[1] - 1.0, 2.0 * n[2]];
        assert!(q.error(on) < 1e-12);
        for t in [0.1, 0.5, 2.0, -3.0] {
            let p = [on[0] + t * n[0], on[1] + t * n[1], on[2] + t * n[2]];
            assert!(close(q.error(p), t * t), "t={t}: {}", q.error(p));
        }
    }

    #[test]
    fn triangle_quadric_is_area_weighted_plane_distance() {
        let q = Quadric::from_triangle([0.0, 0.0, 1.0], [2.0, 0.0, 1.0], [0.0, 3.0, 1.0]);
        assert!(q.error([5.0, -7.0, 1.0]) < 1e-12);
        assert!(close(q.error([0.3, 0.3, 3.0]), 3.0 * 4.0));
        assert_eq!(Quadric::from_triangle([1.0; 3], [1.0; 3], [2.0; 3]), Quadric::ZERO);
    }

    #[test]
    fn three_orthogonal_planes_meet_at_the_optimal_point() {
        let q = Quadric::from_plane([1.0, 0.0, 0.0], -1.0)
            + Quadric::from_plane([0.0, 1.0, 0.0], 2.0)
            + Quadric::from_plane([0.0, 0.0, 1.0], -3.0);
        let p = q.optimal_point().expect("three independent planes");
        assert!(close(p[0], 1.0) && close(p[1], -2.0) && close(p[2], 3.0), "{p:?}");
        assert!(q.error(p) < 1e-12);
        assert!(close(q.error([2.0, -2.0, 3.0]), 1.0));
    }

    #[test]
    fn oblique_planes_give_their_intersection() {
        let mut q = Quadric::ZERO;
        let target = [0.25, -1.5, 4.0];
        for n in [[1.0, 1.0, 0.0], [0.0, 1.0, 2.0], [3.0, -1.0, 1.0], [1.0, 0.0, 0.0]] {
            let len = norm(n);
            let u = n.map(|v| v / len);
            q += Quadric::from_plane(u, -dot(u, target));
        }
        let p = q.optimal_point().unwrap();
        for k in 0..3 {
            assert!((p[k] - target[k]).abs() < 1e-9, "{p:?}");
        }
    }

    #[test]
    fn flat_and_crease_quadrics_have_no_optimal_point() {
        let flat = Quadric::from_triangle([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
            + Quadric::from_triangle([1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]);
        assert_eq!(flat.optimal_point(), None);
        let crease = flat + Quadric::from_plane([1.0, 0.0, 0.0], 0.0);
        assert_eq!(crease.optimal_point(), None);
        assert_eq!(Quadric::ZERO.optimal_point(), None);
    }

    #[test]
    fn boundary_constraint_holds_points_on_the_edge_plane() {
        let (a, b) = ([0.0, 0.0, 0.0], [2.0, 0.0, 0.0]);
        let q = Quadric::from_boundary_edge(a, b, [0.0, 0.0, 1.0], 10.0);
        // Free along the edge and along the face normal, penalised across the edge in the face.
        assert!(q.error([7.0, 0.0, 5.0]) < 1e-12);
        assert!(close(q.error([0.0, 0.5, 0.0]), 10.0 * 4.0 * 0.25));
        assert_eq!(Quadric::from_boundary_edge(a, a, [0.0, 0.0, 1.0], 10.0), Quadric::ZERO);
    }

    #[test]
    fn edge_placement_prefers_the_optimum_near_the_edge() {
        let corner = Quadric::from_plane([1.0, 0.0, 0.0], -1.0)
            + Quadric::from_plane([0.0, 1.0, 0.0], -1.0)
            + Quadric::from_plane([0.0, 0.0, 1.0], -1.0);
        let (a, b) = ([0.5, 1.0, 1.0], [1.5, 1.0, 1.0]);
        assert_eq!(corner.optimal_point_near(a, b), corner.optimal_point());
        let (p, e) = corner.best_point_on_edge(a, b);
        assert!(dist2(p, [1.0; 3]) < 1e-18 && e < 1e-12);
        // The same corner seen from an edge far away is out of reach.
        let (far_a, far_b) = ([10.0, 0.0, 0.0], [10.5, 0.0, 0.0]);
        assert_eq!(corner.optimal_point_near(far_a, far_b), None);
        assert_eq!(corner.best_point_on_edge(far_a, far_b).0, far_a);
        // A plane holds every candidate at zero error: the midpoint wins the tie.
        let flat = Quadric::from_plane([0.0, 0.0, 1.0], 0.0);
        assert_eq!(flat.best_point_on_edge([0.0; 3], [2.0, 0.0, 0.0]), ([1.0, 0.0, 0.0], 0.0));
        // A tilted plane through the first end: that end wins.
        let tilted = Quadric::from_plane([0.6, 0.0, 0.8], 0.0);
        assert_eq!(tilted.best_point_on_edge([0.0; 3], [2.0, 0.0, 0.0]).0, [0.0; 3]);
    }

    #[test]
    fn sums_and_weights_are_linear() {
        let p = Quadric::from_plane([0.0, 1.0, 0.0], -1.0);
        let q = Quadric::from_plane([1.0, 0.0, 0.0], 0.0);
        let x = [0.5, 3.0, -2.0];
        assert!(close((p + q).error(x), p.error(x) + q.error(x)));
        assert!(close((p * 3.0).error(x), 3.0 * p.error(x)));
        let mut r = p;
        r += q;
        assert_eq!(r, p + q);
    }
}
