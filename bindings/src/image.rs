//! Texture images for `dynmesh.io`: `dynmesh_meshio::png_image` on numpy arrays, with the
//! GIL released so that a writer thread overlaps the encoding with the decoding of the next
//! frame.

use std::path::PathBuf;

use numpy::ndarray::Array3;
use numpy::{IntoPyArray, PyArray3, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyBytes;

use dynmesh_meshio::atomic_write::write_atomically;
use dynmesh_meshio::png_image::{decode_rgb8, encode_rgb8};

use crate::decode_files::io_error;
use crate::errors::released;

/// Adds the image functions to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(encode_png, m)?)?;
    m.add_function(wrap_pyfunction!(write_png, m)?)?;
    m.add_function(wrap_pyfunction!(read_png, m)?)?;
    Ok(())
}

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

fn encoding_error(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(format!("cannot encode PNG: {e}"))
}

/// The PNG file of an (H, W, 3) uint8 RGB image (lossless), as bytes.
#[pyfunction]
fn encode_png<'py>(py: Python<'py>, image: PyReadonlyArray3<'py, u8>) -> PyResult<Bound<'py, PyBytes>> {
    let (w, h, rgb) = rgb_rows(&image)?;
    let bytes = released(py, || encode_rgb8(w, h, &rgb))?.map_err(encoding_error)?;
    Ok(PyBytes::new(py, &bytes))
}

/// Writes an (H, W, 3) uint8 RGB image as PNG to `path`, atomically: a temporary file beside
/// it, synced, then renamed into place (removed on failure). Raises OSError naming `path`.
#[pyfunction]
fn write_png(py: Python<'_>, path: PathBuf, image: PyReadonlyArray3<'_, u8>) -> PyResult<()> {
    let (w, h, rgb) = rgb_rows(&image)?;
    released(py, || {
        let bytes = encode_rgb8(w, h, &rgb).map_err(encoding_error)?;
        write_atomically(&path, &[bytes]).map_err(|e| io_error(&path, e))
    })?
}

/// The (H, W, 3) uint8 RGB pixels of a PNG file's bytes, rows from the top, or None when
/// this reader leaves the file to Pillow (16-bit samples, animations, oversized or
/// malformed files).
#[pyfunction]
fn read_png<'py>(py: Python<'py>, data: &[u8]) -> PyResult<Option<Bound<'py, PyArray3<u8>>>> {
    let Some((w, h, rgb)) = released(py, || decode_rgb8(data))? else { return Ok(None) };
    let array = Array3::from_shape_vec((h as usize, w as usize, 3), rgb).expect("shape");
    Ok(Some(array.into_pyarray(py)))
}
