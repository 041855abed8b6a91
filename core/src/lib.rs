//! dynmesh core: a V-DMC style codec for dynamic meshes.
//!
//! # The public API
//!
//! - [`encode`]: [`encode::SequenceEncoder`] codes the frames of a sequence, in order, under an
//!   [`encode::EncoderConfig`]; each call returns the frame's unit, its reconstruction and
//!   statistics.
//! - [`decode`]: [`decode::Decoder`] opens a stream (strict, or tolerant of damaged frame
//!   units) and decodes its frames in any order, at any level of detail.
//! - [`bitstream`]: the container, to inspect and assemble streams: the sequence header, frame
//!   types, the header's and the texture unit's bytes.
//! - [`texturing`]: the texture stage's pieces that the Python orchestration calls: UV atlas
//!   coding, UV subdivision, texture transfer and padding, colour conversion of the video,
//!   the texture unit's payload.
//! - [`eval`] (cargo feature `eval`, on by default): D1/D2 and colour PSNR as the MPEG common
//!   test conditions measure them, point sampling, and the snapshot renderer.
//! - `fuzzing` (cargo feature `fuzzing`): the fuzz targets' entry points.
//! - [`Mesh`] is what goes in and comes out; [`Error`] is every fallible function's error:
//!   [`Error::Input`] (the caller's input is refused), [`Error::Decode`] (a truncated or
//!   corrupted stream, with the frame and byte offset), [`Error::Unsupported`] (a valid stream
//!   this build does not read, such as another format version) and [`Error::Internal`] (a bug).
//!
//! # Inside
//!
//! The stages are private, one folder each. Data flows one way through the encoder: input
//! `Mesh` → `geom` (welding, the position grid) → `base` (intra frame: decimation, refit and the
//! static base-mesh coder, whose decoded result every later stage uses) or `inter` (predicted
//! frame: tracking or the anchor mesh, then motion coding) → `residual` (subdivision, fitting
//! and local frames, lifting wavelet, quantization, coefficient coding) → `stream` (the
//! container); every stage codes its blocks with the range coder `ec`, which sits below them
//! all; `texture` codes the atlas and resamples the texture. The `decoder`
//! runs the inverse path; `model` is the reconstruction both sides share, so the `encoder`'s
//! reconstruction and the decoder's output agree bit for bit. `docs/architecture.md` describes
//! each.

mod api;
mod error;
mod geom;
mod ec;
mod stream;
mod base;
mod inter;
mod residual;
mod texture;
mod model;
mod encoder;
mod decoder;
#[cfg(feature = "eval")]
pub mod eval;
#[cfg(any(test, feature = "fuzzing"))]
pub mod fuzzing;
#[cfg(feature = "internals")]
#[doc(hidden)]
pub mod internals;
#[cfg(test)]
mod shared_data;
#[cfg(test)]
mod tests;

pub use api::{bitstream, decode, encode, texturing};
pub use error::Error;
/// A triangle mesh: positions and faces indexing them (`[u32; 3]`, counter-clockwise).
/// `Mesh::validate` refuses faces out of range and coordinates that are not finite; its error
/// converts into [`Error::Input`] with `?`.
pub use geom::mesh::Mesh;
