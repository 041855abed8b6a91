//! Measuring and showing meshes, apart from the codec (cargo feature `eval`): meshes sampled
//! into point clouds as mmetric does ([`sampling`]), D1/D2 geometry and Y/Cb/Cr texture PSNR
//! ([`metrics`]), and a snapshot renderer ([`render`]).

pub mod sampling;
pub mod metrics;
pub mod render;
