//! The triangle mesh that flows through the pipeline.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use rayon::prelude::*;

use crate::error::InputError;

/// The key of the undirected edge `{a, b}`.
#[inline]
pub fn edge_key(a: u32, b: u32) -> u64 {
    ((a.min(b) as u64) << 32) | a.max(b) as u64
}

/// A hash map keyed by edge (or other packed `u64`) keys. The default SipHash guards against
/// adversarial keys, which vertex indices are not; a multiplicative hash is several times
/// faster on the subdivision and connectivity hot paths.
pub type EdgeMap<V> = HashMap<u64, V, BuildHasherDefault<EdgeHasher>>;

/// Fibonacci hashing of one `u64`, folded so that the low bits depend on every input bit.
#[derive(Default)]
pub struct EdgeHasher(u64);

impl Hasher for EdgeHasher {
    #[inline]
    fn write_u64(&mut self, key: u64) {
        let h = key.wrapping_mul(0x9E37_79B9_7F4A_7C15);
        self.0 = h ^ (h >> 29);
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(self.0 ^ b as u64);
        }
    }
    #[inline]
    fn finish(&self) -> u64 {
        self.0
    }
}

/// An indexed triangle mesh: positions and counter-clockwise triangles.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    pub positions: Vec<[f64; 3]>,
    pub faces: Vec<[u32; 3]>,
}

impl Mesh {
    pub fn new(positions: Vec<[f64; 3]>, faces: Vec<[u32; 3]>) -> Self {
        Self { positions, faces }
    }

    /// Checks what every stage relies on: at least one face, indices in range, finite
    /// coordinates.
    pub fn validate(&self) -> Result<(), InputError> {
        if self.faces.is_empty() {
            return Err(InputError("mesh has no faces".into()));
        }
        if let Some(i) = self.positions.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(InputError(format!("vertex {i} has a NaN or infinite coordinate")));
        }
        let n = self.positions.len() as u64;
        if let Some(f) = self.faces.iter().position(|f| f.iter().any(|&v| v as u64 >= n)) {
            return Err(InputError(format!(
                "face {f} refers to a vertex beyond the {n} vertices of the mesh"
            )));
        }
        Ok(())
    }

    /// Axis-aligned bounding box `(min, max)` of the positions; `None` when there are none.
    pub fn bounds(&self) -> Option<([f64; 3], [f64; 3])> {
        bounds(&self.positions)
    }
}

/// Axis-aligned bounding box `(min, max)` of a point set; `None` when it is empty.
pub fn bounds(points: &[[f64; 3]]) -> Option<([f64; 3], [f64; 3])> {
    let first = *points.first()?;
    Some(points.iter().fold((first, first), |(mut lo, mut hi), p| {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
        (lo, hi)
    }))
}

#[inline]
pub fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline]
pub fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

#[inline]
pub fn scale(a: [f64; 3], s: f64) -> [f64; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}

#[inline]
pub fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline]
pub fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// Squared distance from `a` to `b`.
#[inline]
pub fn dist2(a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = sub(a, b);
    dot(d, d)
}

#[inline]
pub fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// The point with barycentric coordinates `w` in the triangle `corners`.
#[inline]
pub fn interpolate(corners: [[f64; 3]; 3], w: [f64; 3]) -> [f64; 3] {
    add(add(scale(corners[0], w[0]), scale(corners[1], w[1])), scale(corners[2], w[2]))
}

/// `a / |a|`, or zero when `a` is (numerically) zero.
#[inline]
pub fn normalize(a: [f64; 3]) -> [f64; 3] {
    let n = norm(a);
    if n > 1e-300 { scale(a, 1.0 / n) } else { [0.0; 3] }
}

/// Area-weighted vertex normals (unit length; zero for isolated vertices).
pub fn vertex_normals(positions: &[[f64; 3]], faces: &[[u32; 3]]) -> Vec<[f64; 3]> {
    let mut acc = vec![[0.0f64; 3]; positions.len()];
    for f in faces {
        let [a, b, c] = f.map(|v| positions[v as usize]);
        let n = cross(sub(b, a), sub(c, a));
        for &v in f {
            acc[v as usize] = add(acc[v as usize], n);
        }
    }
    acc.into_iter().map(normalize).collect()
}

/// Neighbour lists of a face list over `n` vertices (indices in range), sorted and without repeats
/// (compressed rows: neighbours of `v` are `adj[start[v]..start[v + 1]]`). The one vertex
/// adjacency of the codec: motion coding, the displacement refinement and the adaptive
/// quantization's valences (on every decoded frame's subdivided mesh) read it.
pub struct Adjacency {
    start: Vec<usize>,
    adj: Vec<u32>,
}

impl Adjacency {
    pub fn new(n: usize, faces: &[[u32; 3]]) -> Self {
        // One array laid out by a counting pass (no per-vertex allocation), each row then
        // sorted and deduplicated in parallel, and the rows closed up.
        let mut start = vec![0usize; n + 1];
        for f in faces {
            for &v in f {
                start[v as usize + 1] += 2;
            }
        }
        for v in 0..n {
            start[v + 1] += start[v];
        }
        let mut fill = start.clone();
        let mut adj = vec![0u32; start[n]];
        for f in faces {
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                adj[fill[a as usize]] = b;
                fill[a as usize] += 1;
                adj[fill[b as usize]] = a;
                fill[b as usize] += 1;
            }
        }
        let mut rows: Vec<&mut [u32]> = Vec::with_capacity(n);
        let mut rest = &mut adj[..];
        for v in 0..n {
            let (row, tail) = rest.split_at_mut(start[v + 1] - start[v]);
            rows.push(row);
            rest = tail;
        }
        let lens: Vec<usize> = rows.into_par_iter().map(sorted_distinct).collect();
        let mut closed = 0;
        for v in 0..n {
            adj.copy_within(start[v]..start[v] + lens[v], closed);
            start[v] = closed;
            closed += lens[v];
        }
        start[n] = closed;
        adj.truncate(closed);
        Self { start, adj }
    }

    /// The neighbours of `v`, ascending.
    pub fn of(&self, v: usize) -> &[u32] {
        &self.adj[self.start[v]..self.start[v + 1]]
    }
}

/// Sorts `row` and moves its distinct values to the front; returns how many there are.
fn sorted_distinct(row: &mut [u32]) -> usize {
    row.sort_unstable();
    let mut len = 0;
    for i in 0..row.len() {
        if i == 0 || row[i] != row[len - 1] {
            row[len] = row[i];
            len += 1;
        }
    }
    len
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri() -> Mesh {
        Mesh::new(vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], vec![[0, 1, 2]])
    }

    #[test]
    fn validate_accepts_a_triangle_and_rejects_bad_meshes() {
        assert!(tri().validate().is_ok());
        let mut m = tri();
        m.faces[0][2] = 3;
        assert!(m.validate().unwrap_err().0.contains("face 0"));
        let mut m = tri();
        m.positions[1][1] = f64::NAN;
        assert!(m.validate().unwrap_err().0.contains("vertex 1"));
        let m = Mesh::new(tri().positions, vec![]);
        assert!(m.validate().is_err());
    }

    #[test]
    fn normals_of_a_ccw_triangle_point_up() {
        let m = tri();
        let n = vertex_normals(&m.positions, &m.faces);
        assert_eq!(n, vec![[0.0, 0.0, 1.0]; 3]);
    }
}
