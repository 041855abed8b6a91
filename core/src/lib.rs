//! dynmesh core: the stages of a V-DMC style codec for dynamic meshes, one folder per stage.
//!
//! Data flows one way through the encoder: input [`geom::mesh::Mesh`] → [`geom`] (welding,
//! the position grid) → [`base`] (intra frame: decimation, refit and the static base-mesh
//! coder, whose decoded result every later stage uses) or [`inter`] (predicted frame:
//! tracking or the anchor mesh, then motion coding) → [`residual`] (subdivision, fitting and
//! local frames, lifting wavelet, quantization, coefficient coding) → [`stream`] (entropy
//! coder and container); [`texture`] codes the atlas and resamples the texture. The
//! [`decoder`] runs the inverse path; [`model`] is the reconstruction both sides share, so
//! the [`encoder`]'s reconstruction and the decoder's output agree bit for bit. [`eval`] (feature `eval`) measures
//! D1/D2 PSNR as the MPEG common test conditions do and renders snapshots. `fuzzing` (feature
//! `fuzzing`, which the fuzz crate turns on) holds the fuzz targets' entry points.

pub mod error;
pub mod geom;
pub mod stream;
pub mod base;
pub mod inter;
pub mod residual;
pub mod texture;
pub mod model;
pub mod encoder;
pub mod decoder;
#[cfg(feature = "eval")]
pub mod eval;
#[cfg(any(test, feature = "fuzzing"))]
pub mod fuzzing;
#[cfg(test)]
mod shared_data;
