//! Which UV each corner of a face uses, coded by both sides of [`crate::texture::uvcoder`] through
//! one function driven by [`Side`].
//!
//! **Which UV.** Each position vertex keeps the UVs already used at it (its candidates). A
//! corner either reuses one of them, takes a new UV, or (rarely: an atlas may share a UV
//! between positions) names any earlier UV by index. Most vertices have exactly one UV, so
//! the usual symbol is "the first candidate" at a fraction of a bit. Candidates are ranked
//! so that the first is nearly always right: one that forms an already-coded UV edge with a
//! UV this face reuses is on the same side of the seam; then the nearest in UV space to such
//! a UV (charts lie apart in the atlas); then the most recently used. The corners of a face
//! are decided in order of how many candidates they have, so that the ambiguous seam
//! corners come last, with the most context. The "first candidate" flag is modelled by
//! whether the candidate shares a coded UV edge with a reused UV of the face (or lies at a
//! plausible distance from one, given the atlas's running texels-per-unit), whether the face
//! already took new UVs and where, and, with positions, whether the coded face that used the
//! candidate across an edge continues this face smoothly: seams follow creases.
//!

use crate::error::Corrupt;
use crate::ec::Side;
use crate::geom::mesh::{dot, edge_key, sub};
use crate::texture::uv_state::{face_normal, squared_distance, Atlas, Models, Truth, BEND_COS};

/// What a corner uses: a UV already coded (by coded index) or a new one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Choice {
    Existing(u32),
    New,
}

/// Codes which UV each corner of `face` uses. Returns the coded indices; a new UV gets the
/// next free index (`atlas.uv.len()` and up, in decision order) and its value comes later.
pub(crate) fn decide_corners<S: Side>(
    side: &mut S,
    models: &mut Models,
    atlas: &Atlas,
    face: &[u32; 3],
    mut truth: Option<(&mut Truth, usize)>,
) -> Result<[u32; 3], Corrupt> {
    let coded = atlas.uv.len() as u32;
    let mut ids = [u32::MAX; 3];
    let mut pending = 0u32;
    let mut news = 0;
    let mut order = [0usize, 1, 2];
    order.sort_by_key(|&k| atlas.candidates[face[k] as usize].len());
    for k in order {
        let references: Vec<u32> = ids.iter().copied().filter(|&i| i < coded).collect();
        let ranked = ranked_candidates(atlas, &atlas.candidates[face[k] as usize], &references);
        let reference_corners: Vec<usize> = (0..3).filter(|&j| ids[j] < coded).collect();
        let wanted = truth.as_ref().map(|(t, f)| t.coded_index[t.uv_faces[*f][k] as usize]);
        let wanted = match wanted {
            Some(u32::MAX) | None => Choice::New,
            Some(i) => Choice::Existing(i),
        };
        let context = CornerContext {
            several: ranked.len() > 1,
            reference: match ranked.first() {
                None => 0,
                _ if references.is_empty() => 0,
                Some(&c) if references.iter().any(|&r| atlas.opposite.contains_key(&edge_key(c, r))) => 1,
                Some(&c) if reference_corners.iter().any(|&j| plausible(atlas, face, k, c, j, ids[j])) => 2,
                Some(_) => 3,
            },
            news,
            bend: match ranked.first() {
                Some(&c) if references.is_empty() => bend(atlas, face, k, c),
                _ => 0,
            },
        };
        let choice = code_choice(side, models, &ranked, context, coded + pending, wanted)?;
        ids[k] = match choice {
            Choice::Existing(i) => i,
            Choice::New => {
                news = news.max(if ranked.is_empty() { 1 } else { 2 });
                pending += 1;
                coded + pending - 1
            }
        };
        if let Some((t, f)) = truth.as_mut() {
            t.coded_index[t.uv_faces[*f][k] as usize] = ids[k];
        }
    }
    Ok(ids)
}

/// Context of a corner's decision.
#[derive(Clone, Copy)]
struct CornerContext {
    several: bool,
    /// 0: no reused UV in the face yet; 1: the first candidate shares a coded UV edge with
    /// one; 2: it does not, but lies at a plausible distance from one; 3: it is far.
    reference: usize,
    /// New UVs of the face so far: 0 none; 1 only at vertices without candidates (the chart
    /// grows); 2 at a vertex that had candidates (the face is across a seam).
    news: usize,
    /// Without a reference: 0 unknown, 1 a coded face across an edge at the corner uses the
    /// first candidate there and continues this face smoothly, 2 it bends sharply (seams
    /// follow creases).
    bend: usize,
}

/// Whether UV `c` at corner `k` lies about as far from UV `r` at corner `j` as the atlas's
/// scale makes likely for the same chart (another chart is usually far away).
fn plausible(atlas: &Atlas, face: &[u32; 3], k: usize, c: u32, j: usize, r: u32) -> bool {
    if atlas.edges == 0.0 {
        return true;
    }
    let expected = match atlas.positions {
        Some(p) if atlas.length_3d > 0.0 => {
            let d = sub(p[face[k] as usize], p[face[j] as usize]);
            dot(d, d).sqrt() * atlas.uv_length / atlas.length_3d
        }
        _ => atlas.uv_length / atlas.edges,
    };
    let distance = (squared_distance(atlas.uv[c as usize], atlas.uv[r as usize]) as f64).sqrt();
    distance <= 2.0 * expected + 2.0
}

/// The [`CornerContext::bend`] of candidate `c` at corner `k`.
fn bend(atlas: &Atlas, face: &[u32; 3], k: usize, c: u32) -> usize {
    let Some(p) = atlas.positions else { return 0 };
    let Some(n) = face_normal(p, face) else { return 0 };
    let v = face[k];
    let smoothest = (1..3)
        .filter_map(|d| atlas.edge_face.get(&edge_key(v, face[(k + d) % 3])))
        .filter(|&&g| (0..3).any(|i| atlas.faces[g as usize][i] == v && atlas.uv_faces[g as usize][i] == c))
        .filter_map(|&g| face_normal(p, &atlas.faces[g as usize]))
        .map(|m| dot(n, m))
        .fold(f64::NEG_INFINITY, f64::max);
    match smoothest {
        x if x == f64::NEG_INFINITY => 0,
        x if x >= BEND_COS => 1,
        _ => 2,
    }
}

/// The candidates most likely first: those sharing a coded UV edge with a reference (a UV
/// this face reuses), then by distance to the nearest reference, then most recently used.
fn ranked_candidates(atlas: &Atlas, candidates: &[u32], references: &[u32]) -> Vec<u32> {
    let mut ranked = candidates.to_vec();
    ranked.sort_by_key(|&c| {
        let connected = references.iter().any(|&r| atlas.opposite.contains_key(&edge_key(c, r)));
        let distance = references.iter().map(|&r| squared_distance(atlas.uv[c as usize], atlas.uv[r as usize])).min();
        (!connected, distance.unwrap_or(0), std::cmp::Reverse(atlas.last_used[c as usize]))
    });
    ranked
}

/// Codes one corner's choice among `ranked` candidates, a new UV, or (escape) any of the
/// `total` UVs coded or pending so far by index.
fn code_choice<S: Side>(
    side: &mut S,
    models: &mut Models,
    ranked: &[u32],
    cx: CornerContext,
    total: u32,
    wanted: Choice,
) -> Result<Choice, Corrupt> {
    if ranked.is_empty() {
        if side.bit(&mut models.fresh, wanted == Choice::New) {
            return Ok(Choice::New);
        }
    } else {
        let m = &mut models.first[cx.several as usize][cx.reference][cx.news][cx.bend];
        if side.bit(m, wanted == Choice::Existing(ranked[0])) {
            return Ok(Choice::Existing(ranked[0]));
        }
        if side.bit(&mut models.new[cx.several as usize][cx.news], wanted == Choice::New) {
            return Ok(Choice::New);
        }
        for (r, &c) in ranked.iter().enumerate().skip(1) {
            if side.bit(&mut models.rank[(r - 1).min(3)], wanted == Choice::Existing(c)) {
                return Ok(Choice::Existing(c));
            }
        }
    }
    if total == 0 {
        return Err("UV atlas: a corner refers to an earlier UV before any".into());
    }
    let index = match wanted {
        Choice::Existing(i) => i,
        Choice::New => 0,
    };
    let i = side.bypass(index, index_bits(total));
    if i >= total {
        return Err(format!("UV atlas: a corner refers to UV {i} of {total}").into());
    }
    Ok(Choice::Existing(i))
}

/// Bits that hold any index below `total` (> 0).
fn index_bits(total: u32) -> u32 {
    32 - (total - 1).leading_zeros()
}

