//! The base mesh of a frame whose input has the same connectivity as the reference's input
//! (constant topology, the MPEG test model's only inter case): every base vertex rides on
//! an input surface point.
//!
//! A vertex is bound once, where a run of frames with one connectivity begins: to the
//! closest point on that frame's input (triangle and barycentric coordinates) and its
//! offset from it. In every later frame of the run it goes to the same barycentric point of
//! the same triangle, plus the offset. Binding again in every frame, from the decoded
//! (quantized) base, let vertices wander along the surface and jump between parts that
//! pass close to each other, such as two legs: on horse_gallop that cost 10 % more bytes
//! for the same D1 (D1 BD-rate against all-intra -47 % instead of -52 %).

use rayon::prelude::*;

use crate::geom::bvh::Bvh;
use crate::geom::mesh::{add, interpolate, sub, Mesh};

/// True when `a` and `b` have the same vertex count and the same triangles in the same order.
pub fn same_connectivity(a: &Mesh, b: &Mesh) -> bool {
    a.positions.len() == b.positions.len() && a.faces == b.faces
}

/// Where a base vertex sits on an input surface: a triangle, the barycentric coordinates
/// of the vertex's closest point on it, and the vertex's offset from that point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Binding {
    triangle: u32,
    weights: [f64; 3],
    offset: [f64; 3],
}

/// One binding per point; `None` for a point that has nothing to bind to.
pub type Bindings = Vec<Option<Binding>>;

/// Binds each point of `base` to its closest point on the input surface that `surface`
/// indexes (the encoder's index of the reference input); `None` for every point when the
/// input has no triangles.
pub fn bind(base: &[[f64; 3]], surface: &Bvh) -> Bindings {
    base.par_iter()
        .map(|&p| {
            let hit = surface.closest_point(p)?;
            Some(Binding { triangle: hit.triangle, weights: hit.bary, offset: sub(p, hit.point) })
        })
        .collect()
}

/// The positions of bound points on `input`, which must have the connectivity of the input
/// they were bound on; an unbound point keeps its position in `unbound`.
pub fn bound_positions(bindings: &[Option<Binding>], input: &Mesh, unbound: &[[f64; 3]]) -> Vec<[f64; 3]> {
    bindings
        .iter()
        .zip(unbound)
        .map(|(b, &p)| {
            let Some(b) = b else { return p };
            let corners = input.faces[b.triangle as usize].map(|v| input.positions[v as usize]);
            add(interpolate(corners, b.weights), b.offset)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn index(m: &Mesh) -> Bvh {
        Bvh::new(&m.positions, &m.faces)
    }

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
        let moved = bound_positions(&bind(&base, &index(&a)), &b, &base);
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
        let p = [[1.5, 2.5, 0.75]];
        let moved = bound_positions(&bind(&p, &index(&a)), &b, &p);
        assert!((moved[0][0] - 11.5).abs() < 1e-9 && (moved[0][2] - 0.75).abs() < 1e-9);
    }

    #[test]
    fn a_binding_holds_when_another_part_comes_closer() {
        // Two parallel triangles 1 apart; a point 0.4 above the lower one is bound to it.
        // Then the upper one comes down to 0.6 and the lower one slides along x, twice. The
        // point follows the lower triangle throughout; finding its closest point again in
        // the second frame would move it to the upper one, now 0.2 away.
        let mut a = Mesh::new(vec![[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [0.0, 4.0, 0.0]], vec![[0, 1, 2], [3, 4, 5]]);
        a.positions.extend(a.positions.clone().iter().map(|q| [q[0], q[1], 1.0]));
        let slid = |m: &Mesh| {
            let mut m = m.clone();
            m.positions[..3].iter_mut().for_each(|q| q[0] += 1.0);
            m.positions[3..].iter_mut().for_each(|q| q[2] = 0.6);
            m
        };
        let (b, c) = (slid(&a), slid(&slid(&a)));
        let p = [[1.0, 1.0, 0.4]];
        let bindings = bind(&p, &index(&a));
        let at_b = bound_positions(&bindings, &b, &p);
        let at_c = bound_positions(&bindings, &c, &p);
        let near = |x: [f64; 3], y: [f64; 3]| (0..3).all(|k| (x[k] - y[k]).abs() < 1e-9);
        assert!(near(at_b[0], [2.0, 1.0, 0.4]) && near(at_c[0], [3.0, 1.0, 0.4]), "{at_b:?} {at_c:?}");
        assert_eq!(bind(&at_b, &index(&b))[0].map(|x| x.triangle), Some(1), "a fresh binding would jump");
        let empty = Mesh::default();
        assert_eq!(bound_positions(&bind(&p, &index(&empty)), &empty, &p), p.to_vec());
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
