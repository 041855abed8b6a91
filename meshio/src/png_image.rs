//! Texture images as PNG: a textured `dynmesh decode` writes one per frame, and reading one
//! is on the path of every textured encode.
//!
//! Pillow (zlib level 1) took 64 ms of CPU to encode a decoded 1024 x 1024 texture, holding
//! the GIL, after copying the array into an image of its own. The `png` crate encodes it in
//! 9 ms (adaptive row filters, its fdeflate compressor: lossless, and 3 % smaller than
//! Pillow's file on liam_textured), so that the bindings' writer thread overlaps it with the
//! decoding of the next frame.
//!
//! Reading decodes 8-bit PNGs (any colour type, palettes and transparency expanded, alpha
//! dropped: what Pillow's `convert("RGB")` gives) in a third of Pillow's time; for anything
//! else (16-bit samples, an animation, a file the crate refuses) [`decode_rgb8`] answers
//! None and `dynmesh.io` reads the file with Pillow, which keeps Pillow's result and its
//! error messages for those.

use std::io::Cursor;

/// Largest side of an image read here; larger ones go to Pillow (and its decompression bomb check).
const MAX_READ_SIDE: u32 = 16384;

/// PNG bytes of `width` x `height` RGB pixels (`rgb`: rows from the top, 3 bytes a pixel,
/// `3 * width * height` bytes): 8-bit, adaptive row filters, fdeflate.
///
/// Errors: what the `png` crate refuses (a zero side, `rgb` of the wrong length).
pub fn encode_rgb8(width: u32, height: u32, rgb: &[u8]) -> Result<Vec<u8>, png::EncodingError> {
    let mut out = Vec::with_capacity(rgb.len() / 2 + 1024);
    let mut encoder = png::Encoder::new(&mut out, width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_compression(png::Compression::Fast);
    let mut writer = encoder.write_header()?;
    writer.write_image_data(rgb)?;
    writer.finish()?;
    Ok(out)
}

/// (width, height, RGB pixels rows from the top) of an 8-bit PNG file's bytes, or None when
/// this reader leaves the file to Pillow: 16-bit samples, animations, sides over 16384,
/// malformed files.
pub fn decode_rgb8(data: &[u8]) -> Option<(u32, u32, Vec<u8>)> {
    let mut options = png::DecodeOptions::default();
    options.set_ignore_text_chunk(true);
    options.set_ignore_iccp_chunk(true);
    let mut decoder = png::Decoder::new_with_options(Cursor::new(data), options);
    decoder.set_limits(png::Limits { bytes: 1 << 30 });
    decoder.set_transformations(png::Transformations::EXPAND);
    let header = decoder.read_header_info().ok()?;
    if header.bit_depth == png::BitDepth::Sixteen || header.width > MAX_READ_SIDE || header.height > MAX_READ_SIDE {
        return None;
    }
    let mut reader = decoder.read_info().ok()?;
    if reader.info().animation_control.is_some() {
        return None;
    }
    let mut buf = vec![0; reader.output_buffer_size()?];
    let frame = reader.next_frame(&mut buf).ok()?;
    let (w, h) = (frame.width, frame.height);
    let pixels = (w as usize) * (h as usize);
    let channels = match frame.color_type {
        png::ColorType::Grayscale => 1,
        png::ColorType::GrayscaleAlpha => 2,
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        png::ColorType::Indexed => return None, // expanded above; never here
    };
    if frame.bit_depth != png::BitDepth::Eight || frame.line_size != w as usize * channels {
        return None;
    }
    buf.truncate(pixels * channels);
    let rgb = match channels {
        3 => buf,
        4 => buf.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect(),
        _ => buf.chunks_exact(channels).flat_map(|p| [p[0]; 3]).collect(),
    };
    Some((w, h, rgb))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn png_round_trips_losslessly() {
        let (w, h) = (37u32, 23u32);
        let rgb: Vec<u8> = (0..w * h * 3).map(|i| (i * 7 % 251) as u8).collect();
        let bytes = encode_rgb8(w, h, &rgb).unwrap();
        assert_eq!(decode_rgb8(&bytes), Some((w, h, rgb)));
    }

    #[test]
    fn sixteen_bit_and_garbage_are_left_to_pillow() {
        let mut out = Vec::new();
        let mut e = png::Encoder::new(&mut out, 2, 2);
        e.set_color(png::ColorType::Rgb);
        e.set_depth(png::BitDepth::Sixteen);
        let mut w = e.write_header().unwrap();
        w.write_image_data(&[0; 24]).unwrap();
        w.finish().unwrap();
        assert_eq!(decode_rgb8(&out), None);
        assert_eq!(decode_rgb8(b"\x89PNG\r\n\x1a\nnot a png"), None);
    }
}
