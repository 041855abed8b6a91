//! The frame payload: the fields inside a frame unit, written by the encoder and read by the
//! decoder through this one pair of functions (`docs/bitstream.md`, "Frame payload").
//!
//! Intra: QP, base mesh block, coefficient block. Predicted: reference distance, QP, motion
//! block, mode (coefficient differences, refresh), refresh block if any, coefficient block.
//! The fields and codes are declared in [`syntax`](super::syntax) (`INTRA_PAYLOAD`,
//! `PREDICTED_PAYLOAD`).

use crate::error::DecodeError;
use crate::stream::bitstream::{FrameType, Reader, Unit, Writer};
use crate::stream::syntax::{MODE_COEFFICIENT_DIFFERENCES, MODE_MAX, MODE_REFRESH, QP_MAX, QP_MIN};

/// The fields of a frame payload.
#[derive(Debug, Clone, PartialEq)]
pub struct Payload<'a> {
    /// Frames back to the reference (predicted frames; 0 for intra, where it is not written).
    pub reference_distance: u32,
    pub qp: i32,
    /// The base mesh block (intra) or the motion block (predicted).
    pub base: &'a [u8],
    /// Predicted frames: the refresh block, empty when no region is refreshed.
    pub refresh: &'a [u8],
    /// Predicted frames: the coefficients are differences from the reference's (mode 1).
    pub coefficients_predicted: bool,
    pub coefficients: &'a [u8],
}

/// Where a read payload's blocks start in the stream, for error messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Offsets {
    pub base: u64,
    pub refresh: u64,
    pub coefficients: u64,
}

impl<'a> Payload<'a> {
    /// The payload's bytes for a frame of type `frame_type`; the fields intra frames do
    /// not carry (reference distance, mode, refresh block) are not written.
    pub fn to_bytes(&self, frame_type: FrameType) -> Vec<u8> {
        let mut w = Writer::default();
        let predicted = frame_type == FrameType::Predicted;
        if predicted {
            w.u32(self.reference_distance);
        }
        w.i32(self.qp);
        w.block(self.base);
        if predicted {
            let refreshed = !self.refresh.is_empty();
            let differences = if self.coefficients_predicted { MODE_COEFFICIENT_DIFFERENCES } else { 0 };
            w.u8(differences | if refreshed { MODE_REFRESH } else { 0 });
            if refreshed {
                w.block(self.refresh);
            }
        }
        w.block(self.coefficients);
        w.bytes
    }

    /// Splits the payload of `unit`, frame `frame`, into its fields, checking that the
    /// reference distance names an earlier frame, the QP is in range, the mode is known and no
    /// bytes follow the last block.
    pub fn read(unit: &Unit<'a>, frame: u32) -> Result<(Self, Offsets), DecodeError> {
        let mut r = Reader::new(unit.payload, unit.offset, Some(frame));
        let predicted = unit.frame_type == FrameType::Predicted;
        let reference_distance = if predicted { reference_distance(&mut r, frame)? } else { 0 };
        let qp = r.i32("QP")?;
        if !(QP_MIN..=QP_MAX).contains(&qp) {
            return Err(r.error(format!("QP {qp} out of range")));
        }
        let (base, base_offset) = r.block("base mesh")?;
        let (coefficients_predicted, refreshed) = if predicted { predicted_mode(&mut r)? } else { (false, false) };
        let (refresh, refresh_offset) = if refreshed { r.block("refresh")? } else { (&[][..], 0) };
        if refreshed && refresh.is_empty() {
            return Err(r.error("empty refresh block"));
        }
        let (coefficients, coefficients_offset) = r.block("displacements")?;
        if r.remaining() != 0 {
            return Err(r.error("unexpected bytes at the end of the frame"));
        }
        let payload = Self { reference_distance, qp, base, refresh, coefficients_predicted, coefficients };
        Ok((payload, Offsets { base: base_offset, refresh: refresh_offset, coefficients: coefficients_offset }))
    }
}

fn reference_distance(r: &mut Reader, frame: u32) -> Result<u32, DecodeError> {
    let d = r.u32("reference distance")?;
    if d == 0 || d > frame {
        return Err(r.error(format!("reference distance {d} does not name an earlier frame")));
    }
    Ok(d)
}

/// A predicted frame's mode: whether its coefficients are coded as differences from the
/// reference's (bit 0) and whether a refresh block follows (bit 1).
fn predicted_mode(r: &mut Reader) -> Result<(bool, bool), DecodeError> {
    match r.u8("predicted frame mode")? {
        m @ 0..=MODE_MAX => Ok((m & MODE_COEFFICIENT_DIFFERENCES != 0, m & MODE_REFRESH != 0)),
        m => Err(r.error(format!("unknown predicted frame mode {m}"))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit(frame_type: FrameType, payload: &[u8]) -> Unit<'_> {
        Unit { frame_type, payload, offset: 100, texture: None }
    }

    #[test]
    fn payloads_round_trip() {
        let intra = Payload { reference_distance: 0, qp: 28, base: &[1, 2, 3], refresh: &[], coefficients_predicted: false, coefficients: &[4] };
        let bytes = intra.to_bytes(FrameType::Intra);
        assert_eq!(bytes.len(), 4 + 4 + 3 + 4 + 1);
        let (read, offsets) = Payload::read(&unit(FrameType::Intra, &bytes), 0).unwrap();
        assert_eq!(read, intra);
        assert_eq!(offsets, Offsets { base: 108, refresh: 0, coefficients: 115 });

        let predicted = Payload { reference_distance: 2, qp: -3, base: &[], refresh: &[], coefficients_predicted: true, coefficients: &[9, 9] };
        let bytes = predicted.to_bytes(FrameType::Predicted);
        let (read, _) = Payload::read(&unit(FrameType::Predicted, &bytes), 5).unwrap();
        assert_eq!(read, predicted);

        let refreshed = Payload { refresh: &[5, 6], ..predicted.clone() };
        let bytes = refreshed.to_bytes(FrameType::Predicted);
        let (read, offsets) = Payload::read(&unit(FrameType::Predicted, &bytes), 5).unwrap();
        assert_eq!(read, refreshed);
        assert_eq!(offsets.refresh, 100 + 4 + 4 + 4 + 1 + 4);
    }

    #[test]
    fn bad_fields_are_refused_with_their_offset() {
        let p = Payload { reference_distance: 3, qp: 28, base: &[1], refresh: &[], coefficients_predicted: false, coefficients: &[] };
        let bytes = p.to_bytes(FrameType::Predicted);
        let e = Payload::read(&unit(FrameType::Predicted, &bytes), 2).unwrap_err();
        assert!(e.reason.contains("reference distance 3"), "{e}");
        assert_eq!((e.frame, e.offset), (Some(2), 104));

        let mut mode = bytes.clone();
        mode[4 + 4 + 4 + 1] = 7;
        let e = Payload::read(&unit(FrameType::Predicted, &mode), 3).unwrap_err();
        assert!(e.reason.contains("unknown predicted frame mode 7"), "{e}");

        let mut empty = bytes.clone();
        empty[4 + 4 + 4 + 1] = 2;
        empty.splice(4 + 4 + 4 + 1 + 1..4 + 4 + 4 + 1 + 1, [0; 4]);
        let e = Payload::read(&unit(FrameType::Predicted, &empty), 3).unwrap_err();
        assert!(e.reason.contains("empty refresh block"), "{e}");

        let qp = Payload { qp: 1000, ..p.clone() }.to_bytes(FrameType::Intra);
        assert!(Payload::read(&unit(FrameType::Intra, &qp), 0).unwrap_err().reason.contains("QP 1000"));

        let mut long = p.to_bytes(FrameType::Intra);
        long.push(0);
        assert!(Payload::read(&unit(FrameType::Intra, &long), 0).unwrap_err().reason.contains("unexpected bytes"));
        let short = &p.to_bytes(FrameType::Intra)[..6];
        assert!(Payload::read(&unit(FrameType::Intra, short), 0).is_err());
    }
}
