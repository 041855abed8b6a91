//! `dynmesh decode` to OBJ or PLY files in one call of the core: `dynmesh_meshio::decode_files`
//! with the GIL released, its failures made the exceptions `dynmesh.io` raises.

use std::io;
use std::path::{Path, PathBuf};

use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use dynmesh_meshio::decode_files::{self, Failure, FileFormat, WriteFailure};

use crate::errors::{core_error, released};

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(decode_to_files, m)?)
}

/// Decodes every frame of `data` and writes frame `i` to `directory/frame_{i:04}.{format}`
/// (`obj` or `ply`; nothing is written without a directory). Returns, per frame in order,
/// `(frame, hash, error)`: `hash` the `--hash` SHA-256 when `hash` is true, `error` None or
/// the exception of the frame (a `DecodeError`, or the `OSError` / `ValueError` of writing
/// it). `progress()` is called once per frame. Errors when the stream cannot be opened, as
/// `Decoder(data, tolerant, lod)` does.
#[pyfunction]
#[pyo3(signature = (data, directory=None, format="obj", lod=None, tolerant=false, hash=false, progress=None))]
#[allow(clippy::too_many_arguments)]
fn decode_to_files<'py>(
    py: Python<'py>,
    data: &[u8],
    directory: Option<PathBuf>,
    format: &str,
    lod: Option<u32>,
    tolerant: bool,
    hash: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<Vec<Bound<'py, PyTuple>>> {
    let format = FileFormat::from_name(format).map_err(PyValueError::new_err)?;
    let decoder = crate::open_decoder(data, tolerant, lod)?;
    let progress = || {
        if let Some(p) = &progress {
            Python::with_gil(|py| p.call0(py).map(drop).unwrap_or_else(|e| e.write_unraisable(py, None)));
        }
    };
    let outcomes = released(py, || decode_files::decode_to_files(&decoder, directory.as_deref(), format, hash, &progress))?;
    outcomes
        .into_iter()
        .map(|(i, outcome)| {
            let (digest, error) = match outcome {
                Ok(d) => (d, None),
                Err(Failure::Decode(e)) => (None, Some(core_error(e).into_value(py))),
                Err(Failure::Write(w)) => (None, Some(write_error(w).into_value(py))),
            };
            PyTuple::new(py, [i.into_pyobject(py)?.into_any(), digest.into_pyobject(py)?, error.into_pyobject(py)?])
        })
        .collect()
}

/// The exception `dynmesh.io.write_mesh` raises for the same failure: an OSError naming
/// the target (never the temporary file), or the ValueError of its MeshError.
fn write_error(w: WriteFailure) -> PyErr {
    match w {
        WriteFailure::Io(p, e) => io_error(&p, e),
        non_finite => PyValueError::new_err(non_finite.to_string()),
    }
}

/// The OSError that Python's own file functions raise for `e` on `path`: errno, strerror
/// and the target's name (never a temporary file's).
pub(crate) fn io_error(path: &Path, e: io::Error) -> PyErr {
    match e.raw_os_error() {
        Some(errno) => {
            let text = e.to_string();
            let strerror = text.split(" (os error").next().unwrap_or(&text).to_string();
            PyOSError::new_err((errno, strerror, path.display().to_string()))
        }
        None => PyOSError::new_err(format!("{}: {e}", path.display())),
    }
}
