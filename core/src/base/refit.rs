//! Refitting the base mesh so that its subdivision fits the input.
//!
//! Decimation places each base vertex where the quadric error of its collapses is least,
//! which is a good place for the base mesh itself but not for the surface its subdivision
//! makes: midpoints and Loop's smoothing pull the subdivided surface inside convex parts and
//! outside concave ones, and the displacements must then pay for the gap. The subdivision is
//! linear in the base positions (`Subdivision::apply`), so the base positions whose
//! subdivision lies closest, in the least-squares sense, to points fitted on the input are
//! the solution of the normal equations `S^T S x = S^T t`, solved here by conjugate
//! gradients from the decimated positions. The MPEG test model refits its base mesh the same
//! way before coding it.

use crate::geom::bvh::Bvh;
use crate::residual::displace;
use crate::geom::mesh::{add, sub, Mesh};
use crate::residual::subdivide::{subdivide, Scheme};

/// Conjugate-gradient iterations: the system is well conditioned (each subdivided vertex
/// depends on a few nearby base vertices), and more iterations change D1 by under 0.01 dB.
const ITERATIONS: usize = 30;

/// The base positions (grid units) whose subdivision with `schemes` on `base`'s faces lies
/// closest to the input surface `target`: the subdivided base is fitted onto the input
/// (normal line crossings, else closest points; see `displace::fit_displacements`), and
/// the base positions are solved so that their subdivision comes nearest those points. A
/// vertex that no face uses keeps its position. `base` is returned unchanged without
/// subdivision or faces.
pub fn refit_base(base: &Mesh, schemes: &[Scheme], target: &Bvh) -> Vec<[f64; 3]> {
    if schemes.is_empty() || base.faces.is_empty() || target.is_empty() {
        return base.positions.clone();
    }
    let sub = subdivide(&base.positions, &base.faces, schemes);
    let frames = displace::local_frames(&sub.positions, &sub.faces);
    let moves = displace::fit_displacements(&sub.positions, &sub.faces, &frames, target, false);
    let fitted: Vec<[f64; 3]> = sub.positions.iter().zip(&moves).map(|(&p, &d)| add(p, d)).collect();
    let transposed = sub.transposed();
    least_squares(|x| sub.apply(x), |y| transposed.apply(y), &base.positions, &fitted, ITERATIONS)
}

/// `x` minimizing `|A x - b|^2` by conjugate gradients on `A^T A x = A^T b` from `x0`, `n`
/// iterations at most, for the three coordinates at once (they do not interact); `a` and
/// `at` apply `A` and its transpose.
fn least_squares(
    a: impl Fn(&[[f64; 3]]) -> Vec<[f64; 3]>,
    at: impl Fn(&[[f64; 3]]) -> Vec<[f64; 3]>,
    x0: &[[f64; 3]],
    b: &[[f64; 3]],
    n: usize,
) -> Vec<[f64; 3]> {
    let mut x = x0.to_vec();
    let residual: Vec<[f64; 3]> = b.iter().zip(a(&x)).map(|(&bi, ai)| sub(bi, ai)).collect();
    let mut r = at(&residual);
    let mut p = r.clone();
    let mut rr = column_dots(&r, &r);
    for _ in 0..n {
        let ap = at(&a(&p));
        let pap = column_dots(&p, &ap);
        if (0..3).all(|k| pap[k] <= 0.0 || rr[k] <= 1e-24) {
            break;
        }
        let alpha: [f64; 3] = std::array::from_fn(|k| if pap[k] > 0.0 { rr[k] / pap[k] } else { 0.0 });
        for i in 0..x.len() {
            for k in 0..3 {
                x[i][k] += alpha[k] * p[i][k];
                r[i][k] -= alpha[k] * ap[i][k];
            }
        }
        let next = column_dots(&r, &r);
        let beta: [f64; 3] = std::array::from_fn(|k| if rr[k] > 0.0 { next[k] / rr[k] } else { 0.0 });
        for i in 0..p.len() {
            for k in 0..3 {
                p[i][k] = r[i][k] + beta[k] * p[i][k];
            }
        }
        rr = next;
    }
    x
}

/// Per coordinate, the dot product of two vector fields.
fn column_dots(u: &[[f64; 3]], v: &[[f64; 3]]) -> [f64; 3] {
    std::array::from_fn(|k| u.iter().zip(v).map(|(a, b)| a[k] * b[k]).sum())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::mesh::dot;
    use crate::residual::subdivide::Scheme::{Loop, Midpoint};

    /// An octahedron, whose Loop subdivision shrinks well inside the unit sphere.
    fn octahedron() -> Mesh {
        let p = vec![[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]];
        let f = vec![[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]];
        Mesh::new(p.into_iter().map(|q: [f64; 3]| q.map(|c| 10.0 * c)).collect(), f)
    }

    /// The octahedron subdivided `levels` times and pushed onto the sphere of radius 10.
    fn sphere(levels: usize) -> Mesh {
        let o = octahedron();
        let s = subdivide(&o.positions, &o.faces, &vec![Midpoint; levels]);
        let p = s.positions.iter().map(|&q| q.map(|c| 10.0 * c / dot(q, q).sqrt())).collect();
        Mesh::new(p, s.faces)
    }

    fn mean_distance_to_sphere(p: &[[f64; 3]]) -> f64 {
        p.iter().map(|&q| (dot(q, q).sqrt() - 10.0).abs()).sum::<f64>() / p.len() as f64
    }

    #[test]
    fn the_refitted_subdivision_lies_closer_to_the_input() {
        let (base, input) = (octahedron(), sphere(4));
        let target = Bvh::new(&input.positions, &input.faces);
        let schemes = [Midpoint, Midpoint, Loop];
        let before = mean_distance_to_sphere(&subdivide(&base.positions, &base.faces, &schemes).positions);
        let refitted = refit_base(&base, &schemes, &target);
        let after = mean_distance_to_sphere(&subdivide(&refitted, &base.faces, &schemes).positions);
        assert!(after < 0.5 * before, "{before} -> {after}");
        // By symmetry the refit only scales the octahedron out.
        assert!(refitted[0][0] > 10.0 && refitted[0][1].abs() < 1e-9, "{:?}", refitted[0]);
    }

    #[test]
    fn least_squares_solves_a_small_system() {
        // A = [[2, 0], [1, 1], [0, 3]] acting on each coordinate.
        let a = |x: &[[f64; 3]]| vec![x[0].map(|c| 2.0 * c), std::array::from_fn(|k| x[0][k] + x[1][k]), x[1].map(|c| 3.0 * c)];
        let at = |y: &[[f64; 3]]| vec![std::array::from_fn(|k| 2.0 * y[0][k] + y[1][k]), std::array::from_fn(|k| y[1][k] + 3.0 * y[2][k])];
        let truth = [[1.0, -2.0, 0.5], [3.0, 0.0, -1.0]];
        let b = a(&truth);
        let x = least_squares(a, at, &[[0.0; 3]; 2], &b, 10);
        for i in 0..2 {
            for k in 0..3 {
                assert!((x[i][k] - truth[i][k]).abs() < 1e-9, "{x:?}");
            }
        }
    }

    #[test]
    fn without_subdivision_the_base_stays() {
        let (base, input) = (octahedron(), sphere(2));
        assert_eq!(refit_base(&base, &[], &Bvh::new(&input.positions, &input.faces)), base.positions);
    }
}
