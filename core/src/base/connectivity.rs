//! The connectivity of the base mesh block ([`crate::base::coder`]), coded by both sides
//! through one traversal driven by [`Side`].
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

use crate::error::Corrupt;
use crate::ec::{BitModel, IntModel, Side, UIntModel};
use crate::geom::mesh::{edge_key, EdgeMap};

/// The encoder's knowledge of the input mesh: which faces are still to code and how
/// original vertex indices map to the canonical ones.
pub(crate) struct Source<'a> {
    faces: &'a [[u32; 3]],
    coded: Vec<bool>,
    /// (undirected edge key in original indices, face), sorted: faces on an edge in input order.
    edge_faces: Vec<(u64, u32)>,
    next_seed: usize,
    old2new: Vec<u32>,
    pub new2old: Vec<u32>,
}

impl<'a> Source<'a> {
    pub fn new(faces: &'a [[u32; 3]], n_positions: usize) -> Self {
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
pub(crate) struct Conn {
    pub faces: Vec<[u32; 3]>,
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
pub(crate) fn connectivity<S: Side>(
    s: &mut S,
    mut source: Option<&mut Source>,
    n_vertices: u32,
    n_faces: usize,
) -> Result<Conn, Corrupt> {
    let mut st = Conn::default();
    let mut m = ConnModels::new();
    while st.faces.len() < n_faces {
        if s.failed() {
            return Err(format!("connectivity data ends at face {}", st.faces.len()).into());
        }
        match st.pop_gate() {
            Some(gate) => {
                faces_across(s, &mut st, &mut m, source.as_deref_mut(), n_vertices, n_faces, gate)?
            }
            None => seed(s, &mut st, &mut m, source.as_deref_mut(), n_vertices)?,
        }
    }
    if st.visited() != n_vertices {
        return Err(format!("{} of {n_vertices} vertices used", st.visited()).into());
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
) -> Result<(), Corrupt> {
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
) -> Result<(), Corrupt> {
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
) -> Result<u32, Corrupt> {
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
        return Err(format!("face {} has an impossible vertex", st.faces.len()).into());
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
) -> Result<(), Corrupt> {
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
            return Err(format!("seed face {} refers to a future vertex", st.faces.len()).into());
        }
        f[k] = visited - 1 - back;
    }
    if f[0] == f[1] || f[1] == f[2] || f[2] == f[0] {
        return Err(format!("seed face {} repeats a vertex", st.faces.len()).into());
    }
    st.add_face(f, None);
    Ok(())
}
