//! Rigid alignment in front of the anchor's matching (ours; not a stage of the paper): each
//! connected part of the reference base gets the rigid motion that brings its vertices
//! closest to the input surface, by iterative closest points.
//!
//! Nearest-neighbour matching and neighbour-mean motion describe small, smooth motion. A part
//! that turns by more than the spacing of its features (a gear by more than a tooth, a body
//! turning on the spot) is matched vertex by vertex to the wrong features, and the anchor
//! tears. A rigid motion per part moves the whole part consistently first, so that the
//! matching only has to follow what is left. Each part starts from no motion and from the
//! motion it had in the previous frame (a constant-velocity prediction, when the reference
//! frame was itself predicted; otherwise from the most promising of a few turns about its
//! principal axes), and keeps whichever result lies closer to the input; a
//! part whose fit does not lie clearly closer than not moving at all stays where it is.

use nalgebra::{Matrix3, Rotation3, SymmetricEigen, Unit, Vector3};
use rayon::prelude::*;

use crate::geom::bvh::Bvh;
use crate::geom::mesh::{add, norm, sub, Mesh};

/// Closest-point rounds per start, at most: a part turning along itself (a rim, a disc)
/// creeps towards its fit, a few grid units a round.
const ROUNDS: usize = 24;
/// Rounds stop when no point of the part moves more than this share of the part's size from
/// one round to the next.
const SETTLED: f64 = 1e-5;
/// The share of pairs, nearest first, that a round's fit uses: where the input's topology
/// changed (an arm that left the body) the reference has no counterpart and would pull the
/// part off. Not a multiple of the median: a turning disc or rim slides along itself, so
/// most pairs are at distance zero and the few that see the turn (the flanks of its teeth)
/// are the ones that count.
const KEEP: f64 = 0.9;
/// The rounds fit at most this many of a part's points (every k-th, in order); the costs that
/// choose between the fits use all of them. The rounds were 90 % of the anchor's time on
/// dancer, whose body is one part of 1,800 base vertices; fitting a sixth of them left its
/// streams and basketball_player's within a byte (docs/results.md).
const ROUND_SAMPLES: usize = 512;
/// Parts with fewer vertices keep no motion: three points do not determine a rotation well.
const MIN_PART: usize = 6;
/// A fit is kept only when it brings the part at least this much closer (trimmed cost
/// against no motion): a body whose limbs move apart is not moved rigidly, which on the
/// capture sequences cost bits, while a part that turns as a whole is.
const GAIN: f64 = 0.5;

/// A point and the point it should move to.
pub type Pair = ([f64; 3], [f64; 3]);

/// A rotation then a translation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rigid {
    pub rotation: [[f64; 3]; 3],
    pub translation: [f64; 3],
}

impl Rigid {
    pub const IDENTITY: Self = Self { rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], translation: [0.0; 3] };

    pub fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        add(self.rotate(p), self.translation)
    }

    fn from_matrices(r: &Matrix3<f64>, t: &Vector3<f64>) -> Self {
        Self { rotation: std::array::from_fn(|i| std::array::from_fn(|j| r[(i, j)])), translation: [t[0], t[1], t[2]] }
    }

    /// The rotation alone (for directions).
    pub fn rotate(&self, p: [f64; 3]) -> [f64; 3] {
        let r = &self.rotation;
        std::array::from_fn(|i| r[i][0] * p[0] + r[i][1] * p[1] + r[i][2] * p[2])
    }
}

/// Per connected part of `reference` (by faces; a vertex that no face uses is a part of its
/// own), the part index of each vertex, parts numbered in the order of their first vertex.
pub fn parts(reference: &Mesh) -> Vec<u32> {
    let n = reference.positions.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut v: usize) -> usize {
        while parent[v] != v {
            parent[v] = parent[parent[v]];
            v = parent[v];
        }
        v
    }
    for f in &reference.faces {
        for k in 1..3 {
            let (a, b) = (root(&mut parent, f[0] as usize), root(&mut parent, f[k] as usize));
            parent[a.max(b)] = a.min(b);
        }
    }
    let mut label = vec![u32::MAX; n];
    let mut count = 0;
    for v in 0..n {
        let r = root(&mut parent, v);
        if label[r] == u32::MAX {
            label[r] = count;
            count += 1;
        }
        label[v] = label[r];
    }
    label
}

/// The parts of a reference base and how each moved.
#[derive(Debug, Clone, PartialEq)]
pub struct PartMotions {
    /// The part of each vertex: its connected piece ([`parts`]), or a part found inside a
    /// piece ([`super::parts`]), numbered after the pieces.
    pub parts: Vec<u32>,
    /// The motion of each part; the first `pieces` are the pieces' own motions.
    pub motions: Vec<Rigid>,
    /// The number of connected pieces.
    pub pieces: usize,
}

impl PartMotions {
    /// The motion of vertex `v`.
    pub fn of(&self, v: usize) -> Rigid {
        self.motions[self.parts[v] as usize]
    }

    /// `positions` (one per vertex) each moved by its part's motion.
    pub fn moved(&self, positions: &[[f64; 3]]) -> Vec<[f64; 3]> {
        positions.iter().enumerate().map(|(v, &p)| self.of(v).apply(p)).collect()
    }
}

/// A reference moved part by part.
pub struct Aligned {
    pub positions: Vec<[f64; 3]>,
    pub motions: PartMotions,
}

/// The rigid motion of each connected piece of `reference` onto `input`, tried from no
/// motion and from the piece's motion in `previous` when given (ignored unless it has as
/// many pieces), and the reference positions moved by them. [`super::parts`] may then cut the
/// pieces further.
pub fn align_parts(reference: &Mesh, input: &Bvh, previous: Option<&PartMotions>) -> Aligned {
    let label = parts(reference);
    let members = piece_members(&label);
    let count = members.len();
    let motions: Vec<Rigid> = members
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let predicted = previous.filter(|p| p.pieces == count).map(|p| p.motions[i]);
            let points: Vec<[f64; 3]> = m.iter().map(|&v| reference.positions[v]).collect();
            if m.len() < MIN_PART || input.is_empty() { Rigid::IDENTITY } else { part_motion(&points, input, predicted) }
        })
        .collect();
    let motions = PartMotions { parts: label, motions, pieces: count };
    Aligned { positions: motions.moved(&reference.positions), motions }
}

/// The vertices of each part of a labelling, ascending.
pub fn piece_members(label: &[u32]) -> Vec<Vec<usize>> {
    let count = label.iter().map(|&l| l as usize + 1).max().unwrap_or(0);
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); count];
    for (v, &l) in label.iter().enumerate() {
        members[l as usize].push(v);
    }
    members
}

/// The best of ICP from no motion and from `predicted` (or, without one, from the best
/// screened turn), or no motion if none lies [`GAIN`] closer.
pub(super) fn part_motion(points: &[[f64; 3]], input: &Bvh, predicted: Option<Rigid>) -> Rigid {
    let mut best = (trimmed_cost(points, input, &Rigid::IDENTITY) * GAIN, Rigid::IDENTITY);
    let turned = predicted.is_none().then(|| screened_turn(points, input));
    let sample = every_kth(points, ROUND_SAMPLES);
    for start in std::iter::once(Rigid::IDENTITY).chain(predicted).chain(turned) {
        let fitted = icp(&sample, input, start, ROUNDS);
        let cost = trimmed_cost(points, input, &fitted);
        if cost < best.0 {
            best = (cost, fitted);
        }
    }
    best.1
}

/// ICP from `start` over (a sample of) `points`: a motion found on part of them, fitted to all.
pub(super) fn refined_motion(points: &[[f64; 3]], input: &Bvh, start: Rigid) -> Rigid {
    let fitted = icp(&every_kth(points, ROUND_SAMPLES), input, start, ROUNDS);
    if trimmed_cost(points, input, &fitted) < trimmed_cost(points, input, &start) { fitted } else { start }
}

/// The turns tried when a part has no previous motion, in degrees about each of its principal
/// axes through its centroid: on a coarse base rim (a gear of 174 base vertices turned by 12
/// degrees) ICP from no motion stalled near it or turned the wrong way, so gears turning 12
/// degrees or more per frame were coded intra.
const TURN_DEGREES: [f64; 4] = [-20.0, -10.0, 10.0, 20.0];
/// Each turn is screened by a few rounds over a few points before the best one is refined.
const SCREEN_ROUNDS: usize = 4;
const SCREEN_SAMPLES: usize = 128;

/// The turned start ([`TURN_DEGREES`]) whose short ICP ends closest to the input, refined no
/// further.
fn screened_turn(points: &[[f64; 3]], input: &Bvh) -> Rigid {
    let c = centroid(points.iter().copied());
    let cov: Matrix3<f64> = points.iter().map(|&p| (Vector3::from(p) - c) * (Vector3::from(p) - c).transpose()).sum::<Matrix3<f64>>() / points.len() as f64;
    let axes = SymmetricEigen::new(cov).eigenvectors;
    let sample = every_kth(points, SCREEN_SAMPLES);
    let starts = (0..3).flat_map(|k| TURN_DEGREES.iter().map(move |&d| (k, d))).map(|(k, d)| {
        let r = Rotation3::from_axis_angle(&Unit::new_normalize(axes.column(k).into_owned()), d.to_radians());
        Rigid::from_matrices(r.matrix(), &(c - r * c))
    });
    starts
        .map(|start| icp(&sample, input, start, SCREEN_ROUNDS))
        .map(|fit| (trimmed_cost(&sample, input, &fit), fit))
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, fit)| fit)
        .expect("there are turns to try")
}

/// Every k-th of `points`, in order, k the least that leaves at most `most`.
fn every_kth(points: &[[f64; 3]], most: usize) -> Vec<[f64; 3]> {
    points.iter().step_by(points.len().div_ceil(most).max(1)).copied().collect()
}

/// Mean squared distance to the surface of the [`KEEP`] share of the moved points nearest
/// to it: what ICP lowers, measured the same way for every candidate.
pub(super) fn trimmed_cost(points: &[[f64; 3]], input: &Bvh, motion: &Rigid) -> f64 {
    let d2: Vec<f64> = points.par_iter().map(|&p| input.closest_point(motion.apply(p)).map_or(0.0, |c| c.dist2)).collect();
    let limit = kept_limit(&d2);
    let kept: Vec<f64> = d2.into_iter().filter(|&d| d <= limit).collect();
    kept.iter().sum::<f64>() / kept.len().max(1) as f64
}

/// The largest of the [`KEEP`] share of smallest values.
fn kept_limit(values: &[f64]) -> f64 {
    let mut v = values.to_vec();
    let k = ((v.len() as f64 * KEEP).ceil() as usize).clamp(1, v.len()) - 1;
    v.select_nth_unstable_by(k, f64::total_cmp);
    v[k]
}

/// Point-to-point iterative closest points from `start`, trimmed to [`KEEP`], at most `rounds`
/// rounds.
fn icp(points: &[[f64; 3]], input: &Bvh, start: Rigid, rounds: usize) -> Rigid {
    let mut motion = start;
    let mut hints = vec![u32::MAX; points.len()];
    let tolerance = crate::geom::mesh::bounds(points).map_or(0.0, |(lo, hi)| norm(sub(hi, lo))) * SETTLED;
    for _ in 0..rounds {
        // The rounds are most of the anchor's time; the queries are independent, so in parallel.
        let pairs: Vec<([f64; 3], [f64; 3], f64)> = points
            .par_iter()
            .zip(hints.par_iter_mut())
            .filter_map(|(&p, hint)| {
                let c = input.closest_point_near(motion.apply(p), *hint)?;
                *hint = c.triangle;
                Some((p, c.point, c.dist2))
            })
            .collect();
        if pairs.is_empty() {
            break;
        }
        let limit = kept_limit(&pairs.iter().map(|p| p.2).collect::<Vec<_>>());
        let kept: Vec<Pair> = pairs.iter().filter(|p| p.2 <= limit).map(|p| (p.0, p.1)).collect();
        let Some(next) = best_rigid(&kept) else { break };
        let settled = points.iter().all(|&p| norm(sub(next.apply(p), motion.apply(p))) <= tolerance);
        motion = next;
        if settled {
            break;
        }
    }
    motion
}

/// The mean of `points` (not empty).
fn centroid(points: impl ExactSizeIterator<Item = [f64; 3]>) -> Vector3<f64> {
    let n = points.len() as f64;
    points.map(Vector3::from).sum::<Vector3<f64>>() / n
}

/// The rigid motion taking the first point of each pair closest to the second (least squares,
/// Kabsch's method; a reflection is turned into the nearest rotation). None for fewer than
/// three pairs.
pub fn best_rigid(pairs: &[Pair]) -> Option<Rigid> {
    if pairs.len() < 3 {
        return None;
    }
    let (cs, ct) = (centroid(pairs.iter().map(|p| p.0)), centroid(pairs.iter().map(|p| p.1)));
    let h: Matrix3<f64> = pairs.iter().map(|(s, t)| (Vector3::from(*s) - cs) * (Vector3::from(*t) - ct).transpose()).sum();
    let svd = h.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let mut d = Matrix3::identity();
    if (v_t.transpose() * u.transpose()).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let r = v_t.transpose() * d * u.transpose();
    let t = ct - r * cs;
    Some(Rigid::from_matrices(&r, &t))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn turn_z(angle: f64, t: [f64; 3]) -> Rigid {
        let (s, c) = angle.sin_cos();
        Rigid { rotation: [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]], translation: t }
    }

    /// A closed, bumpy tube around the z axis (radius 2 with `teeth` ridges), so that a turn
    /// is visible to closest points but repeats every `2 pi / teeth`.
    fn toothed(teeth: u32, motion: &Rigid) -> Mesh {
        let (around, along) = (teeth * 6, 4u32);
        let mut m = Mesh::default();
        for j in 0..=along {
            for i in 0..around {
                let a = i as f64 / around as f64 * std::f64::consts::TAU;
                let r = 2.0 + 0.4 * ((a * teeth as f64).cos() > 0.5) as u8 as f64;
                m.positions.push(motion.apply([r * a.cos(), r * a.sin(), j as f64 * 0.5]));
            }
        }
        for j in 0..along {
            for i in 0..around {
                let v = |i: u32, j: u32| j * around + i % around;
                m.faces.push([v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
                m.faces.push([v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
            }
        }
        m
    }

    #[test]
    fn kabsch_recovers_a_rigid_motion() {
        let m = turn_z(0.7, [1.0, -2.0, 0.5]);
        let pts = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0], [1.0, 1.0, 1.0]];
        let pairs: Vec<_> = pts.iter().map(|&p| (p, m.apply(p))).collect();
        let r = best_rigid(&pairs).unwrap();
        for &p in &pts {
            let d = sub(r.apply(p), m.apply(p));
            assert!(d.iter().all(|x| x.abs() < 1e-9), "{d:?}");
        }
        assert!(best_rigid(&pairs[..2]).is_none());
    }

    #[test]
    fn parts_are_the_connected_pieces_in_order_of_their_first_vertex() {
        let m = Mesh::new(vec![[0.0; 3]; 7], vec![[3, 4, 5], [0, 1, 2], [2, 1, 6]]);
        assert_eq!(parts(&m), vec![0, 0, 0, 1, 1, 1, 0]);
    }

    #[test]
    fn a_part_is_moved_onto_the_surface_it_moved_to() {
        let reference = toothed(8, &Rigid::IDENTITY);
        // A small turn and shift: ICP from no motion finds it.
        let input = toothed(8, &turn_z(0.05, [0.1, 0.05, 0.0]));
        let bvh = Bvh::new(&input.positions, &input.faces);
        let a = align_parts(&reference, &bvh, None);
        let before = trimmed_cost(&reference.positions, &bvh, &Rigid::IDENTITY);
        let after = trimmed_cost(&reference.positions, &bvh, &a.motions.motions[0]);
        assert!(after < before * 0.01, "before {before} after {after}");
        assert_eq!(a.positions.len(), reference.positions.len());
    }

    #[test]
    fn the_previous_motion_finds_a_turn_that_no_motion_does_not() {
        // An oval body turning by a large angle each frame: from no motion, ICP settles in the
        // nearer (wrong) alignment; from the previous frame's turn it finds the true one.
        let oval = |m: &Rigid| {
            let mut t = toothed(1, &Rigid::IDENTITY);
            t.positions.iter_mut().for_each(|p| *p = m.apply([p[0] * 2.0, p[1] * 0.6, p[2]]));
            t
        };
        let turn = turn_z(1.2, [0.0; 3]);
        let (reference, input) = (oval(&Rigid::IDENTITY), oval(&turn));
        let bvh = Bvh::new(&input.positions, &input.faces);
        let fits = |previous: Option<&PartMotions>| {
            let a = align_parts(&reference, &bvh, previous);
            trimmed_cost(&reference.positions, &bvh, &a.motions.motions[0])
        };
        let (alone, predicted) = (fits(None), fits(Some(&PartMotions { parts: vec![0; reference.positions.len()], motions: vec![turn_z(1.15, [0.0; 3])], pieces: 1 })));
        assert!(predicted < alone * 0.1 && predicted < 1e-3, "alone {alone} predicted {predicted}");
    }

    #[test]
    fn a_turn_that_only_the_teeth_flanks_show_is_found() {
        // Most points of a turning toothed rim slide along the rim (distance zero); only the
        // flanks see the turn, and they must not be trimmed away as outliers.
        let reference = toothed(12, &Rigid::IDENTITY);
        let input = toothed(12, &turn_z(0.09, [0.0; 3]));
        let bvh = Bvh::new(&input.positions, &input.faces);
        let r = align_parts(&reference, &bvh, None).motions.motions[0].rotation;
        let angle = r[1][0].atan2(r[0][0]);
        assert!((angle - 0.09).abs() < 0.01, "{angle}");
    }

    #[test]
    fn a_part_larger_than_the_round_sample_is_aligned() {
        // 720 vertices: the rounds fit every second one, the choice weighs all.
        let reference = toothed(24, &Rigid::IDENTITY);
        assert!(reference.positions.len() > ROUND_SAMPLES);
        let input = toothed(24, &turn_z(0.06, [0.05, 0.0, 0.02]));
        let bvh = Bvh::new(&input.positions, &input.faces);
        let m = align_parts(&reference, &bvh, None).motions.motions[0];
        let angle = m.rotation[1][0].atan2(m.rotation[0][0]);
        assert!((angle - 0.06).abs() < 0.01, "{angle}");
        assert!(trimmed_cost(&reference.positions, &bvh, &m) < 0.01 * trimmed_cost(&reference.positions, &bvh, &Rigid::IDENTITY));
    }

    #[test]
    fn a_still_part_keeps_no_motion() {
        let m = toothed(8, &Rigid::IDENTITY);
        let bvh = Bvh::new(&m.positions, &m.faces);
        for (a, b) in align_parts(&m, &bvh, None).positions.iter().zip(&m.positions) {
            assert!(sub(*a, *b).iter().all(|x| x.abs() < 1e-9));
        }
    }
}
