//! dynmesh core: the stages of a V-DMC style codec for dynamic meshes.
//!
//! Data flows one way through the encoder: input [`mesh::Mesh`] → [`grid`] (position
//! quantization) → [`decimate`] (base mesh) → [`basecoder`] (static base-mesh coding, whose
//! decoded result every later stage uses) → [`subdivide`] → [`displace`] (fitting and local
//! frames) → [`transform`] (lifting wavelet) → [`quantize`] → [`coefcoder`] (entropy coding of
//! coefficients, over [`ec`]) → [`bitstream`]. The [`decoder`] runs the inverse path, and the
//! [`encoder`] reconstructs each frame with the decoder's own functions so that both agree bit
//! for bit. [`metrics`] measures D1/D2 PSNR as the MPEG common test conditions do.

pub mod error;
pub mod mesh;
pub mod bins;
pub mod weld;
pub mod limits;
pub mod ec;
pub mod grid;
pub mod quadric;
pub mod decimate;
pub mod base_connectivity;
pub mod base_positions;
pub mod basecoder;
pub mod anchor;
pub mod motion;
pub mod tracking;
pub mod subdivide;
pub mod refit;
pub mod bvh;
pub mod displace;
pub mod transform;
pub mod quantize;
pub mod coefcoder;
pub mod bitstream;
pub mod resync;
pub mod encoder;
pub mod decoder;
pub mod sampling;
pub mod metrics;
pub mod texture;
pub mod uv_corners;
pub mod uv_prediction;
pub mod uvcoder;
pub mod render;
pub mod closest;
pub mod transfer;
pub mod pad;
pub mod fuzzing;
#[cfg(test)]
mod shared_data;
