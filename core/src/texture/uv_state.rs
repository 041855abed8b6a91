//! What the UV coder's walk ([`crate::texture::uvcoder`]) shares with its two halves, the
//! corner decisions ([`crate::texture::uv_corners`]) and the predictions of new UVs
//! ([`crate::texture::uv_prediction`]): the adaptive models, the atlas coded so far, the
//! encoder's input, and the small UV and face geometry all three measure with.

use crate::geom::mesh::{cross, dot, sub, EdgeMap};
use crate::ec::{BitModel, IntModel};

/// Cosine of the angle between face normals beyond which an edge counts as a crease.
pub(crate) const BEND_COS: f64 = 0.9;

/// Adaptive contexts, shared by encoder and decoder so that both adapt identically.
pub(crate) struct Models {
    /// "The first-ranked candidate", by [`CornerContext`].
    pub(crate) first: [[[[BitModel; 3]; 3]; 4]; 2],
    /// "A new UV" once the first candidate is refused: by (more than one candidate, the
    /// face's new UVs so far).
    pub(crate) new: [[BitModel; 3]; 2],
    /// Truncated unary over the remaining ranks, then the explicit escape.
    pub(crate) rank: [BitModel; 4],
    /// "A new UV" for a vertex without candidates (else the explicit escape).
    pub(crate) fresh: BitModel,
    pub(crate) residual: [[IntModel; 2]; 6],
}

impl Models {
    pub(crate) fn new() -> Self {
        Self {
            first: [[[[BitModel::default(); 3]; 3]; 4]; 2],
            new: [[BitModel::default(); 3]; 2],
            rank: [BitModel::default(); 4],
            fresh: BitModel::default(),
            residual: std::array::from_fn(|_| std::array::from_fn(|_| IntModel::new(0))),
        }
    }
}

/// What the walk has coded so far, identical on both sides.
pub(crate) struct Atlas<'a> {
    /// The mesh, with its positions when both sides have them (they sharpen the prediction).
    pub(crate) faces: &'a [[u32; 3]],
    pub(crate) positions: Option<&'a [[f64; 3]]>,
    /// For each position edge of a coded face, the first such face.
    pub(crate) edge_face: EdgeMap<u32>,
    /// Sums of the lengths of coded UV edges, of their 3D edges, and their count: the
    /// atlas's scale.
    pub(crate) uv_length: f64,
    pub(crate) length_3d: f64,
    pub(crate) edges: f64,
    /// Whether the last coded face whose UVs have an orientation runs counter-clockwise.
    pub(crate) ccw: bool,
    /// Per coded UV: the position vertex of its first corner, a UV it shares an edge with
    /// (`u32::MAX` if none), and whether its first face runs counter-clockwise in UV space.
    pub(crate) vertex: Vec<u32>,
    pub(crate) neighbour: Vec<u32>,
    pub(crate) ccw_at: Vec<bool>,
    /// UVs in coding order (indices are "coded indices").
    pub(crate) uv: Vec<[u32; 2]>,
    pub(crate) uv_faces: Vec<[u32; 3]>,
    /// UVs used so far at each position vertex, in order of first use.
    pub(crate) candidates: Vec<Vec<u32>>,
    /// Per coded UV, the number of the last face that used it.
    pub(crate) last_used: Vec<u32>,
    /// For each coded UV edge, the third UV of the first face that had it.
    pub(crate) opposite: EdgeMap<u32>,
}

/// The encoder's input: the atlas as given, and where each of its UVs went.
pub(crate) struct Truth<'a> {
    pub(crate) uv_faces: &'a [[u32; 3]],
    pub(crate) uv: &'a [[u32; 2]],
    /// Coded index of each input UV, `u32::MAX` until it is coded.
    pub(crate) coded_index: Vec<u32>,
}

impl<'a> Truth<'a> {
    pub(crate) fn new(uv_faces: &'a [[u32; 3]], uv: &'a [[u32; 2]]) -> Self {
        Self { uv_faces, uv, coded_index: vec![u32::MAX; uv.len()] }
    }
}


pub(crate) fn squared_distance(a: [u32; 2], b: [u32; 2]) -> u64 {
    let dx = a[0].abs_diff(b[0]) as u64;
    let dy = a[1].abs_diff(b[1]) as u64;
    dx * dx + dy * dy
}

/// Twice the signed area of the UV triangle (a, b, c): positive when counter-clockwise.
pub(crate) fn uv_cross(a: [u32; 2], b: [u32; 2], c: [u32; 2]) -> i64 {
    let d = |p: [u32; 2], q: [u32; 2]| [q[0] as i64 - p[0] as i64, q[1] as i64 - p[1] as i64];
    let (u, v) = (d(a, b), d(a, c));
    u[0] * v[1] - u[1] * v[0]
}

/// Unit normal of `face` (counter-clockwise corners), `None` if degenerate.
pub(crate) fn face_normal(p: &[[f64; 3]], face: &[u32; 3]) -> Option<[f64; 3]> {
    let [a, b, c] = face.map(|v| p[v as usize]);
    let n = cross(sub(b, a), sub(c, a));
    let len = dot(n, n).sqrt();
    (len > 0.0 && len.is_finite()).then(|| n.map(|x| x / len))
}
