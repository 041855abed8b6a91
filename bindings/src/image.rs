//! Texture images for `dynmesh.io`: PNG encoded and decoded with the GIL released.
//!
//! A textured `dynmesh decode` writes one PNG per frame. Pillow (zlib level 1) took 64 ms
//! of CPU to encode a decoded 1024 x 1024 texture, holding the GIL, after copying the array
//! into an image of its own. Here the `png` crate encodes it in 9 ms (adaptive row filters,
//! its fdeflate compressor: lossless, and 3 % smaller than Pillow's file on liam_textured),
//! and `write_png` writes it atomically without the GIL, so that a writer thread overlaps
//! it with the decoding of the next frame.
//!
//! Reading decodes 8-bit PNGs (any colour type, palettes and transparency expanded, alpha
//! dropped: what Pillow's `convert("RGB")` gives) in a third of Pillow's time; for anything
//! else (16-bit samples, an animation, a file the crate refuses) `read_png` answers None and
//! `dynmesh.io` reads the file with Pillow, which keeps Pillow's result and its error
//! messages for those.

use std::io::Cursor;
use std::path::PathBuf;

use numpy::ndarray::Array3;
use numpy::{IntoPyArray, PyArray3, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyBytes;

use crate::decode_files::{io_error, write_atomically};

/// Adds the image functions to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(encode_png, m)?)?;
    m.add_function(wrap_pyfunction!(write_png, m)?)?;
    m.add_function(wrap_pyfunction!(read_png, m)?)?;
    Ok(())
}

/// Largest side of an image read here; larger ones go to Pillow (and its decompression bomb check).
const MAX_READ_SIDE: u32 = 16384;

/// The rows of an (H, W, 3) uint8 array, contiguous (copied only when the array is not).
fn rgb_rows<'a>(image: &'a PyReadonlyArray3<'_, u8>) -> PyResult<(u32, u32, std::borrow::Cow<'a, [u8]>)> {
    let shape = image.shape();
    if shape[2] != 3 || shape[0] == 0 || shape[1] == 0 {
        return Err(PyValueError::new_err(format!("expected an (H, W, 3) uint8 image, got shape {shape:?}")));
    }
    let (h, w) = (u32::try_from(shape[0]), u32::try_from(shape[1]));
    let (Ok(h), Ok(w)) = (h, w) else {
        return Err(PyValueError::new_err(format!("image of shape {shape:?} is too large for PNG")));
    };
    // A Fortran-ordered array is contiguous too, but not in row order: only C order is borrowed.
    let data = match image.as_slice().ok().filter(|_| image.is_c_contiguous()) {
        Some(s) => std::borrow::Cow::Borrowed(s),
        None => std::borrow::Cow::Owned(image.as_array().iter().copied().collect()),
    };
    Ok((w, h, data))
}

/// PNG bytes of `width` x `height` RGB rows: 8-bit, adaptive row filters, fdeflate.
pub(crate) fn png_bytes(width: u32, height: u32, rgb: &[u8]) -> Result<Vec<u8>, png::EncodingError> {
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

fn encoding_error(e: png::EncodingError) -> PyErr {
    PyValueError::new_err(format!("cannot encode PNG: {e}"))
}

/// The PNG file of an (H, W, 3) uint8 RGB image (lossless), as bytes.
#[pyfunction]
fn encode_png<'py>(py: Python<'py>, image: PyReadonlyArray3<'py, u8>) -> PyResult<Bound<'py, PyBytes>> {
    let (w, h, rgb) = rgb_rows(&image)?;
    let bytes = py.allow_threads(|| png_bytes(w, h, &rgb)).map_err(encoding_error)?;
    Ok(PyBytes::new(py, &bytes))
}

/// Writes an (H, W, 3) uint8 RGB image as PNG to `path`, atomically: a temporary file beside
/// it, synced, then renamed into place (removed on failure). Raises OSError naming `path`.
#[pyfunction]
fn write_png(py: Python<'_>, path: PathBuf, image: PyReadonlyArray3<'_, u8>) -> PyResult<()> {
    let (w, h, rgb) = rgb_rows(&image)?;
    py.allow_threads(|| {
        let bytes = png_bytes(w, h, &rgb).map_err(encoding_error)?;
        write_atomically(&path, &[bytes]).map_err(|e| io_error(&path, e))
    })
}

/// The (H, W, 3) uint8 RGB pixels of a PNG file's bytes, rows from the top, or None when
/// this reader leaves the file to Pillow (16-bit samples, animations, oversized or
/// malformed files).
#[pyfunction]
fn read_png<'py>(py: Python<'py>, data: &[u8]) -> Option<Bound<'py, PyArray3<u8>>> {
    let (w, h, rgb) = py.allow_threads(|| decode_rgb8(data))?;
    let array = Array3::from_shape_vec((h as usize, w as usize, 3), rgb).expect("shape");
    Some(array.into_pyarray(py))
}

/// (width, height, RGB rows) of an 8-bit PNG, or None.
fn decode_rgb8(data: &[u8]) -> Option<(u32, u32, Vec<u8>)> {
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
        let bytes = png_bytes(w, h, &rgb).unwrap();
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
