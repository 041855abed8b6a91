//! Damaged streams: which frame units survive, and which frame each of them is.
//!
//! [`read_units`](super::bitstream::read_units) refuses a stream at its first bad unit. A video decoder would
//! rather play every frame that does not depend on the damage, so [`scan_units`] walks the
//! same units without giving up: a unit whose CRC fails is skipped by its length field when
//! a valid unit (or the end of the stream) follows there, which is the usual case of damaged
//! payload bytes. When the length itself is damaged, the scan looks for the next position
//! where a unit with a matching CRC starts (resynchronisation), within a budget of hashed
//! bytes proportional to the stream size, so that a hostile stream costs linear work.
//!
//! The format has no frame numbers, so frames are numbered by counting units: forward from
//! the header up to the first damaged region whose unit count is unknown, and backward from
//! the end of the stream (the header gives the frame count) after the last one. Frames that
//! neither count reaches are reported damaged: a frame is never decoded under a number that
//! might not be its own.

use crate::stream::bitstream::FrameType;
use crate::stream::syntax::{FRAME_INTRA, FRAME_PREDICTED, TEXTURE_UNIT, UNIT_LENGTH_AT, UNIT_OVERHEAD, UNIT_PAYLOAD_AT};

/// Bytes of a unit's CRC, after its payload.
const CRC_LEN: usize = UNIT_OVERHEAD - UNIT_PAYLOAD_AT;

/// Bytes the resynchronising search may hash, per byte of stream (plus a floor).
const RESYNC_BUDGET_PER_BYTE: usize = 64;
const RESYNC_BUDGET_FLOOR: usize = 1 << 20;

/// A damaged stretch of the stream and the frames it took with it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Damage {
    /// Byte offsets of the damaged stretch in the whole stream, `[start, end)`.
    pub start: u64,
    pub end: u64,
    pub reason: String,
}

/// What happened to one frame's texture unit.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum TextureSlot {
    None,
    /// Payload offset and length.
    Intact(usize, usize),
    /// The frame had (or may have had) a texture unit, which is damaged.
    Damaged(usize),
}

/// One frame's unit: intact (type, payload offset and length, texture) or lost.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum FrameSlot {
    Intact { frame_type: FrameType, offset: usize, len: usize, texture: TextureSlot },
    Damaged(Damage),
}

/// What a damaged region is known to hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    /// Exactly one frame unit (its type byte said so and its length led to a valid unit).
    Frame,
    /// Exactly one texture unit.
    Texture,
    /// Any number of units.
    Unknown,
}

#[derive(Debug, Clone)]
enum Item {
    Frame { frame_type: FrameType, offset: usize, len: usize },
    Texture { offset: usize, len: usize },
    Gap { kind: Kind, damage: Damage },
}

/// Every frame slot of the stream whose units start at `start`, for a header announcing
/// `frame_count` frames (which the caller has bounded by the stream size).
pub fn scan_units(data: &[u8], start: usize, frame_count: u32) -> Vec<FrameSlot> {
    let mut items = itemize(data, start);
    let known: usize = items.iter().map(|i| matches!(i, Item::Frame { .. } | Item::Gap { kind: Kind::Frame, .. }) as usize).sum();
    let has_unknown = items.iter().any(|i| matches!(i, Item::Gap { kind: Kind::Unknown, .. }));
    if !has_unknown && known != frame_count as usize {
        // A damaged type byte or a trailing stretch: the typed gaps cannot be trusted.
        for i in &mut items {
            if let Item::Gap { kind, .. } = i {
                *kind = Kind::Unknown;
            }
        }
        if !items.iter().any(|i| matches!(i, Item::Gap { .. })) {
            let end = data.len() as u64;
            let reason = format!("the stream holds {known} frame units where the header announces {frame_count}");
            items.push(Item::Gap { kind: Kind::Unknown, damage: Damage { start: end, end, reason } });
        }
    }
    number_frames(&items, frame_count as usize)
}

/// The stream after the header as intact units and damaged gaps, in order.
fn itemize(data: &[u8], start: usize) -> Vec<Item> {
    let mut items = Vec::new();
    let mut budget = data.len().saturating_mul(RESYNC_BUDGET_PER_BYTE).max(RESYNC_BUDGET_FLOOR);
    let mut pos = start;
    while pos < data.len() {
        // Reading units in order hashes each byte once: only the search is budgeted.
        let mut unbounded = usize::MAX;
        match check_unit(data, pos, &mut unbounded) {
            Ok((t, len)) => {
                let offset = pos + UNIT_PAYLOAD_AT;
                items.push(match t {
                    FRAME_INTRA => Item::Frame { frame_type: FrameType::Intra, offset, len },
                    FRAME_PREDICTED => Item::Frame { frame_type: FrameType::Predicted, offset, len },
                    TEXTURE_UNIT => Item::Texture { offset, len },
                    t => gap(pos, pos + UNIT_OVERHEAD + len, Kind::Unknown, format!("unit type {t}")),
                });
                pos += UNIT_OVERHEAD + len;
            }
            Err(reason) => {
                let (end, kind) = skip_damaged(data, pos, &mut budget);
                items.push(gap(pos, end, kind, reason));
                pos = end;
            }
        }
    }
    items
}

fn gap(start: usize, end: usize, kind: Kind, reason: String) -> Item {
    Item::Gap { kind, damage: Damage { start: start as u64, end: end as u64, reason } }
}

/// Where the damaged unit at `pos` ends and what it held: by its own length when a valid
/// unit or the end of the stream follows there, else at the next valid unit.
fn skip_damaged(data: &[u8], pos: usize, budget: &mut usize) -> (usize, Kind) {
    if let Some(next) = claimed_end(data, pos) {
        if next == data.len() || check_unit(data, next, budget).is_ok() {
            let kind = match data[pos] {
                FRAME_INTRA | FRAME_PREDICTED => Kind::Frame,
                TEXTURE_UNIT => Kind::Texture,
                _ => Kind::Unknown,
            };
            return (next, kind);
        }
    }
    let mut q = pos + 1;
    while q < data.len() && *budget > 0 && check_unit(data, q, budget).is_err() {
        q += 1;
    }
    // An exhausted budget gives up on the rest of the stream.
    (if *budget == 0 { data.len() } else { q }, Kind::Unknown)
}

/// The end of the unit at `pos` according to its length field, if that lies in the stream.
fn claimed_end(data: &[u8], pos: usize) -> Option<usize> {
    let len = u32::from_le_bytes(data.get(pos + UNIT_LENGTH_AT..pos + UNIT_PAYLOAD_AT)?.try_into().ok()?) as usize;
    let end = pos.checked_add(UNIT_OVERHEAD)?.checked_add(len)?;
    (end <= data.len()).then_some(end)
}

/// The type and payload length of a unit at `pos` whose length fits and whose CRC matches;
/// hashing costs `budget`.
fn check_unit(data: &[u8], pos: usize, budget: &mut usize) -> Result<(u8, usize), String> {
    let Some(end) = claimed_end(data, pos) else {
        return Err(if data.len() - pos < UNIT_OVERHEAD { "truncated unit".into() } else { "unit length runs past the end of the stream".into() });
    };
    let t = data[pos];
    if t > TEXTURE_UNIT {
        return Err(format!("unit type {t}"));
    }
    let body = &data[pos..end - CRC_LEN];
    *budget = budget.saturating_sub(body.len());
    let crc = u32::from_le_bytes(data[end - CRC_LEN..end].try_into().expect("four bytes"));
    if crc != crc32fast::hash(body) {
        return Err("unit CRC mismatch (corrupted data)".into());
    }
    Ok((t, end - pos - UNIT_OVERHEAD))
}

/// Gives each frame its slot: counted forward up to the first unknown gap, backward after
/// the last one; the frames between are damaged by the gaps.
fn number_frames(items: &[Item], frame_count: usize) -> Vec<FrameSlot> {
    let first_unknown = items.iter().position(|i| matches!(i, Item::Gap { kind: Kind::Unknown, .. }));
    let Some(first) = first_unknown else { return count_forward(items, frame_count) };
    let last = items.iter().rposition(|i| matches!(i, Item::Gap { kind: Kind::Unknown, .. })).expect("one exists");
    let mut head = count_forward(&items[..first], frame_count);
    let mut tail = count_forward(&items[last + 1..], frame_count);
    if head.len() + tail.len() > frame_count {
        // More units than frames: the numbering cannot be trusted past the first gap.
        tail.clear();
    }
    let damage = merged_damage(&items[first..=last]);
    if let (Some(FrameSlot::Intact { texture, .. }), Some(Item::Frame { .. })) = (head.last_mut(), first.checked_sub(1).map(|p| &items[p])) {
        // The gap may have swallowed this frame's texture unit.
        if *texture == TextureSlot::None && textured(items) {
            *texture = TextureSlot::Damaged(damage.start as usize);
        }
    }
    let lost = frame_count - head.len() - tail.len();
    head.extend(std::iter::repeat(FrameSlot::Damaged(damage)).take(lost));
    head.extend(tail);
    head
}

/// The slots of `items`, which holds no unknown gap, numbered from 0; at most `limit`.
fn count_forward(items: &[Item], limit: usize) -> Vec<FrameSlot> {
    let mut slots: Vec<FrameSlot> = Vec::new();
    for item in items {
        match item {
            Item::Frame { frame_type, offset, len } => {
                slots.push(FrameSlot::Intact { frame_type: *frame_type, offset: *offset, len: *len, texture: TextureSlot::None })
            }
            Item::Gap { kind: Kind::Frame, damage } => slots.push(FrameSlot::Damaged(damage.clone())),
            Item::Texture { offset, len } => attach(&mut slots, TextureSlot::Intact(*offset, *len)),
            Item::Gap { kind: _, damage } => attach(&mut slots, TextureSlot::Damaged(damage.start as usize)),
        }
    }
    slots.truncate(limit);
    slots
}

/// Gives the texture unit to the frame before it (a texture unit that follows a damaged
/// frame, or none, goes with it).
fn attach(slots: &mut [FrameSlot], t: TextureSlot) {
    if let Some(FrameSlot::Intact { texture, .. }) = slots.last_mut() {
        if *texture == TextureSlot::None {
            *texture = t;
        }
    }
}

fn textured(items: &[Item]) -> bool {
    items.iter().any(|i| matches!(i, Item::Texture { .. } | Item::Gap { kind: Kind::Texture, .. }))
}

/// One damage record for the region from the first to the last unknown gap.
fn merged_damage(items: &[Item]) -> Damage {
    let gaps: Vec<&Damage> = items.iter().filter_map(|i| if let Item::Gap { damage, .. } = i { Some(damage) } else { None }).collect();
    let reason = if gaps.len() == 1 { gaps[0].reason.clone() } else { format!("{} damaged stretches; first: {}", gaps.len(), gaps[0].reason) };
    Damage { start: gaps[0].start, end: gaps[gaps.len() - 1].end, reason }
}
