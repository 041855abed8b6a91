//! Lossless coding of a base mesh's texture atlas: which UV each face corner uses, and the
//! quantized UVs themselves.
//!
//! An intra frame's atlas is computed on the decoded base mesh, so the decoder already has
//! the faces (and, if the caller passes them, the positions); what it lacks is, per corner,
//! an index into a UV list (a vertex on a chart seam has several UVs) and the list. Both are
//! coded in one range-coded block ([`crate::ec`]), face by face in the given order, which the
//! base mesh coder makes a traversal order, so consecutive faces are neighbours.
//!
//! Which UV each corner uses is [`crate::texture::uv_corners`]; the values of new UVs,
//! predicted from the face, are [`crate::texture::uv_prediction`].
//!
//! The decoded UV list is renumbered in order of first use ([`canonical_uv`]); that is the
//! only thing the coding does not keep. Decoding does a bounded amount of work per face of
//! the caller's mesh, whatever the data, and allocates nothing the faces cannot reference.

use crate::error::Corrupt;
use crate::ec::{DecSide, Decoder, EncSide, Encoder, Side};
use crate::geom::mesh::{dot, edge_key, sub, EdgeMap};
use crate::texture::uv_corners::decide_corners;
use crate::texture::uv_prediction::code_new_uvs;
use crate::texture::uv_state::{squared_distance, uv_cross, Atlas, Models, Truth};

/// An atlas: per face, the UV indices of its corners; and the UVs.
pub type UvAtlas = (Vec<[u32; 3]>, Vec<[u32; 2]>);

/// Largest supported UV bit depth.
pub const MAX_UV_BITS: u32 = 16;
/// UVs kept as candidates per position vertex: bounds the ranking work a hostile mesh can
/// cause. Further UVs at the vertex are still reachable through the explicit escape.
const MAX_CANDIDATES: usize = 32;
/// Codes the atlas of the mesh `faces`: corner `k` of face `f` uses `uv[uv_faces[f][k]]`,
/// a UV quantized to `bits` bits per axis. UVs no corner uses are not coded. Decode with
/// [`decode_uv`].
///
/// Panics if `bits` is not in `1..=MAX_UV_BITS`, if `faces` and `uv_faces` differ in length,
/// if a UV index is beyond `uv`, or if a coordinate is `>= 2^bits`: those are caller bugs.
pub fn encode_uv(faces: &[[u32; 3]], uv_faces: &[[u32; 3]], uv: &[[u32; 2]], bits: u32) -> Vec<u8> {
    encode(faces, None, uv_faces, uv, bits)
}

/// Inverse of [`encode_uv`] for the same `faces` and `bits`: returns `(uv_faces, uv)` in
/// canonical numbering (see [`canonical_uv`]).
///
/// Never panics; returns `Err(reason)` if `bits` is out of range, a face refers to a vertex
/// at or beyond `vertex_count`, or the data is truncated or impossible (a corrupted block may
/// also decode to some other atlas of the right shape). Work and memory are linear in the
/// face count, whatever the data.
pub fn decode_uv(data: &[u8], faces: &[[u32; 3]], vertex_count: usize, bits: u32) -> Result<UvAtlas, Corrupt> {
    decode(data, faces, None, vertex_count, bits)
}

/// [`encode_uv`] for a decoder that also has the mesh's `positions`: new UVs are then
/// predicted from the shape of the 3D triangles, which roughly halves an xatlas atlas.
/// Decode with [`decode_uv_with_positions`] and the same positions, bit for bit (the
/// predictions use only correctly rounded IEEE-754 operations, so every platform agrees).
///
/// Panics as [`encode_uv`] does, and if a face refers to a vertex beyond `positions`.
pub fn encode_uv_with_positions(positions: &[[f64; 3]], faces: &[[u32; 3]], uv_faces: &[[u32; 3]], uv: &[[u32; 2]], bits: u32) -> Vec<u8> {
    assert!(faces.iter().flatten().all(|&v| (v as usize) < positions.len()), "a face refers to a missing vertex");
    encode(faces, Some(positions), uv_faces, uv, bits)
}

/// Inverse of [`encode_uv_with_positions`] for the same `positions`, `faces` and `bits`;
/// errors as [`decode_uv`] (the vertex count is `positions.len()`). Positions that are not
/// finite only weaken the prediction.
pub fn decode_uv_with_positions(data: &[u8], positions: &[[f64; 3]], faces: &[[u32; 3]], bits: u32) -> Result<UvAtlas, Corrupt> {
    decode(data, faces, Some(positions), positions.len(), bits)
}

fn encode(faces: &[[u32; 3]], positions: Option<&[[f64; 3]]>, uv_faces: &[[u32; 3]], uv: &[[u32; 2]], bits: u32) -> Vec<u8> {
    assert!((1..=MAX_UV_BITS).contains(&bits), "UV bit depth {bits} out of range");
    assert_eq!(faces.len(), uv_faces.len(), "one UV triangle per face");
    assert!(uv_faces.iter().flatten().all(|&i| (i as usize) < uv.len()), "a UV index is beyond the UV list");
    assert!(uv.iter().flatten().all(|&c| (c as u64) < 1u64 << bits), "a UV does not fit in {bits} bits");
    let vertex_count = faces.iter().flatten().map(|&v| v as usize + 1).max().unwrap_or(0);
    let mut enc = Encoder::new();
    let mut side = EncSide(&mut enc);
    let coded = walk(&mut side, &mut Models::new(), faces, positions, vertex_count, bits, Some(Truth::new(uv_faces, uv)))
        .expect("the encoder's own atlas is consistent");
    debug_assert_eq!(canonical_uv(&coded.0, &coded.1), canonical_uv(uv_faces, uv));
    enc.finish()
}

fn decode(data: &[u8], faces: &[[u32; 3]], positions: Option<&[[f64; 3]]>, vertex_count: usize, bits: u32) -> Result<UvAtlas, Corrupt> {
    if !(1..=MAX_UV_BITS).contains(&bits) {
        return Err(format!("UV atlas: bit depth {bits} out of range").into());
    }
    if let Some(f) = faces.iter().position(|f| f.iter().any(|&v| v as usize >= vertex_count)) {
        return Err(format!("UV atlas: face {f} refers to a vertex beyond the {vertex_count} vertices").into());
    }
    let mut dec = Decoder::new(data);
    let mut side = DecSide(&mut dec);
    let (uv_faces, uv) = walk(&mut side, &mut Models::new(), faces, positions, vertex_count, bits, None)?;
    dec.finish().map_err(|e| Corrupt(format!("UV atlas: {e}")))?;
    Ok(canonical_uv(&uv_faces, &uv))
}

/// The same atlas with the UVs renumbered in order of first use (face 0 corners 0, 1, 2,
/// then face 1, ...), UVs that no corner uses dropped. Two atlases that differ only in the
/// numbering of their UVs have the same canonical form. Panics if an index is beyond `uv`.
pub fn canonical_uv(uv_faces: &[[u32; 3]], uv: &[[u32; 2]]) -> UvAtlas {
    let mut renumbered = vec![u32::MAX; uv.len()];
    let mut out_uv = Vec::new();
    let out_faces = uv_faces
        .iter()
        .map(|f| {
            f.map(|i| {
                let r = &mut renumbered[i as usize];
                if *r == u32::MAX {
                    *r = out_uv.len() as u32;
                    out_uv.push(uv[i as usize]);
                }
                *r
            })
        })
        .collect();
    (out_faces, out_uv)
}

/// Codes (or, without `truth`, decodes) the whole atlas; returns it in coded numbering.
fn walk<S: Side>(
    side: &mut S,
    models: &mut Models,
    faces: &[[u32; 3]],
    positions: Option<&[[f64; 3]]>,
    vertex_count: usize,
    bits: u32,
    mut truth: Option<Truth>,
) -> Result<UvAtlas, Corrupt> {
    // Only vertices some face uses need a list: a caller's vertex count is not trusted to be small.
    let used_vertices = faces.iter().flatten().map(|&v| v as usize + 1).max().unwrap_or(0).min(vertex_count);
    let mut atlas = Atlas {
        faces,
        positions,
        edge_face: EdgeMap::with_capacity_and_hasher(faces.len() * 3 / 2, Default::default()),
        uv_length: 0.0,
        length_3d: 0.0,
        edges: 0.0,
        ccw: true,
        vertex: Vec::new(),
        neighbour: Vec::new(),
        ccw_at: Vec::new(),
        uv: Vec::new(),
        uv_faces: Vec::with_capacity(faces.len()),
        candidates: vec![Vec::new(); used_vertices],
        last_used: Vec::new(),
        opposite: EdgeMap::with_capacity_and_hasher(faces.len() * 3 / 2, Default::default()),
    };
    for (f, face) in faces.iter().enumerate() {
        let ids = decide_corners(side, models, &atlas, face, truth.as_mut().map(|t| (t, f)))?;
        let values = truth.as_ref().map(|t| t.uv_faces[f].map(|i| t.uv[i as usize]));
        code_new_uvs(side, models, &mut atlas, face, ids, values, bits)?;
        if side.failed() {
            return Err("UV atlas: data ends early or is corrupt".into());
        }
        record_face(&mut atlas, face, ids, f as u32);
    }
    Ok((atlas.uv_faces, atlas.uv))
}

/// Makes the coded face `ids` of position face `face` (number `f`) available as context.
fn record_face(atlas: &mut Atlas, face: &[u32; 3], ids: [u32; 3], f: u32) {
    atlas.last_used.resize(atlas.uv.len(), 0);
    let [a, b, c] = ids.map(|i| atlas.uv[i as usize]);
    match uv_cross(a, b, c) {
        0 => {}
        x => atlas.ccw = x > 0,
    }
    let n = atlas.uv.len();
    atlas.vertex.resize(n, u32::MAX);
    atlas.neighbour.resize(n, u32::MAX);
    atlas.ccw_at.resize(n, atlas.ccw);
    for (k, &id) in ids.iter().enumerate() {
        let i = id as usize;
        if atlas.vertex[i] == u32::MAX {
            atlas.vertex[i] = face[k];
        }
        if atlas.neighbour[i] == u32::MAX {
            atlas.neighbour[i] = [ids[(k + 1) % 3], ids[(k + 2) % 3]].into_iter().find(|&j| j != id).unwrap_or(u32::MAX);
        }
    }
    for k in 0..3 {
        let (va, vb) = (face[k], face[(k + 1) % 3]);
        atlas.edge_face.entry(edge_key(va, vb)).or_insert(f);
        let (ua, ub) = (atlas.uv[ids[k] as usize], atlas.uv[ids[(k + 1) % 3] as usize]);
        atlas.uv_length += (squared_distance(ua, ub) as f64).sqrt();
        atlas.edges += 1.0;
        if let Some(p) = atlas.positions {
            let d = sub(p[va as usize], p[vb as usize]);
            let l = dot(d, d).sqrt();
            if l.is_finite() {
                atlas.length_3d += l;
            }
        }
        let list = &mut atlas.candidates[face[k] as usize];
        if !list.contains(&ids[k]) && list.len() < MAX_CANDIDATES {
            list.push(ids[k]);
        }
        atlas.last_used[ids[k] as usize] = f;
        let (a, b) = (ids[(k + 1) % 3], ids[(k + 2) % 3]);
        if a != b {
            atlas.opposite.entry(edge_key(a, b)).or_insert(ids[k]);
        }
    }
    atlas.uv_faces.push(ids);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lcg(seed: &mut u64) -> u32 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (*seed >> 33) as u32
    }

    /// A `w` x `h` grid sheet (unit spacing in the plane z = 0) cut into two charts along
    /// column `w / 2`: the seam's vertices have one UV in each chart. Each chart is the sheet
    /// scaled by 40 texels per unit, the second also turned by 90 degrees, plus a jitter of
    /// 0..=2 texels. UV indices are shuffled and unused UVs added, so that the input is not
    /// canonical.
    struct Sheet {
        positions: Vec<[f64; 3]>,
        faces: Vec<[u32; 3]>,
        uv_faces: Vec<[u32; 3]>,
        uv: Vec<[u32; 2]>,
    }

    fn seamed_sheet(w: u32, h: u32, seed: u64) -> Sheet {
        let mut faces = Vec::new();
        let mut uv_faces = Vec::new();
        let cut = w / 2;
        let uv_id = |x: u32, y: u32, chart_b: bool| if chart_b { (w + 1) * h + y * w + x } else { y * w + x };
        for y in 0..h - 1 {
            for x in 0..w - 1 {
                let i = y * w + x;
                let b = x >= cut;
                faces.push([i, i + 1, i + w]);
                uv_faces.push([uv_id(x, y, b), uv_id(x + 1, y, b), uv_id(x, y + 1, b)]);
                faces.push([i + 1, i + w + 1, i + w]);
                uv_faces.push([uv_id(x + 1, y, b), uv_id(x + 1, y + 1, b), uv_id(x, y + 1, b)]);
            }
        }
        let n_uv = ((w + 1) * h + w * h) as usize;
        let mut s = seed;
        let mut uv: Vec<[u32; 2]> = (0..n_uv).map(|_| [lcg(&mut s) % 4096, lcg(&mut s) % 4096]).collect();
        for y in 0..h {
            for x in 0..w {
                let jitter = |s: &mut u64| lcg(s) % 3;
                uv[uv_id(x, y, false) as usize] = [100 + 40 * x + jitter(&mut s), 200 + 40 * y + jitter(&mut s)];
                uv[uv_id(x, y, true) as usize] = [3000 - 40 * y + jitter(&mut s), 1500 + 40 * x + jitter(&mut s)];
            }
        }
        let mut perm: Vec<u32> = (0..n_uv as u32).collect();
        for i in (1..n_uv).rev() {
            perm.swap(i, lcg(&mut s) as usize % (i + 1));
        }
        let mut shuffled = vec![[0; 2]; n_uv];
        for (i, &p) in perm.iter().enumerate() {
            shuffled[p as usize] = uv[i];
        }
        Sheet {
            positions: (0..h).flat_map(|y| (0..w).map(move |x| [x as f64, y as f64, 0.0])).collect(),
            faces,
            uv_faces: uv_faces.iter().map(|f| f.map(|i| perm[i as usize])).collect(),
            uv: shuffled,
        }
    }

    fn vertex_count(faces: &[[u32; 3]]) -> usize {
        faces.iter().flatten().map(|&v| v as usize + 1).max().unwrap_or(0)
    }

    fn round_trip(faces: &[[u32; 3]], uv_faces: &[[u32; 3]], uv: &[[u32; 2]], bits: u32) -> usize {
        let data = encode_uv(faces, uv_faces, uv, bits);
        let decoded = decode_uv(&data, faces, vertex_count(faces), bits).expect("decodes");
        assert_eq!(decoded, canonical_uv(uv_faces, uv));
        data.len()
    }

    #[test]
    fn canonical_form_numbers_by_first_use_and_drops_unused() {
        let (f, uv) = canonical_uv(&[[2, 0, 2], [3, 0, 1]], &[[0, 0], [1, 1], [2, 2], [3, 3], [4, 4]]);
        assert_eq!(f, vec![[0, 1, 0], [2, 1, 3]]);
        assert_eq!(uv, vec![[2, 2], [0, 0], [3, 3], [1, 1]]);
    }

    #[test]
    fn a_seamed_atlas_round_trips_and_its_seam_costs_little() {
        let sheet = seamed_sheet(20, 15, 1);
        let (faces, uv_faces, uv) = (&sheet.faces, &sheet.uv_faces, &sheet.uv);
        let bytes = round_trip(faces, uv_faces, uv, 12);
        // 315 UVs on a near-regular grid: a parallelogram misses by a few texels.
        assert!(bytes < 315 * 8 / 8, "{bytes} bytes");
        // The same mesh as one chart of constant UV: what is left is mostly the cost of the
        // adaptive models learning, and the seam's extra UVs cost a few bits each.
        let one_chart: Vec<[u32; 3]> = faces.to_vec();
        let constant = vec![[5, 5]; 300];
        let seamless_bytes = round_trip(faces, &one_chart, &constant, 12);
        assert!(seamless_bytes < 80, "{seamless_bytes} bytes for one constant chart");
        let mut constant_charts = uv.clone();
        constant_charts.iter_mut().for_each(|c| *c = [5, 5]);
        let seamed_bytes = round_trip(faces, uv_faces, &constant_charts, 12);
        assert!(seamed_bytes < seamless_bytes + 15 * 2, "{seamed_bytes} bytes with a seam of 15 vertices");
    }

    #[test]
    fn positions_sharpen_the_prediction() {
        let sheet = seamed_sheet(20, 15, 4);
        let (p, faces, uv_faces, uv) = (&sheet.positions, &sheet.faces, &sheet.uv_faces, &sheet.uv);
        let data = encode_uv_with_positions(p, faces, uv_faces, uv, 12);
        assert_eq!(decode_uv_with_positions(&data, p, faces, 12).expect("decodes"), canonical_uv(uv_faces, uv));
        let without = encode_uv(faces, uv_faces, uv, 12).len();
        assert!(data.len() * 10 < without * 9, "{} bytes with positions, {without} without", data.len());
        // Other positions decode to something else (or fail), never panic.
        let moved: Vec<[f64; 3]> = p.iter().map(|q| [q[0] * 1.5, q[1], f64::NAN]).collect();
        if let Ok(other) = decode_uv_with_positions(&data, &moved, faces, 12) {
            check_shape(faces, &other, 12);
        }
    }

    #[test]
    fn shared_repeated_and_crowded_uvs_round_trip() {
        // A UV shared by two positions, a face using one new UV twice, a face using a UV of
        // another vertex that is new in the same face.
        let faces = vec![[0, 1, 2], [2, 1, 3], [3, 4, 4], [5, 6, 7]];
        let uv_faces = vec![[0, 1, 2], [2, 1, 2], [3, 4, 4], [5, 5, 0]];
        let uv = vec![[0, 0], [10, 0], [0, 10], [7, 7], [65535, 65535], [0, 65535]];
        round_trip(&faces, &uv_faces, &uv, 16);
        // A fan around vertex 0 whose every face gives it its own UV: more than the
        // candidate list holds, so the later ones go through the explicit index.
        let n = (MAX_CANDIDATES + 10) as u32;
        let faces: Vec<[u32; 3]> = (0..n).map(|i| [0, 1 + i, 1 + (i + 1) % n]).collect();
        let uv_faces: Vec<[u32; 3]> = (0..n).map(|i| [n + (i * 7) % n, 1 + i, 1 + (i + 1) % n]).collect();
        let uv: Vec<[u32; 2]> = (0..2 * n).map(|i| [i * 3 % 256, i * 5 % 256]).collect();
        round_trip(&faces, &uv_faces, &uv, 8);
        // Fan faces that come back to earlier UVs of the centre, in a scrambled order.
        let uv_faces: Vec<[u32; 3]> = (0..n).map(|i| [n + (i * 7) % 5, 1 + i, 1 + (i + 1) % n]).collect();
        round_trip(&faces, &uv_faces, &uv, 8);
        assert_eq!(round_trip(&[], &[], &[], 12), encode_uv(&[], &[], &[], 12).len());
    }

    #[test]
    fn bad_arguments_are_errors() {
        let Sheet { faces, uv_faces, uv, positions } = seamed_sheet(4, 4, 2);
        let data = encode_uv(&faces, &uv_faces, &uv, 12);
        assert!(decode_uv_with_positions(&data, &positions[..15], &faces, 12).unwrap_err().0.contains("beyond"));
        assert!(decode_uv(&data, &faces, 16, 0).unwrap_err().0.contains("bit depth"));
        assert!(decode_uv(&data, &faces, 16, 17).unwrap_err().0.contains("bit depth"));
        assert!(decode_uv(&data, &faces, 15, 12).unwrap_err().0.contains("beyond"));
        assert!(decode_uv(&data, &faces, usize::MAX, 12).is_ok());
    }

    /// Any decoded atlas must be usable: one UV triangle per face, indices in range,
    /// coordinates on the grid.
    fn check_shape(faces: &[[u32; 3]], out: &UvAtlas, bits: u32) {
        assert_eq!(out.0.len(), faces.len());
        assert!(out.0.iter().flatten().all(|&i| (i as usize) < out.1.len()));
        assert!(out.1.iter().flatten().all(|&c| c < 1 << bits));
    }

    #[test]
    fn truncated_or_corrupted_blocks_never_panic() {
        let Sheet { faces, uv_faces, uv, .. } = seamed_sheet(12, 9, 3);
        let n = vertex_count(&faces);
        let data = encode_uv(&faces, &uv_faces, &uv, 12);
        for len in 0..data.len() {
            match decode_uv(&data[..len], &faces, n, 12) {
                Ok(out) => check_shape(&faces, &out, 12),
                Err(e) => assert!(e.0.starts_with("UV atlas"), "{e}"),
            }
        }
        assert!(decode_uv(&data[..data.len() / 2], &faces, n, 12).is_err());
        let mut seed = 11u64;
        let mut errors = 0;
        for trial in 0..2000 {
            let mut bad = data.clone();
            for _ in 0..1 + trial % 4 {
                let i = lcg(&mut seed) as usize % bad.len();
                bad[i] ^= 1 << (lcg(&mut seed) % 8);
            }
            match decode_uv(&bad, &faces, n, 12) {
                Ok(out) => check_shape(&faces, &out, 12),
                Err(_) => errors += 1,
            }
        }
        assert!(errors > 0);
        // Pure garbage too.
        for trial in 0..200 {
            let junk: Vec<u8> = (0..trial).map(|_| lcg(&mut seed) as u8).collect();
            if let Ok(out) = decode_uv(&junk, &faces, n, 12) {
                check_shape(&faces, &out, 12);
            }
        }
    }

    /// An atlas dumped by the measuring script: little-endian u32 `vertex count, face count,
    /// UV count, bits`, faces, UV faces and UVs, then optionally f64 positions.
    struct Dump {
        faces: Vec<[u32; 3]>,
        uv_faces: Vec<[u32; 3]>,
        uv: Vec<[u32; 2]>,
        bits: u32,
        vertex_count: usize,
        positions: Option<Vec<[f64; 3]>>,
    }

    fn read_dump(path: &std::path::Path) -> Option<Dump> {
        let bytes = std::fs::read(path).ok()?;
        let word = |i: usize| u32::from_le_bytes(bytes[4 * i..4 * i + 4].try_into().unwrap());
        let (nv, nf, nuv, bits) = (word(0) as usize, word(1) as usize, word(2) as usize, word(3));
        let tri = |at: usize| (0..nf).map(|f| [word(at + 3 * f), word(at + 3 * f + 1), word(at + 3 * f + 2)]).collect();
        let at_uv = 4 + 6 * nf;
        let at_positions = 4 * (at_uv + 2 * nuv);
        let positions = (bytes.len() >= at_positions + 24 * nv).then(|| {
            let f = |i: usize| f64::from_le_bytes(bytes[at_positions + 8 * i..at_positions + 8 * i + 8].try_into().unwrap());
            (0..nv).map(|v| [f(3 * v), f(3 * v + 1), f(3 * v + 2)]).collect()
        });
        Some(Dump {
            faces: tri(4),
            uv_faces: tri(4 + 3 * nf),
            uv: (0..nuv).map(|i| [word(at_uv + 2 * i), word(at_uv + 2 * i + 1)]).collect(),
            bits,
            vertex_count: nv,
            positions,
        })
    }

    /// Size of real atlases, and where their bits go: `UV_ATLAS_DUMPS=/tmp/uvexp cargo test
    /// --release -p dynmesh uvcoder -- --ignored --nocapture` reads every `*.uvbin` there
    /// (fails if there are none, rather than reporting nothing as a pass).
    #[test]
    #[ignore = "needs atlas dumps (UV_ATLAS_DUMPS)"]
    fn real_atlas_sizes() {
        let dir = std::env::var("UV_ATLAS_DUMPS").unwrap_or_else(|_| "/tmp/uvexp".into());
        let entries = std::fs::read_dir(&dir).unwrap_or_else(|e| panic!("no atlas dumps in {dir}: {e}"));
        let mut paths: Vec<_> = entries.flatten().map(|e| e.path()).filter(|p| p.extension().is_some_and(|e| e == "uvbin")).collect();
        assert!(!paths.is_empty(), "no *.uvbin atlas dumps in {dir}");
        paths.sort();
        for path in paths {
            let Some(Dump { faces, uv_faces, uv, bits, vertex_count, positions }) = read_dump(&path) else { continue };
            let expected = canonical_uv(&uv_faces, &uv);
            let n_uv = expected.1.len();
            println!(
                "{}: {} faces, {vertex_count} vertices, {n_uv} UVs at {bits} bits (plain: {:.1} bits/UV for the UVs and {:.1} for the indices)",
                path.file_name().unwrap().to_string_lossy(),
                faces.len(),
                2.0 * bits as f64,
                3.0 * faces.len() as f64 * (n_uv as f64).log2().ceil() / n_uv as f64,
            );
            for p in [None, positions.as_deref()] {
                let t = std::time::Instant::now();
                let data = match p {
                    Some(p) => encode_uv_with_positions(p, &faces, &uv_faces, &uv, bits),
                    None => encode_uv(&faces, &uv_faces, &uv, bits),
                };
                let encode_ms = t.elapsed().as_secs_f64() * 1e3;
                let t = std::time::Instant::now();
                let decoded = match p {
                    Some(p) => decode_uv_with_positions(&data, p, &faces, bits),
                    None => decode_uv(&data, &faces, vertex_count, bits),
                };
                let decode_ms = t.elapsed().as_secs_f64() * 1e3;
                assert_eq!(decoded.as_ref(), Ok(&expected));
                // Damaged real streams, positions or not: an error or a well-formed atlas.
                let mut seed = data.len() as u64;
                for trial in 0..300 {
                    let mut bad = data[..data.len() * (trial + 1) / 301].to_vec();
                    if trial % 2 == 0 {
                        bad = data.clone();
                        let i = lcg(&mut seed) as usize % bad.len();
                        bad[i] ^= 1 << (lcg(&mut seed) % 8);
                    }
                    let out = match p {
                        Some(p) => decode_uv_with_positions(&bad, p, &faces, bits),
                        None => decode_uv(&bad, &faces, vertex_count, bits),
                    };
                    if let Ok(out) = out {
                        check_shape(&faces, &out, bits);
                    }
                }
                let b = 8.0 * data.len() as f64;
                println!(
                    "  {}: {} bytes = {:.2} bits/UV, {:.2} bits/face; encode {encode_ms:.1} ms, decode {decode_ms:.1} ms",
                    if p.is_some() { "with positions" } else { "without positions" },
                    data.len(),
                    b / n_uv as f64,
                    b / faces.len() as f64,
                );
                let classes = super::meter::measure(&faces, p, &uv_faces, &uv, bits);
                let total: f64 = classes.iter().map(|c| c.2).sum();
                for (name, n, b) in classes.iter().filter(|c| c.1 > 0) {
                    println!("    {name:>28}: {n:6} symbols {b:8.0} bits ({:5.2} each, {:4.1}%)", b / *n as f64, 100.0 * b / total);
                }
            }
        }
    }
}

#[cfg(test)]
mod meter {
    //! The ideal code length of each class of symbol, from shadow copies of the adaptive
    //! models (same update rule as `ec`), to see where the bits of an atlas go.
    use super::*;
    use crate::ec::{BitModel, IntModel};
    use crate::texture::uv_prediction::Prediction;
    use std::collections::HashMap;

    #[derive(Default)]
    struct Meter {
        probabilities: HashMap<usize, (u32, u32)>,
        /// Bits and symbols per model (by address; 0 for bypass bits).
        cost: HashMap<usize, (f64, usize)>,
    }

    impl Meter {
        fn code(&mut self, key: usize, v: bool) -> f64 {
            let (fast, slow) = self.probabilities.entry(key).or_insert((32768, 32768));
            let p0 = ((*fast + *slow) >> 1) as f64 / 65536.0;
            if v {
                *fast -= *fast >> 4;
                *slow -= *slow >> 7;
            } else {
                *fast += (65536 - *fast) >> 4;
                *slow += (65536 - *slow) >> 7;
            }
            -(if v { 1.0 - p0 } else { p0 }).log2()
        }

        fn charge(&mut self, model: usize, bits: f64) {
            let c = self.cost.entry(model).or_default();
            c.0 += bits;
            c.1 += 1;
        }
    }

    impl Side for Meter {
        fn uint(&mut self, _: &mut crate::ec::UIntModel, _: u32) -> u32 {
            unreachable!("the UV coder codes no unsigned integers")
        }
        fn bit(&mut self, m: &mut BitModel, v: bool) -> bool {
            let key = m as *const _ as usize;
            let bits = self.code(key, v);
            self.charge(key, bits);
            v
        }
        fn int(&mut self, m: &mut IntModel, v: i32) -> i32 {
            // Zero flag, sign, Exp-Golomb (k = 0) prefix with one model per bit, raw suffix.
            let key = m as *const _ as usize;
            let mut bits = self.code(key, v != 0);
            if v != 0 {
                bits += self.code(key + 1, v < 0);
                let prefix = 63 - (v.unsigned_abs() as u64).leading_zeros();
                bits += (0..prefix).map(|i| self.code(key + 2 + i as usize, true)).sum::<f64>();
                bits += self.code(key + 2 + prefix as usize, false) + prefix as f64;
            }
            self.charge(key, bits);
            v
        }
        fn bypass(&mut self, v: u32, n: u32) -> u32 {
            self.charge(0, n as f64);
            v
        }
        fn failed(&self) -> bool {
            false
        }
    }

    /// (class, symbols, bits) of coding the atlas, classes in a fixed order.
    pub fn measure(faces: &[[u32; 3]], positions: Option<&[[f64; 3]]>, uv_faces: &[[u32; 3]], uv: &[[u32; 2]], bits: u32) -> Vec<(String, usize, f64)> {
        let mut meter = Meter::default();
        let mut models = Models::new();
        let n = faces.iter().flatten().map(|&v| v as usize + 1).max().unwrap_or(0);
        walk(&mut meter, &mut models, faces, positions, n, bits, Some(Truth::new(uv_faces, uv))).expect("codes");
        let address = |m: &BitModel| m as *const _ as usize;
        let choice: Vec<usize> = models
            .first
            .iter()
            .flatten()
            .flatten()
            .flatten()
            .chain(models.new.iter().flatten())
            .chain(&models.rank)
            .chain([&models.fresh])
            .map(address)
            .collect();
        let mut classes = vec![("which UV".to_string(), choice)];
        for (kind, pair) in Prediction::ALL.iter().zip(&models.residual) {
            classes.push((format!("{kind:?} residual"), pair.iter().map(|m| m as *const _ as usize).collect()));
        }
        classes.push(("raw (chart starts, escapes)".into(), vec![0]));
        classes
            .into_iter()
            .map(|(name, keys)| {
                let (b, n) = keys.iter().filter_map(|k| meter.cost.get(k)).fold((0.0, 0), |(b, n), c| (b + c.0, n + c.1));
                (name, n, b)
            })
            .collect()
    }
}
