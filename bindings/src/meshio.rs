//! Mesh files for `dynmesh.io`: the readers and writers of `dynmesh_meshio` on numpy arrays.
//! Python keeps what touches the file system and turns [`MeshFormatError`] `(message, line)`
//! into `MeshError(path, message, line)`.

use std::borrow::Cow;

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyBytes;

use dynmesh_meshio::ply_write::PlyBody;
use dynmesh_meshio::{obj, obj_write, ply, ply_write, FormatError};

use crate::errors::released;

create_exception!(_core, MeshFormatError, PyValueError, "A mesh file that cannot be read; args are (message, 1-based line or None).");

/// Adds the mesh-file functions to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(read_obj, m)?)?;
    m.add_function(wrap_pyfunction!(read_ply, m)?)?;
    m.add_function(wrap_pyfunction!(format_rows, m)?)?;
    m.add_function(wrap_pyfunction!(format_obj_faces, m)?)?;
    m.add_function(wrap_pyfunction!(ply_body, m)?)?;
    m.add("MeshFormatError", m.py().get_type::<MeshFormatError>())?;
    Ok(())
}

fn format_error(e: FormatError) -> PyErr {
    MeshFormatError::new_err((e.message, e.line))
}

/// (positions (N, 3), faces (M, 3), uvs (K, 2) or None, uv_faces (M, 3) or None).
type MeshArrays<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<i64>>, Option<Bound<'py, PyArray2<f64>>>, Option<Bound<'py, PyArray2<i64>>>);

fn mesh_arrays(py: Python<'_>, positions: Vec<f64>, faces: Vec<i64>, uv: Option<(Vec<f64>, Vec<i64>)>) -> MeshArrays<'_> {
    let rows = |v: Vec<f64>, w: usize| Array2::from_shape_vec((v.len() / w, w), v).expect("shape").into_pyarray(py);
    let tris = |v: Vec<i64>| Array2::from_shape_vec((v.len() / 3, 3), v).expect("shape").into_pyarray(py);
    let (uvs, uv_faces) = match uv {
        Some((u, f)) => (Some(rows(u, 2)), Some(tris(f))),
        None => (None, None),
    };
    (rows(positions, 3), tris(faces), uvs, uv_faces)
}

/// (mesh arrays, mtllib arguments, usemtl names, notes).
type ObjRead<'py> = (MeshArrays<'py>, Vec<String>, Vec<String>, Vec<String>);

/// Parses an OBJ file's bytes. Returns ((positions (N, 3), faces (M, 3), uvs (K, 2) or
/// None, uv_faces (M, 3) or None), mtllib arguments, usemtl names in order of first use,
/// notes). Polygons are fan-triangulated; UVs are kept only when every corner has one.
/// Raises MeshFormatError(message, line).
#[pyfunction]
fn read_obj<'py>(py: Python<'py>, data: &[u8]) -> PyResult<ObjRead<'py>> {
    let m = released(py, || obj::read_obj(data))?.map_err(format_error)?;
    Ok((mesh_arrays(py, m.positions, m.faces, m.uv), m.mtllibs, m.materials, m.notes))
}

/// Parses a PLY file's bytes (ASCII, binary little or big endian). Returns ((positions,
/// faces, uvs or None, uv_faces or None), header comments, notes): UVs are the faces'
/// per-corner `texcoord` lists, else per-vertex u,v (s,t, texture_u/v, texture_s/t) with
/// uv_faces equal to faces. Raises MeshFormatError(message, line).
#[pyfunction]
fn read_ply<'py>(py: Python<'py>, data: &[u8]) -> PyResult<(MeshArrays<'py>, Vec<String>, Vec<String>)> {
    let m = released(py, || ply::read_ply(data))?.map_err(format_error)?;
    Ok((mesh_arrays(py, m.positions, m.faces, m.uv), m.comments, m.notes))
}

/// Blocks of text laid end to end as one bytes object.
fn joined<'py>(py: Python<'py>, blocks: &[Vec<u8>]) -> PyResult<Bound<'py, PyBytes>> {
    let total = blocks.iter().map(Vec::len).sum();
    PyBytes::new_with(py, total, |buf| {
        let mut at = 0;
        for b in blocks {
            buf[at..at + b.len()].copy_from_slice(b);
            at += b.len();
        }
        Ok(())
    })
}

/// The array's values row by row, borrowed when it is C-contiguous.
fn contiguous<'a, T: numpy::Element + Copy>(a: &'a PyReadonlyArray2<'_, T>, width: usize, what: &str) -> PyResult<Cow<'a, [T]>> {
    let v = a.as_array();
    if v.ncols() != width {
        return Err(PyValueError::new_err(format!("{what} must have shape (N, {width})")));
    }
    // A Fortran-ordered array is contiguous too, but not row by row: only C order is borrowed.
    Ok(match a.as_slice().ok().filter(|_| a.is_c_contiguous()) {
        Some(s) => Cow::Borrowed(s),
        None => Cow::Owned(v.iter().copied().collect()),
    })
}

/// One line per row of `values` (N, W): `prefix` (if any), then the row's floats as
/// Python's repr (shortest round trip), space-separated: `v 0.1 -2.0 1e-05`.
#[pyfunction]
fn format_rows<'py>(py: Python<'py>, values: PyReadonlyArray2<'py, f64>, prefix: &str) -> PyResult<Bound<'py, PyBytes>> {
    let width = values.as_array().ncols();
    let flat = contiguous(&values, width, "values")?;
    joined(py, &released(py, || obj_write::format_rows(&flat, width, prefix))?)
}

/// OBJ face lines from 0-based faces (M, 3): `f 1 2 3`, or `f 1/1 2/2 3/3` with uv_faces.
#[pyfunction]
#[pyo3(signature = (faces, uv_faces=None))]
fn format_obj_faces<'py>(py: Python<'py>, faces: PyReadonlyArray2<'py, i64>, uv_faces: Option<PyReadonlyArray2<'py, i64>>) -> PyResult<Bound<'py, PyBytes>> {
    let faces = contiguous(&faces, 3, "faces")?;
    let uv_faces = uv_faces.as_ref().map(|u| contiguous(u, 3, "uv_faces")).transpose()?;
    let blocks = released(py, || obj_write::format_obj_faces(&faces, uv_faces.as_deref()))?.map_err(PyValueError::new_err)?;
    joined(py, &blocks)
}

/// The body of a PLY file after its header: vertex rows (N, W) of doubles, then faces
/// (M, 3) as `list uchar int`, each followed by its `texcoord` (M, 6) `list uchar double`
/// when given. ASCII rows use Python's float repr; binary is little endian.
#[pyfunction]
#[pyo3(signature = (vertex, faces, texcoord, ascii))]
fn ply_body<'py>(
    py: Python<'py>,
    vertex: PyReadonlyArray2<'py, f64>,
    faces: PyReadonlyArray2<'py, i64>,
    texcoord: Option<PyReadonlyArray2<'py, f64>>,
    ascii: bool,
) -> PyResult<Bound<'py, PyBytes>> {
    let width = vertex.as_array().ncols();
    let vertex = contiguous(&vertex, width, "vertex")?;
    let faces = contiguous(&faces, 3, "faces")?;
    let texcoord = texcoord.as_ref().map(|t| contiguous(t, 6, "texcoord")).transpose()?;
    let body = PlyBody { vertex: &vertex, width, faces: &faces, texcoord: texcoord.as_deref(), ascii };
    let blocks = released(py, || ply_write::ply_body(&body))?.map_err(PyValueError::new_err)?;
    joined(py, &blocks)
}
