//! Snapshot renderer: draws a mesh, textured or not, into an RGB image so that people can look
//! at decoded frames (from the command line or Python) without a GPU or a 3D viewer.
//!
//! An orthographic camera looks at the mesh from the direction [`View`] gives; the mesh is framed
//! to fit the image with a small margin, keeping its aspect. Every triangle is rasterised with a
//! depth buffer, sampled at pixel centres (a pixel on an edge shared by two triangles belongs to
//! both, so closed surfaces have no cracks). The pixel's colour is the texture read bilinearly at
//! the UV interpolated there (light grey without a texture), times Lambert shading from a light
//! at the camera, `0.35 + 0.65 |cos|`: the absolute cosine lights the back faces of open
//! captures too. The background is white.
//!
//! Speed: the image is cut into tiles; triangles are binned into the tiles their pixel box
//! overlaps, and rayon renders the tiles in parallel. Shading is deferred (depth pass first,
//! then one texture lookup per covered pixel), so overdraw costs only depth tests. The result
//! does not depend on the thread count: within a tile triangles are drawn in face order, and a
//! depth tie keeps the earlier face.

use rayon::prelude::*;

use crate::geom::bins::Bins;
use crate::geom::mesh::{cross, dot, norm};
use crate::texture::{Texture, UvMesh};

/// Fraction of the image's width and height left blank on each side of the mesh.
const MARGIN: f64 = 0.05;
/// Side of a square tile, in pixels.
const TILE: usize = 32;
/// Faces per rayon task when binning.
const CHUNK: usize = 4096;
const BACKGROUND: [u8; 3] = [255, 255, 255];
/// Surface colour without a texture (channels 0-255).
const UNTEXTURED: [f64; 3] = [200.0, 200.0, 200.0];
/// Shading factor of a surface seen edge-on; 1 at normal incidence.
const AMBIENT: f64 = 0.35;
/// Marks a pixel no triangle covers.
const NO_FACE: u32 = u32::MAX;

/// Direction of the orthographic camera. At azimuth 0 and elevation 0 it looks along -z at the
/// front of the mesh, with +y up and +x to the right. A positive azimuth (degrees) turns the
/// camera about the +y axis towards +x (90: looking along -x from the +x side); a positive
/// elevation (degrees) raises it above the mesh, looking down (90: looking along -y). Non-finite
/// angles give a blank image.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct View {
    /// Degrees about +y, from the front (+z side) towards +x.
    pub azimuth_deg: f64,
    /// Degrees above the horizontal plane.
    pub elevation_deg: f64,
}

/// Renders `mesh` into a `width` x `height` image (sizes below 1 count as 1) seen from `view`,
/// framed to fit with a margin of 5% of each side and its aspect kept.
///
/// A face is drawn with `texture` read bilinearly ([`Texture::sample`]) at its interpolated UVs
/// when a texture is given and the face has a valid UV triangle (`mesh.uv_faces[f]` present,
/// indices in range), in light grey otherwise; times `0.35 + 0.65 |cos|` of the angle between
/// its normal and the view. Faces with an out-of-range vertex index or a non-finite coordinate
/// are skipped, and the framing uses the vertices of the other faces only; faces seen edge-on
/// draw nothing. A mesh with nothing to draw gives a white image. Deterministic and independent
/// of thread count.
pub fn render(
    mesh: &UvMesh,
    texture: Option<&Texture>,
    width: usize,
    height: usize,
    view: View,
) -> Texture {
    let (width, height) = (width.max(1), height.max(1));
    let camera = Camera::new(view);
    let faces = &mesh.mesh.faces;
    let eye: Vec<[f64; 3]> = mesh.mesh.positions.par_iter().map(|&p| camera.project(p)).collect();
    let Some(bounds) = drawn_bounds(&eye, faces) else {
        return Texture::filled(width, height, BACKGROUND);
    };
    let frame = Frame::fit(bounds, width, height);
    let screen: Vec<[f64; 3]> = eye.par_iter().map(|&e| frame.to_pixels(e)).collect();
    let tiles = Tiles::new(width, height);
    let bins = bin_faces(&screen, faces, &tiles);
    let scene = Scene { mesh, texture, screen: &screen, scale: frame.scale };
    let rendered: Vec<Vec<[u8; 3]>> = (0..tiles.count())
        .into_par_iter()
        .map(|t| scene.tile(tiles.rect(t), bins.of(t).iter().map(|&f| f as usize)))
        .collect();
    tiles.assemble(&rendered)
}

/// Orthonormal camera frame: `right`, `up`, and `toward` the camera (the light comes from there).
struct Camera {
    right: [f64; 3],
    up: [f64; 3],
    toward: [f64; 3],
}

impl Camera {
    fn new(view: View) -> Self {
        let (sa, ca) = view.azimuth_deg.to_radians().sin_cos();
        let (se, ce) = view.elevation_deg.to_radians().sin_cos();
        Self { right: [ca, 0.0, -sa], up: [-sa * se, ce, -ca * se], toward: [sa * ce, se, ca * ce] }
    }

    /// (right, up, depth) camera coordinates of a point; larger depth is nearer the camera.
    fn project(&self, p: [f64; 3]) -> [f64; 3] {
        [dot(p, self.right), dot(p, self.up), dot(p, self.toward)]
    }
}

/// The corners of `face` in `coords`, or `None` if an index is out of range or a value not finite.
fn corners(coords: &[[f64; 3]], face: &[u32; 3]) -> Option<[[f64; 3]; 3]> {
    let [a, b, c] = face.map(|v| coords.get(v as usize).copied());
    let tri = [a?, b?, c?];
    tri.iter().flatten().all(|v| v.is_finite()).then_some(tri)
}

/// Box `(min x, min y, max x, max y)` in camera coordinates of the drawable faces' corners, or
/// `None` when no face is drawable.
fn drawn_bounds(eye: &[[f64; 3]], faces: &[[u32; 3]]) -> Option<[f64; 4]> {
    let empty = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
    let grow = |b: [f64; 4], p: &[f64; 3]| {
        [b[0].min(p[0]), b[1].min(p[1]), b[2].max(p[0]), b[3].max(p[1])]
    };
    let join =
        |a: [f64; 4], b: [f64; 4]| [a[0].min(b[0]), a[1].min(b[1]), a[2].max(b[2]), a[3].max(b[3])];
    let bounds = faces
        .par_iter()
        .filter_map(|f| corners(eye, f))
        .fold(|| empty, |b, tri| tri.iter().fold(b, grow))
        .reduce(|| empty, join);
    (bounds[0] <= bounds[2]).then_some(bounds)
}

/// Camera-to-pixel mapping: pixel x to the right, y down from the top row; pixel (i, j) covers
/// `[i, i + 1) x [j, j + 1)`.
struct Frame {
    centre: [f64; 2],
    scale: f64,
    half: [f64; 2],
}

impl Frame {
    /// The largest uniform scale fitting `bounds` inside the image less its margins, centred.
    fn fit([x0, y0, x1, y1]: [f64; 4], width: usize, height: usize) -> Self {
        let fit = |pixels: usize, range: f64| pixels as f64 * (1.0 - 2.0 * MARGIN) / range;
        let scale = fit(width, x1 - x0).min(fit(height, y1 - y0));
        // A single point, or a span too small for f64, has no meaningful scale; any will do.
        let scale = if scale.is_finite() { scale } else { 1.0 };
        Self {
            centre: [0.5 * (x0 + x1), 0.5 * (y0 + y1)],
            scale,
            half: [0.5 * width as f64, 0.5 * height as f64],
        }
    }

    fn to_pixels(&self, [x, y, depth]: [f64; 3]) -> [f64; 3] {
        [
            self.half[0] + (x - self.centre[0]) * self.scale,
            self.half[1] - (y - self.centre[1]) * self.scale,
            depth,
        ]
    }
}

/// Pixel rectangle `[x0, x1) x [y0, y1)`.
#[derive(Debug, Clone, Copy)]
struct Rect {
    x0: usize,
    y0: usize,
    x1: usize,
    y1: usize,
}

/// The image's tiling: `across` x `down` tiles of [`TILE`] pixels (smaller at the right and
/// bottom edges), numbered row by row.
struct Tiles {
    width: usize,
    height: usize,
    across: usize,
    down: usize,
}

impl Tiles {
    fn new(width: usize, height: usize) -> Self {
        Self { width, height, across: width.div_ceil(TILE), down: height.div_ceil(TILE) }
    }

    fn count(&self) -> usize {
        self.across * self.down
    }

    fn rect(&self, t: usize) -> Rect {
        let (x0, y0) = ((t % self.across) * TILE, (t / self.across) * TILE);
        Rect { x0, y0, x1: (x0 + TILE).min(self.width), y1: (y0 + TILE).min(self.height) }
    }

    /// The image from the tiles' pixels (each row-major within its tile).
    fn assemble(&self, tiles: &[Vec<[u8; 3]>]) -> Texture {
        let mut image = Texture::filled(self.width, self.height, BACKGROUND);
        for (t, pixels) in tiles.iter().enumerate() {
            let r = self.rect(t);
            let w = r.x1 - r.x0;
            for (row, src) in pixels.chunks_exact(w).enumerate() {
                let start = (r.y0 + row) * self.width + r.x0;
                image.rgb[start..start + w].copy_from_slice(src);
            }
        }
        image
    }
}

/// Range of pixel indices in `0..n` whose centres `i + 0.5` lie in `[lo, hi]` (may be empty).
fn pixel_span(lo: f64, hi: f64, n: usize) -> (usize, usize) {
    // Float-to-int casts saturate, so far-off coordinates clamp instead of wrapping.
    let first = (lo - 0.5).ceil().max(0.0) as usize;
    let end = ((hi - 0.5).floor() + 1.0).max(0.0) as usize;
    (first, end.min(n))
}

/// Pixel box `(x0, x1, y0, y1)` of the pixel centres a triangle's box covers, clipped to `w x h`.
fn pixel_box(tri: &[[f64; 3]; 3], w: usize, h: usize) -> (usize, usize, usize, usize) {
    let lo = |k: usize| tri[0][k].min(tri[1][k]).min(tri[2][k]);
    let hi = |k: usize| tri[0][k].max(tri[1][k]).max(tri[2][k]);
    let (x0, x1) = pixel_span(lo(0), hi(0), w);
    let (y0, y1) = pixel_span(lo(1), hi(1), h);
    (x0, x1, y0, y1)
}

/// Bins every drawable face into the tiles its pixel box overlaps.
fn bin_faces(screen: &[[f64; 3]], faces: &[[u32; 3]], tiles: &Tiles) -> Bins {
    let per_chunk: Vec<Vec<(u32, u32)>> = faces
        .par_chunks(CHUNK)
        .enumerate()
        .map(|(c, chunk)| {
            let mut out = Vec::with_capacity(chunk.len());
            for (i, face) in chunk.iter().enumerate() {
                let Some(tri) = corners(screen, face) else { continue };
                let (x0, x1, y0, y1) = pixel_box(&tri, tiles.width, tiles.height);
                if x0 >= x1 || y0 >= y1 {
                    continue;
                }
                let f = (c * CHUNK + i) as u32;
                for ty in y0 / TILE..=(y1 - 1) / TILE {
                    for tx in x0 / TILE..=(x1 - 1) / TILE {
                        out.push(((ty * tiles.across + tx) as u32, f));
                    }
                }
            }
            out
        })
        .collect();
    // Chunk after chunk, so that each tile keeps face order.
    Bins::new(tiles.count(), || per_chunk.iter().flatten().copied())
}

/// One edge's function `p -> orient(a, b, p)` (twice the signed area of `(a, b, p)`), evaluated
/// from the lexicographically smaller endpoint so that the two triangles sharing an edge get
/// exactly opposite values and no pixel centre on the edge slips between them.
struct Edge {
    origin: [f64; 2],
    delta: [f64; 2],
    sign: f64,
}

impl Edge {
    fn new(a: [f64; 3], b: [f64; 3]) -> Self {
        let (p, q, sign) = if (a[0], a[1]) <= (b[0], b[1]) { (a, b, 1.0) } else { (b, a, -1.0) };
        Self { origin: [p[0], p[1]], delta: [q[0] - p[0], q[1] - p[1]], sign }
    }

    fn at(&self, p: [f64; 2]) -> f64 {
        self.sign
            * (self.delta[0] * (p[1] - self.origin[1]) - self.delta[1] * (p[0] - self.origin[0]))
    }
}

/// Everything a tile needs to draw and shade its faces.
struct Scene<'a> {
    mesh: &'a UvMesh,
    texture: Option<&'a Texture>,
    /// Pixel x, pixel y, depth (larger is nearer) of every vertex.
    screen: &'a [[f64; 3]],
    /// Pixels per unit of length (camera coordinates to pixels).
    scale: f64,
}

/// What the depth pass keeps for one pixel: the nearest face, its barycentric weights there
/// and its shading factor.
#[derive(Clone, Copy)]
struct Fragment {
    depth: f64,
    face: u32,
    weights: [f64; 3],
    light: f64,
}

impl Scene<'_> {
    /// The pixels of rectangle `r` (row-major), drawing `faces` in the order given.
    fn tile(&self, r: Rect, faces: impl Iterator<Item = usize>) -> Vec<[u8; 3]> {
        let w = r.x1 - r.x0;
        let empty =
            Fragment { depth: f64::NEG_INFINITY, face: NO_FACE, weights: [0.0; 3], light: 0.0 };
        let mut frags = vec![empty; w * (r.y1 - r.y0)];
        for f in faces {
            self.draw(f, r, &mut frags);
        }
        frags.iter().map(|frag| self.shade(frag)).collect()
    }

    /// Depth-tests face `f` into the fragments of rectangle `r`.
    fn draw(&self, f: usize, r: Rect, frags: &mut [Fragment]) {
        let Some([a, b, c]) = corners(self.screen, &self.mesh.mesh.faces[f]) else { return };
        let (x0, x1, y0, y1) = pixel_box(&[a, b, c], r.x1, r.y1);
        let w = r.x1 - r.x0;
        let edges = [Edge::new(b, c), Edge::new(c, a), Edge::new(a, b)];
        let light = self.light([a, b, c]);
        for y in y0.max(r.y0)..y1 {
            for x in x0.max(r.x0)..x1 {
                let p = [x as f64 + 0.5, y as f64 + 0.5];
                let e = [edges[0].at(p), edges[1].at(p), edges[2].at(p)];
                let inside = (e[0] >= 0.0 && e[1] >= 0.0 && e[2] >= 0.0)
                    || (e[0] <= 0.0 && e[1] <= 0.0 && e[2] <= 0.0);
                let total = e[0] + e[1] + e[2];
                if !inside || total == 0.0 {
                    continue;
                }
                let weights = e.map(|v| v / total);
                let depth = weights[0] * a[2] + weights[1] * b[2] + weights[2] * c[2];
                let frag = &mut frags[(y - r.y0) * w + (x - r.x0)];
                if depth > frag.depth {
                    *frag = Fragment { depth, face: f as u32, weights, light };
                }
            }
        }
    }

    /// Final colour of one fragment.
    fn shade(&self, frag: &Fragment) -> [u8; 3] {
        if frag.face == NO_FACE {
            return BACKGROUND;
        }
        let base = self.surface_colour(frag.face as usize, frag.weights);
        // Non-negative, so adding 0.5 and truncating rounds (the cast saturates at 255).
        base.map(|v| (v * frag.light + 0.5) as u8)
    }

    /// Texture colour at barycentric `weights` of face `f`, or [`UNTEXTURED`].
    fn surface_colour(&self, f: usize, weights: [f64; 3]) -> [f64; 3] {
        let Some(texture) = self.texture else { return UNTEXTURED };
        let uv = self.mesh.uv_faces.get(f).and_then(|t| {
            let [a, b, c] = t.map(|i| self.mesh.uv.get(i as usize));
            Some([*a?, *b?, *c?])
        });
        let Some(uv) = uv else { return UNTEXTURED };
        texture.sample(std::array::from_fn(|k| {
            weights[0] * uv[0][k] + weights[1] * uv[1][k] + weights[2] * uv[2][k]
        }))
    }

    /// `AMBIENT + (1 - AMBIENT) |cos|` of the angle between the normal of the triangle
    /// `[a, b, c]` (pixel coordinates) and the direction to the camera. Taken from the pixel coordinates
    /// already at hand rather than the mesh's positions: in camera space the camera looks along
    /// the depth axis, and undoing the scale of x and y recovers the angle (y's flip only
    /// changes the sign of the cosine).
    fn light(&self, [a, b, c]: [[f64; 3]; 3]) -> f64 {
        let camera =
            |p: [f64; 3]| [(p[0] - a[0]) / self.scale, (p[1] - a[1]) / self.scale, p[2] - a[2]];
        let n = cross(camera(b), camera(c));
        let cos = n[2].abs() / norm(n);
        AMBIENT + (1.0 - AMBIENT) * if cos.is_finite() { cos } else { 1.0 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::mesh::Mesh;

    /// Axis-aligned square `[x0, x1] x [y0, y1]` at depth `z`, facing +z, every corner at `uv`.
    fn quad(x0: f64, y0: f64, x1: f64, y1: f64, z: f64, uv: [f64; 2]) -> UvMesh {
        let p = vec![[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]];
        UvMesh {
            mesh: Mesh::new(p, vec![[0, 1, 2], [0, 2, 3]]),
            uv: vec![uv],
            uv_faces: vec![[0; 3]; 2],
        }
    }

    /// The faces of `b` appended to those of `a`.
    fn join(a: &UvMesh, b: &UvMesh) -> UvMesh {
        let (nv, nu) = (a.mesh.positions.len() as u32, a.uv.len() as u32);
        let mut m = a.clone();
        m.mesh.positions.extend(&b.mesh.positions);
        m.mesh.faces.extend(b.mesh.faces.iter().map(|f| f.map(|v| v + nv)));
        m.uv.extend(&b.uv);
        m.uv_faces.extend(b.uv_faces.iter().map(|f| f.map(|v| v + nu)));
        m
    }

    /// 4 x 1 texture: red on the left half (u < 0.5), blue on the right, so that UVs between
    /// [`RED_UV`] and 0 (or [`BLUE_UV`] and 1) read pure colours.
    fn red_blue() -> Texture {
        Texture {
            width: 4,
            height: 1,
            rgb: vec![[255, 0, 0], [255, 0, 0], [0, 0, 255], [0, 0, 255]],
        }
    }

    const RED_UV: [f64; 2] = [0.25, 0.5];
    const BLUE_UV: [f64; 2] = [0.75, 0.5];
    const FRONT: View = View { azimuth_deg: 0.0, elevation_deg: 0.0 };

    fn at(image: &Texture, x: usize, y: usize) -> [u8; 3] {
        image.texel(x, y)
    }

    #[test]
    fn front_quad_shows_its_colour_in_the_middle_and_white_corners() {
        let m = quad(-1.0, -1.0, 1.0, 1.0, 0.0, [0.5, 0.5]);
        let t = Texture::filled(4, 4, [200, 100, 50]);
        let image = render(&m, Some(&t), 64, 64, FRONT);
        assert_eq!((image.width, image.height), (64, 64));
        assert_eq!(at(&image, 32, 32), [200, 100, 50]);
        assert_eq!(at(&image, 4, 4), [200, 100, 50]);
        for (x, y) in [(0, 0), (63, 0), (0, 63), (63, 63)] {
            assert_eq!(at(&image, x, y), [255; 3], "corner ({x}, {y})");
        }
        // 5% margin: the square spans pixels 3.2..60.8, i.e. pixel centres 3..=60.
        let covered = image.rgb.iter().filter(|&&c| c != [255; 3]).count();
        assert_eq!(covered, 58 * 58);
    }

    #[test]
    fn texture_orientation_and_aspect_are_kept() {
        // A 2:1 quad textured with red | blue, in a square image: red left, blue right, and
        // white bands above and below.
        let mut m = quad(0.0, 0.0, 2.0, 1.0, 0.0, [0.0, 0.0]);
        m.uv = vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        m.uv_faces = vec![[0, 1, 2], [0, 2, 3]];
        let image = render(&m, Some(&red_blue()), 100, 100, FRONT);
        assert_eq!(at(&image, 10, 50), [255, 0, 0]);
        assert_eq!(at(&image, 89, 50), [0, 0, 255]);
        assert_eq!(at(&image, 50, 20), [255; 3]);
        assert_eq!(at(&image, 50, 80), [255; 3]);
        // v is up: a texture whose top row is green puts green at the top of the quad.
        let t = Texture { width: 1, height: 2, rgb: vec![[0, 255, 0], [0, 0, 255]] };
        let image = render(&m, Some(&t), 100, 100, FRONT);
        assert_eq!(at(&image, 50, 28), [0, 255, 0]);
        assert_eq!(at(&image, 50, 71), [0, 0, 255]);
    }

    #[test]
    fn the_nearer_quad_wins_whatever_the_face_order() {
        let back = quad(-1.0, -1.0, 1.0, 1.0, 0.0, RED_UV);
        let front = quad(-0.5, -0.5, 0.5, 0.5, 0.5, BLUE_UV);
        let t = red_blue();
        for m in [join(&back, &front), join(&front, &back)] {
            let image = render(&m, Some(&t), 64, 64, FRONT);
            assert_eq!(at(&image, 32, 32), [0, 0, 255]);
            assert_eq!(at(&image, 8, 32), [255, 0, 0]);
            // From behind, the red quad (now nearer) hides the blue one.
            let behind =
                render(&m, Some(&t), 64, 64, View { azimuth_deg: 180.0, elevation_deg: 0.0 });
            assert_eq!(at(&behind, 32, 32), [255, 0, 0]);
        }
    }

    #[test]
    fn untextured_faces_are_grey() {
        let m = quad(-1.0, -1.0, 1.0, 1.0, 0.0, [0.5, 0.5]);
        assert_eq!(at(&render(&m, None, 16, 16, FRONT), 8, 8), [200; 3]);
        // A texture but no UV triangles.
        let bare = UvMesh { mesh: m.mesh.clone(), ..UvMesh::default() };
        assert_eq!(at(&render(&bare, Some(&red_blue()), 16, 16, FRONT), 8, 8), [200; 3]);
    }

    #[test]
    fn shading_follows_the_angle_to_the_camera() {
        // Tilted 60 degrees about y: |cos| = 1/2, so 0.35 + 0.65 / 2 of the grey.
        let (s, c) = 60f64.to_radians().sin_cos();
        let p = vec![[-c, -1.0, -s], [c, -1.0, s], [c, 1.0, s], [-c, 1.0, -s]];
        let m = UvMesh { mesh: Mesh::new(p, vec![[0, 1, 2], [0, 2, 3]]), ..UvMesh::default() };
        let expected = (200.0 * (0.35 + 0.65 * 0.5f64)).round() as u8;
        assert_eq!(at(&render(&m, None, 32, 32, FRONT), 16, 16), [expected; 3]);
        // Seen along its normal it is fully lit, from either side.
        for azimuth in [-60.0, 120.0] {
            let image = render(&m, None, 32, 32, View { azimuth_deg: azimuth, elevation_deg: 0.0 });
            assert_eq!(at(&image, 16, 16), [200; 3], "azimuth {azimuth}");
        }
    }

    #[test]
    fn views_turn_around_y_and_look_down() {
        // A quad facing +x is edge-on from the front, and full face from azimuth 90.
        let p = vec![[0.0, -1.0, 1.0], [0.0, -1.0, -1.0], [0.0, 1.0, -1.0], [0.0, 1.0, 1.0]];
        let m = UvMesh { mesh: Mesh::new(p, vec![[0, 1, 2], [0, 2, 3]]), ..UvMesh::default() };
        assert!(render(&m, None, 32, 32, FRONT).rgb.iter().all(|&c| c == [255; 3]));
        assert_eq!(
            at(&render(&m, None, 32, 32, View { azimuth_deg: 90.0, elevation_deg: 0.0 }), 16, 16),
            [200; 3]
        );
        // A floor (facing +y) seen from above; the front edge (+z) is at the bottom of the image.
        let p = vec![[-1.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 0.0, -1.0], [-1.0, 0.0, -1.0]];
        let mut floor =
            UvMesh { mesh: Mesh::new(p, vec![[0, 1, 2], [0, 2, 3]]), ..UvMesh::default() };
        floor.uv = vec![RED_UV, RED_UV, BLUE_UV, BLUE_UV];
        floor.uv_faces = vec![[0, 1, 2], [0, 2, 3]];
        let image = render(
            &floor,
            Some(&red_blue()),
            32,
            32,
            View { azimuth_deg: 0.0, elevation_deg: 90.0 },
        );
        assert_eq!(at(&image, 16, 4), [0, 0, 255]);
        assert_eq!(at(&image, 16, 27), [255, 0, 0]);
    }

    #[test]
    fn tiny_images_and_empty_or_broken_meshes_do_not_panic() {
        let m = quad(-1.0, -1.0, 1.0, 1.0, 0.0, [0.5, 0.5]);
        assert_eq!(render(&m, None, 1, 1, FRONT).rgb, vec![[200; 3]]);
        let zero = render(&m, None, 0, 0, FRONT);
        assert_eq!((zero.width, zero.height), (1, 1));
        let wide = render(&m, None, 7, 1, FRONT);
        assert_eq!(wide.rgb[3], [200; 3]);
        let empty = render(&UvMesh::default(), None, 5, 3, FRONT);
        assert_eq!(empty.rgb, vec![[255; 3]; 15]);
        let mut broken = m.clone();
        broken.mesh.faces.push([0, 1, 99]);
        broken.mesh.positions.push([f64::NAN, 0.0, 0.0]);
        broken.mesh.faces.push([0, 1, 4]);
        broken.uv_faces.push([7, 7, 7]);
        assert_eq!(
            render(&broken, Some(&red_blue()), 16, 16, FRONT),
            render(&m, Some(&red_blue()), 16, 16, FRONT)
        );
        let point =
            UvMesh { mesh: Mesh::new(vec![[1.0; 3]; 3], vec![[0, 1, 2]]), ..UvMesh::default() };
        assert!(render(&point, None, 8, 8, FRONT).rgb.iter().all(|&c| c == [255; 3]));
        let nan_view = View { azimuth_deg: f64::NAN, elevation_deg: 0.0 };
        assert!(render(&m, None, 8, 8, nan_view).rgb.iter().all(|&c| c == [255; 3]));
    }

    /// The test meshes' wavy sheet as a textured mesh.
    fn wavy_sheet(n: u32) -> UvMesh {
        let ((p, f), uv) = crate::geom::testmesh::wavy_sheet(n);
        UvMesh { mesh: Mesh::new(p, f.clone()), uv, uv_faces: f }
    }

    fn checker(size: usize) -> Texture {
        let rgb = (0..size * size).map(|k| {
            let (x, y) = (k % size, k / size);
            if (x / 8 + y / 8) % 2 == 0 {
                [230, 60, 40]
            } else {
                [40, 90, 220]
            }
        });
        Texture { width: size, height: size, rgb: rgb.collect() }
    }

    #[test]
    fn closed_sheet_has_no_cracks_and_threads_do_not_matter() {
        let m = wavy_sheet(60);
        let t = checker(64);
        let view = View { azimuth_deg: 20.0, elevation_deg: 15.0 };
        let run = |threads| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
            pool.install(|| render(&m, Some(&t), 200, 150, view))
        };
        let one = run(1);
        assert_eq!(one, run(3));
        // Looking straight at it, every pixel inside the sheet's outline is covered.
        let image = render(&m, Some(&t), 200, 200, FRONT);
        let inside = (15..185).flat_map(|y| (15..185).map(move |x| (x, y)));
        let holes = inside.filter(|&(x, y)| at(&image, x, y) == [255; 3]).count();
        assert_eq!(holes, 0);
    }
}
