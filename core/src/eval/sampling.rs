//! Meshes sampled into point clouds on a grid, as the MPEG tool mmetric samples them
//! (`sample --mode grid --useNormal --useFixedPoint`, with `--bilinear` for colour): the
//! first half of [`crate::eval::metrics`], whose module documentation lists what is mirrored
//! (the grid, the rasterization, duplicates, colour samples) and what is not.

use rayon::prelude::*;

use crate::error::Error;
use crate::texture::{Texture, UvMesh};

/// Fixed-point scale of the grid corner and step (16 fractional bits).
const FIXED_POINT: f32 = 65536.0;
/// Determinant tolerance of mmetric's ray/triangle test.
const RAY_EPSILON: f32 = 1e-6;
/// Triangles (sampling) and points (queries, in [`crate::eval::metrics`]) per rayon task.
pub(crate) const CHUNK: usize = 2048;

/// The sampling grid: lines at `origin + i * step` on every axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SamplingGrid {
    pub origin: [f64; 3],
    pub step: f64,
}

impl SamplingGrid {
    /// mmetric's grid over the box `[min, max]` of the reference mesh (or sequence):
    /// `min` rounded down and `max` rounded up to multiples of 1/65536, then
    /// step = largest side x (1 / (grid_size - 1)) rounded up to a multiple of 1/65536, all in
    /// `f32` as mmetric computes it. `grid_size` below 2 is treated as 2. A box of zero size
    /// whose corners are already multiples of 1/65536 gives step 0 (such a grid samples nothing).
    pub fn over_box(min: [f64; 3], max: [f64; 3], grid_size: u32) -> Self {
        let lo = min.map(|v| (v as f32 * FIXED_POINT).floor() / FIXED_POINT);
        let hi = max.map(|v| (v as f32 * FIXED_POINT).ceil() / FIXED_POINT);
        let range = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(hi[2] - lo[2]);
        let intervals = grid_size.max(2) - 1;
        let step = range * (1.0f32 / intervals as f32);
        let step = (step * FIXED_POINT).ceil() / FIXED_POINT;
        Self { origin: lo.map(f64::from), step: f64::from(step) }
    }
}

/// A sampled point cloud: `normals[i]` belongs to `points[i]`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PointCloud {
    pub points: Vec<[f64; 3]>,
    pub normals: Vec<[f64; 3]>,
}

/// One raw sample in mmetric's single precision: position then normal, each coordinate as
/// [`order_key`] so that comparing keys compares values (-0.0 equal to 0.0).
type SampleKey = [u32; 6];

/// Samples the triangle mesh `(positions, faces)` on `grid` as mmetric's grid mode does (see the
/// module documentation). Returns one point per distinct position, sorted by (x, y, z), with the
/// mean of the face normals of the distinct (position, normal) samples merged into it.
/// Faces with an out-of-range index or (near) zero area are skipped. A grid whose step is not a
/// positive finite number gives an empty cloud. Deterministic and independent of thread count.
pub fn sample_grid(positions: &[[f64; 3]], faces: &[[u32; 3]], grid: &SamplingGrid) -> PointCloud {
    merge_positions(&raw_samples(positions, faces, grid, Some(&first_copies(positions, faces)), |_, _, _| ()))
}

/// Which faces [`sample_grid`] rasterizes: all but those whose corners, in `f32` and rotated as
/// [`fetch_triangle`] rotates them, repeat an earlier face's. A repetition casts the same rays
/// and makes the same samples, which the deduplication merges, so leaving it out changes no
/// point; a mesh of a million copies of one large face would otherwise cast a million times
/// its rays. Faces with an index out of range are kept (they are skipped later).
fn first_copies(positions: &[[f64; 3]], faces: &[[u32; 3]]) -> Vec<bool> {
    let keys: Vec<Option<[u32; 9]>> = faces
        .par_iter()
        .map(|f| fetch_triangle(positions, f).map(|(t, _)| std::array::from_fn(|i| t[i / 3][i % 3].to_bits())))
        .collect();
    let mut order: Vec<u32> = (0..faces.len() as u32).collect();
    order.par_sort_unstable_by_key(|&f| (keys[f as usize], f));
    let mut keep = vec![true; faces.len()];
    for pair in order.windows(2) {
        let (a, b) = (&keys[pair[0] as usize], &keys[pair[1] as usize]);
        if a.is_some() && a == b {
            keep[pair[1] as usize] = false;
        }
    }
    keep
}

/// [`sample_grid`] of `mesh` (the same points and normals, in the same order) together with each
/// point's colour, 8-bit RGB, as mmetric hands it to pc_error: `texture` is read bilinearly at
/// the UV interpolated at each raw sample, both in mmetric's single precision
/// (`bilinear_f32`); raw samples equal in position, normal *and* (unrounded) colour count once
/// (mmetric's sampler keeps all three in its duplicate test); each remaining sample is rounded
/// to 8 bits per channel, and a point's colour is the mean of the rounded colours of the samples
/// merged into it, truncated (pc_error's integer mean). A face without a valid UV triangle
/// (missing, or an index out of range) reads texel (0, 0). Deterministic and independent of
/// thread count.
pub fn sample_grid_coloured(
    mesh: &UvMesh,
    texture: &Texture,
    grid: &SamplingGrid,
) -> (PointCloud, Vec<[u8; 3]>) {
    let samples = raw_samples(&mesh.mesh.positions, &mesh.mesh.faces, grid, None, |face, first, w| {
        let colour = match uv_at(mesh, face, first, w) {
            Some(uv) => bilinear_f32(texture, uv),
            None => texture.texel(0, 0).map(f32::from),
        };
        // Non-negative and finite, so equal bits are equal values (mmetric compares floats).
        colour.map(f32::to_bits)
    });
    let colours = position_runs(&samples).map(merged_colour).collect();
    (merge_positions(&samples), colours)
}

/// The sorted, deduplicated raw samples of `(positions, faces)` on `grid` (only of the faces
/// that `keep` marks, when given), each carrying `payload(face index, rotation, barycentric
/// weights)`: the weights are those of the corners of the triangle as [`fetch_triangle`]
/// rotated it (rotated left by `rotation`), in `f32` as the ray test gives them. Samples equal
/// in position, normal and payload count once.
fn raw_samples<C, F>(
    positions: &[[f64; 3]],
    faces: &[[u32; 3]],
    grid: &SamplingGrid,
    keep: Option<&[bool]>,
    payload: F,
) -> Vec<(SampleKey, C)>
where
    C: Ord + Send,
    F: Fn(usize, usize, [f32; 3]) -> C + Sync,
{
    let Some(g) = GridF32::new(grid) else {
        return Vec::new();
    };
    let mut samples: Vec<(SampleKey, C)> = faces
        .par_chunks(CHUNK)
        .enumerate()
        .flat_map_iter(|(c, chunk)| {
            let mut out = Vec::new();
            for (i, face) in chunk.iter().enumerate() {
                if keep.is_some_and(|k| !k[c * CHUNK + i]) {
                    continue;
                }
                if let Some((tri, first)) = fetch_triangle(positions, face) {
                    rasterize(tri, &g, |key, w| out.push((key, payload(c * CHUNK + i, first, w))));
                }
            }
            out
        })
        .collect();
    samples.par_sort_unstable();
    samples.dedup();
    samples
}

/// Texture coordinate at barycentric weights `w` of the corners of face `face` of `mesh` rotated
/// left by `first`, computed as mmetric does (`f32`, corner by corner in the rotated order, which
/// is the order its `reindex --sort oriented` leaves); `None` when the face has no valid UV
/// triangle.
fn uv_at(mesh: &UvMesh, face: usize, first: usize, w: [f32; 3]) -> Option<[f32; 2]> {
    let t = mesh.uv_faces.get(face)?;
    let mut uv = [[0.0f32; 2]; 3];
    for (k, corner) in uv.iter_mut().enumerate() {
        *corner = mesh.uv.get(t[(k + first) % 3] as usize)?.map(|c| c as f32);
    }
    Some(std::array::from_fn(|k| uv[0][k] * w[0] + uv[1][k] * w[1] + uv[2][k] * w[2]))
}

/// mmetric's bilinear texture lookup (`texture2D_bilinear`), in its single precision: the
/// sample's position in texels is `uv * size - 1/2` (v up, so rows count from the bottom), each
/// of the four texels is clamped to the image on its own, and the blend is `a (1 - t) + b t`,
/// first along rows, then between them. The precision matters: it decides on which side of a
/// half level a sample lies, and so how it rounds to 8 bits. Channels 0-255, not rounded. The
/// texture must not be empty (the bindings refuse one).
pub(crate) fn bilinear_f32(texture: &Texture, uv: [f32; 2]) -> [f32; 3] {
    let size = [texture.width, texture.height];
    let pos: [f32; 2] = std::array::from_fn(|k| uv[k] * size[k] as f32 - 0.5);
    // `as` saturates (NaN gives 0); a blend weight that is not finite (a UV too large for `f32`
    // texel arithmetic) takes the corner texel, so no NaN reaches the rounding.
    let corner = pos.map(|p| p.floor() as i64);
    let frac = pos.map(|p| Some(p - p.floor()).filter(|f| f.is_finite()).unwrap_or(0.0));
    let texel = |dx: i64, dy: i64| {
        let x = corner[0].saturating_add(dx).clamp(0, size[0] as i64 - 1) as usize;
        let y = corner[1].saturating_add(dy).clamp(0, size[1] as i64 - 1) as usize;
        texture.texel(x, size[1] - 1 - y).map(f32::from)
    };
    let mix = |a: [f32; 3], b: [f32; 3], t: f32| -> [f32; 3] {
        std::array::from_fn(|k| a[k] * (1.0 - t) + b[k] * t)
    };
    let low = mix(texel(0, 0), texel(1, 0), frac[0]);
    let high = mix(texel(0, 1), texel(1, 1), frac[0]);
    mix(low, high, frac[1])
}

/// Runs of sorted samples sharing one position: one run per point of the merged cloud.
fn position_runs<C>(samples: &[(SampleKey, C)]) -> impl Iterator<Item = &[(SampleKey, C)]> {
    samples.chunk_by(|a, b| a.0[..3] == b.0[..3])
}

/// The colour of one merged point, as pc_error forms it: each sample's `f32` colour (stored as
/// bits) rounded to 8 bits (half away from zero, as `std::roundf`), then the integer mean of
/// those, truncated.
fn merged_colour(run: &[(SampleKey, [u32; 3])]) -> [u8; 3] {
    let sum = run.iter().fold([0u32; 3], |s, (_, c)| {
        std::array::from_fn(|k| s[k] + u32::from(f32::from_bits(c[k]).round() as u8))
    });
    sum.map(|v| (v / run.len() as u32) as u8)
}

/// Grid origin and step in the single precision mmetric computes with.
struct GridF32 {
    origin: [f32; 3],
    step: f32,
}

impl GridF32 {
    fn new(grid: &SamplingGrid) -> Option<Self> {
        let step = grid.step as f32;
        let origin = grid.origin.map(|v| v as f32);
        let ok = step.is_finite() && step > 0.0 && origin.iter().all(|v| v.is_finite());
        ok.then_some(Self { origin, step })
    }
}

/// The triangle's corners in `f32`, rotated left so that the lexicographically smallest comes
/// first (orientation kept), and the rotation; `None` if an index is out of range.
fn fetch_triangle(positions: &[[f64; 3]], face: &[u32; 3]) -> Option<([[f32; 3]; 3], usize)> {
    let mut tri = [[0.0f32; 3]; 3];
    for (corner, &v) in tri.iter_mut().zip(face) {
        *corner = positions.get(v as usize)?.map(|c| c as f32);
    }
    let first = (1..3).fold(0, |m, i| if cmp_f32s(&tri[i], &tri[m]).is_lt() { i } else { m });
    tri.rotate_left(first);
    Some((tri, first))
}

/// Calls `hit(sample, weights)` for each grid sample of one triangle: the sample's position and
/// face normal as a key, and the barycentric weights of `tri`'s corners at it.
fn rasterize(tri: [[f32; 3]; 3], g: &GridF32, mut hit: impl FnMut(SampleKey, [f32; 3])) {
    let Some(nrm) = face_normal(tri) else { return };
    let [nx, ny, nz] = nrm.map(order_key);
    let (main, second, third) = ray_axes(nrm);
    let lo: [f32; 3] = std::array::from_fn(|k| ((min3(tri, k) - g.origin[k]) / g.step).floor());
    let hi: [f32; 3] = std::array::from_fn(|k| ((max3(tri, k) - g.origin[k]) / g.step).ceil());
    let mut origin = [0.0f32; 3];
    origin[main] = g.origin[main] + lo[main] * g.step;
    let mut dir = [0.0f32; 3];
    dir[main] = 1.0;
    for i in 0..line_count(lo[second], hi[second]) {
        origin[second] = g.origin[second] + (lo[second] + i as f32) * g.step;
        for j in 0..line_count(lo[third], hi[third]) {
            origin[third] = g.origin[third] + (lo[third] + j as f32) * g.step;
            if let Some([t, u, v]) = ray_hit(origin, dir, tri) {
                let [x, y, z] = std::array::from_fn(|k| order_key(origin[k] + dir[k] * t));
                hit([x, y, z, nx, ny, nz], [1.0 - u - v, u, v]);
            }
        }
    }
}

/// Most rays a metric may cast on one mesh: each can make a sample of about 32 bytes, and
/// both meshes are sampled at once, so this keeps a comparison to a few gigabytes. The
/// default grid (1024) casts a few million on a captured frame.
pub const MAX_SAMPLE_RAYS: u64 = 1 << 25;

/// Refuses a comparison of `reference` and `decoded` (positions, faces) whose sampling on
/// `grid` would be empty on either side (nothing to measure) or cast more than
/// [`MAX_SAMPLE_RAYS`], before any sample is made; `coloured` counts the rays of
/// [`sample_grid_coloured`]. Errors: [`Error::Input`] naming the side and why.
pub fn check_sampling(reference: MeshRef, decoded: MeshRef, grid: &SamplingGrid, coloured: bool) -> Result<(), Error> {
    let count = if coloured { ray_count_coloured } else { ray_count };
    for (what, (positions, faces)) in [("reference", reference), ("decoded", decoded)] {
        let rays = count(positions, faces, grid);
        if rays == 0 {
            return Err(Error::Input(format!(
                "the {what} mesh has no surface to sample (all {} faces are degenerate or empty)",
                faces.len()
            )));
        }
        if rays > MAX_SAMPLE_RAYS {
            return Err(Error::Input(format!(
                "sampling the {what} mesh would cast {rays} rays, beyond the limit of {MAX_SAMPLE_RAYS}; \
                 use a smaller grid size"
            )));
        }
    }
    Ok(())
}

/// Refuses error figures that are not finite: one side sampled to no points, so there is no
/// measurement (identical geometry gives an MSE of 0, a PSNR of infinity, which stays).
/// Errors: [`Error::Input`].
pub fn check_measured(mse: &[f64]) -> Result<(), Error> {
    if mse.iter().all(|m| m.is_finite()) {
        return Ok(());
    }
    Err(Error::Input("no distortion can be measured: one of the meshes gives no sample on the grid".into()))
}

/// A mesh as [`check_sampling`] takes it: positions and faces.
pub type MeshRef<'a> = (&'a [[f64; 3]], &'a [[u32; 3]]);

/// Rays that [`sample_grid`] casts for `(positions, faces)` on `grid`, counted without casting
/// them (each makes at most one raw sample): what sampling will cost in time and memory.
pub fn ray_count(positions: &[[f64; 3]], faces: &[[u32; 3]], grid: &SamplingGrid) -> u64 {
    let keep = first_copies(positions, faces);
    let kept: Vec<[u32; 3]> = faces.iter().zip(&keep).filter(|(_, &k)| k).map(|(f, _)| *f).collect();
    ray_count_coloured(positions, &kept, grid)
}

/// Rays that [`sample_grid_coloured`] casts for a mesh of these `positions` and `faces` on `grid`:
/// one set for every face, repetitions included (their colours may differ).
pub fn ray_count_coloured(positions: &[[f64; 3]], faces: &[[u32; 3]], grid: &SamplingGrid) -> u64 {
    let Some(g) = GridF32::new(grid) else { return 0 };
    let rays = |face: &[u32; 3]| {
        let Some((tri, _)) = fetch_triangle(positions, face) else { return 0 };
        let Some(nrm) = face_normal(tri) else { return 0 };
        let (_, second, third) = ray_axes(nrm);
        let lines = |k: usize| {
            line_count(((min3(tri, k) - g.origin[k]) / g.step).floor(), ((max3(tri, k) - g.origin[k]) / g.step).ceil())
        };
        lines(second).saturating_mul(lines(third))
    };
    faces.par_iter().map(rays).reduce(|| 0, u64::saturating_add)
}

/// Unit normal `normalize(cross(b - a, c - a))` in `f32`, or `None` for a triangle whose area
/// is below `f64::EPSILON` (mmetric's degeneracy test).
fn face_normal([a, b, c]: [[f32; 3]; 3]) -> Option<[f32; 3]> {
    let n = cross32(sub32(b, a), sub32(c, a));
    let len = dot32(n, n).sqrt();
    if 0.5 * f64::from(len) < f64::EPSILON {
        return None;
    }
    Some(scale32(n, 1.0 / len))
}

/// (ray axis, first grid axis, second grid axis): rays run along the axis of the largest
/// |normal| component, ties going to x, then y (mmetric's order).
fn ray_axes(n: [f32; 3]) -> (usize, usize, usize) {
    let [x, y, z] = n.map(f32::abs);
    if x >= y && x >= z {
        (0, 1, 2)
    } else if y >= x && y >= z {
        (1, 0, 2)
    } else {
        (2, 0, 1)
    }
}

/// Number of grid lines from `lo` to `hi` inclusive (0 if the range is not finite).
fn line_count(lo: f32, hi: f32) -> u64 {
    let span = hi - lo;
    if span.is_finite() && span >= 0.0 {
        (span as u64).saturating_add(1)
    } else {
        0
    }
}

/// Moller-Trumbore in `f32` with mmetric's tolerance and inclusive bounds: the ray parameter
/// of the hit and the barycentric weights `(u, v)` of `v1` and `v2` there, or `None`.
fn ray_hit(origin: [f32; 3], dir: [f32; 3], [v0, v1, v2]: [[f32; 3]; 3]) -> Option<[f32; 3]> {
    let edge1 = sub32(v1, v0);
    let edge2 = sub32(v2, v0);
    let pvec = cross32(dir, edge2);
    let det = dot32(edge1, pvec);
    if det > -RAY_EPSILON && det < RAY_EPSILON {
        return None;
    }
    let inv_det = 1.0 / det;
    let tvec = sub32(origin, v0);
    let u = dot32(tvec, pvec) * inv_det;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let qvec = cross32(tvec, edge1);
    let v = dot32(dir, qvec) * inv_det;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    Some([dot32(edge2, qvec) * inv_det, u, v])
}

/// Collapses runs of equal positions in sorted samples into one point carrying the mean of
/// the normals of its distinct (position, normal) samples (in `f32`, as pc_error averages them).
fn merge_positions<C>(samples: &[(SampleKey, C)]) -> PointCloud {
    let mut cloud = PointCloud::default();
    for run in position_runs(samples) {
        let (count, sum) =
            run.chunk_by(|a, b| a.0 == b.0).fold((0.0f32, [0.0f32; 3]), |(n, s), same| {
                let k = same[0].0;
                (n + 1.0, add32(s, [k[3], k[4], k[5]].map(key_value)))
            });
        let k = run[0].0;
        cloud.points.push([k[0], k[1], k[2]].map(|v| f64::from(key_value(v))));
        cloud.normals.push(sum.map(|v| f64::from(v / count)));
    }
    cloud
}

/// Order-preserving integer image of an `f32` (-0.0 maps like 0.0; NaNs sort last or first by
/// sign, consistently).
fn order_key(v: f32) -> u32 {
    let bits = (v + 0.0).to_bits();
    if bits >> 31 == 1 {
        !bits
    } else {
        bits | (1 << 31)
    }
}

/// Inverse of [`order_key`].
fn key_value(k: u32) -> f32 {
    f32::from_bits(if k >> 31 == 1 { k & !(1 << 31) } else { !k })
}

// ---- small f32 vector helpers (mmetric samples in single precision) ----

fn sub32(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn add32(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn scale32(a: [f32; 3], s: f32) -> [f32; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}

fn dot32(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross32(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[1] * b[2] - b[1] * a[2], a[2] * b[0] - b[2] * a[0], a[0] * b[1] - b[0] * a[1]]
}

fn min3(tri: [[f32; 3]; 3], k: usize) -> f32 {
    tri[0][k].min(tri[1][k]).min(tri[2][k])
}

fn max3(tri: [[f32; 3]; 3], k: usize) -> f32 {
    tri[0][k].max(tri[1][k]).max(tri[2][k])
}

/// Lexicographic order of `f32` triples (-0.0 equal to 0.0), as mmetric's vertex sort.
fn cmp_f32s(a: &[f32; 3], b: &[f32; 3]) -> std::cmp::Ordering {
    a.map(order_key).cmp(&b.map(order_key))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    type Mesh = (Vec<[f64; 3]>, Vec<[u32; 3]>);

    /// Unit square in the plane z = `z`, split along the (1,0)-(0,1) diagonal, normal +z.
    pub(crate) fn square(z: f64) -> Mesh {
        let p = vec![[0.0, 0.0, z], [1.0, 0.0, z], [1.0, 1.0, z], [0.0, 1.0, z]];
        (p, vec![[0, 1, 3], [1, 2, 3]])
    }

    /// Grid of size 11 over the unit square's box: step = 0.1 rounded up to 6554/65536.
    pub(crate) fn square_grid() -> SamplingGrid {
        SamplingGrid::over_box([0.0; 3], [1.0, 1.0, 0.0], 11)
    }

    #[test]
    fn grid_rounds_corner_and_step_to_fixed_point() {
        let g = SamplingGrid::over_box([-0.3, 0.2, 1.0], [1.7, 0.5, 1.0], 1024);
        let fp = 65536.0;
        assert_eq!(g.origin[0], ((-0.3f32 * 65536.0).floor() / 65536.0) as f64);
        assert!(g.origin[0] <= -0.3 && g.origin[0] > -0.3 - 1.0 / fp);
        assert!(g.origin[1] <= 0.2 && g.origin[1] > 0.2 - 1.0 / fp);
        assert_eq!(g.origin[2], 1.0);
        assert_eq!((g.step * fp).fract(), 0.0);
        assert!(g.step >= 2.0 / 1023.0 && g.step < 2.0 / 1023.0 + 2.0 / fp);
        assert_eq!(square_grid().step, 6554.0 / fp);
    }

    #[test]
    fn repeated_faces_are_sampled_once_and_their_rays_counted_once() {
        let (mut p, f) = square(0.0);
        let grid = square_grid();
        let once = sample_grid(&p, &f, &grid);
        // Copies of the first face (one by other indices at the same places, one rotated),
        // and its flipped twin, whose normal differs: that one does count.
        p.extend([p[0], p[1], p[3]]);
        let mut repeated = f.clone();
        for _ in 0..1000 {
            repeated.extend([f[0], [4, 5, 6], [1, 3, 0]]);
        }
        assert_eq!(sample_grid(&p, &repeated, &grid), once);
        assert_eq!(ray_count(&p, &repeated, &grid), ray_count(&p, &f, &grid));
        assert_eq!(ray_count_coloured(&p, &repeated, &grid), 3001 * ray_count(&p, &f[..1], &grid) + ray_count(&p, &f[1..], &grid));
        repeated.push([0, 3, 1]);
        assert_eq!(ray_count(&p, &repeated, &grid), ray_count(&p, &f, &grid) + ray_count(&p, &f[..1], &grid));
        assert_ne!(sample_grid(&p, &repeated, &grid), once);
    }

    #[test]
    fn unit_square_gives_one_point_per_grid_line_pair() {
        let (p, f) = square(0.0);
        let cloud = sample_grid(&p, &f, &square_grid());
        // Lines 0..=9 on x and y (line 10 lies at 1.00006, outside the square).
        assert_eq!(cloud.points.len(), 100);
        assert_eq!(cloud.normals.len(), 100);
        assert!(cloud.normals.iter().all(|n| *n == [0.0, 0.0, 1.0]));
        assert!(cloud.points.iter().all(|q| q[2] == 0.0));
    }

    #[test]
    fn shared_edge_points_keep_the_mean_normal() {
        // Two triangles folded along x = 0.5 (a roof): grid points on the ridge are hit by both.
        let p = vec![
            [0.0, 0.0, 0.0],
            [0.5, 0.0, 0.25],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.5, 1.0, 0.25],
            [1.0, 1.0, 0.0],
        ];
        let f = vec![[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4]];
        let grid = SamplingGrid::over_box([0.0; 3], [1.0, 1.0, 0.25], 3);
        let cloud = sample_grid(&p, &f, &grid);
        let ridge: Vec<_> =
            (0..cloud.points.len()).filter(|&i| cloud.points[i][0] == 0.5).collect();
        assert!(!ridge.is_empty());
        for i in ridge {
            let n = cloud.normals[i];
            assert!(n[0].abs() < 1e-6 && n[1].abs() < 1e-6 && n[2] > 0.0 && n[2] < 1.0, "{n:?}");
        }
    }
}
