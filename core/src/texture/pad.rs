//! Push-pull padding of a texture atlas's gutters.
//!
//! The texels no chart covers are filled with smooth colour, because a video coder spends
//! many bits on the sharp edges between charts and an untouched (black) gutter.

use rayon::prelude::*;

use crate::texture::Texture;

/// Fills the texels of `texture` that are not `covered` (one flag per texel, row-major from
/// the top, as [`crate::texture::transfer::Transferred::covered`]) by push-pull, leaving covered texels unchanged.
///
/// Push: a pyramid of ever coarser images (each side halved, rounding up, down to 1 x 1), each
/// texel the mean of the covered full-resolution texels beneath it. Pull: from the coarsest
/// level up, every texel with nothing covered beneath it takes the bilinear upsampling of the
/// level below it. The gutters thus continue the charts' colours smoothly and fade towards the
/// mean colour of the neighbourhood, which a video coder codes cheaply. Any size works.
///
/// If no texel is covered there is nothing to spread and the texture is left as it is.
/// Panics if `covered.len()` is not `width * height`.
pub fn pad(texture: &mut Texture, covered: &[bool]) {
    assert_eq!(covered.len(), texture.rgb.len(), "one coverage flag per texel");
    if covered.iter().all(|&c| c) || !covered.contains(&true) {
        return;
    }
    let (rgb, w) = (&texture.rgb, texture.width);
    // Full-resolution texels weigh 1 or 0: adding the colour is adding it times its weight.
    let mut levels = vec![reduce(w, texture.height, |i, sum, total| {
        if covered[i] {
            (0..3).for_each(|k| sum[k] += f32::from(rgb[i][k]));
            *total += 1.0;
        }
    })];
    while let Some(last) = levels.last().filter(|l| l.width > 1 || l.height > 1) {
        let next = reduce(last.width, last.height, |i, sum, total| {
            let (c, wt) = (last.colour[i], last.weight[i]);
            if wt > 0.0 {
                (0..3).for_each(|k| sum[k] += c[k] * wt);
                *total += wt;
            }
        });
        levels.push(next);
    }
    for k in (0..levels.len() - 1).rev() {
        let (fine, coarse) = levels.split_at_mut(k + 1);
        fill_level(&mut fine[k], &coarse[0]);
    }
    fill_texture(texture, covered, &levels[0]);
}

/// One level of the push-pull pyramid.
struct Level {
    width: usize,
    height: usize,
    colour: Vec<[f32; 3]>,
    /// Covered full-resolution texels beneath each texel; 0 means the colour is yet unknown.
    weight: Vec<f32>,
}

impl Level {
    /// Calls `fill(x, colour)` for each texel `x` of row `y` of the level above (twice the
    /// size) that `wanted` says, with the colour at its centre interpolated bilinearly.
    fn upsample_row(&self, y: usize, width: usize, mut wanted: impl FnMut(usize) -> bool, mut fill: impl FnMut(usize, [f32; 3])) {
        let (y0, y1, ty) = taps(y, self.height);
        let (r0, r1) = (&self.colour[y0 * self.width..][..self.width], &self.colour[y1 * self.width..][..self.width]);
        for x in 0..width {
            if !wanted(x) {
                continue;
            }
            let (x0, x1, tx) = taps(x, self.width);
            let (a, b, c, d) = (r0[x0], r0[x1], r1[x0], r1[x1]);
            fill(
                x,
                std::array::from_fn(|k| {
                    let top = a[k] + (b[k] - a[k]) * tx;
                    let bottom = c[k] + (d[k] - c[k]) * tx;
                    top + (bottom - top) * ty
                }),
            );
        }
    }
}

/// The two texels of a coarse row (of `n`) that fine texel `i` interpolates between, and the
/// weight of the second: the fine centre lies a quarter of a coarse texel from the centre of
/// its parent `i / 2`, towards the neighbour on its side (clamped at the border).
fn taps(i: usize, n: usize) -> (usize, usize, f32) {
    let j = i / 2;
    match (i % 2, j) {
        (0, 0) => (0, 0, 0.0),
        (0, _) => (j - 1, j, 0.75),
        _ if j + 1 < n => (j, j + 1, 0.25),
        _ => (j, j, 0.0),
    }
}

/// The next coarser level of a `width` x `height` level: each texel is the weighted mean of
/// its (up to) four children, which `add(i, sum, total)` adds (`i` the child's index in its
/// level), in row-major order.
fn reduce(width: usize, height: usize, add: impl Fn(usize, &mut [f32; 3], &mut f32) + Sync) -> Level {
    let (w, h) = (width.div_ceil(2), height.div_ceil(2));
    let mut colour = vec![[0.0f32; 3]; w * h];
    let mut weight = vec![0.0f32; w * h];
    colour.par_chunks_mut(w).zip(weight.par_chunks_mut(w)).enumerate().for_each(|(y, (crow, wrow))| {
        let top = 2 * y * width;
        let bottom = (2 * y + 1 < height).then_some(top + width);
        for x in 0..w {
            let (mut sum, mut total) = ([0.0f32; 3], 0.0f32);
            let right = 2 * x + 1 < width;
            for row in [Some(top), bottom].into_iter().flatten() {
                add(row + 2 * x, &mut sum, &mut total);
                if right {
                    add(row + 2 * x + 1, &mut sum, &mut total);
                }
            }
            if total > 0.0 {
                crow[x] = sum.map(|s| s / total);
                wrow[x] = total;
            }
        }
    });
    Level { width: w, height: h, colour, weight }
}

/// Gives the texels of `fine` that have no colour yet the colour of `coarse`, already filled.
fn fill_level(fine: &mut Level, coarse: &Level) {
    let w = fine.width;
    fine.colour.par_chunks_mut(w).zip(fine.weight.par_chunks(w)).enumerate().for_each(|(y, (row, weights))| {
        coarse.upsample_row(y, w, |x| weights[x] == 0.0, |x, c| row[x] = c);
    });
}

fn fill_texture(texture: &mut Texture, covered: &[bool], coarse: &Level) {
    let w = texture.width;
    texture.rgb.par_chunks_mut(w).zip(covered.par_chunks(w)).enumerate().for_each(|(y, (row, cov))| {
        coarse.upsample_row(y, w, |x| !cov[x], |x, c| row[x] = c.map(round_channel));
    });
}

/// `v.round().clamp(0.0, 255.0) as u8`, without the library call `f32::round` costs on
/// baseline x86-64: clamped first (which changes no result), the value is non-negative (or
/// NaN, which both map to 0), so it rounds half away from zero by its fraction, exactly.
fn round_channel(v: f32) -> u8 {
    let v = v.clamp(0.0, 255.0);
    let t = v as u8;
    if v - f32::from(t) >= 0.5 { t + 1 } else { t }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::testmesh::Rng;

    /// A texture of pseudo-random colours: any misplaced texel shows.
    fn noise(width: usize, height: usize, seed: u64) -> Texture {
        let mut rng = Rng(seed);
        let rgb = (0..width * height).map(|_| [0; 3].map(|_: u8| (rng.unit() * 256.0) as u8)).collect();
        Texture { width, height, rgb }
    }

    #[test]
    fn channels_round_as_round_then_clamp() {
        let mut values = vec![f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -0.0, f32::MAX, f32::MIN_POSITIVE];
        // Every value near each half and each integer, a few steps of the float either side.
        for n in -2..=260 {
            for x in [n as f32, n as f32 + 0.5] {
                let mut v = x;
                for _ in 0..4 {
                    v = f32::from_bits(v.to_bits().wrapping_sub(1));
                }
                for _ in 0..9 {
                    values.push(v);
                    v = f32::from_bits(v.to_bits().wrapping_add(1));
                }
            }
        }
        let mut rng = Rng(7);
        values.extend((0..100_000).map(|_| rng.range(-10.0, 270.0) as f32));
        for v in values {
            assert_eq!(round_channel(v), v.round().clamp(0.0, 255.0) as u8, "{v} ({:#x})", v.to_bits());
        }
    }

    #[test]
    fn pad_keeps_covered_texels_and_fills_the_rest_within_their_range() {
        for (w, h) in [(37, 23), (1, 9), (64, 64), (5, 1)] {
            let mut tex = noise(w, h, 3);
            let mut rng = Rng(w as u64 * 31 + h as u64);
            let covered: Vec<bool> = (0..w * h).map(|i| i == w * h / 2 || rng.unit() < 0.2).collect();
            let before = tex.clone();
            for (c, &k) in tex.rgb.iter_mut().zip(&covered) {
                if !k {
                    *c = [0, 0, 0];
                }
            }
            pad(&mut tex, &covered);
            let (lo, hi) = covered.iter().zip(&before.rgb).filter(|(&k, _)| k).fold(([255u8; 3], [0u8; 3]), |(lo, hi), (_, c)| {
                ([0, 1, 2].map(|k| lo[k].min(c[k])), [0, 1, 2].map(|k| hi[k].max(c[k])))
            });
            for (i, (&k, c)) in covered.iter().zip(&tex.rgb).enumerate() {
                if k {
                    assert_eq!(*c, before.rgb[i]);
                } else {
                    assert!((0..3).all(|j| (lo[j]..=hi[j]).contains(&c[j])), "{w}x{h} texel {i}: {c:?}");
                }
            }
        }
    }

    #[test]
    fn pad_spreads_a_uniform_colour_everywhere() {
        let (w, h) = (45, 30);
        let mut tex = Texture::filled(w, h, [0, 0, 0]);
        let covered: Vec<bool> = (0..w * h).map(|i| (i % w) > 30 && (i / w) < 7).collect();
        for (c, &k) in tex.rgb.iter_mut().zip(&covered) {
            if k {
                *c = [200, 17, 93];
            }
        }
        pad(&mut tex, &covered);
        assert!(tex.rgb.iter().all(|&c| c == [200, 17, 93]));
        // Nothing covered: nothing to spread, nothing changes; a single texel spreads anywhere.
        let mut none = noise(7, 3, 2);
        let copy = none.clone();
        pad(&mut none, &[false; 21]);
        assert_eq!(none, copy);
        let mut one = Texture::filled(6, 11, [0, 0, 0]);
        one.rgb[65] = [1, 2, 3];
        let mut covered = vec![false; 66];
        covered[65] = true;
        pad(&mut one, &covered);
        assert!(one.rgb.iter().all(|&c| c == [1, 2, 3]));
    }

    #[test]
    fn pad_gutters_fade_smoothly_to_the_mean_colour() {
        // A horizontal ramp (0, 4, .., 124) covered on its left half: the gutter on the right
        // starts near the chart's edge colour, falls without ringing, and ends at the mean (62).
        let (w, h) = (64, 16);
        let mut tex = Texture::filled(w, h, [0; 3]);
        let covered: Vec<bool> = (0..w * h).map(|i| i % w < 32).collect();
        for (i, c) in tex.rgb.iter_mut().enumerate() {
            if covered[i] {
                *c = [(4 * (i % w)) as u8, 0, 0];
            }
        }
        pad(&mut tex, &covered);
        let row: Vec<i32> = (31..w).map(|x| tex.texel(x, 8)[0] as i32).collect();
        assert!(row[0] - row[1] < 124 / 4, "jump at the chart edge: {row:?}");
        assert!(row.windows(2).all(|p| p[1] <= p[0]), "{row:?}");
        assert_eq!(row[row.len() - 1], 62);
    }
}
