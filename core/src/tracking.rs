//! The base mesh of a frame whose input has the same connectivity as the reference's input
//! (constant topology, the MPEG test model's only inter case): every reference base vertex
//! rides on the input surface point it sits closest to.
//!
//! The point is found on the reference input (triangle and barycentric coordinates); since
//! the current input has the same triangles, the same barycentric point on the current
//! triangle is where the vertex goes, and it keeps its offset from the surface.

use rayon::prelude::*;

use crate::bvh::Bvh;
use crate::mesh::{add, dot, sub, Mesh};

/// True when `a` and `b` have the same vertex count and the same triangles in the same order.
pub fn same_connectivity(a: &Mesh, b: &Mesh) -> bool {
    a.positions.len() == b.positions.len() && a.faces == b.faces
}

/// Positions of the reference base vertices `base` (on `reference_input`) carried to
/// `current_input`, which must have `reference_input`'s connectivity.
pub fn tracked_positions(base: &[[f64; 3]], reference_input: &Mesh, current_input: &Mesh) -> Vec<[f64; 3]> {
    debug_assert!(same_connectivity(reference_input, current_input));
    let bvh = Bvh::new(&reference_input.positions, &reference_input.faces);
    base.par_iter()
        .map(|&p| {
            let Some(hit) = bvh.closest_point(p) else { return p };
            let f = reference_input.faces[hit.triangle as usize];
            let corner = |m: &Mesh, k: usize| m.positions[f[k] as usize];
            let w = barycentric(hit.point, corner(reference_input, 0), corner(reference_input, 1), corner(reference_input, 2));
            let moved: [f64; 3] = std::array::from_fn(|i| (0..3).map(|k| w[k] * corner(current_input, k)[i]).sum());
            add(moved, sub(p, hit.point))
        })
        .collect()
}

/// Barycentric coordinates of `p` (assumed in the plane of `abc`); a degenerate triangle
/// gives its first corner.
fn barycentric(p: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [f64; 3] {
    let (v0, v1, v2) = (sub(b, a), sub(c, a), sub(p, a));
    let (d00, d01, d11) = (dot(v0, v0), dot(v0, v1), dot(v1, v1));
    let (d20, d21) = (dot(v2, v0), dot(v2, v1));
    let den = d00 * d11 - d01 * d01;
    if den.abs() <= f64::EPSILON * d00 * d11 || den == 0.0 {
        return [1.0, 0.0, 0.0];
    }
    let v = (d11 * d20 - d01 * d21) / den;
    let w = (d00 * d21 - d01 * d20) / den;
    [1.0 - v - w, v, w]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sheet() -> Mesh {
        let p = (0..5).flat_map(|y| (0..5).map(move |x| [x as f64, y as f64, 0.0])).collect();
        let mut f = Vec::new();
        for y in 0..4u32 {
            for x in 0..4u32 {
                let i = y * 5 + x;
                f.push([i, i + 1, i + 5]);
                f.push([i + 1, i + 6, i + 5]);
            }
        }
        Mesh::new(p, f)
    }

    #[test]
    fn points_follow_an_affine_motion_of_the_input_exactly() {
        let a = sheet();
        let mut b = a.clone();
        for p in &mut b.positions {
            *p = [2.0 * p[0] + 1.0, p[1] - 3.0, 0.5 * p[0]];
        }
        let base = [[0.5, 0.5, 0.0], [3.25, 1.75, 0.0], [4.0, 4.0, 0.0]];
        let moved = tracked_positions(&base, &a, &b);
        for (q, m) in base.iter().zip(&moved) {
            let expect = [2.0 * q[0] + 1.0, q[1] - 3.0, 0.5 * q[0]];
            assert!((0..3).all(|k| (m[k] - expect[k]).abs() < 1e-9), "{m:?} vs {expect:?}");
        }
    }

    #[test]
    fn the_offset_from_the_surface_is_kept() {
        let a = sheet();
        let mut b = a.clone();
        b.positions.iter_mut().for_each(|p| p[0] += 10.0);
        let moved = tracked_positions(&[[1.5, 2.5, 0.75]], &a, &b);
        assert!((moved[0][0] - 11.5).abs() < 1e-9 && (moved[0][2] - 0.75).abs() < 1e-9);
    }

    #[test]
    fn connectivity_comparison() {
        let a = sheet();
        let mut b = a.clone();
        assert!(same_connectivity(&a, &b));
        b.faces.swap(0, 1);
        assert!(!same_connectivity(&a, &b));
    }
}
