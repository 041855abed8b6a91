//! Python binding of the texture transfer: the input frame's texture re-sampled onto the
//! atlas of the reconstructed mesh, padded for video coding.

use dynmesh::texturing::{self, UvMesh};
use dynmesh::Mesh;
use numpy::ndarray::Array3;
use numpy::{IntoPyArray, PyArray3, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::colour::{texture_of, valid_uv_mesh};
use crate::errors::{input_error, released};

/// Largest atlas side accepted, the stream's (keeps a typo from allocating gigabytes).
const MAX_SIDE: usize = texturing::MAX_SIDE as usize;

/// Adds the transfer function to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(transfer_texture, m)?)?;
    Ok(())
}

/// The texture of `source` (its mesh, per-corner UVs and (H, W, 3) uint8 texture) transferred
/// onto the atlas of `target` (its mesh and per-corner UVs) as a `width` x `height` image: every
/// texel that a target UV triangle covers takes the colour of the closest point of the source
/// surface; with `pad` the others are filled by push-pull. Returns (image (height, width, 3)
/// uint8, fraction of texels covered). Raises InputError for inconsistent arrays.
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
            return Err(input_error(format!("{name} must be from 1 to {MAX_SIDE}, not {side}")));
        }
    }
    let named = |what: &'static str| move |e: PyErr| input_error(format!("{what}: {}", e.value(py)));
    let target = match quick_uv_mesh(&target_positions, &target_faces, &target_uv, &target_uv_faces) {
        Some(mesh) => mesh,
        None => valid_uv_mesh(&target_positions, &target_faces, &target_uv, &target_uv_faces).map_err(named("target"))?,
    };
    let source = match quick_uv_mesh(&source_positions, &source_faces, &source_uv, &source_uv_faces) {
        Some(mesh) => mesh,
        None => valid_uv_mesh(&source_positions, &source_faces, &source_uv, &source_uv_faces).map_err(named("source"))?,
    };
    let texture = texture_of(&source_texture).map_err(named("source texture"))?;
    let (image, covered) = released(py, || {
        let mut t = texturing::transfer_texture(&target, &source, &texture, width, height);
        if pad {
            texturing::pad(&mut t.texture, &t.covered);
        }
        let covered = t.covered.iter().filter(|&&c| c).count() as f64 / t.covered.len() as f64;
        (t.texture, covered)
    })?;
    let flat = image.rgb.into_flattened();
    Ok((Array3::from_shape_vec((height, width, 3), flat).expect("shape").into_pyarray(py), covered))
}

/// What `valid_uv_mesh` makes of C-contiguous arrays that pass its checks, read as slices
/// rather than row by row (which costs milliseconds on meshes of 100k faces, with the GIL
/// held); `None` for anything else, which `valid_uv_mesh` then converts or reports.
fn quick_uv_mesh(
    positions: &PyReadonlyArray2<f64>,
    faces: &PyReadonlyArray2<i64>,
    uv: &PyReadonlyArray2<f64>,
    uv_faces: &PyReadonlyArray2<i64>,
) -> Option<UvMesh> {
    let rows = |a: &[usize], width: usize| (a.len() == 2 && a[1] == width).then_some(a[0]);
    let (n, m) = (rows(positions.shape(), 3)?, rows(faces.shape(), 3)?);
    let k = rows(uv.shape(), 2)?;
    if rows(uv_faces.shape(), 3)? != m {
        return None;
    }
    let (positions, uv) = (c_slice(positions)?, c_slice(uv)?);
    let indices = |a: &PyReadonlyArray2<i64>, count: usize| -> Option<Vec<[u32; 3]>> {
        let s = c_slice(a)?;
        let ok = s.iter().all(|&x| 0 <= x && (x as u64) < count as u64);
        ok.then(|| s.chunks_exact(3).map(|t| [t[0] as u32, t[1] as u32, t[2] as u32]).collect())
    };
    let (faces, uv_faces) = (indices(faces, n)?, indices(uv_faces, k)?);
    let mesh = UvMesh {
        mesh: Mesh::new(positions.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect(), faces),
        uv: uv.chunks_exact(2).map(|p| [p[0], p[1]]).collect(),
        uv_faces,
    };
    mesh.validate().is_ok().then_some(mesh)
}

/// The values of `a` row by row, if it is C-contiguous (`as_slice` also takes Fortran order).
fn c_slice<'a, T: numpy::Element>(a: &'a PyReadonlyArray2<'_, T>) -> Option<&'a [T]> {
    if a.is_c_contiguous() { a.as_slice().ok() } else { None }
}
