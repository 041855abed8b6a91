//! Python binding of the texture transfer: the input frame's texture re-sampled onto the
//! atlas of the reconstructed mesh, padded for video coding.

use numpy::ndarray::Array3;
use numpy::{IntoPyArray, PyArray3, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::colour::{texture_of, valid_uv_mesh};

/// Largest atlas side accepted (keeps a typo from allocating gigabytes).
const MAX_SIDE: usize = 16384;

/// Adds the transfer function to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(transfer_texture, m)?)?;
    Ok(())
}

/// The texture of `source` (its mesh, per-corner UVs and (H, W, 3) uint8 texture) transferred
/// onto the atlas of `target` (its mesh and per-corner UVs) as a `width` x `height` image: every
/// texel that a target UV triangle covers takes the colour of the closest point of the source
/// surface; with `pad` the others are filled by push-pull. Returns (image (height, width, 3)
/// uint8, fraction of texels covered). Raises ValueError for inconsistent arrays.
#[pyfunction]
#[pyo3(signature = (
    target_positions, target_faces, target_uv, target_uv_faces,
    source_positions, source_faces, source_uv, source_uv_faces, source_texture,
    width, height, pad=true
))]
#[allow(clippy::too_many_arguments)]
fn transfer_texture<'py>(
    py: Python<'py>,
    target_positions: PyReadonlyArray2<'py, f64>,
    target_faces: PyReadonlyArray2<'py, i64>,
    target_uv: PyReadonlyArray2<'py, f64>,
    target_uv_faces: PyReadonlyArray2<'py, i64>,
    source_positions: PyReadonlyArray2<'py, f64>,
    source_faces: PyReadonlyArray2<'py, i64>,
    source_uv: PyReadonlyArray2<'py, f64>,
    source_uv_faces: PyReadonlyArray2<'py, i64>,
    source_texture: PyReadonlyArray3<'py, u8>,
    width: usize,
    height: usize,
    pad: bool,
) -> PyResult<(Bound<'py, PyArray3<u8>>, f64)> {
    for (name, side) in [("width", width), ("height", height)] {
        if !(1..=MAX_SIDE).contains(&side) {
            return Err(PyValueError::new_err(format!("{name} must be in 1..={MAX_SIDE}, not {side}")));
        }
    }
    let named = |what: &'static str| move |e: PyErr| PyValueError::new_err(format!("{what}: {}", e.value(py)));
    let target = valid_uv_mesh(&target_positions, &target_faces, &target_uv, &target_uv_faces).map_err(named("target"))?;
    let source = valid_uv_mesh(&source_positions, &source_faces, &source_uv, &source_uv_faces).map_err(named("source"))?;
    let texture = texture_of(&source_texture).map_err(named("source texture"))?;
    let (image, covered) = py.allow_threads(|| {
        let mut t = dynmesh::texture::transfer::transfer_texture(&target, &source, &texture, width, height);
        if pad {
            dynmesh::texture::pad::pad(&mut t.texture, &t.covered);
        }
        let covered = t.covered.iter().filter(|&&c| c).count() as f64 / t.covered.len() as f64;
        (t.texture, covered)
    });
    let flat = image.rgb.into_flattened();
    Ok((Array3::from_shape_vec((height, width, 3), flat).expect("shape").into_pyarray(py), covered))
}
