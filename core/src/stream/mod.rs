//! Bytes, the last stage: the container of sequence header and CRC-checked frame units
//! ([`bitstream`]), the fields inside a frame unit
//! ([`payload`]) and a texture unit ([`texture_payload`]), and the recovery of the frame units
//! that survive in a damaged stream ([`resync`]). [`syntax`] declares the fields, widths, codes
//! and limits of the container and the payloads that those writers and readers go through
//! (and `web/src/stream/syntax.js` mirrors). The range coder the stages' blocks are coded
//! with is [`crate::ec`], below every stage, so that no stage imports this container.

pub mod syntax;
pub mod bitstream;
pub mod payload;
pub mod texture_payload;
pub mod resync;
