//! Lossless static coder of the base mesh (the role Draco/Edgebreaker plays in the test model).
//!
//! The stream is one range-coded block ([`crate::ec`]) in which every symbol has an adaptive
//! context. Connectivity is coded whole before positions, so that each position can be
//! predicted from all of its neighbours that precede it, not only from the face it was
//! reached through: that is worth more than the geometric contexts interleaving would give
//! the connectivity symbols.
//!
//! **Connectivity** is a region-growing traversal over *gates*: half-edges of decoded faces
//! whose other side is unexplored, kept on a stack. Popping the newest gate first turns the
//! traversal around one vertex until its fan is closed, then moves on to the next (like
//! Edgebreaker's spiral), which keeps the region's boundary short. For a popped gate a→b the
//! coder says whether a face lies across it, whether that face runs against the gate (face
//! (b,a,c), the normal case) or with it (inconsistent orientation), and where its third
//! vertex c is:
//! - new: c takes the next vertex index;
//! - next / prev: c ends an open gate at b / at a, i.e. is b's successor or a's predecessor on
//!   the region's boundary (Edgebreaker's R, L and E cases);
//! - walk: c is further along the boundary, found by following open gates from b or a
//!   (Edgebreaker's S case, which nearly always lands two or three steps away);
//! - other: any known vertex by its index relative to a (non-manifold joins).
//!
//! A new face's half-edge that meets an open gate in the opposite direction closes it without
//! a symbol, so a closed manifold costs about one decision per face. When the stack runs dry
//! and faces remain, a seed face starts a new component, each of its vertices new or an
//! explicit earlier one. Nothing assumes a manifold: a non-manifold edge answers "another
//! face across this gate?" again, a vertex shared between components is an explicit
//! reference, and a face the traversal never reaches becomes a seed. Vertices no face uses
//! are dropped, and so are faces with a repeated vertex.
//!
//! **Positions** follow, in a greedy order computed from the connectivity (the vertex with
//! the most parallelograms available next). A vertex with a parallelogram (a face (v,x,y)
//! with x, y decoded and a face (x,y,z) across xy with z decoded) is predicted by a
//! least-squares blend, learnt online on both sides, of: the mean parallelogram x + y - z,
//! the mean apex of the equilateral triangle on xy, and the mean prediction error of its
//! decoded neighbours, each taken relative to the centroid of those neighbours. Otherwise it
//! is predicted by that centroid, else by the last decoded vertex (the grid centre for the
//! first). The prediction is rounded, clamped into [0, 2^bits), and the residual is coded per
//! axis as an adaptive zero flag, sign and Exp-Golomb magnitude, with contexts by axis and
//! kind of prediction (none, centroid, one parallelogram, several).
//!
//! Format:
//! ```text
//! uint n_vertices, uint n_faces   adaptive Exp-Golomb (k = 8); n_faces <= 4 x byte length,
//!                                 3 <= n_vertices <= 3 n_faces unless both are 0
//! connectivity symbols            the traversal above, until n_faces faces are known
//! 3 x n_vertices residuals        in the greedy order
//! zero bytes                      padding to ceil(n_faces / 4) bytes, so that bound holds
//! ```
//! The canonical mesh is the decoder's: vertices numbered in order of creation by the
//! traversal, faces in traversal order.


use crate::ec::{BitModel, DecSide, Decoder, EncSide, Encoder, IntModel, Side, UIntModel};
use crate::mesh::{edge_key, EdgeMap};

/// Most faces one byte of stream may announce: a hostile stream costs at most this much
/// work and memory per byte. Real meshes need well over 2 bits per face; the encoder pads the
/// streams of unusually regular ones, so the bound never rejects its own output.
const MAX_FACES_PER_BYTE: usize = 4;
/// Largest supported position bit depth (residuals must fit an i32 with room to spare).
pub const MAX_BITS: u32 = 30;
/// Faces across one edge considered for a parallelogram: bounds work on hostile fans.
const MAX_EDGE_SCAN: usize = 16;

/// Codes a triangle mesh with integer positions in `[0, 2^bits)` losslessly up to a
/// relabelling of vertices and an order/rotation of faces (orientation kept).
///
/// Vertices no face references are dropped, and so are faces with a repeated vertex index
/// (they carry no surface). Panics if `bits` is not in `1..=MAX_BITS`, if a face refers to a
/// vertex beyond `positions`, or if a coordinate is `>= 2^bits`: those are caller bugs.
pub fn encode_base(positions: &[[u32; 3]], faces: &[[u32; 3]], bits: u32) -> Vec<u8> {
    encode(positions, faces, bits, true)
}

/// [`encode_base`], or only its header and connectivity (to measure their share).
fn encode(positions: &[[u32; 3]], faces: &[[u32; 3]], bits: u32, with_positions: bool) -> Vec<u8> {
    assert!((1..=MAX_BITS).contains(&bits), "position bit depth {bits} out of range");
    assert!(
        positions.iter().flatten().all(|&c| (c as u64) < 1u64 << bits),
        "a position does not fit in {bits} bits"
    );
    assert!(
        faces.iter().flatten().all(|&v| (v as usize) < positions.len()),
        "a face refers to a missing vertex"
    );
    assert!(faces.len() < (u32::MAX / 3) as usize, "too many faces");
    let faces: Vec<[u32; 3]> =
        faces.iter().copied().filter(|f| f[0] != f[1] && f[1] != f[2] && f[2] != f[0]).collect();
    let mut used = vec![false; positions.len()];
    faces.iter().flatten().for_each(|&v| used[v as usize] = true);
    let n_vertices = used.iter().filter(|&&u| u).count() as u32;

    let mut side = EncSide(Encoder::new());
    let mut header = UIntModel::new(8);
    side.0.uint(&mut header, n_vertices);
    side.0.uint(&mut header, faces.len() as u32);
    let mut source = Source::new(&faces, positions.len());
    let conn = connectivity(&mut side, Some(&mut source), n_vertices, faces.len())
        .expect("the encoder's own traversal is consistent");
    let ordered: Vec<[u32; 3]> = source.new2old.iter().map(|&o| positions[o as usize]).collect();
    if with_positions {
        code_positions(&mut side, &conn.faces, n_vertices as usize, bits, Some(&ordered))
            .expect("the encoder's own positions are in range");
    }
    let mut out = side.0.finish();
    let min_len = if with_positions { faces.len().div_ceil(MAX_FACES_PER_BYTE) } else { 0 };
    if out.len() < min_len {
        out.resize(min_len, 0);
    }
    out
}

/// A base mesh on the base grid: integer positions and faces.
pub type GridMesh = (Vec<[u32; 3]>, Vec<[u32; 3]>);

/// Inverse of [`encode_base`] for the same `bits`. Returns the canonical mesh `(positions,
/// faces)`: vertices in order of first use by the traversal, faces in traversal order; the
/// encoder's caller uses exactly this decoded mesh from then on.
///
/// Never panics; returns `Err(reason)` for any stream the encoder cannot have written (as far
/// as it can tell: a corrupted stream may also decode to some other valid mesh). Work and
/// memory are bounded by `MAX_FACES_PER_BYTE` faces per input byte.
pub fn decode_base(data: &[u8], bits: u32) -> Result<GridMesh, String> {
    if !(1..=MAX_BITS).contains(&bits) {
        return Err(format!("base mesh: position bit depth {bits} out of range"));
    }
    let mut side = DecSide(Decoder::new(data));
    let mut header = UIntModel::new(8);
    let n_vertices = side.0.uint(&mut header) as usize;
    let n_faces = side.0.uint(&mut header) as usize;
    side.0.finish().map_err(|e| format!("base mesh header: {e}"))?;
    if n_faces > data.len().saturating_mul(MAX_FACES_PER_BYTE) {
        return Err(format!("base mesh: {n_faces} faces cannot fit in {} bytes", data.len()));
    }
    if n_vertices > 3 * n_faces || (n_faces > 0 && n_vertices < 3) {
        return Err(format!("base mesh: {n_vertices} vertices cannot belong to {n_faces} faces"));
    }
    let conn = connectivity(&mut side, None, n_vertices as u32, n_faces)?;
    let positions = code_positions(&mut side, &conn.faces, n_vertices, bits, None)?;
    side.0.finish().map_err(|e| format!("base mesh: {e}"))?;
    Ok((positions, conn.faces))
}

/// The encoder's knowledge of the input mesh: which faces are still to code and how
/// original vertex indices map to the canonical ones.
struct Source<'a> {
    faces: &'a [[u32; 3]],
    coded: Vec<bool>,
    /// (undirected edge key in original indices, face), sorted: faces on an edge in input order.
    edge_faces: Vec<(u64, u32)>,
    next_seed: usize,
    old2new: Vec<u32>,
    new2old: Vec<u32>,
}

impl<'a> Source<'a> {
    fn new(faces: &'a [[u32; 3]], n_positions: usize) -> Self {
        let mut edge_faces: Vec<(u64, u32)> = (0..faces.len() * 3)
            .map(|i| (edge_key(faces[i / 3][i % 3], faces[i / 3][(i + 1) % 3]), (i / 3) as u32))
            .collect();
        edge_faces.sort_unstable();
        let coded = vec![false; faces.len()];
        Self {
            faces,
            coded,
            edge_faces,
            next_seed: 0,
            old2new: vec![u32::MAX; n_positions],
            new2old: vec![],
        }
    }

    /// Takes the next uncoded face across canonical edge a→b, preferring one oriented
    /// against it: `(flipped, third vertex in original indices)`.
    fn take_across(&mut self, a: u32, b: u32) -> Option<(bool, u32)> {
        let (ao, bo) = (self.new2old[a as usize], self.new2old[b as usize]);
        let key = edge_key(ao, bo);
        let from = self.edge_faces.partition_point(|e| e.0 < key);
        let on_edge = self.edge_faces[from..].iter().take_while(|e| e.0 == key).map(|e| e.1);
        let mut best: Option<(bool, u32, u32)> = None;
        for f in on_edge.filter(|&f| !self.coded[f as usize]) {
            let t = self.faces[f as usize];
            let k = t.iter().position(|&v| v == bo).expect("edge lists hold their faces");
            let flipped = t[(k + 1) % 3] != ao;
            let third = t.iter().copied().find(|&v| v != ao && v != bo).expect("three vertices");
            if !flipped {
                best = Some((false, third, f));
                break;
            }
            best = best.or(Some((true, third, f)));
        }
        let (flipped, third, f) = best?;
        self.coded[f as usize] = true;
        Some((flipped, third))
    }

    /// Takes the first uncoded face in input order.
    fn take_seed(&mut self) -> Option<[u32; 3]> {
        while self.next_seed < self.faces.len() && self.coded[self.next_seed] {
            self.next_seed += 1;
        }
        let f = *self.faces.get(self.next_seed)?;
        self.coded[self.next_seed] = true;
        Some(f)
    }

    /// Canonical index of original vertex `o`, if it has one yet.
    fn known(&self, o: u32) -> Option<u32> {
        Some(self.old2new[o as usize]).filter(|&n| n != u32::MAX)
    }

    fn assign(&mut self, o: u32, n: u32) {
        debug_assert_eq!(n as usize, self.new2old.len());
        self.old2new[o as usize] = n;
        self.new2old.push(o);
    }
}

/// A half-edge a→b of a decoded face whose other side is unexplored while `open`.
#[derive(Clone, Copy)]
struct Gate {
    a: u32,
    b: u32,
    open: bool,
    /// Positions in `out_open[a]` and `in_open[b]`, for O(1) removal.
    slot_out: u32,
    slot_in: u32,
    /// The previous gate of the same directed half-edge (`u32::MAX`: none).
    below: u32,
}

/// Traversal state, identical in encoder and decoder.
#[derive(Default)]
struct Conn {
    faces: Vec<[u32; 3]>,
    gates: Vec<Gate>,
    stack: Vec<u32>,
    out_open: Vec<Vec<u32>>,
    in_open: Vec<Vec<u32>>,
    /// Directed half-edge -> its latest gate, possibly closed: the gates of one half-edge
    /// form a chain through `Gate::below`, closed ones dropped lazily when met.
    by_pair: EdgeMap<u32>,
    /// Faces decoded around each vertex (a context for the connectivity symbols).
    face_count: Vec<u32>,
    /// Vertices starting / ending a gate with no face across: the mesh's border goes on there.
    border_out: Vec<bool>,
    border_in: Vec<bool>,
}

/// Where the third vertex of a face across a gate is.
#[derive(Clone, Copy, PartialEq, Debug)]
enum Third {
    New,
    /// i-th open gate end at b (the "next" boundary vertex).
    Next(u32),
    /// i-th open gate end at a (the "previous" boundary vertex).
    Prev(u32),
    /// Further along the boundary: j-th of (2 steps from b, 2 steps from a, 3 from b, ...).
    Walk(u32),
    Other(u32),
}

/// Boundary steps tried beyond the immediate neighbours before an explicit index: bounds the
/// work of one symbol while catching most Edgebreaker "split" cases, which land close by.
const MAX_WALK: u32 = 32;

impl Conn {
    fn visited(&self) -> u32 {
        self.out_open.len() as u32
    }

    fn new_vertex(&mut self) -> u32 {
        self.out_open.push(vec![]);
        self.in_open.push(vec![]);
        self.face_count.push(0);
        self.border_out.push(false);
        self.border_in.push(false);
        self.visited() - 1
    }

    /// Pops the next open gate, closing it.
    fn pop_gate(&mut self) -> Option<(u32, u32)> {
        while let Some(g) = self.stack.pop() {
            if self.gates[g as usize].open {
                self.close(g);
                let gate = self.gates[g as usize];
                return Some((gate.a, gate.b));
            }
        }
        None
    }

    fn close(&mut self, g: u32) {
        let gate = self.gates[g as usize];
        self.gates[g as usize].open = false;
        let list = &mut self.out_open[gate.a as usize];
        list.swap_remove(gate.slot_out as usize);
        if let Some(&moved) = list.get(gate.slot_out as usize) {
            self.gates[moved as usize].slot_out = gate.slot_out;
        }
        let list = &mut self.in_open[gate.b as usize];
        list.swap_remove(gate.slot_in as usize);
        if let Some(&moved) = list.get(gate.slot_in as usize) {
            self.gates[moved as usize].slot_in = gate.slot_in;
        }
    }

    /// An open gate a→b, if any (the most recent one).
    fn find_open(&mut self, a: u32, b: u32) -> Option<u32> {
        let head = self.by_pair.get_mut(&(((a as u64) << 32) | b as u64))?;
        while *head != u32::MAX {
            let gate = self.gates[*head as usize];
            if gate.open {
                return Some(*head);
            }
            *head = gate.below;
        }
        None
    }

    fn open_gate(&mut self, a: u32, b: u32) {
        let g = self.gates.len() as u32;
        let slot_out = self.out_open[a as usize].len() as u32;
        let slot_in = self.in_open[b as usize].len() as u32;
        let head = self.by_pair.entry(((a as u64) << 32) | b as u64).or_insert(u32::MAX);
        self.gates.push(Gate { a, b, open: true, slot_out, slot_in, below: *head });
        *head = g;
        self.out_open[a as usize].push(g);
        self.in_open[b as usize].push(g);
        self.stack.push(g);
    }

    /// Adds a face; `entry` is its half-edge that crosses the popped gate (no new gate). Each
    /// other half-edge closes an opposite open gate or opens a gate of its own.
    fn add_face(&mut self, f: [u32; 3], entry: Option<usize>) {
        self.faces.push(f);
        for &v in &f {
            self.face_count[v as usize] += 1;
        }
        for k in 0..3 {
            if Some(k) == entry {
                continue;
            }
            let (u, w) = (f[k], f[(k + 1) % 3]);
            match self.find_open(w, u) {
                Some(g) => self.close(g),
                None => self.open_gate(u, w),
            }
        }
    }

    /// Candidates for the third vertex of a face across gate a→b: "next" are ends of open
    /// gates at b that the face would close, "prev" those at a.
    fn candidates(&self, a: u32, b: u32, flipped: bool) -> (&[u32], &[u32]) {
        if flipped {
            // Face (a,b,c) closes open c→b and a→c.
            (&self.in_open[b as usize], &self.out_open[a as usize])
        } else {
            // Face (b,a,c) closes open b→c and c→a.
            (&self.out_open[b as usize], &self.in_open[a as usize])
        }
    }

    /// The boundary vertex `steps` gates away from `from`, following open gates forward
    /// (`forward`: from a gate's start to its end) or backward; the first gate of each vertex.
    fn walk(&self, mut from: u32, forward: bool, steps: u32) -> Option<u32> {
        for _ in 0..steps {
            let list =
                if forward { &self.out_open[from as usize] } else { &self.in_open[from as usize] };
            let g = self.gates[*list.first()? as usize];
            from = if forward { g.b } else { g.a };
        }
        Some(from)
    }

    /// The vertex `Walk(j)` names, for a face across a→b.
    fn walked(&self, a: u32, b: u32, flipped: bool, j: u32) -> Option<u32> {
        let steps = 2 + j / 2;
        if j % 2 == 0 {
            self.walk(b, !flipped, steps)
        } else {
            self.walk(a, flipped, steps)
        }
    }

    /// The vertex a candidate gate offers (its end other than the gate's vertex).
    fn offered(&self, g: u32, at: u32) -> u32 {
        let gate = self.gates[g as usize];
        if gate.a == at {
            gate.b
        } else {
            gate.a
        }
    }
}

const SYMBOL_CONTEXTS: usize = 512;

/// Adaptive contexts of the connectivity symbols.
struct ConnModels {
    has_face: [BitModel; 6],
    more: BitModel,
    flipped: BitModel,
    is_new: [BitModel; SYMBOL_CONTEXTS],
    is_next: [BitModel; SYMBOL_CONTEXTS],
    is_prev: [BitModel; SYMBOL_CONTEXTS],
    which: UIntModel,
    is_walk: BitModel,
    walk: UIntModel,
    other: IntModel,
    seed_new: BitModel,
    seed_index: UIntModel,
    /// The previous third-vertex symbol (0 new, 1 next, 2 prev, 3 further) and gate answer:
    /// contexts, since traversals repeat patterns.
    last: usize,
    last_had_face: bool,
}

impl ConnModels {
    fn new() -> Self {
        Self {
            has_face: Default::default(),
            more: BitModel::default(),
            flipped: BitModel::default(),
            is_new: [BitModel::default(); SYMBOL_CONTEXTS],
            is_next: [BitModel::default(); SYMBOL_CONTEXTS],
            is_prev: [BitModel::default(); SYMBOL_CONTEXTS],
            which: UIntModel::new(0),
            is_walk: BitModel::default(),
            walk: UIntModel::new(0),
            other: IntModel::new(3),
            seed_new: BitModel::default(),
            seed_index: UIntModel::new(4),
            last: 0,
            last_had_face: true,
        }
    }
}

/// Codes the whole connectivity. `source` is the encoder's input mesh (None when decoding).
fn connectivity<S: Side>(
    s: &mut S,
    mut source: Option<&mut Source>,
    n_vertices: u32,
    n_faces: usize,
) -> Result<Conn, String> {
    let mut st = Conn::default();
    let mut m = ConnModels::new();
    while st.faces.len() < n_faces {
        if s.failed() {
            return Err(format!("base mesh: connectivity data ends at face {}", st.faces.len()));
        }
        match st.pop_gate() {
            Some(gate) => {
                faces_across(s, &mut st, &mut m, source.as_deref_mut(), n_vertices, n_faces, gate)?
            }
            None => seed(s, &mut st, &mut m, source.as_deref_mut(), n_vertices)?,
        }
    }
    if st.visited() != n_vertices {
        return Err(format!("base mesh: {} of {n_vertices} vertices used", st.visited()));
    }
    Ok(st)
}

/// Codes the faces across a popped gate a→b: usually one, none on a border, several on a
/// non-manifold edge. Nothing is coded once all faces are known.
fn faces_across<S: Side>(
    s: &mut S,
    st: &mut Conn,
    m: &mut ConnModels,
    mut source: Option<&mut Source>,
    n_vertices: u32,
    n_faces: usize,
    (a, b): (u32, u32),
) -> Result<(), String> {
    let mut first = true;
    while st.faces.len() < n_faces && !s.failed() {
        let across = source.as_deref_mut().and_then(|src| src.take_across(a, b));
        let has = if first {
            // A border runs on where one ended: at a border vertex the next gate is likelier
            // to be a border too.
            let ctx = m.last_had_face as usize
                | (st.border_in[a as usize] as usize + st.border_out[b as usize] as usize) << 1;
            s.bit(&mut m.has_face[ctx], across.is_some())
        } else {
            s.bit(&mut m.more, across.is_some())
        };
        if first {
            m.last_had_face = has;
            if !has {
                st.border_out[a as usize] = true;
                st.border_in[b as usize] = true;
            }
        }
        if !has {
            break;
        }
        first = false;
        face_across(s, st, m, source.as_deref_mut(), n_vertices, (a, b), across)?;
    }
    Ok(())
}

/// Codes the face across gate a→b (`across` is the encoder's answer).
fn face_across<S: Side>(
    s: &mut S,
    st: &mut Conn,
    m: &mut ConnModels,
    source: Option<&mut Source>,
    n_vertices: u32,
    (a, b): (u32, u32),
    across: Option<(bool, u32)>,
) -> Result<(), String> {
    let flipped = s.bit(&mut m.flipped, across.is_some_and(|x| x.0));
    let third = across.map(|(_, c)| classify(st, source.as_deref(), a, b, flipped, c));
    let c = third_vertex(s, st, m, n_vertices, (a, b), flipped, third)?;
    if let (Some(src), Some((_, co)), Some(Third::New)) = (source, across, third) {
        src.assign(co, c);
    }
    if flipped {
        st.add_face([a, b, c], Some(0));
    } else {
        st.add_face([b, a, c], Some(0));
    }
    Ok(())
}

/// The encoder's choice of symbol for original third vertex `co`.
fn classify(st: &Conn, source: Option<&Source>, a: u32, b: u32, flipped: bool, co: u32) -> Third {
    let Some(c) = source.and_then(|src| src.known(co)) else {
        return Third::New;
    };
    let (next, prev) = st.candidates(a, b, flipped);
    if let Some(i) = next.iter().position(|&g| st.offered(g, b) == c) {
        return Third::Next(i as u32);
    }
    if let Some(i) = prev.iter().position(|&g| st.offered(g, a) == c) {
        return Third::Prev(i as u32);
    }
    (0..2 * MAX_WALK)
        .find(|&j| st.walked(a, b, flipped, j) == Some(c))
        .map_or(Third::Other(c), Third::Walk)
}

/// Codes where the third vertex is and returns it (creating it if new).
fn third_vertex<S: Side>(
    s: &mut S,
    st: &mut Conn,
    m: &mut ConnModels,
    n_vertices: u32,
    (a, b): (u32, u32),
    flipped: bool,
    third: Option<Third>,
) -> Result<u32, String> {
    let (n_next, n_prev) = {
        let (next, prev) = st.candidates(a, b, flipped);
        (next.len(), prev.len())
    };
    let ctx = symbol_context(st, m, a, b, n_next, n_prev);
    let t = third.unwrap_or(Third::New);
    let sym = decide_third(s, m, ctx, a, st.visited() < n_vertices, (n_next, n_prev), t);
    m.last = match sym {
        Third::New => 0,
        Third::Next(_) => 1,
        Third::Prev(_) => 2,
        Third::Walk(_) | Third::Other(_) => 3,
    };
    let c = match sym {
        Third::New => return Ok(st.new_vertex()),
        Third::Next(i) => st.offered(st.candidates(a, b, flipped).0[i as usize], b),
        Third::Prev(i) => st.offered(st.candidates(a, b, flipped).1[i as usize], a),
        Third::Walk(j) => st.walked(a, b, flipped, j).unwrap_or(u32::MAX),
        Third::Other(c) => c,
    };
    if c == a || c == b || c >= st.visited() {
        return Err(format!("base mesh: face {} has an impossible vertex", st.faces.len()));
    }
    Ok(c)
}

/// Context of the third-vertex symbol: which candidates exist, the previous symbol, and how
/// many faces a and b already have (b, whose fan the traversal is turning around, is the
/// likelier to be closed by this face, the more faces it has).
fn symbol_context(
    st: &Conn,
    m: &ConnModels,
    a: u32,
    b: u32,
    n_next: usize,
    n_prev: usize,
) -> usize {
    let faces_b = st.face_count[b as usize].min(7) as usize;
    let faces_a = st.face_count[a as usize].min(3) as usize;
    n_next.min(1) | n_prev.min(1) << 1 | m.last << 2 | faces_b << 4 | faces_a << 7
}

/// Codes the symbol `t` (encoder) or reads one. Candidate indices out of range and Other
/// vertices out of u32 come back as `Other(u32::MAX)`, which the caller rejects.
fn decide_third<S: Side>(
    s: &mut S,
    m: &mut ConnModels,
    ctx: usize,
    a: u32,
    can_new: bool,
    (n_next, n_prev): (usize, usize),
    t: Third,
) -> Third {
    if can_new && s.bit(&mut m.is_new[ctx], t == Third::New) {
        return Third::New;
    }
    if n_next > 0 && s.bit(&mut m.is_next[ctx], matches!(t, Third::Next(_))) {
        let i = if let Third::Next(i) = t { i } else { 0 };
        let i = if n_next > 1 { s.uint(&mut m.which, i) } else { 0 };
        return if (i as usize) < n_next { Third::Next(i) } else { Third::Other(u32::MAX) };
    }
    if n_prev > 0 && s.bit(&mut m.is_prev[ctx], matches!(t, Third::Prev(_))) {
        let i = if let Third::Prev(i) = t { i } else { 0 };
        let i = if n_prev > 1 { s.uint(&mut m.which, i) } else { 0 };
        return if (i as usize) < n_prev { Third::Prev(i) } else { Third::Other(u32::MAX) };
    }
    if s.bit(&mut m.is_walk, matches!(t, Third::Walk(_))) {
        let j = s.uint(&mut m.walk, if let Third::Walk(j) = t { j } else { 0 });
        return if j < 2 * MAX_WALK { Third::Walk(j) } else { Third::Other(u32::MAX) };
    }
    let c = if let Third::Other(c) = t { c as i64 } else { 0 };
    let d = s.int(&mut m.other, (c - a as i64) as i32);
    Third::Other(u32::try_from(a as i64 + d as i64).unwrap_or(u32::MAX))
}

/// Codes a seed face: each vertex new or an explicit earlier one (counted back from the
/// newest, since shared vertices of touching components tend to be recent).
fn seed<S: Side>(
    s: &mut S,
    st: &mut Conn,
    m: &mut ConnModels,
    mut source: Option<&mut Source>,
    n_vertices: u32,
) -> Result<(), String> {
    let orig = source.as_deref_mut().and_then(|src| src.take_seed());
    let mut f = [0u32; 3];
    for k in 0..3 {
        let known = orig.and_then(|o| source.as_deref().and_then(|src| src.known(o[k])));
        let visited = st.visited();
        if visited < n_vertices && s.bit(&mut m.seed_new, known.is_none()) {
            f[k] = st.new_vertex();
            if let (Some(src), Some(o)) = (source.as_deref_mut(), orig) {
                src.assign(o[k], f[k]);
            }
            continue;
        }
        let back = s.uint(&mut m.seed_index, known.map_or(0, |c| visited.wrapping_sub(1) - c));
        if back >= visited {
            return Err(format!(
                "base mesh: seed face {} refers to a future vertex",
                st.faces.len()
            ));
        }
        f[k] = visited - 1 - back;
    }
    if f[0] == f[1] || f[1] == f[2] || f[2] == f[0] {
        return Err(format!("base mesh: seed face {} repeats a vertex", st.faces.len()));
    }
    st.add_face(f, None);
    Ok(())
}

/// Vertex -> faces and face edge -> faces across it, of the decoded connectivity.
struct Adjacency {
    start: Vec<u32>,
    vertex_faces: Vec<u32>,
    /// (undirected edge key, face), sorted.
    edges: Vec<(u64, u32)>,
    /// For edge k of face f (from corner k to k+1), where its key starts in `edges`.
    edge_at: Vec<u32>,
}

impl Adjacency {
    fn new(faces: &[[u32; 3]], n: usize) -> Self {
        let mut start = vec![0u32; n + 1];
        faces.iter().flatten().for_each(|&v| start[v as usize + 1] += 1);
        for i in 0..n {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut vertex_faces = vec![0u32; faces.len() * 3];
        let mut edges = Vec::with_capacity(faces.len() * 3);
        for (i, f) in faces.iter().enumerate() {
            for k in 0..3 {
                let v = f[k] as usize;
                vertex_faces[fill[v] as usize] = i as u32;
                fill[v] += 1;
                edges.push((edge_key(f[k], f[(k + 1) % 3]), i as u32));
            }
        }
        edges.sort_unstable();
        let mut edge_at = vec![0u32; faces.len() * 3];
        let mut group = 0;
        for (i, &(key, f)) in edges.iter().enumerate() {
            if key != edges[group].0 {
                group = i;
            }
            let t = faces[f as usize];
            let k = (0..3).find(|&k| edge_key(t[k], t[(k + 1) % 3]) == key).unwrap_or(0);
            edge_at[f as usize * 3 + k] = group as u32;
        }
        Self { start, vertex_faces, edges, edge_at }
    }

    fn faces_of(&self, v: u32) -> &[u32] {
        &self.vertex_faces[self.start[v as usize] as usize..self.start[v as usize + 1] as usize]
    }

    /// The other faces on edge k of face f (at most `MAX_EDGE_SCAN` looked at).
    fn across(&self, f: u32, k: usize) -> impl Iterator<Item = u32> + '_ {
        let from = self.edge_at[f as usize * 3 + k] as usize;
        let key = self.edges[from].0;
        self.edges[from..]
            .iter()
            .take_while(move |e| e.0 == key)
            .take(MAX_EDGE_SCAN)
            .map(|e| e.1)
            .filter(move |&g| g != f)
    }
}

/// Kinds of prediction, each with its own residual contexts.
const PRED_KINDS: usize = 4;

/// The order positions are coded in: greedily a vertex with the most parallelograms
/// available, then the most decoded neighbours, so that most vertices are predicted from
/// several sides. Both sides derive it from the connectivity alone.
struct Order {
    /// Parallelograms and decoded neighbours (with multiplicity) per vertex.
    score: Vec<(u32, u32)>,
    done: Vec<bool>,
    /// Vertices by capped score (stale entries are skipped when met); LIFO within one.
    buckets: Vec<Vec<u32>>,
    top: usize,
    /// Lowest index that may still be undecoded: where a new component starts.
    cursor: usize,
}

const ORDER_BUCKETS: usize = 8 * 16;

fn bucket((parallelograms, neighbours): (u32, u32)) -> usize {
    parallelograms.min(7) as usize * 16 + neighbours.min(15) as usize
}

impl Order {
    fn new(n: usize) -> Self {
        let buckets = vec![vec![]; ORDER_BUCKETS];
        Self { score: vec![(0, 0); n], done: vec![false; n], buckets, top: 0, cursor: 0 }
    }

    fn next(&mut self) -> Option<u32> {
        loop {
            while let Some(v) = self.buckets[self.top].pop() {
                if !self.done[v as usize] && bucket(self.score[v as usize]) == self.top {
                    return Some(v);
                }
            }
            if self.top == 0 {
                break;
            }
            self.top -= 1;
        }
        while self.cursor < self.done.len() && self.done[self.cursor] {
            self.cursor += 1;
        }
        (self.cursor < self.done.len()).then_some(self.cursor as u32)
    }

    /// Marks `v` decoded and credits the vertices whose predictions it completes.
    fn decoded(&mut self, v: u32, faces: &[[u32; 3]], adj: &Adjacency) {
        self.done[v as usize] = true;
        for &f in adj.faces_of(v) {
            let t = faces[f as usize];
            let kv = t.iter().position(|&u| u == v).unwrap_or(0);
            let (p, q) = (t[(kv + 1) % 3], t[(kv + 2) % 3]);
            self.credit(p, 0, 1);
            self.credit(q, 0, 1);
            if self.done[p as usize] && self.done[q as usize] {
                // v is the far vertex z of parallelograms across edge pq.
                for g in adj.across(f, (kv + 1) % 3) {
                    self.credit(third(faces[g as usize], p, q), 1, 0);
                }
            }
            // v is x of a parallelogram for w in face (v, w, y) across edge vy.
            for (w, y, k) in [(p, q, (kv + 2) % 3), (q, p, kv)] {
                if !self.done[w as usize] && self.done[y as usize] {
                    let n = adj
                        .across(f, k)
                        .filter(|&g| self.is_done(third(faces[g as usize], v, y)))
                        .count();
                    if n > 0 {
                        self.credit(w, n as u32, 0);
                    }
                }
            }
        }
    }

    fn is_done(&self, u: u32) -> bool {
        self.done.get(u as usize).copied().unwrap_or(false)
    }

    fn credit(&mut self, w: u32, parallelograms: u32, neighbours: u32) {
        if w as usize >= self.done.len() || self.done[w as usize] {
            return;
        }
        let sc = &mut self.score[w as usize];
        sc.0 += parallelograms;
        sc.1 += neighbours;
        let b = bucket(*sc);
        self.buckets[b].push(w);
        self.top = self.top.max(b);
    }
}

/// The vertex of `t` other than `x` and `y` (`u32::MAX` if none).
fn third(t: [u32; 3], x: u32, y: u32) -> u32 {
    t.iter().copied().find(|&u| u != x && u != y).unwrap_or(u32::MAX)
}

/// Predictors blended for a vertex with a parallelogram, as offsets from the centroid of its
/// decoded neighbours: the mean parallelogram (exact on regular meshes), the mean apex of an
/// equilateral triangle on the shared edge (decimated meshes have well-shaped triangles more
/// than parallelograms), and the mean prediction error of the decoded neighbours (curvature
/// that the others miss consistently).
const FEATURES: usize = 3;
/// Forgetting factor of the blend's statistics: about the last 256 vertices count.
const BLEND_DECAY: f64 = 1.0 - 1.0 / 256.0;

/// Online least-squares weights of the predictors, learnt identically by encoder and decoder
/// from the decoded positions: no fixed weights suit both smooth regular meshes and
/// decimated captures. Only IEEE basic operations are used, so both sides agree bit for bit.
struct Blend {
    a: [[f64; FEATURES]; FEATURES],
    b: [f64; FEATURES],
}

impl Blend {
    fn new() -> Self {
        // A small ridge that starts the weights at the plain parallelogram.
        let mut a = [[0.0; FEATURES]; FEATURES];
        (0..FEATURES).for_each(|k| a[k][k] = 1.0);
        let mut b = [0.0; FEATURES];
        b[0] = 1.0;
        Self { a, b }
    }

    fn weights(&self) -> [f64; FEATURES] {
        solve(self.a, self.b)
            .filter(|w| w.iter().all(|x| x.is_finite()))
            .map_or([1.0, 0.0, 0.0], |w| w.map(|x| x.clamp(-4.0, 4.0)))
    }

    fn learn(&mut self, x: &[[f64; 3]; FEATURES], e: [f64; 3]) {
        for r in 0..FEATURES {
            self.b[r] = self.b[r] * BLEND_DECAY + dot(x[r], e);
            for c in 0..FEATURES {
                self.a[r][c] = self.a[r][c] * BLEND_DECAY + dot(x[r], x[c]);
            }
        }
    }
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Gaussian elimination with partial pivoting; None if (nearly) singular.
fn solve(mut a: [[f64; FEATURES]; FEATURES], mut b: [f64; FEATURES]) -> Option<[f64; FEATURES]> {
    for c in 0..FEATURES {
        let p = (c..FEATURES).fold(c, |p, r| if a[r][c].abs() > a[p][c].abs() { r } else { p });
        if a[p][c].is_nan() || a[p][c].abs() <= 1e-9 {
            return None;
        }
        a.swap(c, p);
        b.swap(c, p);
        let pivot = a[c];
        for r in (0..FEATURES).filter(|&r| r != c) {
            let f = a[r][c] / pivot[c];
            a[r].iter_mut().zip(pivot).skip(c).for_each(|(x, p)| *x -= f * p);
            b[r] -= f * b[c];
        }
    }
    Some(std::array::from_fn(|k| b[k] / a[k][k]))
}

/// Apex of the equilateral triangle on edge xy, in the plane of triangle xyz, opposite z.
fn equilateral_apex(x: [f64; 3], y: [f64; 3], z: [f64; 3]) -> [f64; 3] {
    let e = sub3(y, x);
    let l2 = dot(e, e);
    let t = dot(sub3(z, x), e) / l2;
    let perp: [f64; 3] = std::array::from_fn(|i| x[i] + e[i] * t - z[i]);
    let h = dot(perp, perp).sqrt();
    if !(l2 > 0.0 && h > 0.0) {
        return std::array::from_fn(|i| x[i] + y[i] - z[i]);
    }
    let scale = l2.sqrt() * (0.75f64).sqrt() / h;
    std::array::from_fn(|i| (x[i] + y[i]) / 2.0 + perp[i] * scale)
}

fn sub3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn as_f64(p: [u32; 3]) -> [f64; 3] {
    p.map(|c| c as f64)
}

/// What is known around a vertex about to be decoded.
struct Neighbourhood {
    /// Centroid of decoded neighbours (one count per face) and the mean of their errors.
    centroid: Option<([f64; 3], [f64; 3])>,
    /// Mean parallelogram and mean equilateral apex, and how many there are.
    parallelograms: Option<([f64; 3], [f64; 3], usize)>,
}

fn neighbourhood(
    v: u32,
    pos: &[[u32; 3]],
    err: &[[f64; 3]],
    done: &[bool],
    faces: &[[u32; 3]],
    adj: &Adjacency,
) -> Neighbourhood {
    let is_done = |u: u32| done.get(u as usize).copied().unwrap_or(false);
    let (mut para, mut equi, mut np) = ([0.0; 3], [0.0; 3], 0usize);
    let (mut cen, mut rn, mut nc) = ([0.0; 3], [0.0; 3], 0usize);
    for &f in adj.faces_of(v) {
        let t = faces[f as usize];
        for &u in t.iter().filter(|&&u| u != v && is_done(u)) {
            (0..3).for_each(|i| cen[i] += pos[u as usize][i] as f64);
            (0..3).for_each(|i| rn[i] += err[u as usize][i]);
            nc += 1;
        }
        let k = t.iter().position(|&u| u == v).unwrap_or(0);
        let (x, y) = (t[(k + 1) % 3], t[(k + 2) % 3]);
        if !is_done(x) || !is_done(y) {
            continue;
        }
        for g in adj.across(f, (k + 1) % 3) {
            let z = third(faces[g as usize], x, y);
            if is_done(z) {
                let (px, py, pz) =
                    (as_f64(pos[x as usize]), as_f64(pos[y as usize]), as_f64(pos[z as usize]));
                let apex = equilateral_apex(px, py, pz);
                (0..3).for_each(|i| para[i] += px[i] + py[i] - pz[i]);
                (0..3).for_each(|i| equi[i] += apex[i]);
                np += 1;
            }
        }
    }
    let mean = |s: [f64; 3], n: usize| s.map(|c| c / n as f64);
    Neighbourhood {
        centroid: (nc > 0).then(|| (mean(cen, nc), mean(rn, nc))),
        parallelograms: (np > 0).then(|| (mean(para, np), mean(equi, np), np)),
    }
}

/// The features the blend used: the centroid they are relative to, and their values.
type Features = Option<([f64; 3], [[f64; 3]; FEATURES])>;

/// Prediction and its kind: the [`Blend`] where a parallelogram exists, else the centroid of
/// decoded neighbours, else `fallback`.
fn predict(nb: Neighbourhood, blend: &Blend, fallback: [f64; 3]) -> ([f64; 3], usize, Features) {
    match (nb.centroid, nb.parallelograms) {
        (Some((cen, rn)), Some((para, equi, np))) => {
            let x = [sub3(para, cen), sub3(equi, cen), rn];
            let w = blend.weights();
            let p = std::array::from_fn(|i| {
                cen[i] + (0..FEATURES).map(|k| w[k] * x[k][i]).sum::<f64>()
            });
            (p, 1 + np.min(2), Some((cen, x)))
        }
        (Some((cen, _)), None) => (cen, 1, None),
        _ => (fallback, 0, None),
    }
}

/// Codes positions in [`Order`], with [`predict`]ions from the last decoded vertex (or the
/// centre of the grid) as the last resort; `enc` holds the positions when encoding.
fn code_positions<S: Side>(
    s: &mut S,
    faces: &[[u32; 3]],
    n: usize,
    bits: u32,
    enc: Option<&[[u32; 3]]>,
) -> Result<Vec<[u32; 3]>, String> {
    let adj = Adjacency::new(faces, n);
    let mut models: Vec<IntModel> = (0..PRED_KINDS * 3).map(|_| IntModel::new(2)).collect();
    let mut pos = vec![[0u32; 3]; n];
    let mut err = vec![[0f64; 3]; n];
    let mut order = Order::new(n);
    let mut blend = Blend::new();
    let mut last = None;
    let max = (1i64 << bits) - 1;
    while let Some(v) = order.next() {
        if s.failed() {
            return Err(format!("base mesh: position data ends at vertex {v}"));
        }
        let nb = neighbourhood(v, &pos, &err, &order.done, faces, &adj);
        let fallback = last.map_or([(1u64 << (bits - 1)) as f64; 3], |u| as_f64(pos[u as usize]));
        let (pred, kind, features) = predict(nb, &blend, fallback);
        let ipred = pred.map(|c| (c.round() as i64).clamp(0, max));
        for i in 0..3 {
            let actual = enc.map_or(0, |e| e[v as usize][i] as i64);
            let r = s.int(&mut models[kind * 3 + i], (actual - ipred[i]) as i32) as i64;
            pos[v as usize][i] = u32::try_from(ipred[i] + r)
                .ok()
                .filter(|&c| c as i64 <= max)
                .ok_or_else(|| format!("base mesh: vertex {v} lies outside the {bits}-bit grid"))?;
        }
        if let Some((cen, x)) = features {
            let actual = as_f64(pos[v as usize]);
            err[v as usize] = sub3(actual, pred);
            blend.learn(&x, sub3(actual, cen));
        }
        order.decoded(v, faces, &adj);
        last = Some(v);
    }
    Ok(pos)
}

#[cfg(test)]
mod tests {
    use super::*;

    type Tri = [[u32; 3]; 3];
    type IntMesh = (Vec<[u32; 3]>, Vec<[u32; 3]>);
    type FloatMesh = (Vec<[f64; 3]>, Vec<[u32; 3]>);

    fn lcg(seed: &mut u64) -> u32 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (*seed >> 33) as u32
    }

    /// Faces as position triples in their least rotation (orientation kept), sorted: equal
    /// iff the meshes are equal up to relabelling and face order/rotation.
    fn canonical(positions: &[[u32; 3]], faces: &[[u32; 3]]) -> Vec<Tri> {
        let mut out: Vec<Tri> = faces
            .iter()
            .filter(|f| f[0] != f[1] && f[1] != f[2] && f[2] != f[0])
            .map(|f| {
                let t = f.map(|v| positions[v as usize]);
                (0..3).map(|k| [t[k], t[(k + 1) % 3], t[(k + 2) % 3]]).min().unwrap()
            })
            .collect();
        out.sort_unstable();
        out
    }

    fn round_trip(positions: &[[u32; 3]], faces: &[[u32; 3]], bits: u32) -> usize {
        let data = encode_base(positions, faces, bits);
        let (p, f) = decode_base(&data, bits).expect("own stream decodes");
        assert_eq!(canonical(&p, &f), canonical(positions, faces));
        assert_eq!(decode_base(&data, bits).unwrap(), (p.clone(), f.clone()), "deterministic");
        let used = f.iter().flatten().collect::<std::collections::BTreeSet<_>>().len();
        assert_eq!(used, p.len(), "no unreferenced vertex");
        data.len()
    }

    fn scale(p: [f64; 3], bits: u32) -> [u32; 3] {
        let max = ((1u64 << bits) - 1) as f64;
        p.map(|c| (c.clamp(0.0, 1.0) * max).round() as u32)
    }

    fn grid(n: u32, bits: u32) -> IntMesh {
        let mut p = vec![];
        for j in 0..=n {
            for i in 0..=n {
                let (x, y) = (i as f64 / n as f64, j as f64 / n as f64);
                p.push(scale([x, y, 0.5 + 0.1 * (3.0 * x).sin() * y], bits));
            }
        }
        let mut f = vec![];
        let id = |i: u32, j: u32| j * (n + 1) + i;
        for j in 0..n {
            for i in 0..n {
                f.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                f.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        (p, f)
    }

    /// Icosahedron subdivided `levels` times, projected on a sphere (20 * 4^levels faces).
    fn icosphere(levels: u32, bits: u32) -> IntMesh {
        let (p, f) = crate::bvh::testmesh::icosphere(levels, 1.0);
        (p.iter().map(|v| scale(v.map(|c| 0.5 + 0.5 * c), bits)).collect(), f)
    }

    fn cube(bits: u32) -> IntMesh {
        let m = (1u32 << bits) - 1;
        let p = (0..8).map(|i| [(i & 1) * m, (i >> 1 & 1) * m, (i >> 2 & 1) * m]).collect();
        let f = vec![
            [0, 2, 3],
            [0, 3, 1],
            [4, 5, 7],
            [4, 7, 6],
            [0, 1, 5],
            [0, 5, 4],
            [2, 6, 7],
            [2, 7, 3],
            [0, 4, 6],
            [0, 6, 2],
            [1, 3, 7],
            [1, 7, 5],
        ];
        (p, f)
    }

    fn test_meshes(bits: u32) -> Vec<(&'static str, IntMesh)> {
        let tri = (vec![[1, 2, 3], [7, 1, 0], [0, 5, 2]], vec![[0, 1, 2]]);
        let (gp, gf) = grid(12, bits);
        let (ip, i_f) = icosphere(2, bits);
        let (cp, cf) = cube(bits);
        // Two disjoint components, plus a third touching the second at one vertex, with an
        // unreferenced vertex and a degenerate face in between.
        let mut two_p = cp.clone();
        two_p.extend(ip.iter().map(|v| v.map(|c| c / 2)));
        two_p.push([1, 1, 1]);
        let mut two_f: Vec<[u32; 3]> = i_f.iter().map(|f| f.map(|v| v + 8)).collect();
        two_f.extend(&cf);
        two_f.push([3, 3, 5]);
        two_f.push([8, 20, 2]);
        // Three faces on one edge, one of them oriented with the others, plus a duplicate.
        let fan_p = vec![[0, 0, 0], [9, 0, 0], [4, 8, 0], [4, 0, 8], [4, 9, 9], [5, 5, 5]];
        let fan_f = vec![[0, 1, 2], [1, 0, 3], [0, 1, 4], [1, 0, 3], [2, 1, 5], [5, 1, 2]];
        // Duplicate positions: a grid whose middle column is doubled (a cut through the mesh).
        let (mut dp, mut df) = grid(6, bits);
        let base = dp.len() as u32;
        let column: Vec<[u32; 3]> = (0..7).map(|j| dp[j * 7 + 3]).collect();
        dp.extend(column);
        for f in df.iter_mut().filter(|f| f.iter().all(|&v| v % 7 >= 3)) {
            f.iter_mut().filter(|v| **v % 7 == 3).for_each(|v| *v = base + *v / 7);
        }
        vec![
            ("triangle", tri),
            ("grid", (gp, gf)),
            ("icosphere", (ip, i_f)),
            ("cube", (cp, cf)),
            ("components", (two_p, two_f)),
            ("non-manifold fan", (fan_p, fan_f)),
            ("duplicate positions", (dp, df)),
            ("empty", (vec![[1, 1, 1]], vec![])),
        ]
    }

    #[test]
    fn round_trips_up_to_relabelling() {
        for bits in [10, 12, 16] {
            for (name, (p, f)) in test_meshes(bits) {
                let n = round_trip(&p, &f, bits);
                println!("{name} ({bits} bits): {} faces, {n} bytes", f.len());
            }
        }
    }

    #[test]
    fn random_soups_round_trip() {
        let mut seed = 11u64;
        for _ in 0..300 {
            let nv = 3 + lcg(&mut seed) % 12;
            let p: Vec<[u32; 3]> = (0..nv).map(|_| [0; 3].map(|_| lcg(&mut seed) % 1024)).collect();
            let nf = lcg(&mut seed) % 20;
            let f: Vec<[u32; 3]> = (0..nf).map(|_| [0; 3].map(|_| lcg(&mut seed) % nv)).collect();
            round_trip(&p, &f, 10);
        }
    }

    /// Prints and returns bits per face for connectivity and for positions; the times are of
    /// one cold run each (tests share the machine: indicative only).
    fn report(name: &str, p: &[[u32; 3]], f: &[[u32; 3]], bits: u32) -> (f64, f64) {
        let t = std::time::Instant::now();
        let data = encode_base(p, f, bits);
        let encode_time = t.elapsed();
        let t = std::time::Instant::now();
        let (dp, df) = decode_base(&data, bits).unwrap();
        let decode_time = t.elapsed();
        assert_eq!(canonical(&dp, &df), canonical(p, f));
        let (total, conn) = (data.len() * 8, encode(p, f, bits, false).len() * 8);
        let nf = df.len() as f64;
        let (c, g) = (conn as f64 / nf, (total - conn) as f64 / nf);
        println!(
            "{name}: {} faces {} vertices, {bits} bits: {:.3} bits/face = {c:.3} connectivity \
             + {g:.3} positions ({:.2} bits/vertex); encode {encode_time:.2?} decode {decode_time:.2?}",
            df.len(),
            dp.len(),
            c + g,
            (total - conn) as f64 / dp.len() as f64,
        );
        (c, g)
    }

    #[test]
    fn compresses_a_smooth_sphere() {
        let (p, f) = icosphere(4, 12);
        let (c, g) = report("icosphere", &p, &f, 12);
        // Measured: 0.14 connectivity + 6.39 positions.
        assert!(c < 0.2 && c + g < 7.0, "{c} + {g} bits per face");
    }

    #[test]
    fn pads_streams_of_very_regular_meshes() {
        // A flat regular grid is predicted exactly: far under one bit per face.
        let n = 60u32;
        let p: Vec<[u32; 3]> =
            (0..=n).flat_map(|j| (0..=n).map(move |i| [8 * i, 8 * j, 77])).collect();
        let id = |i: u32, j: u32| j * (n + 1) + i;
        let f: Vec<[u32; 3]> = (0..n * n)
            .flat_map(|k| {
                let (i, j) = (k % n, k / n);
                [
                    [id(i, j), id(i + 1, j), id(i + 1, j + 1)],
                    [id(i, j), id(i + 1, j + 1), id(i, j + 1)],
                ]
            })
            .collect();
        let len = round_trip(&p, &f, 10);
        assert_eq!(len, f.len().div_ceil(MAX_FACES_PER_BYTE));
    }

    #[test]
    fn extreme_bit_depths_round_trip() {
        for bits in [1, MAX_BITS] {
            let (p, f) = icosphere(1, bits);
            round_trip(&p, &f, bits);
        }
        let (p, f) = cube(MAX_BITS);
        round_trip(&p, &f, MAX_BITS);
    }

    fn small_stream() -> Vec<u8> {
        let (p, f) = icosphere(1, 10);
        encode_base(&p, &f, 10)
    }

    fn check_valid(r: &Result<IntMesh, String>, bits: u32) {
        if let Ok((p, f)) = r {
            assert!(f.iter().flatten().all(|&v| (v as usize) < p.len()));
            assert!(f.iter().all(|t| t[0] != t[1] && t[1] != t[2] && t[2] != t[0]));
            assert!(p.iter().flatten().all(|&c| c < 1 << bits));
        }
    }

    #[test]
    fn truncations_never_panic() {
        let data = small_stream();
        for n in 0..data.len() {
            let r = decode_base(&data[..n], 10);
            check_valid(&r, 10);
        }
    }

    #[test]
    fn byte_flips_never_panic() {
        let data = small_stream();
        let mut seed = 5u64;
        let mut ok = 0;
        for _ in 0..2000 {
            let mut d = data.clone();
            for _ in 0..1 + lcg(&mut seed) % 3 {
                let i = lcg(&mut seed) as usize % d.len();
                d[i] ^= 1 + (lcg(&mut seed) % 255) as u8;
            }
            let r = decode_base(&d, 10);
            check_valid(&r, 10);
            ok += r.is_ok() as usize;
        }
        println!("{ok} of 2000 corrupted streams decoded to some valid mesh");
    }

    #[test]
    fn huge_counts_are_rejected_quickly() {
        let mut e = Encoder::new();
        let mut m = UIntModel::new(8);
        e.uint(&mut m, 1_000_000_000);
        e.uint(&mut m, 4_000_000_000);
        let data = e.finish();
        let t = std::time::Instant::now();
        assert!(decode_base(&data, 12).is_err());
        let mut big = data.clone();
        big.resize(1 << 20, 0xA5);
        assert!(decode_base(&big, 12).is_err());
        assert!(t.elapsed().as_millis() < 200);
        // About the cheapest mesh there is, a regular grid at one point, hits the bound: its
        // stream is padded, decodes in time proportional to its length, fails unpadded.
        let (_, f) = grid(300, 12);
        let p = vec![[5, 5, 5]; 301 * 301];
        let data = encode_base(&p, &f, 12);
        assert_eq!(data.len(), f.len() / MAX_FACES_PER_BYTE);
        let t = std::time::Instant::now();
        assert_eq!(decode_base(&data, 12).map(|m| m.1.len()), Ok(f.len()));
        println!("{} faces in {} bytes decoded in {:?}", f.len(), data.len(), t.elapsed());
        assert!(decode_base(&data[..data.len() - 1], 12).is_err());
        // Random data of every short length.
        let mut seed = 9u64;
        for len in 0..300 {
            let d: Vec<u8> = (0..len).map(|_| lcg(&mut seed) as u8).collect();
            check_valid(&decode_base(&d, 12), 12);
        }
    }

    mod shared_data {
        use super::*;

        #[test]
        #[ignore = "needs ../shared/data"]
        fn codes_a_real_capture_frame() {
            let frame = crate::shared_data::read_obj("basketball_player/basketball_player_fr0011.obj");
            let (p, f) = (frame.positions, frame.faces);
            let bits = 12;
            let (lo, hi) = crate::mesh::bounds(&p).unwrap();
            let side = (0..3).map(|i| hi[i] - lo[i]).fold(0.0, f64::max);
            let max = ((1u32 << bits) - 1) as f64;
            let q: Vec<[u32; 3]> = p
                .iter()
                .map(|v| [0, 1, 2].map(|i| ((v[i] - lo[i]) / side * max).round() as u32))
                .collect();
            let f: Vec<[u32; 3]> = f
                .into_iter()
                .filter(|t| {
                    let k = t.map(|v| q[v as usize]);
                    k[0] != k[1] && k[1] != k[2] && k[2] != k[0]
                })
                .collect();
            report("basketball_player_fr0011", &q, &f, bits);
            // The real base mesh is a decimated frame: a crude stand-in for that.
            let (dp, df) = decimate(&p, &f, 5000);
            let dq: Vec<[u32; 3]> = dp
                .iter()
                .map(|v| [0, 1, 2].map(|i| ((v[i] - lo[i]) / side * max).round() as u32))
                .collect();
            report("basketball_player_fr0011 decimated", &dq, &df, bits);
            report(
                "basketball_player_fr0011 decimated",
                &dq.iter().map(|v| v.map(|c| c >> 2)).collect::<Vec<_>>(),
                &df,
                10,
            );
        }
    }

    fn normal(t: [[f64; 3]; 3]) -> [f64; 3] {
        let (u, v) = ([0, 1, 2].map(|i| t[1][i] - t[0][i]), [0, 1, 2].map(|i| t[2][i] - t[0][i]));
        [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
    }

    /// Shortest-edge-first collapse to the midpoint, keeping the link condition and face
    /// orientations: a test stand-in for the QEM decimator, irregular in the same way.
    fn decimate(p: &[[f64; 3]], f: &[[u32; 3]], target: usize) -> FloatMesh {
        use std::cmp::Reverse;
        let (mut p, mut f) = (p.to_vec(), f.to_vec());
        let mut alive = vec![true; f.len()];
        let mut vf: Vec<Vec<u32>> = vec![vec![]; p.len()];
        for (i, t) in f.iter().enumerate() {
            t.iter().for_each(|&v| vf[v as usize].push(i as u32));
        }
        let len2 = |p: &[[f64; 3]], a: u32, b: u32| -> u64 {
            let d: f64 = (0..3).map(|i| (p[a as usize][i] - p[b as usize][i]).powi(2)).sum();
            (d * 1e12) as u64
        };
        let edges = |p: &[[f64; 3]], t: [u32; 3]| -> Vec<_> {
            (0..3).map(|k| Reverse((len2(p, t[k], t[(k + 1) % 3]), t[k], t[(k + 1) % 3]))).collect()
        };
        let mut heap: std::collections::BinaryHeap<_> =
            f.iter().flat_map(|&t| edges(&p, t)).collect();
        let mut count = f.len();
        while let Some(Reverse((l, a, b))) = heap.pop() {
            if count <= target {
                break;
            }
            let shared: Vec<u32> =
                vf[a as usize].iter().copied().filter(|&x| f[x as usize].contains(&b)).collect();
            if shared.is_empty() || l != len2(&p, a, b) {
                continue;
            }
            let ring = |v: u32| -> std::collections::BTreeSet<u32> {
                vf[v as usize].iter().flat_map(|&x| f[x as usize]).collect()
            };
            if ring(a).intersection(&ring(b)).count() != shared.len() + 2 {
                continue;
            }
            let mid = [0, 1, 2].map(|i| (p[a as usize][i] + p[b as usize][i]) / 2.0);
            let moved = |t: [u32; 3]| t.map(|v| if v == a || v == b { mid } else { p[v as usize] });
            let flips =
                vf[a as usize].iter().chain(&vf[b as usize]).filter(|x| !shared.contains(x)).any(
                    |&x| {
                        let t = f[x as usize];
                        let (n0, n1) = (normal(t.map(|v| p[v as usize])), normal(moved(t)));
                        (0..3).map(|i| n0[i] * n1[i]).sum::<f64>() <= 0.0
                    },
                );
            if flips {
                continue;
            }
            p[a as usize] = mid;
            for &x in &shared {
                alive[x as usize] = false;
                count -= 1;
                for v in f[x as usize] {
                    vf[v as usize].retain(|&y| y != x);
                }
            }
            for x in std::mem::take(&mut vf[b as usize]) {
                f[x as usize].iter_mut().filter(|v| **v == b).for_each(|v| *v = a);
                vf[a as usize].push(x);
            }
            heap.extend(vf[a as usize].iter().flat_map(|&x| edges(&p, f[x as usize])));
        }
        let faces = f.iter().zip(&alive).filter(|x| *x.1).map(|x| *x.0).collect();
        (p, faces)
    }
}
