//! D1 / D2 geometry PSNR and Y / Cb / Cr texture PSNR as the MPEG V-DMC common test conditions
//! measure them with the MPEG tool `mmetric` (`sample --mode grid --useNormal --useFixedPoint`
//! followed by `compare --mode pcc`, whose distance code is the MPEG `pc_error` / dmetric
//! library).
//!
//! Pipeline: [`SamplingGrid::over_box`] lays one grid over the reference box, [`sample_grid`]
//! turns each mesh into a point cloud with per-point normals, [`distortion`] computes the
//! symmetric point-to-point (D1) and point-to-plane (D2) mean squared errors, [`psnr`] converts
//! an MSE into dB. [`mesh_psnr`] chains the four.
//!
//! Texture: [`sample_grid_coloured`] samples a textured mesh at the same points, reading the
//! texture bilinearly at each sample's UV and rounding to 8-bit RGB as mmetric does;
//! [`colour_mse`] is the symmetric per-channel error in BT.709 YCbCr [0, 1] (for each point, the
//! squared difference to the colour of its nearest points in the other cloud), [`colour_psnr`]
//! converts with peak 1.
//! [`textured_mse`] / [`textured_psnr`] chain them with the geometry figures, sharing one pass of
//! nearest-neighbour queries.
//!
//! # What is mirrored from mmetric
//! - **Grid.** The box corner is rounded down and the far corner up to multiples of 1/65536;
//!   step = (largest side of the rounded box) x (1 / (grid size - 1)), rounded *up* to a multiple
//!   of 1/65536. As in mmetric all of this is single precision (`f32`).
//! - **Rasterization** (single precision, like mmetric's `glm::vec3`). Each triangle is first
//!   rotated so that its lexicographically smallest vertex comes first (what mmetric's
//!   `reindex --sort oriented` does before sampling; it changes only rounding). Triangles with
//!   area below `f64::EPSILON` are skipped. The face normal is `normalize(cross(b - a, c - a))`.
//!   The main axis is the one with the largest |normal| component (ties: x before y before z).
//!   Rays run along +main axis from the grid plane at `floor((tri_min - origin) / step)`, one per
//!   grid line `floor(..)..=ceil(..)` of the triangle's box on the two other axes. The hit test is
//!   Moller-Trumbore with mmetric's absolute determinant tolerance 1e-6 and inclusive
//!   barycentric bounds (u >= 0, v >= 0, u + v <= 1), so points on a shared edge are produced by
//!   both triangles. The point is `ray origin + t` on the main axis and keeps the face normal.
//! - **Duplicates.** mmetric's sampler merges points equal in position *and* normal; the pcc
//!   comparison (dropDuplicates = 2) then merges points equal in position, giving them the
//!   plain mean of their normals (not renormalized). [`sample_grid`] does both, by sorting.
//! - **Distances** (`neighborsProc = 1`, `bAverageNormals = 1`,
//!   `normalCalcModificationEnable = 1`, threshold for "same distance" 1e-20). For each point of
//!   A: D1 term = squared distance to its nearest point of B; D2 term = mean, over the nearest
//!   points of B whose squared distances chain within 1e-20 of each other (at most 30), of the
//!   squared projection of (a - b) on that b's own normal. Each direction's MSE is the mean over
//!   the points of A; the result keeps the larger of A->B and B->A for D1 and D2 separately.
//!   pc_error asks its kd-tree for 10 neighbours (growing by 5, up to 30, while all are tied);
//!   here a nearest-point query plus a search within the tie radius yields the same tie set, and
//!   since D1 uses only the distance and D2 averages over the whole tie set, the order of equal
//!   neighbours (unspecified in nanoflann) does not matter.
//! - **Colour samples** (`sample --bilinear`, then `compare`'s conversion to pc_error's cloud).
//!   The UV at a sample is interpolated from the rotated triangle's corners with the ray test's
//!   weights, and the texture read bilinearly, both in `f32` as mmetric computes them. The
//!   sampler's duplicate test includes the unrounded colour, so samples equal in position and
//!   normal but not in colour are all kept. Each kept sample is then rounded to 8 bits per
//!   channel (`roundf`), and pc_error's merge of equal positions (dropDuplicates = 2) gives a
//!   point the integer mean of its samples' rounded colours, *truncated*.
//! - **Colour distances** (`mseSpace = 1`, `neighborsProc = 1`). The colour a point of A is
//!   compared with is the mean of the 8-bit colours of the same tie set in B, rounded to 8 bits
//!   (half away from zero); each tie counts once (pc_error weighs ties by their merged-sample
//!   count only with `neighborsProc = 2`). Both colours go to YCbCr [0, 1] with pc_error's
//!   BT.709 matrix (coefficients to four decimals, stored in `f32`); the squared difference per
//!   channel (in `f32`), mean over the points of A, the larger direction per channel, PSNR
//!   `10 log10(1 / mse)`.
//!
//! Checked against: basketball_player frame 12 against frame 11 (grid over frame 11's box, grid
//! size 1024, peak 18.73565) gives D1 70.790 dB and D2 71.908 dB, mmetric's figures to 1e-3 dB.
//! Sources read: MPEGGroup/mpeg-pcc-mmetric (`mmSample.cpp`, `mmModel.h`, `mmCompare.cpp`,
//! `mmCmdCompare.h`, `mmGeometry.cpp`) and the dmetric `pcc_distortion.cpp` it depends on
//! (with `normalCalcModificationEnable`), as the V-DMC test model's `VMCMetrics` calls them.
//!
//! # Choices where mmetric's behaviour could not be mirrored exactly
//! - The order of floating-point sums differs (mmetric averages duplicate normals in insertion
//!   order and sums errors in OpenMP thread order): differences are at the last-bit level. Our
//!   sums are in a fixed order, so results are identical run to run and thread count to thread
//!   count.
//! - Distances are computed in `f64` from the `f32` sample coordinates; `pc_error` subtracts
//!   coordinates in `f32` before squaring in `f64` (relative difference ~1e-7 per term).
//! - mmetric skips a ray axis when the *reference box* is flat along one of the two other axes.
//!   [`SamplingGrid`] keeps no box extent, so that rule is not applied; it can only matter for a
//!   reference whose bounding box has zero thickness.
//! - mmetric's own fallback when no box is given (cubic box of the mesh itself) is not offered:
//!   the caller always passes the reference box.
//! - Normals of textured comparisons (the one deviation in what is computed; colour is mirrored
//!   step for step, checked against the sources, not against mmetric runs). mmetric's sampler
//!   keeps samples that differ only in colour, and pc_error averages the normals of all of them
//!   too. [`sample_grid_coloured`] keeps the normals of [`sample_grid`] (distinct (position,
//!   normal) only), so that a textured comparison's D1/D2 are exactly the geometric ones. The
//!   normals, and so D2, can differ from mmetric's only at a point hit by faces of two or more
//!   different normals where faces of one normal disagree in colour (a texture seam on a
//!   crease); colour figures do not use normals and are not affected.
//! - Like mmetric, the number of rays per triangle grows with the triangle's extent in grid
//!   steps: a wildly misplaced vertex in a decoded mesh makes sampling slow, not wrong.
use rayon::prelude::*;

use crate::geom::mesh::{dot, sub};
use crate::eval::sampling::{sample_grid, sample_grid_coloured, PointCloud, SamplingGrid};
use crate::eval::sampling::CHUNK;
use crate::texture::{Texture, UvMesh};

/// Squared distances closer than this (chained) count as "the same distance" in D2.
const SAME_DISTANCE: f64 = 1e-20;
/// At most this many equidistant nearest neighbours enter one D2 term (pc_error's limit).
const MAX_NEIGHBOURS: usize = 30;

/// Squared-error means of one comparison: D1 point-to-point, D2 point-to-plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Distortion {
    pub d1_mse: f64,
    pub d2_mse: f64,
}

/// Symmetric D1/D2 distortion between two sampled clouds: for each of D1 and D2 the larger of
/// the mean errors `reference -> decoded` (normals of `decoded`) and `decoded -> reference`
/// (normals of `reference`). Both empty: zero. Exactly one empty: infinite. A point without a
/// normal (`normals` shorter than `points`) contributes its point-to-point error to D2.
/// Deterministic and independent of thread count.
pub fn distortion(reference: &PointCloud, decoded: &PointCloud) -> Distortion {
    let (ab, ba) = rayon::join(|| one_way(reference, decoded), || one_way(decoded, reference));
    Distortion { d1_mse: ab.d1_mse.max(ba.d1_mse), d2_mse: ab.d2_mse.max(ba.d2_mse) }
}

type Tree = kiddo::ImmutableKdTree<f64, 3>;

/// Mean errors from the points of `a` to their nearest points of `b`, with `b`'s normals.
fn one_way(a: &PointCloud, b: &PointCloud) -> Distortion {
    let [d1_mse, d2_mse] = one_way_terms(a, b, |tree, q| {
        let (e1, e2) = point_errors(tree, b, a.points[q]);
        [e1, e2]
    });
    Distortion { d1_mse, d2_mse }
}

/// Mean over the points `q` of `a` of `term(tree of b, q)`: zero if `a` is empty, infinite if
/// only `b` is.
fn one_way_terms<const N: usize>(
    a: &PointCloud,
    b: &PointCloud,
    term: impl Fn(&Tree, usize) -> [f64; N] + Sync,
) -> [f64; N] {
    if a.points.is_empty() {
        return [0.0; N];
    }
    if b.points.is_empty() {
        return [f64::INFINITY; N];
    }
    let tree = Tree::new_from_slice(&b.points);
    mean_terms(a.points.len(), |q| term(&tree, q))
}

/// Mean of `term(i)` over `i` in `0..count`, summed per channel chunk by chunk and then chunk
/// after chunk, so the result does not depend on how rayon schedules the chunks.
fn mean_terms<const N: usize>(count: usize, term: impl Fn(usize) -> [f64; N] + Sync) -> [f64; N] {
    let starts: Vec<usize> = (0..count).step_by(CHUNK).collect();
    let partial: Vec<[f64; N]> = starts
        .par_iter()
        .map(|&start| (start..count.min(start + CHUNK)).fold([0.0; N], |s, i| add_n(s, term(i))))
        .collect();
    let sum = partial.into_iter().fold([0.0; N], add_n);
    sum.map(|s| s / count as f64)
}

fn add_n<const N: usize>(a: [f64; N], b: [f64; N]) -> [f64; N] {
    std::array::from_fn(|k| a[k] + b[k])
}

/// (D1, D2) terms of one query point `q` against the cloud `b` indexed by `tree`.
fn point_errors(tree: &Tree, b: &PointCloud, q: [f64; 3]) -> (f64, f64) {
    let mut d2 = 0.0;
    let (d1, count) = visit_nearest(tree, q, |i| d2 += plane_error(b, q, i));
    (d1, d2 / count.max(1) as f64)
}

/// Calls `visit(index)` for each point of pc_error's tie set of `q` in the cloud indexed by
/// `tree`: the nearest points whose squared distances chain within [`SAME_DISTANCE`] of each
/// other, at most [`MAX_NEIGHBOURS`], nearest first (equal distances by index). Returns the
/// squared distance to the nearest point and the number of points visited.
fn visit_nearest(tree: &Tree, q: [f64; 3], mut visit: impl FnMut(usize)) -> (f64, usize) {
    use kiddo::SquaredEuclidean;
    let nearest = tree.nearest_one::<SquaredEuclidean>(&q);
    let radius = nearest.distance + SAME_DISTANCE * MAX_NEIGHBOURS as f64;
    let mut ties = tree.within_unsorted::<SquaredEuclidean>(&q, radius);
    if ties.len() <= 1 {
        visit(nearest.item as usize);
        return (nearest.distance, 1);
    }
    ties.sort_unstable_by(|x, y| x.distance.total_cmp(&y.distance).then(x.item.cmp(&y.item)));
    let mut previous = nearest.distance;
    let mut count = 0usize;
    for nb in ties.iter().take(MAX_NEIGHBOURS) {
        if nb.distance - previous >= SAME_DISTANCE {
            break;
        }
        previous = nb.distance;
        visit(nb.item as usize);
        count += 1;
    }
    (nearest.distance, count)
}

/// Squared projection of `q - b.points[index]` on that point's normal (point-to-point error if
/// it has no normal, 0 if the index is out of range).
fn plane_error(b: &PointCloud, q: [f64; 3], index: usize) -> f64 {
    let Some(&p) = b.points.get(index) else { return 0.0 };
    let err = sub(q, p);
    b.normals.get(index).map_or(dot(err, err), |&n| dot(err, n).powi(2))
}

/// Geometry PSNR in dB: `10 log10(3 peak^2 / mse)`. `mse == 0` gives `f64::INFINITY` (identical
/// geometry); an infinite `mse` gives negative infinity.
pub fn psnr(mse: f64, peak: f64) -> f64 {
    10.0 * (3.0 * peak * peak / mse).log10()
}

/// D1 and D2 PSNR of the mesh `(dec_pos, dec_faces)` against the reference
/// `(ref_pos, ref_faces)`, both sampled on `grid` (normally
/// [`SamplingGrid::over_box`] of the reference bounding box with grid size 1024), with the
/// given peak (the test conditions use the largest side of the source sequence's box).
/// Returns `(d1_psnr, d2_psnr)`; infinite when the sampled geometry is identical.
pub fn mesh_psnr(
    ref_pos: &[[f64; 3]],
    ref_faces: &[[u32; 3]],
    dec_pos: &[[f64; 3]],
    dec_faces: &[[u32; 3]],
    grid: &SamplingGrid,
    peak: f64,
) -> (f64, f64) {
    let (reference, decoded) = rayon::join(
        || sample_grid(ref_pos, ref_faces, grid),
        || sample_grid(dec_pos, dec_faces, grid),
    );
    let d = distortion(&reference, &decoded);
    (psnr(d.d1_mse, peak), psnr(d.d2_mse, peak))
}

/// A sampled cloud with one 8-bit RGB colour per point, as [`sample_grid_coloured`] returns it.
pub type ColouredCloud<'a> = (&'a PointCloud, &'a [[u8; 3]]);

/// Symmetric colour distortion between two coloured clouds, per channel Y, Cb, Cr in [0, 1]
/// (`ycbcr_pcc`), as pc_error computes it (`neighborsProc = 1`, `mseSpace = 1`): for each
/// point of one cloud, the nearest points of the other (the same equidistant set [`distortion`]
/// uses for D2), the mean of their colours rounded to 8 bits (half away from zero), and the
/// squared difference of the two colours' YCbCr; the mean over the points; per channel the
/// larger of the two directions. Both empty: zero; exactly one empty: infinite. Panics if a
/// cloud does not have exactly one colour per point. Deterministic and independent of thread
/// count.
pub fn colour_mse(reference: ColouredCloud<'_>, decoded: ColouredCloud<'_>) -> [f64; 3] {
    let [_, _, y, cb, cr] = textured_distortion_terms(reference, decoded);
    [y, cb, cr]
}

/// pc_error's RGB to YCbCr (`convertRGBtoYUV`, type 1), which the colour PSNR of the test
/// conditions is computed in: BT.709 with its coefficients rounded to four decimals, evaluated in
/// `f64` and stored in `f32`. (The codec's own [`crate::texture::ycbcr709`] uses the exact
/// coefficients; this one serves only to measure as mmetric does.)
fn ycbcr_pcc(rgb: [u8; 3]) -> [f32; 3] {
    let [r, g, b] = rgb.map(f64::from);
    [
        ((0.2126 * r + 0.7152 * g + 0.0722 * b) / 255.0) as f32,
        ((-0.1146 * r - 0.3854 * g + 0.5000 * b) / 255.0 + 0.5) as f32,
        ((0.5000 * r - 0.4542 * g - 0.0458 * b) / 255.0 + 0.5) as f32,
    ]
}

/// Squared YCbCr differences of two 8-bit colours per channel, in `f32` as pc_error forms them.
fn colour_errors(a: [u8; 3], b: [u8; 3]) -> [f64; 3] {
    let (ya, yb) = (ycbcr_pcc(a), ycbcr_pcc(b));
    std::array::from_fn(|k| f64::from((ya[k] - yb[k]) * (ya[k] - yb[k])))
}

/// Geometry and colour distortion of one comparison.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TexturedDistortion {
    /// As [`distortion`] gives it.
    pub geometry: Distortion,
    /// Y, Cb, Cr as [`colour_mse`] gives them.
    pub colour_mse: [f64; 3],
}

/// [`distortion`] and [`colour_mse`] of two coloured clouds in one pass of nearest-neighbour
/// queries (identical results to calling both).
pub fn textured_distortion(
    reference: ColouredCloud<'_>,
    decoded: ColouredCloud<'_>,
) -> TexturedDistortion {
    let [d1_mse, d2_mse, y, cb, cr] = textured_distortion_terms(reference, decoded);
    TexturedDistortion { geometry: Distortion { d1_mse, d2_mse }, colour_mse: [y, cb, cr] }
}

/// Symmetric [D1, D2, Y, Cb, Cr] mean errors: per term the larger direction.
fn textured_distortion_terms(a: ColouredCloud<'_>, b: ColouredCloud<'_>) -> [f64; 5] {
    for (cloud, colours) in [a, b] {
        assert_eq!(
            cloud.points.len(),
            colours.len(),
            "a coloured cloud needs one colour per point"
        );
    }
    let (ab, ba) = rayon::join(|| textured_one_way(a, b), || textured_one_way(b, a));
    std::array::from_fn(|k| ab[k].max(ba[k]))
}

/// Mean [D1, D2, Y, Cb, Cr] errors from the points of `a` to their nearest points of `b`.
fn textured_one_way((a, ac): ColouredCloud<'_>, (b, bc): ColouredCloud<'_>) -> [f64; 5] {
    one_way_terms(a, b, |tree, i| {
        let q = a.points[i];
        let (mut d2, mut sum) = (0.0, [0u32; 3]);
        let (d1, count) = visit_nearest(tree, q, |j| {
            d2 += plane_error(b, q, j);
            sum = std::array::from_fn(|k| sum[k] + u32::from(bc[j][k]));
        });
        let n = count.max(1) as f64;
        let mean = sum.map(|v| (f64::from(v) / n).round() as u8);
        let [y, cb, cr] = colour_errors(ac[i], mean);
        [d1, d2 / n, y, cb, cr]
    })
}

/// Colour PSNR in dB per channel with peak 1, as the test conditions measure YCbCr in [0, 1]:
/// `10 log10(1 / mse)` (no factor 3, unlike the geometric [`psnr`]). `mse == 0` gives
/// `f64::INFINITY`, an infinite `mse` negative infinity.
pub fn colour_psnr(mse: [f64; 3]) -> [f64; 3] {
    mse.map(|m| 10.0 * (1.0 / m).log10())
}

/// Geometry and colour distortion of the textured mesh `decoded` against `reference`, both
/// sampled on `grid` with [`sample_grid_coloured`] (see [`mesh_psnr`] for the grid).
pub fn textured_mse(
    reference: &UvMesh,
    ref_tex: &Texture,
    decoded: &UvMesh,
    dec_tex: &Texture,
    grid: &SamplingGrid,
) -> TexturedDistortion {
    let ((rc, rcol), (dc, dcol)) = rayon::join(
        || sample_grid_coloured(reference, ref_tex, grid),
        || sample_grid_coloured(decoded, dec_tex, grid),
    );
    textured_distortion((&rc, &rcol), (&dc, &dcol))
}

/// PSNRs of one textured comparison, in dB (infinite for identical samples).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TexturedPsnr {
    /// Geometry, as [`mesh_psnr`] gives them (peak as passed).
    pub d1: f64,
    pub d2: f64,
    /// Colour channels, peak 1 ([`colour_psnr`]).
    pub y: f64,
    pub cb: f64,
    pub cr: f64,
}

/// D1, D2 and Y, Cb, Cr PSNR of the textured mesh `decoded` against `reference`, sampled on
/// [`SamplingGrid::over_box`]`(box_min, box_max, grid_size)` (normally the reference box and
/// 1024) with geometry peak `peak` (the largest side of the source sequence's box): the figures
/// of the common test conditions, mirroring [`mesh_psnr`].
#[allow(clippy::too_many_arguments)]
pub fn textured_psnr(
    reference: &UvMesh,
    ref_tex: &Texture,
    decoded: &UvMesh,
    dec_tex: &Texture,
    box_min: [f64; 3],
    box_max: [f64; 3],
    peak: f64,
    grid_size: u32,
) -> TexturedPsnr {
    let grid = SamplingGrid::over_box(box_min, box_max, grid_size);
    let d = textured_mse(reference, ref_tex, decoded, dec_tex, &grid);
    let [y, cb, cr] = colour_psnr(d.colour_mse);
    TexturedPsnr { d1: psnr(d.geometry.d1_mse, peak), d2: psnr(d.geometry.d2_mse, peak), y, cb, cr }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::sampling::bilinear_f32;
    use crate::eval::sampling::tests::{square, square_grid};

    type Mesh = (Vec<[f64; 3]>, Vec<[u32; 3]>);

    /// `n` x `n` quads over the unit square, z = 0.1 sin(2 pi (x + y) + phase).
    fn height_field(n: u32, phase: f64) -> Mesh {
        let z = |x: f64, y: f64| 0.1 * (std::f64::consts::TAU * (x + y) + phase).sin();
        let s = 1.0 / n as f64;
        let p = (0..=n).flat_map(|j| (0..=n).map(move |i| (i as f64 * s, j as f64 * s)));
        let p = p.map(|(x, y)| [x, y, z(x, y)]).collect();
        let at = |i: u32, j: u32| j * (n + 1) + i;
        let quads = (0..n).flat_map(|j| (0..n).map(move |i| (i, j)));
        let f = quads.flat_map(|(i, j)| {
            [[at(i, j), at(i + 1, j), at(i, j + 1)], [at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]]
        });
        (p, f.collect())
    }

    #[test]
    fn identical_meshes_have_zero_error() {
        let p = vec![[0.0, 0.0, 0.0], [1.0, 0.1, 0.2], [0.3, 1.0, 0.1], [0.4, 0.3, 0.9]];
        let f = vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]];
        let grid = SamplingGrid::over_box([0.0; 3], [1.0, 1.0, 0.9], 64);
        let cloud = sample_grid(&p, &f, &grid);
        assert!(cloud.points.len() > 100);
        let d = distortion(&cloud, &cloud);
        assert_eq!(d, Distortion { d1_mse: 0.0, d2_mse: 0.0 });
        assert_eq!(mesh_psnr(&p, &f, &p, &f, &grid, 1.0), (f64::INFINITY, f64::INFINITY));
    }

    #[test]
    fn offset_along_the_normal_gives_its_square() {
        let (p, f) = square(0.0);
        let d = 1.0 / 128.0;
        let (q, _) = square(d);
        let grid = square_grid();
        let dist = distortion(&sample_grid(&p, &f, &grid), &sample_grid(&q, &f, &grid));
        assert_eq!(dist, Distortion { d1_mse: d * d, d2_mse: d * d });
        let expected = 10.0 * (3.0 / (d * d)).log10();
        let (d1, d2) = mesh_psnr(&p, &f, &q, &f, &grid, 1.0);
        assert!((d1 - expected).abs() < 1e-9 && (d2 - expected).abs() < 1e-9);
    }

    #[test]
    fn offset_in_the_plane_counts_for_d1_only() {
        let (p, f) = square(0.0);
        let s = square_grid().step;
        let reference = sample_grid(&p, &f, &square_grid());
        let mut shifted = reference.clone();
        shifted.points.iter_mut().for_each(|q| q[0] += 0.25 * s);
        let d = distortion(&reference, &shifted);
        assert!((d.d1_mse - (0.25 * s).powi(2)).abs() < 1e-12, "{d:?}");
        assert!(d.d2_mse.abs() < 1e-20, "{d:?}");
    }

    #[test]
    fn symmetric_result_keeps_the_larger_direction() {
        let (p, f) = square(0.0);
        let (mut q, mut g) = square(1.0);
        q.extend_from_slice(&p);
        g.extend(f.iter().map(|t| t.map(|v| v + 4)));
        let grid = square_grid();
        let a = sample_grid(&p, &f, &grid);
        let b = sample_grid(&q, &g, &grid);
        assert_eq!(b.points.len(), 200);
        assert_eq!(one_way(&a, &b), Distortion { d1_mse: 0.0, d2_mse: 0.0 });
        // Half of B lies 1 above A (up to f32 rounding of the ray parameter).
        let d = distortion(&a, &b);
        assert!((d.d1_mse - 0.5).abs() < 1e-6 && (d.d2_mse - 0.5).abs() < 1e-6, "{d:?}");
        assert_eq!(d, distortion(&b, &a));
        assert_eq!(d, one_way(&b, &a));
    }

    #[test]
    fn results_do_not_depend_on_thread_count() {
        // More triangles and points than one rayon task takes.
        let (p, f) = height_field(40, 0.0);
        let (q, _) = height_field(40, 0.3);
        let grid = SamplingGrid::over_box([0.0, 0.0, -0.1], [1.0, 1.0, 0.1], 128);
        let run = |threads| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
            pool.install(|| {
                let (a, b) = (sample_grid(&p, &f, &grid), sample_grid(&q, &f, &grid));
                (distortion(&a, &b), a)
            })
        };
        let (d1, a1) = run(1);
        let (d3, a3) = run(3);
        assert_eq!(a1, a3);
        assert_eq!(d1.d1_mse.to_bits(), d3.d1_mse.to_bits());
        assert_eq!(d1.d2_mse.to_bits(), d3.d2_mse.to_bits());
        assert!(d1.d1_mse > 0.0 && d1.d2_mse > 0.0);
    }

    #[test]
    fn degenerate_inputs_do_not_panic() {
        let (p, _) = square(0.0);
        let bad = vec![[0, 1, 9], [0, 0, 1]];
        assert!(sample_grid(&p, &bad, &square_grid()).points.is_empty());
        let zero = SamplingGrid { origin: [0.0; 3], step: 0.0 };
        assert!(sample_grid(&p, &[[0, 1, 3]], &zero).points.is_empty());
        let empty = PointCloud::default();
        assert_eq!(distortion(&empty, &empty), Distortion { d1_mse: 0.0, d2_mse: 0.0 });
        let one = PointCloud { points: vec![[0.0; 3]], normals: vec![] };
        assert_eq!(distortion(&one, &empty).d1_mse, f64::INFINITY);
        // Many coincident points (all tied) and a point without a normal.
        let pile =
            PointCloud { points: vec![[1.0, 2.0, 2.0]; 100], normals: vec![[0.0, 0.0, 1.0]; 100] };
        assert_eq!(distortion(&one, &pile), Distortion { d1_mse: 9.0, d2_mse: 9.0 });
        assert_eq!(one_way(&one, &pile), Distortion { d1_mse: 9.0, d2_mse: 4.0 });
        assert_eq!(psnr(0.0, 1.0), f64::INFINITY);
        assert!((psnr(3.0, 1.0) - 0.0).abs() < 1e-12);
    }

    // ---- colour ----

    use crate::geom::mesh::Mesh as IndexedMesh;

    /// The unit square of [`square`] with its own UV list, UV = (x, y), stored in another order
    /// than the positions so that per-corner UV indexing matters.
    fn textured_square(z: f64) -> UvMesh {
        let (p, f) = square(z);
        let uv = vec![[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];
        UvMesh { mesh: IndexedMesh::new(p, f), uv, uv_faces: vec![[3, 2, 0], [2, 1, 0]] }
    }

    /// 256 x 2 texture: red = column, green 0 on the top row and 200 on the bottom row, blue 50.
    fn gradient_texture() -> Texture {
        let rgb =
            (0..2).flat_map(|y| (0..256).map(move |x| [x as u8, if y == 0 { 0 } else { 200 }, 50]));
        Texture { width: 256, height: 2, rgb: rgb.collect() }
    }

    fn textured_height_field(n: u32, phase: f64) -> UvMesh {
        let (p, f) = height_field(n, phase);
        let uv = p.iter().map(|q| [q[0], q[1]]).collect();
        UvMesh { mesh: IndexedMesh::new(p, f.clone()), uv, uv_faces: f }
    }

    fn close3(a: [f64; 3], b: [f64; 3], rel: f64) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() <= rel * y.abs())
    }

    #[test]
    fn coloured_sampling_keeps_the_geometric_points() {
        let m = textured_height_field(40, 0.2);
        let grid = SamplingGrid::over_box([0.0, 0.0, -0.1], [1.0, 1.0, 0.1], 128);
        let (cloud, colours) = sample_grid_coloured(&m, &gradient_texture(), &grid);
        assert_eq!(cloud, sample_grid(&m.mesh.positions, &m.mesh.faces, &grid));
        assert_eq!(colours.len(), cloud.points.len());
    }

    #[test]
    fn gradient_colours_land_where_expected_rounded() {
        let m = textured_square(0.0);
        let (cloud, colours) = sample_grid_coloured(&m, &gradient_texture(), &square_grid());
        assert_eq!(cloud.points.len(), 100);
        for (q, c) in cloud.points.iter().zip(&colours) {
            // Texel centres at u = (x + 0.5) / 256 hold red = x; rows at v = 0.75 (top, green 0)
            // and v = 0.25 (bottom, green 200); clamped beyond the outer centres. Each point has
            // one sample, so its colour is the nearest 8-bit value.
            let red = (q[0] * 256.0 - 0.5).clamp(0.0, 255.0);
            let green = 200.0 * ((1.0 - q[1]) * 2.0 - 0.5).clamp(0.0, 1.0);
            let near = |got: u8, want: f64| (f64::from(got) - want).abs() <= 0.5 + 1e-3;
            assert!(near(c[0], red) && near(c[1], green) && c[2] == 50, "at {q:?}: {c:?}");
        }
    }

    #[test]
    fn samples_are_rounded_to_8_bits_before_they_are_compared() {
        // Red rises from 0 to 1 across x in [1/4, 3/4] (a 2 x 1 texture, UV = (x, y)); the grid
        // columns at x = i * 0.1000061 read red 0, 0, 0, 0.1, 0.3, 0.5001, 0.7, 0.9, 1, 1. Rounded,
        // half the points are red 1 and half 0, so against black the error is half that of one
        // level; unrounded it would be the mean of the squared fractions (0.365 of it).
        let m = textured_square(0.0);
        let mut ramp = Texture::filled(2, 1, [0, 0, 0]);
        ramp.rgb[1] = [1, 0, 0];
        let d = textured_mse(&m, &ramp, &m, &Texture::filled(2, 1, [0, 0, 0]), &square_grid());
        let one_level = colour_errors([1, 0, 0], [0, 0, 0]);
        assert!(close3(d.colour_mse, one_level.map(|e| 0.5 * e), 1e-12), "{d:?}");
    }

    #[test]
    fn merged_seam_points_truncate_their_mean_colour() {
        // Two triangles meeting along x = 1/2 whose UVs point into a red and a blue half of the
        // texture: grid points on the shared edge get one sample of each colour, whose mean
        // (127.5) pc_error truncates.
        let p = vec![[0.0, 0.0, 0.0], [0.5, 0.0, 0.0], [0.5, 1.0, 0.0], [1.0, 0.0, 0.0]];
        let mesh = IndexedMesh::new(p, vec![[0, 1, 2], [1, 3, 2]]);
        let uv = vec![[0.1, 0.5], [0.2, 0.5], [0.9, 0.5]];
        let m = UvMesh { mesh, uv, uv_faces: vec![[0, 1, 0], [2, 2, 2]] };
        let mut t = Texture::filled(2, 1, [255, 0, 0]);
        t.rgb[1] = [0, 0, 255];
        let grid = SamplingGrid::over_box([0.0; 3], [1.0, 1.0, 0.0], 9); // step 1/8 exactly
        let (cloud, colours) = sample_grid_coloured(&m, &t, &grid);
        let mut seam = 0;
        for (q, c) in cloud.points.iter().zip(&colours) {
            let expected = match q[0] {
                x if x < 0.5 => [255, 0, 0],
                x if x > 0.5 => [0, 0, 255],
                _ => [127, 0, 127],
            };
            seam += usize::from(q[0] == 0.5);
            assert_eq!(*c, expected, "at {q:?}");
        }
        assert!(seam >= 5, "{seam} seam points");
    }

    #[test]
    fn equidistant_neighbours_average_to_a_rounded_colour() {
        // The point of `a` lies halfway between the two points of `b`: it is compared with their
        // mean (10.5, 20, 30) rounded half away from zero.
        let a = PointCloud { points: vec![[0.5, 0.0, 0.0]], normals: vec![[0.0, 0.0, 1.0]] };
        let b = PointCloud {
            points: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]],
            normals: vec![[0.0, 0.0, 1.0]; 2],
        };
        let bc = [[10, 20, 30], [11, 20, 30]];
        let terms = |colour: [u8; 3]| textured_one_way((&a, &[colour]), (&b, &bc));
        assert_eq!(terms([11, 20, 30])[2..], [0.0; 3]);
        let off = colour_errors([10, 20, 30], [11, 20, 30]);
        assert_eq!(terms([10, 20, 30])[2..], off);
        assert!(off.iter().all(|&e| e > 0.0));
    }

    #[test]
    fn ycbcr_is_pc_errors_four_decimal_bt709() {
        assert_eq!(ycbcr_pcc([255; 3]), [1.0, 0.5, 0.5]);
        assert_eq!(ycbcr_pcc([0; 3]), [0.0, 0.5, 0.5]);
        // Exact BT.709 gives Cb = 0.5 - 0.7152 / 1.8556 = 0.114572 for pure green.
        let [y, cb, cr] = ycbcr_pcc([0, 255, 0]);
        assert!((y - 0.7152).abs() < 1e-7 && (cb - 0.1146).abs() < 1e-7, "{y} {cb}");
        assert!((cr - 0.0458).abs() < 1e-7, "{cr}");
    }

    #[test]
    fn identical_textured_meshes_have_infinite_psnr() {
        let m = textured_height_field(20, 0.0);
        let t = gradient_texture();
        let grid = SamplingGrid::over_box([0.0, 0.0, -0.1], [1.0, 1.0, 0.1], 64);
        let (cloud, colours) = sample_grid_coloured(&m, &t, &grid);
        assert_eq!(colour_mse((&cloud, &colours), (&cloud, &colours)), [0.0; 3]);
        assert_eq!(colour_psnr([0.0; 3]), [f64::INFINITY; 3]);
        let p = textured_psnr(&m, &t, &m, &t, [0.0, 0.0, -0.1], [1.0, 1.0, 0.1], 1.0, 64);
        let inf = f64::INFINITY;
        assert_eq!(p, TexturedPsnr { d1: inf, d2: inf, y: inf, cb: inf, cr: inf });
    }

    #[test]
    fn constant_offset_in_one_channel_gives_its_ycbcr_square() {
        let m = textured_height_field(20, 0.0);
        let reference = gradient_texture();
        let k = 7u8;
        let mut decoded = reference.clone();
        decoded.rgb.iter_mut().for_each(|c| c[2] += k); // blue 50 -> 57, no clipping
        let grid = SamplingGrid::over_box([0.0, 0.0, -0.1], [1.0, 1.0, 0.1], 64);
        let d = textured_mse(&m, &reference, &m, &decoded, &grid);
        assert_eq!(d.geometry, Distortion { d1_mse: 0.0, d2_mse: 0.0 });
        // pc_error's blue coefficients times 7 levels; the f32 YCbCr values it subtracts leave
        // a relative error of a few 1e-5 in each square.
        let expected = [0.0722, 0.5, -0.0458].map(|c: f64| (c * k as f64 / 255.0).powi(2));
        assert!(close3(d.colour_mse, expected, 5e-4), "{d:?} vs {expected:?}");
        let p =
            textured_psnr(&m, &reference, &m, &decoded, [0.0, 0.0, -0.1], [1.0, 1.0, 0.1], 1.0, 64);
        assert_eq!([p.y, p.cb, p.cr], colour_psnr(d.colour_mse));
    }

    #[test]
    fn colour_figures_are_symmetric_and_thread_independent() {
        let a = textured_height_field(30, 0.0);
        let mut b = textured_height_field(24, 0.4);
        b.uv.iter_mut().for_each(|uv| uv[0] = 0.9 * uv[0] + 0.05);
        let (ta, mut tb) = (gradient_texture(), gradient_texture());
        tb.rgb.iter_mut().for_each(|c| c[1] = c[1].saturating_add(30));
        let (lo, hi) = ([0.0, 0.0, -0.1], [1.0, 1.0, 0.1]);
        let ab = textured_psnr(&a, &ta, &b, &tb, lo, hi, 1.0, 100);
        let ba = textured_psnr(&b, &tb, &a, &ta, lo, hi, 1.0, 100);
        assert_eq!(ab, ba);
        assert!(ab.y.is_finite() && ab.cb.is_finite() && ab.cr.is_finite() && ab.d1.is_finite());
        // Geometry figures are those of mesh_psnr, and the clouds' colour_mse matches.
        let grid = SamplingGrid::over_box(lo, hi, 100);
        let (pa, fa, pb, fb) = (&a.mesh.positions, &a.mesh.faces, &b.mesh.positions, &b.mesh.faces);
        assert_eq!((ab.d1, ab.d2), mesh_psnr(pa, fa, pb, fb, &grid, 1.0));
        let run = |threads| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
            pool.install(|| {
                let (ca, cola) = sample_grid_coloured(&a, &ta, &grid);
                let (cb, colb) = sample_grid_coloured(&b, &tb, &grid);
                colour_mse((&ca, &cola), (&cb, &colb))
            })
        };
        let one = run(1);
        assert_eq!(one.map(f64::to_bits), run(3).map(f64::to_bits));
        assert_eq!([ab.y, ab.cb, ab.cr], colour_psnr(one));
    }

    #[test]
    fn colour_edge_cases_do_not_panic() {
        let empty = PointCloud::default();
        let one = PointCloud { points: vec![[0.0; 3]], normals: vec![[0.0, 0.0, 1.0]] };
        let grey = [[128; 3]];
        assert_eq!(colour_mse((&empty, &[]), (&empty, &[])), [0.0; 3]);
        assert_eq!(colour_mse((&one, &grey), (&empty, &[])), [f64::INFINITY; 3]);
        assert_eq!(colour_psnr([f64::INFINITY; 3]), [f64::NEG_INFINITY; 3]);
        // A face without UVs reads texel (0, 0) (top left).
        let mut m = textured_square(0.0);
        m.uv_faces.pop();
        let (cloud, colours) = sample_grid_coloured(&m, &gradient_texture(), &square_grid());
        assert_eq!(cloud.points.len(), 100);
        let upper: Vec<_> =
            (0..100).filter(|&i| cloud.points[i][0] + cloud.points[i][1] > 1.01).collect();
        assert!(!upper.is_empty() && upper.iter().all(|&i| colours[i] == [0, 0, 50]));
        // UVs far outside [0, 1] clamp to the border texels.
        let t = gradient_texture();
        assert_eq!(bilinear_f32(&t, [-1e30, 2.0]), [0.0, 0.0, 50.0]);
        assert_eq!(bilinear_f32(&t, [1e30, -1e30]), [255.0, 200.0, 50.0]);
    }

    mod shared_data {
        use super::*;
        use crate::shared_data::read_obj;

        #[test]
        #[ignore = "needs ../shared/data"]
        fn matches_mmetric_on_basketball_player_frames_11_and_12() {
            let r = read_obj("basketball_player/basketball_player_fr0011.obj");
            let d = read_obj("basketball_player/basketball_player_fr0012.obj");
            let (lo, hi) = crate::geom::mesh::bounds(&r.positions).expect("a non-empty reference");
            let grid = SamplingGrid::over_box(lo, hi, 1024);
            let start = std::time::Instant::now();
            let (d1, d2) = mesh_psnr(&r.positions, &r.faces, &d.positions, &d.faces, &grid, 18.73565);
            let elapsed = start.elapsed();
            println!("basketball 11 vs 12: D1 {d1:.4} dB, D2 {d2:.4} dB in {elapsed:?}");
            assert!((d1 - 70.790).abs() < 0.01, "D1 {d1}");
            assert!((d2 - 71.908).abs() < 0.01, "D2 {d2}");
        }
    }
}
