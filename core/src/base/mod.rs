//! The base mesh of an intra frame: [`decimate`] (quadric edge collapse to a target face
//! count), [`refit`] (base positions whose subdivision fits the input best, also used on the
//! base of predicted frames) and its lossless static [`coder`] (the block's header and bounds),
//! which codes [`connectivity`] and then [`positions`]; every later stage continues from the
//! coder's decoded output.

pub mod decimate;
pub mod refit;
pub mod connectivity;
pub mod positions;
pub mod coder;
