//! The base mesh of a predicted frame, from its reference frame's base mesh: [`tracking`]
//! when the input keeps the reference input's connectivity, the coarse-to-fine [`anchor`] when
//! it does not, then [`motion`], the coding of the base vertices' quantized motion over the
//! reference connectivity, and the [`refresh`] of the regions the moved base fits worst.

pub mod anchor;
pub mod motion;
pub mod refresh;
pub mod tracking;
