//! Python bindings of the texture-atlas stages: lossless UV coding and UV subdivision.
//!
//! Arrays are checked here (shapes, index ranges, the UV grid) so that the core's
//! contracts hold and a mistake surfaces as a ValueError naming the bad row, never as a
//! panic.

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyBytes;

use dynmesh::bitstream::MAX_SUBDIV;
use dynmesh::texturing::{self, UvAtlas, MAX_UV_BITS};

use crate::colour::{uv_faces_of, uv_of};
use crate::errors::{core_error, input_error, released};
use crate::{faces_of, positions_of};

type Atlas<'py> = (Bound<'py, PyArray2<i64>>, Bound<'py, PyArray2<i64>>);
type FloatAtlas<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<i64>>);

/// Adds the UV functions to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(encode_uv, m)?)?;
    m.add_function(wrap_pyfunction!(decode_uv, m)?)?;
    m.add_function(wrap_pyfunction!(canonical_uv, m)?)?;
    m.add_function(wrap_pyfunction!(subdivide_uv, m)?)?;
    Ok(())
}

/// Codes a quantized UV atlas of the mesh `faces` (M, 3): `uv_faces` (M, 3) indexes the
/// rows of `uv` (K, 2), integers in [0, 2^bits). With `positions` (N, 3) of the mesh, new
/// UVs are predicted from the 3D triangles (smaller; decode with the same positions).
/// Returns the coded bytes.
#[pyfunction]
#[pyo3(signature = (faces, uv_faces, uv, bits, positions=None))]
fn encode_uv<'py>(
    py: Python<'py>,
    faces: PyReadonlyArray2<'py, i64>,
    uv_faces: PyReadonlyArray2<'py, i64>,
    uv: &Bound<'py, PyAny>,
    bits: u32,
    positions: Option<PyReadonlyArray2<'py, f64>>,
) -> PyResult<Bound<'py, PyBytes>> {
    check_bits(bits)?;
    let positions = positions.as_ref().map(positions_of).transpose()?;
    let vertex_bound = positions.as_ref().map_or(u32::MAX as usize, Vec::len);
    let faces = faces_of(&faces, vertex_bound)?;
    let uv = quantized_uv_of(uv, bits)?;
    let uv_faces = uv_faces_of(&uv_faces, faces.len(), uv.len())?;
    let data = released(py, || match &positions {
        Some(p) => texturing::encode_uv_with_positions(p, &faces, &uv_faces, &uv, bits),
        None => texturing::encode_uv(&faces, &uv_faces, &uv, bits),
    })?;
    Ok(PyBytes::new(py, &data))
}

/// Decodes what `encode_uv` wrote for the same `faces`, `bits` (and `positions`, which
/// must then have `vertex_count` rows). Returns (uv_faces (M, 3), uv (K, 2)), int64, UVs
/// numbered in order of first use. Raises DecodeError `(message,)` for data that cannot be
/// decoded, InputError for inconsistent arguments.
#[pyfunction]
#[pyo3(signature = (data, faces, vertex_count, bits, positions=None))]
fn decode_uv<'py>(
    py: Python<'py>,
    data: &[u8],
    faces: PyReadonlyArray2<'py, i64>,
    vertex_count: usize,
    bits: u32,
    positions: Option<PyReadonlyArray2<'py, f64>>,
) -> PyResult<Atlas<'py>> {
    check_bits(bits)?;
    let positions = positions.as_ref().map(positions_of).transpose()?;
    if let Some(p) = &positions {
        if p.len() != vertex_count {
            return Err(input_error(format!("positions has {} rows, vertex_count is {vertex_count}", p.len())));
        }
    }
    let faces = faces_of(&faces, vertex_count)?;
    let decoded = released(py, || match &positions {
        Some(p) => texturing::decode_uv_with_positions(data, p, &faces, bits),
        None => texturing::decode_uv(data, &faces, vertex_count, bits),
    })?
    .map_err(core_error)?;
    Ok(atlas_arrays(py, decoded))
}

/// The atlas (uv_faces (M, 3), uv (K, 2) of non-negative integers < 2^32) with its UVs
/// renumbered in order of first use and unused ones dropped, as `decode_uv` returns it.
#[pyfunction]
fn canonical_uv<'py>(py: Python<'py>, uv_faces: PyReadonlyArray2<'py, i64>, uv: &Bound<'py, PyAny>) -> PyResult<Atlas<'py>> {
    let uv = quantized_uv_of(uv, 32)?;
    let rows = uv_faces.as_array().nrows();
    let uv_faces = uv_faces_of(&uv_faces, rows, uv.len())?;
    Ok(atlas_arrays(py, released(py, || texturing::canonical_uv(&uv_faces, &uv))?))
}

/// Splits the UV triangles `uv_faces` (M, 3) over `uv` (K, 2) as `iterations` rounds of
/// mesh subdivision split the faces: row i of the result's faces holds the UVs of face i
/// of the subdivided mesh. Returns (uv (K', 2) float64, uv_faces (M * 4^iterations, 3)).
#[pyfunction]
fn subdivide_uv<'py>(
    py: Python<'py>,
    uv: PyReadonlyArray2<'py, f64>,
    uv_faces: PyReadonlyArray2<'py, i64>,
    iterations: u32,
) -> PyResult<FloatAtlas<'py>> {
    if iterations > MAX_SUBDIV {
        return Err(input_error(format!("at most {MAX_SUBDIV} subdivision iterations")));
    }
    let uv = uv_of(&uv)?;
    let rows = uv_faces.as_array().nrows();
    let uv_faces = uv_faces_of(&uv_faces, rows, uv.len())?;
    let (suv, sfaces) = released(py, || texturing::subdivide_uv(&uv, &uv_faces, iterations))?;
    let n = suv.len();
    let suv = Array2::from_shape_vec((n, 2), suv.into_flattened()).expect("shape");
    Ok((suv.into_pyarray(py), index_array(py, sfaces)))
}

fn check_bits(bits: u32) -> PyResult<()> {
    if (1..=MAX_UV_BITS).contains(&bits) {
        Ok(())
    } else {
        Err(input_error(format!("bits must be from 1 to {MAX_UV_BITS}, not {bits}")))
    }
}

/// Integer UVs (K, 2), uint32 or int64, each in [0, 2^bits).
fn quantized_uv_of(uv: &Bound<'_, PyAny>, bits: u32) -> PyResult<Vec<[u32; 2]>> {
    let rows: Vec<[i64; 2]> = if let Ok(a) = uv.extract::<PyReadonlyArray2<u32>>() {
        let v = a.as_array();
        check_uv_shape(v.ncols())?;
        v.rows().into_iter().map(|r| [r[0] as i64, r[1] as i64]).collect()
    } else if let Ok(a) = uv.extract::<PyReadonlyArray2<i64>>() {
        let v = a.as_array();
        check_uv_shape(v.ncols())?;
        v.rows().into_iter().map(|r| [r[0], r[1]]).collect()
    } else {
        return Err(input_error("uv must be a (K, 2) numpy array of uint32 or int64"));
    };
    let limit = 1i64 << bits;
    if let Some(i) = rows.iter().position(|r| r.iter().any(|&c| !(0..limit).contains(&c))) {
        return Err(input_error(format!("uv row {i} is outside [0, 2^{bits})")));
    }
    Ok(rows.into_iter().map(|r| r.map(|c| c as u32)).collect())
}

fn check_uv_shape(cols: usize) -> PyResult<()> {
    if cols == 2 {
        Ok(())
    } else {
        Err(input_error("uv must have shape (K, 2)"))
    }
}

fn index_array<const N: usize>(py: Python<'_>, rows: Vec<[u32; N]>) -> Bound<'_, PyArray2<i64>> {
    let n = rows.len();
    Array2::from_shape_vec((n, N), rows.into_iter().flatten().map(i64::from).collect()).expect("shape").into_pyarray(py)
}

fn atlas_arrays(py: Python<'_>, (uv_faces, uv): UvAtlas) -> Atlas<'_> {
    (index_array(py, uv_faces), index_array(py, uv))
}
