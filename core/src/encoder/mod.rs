//! The encoder: one input frame to one frame unit, plus the reconstruction that the
//! decoder will produce from it, deciding frame by frame in three steps, a module each:
//! which earlier frames a predicted frame may refer to ([`references`]), the ways of coding
//! the frame (intra, predicted, predicted with regions refreshed: [`candidates`]), and which
//! of them to keep ([`decision`]). Its options are [`config`].

mod candidates;
mod config;
mod decision;
mod references;

pub use config::{base_ratio_for_qp, EncoderConfig, FormatParams, LiftingChoice, SearchParams, MAX_REFERENCES};

use std::time::Instant;

use crate::error::InputError;
use crate::geom::bvh::Bvh;
use crate::geom::limits;
use crate::geom::mesh::Mesh;
use crate::geom::weld::{surface_faces, weld};
use crate::inter::anchor::PartMotions;
use crate::inter::tracking::{self, Bindings};
use crate::model::{base_in_world_units, FrameState};
use crate::residual::quantize;
use crate::stream::bitstream::{self, FrameType, SequenceHeader};

/// What encoding one frame produced.
#[derive(Debug, Clone)]
pub struct EncodedFrame {
    /// The complete frame unit, ready to append to the stream.
    pub unit: Vec<u8>,
    /// Exactly what the decoder will output for this frame.
    pub reconstruction: Mesh,
    /// The decoded base mesh, in the input's units: what the texture atlas of an intra
    /// frame is made on. `reconstruction` is its subdivision, face for face.
    pub base: Mesh,
    pub stats: FrameStats,
}

#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameStats {
    pub frame_type: Option<FrameType>,
    /// Frames back to the reference of a predicted frame; 0 for intra.
    pub reference_distance: u32,
    pub bytes: usize,
    /// Bytes of the base mesh (intra) or of its motion and refresh (predicted).
    pub base_bytes: usize,
    /// Base faces of a predicted frame coded intra by the refresh of its worst-fitting
    /// regions (0 when nothing was refreshed).
    pub refreshed_faces: usize,
    pub displacement_bytes: usize,
    pub base_vertices: usize,
    pub base_faces: usize,
    pub output_vertices: usize,
    pub output_faces: usize,
    /// Input faces left out for having no area or repeating another face
    /// (welding, `geom::weld`).
    pub dropped_faces: usize,
    /// Whether the input had the previous input's connectivity.
    pub same_topology: bool,
    /// The frame starts a texture group (intra, or its base faces are not the previous
    /// frame's): in a textured stream it gets a new atlas and a texture unit.
    pub starts_texture_group: bool,
    /// Bytes the other candidate (intra or predicted) would have cost; 0 if it was not coded.
    pub rejected_bytes: usize,
    /// Seconds spent making the predicted frame's base mesh (anchor or tracking).
    pub anchor_seconds: f64,
    pub seconds: f64,
}

/// The state a predicted frame refers to: the previous frame's input and base mesh.
struct Reference {
    /// Input in grid units.
    input: Mesh,
    /// Its base mesh and quantized coefficients, which a predicted frame may code its own
    /// against.
    state: FrameState,
    /// How the base was moved to this frame, when it was predicted.
    motion: Option<Motion>,
    /// Index of `input`'s faces.
    surface: Bvh,
}

/// How a predicted frame's base mesh was found, which the next frame builds on.
#[derive(Clone)]
enum Motion {
    /// Tracked on an input of constant connectivity: the base vertices' places on the input.
    Tracked(Bindings),
    /// By the anchor mesh, with the rigid motion of each part when it was aligned.
    Anchor(Option<PartMotions>),
}

impl Motion {
    /// The dead zone of the coefficient differences of a frame whose base moved this way.
    fn dead_zone(&self) -> f64 {
        match self {
            Self::Tracked(_) => quantize::TRACKED_DEAD_ZONE,
            Self::Anchor(_) => quantize::PREDICTED_DEAD_ZONE,
        }
    }
}

/// A candidate with what the decision needs and the next frames reuse.
struct Chosen {
    candidate: Candidate,
    /// Frames back to the reference; 0 for intra.
    reference_distance: u32,
    /// How the reference's base was moved onto this frame (predicted frames).
    motion: Option<Motion>,
}

/// One way of coding the current frame.
struct Candidate {
    /// Its fields before the displacements (a refreshed candidate repeats a predicted one's
    /// motion block).
    head: Head,
    payload: Vec<u8>,
    displacement_bytes: usize,
    state: FrameState,
    reconstruction: Mesh,
    /// Estimated distortion (see `SequenceEncoder::distortion`); 0 when it was not measured.
    distortion: f64,
}


/// The payload fields of a candidate that come before its displacements.
struct Head {
    frame_type: FrameType,
    reference_distance: u32,
    /// The base mesh block (intra) or the motion block (predicted).
    base_block: Vec<u8>,
    /// The refresh block (predicted frames; empty when nothing is refreshed).
    refresh_block: Vec<u8>,
    /// Faces of the patch the refresh block codes intra.
    refreshed_faces: usize,
}

impl Head {
    /// A head without a refresh.
    fn new(frame_type: FrameType, reference_distance: u32, base_block: Vec<u8>) -> Self {
        Self { frame_type, reference_distance, base_block, refresh_block: Vec::new(), refreshed_faces: 0 }
    }
}

/// Encodes the frames of one sequence in order, predicting from earlier frames of the group.
pub struct SequenceEncoder {
    header: SequenceHeader,
    config: EncoderConfig,
    frame: u32,
    /// The coded frames of the current group a predicted frame may refer to, oldest first:
    /// the last `config.search.references` frames and the latest intra frame.
    references: Vec<Stored>,
    /// Payload bytes and estimated distortion of the last frame coded intra.
    last_intra: Option<(usize, f64)>,
    /// The lowest estimated distortion of the group's frames coded intra (infinite before
    /// the first).
    best_intra: f64,
}

/// The bytes a textured frame's texture adds, which the frame type decides: a frame whose
/// base keeps the previous frame's connectivity continues the texture group (its atlas,
/// and a video frame predicted from the previous one); an intra frame, and a predicted one
/// whose base changed (refreshed, or moved from an older reference), starts a new group
/// (a new atlas, an intra video frame). The texture stage measures both as it goes
/// (`encode_textured`) so that the decision weighs them with the
/// geometry's bytes: texture is most of a textured stream.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TextureCost {
    pub continued: f64,
    pub restarted: f64,
}

/// A coded frame kept as a possible reference.
struct Stored {
    frame: u32,
    intra: bool,
    reference: Reference,
}

impl SequenceEncoder {
    /// An encoder for `frame_count` frames whose positions lie in the box `[min, max]`.
    pub fn new(config: EncoderConfig, frame_count: u32, min: [f64; 3], max: [f64; 3]) -> Result<Self, InputError> {
        config.validate()?;
        if !min.iter().chain(&max).all(|c| c.is_finite()) {
            return Err(InputError("bounding box must be finite".into()));
        }
        Ok(Self { header: config.header(frame_count, min, max), config, frame: 0, references: Vec::new(), last_intra: None, best_intra: f64::INFINITY })
    }

    pub fn header(&self) -> &SequenceHeader {
        &self.header
    }

    /// The index of the frame that [`Self::encode`] codes next.
    pub fn next_frame(&self) -> u32 {
        self.frame
    }

    /// Makes the next frame frame `index`, the first of a group (a multiple of the intra
    /// period), and forgets the references and the last intra frame. The first frame of a
    /// group is intra and reads neither, so from there on this encoder produces the units
    /// the sequential encoder does, and the groups of a sequence can be encoded apart. Only
    /// the `same_topology` statistic of that first frame differs: it has no previous input.
    pub fn start_group(&mut self, index: u32) -> Result<(), InputError> {
        let period = self.config.search.intra_period;
        if index % period != 0 || index >= self.header.frame_count {
            return Err(InputError(format!(
                "frame {index} does not start a group: groups start at multiples of the intra period {period} below {}",
                self.header.frame_count
            )));
        }
        self.frame = index;
        self.references.clear();
        self.last_intra = None;
        self.best_intra = f64::INFINITY;
        Ok(())
    }

    /// Encodes the next frame (in the input's units, inside the header's box), deciding on
    /// its geometry alone.
    pub fn encode(&mut self, mesh: &Mesh) -> Result<EncodedFrame, InputError> {
        self.encode_textured(mesh, || None)
    }

    /// Encodes the next frame of a textured stream, its decision weighing what its texture
    /// costs: `texture_cost` gives that ([`TextureCost`]; None: geometry alone). It is asked
    /// once the predicted candidate is built, most of a frame's work, so that a texture stage
    /// can meanwhile finish the previous frame's texture, which the cost may depend on.
    pub fn encode_textured(&mut self, mesh: &Mesh, texture_cost: impl FnOnce() -> Option<TextureCost>) -> Result<EncodedFrame, InputError> {
        let start = Instant::now();
        mesh.validate()?;
        limits::check_size(mesh)?;
        let welded = weld(mesh);
        let h = &self.header;
        let (input, _) = surface_faces(Mesh::new(welded.positions.iter().map(|&p| h.grid.to_grid(p)).collect(), welded.faces));
        if input.faces.is_empty() {
            return Err(InputError(format!(
                "every face is degenerate: the mesh has no area to code (each of its {} faces has corners that coincide \
                 or lie on one line once coincident vertices are merged)",
                mesh.faces.len()
            )));
        }
        limits::check_valence(&input)?;
        let target = Bvh::new(&input.positions, &input.faces);
        let same_topology = self.references.last().is_some_and(|s| tracking::same_connectivity(&s.reference.input, &input));
        let (predicted, anchor_seconds) = self.best_predicted(&input, &target)?;
        let (chosen, rejected_bytes) = self.choose(predicted, &input, &target, texture_cost)?;
        let starts_texture_group = self.starts_texture_group(&chosen.candidate);
        let unit = bitstream::write_unit(chosen.candidate.head.frame_type, &chosen.candidate.payload);
        let c = chosen.candidate;
        let stats = FrameStats {
            frame_type: Some(c.head.frame_type),
            reference_distance: chosen.reference_distance,
            bytes: unit.len(),
            base_bytes: c.head.base_block.len() + c.head.refresh_block.len(),
            refreshed_faces: c.head.refreshed_faces,
            displacement_bytes: c.displacement_bytes,
            base_vertices: c.state.base.len(),
            base_faces: c.state.faces.len(),
            output_vertices: c.reconstruction.positions.len(),
            output_faces: c.reconstruction.faces.len(),
            dropped_faces: mesh.faces.len() - input.faces.len(),
            same_topology,
            starts_texture_group,
            rejected_bytes,
            anchor_seconds,
            seconds: start.elapsed().as_secs_f64(),
        };
        let base = Mesh::new(base_in_world_units(&self.header, &c.state.base), c.state.faces.clone());
        let intra = c.head.frame_type == FrameType::Intra;
        let reference = Reference { input, state: c.state, motion: chosen.motion, surface: target };
        self.keep_reference(Stored { frame: self.frame, intra, reference });
        self.frame += 1;
        Ok(EncodedFrame { unit, reconstruction: c.reconstruction, base, stats })
    }
}
