//! The container, for inspecting and assembling streams: the sequence header and its fields,
//! frame types, and the serialization of the header and of texture units
//! (`docs/bitstream.md`).

/// Everything the decoder needs before the first frame: frame count, position grid, base
/// mesh bits, subdivision schemes, lifting weights, displacement components, adaptive
/// quantization.
pub use crate::stream::bitstream::SequenceHeader;
/// The position grid over the sequence's bounding box ([`SequenceHeader::grid`]).
pub use crate::geom::grid::Grid;
/// A subdivision iteration's scheme ([`SequenceHeader::schemes`]).
pub use crate::residual::subdivide::Scheme;
/// The lifting transform's update weights ([`SequenceHeader::lifting`]).
pub use crate::residual::transform::Lifting;
/// Kind of a frame unit: intra or predicted.
pub use crate::stream::bitstream::FrameType;
/// The serialized sequence header, the first bytes of a stream. Cannot fail.
pub use crate::stream::bitstream::write_header;
/// The texture unit carrying a payload ([`crate::texturing::TexturePayload::to_bytes`]), to
/// be placed right after its frame's unit. Cannot fail.
pub use crate::stream::bitstream::write_texture_unit;
/// The format version this build writes and reads; a stream of another version is
/// [`crate::Error::Unsupported`].
pub use crate::stream::bitstream::VERSION;
/// Subdivision iterations the format allows.
pub use crate::stream::bitstream::MAX_SUBDIV;
