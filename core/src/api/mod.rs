//! The public surface of the crate, one module per use: [`encode`] a sequence, [`decode`] a
//! stream, read its container ([`bitstream`]), and the texture stage's pieces that the Python
//! orchestration calls ([`texturing`]). Each is a thin layer over the stages: it names what
//! other crates may use and turns the stages' errors into [`crate::Error`]. The stages
//! themselves are private.

pub mod decode;
pub mod encode;
pub mod bitstream;
pub mod texturing;
