//! Welding: one vertex per distinct position.
//!
//! Captured frames repeat a vertex wherever their texture atlas had a seam (basketball_player
//! frame 11: 20,672 vertices on 19,743 positions, 21 pieces and 1,883 boundary edges; welded,
//! one piece and 83 boundary edges). Every such seam would be a hole rim that decimation must
//! keep and the anchor mesh must match across, so the encoder welds each input frame first,
//! as the MPEG test model's simplifier does. The input's per-corner UVs and texture are not
//! affected: texture transfer reads the original frame.

use std::collections::HashMap;

use crate::geom::mesh::Mesh;

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
    fn unused_vertices_go_and_a_clean_mesh_stays_as_it_is() {
        let m = Mesh::new(vec![[5.0; 3], [0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], vec![[1, 2, 3]]);
        let w = weld(&m);
        assert_eq!(w.positions, m.positions[1..].to_vec());
        assert_eq!(w.faces, vec![[0, 1, 2]]);
        assert_eq!(weld(&w), w);
    }
}
