//! Subdivision of the base mesh, with level-of-detail vertex order.
//!
//! Each iteration splits every triangle into four. The vertices of one iteration are
//! appended after all vertices of coarser levels, so a level of detail is a contiguous index
//! range, and each new vertex records its parent edge: the lifting transform and the
//! displacement coder rely on both.

use crate::mesh::{edge_key, EdgeMap};

/// How new vertices are placed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scheme {
    /// New vertices at edge midpoints; old vertices stay (the V-DMC default).
    Midpoint,
    /// Loop subdivision: smooths the surface; boundary and non-manifold edges fall back to
    /// midpoints, boundary vertices to the 1/8-3/4-1/8 rule.
    Loop,
}

/// A subdivided mesh with its level-of-detail structure.
#[derive(Debug, Clone, PartialEq)]
pub struct Subdivision {
    pub positions: Vec<[f64; 3]>,
    pub faces: Vec<[u32; 3]>,
    /// `parents[v - lod_offsets[1]]` is the edge whose split created vertex `v`.
    pub parents: Vec<[u32; 2]>,
    /// Start of each level of detail, then the vertex count: `[0, base, level1, ..., total]`.
    pub lod_offsets: Vec<usize>,
}

impl Subdivision {
    /// Number of levels of detail (base vertices count as level 0).
    pub fn lod_count(&self) -> usize {
        self.lod_offsets.len() - 1
    }

    /// Parent edge of vertex `v`, which must not be a base vertex.
    pub fn parent(&self, v: usize) -> [u32; 2] {
        self.parents[v - self.lod_offsets[1]]
    }
}

/// Subdivides `(positions, faces)` `iterations` times with `scheme`.
pub fn subdivide(positions: &[[f64; 3]], faces: &[[u32; 3]], iterations: u32, scheme: Scheme) -> Subdivision {
    let mut s = Subdivision {
        positions: positions.to_vec(),
        faces: faces.to_vec(),
        parents: Vec::new(),
        lod_offsets: vec![0, positions.len()],
    };
    for _ in 0..iterations {
        split_once(&mut s, scheme);
    }
    s
}

/// One 1-to-4 split, appending the new level.
fn split_once(s: &mut Subdivision, scheme: Scheme) {
    let n0 = s.positions.len();
    let mut edge_vertex: EdgeMap<u32> = EdgeMap::with_capacity_and_hasher(s.faces.len() * 3 / 2, Default::default());
    // Opposite corners of each edge, for Loop's odd-vertex rule.
    let mut opposite: Vec<[u32; 3]> = Vec::new();
    let mut new_faces = Vec::with_capacity(s.faces.len() * 4);
    for f in &s.faces {
        let mids: [u32; 3] = std::array::from_fn(|k| {
            let (a, b, c) = (f[k], f[(k + 1) % 3], f[(k + 2) % 3]);
            let key = edge_key(a, b);
            let next = (n0 + opposite.len()) as u32;
            let v = *edge_vertex.entry(key).or_insert(next);
            if v == next {
                s.parents.push([a.min(b), a.max(b)]);
                opposite.push([c, u32::MAX, 1]);
            } else {
                let o = &mut opposite[(v as usize) - n0];
                o[1] = c;
                o[2] += 1;
            }
            v
        });
        new_faces.push([f[0], mids[0], mids[2]]);
        new_faces.push([mids[0], f[1], mids[1]]);
        new_faces.push([mids[2], mids[1], f[2]]);
        new_faces.push([mids[0], mids[1], mids[2]]);
    }
    let first_parent = s.parents.len() - opposite.len();
    let odd: Vec<[f64; 3]> = (0..opposite.len())
        .map(|i| odd_position(&s.positions, s.parents[first_parent + i], opposite[i], scheme))
        .collect();
    if scheme == Scheme::Loop {
        smooth_even(&mut s.positions, &s.faces);
    }
    s.positions.extend(odd);
    s.faces = new_faces;
    s.lod_offsets.push(s.positions.len());
}

/// Position of the vertex that splits `edge`; `opp = [c, d, face count]`.
fn odd_position(p: &[[f64; 3]], edge: [u32; 2], opp: [u32; 3], scheme: Scheme) -> [f64; 3] {
    let (a, b) = (p[edge[0] as usize], p[edge[1] as usize]);
    if scheme == Scheme::Midpoint || opp[2] != 2 {
        return std::array::from_fn(|k| 0.5 * (a[k] + b[k]));
    }
    let (c, d) = (p[opp[0] as usize], p[opp[1] as usize]);
    std::array::from_fn(|k| 0.375 * (a[k] + b[k]) + 0.125 * (c[k] + d[k]))
}

/// Loop's rule for the old vertices: interior vertices move toward the mean of their
/// neighbours; boundary vertices use their two boundary neighbours only; vertices on
/// non-manifold edges stay put so that no ambiguous rule is applied.
fn smooth_even(positions: &mut [[f64; 3]], faces: &[[u32; 3]]) {
    let mut edge_faces: EdgeMap<u32> = EdgeMap::with_capacity_and_hasher(faces.len() * 3 / 2, Default::default());
    for f in faces {
        for k in 0..3 {
            *edge_faces.entry(edge_key(f[k], f[(k + 1) % 3])).or_insert(0) += 1;
        }
    }
    let n = positions.len();
    let mut ring: Vec<Vec<u32>> = vec![Vec::new(); n];
    let mut boundary: Vec<Vec<u32>> = vec![Vec::new(); n];
    let mut pinned = vec![false; n];
    let mut edges: Vec<(u64, u32)> = edge_faces.into_iter().collect();
    edges.sort_unstable();
    for (key, count) in edges {
        let (a, b) = ((key >> 32) as u32, key as u32);
        ring[a as usize].push(b);
        ring[b as usize].push(a);
        match count {
            1 => {
                boundary[a as usize].push(b);
                boundary[b as usize].push(a);
            }
            2 => {}
            _ => {
                pinned[a as usize] = true;
                pinned[b as usize] = true;
            }
        }
    }
    let old = positions.to_vec();
    for v in 0..n {
        if pinned[v] || ring[v].is_empty() {
            continue;
        }
        positions[v] = match boundary[v].len() {
            0 => interior_even(&old, v, &ring[v]),
            2 => {
                let (a, b) = (old[boundary[v][0] as usize], old[boundary[v][1] as usize]);
                std::array::from_fn(|k| 0.75 * old[v][k] + 0.125 * (a[k] + b[k]))
            }
            _ => old[v],
        };
    }
}

fn interior_even(old: &[[f64; 3]], v: usize, ring: &[u32]) -> [f64; 3] {
    let n = ring.len() as f64;
    let beta = if ring.len() == 3 { 3.0 / 16.0 } else { 3.0 / (8.0 * n) };
    let mut sum = [0.0; 3];
    for &u in ring {
        for k in 0..3 {
            sum[k] += old[u as usize][k];
        }
    }
    std::array::from_fn(|k| (1.0 - n * beta) * old[v][k] + beta * sum[k])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad() -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        (vec![[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 2.0, 0.0], [0.0, 2.0, 0.0]], vec![[0, 1, 2], [0, 2, 3]])
    }

    #[test]
    fn midpoint_levels_are_contiguous_and_new_vertices_sit_on_their_parent_edges() {
        let (p, f) = quad();
        let s = subdivide(&p, &f, 2, Scheme::Midpoint);
        // 4 + 5 edges -> 9 vertices, 9 + 16 edges -> 25 vertices.
        assert_eq!(s.lod_offsets, vec![0, 4, 9, 25]);
        assert_eq!(s.faces.len(), 32);
        for v in 4..s.positions.len() {
            let [a, b] = s.parent(v);
            assert!((a as usize) < v && (b as usize) < v && a < b);
            let (pa, pb) = (s.positions[a as usize], s.positions[b as usize]);
            for k in 0..3 {
                assert_eq!(s.positions[v][k], 0.5 * (pa[k] + pb[k]));
            }
        }
        assert_eq!(&s.positions[..4], &p[..]);
    }

    #[test]
    fn subdivided_faces_keep_orientation() {
        let (p, f) = quad();
        let s = subdivide(&p, &f, 1, Scheme::Midpoint);
        let normal_z = |t: &[u32; 3]| {
            let [a, b, c] = t.map(|v| s.positions[v as usize]);
            (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
        };
        assert!(s.faces.iter().all(|t| normal_z(t) > 0.0));
    }

    #[test]
    fn loop_keeps_a_flat_patch_flat_and_moves_interior_vertices() {
        let (p, f) = quad();
        let s = subdivide(&p, &f, 2, Scheme::Loop);
        assert_eq!(s.lod_offsets, vec![0, 4, 9, 25]);
        assert!(s.positions.iter().all(|q| q[2] == 0.0));
        let closed = [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-1.0, -1.0, 0.0]];
        let tet = vec![[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]];
        let s = subdivide(&closed, &tet, 1, Scheme::Loop);
        assert_ne!(s.positions[0], closed[0]);
    }

    #[test]
    fn zero_iterations_return_the_base_mesh() {
        let (p, f) = quad();
        let s = subdivide(&p, &f, 0, Scheme::Midpoint);
        assert_eq!(s.lod_count(), 1);
        assert_eq!(s.faces, f);
    }
}
