//! Parts of a connected piece of the reference base found by how they move (ours; not in the
//! paper).
//!
//! A capture merges whatever touches into one surface: hands on the body, feet on the floor,
//! the teeth of two meshing gears. One rigid motion per connected piece ([`super::rigid`])
//! then fits none of what moves inside it. So a piece is cut into regions around seeds spread
//! over it (farthest points first); each region gets its own rigid fit; every region then
//! takes, of the piece's motion and all the regions' motions, the one that brings it closest
//! to the input, and regions that took the same motion form a part. A part boundary may thus
//! run anywhere through the piece. Finally each vertex near a boundary may move to a
//! neighbouring part whose motion lands it much closer, so that a boundary follows the
//! surface where two rigid bodies touch rather than the regions' straight cuts.
//!
//! The regions are a tool of the search only: a part is a union of regions that moved alike,
//! so a piece that moves as one keeps one motion, and a body whose limbs bend gets one motion
//! per limb that turns clearly differently.

use crate::geom::bvh::Bvh;
use crate::geom::mesh::{dist2, Mesh};

use super::rigid::{part_motion, piece_members, refined_motion, trimmed_cost, Aligned, PartMotions, Rigid};

/// About one region per this many vertices of a piece...
const REGION_SIZE: usize = 150;
/// ... and at most this many: each region costs a few rigid fits.
const MAX_REGIONS: usize = 12;
/// The regions that choose among the motions found are smaller, about this many vertices:
/// a region that straddles two bodies takes one motion for all of its vertices.
const CHOICE_SIZE: usize = 24;
/// A cell takes a motion by itself only when it brings the cell this much closer (trimmed
/// cost) than any other; otherwise its neighbours decide.
const SPLIT_GAIN: f64 = 0.25;
/// A vertex moves to a neighbouring part only when that part's motion lands it this much
/// closer (squared distance) than its own part's.
const VERTEX_GAIN: f64 = 0.25;

/// Cuts the pieces of `aligned` (from [`super::rigid::align_parts`] on `reference`) into the
/// parts that move apart inside them ([`motion_parts`]), new parts numbered after the pieces,
/// and moves `aligned.positions` by them. A region's search starts from `previous`'s motion
/// of its seed vertex (ignored unless it has one part per vertex of `reference`).
pub fn split_by_motion(reference: &Mesh, input: &Bvh, previous: Option<&PartMotions>, aligned: &mut Aligned) {
    if input.is_empty() {
        return;
    }
    let per_vertex = previous.filter(|p| p.parts.len() == reference.positions.len());
    let motions = &mut aligned.motions;
    for (i, m) in piece_members(&motions.parts.clone()).iter().enumerate() {
        let points: Vec<[f64; 3]> = m.iter().map(|&v| reference.positions[v]).collect();
        let predicted = |k: usize| per_vertex.map(|p| p.of(m[k]));
        if let Some((sub, extra)) = motion_parts(&points, &piece_faces(reference, m), input, motions.motions[i], &predicted) {
            let first = motions.motions.len() as u32 - 1;
            for (&v, &s) in m.iter().zip(&sub) {
                motions.parts[v] = if s == 0 { i as u32 } else { first + s };
            }
            motions.motions.extend(&extra[1..]);
        }
    }
    aligned.positions = motions.moved(&reference.positions);
}

/// Per vertex of `piece` (the positions of one connected piece), the index of its part, and
/// the rigid motion of each part, part 0 being `whole` (the piece's own motion). Returns
/// `None` when the piece is too small to cut or no region moves clearly apart from `whole`.
/// `predicted(v)` is the motion that vertex `v` of the piece had in the reference frame, if
/// known: it predicts the motion of a region seeded at `v`.
fn motion_parts(piece: &[[f64; 3]], faces: &[[u32; 3]], input: &Bvh, whole: Rigid, predicted: &dyn Fn(usize) -> Option<Rigid>) -> Option<(Vec<u32>, Vec<Rigid>)> {
    let k = (piece.len() / REGION_SIZE).min(MAX_REGIONS);
    if k < 2 {
        return None;
    }
    let seeds = farthest_seeds(piece, k);
    let region = nearest_seed(piece, &seeds);
    let members = grouped(piece, &region, k);
    let mut motions = vec![whole];
    // A region is empty only where seeds coincide (vertices at one place); it has no motion.
    motions.extend(seeds.iter().zip(&members).map(|(&s, pts)| if pts.is_empty() { whole } else { part_motion(pts, input, predicted(s)) }));
    let motions = distinct(motions, piece);
    let cells = nearest_seed(piece, &farthest_seeds(piece, (piece.len() / CHOICE_SIZE).max(k)));
    let chosen = propagated(&cell_choices(piece, &cells, input, &motions), &cell_neighbours(faces, &cells));
    if chosen.iter().all(|&c| c == chosen[0]) {
        return None;
    }
    // Parts: the motions some region chose, the piece's own first; each refitted on all of
    // its regions' points together.
    let mut used: Vec<usize> = std::iter::once(0).chain(chosen.iter().copied()).collect();
    used.sort_unstable();
    used.dedup();
    let part_of_motion = |m: usize| used.iter().position(|&u| u == m).expect("a used motion") as u32;
    let mut label: Vec<u32> = cells.iter().map(|&c| part_of_motion(chosen[c as usize])).collect();
    let parts: Vec<Rigid> = used
        .iter()
        .zip(grouped(piece, &label, used.len()))
        .map(|(&m, pts)| if m == 0 || pts.is_empty() { motions[m].1 } else { refined_motion(&pts, input, motions[m].1) })
        .collect();
    follow_contact(piece, faces, input, &parts, &mut label);
    Some((label, parts))
}

/// `k` vertices of `points` spread over them: the farthest from the centroid, then each time
/// the one farthest from those chosen.
fn farthest_seeds(points: &[[f64; 3]], k: usize) -> Vec<usize> {
    let n = points.len() as f64;
    let c = points.iter().fold([0.0; 3], |a, p| std::array::from_fn(|i| a[i] + p[i] / n));
    let first = argmax(points.iter().map(|&p| dist2(p, c)));
    let mut seeds = vec![first];
    let mut near: Vec<f64> = points.iter().map(|&p| dist2(p, points[first])).collect();
    while seeds.len() < k {
        let next = argmax(near.iter().copied());
        seeds.push(next);
        for (d, &p) in near.iter_mut().zip(points) {
            *d = d.min(dist2(p, points[next]));
        }
    }
    seeds
}

/// The index of the largest value (the first of equal ones); 0 for none.
fn argmax(values: impl Iterator<Item = f64>) -> usize {
    values.enumerate().fold((0, f64::NEG_INFINITY), |best, (i, v)| if v > best.1 { (i, v) } else { best }).0
}

/// The points of each label, in order: at least `count` groups (empty ones for labels no
/// point has).
fn grouped(points: &[[f64; 3]], labels: &[u32], count: usize) -> Vec<Vec<[f64; 3]>> {
    let mut groups: Vec<Vec<[f64; 3]>> = piece_members(labels).iter().map(|m| m.iter().map(|&v| points[v]).collect()).collect();
    if groups.len() < count {
        groups.resize(count, Vec::new());
    }
    groups
}

/// The index in `seeds` of the seed nearest to each point (the first of equally near ones).
fn nearest_seed(points: &[[f64; 3]], seeds: &[usize]) -> Vec<u32> {
    points
        .iter()
        .map(|&p| {
            let d = seeds.iter().map(|&s| dist2(p, points[s]));
            d.enumerate().fold((0, f64::INFINITY), |best, (i, v)| if v < best.1 { (i, v) } else { best }).0 as u32
        })
        .collect()
}

/// `motions` with those that move `points` alike replaced by the first of them (each by the
/// index of the one it equals): regions of one body find its motion each.
fn distinct(motions: Vec<Rigid>, points: &[[f64; 3]]) -> Vec<(usize, Rigid)> {
    let Some((lo, hi)) = crate::geom::mesh::bounds(points) else { return motions.into_iter().enumerate().collect() };
    // A few grid cells of a base of this many vertices: motions closer than that move the
    // vertices to the same neighbourhood, where the anchor's matching takes over.
    let tolerance = dist2(lo, hi).sqrt() / (points.len() as f64).sqrt();
    let sample: Vec<[f64; 3]> = points.iter().step_by(points.len().div_ceil(256).max(1)).copied().collect();
    let same = |a: &Rigid, b: &Rigid| sample.iter().all(|&p| dist2(a.apply(p), b.apply(p)) <= tolerance * tolerance);
    let mut out: Vec<(usize, Rigid)> = Vec::with_capacity(motions.len());
    for (i, m) in motions.iter().enumerate() {
        let first = (0..out.len()).find(|&j| out[j].0 == j && same(&motions[j], m));
        out.push((first.unwrap_or(i), *m));
    }
    out
}

/// Per cell, the motion (index of a distinct one) that brings its vertices closest to
/// `input`, when it does so clearly ([`SPLIT_GAIN`] against every other distinct motion);
/// `None` where two motions fit about equally (a flat cap turning about its normal, a rim
/// sliding along itself), for [`propagated`] to decide.
fn cell_choices(piece: &[[f64; 3]], cells: &[u32], input: &Bvh, motions: &[(usize, Rigid)]) -> Vec<Option<usize>> {
    let members = grouped(piece, cells, 0);
    let own: Vec<usize> = (0..motions.len()).filter(|&i| motions[i].0 == i).collect();
    members
        .iter()
        .map(|pts| {
            if pts.is_empty() {
                return None;
            }
            let mut costs: Vec<(f64, usize)> = own.iter().map(|&i| (trimmed_cost(pts, input, &motions[i].1), i)).collect();
            costs.sort_by(|a, b| a.0.total_cmp(&b.0));
            match costs.as_slice() {
                [best, second, ..] if best.0 < SPLIT_GAIN * second.0 => Some(best.1),
                [only] => Some(only.1),
                _ => None,
            }
        })
        .collect()
}

/// The cells next to each cell (sharing an edge of `faces`), ascending.
fn cell_neighbours(faces: &[[u32; 3]], cells: &[u32]) -> Vec<Vec<u32>> {
    let count = cells.iter().map(|&c| c as usize + 1).max().unwrap_or(0);
    let mut next = vec![Vec::new(); count];
    for f in faces {
        for (a, b) in [(f[0], f[1]), (f[1], f[2]), (f[2], f[0])] {
            let (ca, cb) = (cells[a as usize], cells[b as usize]);
            if ca != cb {
                next[ca as usize].push(cb);
                next[cb as usize].push(ca);
            }
        }
    }
    next.iter_mut().for_each(|n| {
        n.sort_unstable();
        n.dedup();
    });
    next
}

/// Every cell's motion: its own choice, or that of the nearest cell (in steps across cells,
/// the lowest index on ties) that made one; motion 0 when no cell did.
fn propagated(choices: &[Option<usize>], neighbours: &[Vec<u32>]) -> Vec<usize> {
    let mut out = choices.to_vec();
    let mut front: Vec<usize> = (0..out.len()).filter(|&c| out[c].is_some()).collect();
    while !front.is_empty() {
        let mut next = Vec::new();
        for &c in &front {
            for &n in &neighbours[c] {
                if out[n as usize].is_none() {
                    out[n as usize] = out[c];
                    next.push(n as usize);
                }
            }
        }
        front = next;
    }
    out.into_iter().map(|c| c.unwrap_or(0)).collect()
}

/// Moves vertices on part boundaries to a neighbouring part whose motion lands them
/// [`VERTEX_GAIN`] closer to `input`, ring after ring while any moves (at most a few): the
/// regions cut the piece along straight lines, the true boundary between two touching
/// bodies runs where their surfaces meet.
fn follow_contact(piece: &[[f64; 3]], faces: &[[u32; 3]], input: &Bvh, parts: &[Rigid], label: &mut [u32]) {
    const RINGS: usize = 8;
    let dist2 = |v: usize, p: u32| input.closest_point(parts[p as usize].apply(piece[v])).map_or(f64::INFINITY, |c| c.dist2);
    for _ in 0..RINGS {
        let mut moves = Vec::new();
        for f in faces {
            for (a, b) in [(f[0], f[1]), (f[1], f[2]), (f[2], f[0])] {
                for (v, other) in [(a, label[b as usize]), (b, label[a as usize])] {
                    if other != label[v as usize] {
                        moves.push((v as usize, other));
                    }
                }
            }
        }
        moves.sort_unstable();
        moves.dedup();
        let mut moved = false;
        for (v, other) in moves {
            if label[v] != other && dist2(v, other) < VERTEX_GAIN * dist2(v, label[v]) {
                label[v] = other;
                moved = true;
            }
        }
        if !moved {
            break;
        }
    }
}

/// The faces of a piece, its vertices renumbered from 0 in order: `members` are the
/// piece's vertex indices in `mesh`, ascending.
fn piece_faces(mesh: &Mesh, members: &[usize]) -> Vec<[u32; 3]> {
    let mut index = vec![u32::MAX; mesh.positions.len()];
    for (i, &v) in members.iter().enumerate() {
        index[v] = i as u32;
    }
    mesh.faces.iter().filter(|f| index[f[0] as usize] != u32::MAX).map(|f| f.map(|v| index[v as usize])).collect()
}

#[cfg(test)]
mod tests {
    use super::super::rigid::align_parts;
    use super::*;

    fn aligned(reference: &Mesh, input: &Bvh, by_motion: bool) -> Aligned {
        let mut a = align_parts(reference, input, None);
        if by_motion {
            split_by_motion(reference, input, None, &mut a);
        }
        a
    }

    /// A turn by `angle` about the z axis through (`x`, 0).
    fn turn_about(x: f64, angle: f64) -> Rigid {
        let (s, c) = angle.sin_cos();
        Rigid { rotation: [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]], translation: [x - c * x, -s * x, 0.0] }
    }

    /// Two toothed tubes around vertical axes at x = -3 and x = 3, each turned by its own
    /// motion, joined into one connected piece by a strip of faces between them: bodies in
    /// contact that a capture meshes as one surface.
    fn touching_tubes(left: &Rigid, right: &Rigid) -> Mesh {
        let (teeth, along) = (8u32, 4u32);
        let around = teeth * 6;
        let mut m = Mesh::default();
        for (x, motion) in [(-3.0, left), (3.0, right)] {
            for j in 0..=along {
                for i in 0..around {
                    let a = i as f64 / around as f64 * std::f64::consts::TAU;
                    let r = 2.0 + 0.4 * ((a * teeth as f64).cos() > 0.5) as u8 as f64;
                    m.positions.push(motion.apply([x + r * a.cos(), r * a.sin(), j as f64 * 0.5]));
                }
            }
        }
        let tube = (along + 1) * around;
        for t in 0..2 {
            for j in 0..along {
                for i in 0..around {
                    let v = |i: u32, j: u32| t * tube + j * around + i % around;
                    m.faces.push([v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
                    m.faces.push([v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
                }
            }
        }
        // The strip: vertex 0 of each ring of the left tube (its +x side) to vertex
        // around / 2 of the right tube's (its -x side).
        for j in 0..along {
            let (a, b) = (j * around, tube + j * around + around / 2);
            m.faces.push([a, b, b + around]);
            m.faces.push([a, b + around, a + around]);
        }
        m
    }

    #[test]
    fn bodies_in_one_piece_that_turn_apart_get_a_part_each() {
        let (left, right) = (turn_about(-3.0, 0.08), turn_about(3.0, -0.08));
        let reference = touching_tubes(&Rigid::IDENTITY, &Rigid::IDENTITY);
        let input = touching_tubes(&left, &right);
        let bvh = Bvh::new(&input.positions, &input.faces);
        let cost = |a: &Aligned| {
            a.positions.iter().map(|&p| bvh.closest_point(p).map_or(0.0, |c| c.dist2)).sum::<f64>() / a.positions.len() as f64
        };
        let (one, cut) = (aligned(&reference, &bvh, false), aligned(&reference, &bvh, true));
        assert_eq!(one.motions.motions.len(), 1, "one connected piece");
        assert!(cost(&cut) < 0.1 * cost(&one), "cut {} one {}", cost(&cut), cost(&one));
        // Each tube's vertices (but a few at the strip) share a part, and the two differ.
        let tube = reference.positions.len() / 2;
        let majority = |vs: std::ops::Range<usize>| {
            let mut count = std::collections::BTreeMap::new();
            vs.clone().for_each(|v| *count.entry(cut.motions.parts[v]).or_insert(0) += 1);
            count.into_iter().max_by_key(|&(_, n)| n).map(|(p, n)| (p, n as f64 / vs.len() as f64)).unwrap()
        };
        let ((pl, sl), (pr, sr)) = (majority(0..tube), majority(tube..2 * tube));
        assert!(pl != pr && sl > 0.9 && sr > 0.9, "left part {pl} ({sl}), right part {pr} ({sr})");
    }

    #[test]
    fn a_piece_that_moves_as_one_stays_one_part() {
        let m = turn_about(0.0, 0.05);
        let reference = touching_tubes(&Rigid::IDENTITY, &Rigid::IDENTITY);
        let input = touching_tubes(&m, &m);
        let bvh = Bvh::new(&input.positions, &input.faces);
        let a = aligned(&reference, &bvh, true);
        assert_eq!(a.motions.motions.len(), 1);
        assert!(a.motions.parts.iter().all(|&p| p == 0));
    }

    #[test]
    fn seeds_spread_and_propagation_fills_undecided_cells() {
        let pts = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [10.0, 0.0, 0.0], [11.0, 0.0, 0.0]];
        let seeds = farthest_seeds(&pts, 2);
        assert_eq!(nearest_seed(&pts, &seeds).iter().filter(|&&s| s == nearest_seed(&pts, &seeds)[0]).count(), 2);
        // Cells in a row 0-1-2-3: 0 chose motion 2, 3 chose motion 1, 1 and 2 undecided.
        let neighbours = vec![vec![1], vec![0, 2], vec![1, 3], vec![2]];
        assert_eq!(propagated(&[Some(2), None, None, Some(1)], &neighbours), vec![2, 2, 1, 1]);
        assert_eq!(propagated(&[None, None], &[vec![1], vec![0]]), vec![0, 0]);
    }
}
