//! Encoding a sequence: a [`SequenceEncoder`] made from an [`EncoderConfig`] turns meshes
//! into frame units, one per call, in order.
//!
//! A stream is the sequence header ([`crate::bitstream::write_header`] of
//! [`SequenceEncoder::header`]) followed by every frame's [`EncodedFrame::unit`] (and, in a
//! textured stream, each frame's texture unit right after it).

use crate::encoder;
use crate::error::Error;
use crate::geom::mesh::Mesh;
use crate::stream::bitstream::SequenceHeader;

/// The encoder's options, every field public, [`Default`] the command line's defaults: what
/// shapes the stream ([`FormatParams`]) apart from how the encoder searches
/// ([`SearchParams`]). [`EncoderConfig::validate`] refuses values out of range (its error
/// converts into [`Error::Input`] with `?`); [`SequenceEncoder::new`] validates too.
pub use crate::encoder::EncoderConfig;
/// The options the stream carries (QP, subdivision, bit depths, lifting, quantization).
pub use crate::encoder::FormatParams;
/// The encoder's search and decision settings (base ratio, intra period, inter stages,
/// rate-distortion slope, refit, references, ...).
pub use crate::encoder::SearchParams;
/// The lifting transform's update weights: per vertex valence or constant.
pub use crate::encoder::LiftingChoice;
/// What encoding one frame produced: the unit, the reconstruction the decoder will output,
/// the decoded base mesh and the frame's statistics.
pub use crate::encoder::EncodedFrame;
/// Statistics of one encoded frame (type, reference, sizes, counts, time).
pub use crate::encoder::FrameStats;
/// The bytes a textured frame's texture adds, whether it continues its texture group or
/// starts one; see [`SequenceEncoder::encode_textured`].
pub use crate::encoder::TextureCost;
/// Most frames a predicted frame may look back (`SearchParams::references`), which is what
/// the decoder keeps.
pub use crate::encoder::MAX_REFERENCES;
/// The base mesh ratio the encoder takes at a QP when [`SearchParams::base_ratio`] is None.
pub use crate::encoder::base_ratio_for_qp;
/// The stages of predicting a frame of another connectivity (`SearchParams::inter`).
pub use crate::inter::anchor::AnchorStages;
/// Adaptive quantization's parameters (`FormatParams::aq`).
pub use crate::residual::quantize::AqParams;
/// The QPs [`FormatParams::qp`] may take.
pub use crate::residual::quantize::QP_RANGE;
/// The subdivision schemes of the iterations (`FormatParams::scheme`), as named on the
/// command line.
pub use crate::residual::subdivide::SchemeChoice;

/// Encodes the frames of one sequence in order, predicting from earlier frames of the group.
pub struct SequenceEncoder {
    inner: encoder::SequenceEncoder,
}

impl SequenceEncoder {
    /// An encoder for `frame_count` frames whose positions lie in the box `[min, max]`.
    ///
    /// Errors: [`Error::Input`] for a configuration out of range or a box that is not finite.
    pub fn new(config: EncoderConfig, frame_count: u32, min: [f64; 3], max: [f64; 3]) -> Result<Self, Error> {
        Ok(Self { inner: encoder::SequenceEncoder::new(config, frame_count, min, max)? })
    }

    /// The sequence header the frames are coded under (frame count, grid, subdivision).
    pub fn header(&self) -> &SequenceHeader {
        self.inner.header()
    }

    /// The index of the frame that the next `encode` call codes.
    pub fn next_frame(&self) -> u32 {
        self.inner.next_frame()
    }

    /// Makes the next frame frame `index`, which must start a group (a multiple of the intra
    /// period below the frame count), and forgets the earlier frames: from there on the
    /// encoder produces the units the sequential encoder does, so that the groups of a
    /// sequence can be encoded apart.
    ///
    /// Errors: [`Error::Input`] when `index` does not start a group.
    pub fn start_group(&mut self, index: u32) -> Result<(), Error> {
        Ok(self.inner.start_group(index)?)
    }

    /// Encodes the next frame (in the input's units, inside the header's box), deciding on its
    /// geometry alone.
    ///
    /// Errors: [`Error::Input`] for a malformed mesh (an index out of range, a coordinate that
    /// is not finite, no face with an area), a frame beyond the limits, or a frame past the
    /// announced count; the message names what is wrong.
    pub fn encode(&mut self, mesh: &Mesh) -> Result<EncodedFrame, Error> {
        Ok(self.inner.encode(mesh)?)
    }

    /// [`SequenceEncoder::encode`] for a frame of a textured stream: its intra/predicted
    /// decision weighs what its texture costs, which `texture_cost` gives (None: geometry
    /// alone). It is called at most once, after the predicted candidate is built (most of a
    /// frame's work), so that a texture stage can meanwhile finish the previous frame.
    ///
    /// Errors: as [`SequenceEncoder::encode`].
    pub fn encode_textured(&mut self, mesh: &Mesh, texture_cost: impl FnOnce() -> Option<TextureCost>) -> Result<EncodedFrame, Error> {
        Ok(self.inner.encode_textured(mesh, texture_cost)?)
    }
}
