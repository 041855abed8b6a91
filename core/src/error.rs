//! Errors of the public surface.

use thiserror::Error;

/// A bitstream that cannot be decoded. Always names where decoding stopped, so that a
/// user can tell a truncated file from a corrupted frame.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("{}byte offset {offset}: {reason}", frame.map(|f| format!("frame {f}, ")).unwrap_or_default())]
pub struct DecodeError {
    /// Index of the frame being decoded, `None` while reading the sequence header.
    pub frame: Option<u32>,
    /// Byte offset in the whole stream where the problem was found.
    pub offset: u64,
    /// What was wrong.
    pub reason: String,
}

impl DecodeError {
    pub fn new(frame: Option<u32>, offset: u64, reason: impl Into<String>) -> Self {
        Self { frame, offset, reason: reason.into() }
    }
}

/// Why a coded block (the base mesh, a UV atlas, range-coded data) cannot be decoded: the
/// one error of the block decoders. The caller names the block's place in the stream (a
/// [`DecodeError`] with frame and offset, or the texture unit).
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("{0}")]
pub struct Corrupt(pub String);

impl From<&'static str> for Corrupt {
    fn from(reason: &'static str) -> Self {
        Self(reason.into())
    }
}

impl From<String> for Corrupt {
    fn from(reason: String) -> Self {
        Self(reason)
    }
}

/// Input that the encoder refuses (a malformed mesh or an option out of range).
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("{0}")]
pub struct InputError(pub String);
