//! A stream decoded to a directory of OBJ or PLY files, one per frame, without Python in the
//! loop: `dynmesh decode` through `dynmesh.api` would move every frame into numpy arrays and
//! back out as text, and pay numpy's import (a quarter of a second, more than the decoding of
//! a 6-frame stream).
//!
//! Intra frames depend on nothing, so the runs of frames from one intra frame up to the next
//! are decoded in parallel, each run by its own clone of the decoder, its predicted frames in
//! order after their references (a reference outside the run is decoded again by the clone,
//! as `Decoder::decode_frame` always does).
//!
//! The files are byte for byte what `dynmesh.io.write_mesh` writes for a mesh without UVs,
//! and are written as it writes them ([`write_atomically`]). One writer thread does the
//! writing, a few frames behind the decoding: a sync waits on the disk (20 ms for a 7 MB
//! frame), and on a decoding thread it would hold a core of the thread pool idle.

use std::fmt;
use std::io;
use std::path::{Path, PathBuf};
use std::sync::mpsc::{sync_channel, SyncSender};

use rayon::prelude::*;

use dynmesh::decode::Decoder;
use dynmesh::bitstream::FrameType;
use dynmesh::Error;
use dynmesh::Mesh;

use crate::atomic_write::write_atomically;
use crate::blocks::text_blocks;
use crate::frame_hash::frame_hash;
use crate::obj_write::{push_obj_faces, push_rows};
use crate::ply_write::{ply_rows, positions_header, PlyBody};

/// The file format of decoded frames.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileFormat {
    /// Text: a comment line, `v` lines, `f` lines.
    Obj,
    /// Binary little endian: double positions, `list uchar int` faces.
    Ply,
}

impl FileFormat {
    /// The format named `name` (`obj` or `ply`, the files' extensions).
    ///
    /// Errors: any other name, with the message the command line shows.
    pub fn from_name(name: &str) -> Result<Self, String> {
        match name {
            "obj" => Ok(Self::Obj),
            "ply" => Ok(Self::Ply),
            other => Err(format!("unknown format {other:?} (expected obj or ply)")),
        }
    }

    fn extension(self) -> &'static str {
        match self {
            Self::Obj => "obj",
            Self::Ply => "ply",
        }
    }
}

/// Why a decoded frame's file was not written.
#[derive(Debug)]
pub enum WriteFailure {
    /// The frame has positions no file can hold (the target's path).
    NonFinite(PathBuf),
    /// Writing the target (its path) failed.
    Io(PathBuf, io::Error),
}

impl fmt::Display for WriteFailure {
    /// The message of `dynmesh.io.write_mesh`'s error for the same failure, naming the target
    /// (never the temporary file).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NonFinite(p) => write!(f, "{}: cannot write a mesh with non-finite positions", p.display()),
            Self::Io(p, e) => write!(f, "{}: {e}", p.display()),
        }
    }
}

/// Why a frame has no file (and no hash).
#[derive(Debug)]
pub enum Failure {
    /// The frame could not be decoded.
    Decode(Error),
    /// The frame was decoded but its file could not be written.
    Write(WriteFailure),
}

/// What became of one frame: written (with its hash when asked), or why not.
pub type Outcome = Result<Option<String>, Failure>;

/// A frame's file for the writer thread: frame, path, contents.
type FileJob = (u32, PathBuf, Vec<Vec<u8>>);

/// Formatted frames the writer may hold back before decoding waits: memory stays at a few
/// frames' text whatever the stream's length.
const WRITE_QUEUE: usize = 2;

/// Decodes every frame of `decoder`'s stream and writes frame `i` to
/// `directory/frame_{i:04}.{obj|ply}` (nothing is written without a directory), calling
/// `progress` once per frame as it is decoded, from the decoding threads.
///
/// Returns, per frame in order, `(frame, outcome)`: the frame's [`frame_hash`] when `hash`
/// is true (else None), or the [`Failure`] of decoding or writing that frame. One frame's
/// failure does not stop the others.
pub fn decode_to_files(
    decoder: &Decoder,
    directory: Option<&Path>,
    format: FileFormat,
    hash: bool,
    progress: &(dyn Fn() + Sync),
) -> Vec<(u32, Outcome)> {
    std::thread::scope(|scope| {
        let (files, queue) = sync_channel::<FileJob>(WRITE_QUEUE);
        let writer = scope.spawn(move || {
            let failures = queue.into_iter().filter_map(|(i, path, chunks)| write_atomically(&path, &chunks).err().map(|e| (i, WriteFailure::Io(path, e))));
            failures.collect::<Vec<_>>()
        });
        let per_run: Vec<Vec<(u32, Outcome)>> = runs_of(decoder)
            .par_iter()
            .map(|run| {
                let mut dec = decoder.clone();
                let frames = run.iter().map(|&i| {
                    let outcome = frame_outcome(&mut dec, i, directory, format, hash, &files);
                    progress();
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
fn frame_outcome(dec: &mut Decoder, i: u32, directory: Option<&Path>, format: FileFormat, hash: bool, files: &SyncSender<FileJob>) -> Outcome {
    let mesh = dec.decode_frame(i).map_err(Failure::Decode)?;
    if let Some(dir) = directory {
        let path = dir.join(format!("frame_{i:04}.{}", format.extension()));
        let chunks = file_chunks(&path, &mesh, format).map_err(Failure::Write)?;
        files.send((i, path, chunks)).expect("the writer thread outlives the decoding");
    }
    Ok(hash.then(|| frame_hash(&mesh)))
}

/// The file of `mesh` as `format`, in pieces; an error for positions no file can hold.
fn file_chunks(path: &Path, mesh: &Mesh, format: FileFormat) -> Result<Vec<Vec<u8>>, WriteFailure> {
    if !mesh.positions.iter().flatten().all(|x| x.is_finite()) {
        return Err(WriteFailure::NonFinite(path.to_path_buf()));
    }
    let positions = mesh.positions.as_flattened();
    let faces = mesh.faces.as_flattened();
    let (nv, nf) = (mesh.positions.len(), mesh.faces.len());
    Ok(match format {
        FileFormat::Obj => {
            let mut chunks = vec![b"# written by dynmesh\n".to_vec()];
            chunks.extend(text_blocks(nv, |lo, hi, out| push_rows(out, positions, 3, "v", lo, hi)));
            chunks.extend(text_blocks(nf, |lo, hi, out| push_obj_faces(out, faces, None, lo, hi)));
            chunks
        }
        FileFormat::Ply => {
            let mut chunks = vec![positions_header(nv, nf).into_bytes()];
            chunks.extend(ply_rows(&PlyBody { vertex: positions, width: 3, faces, texcoord: None, ascii: false }));
            chunks
        }
    })
}
