//! Subdivision of the base mesh, with level-of-detail vertex order.
//!
//! Each iteration splits every triangle into four. The vertices of one iteration are
//! appended after all vertices of coarser levels, so a level of detail is a contiguous index
//! range, and each new vertex records its parent edge: the lifting transform and the
//! displacement coder rely on both.
//!
//! A textured mesh's UV triangles are split the same way ([`subdivide_uv`]), face for face
//! and corner for corner, so that the subdivided mesh keeps its atlas. UVs are always
//! interpolated linearly: a texture is mapped piecewise linearly whatever smoothing the
//! positions get.

use rayon::prelude::*;

use crate::geom::mesh::{edge_key, EdgeMap};

/// How one iteration places its new vertices.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scheme {
    /// New vertices at edge midpoints; old vertices stay.
    Midpoint,
    /// Loop subdivision: smooths the surface; boundary and non-manifold edges fall back to
    /// midpoints, boundary vertices to the 1/8-3/4-1/8 rule.
    Loop,
}

impl Scheme {
    pub const NAMES: [&'static str; 2] = ["midpoint", "loop"];

    pub fn name(self) -> &'static str {
        Self::NAMES[self as usize]
    }

    pub fn from_name(name: &str) -> Option<Self> {
        [Self::Midpoint, Self::Loop].into_iter().find(|s| s.name() == name)
    }
}

/// The schemes of a subdivision's iterations, as an encoder option.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SchemeChoice {
    /// Midpoint on every iteration but the last, Loop on the last: the MPEG test model's
    /// choice (`lodAdaptiveSubdivisionFlag`), which smooths only the finest level, where
    /// the surface is already close to the input.
    Mixed,
    /// One scheme for every iteration.
    All(Scheme),
    /// One scheme per iteration, coarsest first.
    PerIteration(Vec<Scheme>),
}

impl SchemeChoice {
    /// Parses `mixed`, a scheme name, or a comma-separated list of names, one per iteration.
    pub fn parse(spec: &str) -> Result<Self, String> {
        let names: Vec<&str> = spec.split(',').map(str::trim).collect();
        let unknown = || format!("unknown subdivision scheme {spec:?} (mixed, {}, or a comma-separated list of them)", Scheme::NAMES.join(", "));
        match names.as_slice() {
            ["mixed"] => Ok(Self::Mixed),
            [one] => Scheme::from_name(one).map(Self::All).ok_or_else(unknown),
            many => many.iter().map(|n| Scheme::from_name(n)).collect::<Option<Vec<_>>>().map(Self::PerIteration).ok_or_else(unknown),
        }
    }

    /// The option's spelling, which [`SchemeChoice::parse`] reads back.
    pub fn spec(&self) -> String {
        match self {
            Self::Mixed => "mixed".into(),
            Self::All(s) => s.name().into(),
            Self::PerIteration(v) => v.iter().map(|s| s.name()).collect::<Vec<_>>().join(","),
        }
    }

    /// The scheme of each of `iterations` iterations; an error when a per-iteration list
    /// has another length.
    pub fn schemes(&self, iterations: u32) -> Result<Vec<Scheme>, String> {
        let n = iterations as usize;
        match self {
            Self::Mixed => Ok((0..n).map(|i| if i + 1 == n { Scheme::Loop } else { Scheme::Midpoint }).collect()),
            Self::All(s) => Ok(vec![*s; n]),
            Self::PerIteration(v) if v.len() == n => Ok(v.clone()),
            Self::PerIteration(v) => Err(format!("{} subdivision schemes given for {n} iterations", v.len())),
        }
    }
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
    /// Iteration `i`'s positions are `stencils[i]` applied to iteration `i - 1`'s (the base
    /// mesh's for `i = 0`): the subdivision is linear in the base positions, which is what
    /// lets the encoder fit the base mesh so that its subdivision fits the input.
    pub stencils: Vec<Stencils>,
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

    /// The subdivided positions of other base positions `base` (one per base vertex), on
    /// this subdivision's connectivity.
    pub fn apply(&self, base: &[[f64; 3]]) -> Vec<[f64; 3]> {
        self.stencils.iter().fold(base.to_vec(), |p, s| s.apply(&p))
    }

    /// The transpose of [`Subdivision::apply`], built once for repeated use (the base refit
    /// applies it at every conjugate-gradient iteration).
    pub fn transposed(&self) -> Transposed {
        let levels = self.stencils.iter().enumerate().rev().map(|(i, s)| s.transposed(self.lod_offsets[i + 1])).collect();
        Transposed { levels }
    }
}

/// The transpose of a [`Subdivision`]'s map from base to subdivided positions: it gathers one
/// vector per subdivided vertex back onto the base vertices.
#[derive(Debug, Clone, PartialEq)]
pub struct Transposed {
    /// The finest level's transposed stencils first.
    levels: Vec<Stencils>,
}

impl Transposed {
    /// `y` (one vector per subdivided vertex) gathered onto the base vertices: each base
    /// vector is the weighted sum of the subdivided vectors that its stencils reach, summed
    /// in ascending vertex order, as a scatter in vertex order would sum them.
    pub fn apply(&self, y: &[[f64; 3]]) -> Vec<[f64; 3]> {
        self.levels.iter().fold(y.to_vec(), |g, s| s.apply(&g))
    }
}

/// One iteration's position rule: each vertex of the new level as a weighted sum of the
/// vertices of the level before.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Stencils {
    /// Row `v` is `entries[starts[v]..starts[v + 1]]`.
    starts: Vec<u32>,
    entries: Vec<(u32, f64)>,
}

impl Stencils {
    fn push(&mut self, row: &[(u32, f64)]) {
        if self.starts.is_empty() {
            self.starts.push(0);
        }
        self.entries.extend_from_slice(row);
        self.starts.push(self.entries.len() as u32);
    }

    fn row(&self, v: usize) -> &[(u32, f64)] {
        &self.entries[self.starts[v] as usize..self.starts[v + 1] as usize]
    }

    fn rows(&self) -> usize {
        self.starts.len().saturating_sub(1)
    }

    /// The new level's positions from the previous level's `p`: each row's weighted
    /// positions summed in row order, starting from zero.
    pub fn apply(&self, p: &[[f64; 3]]) -> Vec<[f64; 3]> {
        (0..self.rows())
            .into_par_iter()
            .map(|v| {
                self.row(v).iter().fold([0.0; 3], |acc, &(u, w)| {
                    let q = p[u as usize];
                    [acc[0] + w * q[0], acc[1] + w * q[1], acc[2] + w * q[2]]
                })
            })
            .collect()
    }

    /// The stencils of the transpose onto the `n` vertices of the previous level: row `u`
    /// holds `(v, w)` for each entry `(u, w)` of row `v`, in ascending `v` (and row order
    /// within a row), so that [`Stencils::apply`] on it sums what a scatter of the rows in
    /// order would, in the same order, and on all threads.
    fn transposed(&self, n: usize) -> Stencils {
        let mut starts = vec![0u32; n + 1];
        for &(u, _) in &self.entries {
            starts[u as usize + 1] += 1;
        }
        for u in 0..n {
            starts[u + 1] += starts[u];
        }
        let mut next = starts.clone();
        let mut entries = vec![(0u32, 0.0); self.entries.len()];
        for v in 0..self.rows() {
            for &(u, w) in self.row(v) {
                let slot = &mut next[u as usize];
                entries[*slot as usize] = (v as u32, w);
                *slot += 1;
            }
        }
        Stencils { starts, entries }
    }
}

/// Subdivides `(positions, faces)` once per entry of `schemes`, with that scheme.
pub fn subdivide(positions: &[[f64; 3]], faces: &[[u32; 3]], schemes: &[Scheme]) -> Subdivision {
    let mut s = Subdivision {
        positions: positions.to_vec(),
        faces: faces.to_vec(),
        parents: Vec::new(),
        lod_offsets: vec![0, positions.len()],
        stencils: Vec::with_capacity(schemes.len()),
    };
    for &scheme in schemes {
        split_once(&mut s, scheme);
    }
    s
}

/// The faces of `faces` (over `n_vertices` vertices) split `iterations` times, as
/// [`subdivide`] splits them whatever the scheme, without positions, and the vertex count:
/// face `i` of the result is face `i` of `subdivide(..).faces`.
pub fn subdivided_faces(faces: &[[u32; 3]], n_vertices: usize, iterations: usize) -> (Vec<[u32; 3]>, usize) {
    let (mut faces, mut n) = (faces.to_vec(), n_vertices);
    for _ in 0..iterations {
        let split = split_faces(&faces, n);
        n += split.parents.len();
        faces = split.faces;
    }
    (faces, n)
}

/// One 1-to-4 split of a connectivity.
struct Split {
    faces: Vec<[u32; 3]>,
    /// Per new vertex (numbered on from the old vertices in order of first use), the edge it
    /// splits, as `[min, max]`.
    parents: Vec<[u32; 2]>,
    /// Per new vertex, the corners opposite its edge (the second `u32::MAX` on a border) and
    /// how many faces share the edge, for Loop's odd-vertex rule.
    opposite: Vec<[u32; 3]>,
}

/// Splits each face of `faces` (over `n0` vertices) into four with [`split_face`].
fn split_faces(faces: &[[u32; 3]], n0: usize) -> Split {
    let mut edge_vertex: EdgeMap<u32> = EdgeMap::with_capacity_and_hasher(faces.len() * 3 / 2, Default::default());
    let mut split = Split { faces: Vec::with_capacity(faces.len() * 4), parents: Vec::new(), opposite: Vec::new() };
    for f in faces {
        let mids: [u32; 3] = std::array::from_fn(|k| {
            let (a, b, c) = (f[k], f[(k + 1) % 3], f[(k + 2) % 3]);
            let key = edge_key(a, b);
            let next = (n0 + split.opposite.len()) as u32;
            let v = *edge_vertex.entry(key).or_insert(next);
            if v == next {
                split.parents.push([a.min(b), a.max(b)]);
                split.opposite.push([c, u32::MAX, 1]);
            } else {
                let o = &mut split.opposite[(v as usize) - n0];
                o[1] = c;
                o[2] += 1;
            }
            v
        });
        split.faces.extend(split_face(f, mids));
    }
    split
}

/// One 1-to-4 split, appending the new level.
fn split_once(s: &mut Subdivision, scheme: Scheme) {
    let n0 = s.positions.len();
    let Split { faces: new_faces, parents, opposite } = split_faces(&s.faces, n0);
    s.parents.extend(parents);
    let mut stencils = Stencils::default();
    if scheme == Scheme::Loop {
        even_loop_stencils(n0, &s.faces, &mut stencils);
    } else {
        (0..n0 as u32).for_each(|v| stencils.push(&[(v, 1.0)]));
    }
    let first_parent = s.parents.len() - opposite.len();
    for (i, opp) in opposite.iter().enumerate() {
        stencils.push(&odd_stencil(s.parents[first_parent + i], *opp, scheme));
    }
    s.positions = stencils.apply(&s.positions);
    s.stencils.push(stencils);
    s.faces = new_faces;
    s.lod_offsets.push(s.positions.len());
}

/// The four children of triangle `f` whose edge `f[k] -> f[k + 1]` is split by `mids[k]`:
/// the three corner triangles, then the middle one, each keeping `f`'s orientation. Every
/// split (positions and UVs) goes through here, so that face `i` of one subdivision matches
/// face `i` of another.
fn split_face(f: &[u32; 3], mids: [u32; 3]) -> [[u32; 3]; 4] {
    [[f[0], mids[0], mids[2]], [mids[0], f[1], mids[1]], [mids[2], mids[1], f[2]], [mids[0], mids[1], mids[2]]]
}

/// Subdivides a mesh's UV triangles `iterations` times as [`subdivide`] does its faces:
/// `uv_faces[f]` gives the UVs of the corners of face `f` (indices into `uv`), and the
/// result's face `i` gives the UVs of the corners of `subdivide(..).faces[i]` for the same
/// iterations, whatever the scheme. New UVs are edge midpoints, appended level by level;
/// edges are keyed by UV indices, so a seam (a position edge with different UVs on its two
/// sides) stays a seam. Panics if an index is beyond `uv`.
pub fn subdivide_uv(uv: &[[f64; 2]], uv_faces: &[[u32; 3]], iterations: u32) -> (Vec<[f64; 2]>, Vec<[u32; 3]>) {
    let mut uv = uv.to_vec();
    let mut faces = uv_faces.to_vec();
    for _ in 0..iterations {
        let mut edge_uv: EdgeMap<u32> = EdgeMap::with_capacity_and_hasher(faces.len() * 3 / 2, Default::default());
        let mut new_faces = Vec::with_capacity(faces.len() * 4);
        for f in &faces {
            let mids: [u32; 3] = std::array::from_fn(|k| {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                *edge_uv.entry(edge_key(a, b)).or_insert_with(|| {
                    let (pa, pb) = (uv[a as usize], uv[b as usize]);
                    uv.push([0.5 * (pa[0] + pb[0]), 0.5 * (pa[1] + pb[1])]);
                    (uv.len() - 1) as u32
                })
            });
            new_faces.extend(split_face(f, mids));
        }
        faces = new_faces;
    }
    (uv, faces)
}

/// The weights of the vertex that splits `edge`; `opp = [c, d, face count]`: the midpoint,
/// or with Loop on an edge of exactly two faces `3/8 (a + b) + 1/8 (c + d)`.
fn odd_stencil(edge: [u32; 2], opp: [u32; 3], scheme: Scheme) -> Vec<(u32, f64)> {
    if scheme == Scheme::Midpoint || opp[2] != 2 {
        return vec![(edge[0], 0.5), (edge[1], 0.5)];
    }
    vec![(edge[0], 0.375), (edge[1], 0.375), (opp[0], 0.125), (opp[1], 0.125)]
}

/// Loop's rule for the old vertices, one row each: interior vertices move toward the mean
/// of their neighbours; boundary vertices use their two boundary neighbours only; vertices
/// on non-manifold edges stay put so that no ambiguous rule is applied.
fn even_loop_stencils(n: usize, faces: &[[u32; 3]], stencils: &mut Stencils) {
    let mut edge_faces: EdgeMap<u32> = EdgeMap::with_capacity_and_hasher(faces.len() * 3 / 2, Default::default());
    for f in faces {
        for k in 0..3 {
            *edge_faces.entry(edge_key(f[k], f[(k + 1) % 3])).or_insert(0) += 1;
        }
    }
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
    let mut row = Vec::new();
    for v in 0..n {
        row.clear();
        let me = v as u32;
        match (pinned[v] || ring[v].is_empty(), boundary[v].len()) {
            (false, 0) => {
                let k = ring[v].len() as f64;
                let beta = if ring[v].len() == 3 { 3.0 / 16.0 } else { 3.0 / (8.0 * k) };
                row.push((me, 1.0 - k * beta));
                row.extend(ring[v].iter().map(|&u| (u, beta)));
            }
            (false, 2) => row.extend([(me, 0.75), (boundary[v][0], 0.125), (boundary[v][1], 0.125)]),
            _ => row.push((me, 1.0)),
        }
        stencils.push(&row);
    }
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
        let s = subdivide(&p, &f, &[Scheme::Midpoint; 2]);
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
        let s = subdivide(&p, &f, &[Scheme::Midpoint]);
        let normal_z = |t: &[u32; 3]| {
            let [a, b, c] = t.map(|v| s.positions[v as usize]);
            (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
        };
        assert!(s.faces.iter().all(|t| normal_z(t) > 0.0));
    }

    #[test]
    fn loop_keeps_a_flat_patch_flat_and_moves_interior_vertices() {
        let (p, f) = quad();
        let s = subdivide(&p, &f, &[Scheme::Loop; 2]);
        assert_eq!(s.lod_offsets, vec![0, 4, 9, 25]);
        assert!(s.positions.iter().all(|q| q[2] == 0.0));
        let closed = [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-1.0, -1.0, 0.0]];
        let tet = vec![[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]];
        let s = subdivide(&closed, &tet, &[Scheme::Loop]);
        assert_ne!(s.positions[0], closed[0]);
    }

    /// Positions, faces, UVs, UV faces.
    type TexturedMesh = (Vec<[f64; 3]>, Vec<[u32; 3]>, Vec<[f64; 2]>, Vec<[u32; 3]>);

    /// Two triangles sharing the position edge 1-2, with different UVs on either side of it
    /// (a seam); on each side the UV is an affine function of the position.
    fn seamed_pair() -> TexturedMesh {
        let p = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]];
        let f = vec![[0, 1, 2], [1, 3, 2]];
        let uv = [[0.1, 0.2], [0.3, 0.2], [0.1, 0.4], [0.9, 0.1], [0.7, 0.3], [0.7, 0.1]];
        (p, f, uv.to_vec(), vec![[0, 1, 2], [3, 4, 5]])
    }

    /// The UV map of [`seamed_pair`]: face 0's side, face 1's side.
    fn chart(p: [f64; 3], side: usize) -> [f64; 2] {
        match side {
            0 => [0.1 + 0.2 * p[0], 0.2 + 0.2 * p[1]],
            _ => [0.9 - 0.2 * p[1], 0.1 + 0.2 * (p[0] + p[1] - 1.0)],
        }
    }

    #[test]
    fn uv_subdivision_follows_the_faces_and_keeps_the_seam() {
        let (p, f, uv, uv_faces) = seamed_pair();
        for (i, t) in f.iter().enumerate() {
            for k in 0..3 {
                let expect = chart(p[t[k] as usize], i);
                let got = uv[uv_faces[i][k] as usize];
                assert!((0..2).all(|a| (got[a] - expect[a]).abs() < 1e-12), "base face {i} corner {k}");
            }
        }
        for scheme in [Scheme::Midpoint, Scheme::Loop] {
            let s = subdivide(&p, &f, &[scheme; 2]);
            let (suv, suv_faces) = subdivide_uv(&uv, &uv_faces, 2);
            assert_eq!(suv_faces.len(), s.faces.len());
            if scheme == Scheme::Loop {
                continue; // Loop moves the positions; the UVs stay piecewise linear.
            }
            // 32 faces: the first 16 come from face 0, the rest from face 1.
            for (i, (t, ut)) in s.faces.iter().zip(&suv_faces).enumerate() {
                for k in 0..3 {
                    let expect = chart(s.positions[t[k] as usize], i / 16);
                    let got = suv[ut[k] as usize];
                    assert!((0..2).all(|a| (got[a] - expect[a]).abs() < 1e-12), "face {i} corner {k}: {got:?} vs {expect:?}");
                }
            }
            // Every vertex on the seam 1-2 (x + y = 1) has one UV on each side, the others one.
            let mut uvs_of = vec![std::collections::BTreeSet::new(); s.positions.len()];
            for (t, ut) in s.faces.iter().zip(&suv_faces) {
                for k in 0..3 {
                    uvs_of[t[k] as usize].insert(ut[k]);
                }
            }
            for (v, set) in uvs_of.iter().enumerate() {
                let q = s.positions[v];
                let on_seam = (q[0] + q[1] - 1.0).abs() < 1e-12;
                assert_eq!(set.len(), if on_seam { 2 } else { 1 }, "vertex {v} at {q:?}");
            }
            // Two subdivisions of an edge per side: 5 seam vertices, 25 + 5 UVs.
            assert_eq!(suv.len(), s.positions.len() + 5);
        }
    }

    #[test]
    fn scheme_choices_parse_and_resolve_per_iteration() {
        use Scheme::{Loop, Midpoint};
        assert_eq!(SchemeChoice::parse("mixed").unwrap().schemes(3).unwrap(), vec![Midpoint, Midpoint, Loop]);
        assert_eq!(SchemeChoice::parse("loop").unwrap().schemes(2).unwrap(), vec![Loop, Loop]);
        let list = SchemeChoice::parse("loop, midpoint").unwrap();
        assert_eq!(list.schemes(2).unwrap(), vec![Loop, Midpoint]);
        assert_eq!(SchemeChoice::parse(&list.spec()).unwrap(), list);
        assert!(list.schemes(3).unwrap_err().contains("2 subdivision schemes given for 3"));
        assert!(SchemeChoice::parse("cubic").is_err());
        assert!(SchemeChoice::parse("loop,,midpoint").is_err());
        assert_eq!(SchemeChoice::Mixed.schemes(0).unwrap(), vec![]);
    }

    #[test]
    fn a_mixed_subdivision_smooths_only_its_last_level() {
        let (p, f) = quad();
        let mixed = subdivide(&p, &f, &[Scheme::Midpoint, Scheme::Loop]);
        let midpoint = subdivide(&p, &f, &[Scheme::Midpoint]);
        let looped = subdivide(&midpoint.positions, &midpoint.faces, &[Scheme::Loop]);
        assert_eq!(mixed.positions, looped.positions);
        assert_eq!(mixed.lod_offsets, vec![0, 4, 9, 25]);
    }

    #[test]
    fn the_transposed_subdivision_is_the_adjoint_of_the_subdivision() {
        let closed = [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-1.0, -1.0, 0.0]];
        let tet = vec![[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]];
        let s = subdivide(&closed, &tet, &[Scheme::Midpoint, Scheme::Loop]);
        assert_eq!(s.apply(&closed), s.positions);
        // <S x, y> = <x, S^T y> for arbitrary x and y.
        let x: Vec<[f64; 3]> = (0..4).map(|i| [i as f64, 1.0 - i as f64, 0.5 * i as f64]).collect();
        let y: Vec<[f64; 3]> = (0..s.positions.len()).map(|i| [(i % 5) as f64, (i % 3) as f64 - 1.0, 0.25]).collect();
        let dot = |a: &[[f64; 3]], b: &[[f64; 3]]| a.iter().zip(b).map(|(p, q)| p[0] * q[0] + p[1] * q[1] + p[2] * q[2]).sum::<f64>();
        let gathered = s.transposed().apply(&y);
        let (lhs, rhs) = (dot(&s.apply(&x), &y), dot(&x, &gathered));
        assert!((lhs - rhs).abs() < 1e-9 * lhs.abs().max(1.0), "{lhs} vs {rhs}");
        // Summed as a scatter in vertex order sums: the same bits.
        let scattered = s.stencils.iter().enumerate().rev().fold(y.clone(), |g, (i, st)| {
            let mut out = vec![[0.0; 3]; s.lod_offsets[i + 1]];
            for (v, yv) in g.iter().enumerate() {
                for &(u, w) in st.row(v) {
                    (0..3).for_each(|k| out[u as usize][k] += w * yv[k]);
                }
            }
            out
        });
        assert_eq!(gathered, scattered);
    }

    #[test]
    fn zero_iterations_return_the_base_mesh() {
        let (p, f) = quad();
        let s = subdivide(&p, &f, &[]);
        assert_eq!(s.lod_count(), 1);
        assert_eq!(s.faces, f);
    }
}
