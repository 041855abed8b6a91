//! Textures and textured meshes: the types every texture stage shares (this file), the
//! lossless coding of an intra frame's atlas ([`uvcoder`], over [`uv_corners`] and
//! [`uv_prediction`]), the transfer of the input texture onto the reconstructed mesh's atlas
//! ([`transfer`]) and the push-pull padding of its gutters ([`pad`]).
//!
//! Conventions (those of OBJ and PNG): a texture is stored row by row from the *top* of the
//! image; texture coordinates have `u` to the right and `v` *up*, both in [0, 1]. Texel
//! `(x, y)` (column, row from the top) has its centre at `u = (x + 0.5) / width`,
//! `v = 1 - (y + 0.5) / height`.

pub mod uv_corners;
pub mod uv_state;
pub mod uv_prediction;
pub mod uvcoder;
pub mod transfer;
pub mod pad;

use rayon::prelude::*;

use crate::geom::mesh::Mesh;

/// An RGB image, 8 bits per channel, rows from the top.
#[derive(Debug, Clone, PartialEq)]
pub struct Texture {
    pub width: usize,
    pub height: usize,
    /// `width * height` texels, row-major from the top.
    pub rgb: Vec<[u8; 3]>,
}

impl Texture {
    /// A texture of one colour. Panics if either side is zero.
    pub fn filled(width: usize, height: usize, colour: [u8; 3]) -> Self {
        assert!(width > 0 && height > 0, "texture of zero size");
        Self { width, height, rgb: vec![colour; width * height] }
    }

    /// The texel at column `x`, row `y` (from the top).
    #[inline]
    pub fn texel(&self, x: usize, y: usize) -> [u8; 3] {
        self.rgb[y * self.width + x]
    }

    /// Bilinear lookup at texture coordinate `uv` (channels 0-255, not rounded). Coordinates
    /// outside [0, 1] are clamped to the border texels (a mesh's UVs may overshoot a little
    /// after quantization); a NaN coordinate reads texel (0, 0).
    pub fn sample(&self, uv: [f64; 2]) -> [f64; 3] {
        let fx = (uv[0] * self.width as f64 - 0.5).clamp(0.0, (self.width - 1) as f64);
        let fy = ((1.0 - uv[1]) * self.height as f64 - 0.5).clamp(0.0, (self.height - 1) as f64);
        let (fx, fy) = (if fx.is_nan() { 0.0 } else { fx }, if fy.is_nan() { 0.0 } else { fy });
        let (x0, y0) = (fx.floor() as usize, fy.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(self.width - 1), (y0 + 1).min(self.height - 1));
        let (tx, ty) = (fx - x0 as f64, fy - y0 as f64);
        let (a, b, c, d) = (self.texel(x0, y0), self.texel(x1, y0), self.texel(x0, y1), self.texel(x1, y1));
        std::array::from_fn(|k| {
            let top = a[k] as f64 * (1.0 - tx) + b[k] as f64 * tx;
            let bottom = c[k] as f64 * (1.0 - tx) + d[k] as f64 * tx;
            top * (1.0 - ty) + bottom * ty
        })
    }
}

/// A triangle mesh with texture coordinates kept apart from positions, as OBJ keeps them:
/// `uv_faces[f]` gives the UV index of each corner of `faces[f]`, so a vertex on a seam of the
/// atlas has one position and several UVs.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct UvMesh {
    pub mesh: Mesh,
    pub uv: Vec<[f64; 2]>,
    /// Same length as `mesh.faces`.
    pub uv_faces: Vec<[u32; 3]>,
}

impl UvMesh {
    /// Checks what every texture stage relies on: a valid mesh, one UV triangle per face,
    /// UV indices in range and finite UVs. Returns a message naming the first problem.
    pub fn validate(&self) -> Result<(), String> {
        self.mesh.validate().map_err(|e| e.to_string())?;
        if self.uv_faces.len() != self.mesh.faces.len() {
            return Err(format!("{} UV faces for {} faces", self.uv_faces.len(), self.mesh.faces.len()));
        }
        if let Some((f, _)) = self.uv_faces.iter().enumerate().find(|(_, t)| t.iter().any(|&i| i as usize >= self.uv.len())) {
            return Err(format!("UV face {f} refers to a UV index >= {}", self.uv.len()));
        }
        if let Some(i) = self.uv.iter().position(|p| !p[0].is_finite() || !p[1].is_finite()) {
            return Err(format!("UV {i} is not finite"));
        }
        Ok(())
    }
}

// BT.709: Y = KR R + KG G + KB B, Cb = (B - Y) / CB_SCALE, Cr = (R - Y) / CR_SCALE.
const KR: f64 = 0.2126;
const KG: f64 = 0.7152;
const KB: f64 = 0.0722;
const CB_SCALE: f64 = 1.8556;
const CR_SCALE: f64 = 1.5748;

/// BT.709 Y, Cb, Cr in [0, 1] (full range, Cb and Cr centred on 0.5) of an RGB colour with
/// channels in [0, 255]: the colour space of the texture PSNR in the common test conditions.
pub fn ycbcr709(rgb: [f64; 3]) -> [f64; 3] {
    let [r, g, b] = rgb.map(|c| c / 255.0);
    let y = KR * r + KG * g + KB * b;
    [y, (b - y) / CB_SCALE + 0.5, (r - y) / CR_SCALE + 0.5]
}

/// Full scale of the 10-bit planes of the texture video.
const PEAK_10BIT: f64 = 1023.0;

/// The texture as the video codes it: FFmpeg's `yuv420p10le` layout, full-range 10-bit
/// BT.709 (`ycbcr709`) Y for every texel, then the Cb and Cr planes, each the mean over 2 x 2
/// texels. `width * height * 3 / 2` samples. Panics unless both sides are even.
pub fn yuv420_10bit(t: &Texture) -> Vec<u16> {
    assert!(t.width % 2 == 0 && t.height % 2 == 0, "4:2:0 needs even sides, not {}x{}", t.width, t.height);
    let (w, h) = (t.width, t.height);
    // Adding a half and truncating rounds the non-negative values exactly as `round` would, and
    // compiles to a few instructions instead of a libm call per sample.
    let level = |v: f64| (v * PEAK_10BIT + 0.5).clamp(0.0, PEAK_10BIT) as u16;
    let mut out = vec![0u16; w * h * 3 / 2];
    let (luma, chroma) = out.split_at_mut(w * h);
    let (cb, cr) = chroma.split_at_mut(w * h / 4);
    // One pass per 2 x 2 block: its four lumas and the mean of their chroma.
    luma.par_chunks_mut(2 * w).zip(cb.par_chunks_mut(w / 2)).zip(cr.par_chunks_mut(w / 2)).enumerate().for_each(
        |(y, ((luma_rows, cb_row), cr_row))| {
            for x in 0..w / 2 {
                let mut sum = [0.0; 2];
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let c = ycbcr709(t.texel(2 * x + dx, 2 * y + dy).map(f64::from));
                    luma_rows[dy * w + 2 * x + dx] = level(c[0]);
                    sum = [sum[0] + c[1], sum[1] + c[2]];
                }
                cb_row[x] = level(sum[0] / 4.0);
                cr_row[x] = level(sum[1] / 4.0);
            }
        },
    );
    out
}

/// The RGB texture of `yuv420_10bit` planes (`width * height * 3 / 2` samples, both sides
/// even), each chroma sample used for its 2 x 2 texels; the inverse of `ycbcr709`, rounded.
/// Returns an error naming the mismatch when the plane sizes do not fit the sides.
pub fn rgb_of_yuv420_10bit(planes: &[u16], width: usize, height: usize) -> Result<Texture, String> {
    if width == 0 || height == 0 || width % 2 != 0 || height % 2 != 0 || planes.len() != width * height * 3 / 2 {
        return Err(format!("{} samples are not the 4:2:0 planes of a {width}x{height} image", planes.len()));
    }
    let (luma, chroma) = planes.split_at(width * height);
    let (cb, cr) = chroma.split_at(width * height / 4);
    let byte = |v: f64| (v * 255.0 + 0.5).clamp(0.0, 255.0) as u8; // rounds, see `yuv420_10bit`
    let mut rgb = vec![[0u8; 3]; width * height];
    rgb.par_chunks_mut(width).enumerate().for_each(|(y, row)| {
        for (x, texel) in row.iter_mut().enumerate() {
            let c = (y / 2) * (width / 2) + x / 2;
            let l = luma[y * width + x] as f64 / PEAK_10BIT;
            let (u, v) = (cb[c] as f64 / PEAK_10BIT - 0.5, cr[c] as f64 / PEAK_10BIT - 0.5);
            let (r, b) = (l + CR_SCALE * v, l + CB_SCALE * u);
            let g = (l - KR * r - KB * b) / KG;
            *texel = [byte(r), byte(g), byte(b)];
        }
    });
    Ok(Texture { width, height, rgb })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sample_hits_texel_centres_and_interpolates_between_them() {
        let mut t = Texture::filled(2, 2, [0, 0, 0]);
        t.rgb[1] = [200, 0, 0]; // top right
        assert_eq!(t.sample([0.75, 0.75]), [200.0, 0.0, 0.0]);
        assert_eq!(t.sample([0.25, 0.75]), [0.0, 0.0, 0.0]);
        assert_eq!(t.sample([0.5, 0.75]), [100.0, 0.0, 0.0]);
        // Clamped outside the image, and below the top row's centre only the bottom row counts.
        assert_eq!(t.sample([2.0, 2.0]), [200.0, 0.0, 0.0]);
        assert_eq!(t.sample([0.75, 0.0]), [0.0, 0.0, 0.0]);
        assert_eq!(t.sample([f64::NAN, 0.75]), [0.0, 0.0, 0.0]);
    }

    #[test]
    fn ycbcr_of_white_grey_and_primaries() {
        let close = |a: [f64; 3], b: [f64; 3]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-9);
        assert!(close(ycbcr709([255.0; 3]), [1.0, 0.5, 0.5]));
        assert!(close(ycbcr709([0.0; 3]), [0.0, 0.5, 0.5]));
        assert!(close(ycbcr709([0.0, 0.0, 255.0]), [0.0722, 1.0, 0.5 - 0.0722 / 1.5748]));
        assert!(close(ycbcr709([255.0, 0.0, 0.0]), [0.2126, 0.5 - 0.2126 / 1.8556, 1.0]));
    }

    #[test]
    fn validate_names_the_problem() {
        let mesh = Mesh::new(vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], vec![[0, 1, 2]]);
        let good = UvMesh { mesh: mesh.clone(), uv: vec![[0.0; 2], [1.0, 0.0], [0.0, 1.0]], uv_faces: vec![[0, 1, 2]] };
        assert!(good.validate().is_ok());
        let short = UvMesh { uv_faces: vec![], ..good.clone() };
        assert!(short.validate().unwrap_err().contains("UV faces"));
        let out = UvMesh { uv_faces: vec![[0, 1, 3]], ..good.clone() };
        assert!(out.validate().unwrap_err().contains("UV index"));
        let nan = UvMesh { uv: vec![[0.0; 2], [f64::NAN, 0.0], [0.0, 1.0]], ..good };
        assert!(nan.validate().unwrap_err().contains("not finite"));
    }

    #[test]
    fn yuv420_round_trip_keeps_flat_colours_and_averages_chroma() {
        let mut t = Texture::filled(4, 2, [30, 140, 220]);
        let back = rgb_of_yuv420_10bit(&yuv420_10bit(&t), 4, 2).unwrap();
        assert!(back.rgb.iter().all(|c| c.iter().zip([30, 140, 220]).all(|(a, b)| (*a as i32 - b).abs() <= 1)), "{back:?}");
        // Grey has neutral chroma (512); a 2x2 block of black and white averages its luma apart.
        t = Texture::filled(2, 2, [0, 0, 0]);
        t.rgb[0] = [255, 255, 255];
        let planes = yuv420_10bit(&t);
        assert_eq!(planes, vec![1023, 0, 0, 0, 512, 512]);
        assert_eq!(rgb_of_yuv420_10bit(&planes, 2, 2).unwrap().rgb, vec![[255; 3], [0; 3], [0; 3], [0; 3]]);
        assert!(rgb_of_yuv420_10bit(&planes, 4, 2).unwrap_err().contains("4x2"));
        assert!(rgb_of_yuv420_10bit(&planes, 3, 2).is_err());
    }
}
