//! Texture transfer onto a new UV atlas.
//!
//! The encoder codes a reconstructed mesh (a subdivided, displaced base mesh) whose UV atlas
//! differs from the input frame's. As in V-DMC, the input frame's texture is therefore
//! re-sampled onto the reconstructed mesh's atlas: every texel of the new atlas that a UV
//! triangle covers is mapped to its 3D point on the reconstructed surface, that point is
//! projected onto the input surface (closest point), and the input texture is read at the
//! input UVs of the projection. [`transfer_texture`] does this; [`crate::texture::pad::pad`] then fills
//! the texels no chart covers.
//!
//! The closest-point searches dominate the cost (an atlas has millions of texels). Rather than
//! asking the source's Bvh for each, the image is cut into bands of rows, one rayon task each;
//! a band is rasterised, then walked texel after adjacent texel, so that a
//! `crate::geom::closest::Finder` starts each search from the answer before, and mostly
//! settles it within a cell of its grid. Its answers are exactly the Bvh's (the few texels
//! too far from the source for its grid are answered by a Bvh at the end), so the result
//! does not depend on the walk.
//!
//! Image conventions are those of [`crate::texture`]: rows from the top, `v` up, texel
//! `(x, y)` centred at `u = (x + 0.5) / width`, `v = 1 - (y + 0.5) / height`.

use std::ops::Range;

use rayon::prelude::*;

use crate::geom::bins::Bins;
use crate::geom::closest::{largest_coordinate, Finder, Hit, Source};
use crate::geom::mesh::interpolate;
use crate::texture::{Texture, UvMesh};

/// How far around a UV triangle texels are still covered, in texels along each axis: a
/// texel counts when its centre lies strictly within this Chebyshev distance of the
/// triangle. One texel is exactly the reach of a bilinear lookup, so every lookup at a UV
/// inside a chart reads transferred colour, never gutter.
const REACH: f64 = 1.0;

/// Image rows rasterised and transferred by one rayon task. Small enough that a 2048-row
/// atlas gives hundreds of tasks to balance (charts are unevenly spread over the rows), large
/// enough that a UV triangle rarely straddles two bands and is rasterised twice.
const BAND: usize = 8;

/// UV triangles with less than this doubled area (in texels²) are treated as degenerate: they
/// hold no texel centre, and their barycentrics would be mostly rounding.
const MIN_AREA2: f64 = 1e-12;

/// The result of [`transfer_texture`].
#[derive(Debug, Clone, PartialEq)]
pub struct Transferred {
    /// The target's texture: transferred colour on covered texels, black elsewhere.
    pub texture: Texture,
    /// One flag per texel (row-major from the top): whether a UV triangle of the target covers
    /// it, i.e. whether the texel holds transferred colour. Input of [`crate::texture::pad::pad`].
    pub covered: Vec<bool>,
}

/// Re-samples `source_texture`, the texture of `source`, onto the UV atlas of `target`, as a
/// `width` x `height` texture.
///
/// A texel is covered when its centre lies strictly within one texel (along each axis) of a
/// UV triangle of `target`, so that bilinear lookups anywhere inside a chart read transferred
/// colour. Its colour is found thus: the texel centre, clamped onto the nearest point of the
/// UV triangle, gives barycentrics; these give a 3D point on the target's triangle; the
/// closest point of the source surface to it (lowest source face on ties) gives a source face
/// and barycentrics there, which interpolate the source UVs; `source_texture` is sampled
/// bilinearly at them ([`Texture::sample`]) and rounded.
///
/// When several UV triangles cover a texel, the one nearest to its centre wins (distance 0
/// for every triangle that contains it), and among equally near ones the lowest face index;
/// so overlapping charts and texels on shared UV edges get one deterministic owner, and a
/// chart's own texels are never taken over by the margin of a neighbouring chart. The result
/// does not depend on the number of rayon threads.
///
/// Both meshes must pass [`UvMesh::validate`] (not checked here, except that nothing panics);
/// `width` and `height` should be at least 1 (either 0 gives an empty texture). Edge cases:
/// UV triangles of zero area are skipped; UVs outside [0, 1] are clipped to the image (a
/// triangle off the image covers nothing); source UVs outside [0, 1] read the border texels
/// of `source_texture`. An empty `target` covers nothing, and with an empty `source` no colour
/// can be found, so nothing is covered either: the texture is then all black.
pub fn transfer_texture(
    target: &UvMesh,
    source: &UvMesh,
    source_texture: &Texture,
    width: usize,
    height: usize,
) -> Transferred {
    let mut rgb = vec![[0u8; 3]; width * height];
    let mut covered = vec![false; width * height];
    if !source.mesh.faces.is_empty() && width > 0 && height > 0 {
        let magnitude = largest_coordinate(&target.mesh.positions);
        let (prepared, bins) = rayon::join(|| Source::new(&source.mesh, magnitude), || bin_faces(target, width, height));
        let ctx = Context { target, source, source_texture, prepared, width, height };
        let rows = BAND * width;
        // Each rayon job reuses its buffers and finder over its bands; the results do not
        // depend on what the finder remembers, so neither on how the bands are split. The
        // texels too far from the source for the finder are answered together at the end.
        let far: Vec<(usize, [f64; 3])> = rgb
            .par_chunks_mut(rows)
            .zip(covered.par_chunks_mut(rows))
            .enumerate()
            .map_init(
                || Worker::new(&ctx),
                |worker, (band, (rgb, covered))| worker.band(band * BAND, bins.of(band), rgb, covered),
            )
            .flatten_iter()
            .collect();
        if !far.is_empty() {
            let points: Vec<[f64; 3]> = far.iter().map(|&(_, p)| p).collect();
            for (&(i, _), hit) in far.iter().zip(ctx.prepared.closest_far(&points)) {
                if let Some(hit) = hit {
                    rgb[i] = ctx.colour(&hit);
                    covered[i] = true;
                }
            }
        }
    }
    Transferred { texture: Texture { width, height, rgb }, covered }
}

/// Everything the per-band workers read.
struct Context<'a> {
    target: &'a UvMesh,
    source: &'a UvMesh,
    source_texture: &'a Texture,
    prepared: Source<'a>,
    width: usize,
    height: usize,
}

impl Context<'_> {
    fn uv_triangle(&self, face: u32) -> Option<UvTriangle> {
        uv_triangle(self.target, face, self.width, self.height)
    }

    fn target_corners(&self, face: u32) -> [[f64; 3]; 3] {
        self.target.mesh.faces[face as usize].map(|v| self.target.mesh.positions[v as usize])
    }

    /// The source texture at the source UVs of `hit`, rounded.
    fn colour(&self, hit: &Hit) -> [u8; 3] {
        let uv = self.source.uv_faces[hit.triangle as usize].map(|i| self.source.uv[i as usize]);
        let w = hit.bary;
        let uv = [0, 1].map(|k| w[0] * uv[0][k] + w[1] * uv[1][k] + w[2] * uv[2][k]);
        sample_rounded(self.source_texture, uv)
    }
}

/// [`Texture::sample`] at `uv`, rounded: the same arithmetic, without its library calls on
/// baseline x86-64 (`floor`: the coordinates are clamped non-negative first, so truncating
/// floors them; `round`: truncating after adding a half rounds the non-negative channels).
fn sample_rounded(texture: &Texture, uv: [f64; 2]) -> [u8; 3] {
    let (w, h) = (texture.width, texture.height);
    let fx = (uv[0] * w as f64 - 0.5).clamp(0.0, (w - 1) as f64);
    let fy = ((1.0 - uv[1]) * h as f64 - 0.5).clamp(0.0, (h - 1) as f64);
    let (fx, fy) = (if fx.is_nan() { 0.0 } else { fx }, if fy.is_nan() { 0.0 } else { fy });
    let (x0, y0) = (fx as usize, fy as usize);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (tx, ty) = (fx - x0 as f64, fy - y0 as f64);
    let (top, bottom) = (&texture.rgb[y0 * w..][..w], &texture.rgb[y1 * w..][..w]);
    let (a, b, c, d) = (top[x0], top[x1], bottom[x0], bottom[x1]);
    std::array::from_fn(|k| {
        let top = a[k] as f64 * (1.0 - tx) + b[k] as f64 * tx;
        let bottom = c[k] as f64 * (1.0 - tx) + d[k] as f64 * tx;
        (top * (1.0 - ty) + bottom * ty + 0.5) as u8
    })
}

/// The UV triangle of face `face` of `target` in the texels of a `width` x `height` image.
fn uv_triangle(target: &UvMesh, face: u32, width: usize, height: usize) -> Option<UvTriangle> {
    let uv = target.uv_faces[face as usize].map(|i| target.uv[i as usize]);
    UvTriangle::new(uv, width, height)
}

/// Sorts the target faces into the bands their covered texels may fall in, so that each band
/// task visits only its own faces (in face order).
fn bin_faces(target: &UvMesh, width: usize, height: usize) -> Bins {
    let bands = height.div_ceil(BAND);
    let spans: Vec<Range<u32>> = (0..target.mesh.faces.len() as u32)
        .into_par_iter()
        .map(|f| {
            let texels = uv_triangle(target, f, width, height).and_then(|t| t.texels(width, height));
            texels.map_or(0..0, |(_, rows)| (rows.start / BAND) as u32..((rows.end - 1) / BAND + 1) as u32)
        })
        .collect();
    Bins::new(bands, || spans.iter().enumerate().flat_map(|(f, s)| s.clone().map(move |b| (b, f as u32))))
}

/// One rayon job's state: the finder and the buffers of a band.
struct Worker<'a> {
    ctx: &'a Context<'a>,
    finder: Finder<'a>,
    tris: Vec<(u32, UvTriangle)>,
    owners: Owners,
}

impl<'a> Worker<'a> {
    fn new(ctx: &'a Context<'a>) -> Self {
        let finder = Finder::new(&ctx.prepared);
        Self { ctx, finder, tris: Vec::new(), owners: Owners { keys: Vec::new(), points: Vec::new() } }
    }

    /// Rasterises `faces` into the band of rows starting at `y0` and transfers the colour of
    /// every texel they cover; returns the texels (index in the image, point) that the finder
    /// leaves to [`Source::closest_far`].
    fn band(&mut self, y0: usize, faces: &[u32], rgb: &mut [[u8; 3]], covered: &mut [bool]) -> Vec<(usize, [f64; 3])> {
        let ctx = self.ctx;
        let (w, rows) = (ctx.width, rgb.len() / ctx.width);
        self.tris.clear();
        self.tris.extend(faces.iter().filter_map(|&f| Some((f, ctx.uv_triangle(f)?))));
        self.owners.draw_band(ctx, y0, rows, &self.tris);
        let mut far = Vec::new();
        // Column by column, down and up in turn: each texel is next to the one before, so
        // the finder's last answer is mostly the next one's too, or a neighbour of it.
        for x in 0..w {
            for k in 0..rows {
                let i = if x % 2 == 0 { k } else { rows - 1 - k } * w + x;
                let Some(point) = self.owners.point(i) else { continue };
                match self.finder.closest(point) {
                    Some(hit) => {
                        rgb[i] = ctx.colour(&hit);
                        covered[i] = true;
                    }
                    None => far.push((y0 * w + i, point)),
                }
            }
        }
        far
    }
}

/// The face that owns each texel of a band, and the texel's point on it.
struct Owners {
    /// `FREE`, or the distance from the texel centre to the triangle in the high half (as
    /// `f32` bits, which order like the non-negative values; 0 only for a texel inside) and
    /// the face index in the low half: the minimum key is the nearest face, lowest index
    /// first, whatever the order in which faces are drawn.
    keys: Vec<u64>,
    /// The point of the owner's 3D triangle at the texel: kept rather than the barycentrics,
    /// so that the triangle's corners are read once per face, not once per texel.
    points: Vec<[f64; 3]>,
}

/// No face owns the texel.
const FREE: u64 = u64::MAX;

impl Owners {
    /// Finds the owners of the texels of the band of `rows` rows from `y0` among `tris`.
    fn draw_band(&mut self, ctx: &Context, y0: usize, rows: usize, tris: &[(u32, UvTriangle)]) {
        self.keys.clear();
        self.keys.resize(rows * ctx.width, FREE);
        self.points.resize(rows * ctx.width, [0.0; 3]);
        let owners = self;
        // Insides first: a texel inside some triangle then skips the margin work of all the
        // others, and only chart borders pay for it.
        let band = y0..y0 + rows;
        for &(face, ref tri) in tris {
            let texels = tri.box_texels(ctx.width, ctx.height);
            owners.draw(ctx, band.clone(), face, texels, |_| true, |p| Some((tri.inside(p)?, 0)));
        }
        for &(face, ref tri) in tris {
            let texels = tri.texels(ctx.width, ctx.height);
            let margin = |p| tri.margin(p).map(|(w, d2)| (w, margin_rank(d2)));
            owners.draw(ctx, band.clone(), face, texels, |key| key >> 32 != 0, margin);
        }
    }

    /// Offers `texels` (columns, rows) within the band's `rows` to `face`, where `open` says
    /// whether a texel's current key may still be beaten and `locate` gives the face's
    /// barycentrics and distance rank at a texel centre, or `None` if it does not cover it.
    fn draw(
        &mut self,
        ctx: &Context,
        rows: Range<usize>,
        face: u32,
        texels: Option<(Range<usize>, Range<usize>)>,
        open: impl Fn(u64) -> bool,
        locate: impl Fn([f64; 2]) -> Option<([f64; 3], u32)>,
    ) {
        let Some((xs, ys)) = texels else { return };
        let (width, corners) = (ctx.width, ctx.target_corners(face));
        for y in ys.start.max(rows.start)..ys.end.min(rows.end) {
            for x in xs.clone() {
                let i = (y - rows.start) * width + x;
                if !open(self.keys[i]) {
                    continue;
                }
                let Some((bary, rank)) = locate(texel_centre(x, y)) else { continue };
                let key = u64::from(rank) << 32 | u64::from(face);
                if key < self.keys[i] {
                    self.keys[i] = key;
                    self.points[i] = interpolate(corners, bary);
                }
            }
        }
    }

    fn point(&self, i: usize) -> Option<[f64; 3]> {
        (self.keys[i] != FREE).then_some(self.points[i])
    }
}

/// The distance rank of a texel in a triangle's margin: its squared distance as `f32` bits,
/// at least 1 so that it never ties with a texel inside.
fn margin_rank(d2: f64) -> u32 {
    (d2 as f32).to_bits().max(1)
}

/// Centre of texel `(x, y)` in texel units (x right, y down).
fn texel_centre(x: usize, y: usize) -> [f64; 2] {
    [x as f64 + 0.5, y as f64 + 0.5]
}

/// A UV triangle in texel units: `x = u * width`, `y = (1 - v) * height`.
struct UvTriangle {
    corners: [[f64; 2]; 3],
    /// Edge function of edge `i` (corner `i` to corner `i + 1`): `e(p) = n · p + c`, oriented
    /// to be >= 0 inside, where it is the barycentric of corner `i + 2` times twice the area.
    n: [[f64; 2]; 3],
    c: [f64; 3],
    lo: [f64; 2],
    hi: [f64; 2],
}

impl UvTriangle {
    /// `None` for a degenerate triangle (or one whose texel coordinates overflow).
    fn new(uv: [[f64; 2]; 3], width: usize, height: usize) -> Option<Self> {
        let corners = uv.map(|p| [p[0] * width as f64, (1.0 - p[1]) * height as f64]);
        let [a, b, c] = corners;
        let area2 = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
        if !(area2.abs() > MIN_AREA2 && area2.is_finite()) {
            return None;
        }
        let s = area2.signum();
        let n = [0, 1, 2].map(|i| {
            let (p, q) = (corners[i], corners[(i + 1) % 3]);
            [-s * (q[1] - p[1]), s * (q[0] - p[0])]
        });
        let lo = [0, 1].map(|k| a[k].min(b[k]).min(c[k]));
        let hi = [0, 1].map(|k| a[k].max(b[k]).max(c[k]));
        let c = [0, 1, 2].map(|i| -(n[i][0] * corners[i][0] + n[i][1] * corners[i][1]));
        Some(Self { corners, n, c, lo, hi })
    }

    /// The texels (columns, rows; clipped to the image) whose centres lie strictly within
    /// `REACH` of the triangle's box: all it may cover.
    fn texels(&self, width: usize, height: usize) -> Option<(Range<usize>, Range<usize>)> {
        let axis = |k: usize, n: usize| centres_within(self.lo[k] - REACH, self.hi[k] + REACH, n, false);
        Some((axis(0, width)?, axis(1, height)?))
    }

    /// The texels whose centres lie in the triangle's closed box: all it may contain.
    fn box_texels(&self, width: usize, height: usize) -> Option<(Range<usize>, Range<usize>)> {
        let axis = |k: usize, n: usize| centres_within(self.lo[k], self.hi[k], n, true);
        Some((axis(0, width)?, axis(1, height)?))
    }

    fn edge_functions(&self, p: [f64; 2]) -> [f64; 3] {
        [0, 1, 2].map(|i| self.n[i][0] * p[0] + self.n[i][1] * p[1] + self.c[i])
    }

    /// Barycentrics of `p` if it lies inside the triangle (edges included). The box test
    /// first, so that rounding in the edge functions cannot let in a point beyond the box that
    /// [`UvTriangle::box_texels`] leaves out.
    fn inside(&self, p: [f64; 2]) -> Option<[f64; 3]> {
        if (0..2).any(|k| p[k] < self.lo[k] || p[k] > self.hi[k]) {
            return None;
        }
        let e = self.edge_functions(p);
        let sum = e[0] + e[1] + e[2];
        (e.iter().all(|&x| x >= 0.0) && sum > 0.0).then(|| [e[1] / sum, e[2] / sum, e[0] / sum])
    }

    /// For `p` outside the triangle but strictly within `REACH` of it along each axis: the
    /// barycentrics of the nearest point of the triangle and the squared distance to it. The
    /// test is the separating-axis test of the triangle against the square of half-side
    /// `REACH` around `p`: the square's own axes, then the edge normals.
    fn margin(&self, p: [f64; 2]) -> Option<([f64; 3], f64)> {
        if (0..2).any(|k| p[k] <= self.lo[k] - REACH || p[k] >= self.hi[k] + REACH) {
            return None;
        }
        let e = self.edge_functions(p);
        let reach = |i: usize| REACH * (self.n[i][0].abs() + self.n[i][1].abs());
        if (0..3).any(|i| e[i] + reach(i) <= 0.0) {
            return None;
        }
        Some(self.nearest_on_edges(p))
    }

    /// The nearest point of the boundary (not merely clamped barycentrics, so that the colour
    /// comes from the nearest part of the chart).
    fn nearest_on_edges(&self, p: [f64; 2]) -> ([f64; 3], f64) {
        let mut best = ([1.0, 0.0, 0.0], f64::INFINITY);
        for i in 0..3 {
            let (a, b) = (self.corners[i], self.corners[(i + 1) % 3]);
            let (t, d2) = nearest_on_segment(p, a, b);
            if d2 < best.1 {
                let mut w = [0.0; 3];
                w[i] = 1.0 - t;
                w[(i + 1) % 3] = t;
                best = (w, d2);
            }
        }
        best
    }
}

/// The indices `i` in `0..n` whose centres `i + 0.5` lie in `[lo, hi]` (`closed`) or in
/// `(lo, hi)`, or `None` if there are none.
fn centres_within(lo: f64, hi: f64, n: usize, closed: bool) -> Option<Range<usize>> {
    // Clamping first changes no answer, keeps the conversions below exact, and spares the
    // library calls `f64::floor` and `f64::ceil` cost on baseline x86-64 (this runs several
    // times per target face).
    let clamp = |x: f64| (x - 0.5).clamp(-1.0, n as f64 + 1.0);
    let (lo, hi) = (clamp(lo), clamp(hi));
    let (first, last) = if closed { (ceil(lo), floor(hi)) } else { (floor(lo) + 1, ceil(hi) - 1) };
    let (first, last) = (first.max(0), last.min(n as i64 - 1));
    (first <= last).then(|| first as usize..last as usize + 1)
}

/// `x.floor()` for `x` well within the range of `i64`.
fn floor(x: f64) -> i64 {
    let t = x as i64;
    if (t as f64) > x { t - 1 } else { t }
}

fn ceil(x: f64) -> i64 {
    let t = x as i64;
    if (t as f64) < x { t + 1 } else { t }
}

/// Parameter in [0, 1] of the point of segment `ab` nearest to `p`, and its squared distance.
fn nearest_on_segment(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> (f64, f64) {
    let (ab, ap) = ([b[0] - a[0], b[1] - a[1]], [p[0] - a[0], p[1] - a[1]]);
    let len2 = ab[0] * ab[0] + ab[1] * ab[1];
    let t = if len2 > 0.0 { ((ap[0] * ab[0] + ap[1] * ab[1]) / len2).clamp(0.0, 1.0) } else { 0.0 };
    let d = [ap[0] - t * ab[0], ap[1] - t * ab[1]];
    (t, d[0] * d[0] + d[1] * d[1])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::testmesh::{midpoint, Rng, Soup};
    use crate::geom::bvh::Bvh;
    use crate::geom::mesh::{scale, Mesh};
    use crate::texture::pad::pad;

    fn uv_mesh(positions: Vec<[f64; 3]>, faces: Vec<[u32; 3]>, uv: Vec<[f64; 2]>) -> UvMesh {
        let uv_faces = faces.clone();
        let m = UvMesh { mesh: Mesh::new(positions, faces), uv, uv_faces };
        m.validate().unwrap();
        m
    }

    /// The unit square in the plane z, as two triangles, with the given UV at each corner
    /// (corners (0,0), (1,0), (1,1), (0,1)).
    fn square(z: f64, uv: [[f64; 2]; 4]) -> UvMesh {
        let pos = vec![[0.0, 0.0, z], [1.0, 0.0, z], [1.0, 1.0, z], [0.0, 1.0, z]];
        uv_mesh(pos, vec![[0, 1, 2], [0, 2, 3]], uv.to_vec())
    }

    const IDENTITY: [[f64; 2]; 4] = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];

    /// A texture of pseudo-random colours: any misplaced texel shows.
    fn noise(width: usize, height: usize, seed: u64) -> Texture {
        let mut rng = Rng(seed);
        let rgb = (0..width * height).map(|_| [0; 3].map(|_: u8| (rng.unit() * 256.0) as u8)).collect();
        Texture { width, height, rgb }
    }

    fn max_diff(a: [u8; 3], b: [u8; 3]) -> u8 {
        (0..3).map(|k| a[k].abs_diff(b[k])).max().unwrap()
    }

    #[test]
    fn mirrored_and_rotated_atlases_carry_the_source_texels() {
        let n = 32;
        let source = square(0.0, IDENTITY);
        let tex = noise(n, n, 5);
        // Mirrored left-right: target texel (x, y) shows point (1 - u, v), source texel (n-1-x, y).
        let mirrored = square(0.0, [[1.0, 0.0], [0.0, 0.0], [0.0, 1.0], [1.0, 1.0]]);
        // Rotated a quarter turn: the target's u is the point's y, its v is 1 - x.
        let rotated = square(0.0, [[0.0, 1.0], [0.0, 0.0], [1.0, 0.0], [1.0, 1.0]]);
        let want_mirrored = |x: usize, y: usize| tex.texel(n - 1 - x, y);
        // Target texel (x, y): u = (x+.5)/n = point y, 1 - v = (y+.5)/n = point x... rows of
        // the source from the top are 1 - point y.
        let want_rotated = |x: usize, y: usize| tex.texel(y, n - 1 - x);
        for (target, want) in [(mirrored, &want_mirrored as &dyn Fn(usize, usize) -> [u8; 3]), (rotated, &want_rotated)] {
            let out = transfer_texture(&target, &source, &tex, n, n);
            assert!(out.covered.iter().all(|&c| c));
            for y in 0..n {
                for x in 0..n {
                    let got = out.texture.texel(x, y);
                    assert!(max_diff(got, want(x, y)) <= 1, "texel ({x}, {y}): {got:?} vs {:?}", want(x, y));
                }
            }
        }
    }

    /// A horizontal red ramp and vertical green ramp: bilinear lookups of it are exact away
    /// from the border half-texel, so a change of resolution has a known answer.
    fn gradient(n: usize) -> Texture {
        let rgb = (0..n * n).map(|i| [(8 * (i % n)) as u8, (8 * (i / n)) as u8, 77]).collect();
        Texture { width: n, height: n, rgb }
    }

    /// The gradient's colour at a UV inside its texel centres.
    fn gradient_at(n: usize, uv: [f64; 2]) -> [f64; 3] {
        [8.0 * (uv[0] * n as f64 - 0.5), 8.0 * ((1.0 - uv[1]) * n as f64 - 0.5), 77.0]
    }

    #[test]
    fn gradient_resampled_at_another_resolution_and_through_an_offset_surface() {
        let source = square(0.0, IDENTITY);
        let tex = gradient(32);
        // Mirrored top-bottom, and lifted off the source plane: the closest point of the
        // source is straight below.
        let target = square(0.05, [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]]);
        let m = 20;
        let out = transfer_texture(&target, &source, &tex, m, m);
        for y in 0..m {
            for x in 0..m {
                let (u, v) = ((x as f64 + 0.5) / m as f64, 1.0 - (y as f64 + 0.5) / m as f64);
                let src_uv = [u, 1.0 - v];
                let inner = src_uv.iter().all(|&c| (0.5 / 32.0..=1.0 - 0.5 / 32.0).contains(&c));
                if inner {
                    let want = gradient_at(32, src_uv).map(|c| c.round() as u8);
                    assert!(max_diff(out.texture.texel(x, y), want) <= 1, "({x}, {y})");
                }
            }
        }
    }

    #[test]
    fn coverage_matches_the_uv_area_plus_the_reach_margin() {
        let n = 200;
        let pos = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let uv = vec![[0.1, 0.15], [0.87, 0.3], [0.33, 0.81]];
        let target = uv_mesh(pos.clone(), vec![[0, 1, 2]], uv.clone());
        let source = uv_mesh(pos, vec![[0, 1, 2]], uv.clone());
        let out = transfer_texture(&target, &source, &Texture::filled(4, 4, [9, 9, 9]), n, n);
        let count = out.covered.iter().filter(|&&c| c).count() as f64;
        // In texels: the triangle grown by a square of half-side REACH (a Minkowski sum).
        let px: Vec<[f64; 2]> = uv.iter().map(|p| [p[0] * n as f64, p[1] * n as f64]).collect();
        let area = 0.5 * ((px[1][0] - px[0][0]) * (px[2][1] - px[0][1]) - (px[1][1] - px[0][1]) * (px[2][0] - px[0][0])).abs();
        let width = |k: usize| px.iter().map(|p| p[k]).fold(f64::MIN, f64::max) - px.iter().map(|p| p[k]).fold(f64::MAX, f64::min);
        let grown = area + 2.0 * REACH * (width(0) + width(1)) + 4.0 * REACH * REACH;
        // Within rounding: the texel centres in a region differ from its area by a fraction
        // of its perimeter at most, and mostly much less.
        assert!((count - grown).abs() < 0.0025 * grown, "{count} texels for {grown}");
        assert!(out.texture.rgb.iter().zip(&out.covered).all(|(c, &k)| *c == if k { [9; 3] } else { [0; 3] }));
        // Two triangles tiling the image cover it all.
        let square = square(0.0, IDENTITY);
        let out = transfer_texture(&square, &square, &Texture::filled(4, 4, [9, 9, 9]), 13, 7);
        assert!(out.covered.iter().all(|&c| c));
    }

    #[test]
    fn chart_margins_do_not_take_texels_inside_other_charts() {
        // Two charts side by side, the right one first in face order: texels left of the
        // boundary belong to the left chart even though the right one's margin reaches them.
        let pos = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
        let source = uv_mesh(pos.clone(), vec![[0, 1, 2], [0, 2, 3]], IDENTITY.to_vec());
        let tex = gradient(16);
        let mut pos2 = pos.clone();
        pos2.extend(pos.iter().map(|p| [p[0] + 10.0, p[1], p[2]]));
        let faces = vec![[4, 5, 6], [4, 6, 7], [0, 1, 2], [0, 2, 3]];
        // Left chart: u in [0, 0.5]; right chart: u in [0.5, 1], both full height.
        let uv = vec![[0.0, 0.0], [0.5, 0.0], [0.5, 1.0], [0.0, 1.0], [0.5, 0.0], [1.0, 0.0], [1.0, 1.0], [0.5, 1.0]];
        let target = UvMesh { mesh: Mesh::new(pos2, faces), uv, uv_faces: vec![[4, 5, 6], [4, 6, 7], [0, 1, 2], [0, 2, 3]] };
        target.validate().unwrap();
        // The right chart lies 10 units off in x: its closest source points are on the
        // source's right edge, the gradient's last column (red 120). Texel column 7 lies in the
        // left chart (red 8 * (15 - 0.5) there) and within the right chart's margin.
        let out = transfer_texture(&target, &source, &tex, 16, 16);
        for y in 0..16 {
            assert!(out.texture.texel(7, y)[0].abs_diff(116) <= 1, "left chart at (7, {y})");
            assert_eq!(out.texture.texel(8, y)[0], 120, "right chart at (8, {y})");
        }
        assert!(out.covered.iter().all(|&c| c));
    }

    #[test]
    fn degenerate_clipped_and_empty_inputs_do_not_panic() {
        let source = square(0.0, IDENTITY);
        let tex = noise(8, 8, 1);
        // A zero-area UV triangle, and one far outside the image.
        let pos = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let flat = uv_mesh(pos.clone(), vec![[0, 1, 2]], vec![[0.2, 0.2], [0.4, 0.4], [0.6, 0.6]]);
        let far = uv_mesh(pos.clone(), vec![[0, 1, 2]], vec![[5.0, 5.0], [6.0, 5.0], [5.0, 1e300]]);
        for t in [&flat, &far] {
            let out = transfer_texture(t, &source, &tex, 9, 5);
            assert!(!out.covered.contains(&true));
        }
        // Partly off the image: only the part inside is covered, clipped at the border.
        let big = uv_mesh(pos, vec![[0, 1, 2]], vec![[-1.0, -1.0], [3.0, -1.0], [-1.0, 3.0]]);
        let out = transfer_texture(&big, &source, &tex, 9, 5);
        assert!(out.covered.iter().all(|&c| c));
        let empty = UvMesh::default();
        for (t, s) in [(&empty, &source), (&source, &empty)] {
            let out = transfer_texture(t, s, &tex, 3, 4);
            assert_eq!((out.texture.rgb.len(), out.covered.contains(&true)), (12, false));
            assert!(out.texture.rgb.iter().all(|&c| c == [0; 3]));
        }
        let one = transfer_texture(&source, &source, &tex, 1, 1);
        assert_eq!(one.covered, vec![true]);
        let mut zero = transfer_texture(&source, &source, &tex, 0, 5);
        assert!(zero.texture.rgb.is_empty() && zero.covered.is_empty());
        pad(&mut zero.texture, &zero.covered);
    }

    /// Lat-long sphere with a UV atlas: `u` around, `v` up, a seam at `u = 0 = 1`, pole fans.
    /// Returns the mesh and its UVs as a second soup (z = 0), faces in the same order.
    fn sphere(stacks: u32, slices: u32, radius: impl Fn(f64, f64) -> f64) -> (Soup, Soup) {
        use std::f64::consts::PI;
        let (mut pos, mut uv) = (Vec::new(), Vec::new());
        for i in 0..=stacks {
            for j in 0..=slices {
                let (th, ph) = (PI * i as f64 / stacks as f64, 2.0 * PI * j as f64 / slices as f64);
                let r = radius(th, ph);
                pos.push([r * th.sin() * ph.cos(), r * th.sin() * ph.sin(), r * th.cos()]);
                uv.push([j as f64 / slices as f64, 1.0 - i as f64 / stacks as f64, 0.0]);
            }
        }
        let at = |i: u32, j: u32| i * (slices + 1) + j;
        let mut faces = Vec::new();
        for i in 0..stacks {
            for j in 0..slices {
                let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                if i > 0 {
                    faces.push([a, b, d]);
                }
                if i + 1 < stacks {
                    faces.push([b, c, d]);
                }
            }
        }
        // Positions are duplicated along the seam and at the poles, like the UVs: the same
        // index serves both, which keeps the test simple.
        ((pos, faces.clone()), (uv, faces))
    }

    fn uv_mesh_of((pos, faces): Soup, (uv, uv_faces): Soup, margin: f64) -> UvMesh {
        let uv = uv.iter().map(|p| [margin + (1.0 - 2.0 * margin) * p[0], margin + (1.0 - 2.0 * margin) * p[1]]).collect();
        let m = UvMesh { mesh: Mesh::new(pos, faces), uv, uv_faces };
        m.validate().unwrap();
        m
    }

    fn bumpy(th: f64, ph: f64) -> f64 {
        1.0 + 0.05 * (4.0 * th).sin() * (6.0 * ph).cos()
    }

    /// Source: a bumpy sphere; target: a coarser one, midpoint-subdivided `levels` times (as
    /// the codec subdivides its base mesh), so its vertices lie off the source surface.
    fn sphere_pair(source_size: (u32, u32), base_size: (u32, u32), levels: u32) -> (UvMesh, UvMesh) {
        let (s, suv) = sphere(source_size.0, source_size.1, bumpy);
        let (b, buv) = sphere(base_size.0, base_size.1, bumpy);
        let target = uv_mesh_of(midpoint(&b, levels), midpoint(&buv, levels), 0.02);
        (target, uv_mesh_of(s, suv, 0.0))
    }

    #[test]
    fn same_result_on_one_and_two_threads() {
        let (target, source) = sphere_pair((30, 60), (10, 20), 2);
        let tex = noise(64, 32, 9);
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| {
                let mut out = transfer_texture(&target, &source, &tex, 150, 97);
                pad(&mut out.texture, &out.covered);
                out
            })
        };
        let one = run(1);
        assert!(one.covered.iter().filter(|&&c| c).count() > 150 * 97 * 9 / 10);
        assert_eq!(one, run(2));
    }

    #[test]
    fn rounded_samples_are_the_texture_samples_rounded() {
        let mut rng = Rng(31);
        for (w, h) in [(1, 1), (1, 7), (5, 1), (13, 8), (64, 32)] {
            let tex = noise(w, h, w as u64 + 100 * h as u64);
            let mut uvs = vec![[f64::NAN, 0.5], [0.5, f64::NAN], [-0.1, 1.3], [1.0, 0.0], [0.0, 1.0], [f64::INFINITY, -1e300]];
            // Texel centres and edges exactly, and anywhere around the image.
            for x in 0..=2 * w {
                for y in 0..=2 * h {
                    uvs.push([x as f64 / (2 * w) as f64, y as f64 / (2 * h) as f64]);
                }
            }
            uvs.extend((0..2000).map(|_| [rng.range(-0.2, 1.2), rng.range(-0.2, 1.2)]));
            for uv in uvs {
                assert_eq!(sample_rounded(&tex, uv), tex.sample(uv).map(|c| (c + 0.5) as u8), "{w}x{h} at {uv:?}");
            }
        }
    }

    #[test]
    fn texel_ranges_match_floor_and_ceil() {
        let mut rng = Rng(23);
        for _ in 0..20_000 {
            let n = 1 + (rng.unit() * 40.0) as usize;
            let lo = rng.range(-5.0, 45.0).round() / [1.0, 2.0, 4.0][(rng.unit() * 3.0) as usize];
            let hi = lo + rng.range(0.0, 6.0) * (rng.unit() < 0.8) as u8 as f64;
            for closed in [false, true] {
                let inside = |c: f64| if closed { lo <= c && c <= hi } else { lo < c && c < hi };
                let want: Vec<usize> = (0..n).filter(|&i| inside(i as f64 + 0.5)).collect();
                let got: Vec<usize> = centres_within(lo, hi, n, closed).map_or(vec![], |r| r.collect());
                assert_eq!(got, want, "({lo}, {hi}) n {n} closed {closed}");
            }
        }
        assert_eq!(centres_within(-1e300, 1e300, 3, false), Some(0..3));
        assert_eq!(centres_within(f64::NEG_INFINITY, -1e300, 3, true), None);
    }

    /// The transfer done the slow and obvious way: every face tried at every texel, and the
    /// whole source's Bvh asked for every closest point.
    fn reference(target: &UvMesh, source: &UvMesh, tex: &Texture, w: usize, h: usize) -> Transferred {
        let bvh = Bvh::new(&source.mesh.positions, &source.mesh.faces);
        let mut out = Transferred { texture: Texture::filled(w, h, [0; 3]), covered: vec![false; w * h] };
        for y in 0..h {
            for x in 0..w {
                let mut best: Option<(u64, [f64; 3])> = None;
                for (f, uvf) in target.uv_faces.iter().enumerate() {
                    let Some(tri) = UvTriangle::new(uvf.map(|i| target.uv[i as usize]), w, h) else { continue };
                    let p = texel_centre(x, y);
                    let found = match tri.inside(p) {
                        Some(b) => Some((b, 0)),
                        None => tri.margin(p).map(|(b, d2)| (b, margin_rank(d2))),
                    };
                    if let Some((b, rank)) = found {
                        let key = u64::from(rank) << 32 | f as u64;
                        if best.map_or(true, |(k, _)| key < k) {
                            best = Some((key, b));
                        }
                    }
                }
                let Some((key, b)) = best else { continue };
                let corners = target.mesh.faces[key as u32 as usize].map(|v| target.mesh.positions[v as usize]);
                let q = interpolate(corners, b);
                let hit = bvh.closest_point(q).unwrap();
                let (s, bary) = (hit.triangle, hit.bary);
                let uv = source.uv_faces[s as usize].map(|i| source.uv[i as usize]);
                let uv = [0, 1].map(|k| bary[0] * uv[0][k] + bary[1] * uv[1][k] + bary[2] * uv[2][k]);
                out.texture.rgb[y * w + x] = tex.sample(uv).map(|c| c.round() as u8);
                out.covered[y * w + x] = true;
            }
        }
        out
    }

    #[test]
    fn same_result_as_the_obvious_way() {
        let tex = noise(64, 32, 9);
        let (target, source) = sphere_pair((30, 60), (10, 20), 2);
        assert_eq!(transfer_texture(&target, &source, &tex, 61, 47), reference(&target, &source, &tex, 61, 47));
        // A target well off the source (scaled up, and shrunk), with its faces shuffled.
        for s in [1.5, 0.3] {
            let mut far = target.clone();
            far.mesh.positions.iter_mut().for_each(|p| *p = scale(*p, s));
            let mut rng = Rng(5);
            for i in (1..far.mesh.faces.len()).rev() {
                let j = (rng.unit() * (i + 1) as f64) as usize;
                far.mesh.faces.swap(i, j);
                far.uv_faces.swap(i, j);
            }
            assert_eq!(transfer_texture(&far, &source, &tex, 40, 33), reference(&far, &source, &tex, 40, 33));
        }
    }
}
