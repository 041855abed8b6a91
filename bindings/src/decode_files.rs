//! `dynmesh decode` to OBJ or PLY files in one call of the core.
//!
//! Through `dynmesh.api` every decoded frame would cross into numpy arrays and back out as
//! text, and the command would pay numpy's import (a quarter of a second, more than the
//! decoding of a 6-frame stream). Here the frames are decoded and written without Python.
//! Intra frames depend on nothing, so the runs of frames from one intra frame up to the
//! next are decoded in parallel, each run by its own clone of the decoder, its predicted
//! frames in order after their references (a reference outside the run is decoded again
//! by the clone, as `Decoder::decode_frame` always does).
//!
//! The files are byte for byte what `dynmesh.io.write_mesh` writes for a mesh without UVs,
//! and are written as it writes them: into a temporary file beside the target, synced,
//! then renamed into place, so a failure never leaves a partial file. One writer thread does
//! the writing, a few frames behind the decoding: a sync waits on the disk (20 ms for a
//! 7 MB frame), and on a decoding thread it would hold a core of the thread pool idle.

use std::fs::{self, OpenOptions};
use std::hash::{BuildHasher, RandomState};
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{sync_channel, SyncSender};

use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyTuple;
use rayon::prelude::*;
use sha2::{Digest, Sha256};

use dynmesh::stream::bitstream::FrameType;
use dynmesh::decoder::Decoder;
use dynmesh::error::DecodeError as CoreDecodeError;
use dynmesh::geom::mesh::Mesh;

use crate::meshio::{push_obj_faces, push_ply_rows, push_rows, text_blocks, PlyBody};

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(decode_to_files, m)?)
}

#[derive(Clone, Copy)]
enum Format {
    Obj,
    Ply,
}

/// What went wrong writing a frame, turned into a Python exception once the GIL is held.
enum WriteFailure {
    NonFinite(PathBuf),
    Io(PathBuf, io::Error),
}

/// What became of one frame: written (with its hash when asked), or why not.
type Outcome = Result<Option<String>, Failure>;

/// A frame's file for the writer thread: frame, path, contents.
type FileJob = (u32, PathBuf, Vec<Vec<u8>>);

/// Formatted frames the writer may hold back before decoding waits: memory stays at a few
/// frames' text whatever the stream's length.
const WRITE_QUEUE: usize = 2;

enum Failure {
    Decode(CoreDecodeError),
    Write(WriteFailure),
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
    let format = match format {
        "obj" => Format::Obj,
        "ply" => Format::Ply,
        other => return Err(PyValueError::new_err(format!("unknown format {other:?} (expected obj or ply)"))),
    };
    let decoder = crate::open_decoder(data, tolerant, lod)?;
    let outcomes: Vec<(u32, Outcome)> = py.allow_threads(|| {
        std::thread::scope(|scope| {
            let (files, queue) = sync_channel::<FileJob>(WRITE_QUEUE);
            let writer = scope.spawn(move || {
                let failures = queue.into_iter().filter_map(|(i, path, chunks)| write_atomically(&path, &chunks).err().map(|e| (i, WriteFailure::Io(path, e))));
                failures.collect::<Vec<_>>()
            });
            let per_run: Vec<Vec<(u32, Outcome)>> = runs_of(&decoder)
                .par_iter()
                .map(|run| {
                    let mut dec = decoder.clone();
                    let frames = run.iter().map(|&i| {
                        let outcome = frame_outcome(&mut dec, i, directory.as_deref(), format, hash, &files);
                        if let Some(p) = &progress {
                            Python::with_gil(|py| p.call0(py).map(drop).unwrap_or_else(|e| e.write_unraisable(py, None)));
                        }
                        (i, outcome)
                    });
                    frames.collect()
                })
                .collect();
            drop(files);
            let mut failed: Vec<(u32, WriteFailure)> = writer.join().expect("the writer thread does not panic");
            let outcomes = per_run.into_iter().flatten().map(|(i, outcome)| match failed.iter().position(|f| f.0 == i) {
                Some(k) if outcome.is_ok() => (i, Err(Failure::Write(failed.swap_remove(k).1))),
                _ => (i, outcome),
            });
            outcomes.collect()
        })
    });
    outcomes
        .into_iter()
        .map(|(i, outcome)| {
            let (digest, error) = match outcome {
                Ok(d) => (d, None),
                Err(Failure::Decode(e)) => (None, Some(crate::decode_error(e).into_value(py))),
                Err(Failure::Write(w)) => (None, Some(write_error(w).into_value(py))),
            };
            PyTuple::new(py, [i.into_pyobject(py)?.into_any(), digest.into_pyobject(py)?, error.into_pyobject(py)?])
        })
        .collect()
}

/// The frames in runs that decode independently: each intra frame (or damaged unit, whose
/// type is unknown) starts a run, and the predicted frames after it join it.
fn runs_of(decoder: &Decoder) -> Vec<Vec<u32>> {
    let mut runs: Vec<Vec<u32>> = Vec::new();
    for i in 0..decoder.frame_count() {
        let predicted = decoder.frame_info(i).is_ok_and(|f| f.frame_type == FrameType::Predicted);
        match runs.last_mut() {
            Some(run) if predicted => run.push(i),
            _ => runs.push(vec![i]),
        }
    }
    runs
}

/// Decodes frame `i` and hands its file to the writer thread (`files`); its writing may
/// still fail there.
fn frame_outcome(dec: &mut Decoder, i: u32, directory: Option<&Path>, format: Format, hash: bool, files: &SyncSender<FileJob>) -> Outcome {
    let mesh = dec.decode_frame(i).map_err(Failure::Decode)?;
    if let Some(dir) = directory {
        let name = format!("frame_{i:04}.{}", match format {
            Format::Obj => "obj",
            Format::Ply => "ply",
        });
        let path = dir.join(name);
        let chunks = file_chunks(&path, &mesh, format).map_err(Failure::Write)?;
        files.send((i, path, chunks)).expect("the writer thread outlives the decoding");
    }
    Ok(hash.then(|| frame_hash(&mesh)))
}

/// SHA-256 of the positions as little-endian float64, then the faces as little-endian
/// uint32: `dynmesh.conformance.frame_hash`.
fn frame_hash(mesh: &Mesh) -> String {
    let mut h = Sha256::new();
    mesh.positions.iter().flatten().for_each(|x| h.update(x.to_le_bytes()));
    mesh.faces.iter().flatten().for_each(|i| h.update(i.to_le_bytes()));
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

/// The file of `mesh` as `format`, in pieces; an error for positions no file can hold.
fn file_chunks(path: &Path, mesh: &Mesh, format: Format) -> Result<Vec<Vec<u8>>, WriteFailure> {
    if !mesh.positions.iter().flatten().all(|x| x.is_finite()) {
        return Err(WriteFailure::NonFinite(path.to_path_buf()));
    }
    let positions = mesh.positions.as_flattened();
    let faces = mesh.faces.as_flattened();
    let (nv, nf) = (mesh.positions.len(), mesh.faces.len());
    Ok(match format {
        Format::Obj => {
            let mut chunks = vec![b"# written by dynmesh\n".to_vec()];
            chunks.extend(text_blocks(nv, |lo, hi, out| push_rows(out, positions, 3, "v", lo, hi)));
            chunks.extend(text_blocks(nf, |lo, hi, out| push_obj_faces(out, faces, None, lo, hi)));
            chunks
        }
        Format::Ply => {
            let mut chunks = vec![ply_header(nv, nf).into_bytes()];
            let body = PlyBody { vertex: positions, width: 3, faces, texcoord: None, ascii: false };
            chunks.extend(text_blocks(nv + nf, |lo, hi, out| push_ply_rows(out, &body, lo, hi)));
            chunks
        }
    })
}

/// The header `dynmesh.io` writes for a binary PLY of positions and faces.
fn ply_header(vertices: usize, faces: usize) -> String {
    format!(
        "ply\nformat binary_little_endian 1.0\ncomment written by dynmesh\nelement vertex {vertices}\n\
         property double x\nproperty double y\nproperty double z\nelement face {faces}\n\
         property list uchar int vertex_indices\nend_header\n"
    )
}

/// `chunks` into a new temporary file beside `path`, synced, then renamed to `path`; the
/// temporary file is removed on failure.
pub(crate) fn write_atomically(path: &Path, chunks: &[Vec<u8>]) -> io::Result<()> {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let tag = RandomState::new().hash_one(path) as u32;
    let tmp = path.with_file_name(format!(".{name}.{}.{tag:08x}.tmp", std::process::id()));
    let mut file = OpenOptions::new().write(true).create_new(true).open(&tmp)?;
    let written = chunks.iter().try_for_each(|c| file.write_all(c)).and_then(|()| file.sync_all());
    drop(file);
    let placed = written.and_then(|()| fs::rename(&tmp, path));
    if placed.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    placed
}

/// The exception `dynmesh.io.write_mesh` raises for the same failure: an OSError naming
/// the target (never the temporary file), or the ValueError text of its MeshError.
fn write_error(w: WriteFailure) -> PyErr {
    match w {
        WriteFailure::NonFinite(p) => PyValueError::new_err(format!("{}: cannot write a mesh with non-finite positions", p.display())),
        WriteFailure::Io(p, e) => io_error(&p, e),
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
