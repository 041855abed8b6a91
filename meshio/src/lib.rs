//! The files of dynmesh: meshes read from and written to OBJ and PLY, texture images as PNG,
//! and a stream decoded to a directory of frame files.
//!
//! The Python package's `dynmesh.io` and `dynmesh decode` do the per-line, per-value and
//! per-pixel work here, through the bindings (`dynmesh._core`), which only convert arrays
//! and errors and release the GIL. Python keeps what touches the file system around it
//! (reading the file, the .mtl library and texture paths, checks before writing).
//!
//! Everything here reproduces what the former Python code did, byte for byte and message for
//! message, because the tests and users' files pin it: numbers are read as Python's `float()`
//! and `int()` read them, tokens split where `str.split()` splits, floats are written as
//! Python's `repr`, and every error names what `dynmesh.io`'s errors named. That is why the
//! readers are hand-written rather than `tobj` or `ply-rs` (see [`obj`] and [`ply`]).
//!
//! - [`obj`], [`ply`]: the readers; [`FormatError`] their error.
//! - [`obj_write`], [`ply_write`]: the writers' rows.
//! - [`png_image`]: PNG encoding and decoding of RGB textures.
//! - [`atomic_write`]: files written whole or not at all.
//! - [`decode_files`]: a stream's frames decoded in parallel and written as files;
//!   [`frame_hash`] the hash `--hash` prints for each.

pub mod atomic_write;
mod blocks;
pub mod decode_files;
mod error;
pub mod frame_hash;
pub mod obj;
pub mod obj_write;
pub mod ply;
pub mod ply_write;
pub mod png_image;
mod polygons;
mod python_repr;
mod tokens;

pub use error::{FormatError, Result};
