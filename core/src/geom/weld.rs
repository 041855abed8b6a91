//! Welding: one vertex per distinct position.
//!
//! Captured frames repeat a vertex wherever their texture atlas had a seam (basketball_player
//! frame 11: 20,672 vertices on 19,743 positions, 21 pieces and 1,883 boundary edges; welded,
//! one piece and 83 boundary edges). Every such seam would be a hole rim that decimation must
//! keep and the anchor mesh must match across, so the encoder welds each input frame first,
//! as the MPEG test model's simplifier does. The input's per-corner UVs and texture are not
//! affected: texture transfer reads the original frame.
//!
//! Then the faces that have no surface go too ([`surface_faces`]): those whose corners lie on
//! one line and those that repeat another face. They add nothing to the surface the codec
//! codes (nor to what the metrics sample), and in numbers they cost quadratic time:
//! decimated, a strip of 100,000 collinear faces became a base mesh of thousands of faces
//! stacked on a few grid points, and every closest-point search near such a stack tried every
//! face in it (28 s for one frame, minutes at 300,000 faces).

use std::collections::{HashMap, HashSet};

use crate::geom::mesh::{cross, dot, sub, Mesh};

/// A face whose largest angle has a sine squared at most this (a sine of 1e-10) has its
/// corners on one line: the threshold below which the closest-point search treats a triangle
/// as its edges (`bvh::closest_on_triangle`).
pub const COLLINEAR_SIN2: f64 = 1e-20;
/// ... and so has a face whose corner at the largest angle lies at most this far from the
/// longest edge, in grid units (a 2^-12 of the sequence box's largest side at the default 12
/// bits): rounding moves points computed on one line about 1e-12 units off it, which next to
/// a short edge makes a sine far above [`COLLINEAR_SIN2`].
pub const COLLINEAR_HEIGHT: f64 = 1e-9;

/// `mesh` with coincident positions merged into one vertex (first occurrence order), faces
/// that lose an edge to the merge dropped, and vertices that no remaining face uses
/// dropped. Positions are compared exactly (`-0.0` equals `0.0`). The faces keep their
/// order and orientation. Indices must be in range.
pub fn weld(mesh: &Mesh) -> Mesh {
    let mut first: HashMap<[u64; 3], u32> = HashMap::with_capacity(mesh.positions.len());
    let canonical: Vec<u32> = mesh
        .positions
        .iter()
        .enumerate()
        .map(|(i, p)| *first.entry(p.map(|c| (c + 0.0).to_bits())).or_insert(i as u32))
        .collect();
    let faces: Vec<[u32; 3]> = mesh
        .faces
        .iter()
        .map(|f| f.map(|v| canonical[v as usize]))
        .filter(|f| f[0] != f[1] && f[1] != f[2] && f[2] != f[0])
        .collect();
    compact(&mesh.positions, faces)
}

/// `mesh` (in grid units) without its faces that have no surface, and how many faces went: a
/// face whose corners lie on one line ([`has_area`]) or repeat a vertex, and a face with the three
/// vertices of an earlier one (in either orientation; the first stays). Vertices that no
/// remaining face uses are dropped; the rest keep their order, the faces their order and
/// orientation. A mesh that loses no face is returned as it is. Run after [`weld`], so that
/// faces whose corners coincide repeat a vertex. Linear in the faces (one hash per face).
pub fn surface_faces(mesh: Mesh) -> (Mesh, usize) {
    let p = &mesh.positions;
    let mut seen: HashSet<[u32; 3]> = HashSet::with_capacity(mesh.faces.len());
    let keep: Vec<bool> = mesh
        .faces
        .iter()
        .map(|f| {
            let mut key = *f;
            key.sort_unstable();
            has_area(f.map(|v| p[v as usize])) && seen.insert(key)
        })
        .collect();
    let dropped = keep.iter().filter(|&&k| !k).count();
    if dropped == 0 {
        return (mesh, 0);
    }
    let faces = mesh.faces.iter().zip(&keep).filter(|(_, &k)| k).map(|(f, _)| *f).collect();
    (compact(&mesh.positions, faces), dropped)
}

/// Whether the corners `[a, b, c]` (grid units) do not lie on one line: the sine of the
/// face's largest angle, between its two shorter edges, is above the root of
/// [`COLLINEAR_SIN2`], and that angle's corner lies farther than [`COLLINEAR_HEIGHT`] from the
/// longest edge. False when two corners coincide.
pub fn has_area([a, b, c]: [[f64; 3]; 3]) -> bool {
    let n = cross(sub(b, a), sub(c, a));
    let n2 = dot(n, n);
    let mut l = [sub(b, a), sub(c, b), sub(a, c)].map(|e| dot(e, e));
    l.sort_unstable_by(f64::total_cmp);
    // The height over the longest edge is |n| / sqrt(l[2]).
    n2 > COLLINEAR_SIN2 * l[0] * l[1] && n2 > COLLINEAR_HEIGHT * COLLINEAR_HEIGHT * l[2]
}

/// The vertices that `faces` use, in their original order, and the faces renumbered onto them.
fn compact(positions: &[[f64; 3]], mut faces: Vec<[u32; 3]>) -> Mesh {
    let mut new_index = vec![u32::MAX; positions.len()];
    let mut kept = Vec::new();
    let mut used = vec![false; positions.len()];
    for f in &faces {
        for &v in f {
            used[v as usize] = true;
        }
    }
    for (v, &u) in used.iter().enumerate() {
        if u {
            new_index[v] = kept.len() as u32;
            kept.push(positions[v]);
        }
    }
    for f in &mut faces {
        *f = f.map(|v| new_index[v as usize]);
    }
    Mesh::new(kept, faces)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_seam_is_closed_and_its_degenerate_face_dropped() {
        // Two triangles sharing the edge (1, 2) through duplicated vertices 3 and 4, plus a
        // face that collapses when 5 merges with 0.
        let p = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [-0.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
        ];
        let m = Mesh::new(p, vec![[0, 1, 2], [3, 6, 4], [5, 0, 1]]);
        let w = weld(&m);
        assert_eq!(w.positions, vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]]);
        assert_eq!(w.faces, vec![[0, 1, 2], [1, 3, 2]]);
    }

    #[test]
    fn faces_without_surface_go_with_their_vertices_and_the_rest_keep_their_order() {
        let p = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [2.0, 0.0, 0.0], // on the line through 0 and 1
            [1.0, 1.0, 0.0],
        ];
        // A proper face, a collinear one, a repetition in the other orientation, one more
        // proper face, a repetition in a rotated order, a face with a repeated vertex.
        let m = Mesh::new(p, vec![[0, 1, 2], [0, 3, 1], [0, 2, 1], [1, 4, 2], [4, 2, 1], [2, 2, 4]]);
        let (s, dropped) = surface_faces(m.clone());
        assert_eq!(dropped, 4);
        assert_eq!(s.positions, vec![m.positions[0], m.positions[1], m.positions[2], m.positions[4]]);
        assert_eq!(s.faces, vec![[0, 1, 2], [1, 3, 2]]);
        let (again, none) = surface_faces(s.clone());
        assert_eq!((again, none), (s, 0));
    }

    #[test]
    fn collinear_corners_are_found_to_rounding_at_any_slope_and_slivers_stay() {
        // Points of slanted lines across a 4096-unit grid, computed in floating point: not
        // exactly collinear, some corners close together.
        let on_line = |t: f64| [100.1 + 1000.3 * t, 2000.7 - 1100.1 * t, 5.2 + 3000.9 * t];
        let mut rng = crate::geom::testmesh::Rng(5);
        for _ in 0..10_000 {
            let t = [rng.range(0.0, 1.0), rng.range(0.0, 1.0), rng.range(0.0, 1e-3)];
            let [a, b, c] = [t[0], t[0] + t[2], t[1]].map(on_line);
            assert!(!has_area([a, b, c]) && !has_area([c, a, b]), "{t:?}");
        }
        // A needle (a tiny angle at one corner only), a flat cap 1e-6 high and a tiny
        // triangle keep their area.
        assert!(has_area([[0.0, 0.0, 0.0], [1e3, 0.0, 0.0], [1e3, 1.0, 0.0]]));
        assert!(has_area([[0.0, 0.0, 0.0], [0.5, 1e-6, 0.0], [1.0, 0.0, 0.0]]));
        assert!(has_area([[0.0, 0.0, 0.0], [1e-6, 0.0, 0.0], [0.0, 1e-6, 0.0]]));
        assert!(!has_area([[1.0; 3], [1.0; 3], [2.0, 0.0, 0.0]]));
    }

    #[test]
    fn unused_vertices_go_and_a_clean_mesh_stays_as_it_is() {
        let m = Mesh::new(vec![[5.0; 3], [0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], vec![[1, 2, 3]]);
        let w = weld(&m);
        assert_eq!(w.positions, m.positions[1..].to_vec());
        assert_eq!(w.faces, vec![[0, 1, 2]]);
        assert_eq!(weld(&w), w);
    }
}
