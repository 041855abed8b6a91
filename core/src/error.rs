//! Errors: [`Error`], the one error of the public API, and the internal errors it is made from
//! ([`InputError`], [`DecodeError`], [`Corrupt`]), which the stages return.

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

/// The error of the public API ([`crate::encode`], [`crate::decode`], [`crate::texturing`]):
/// which of four things went wrong, so that a caller can tell its own mistake from a damaged
/// stream, a stream this build cannot read, and a bug.
///
/// Every variant displays as one sentence for a user. Conversions from the core's internal
/// errors: an input error becomes [`Error::Input`], a decoding error [`Error::Decode`]
/// (frame and offset kept), a corrupt block given on its own [`Error::Decode`] without a
/// place in a stream.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[non_exhaustive]
pub enum Error {
    /// Input the encoder or a function refuses: a malformed mesh (an index out of range, a
    /// coordinate that is not finite, no area to code), a frame beyond the limits, an option
    /// out of range, a call out of order. The message names what is wrong.
    #[error("{0}")]
    Input(String),
    /// Data that cannot be decoded: a truncated or corrupted stream, frame unit or coded
    /// block. `frame` is the frame being decoded (None while reading the sequence header, or
    /// for a block given on its own); `offset` the byte offset in the whole stream where
    /// decoding stopped (None for a block given on its own).
    #[error("{}{}{reason}", frame.map(|f| format!("frame {f}, ")).unwrap_or_default(), offset.map(|o| format!("byte offset {o}: ")).unwrap_or_default())]
    Decode {
        /// The frame being decoded.
        frame: Option<u32>,
        /// Byte offset in the stream where the problem was found.
        offset: Option<u64>,
        /// What was wrong.
        reason: String,
    },
    /// Well-formed data this build does not read: a stream of another format version, a
    /// texture unit of another version or of a video codec it does not know. The message
    /// says which, and where.
    #[error("{0}")]
    Unsupported(String),
    /// A bug in dynmesh: a condition the code should have made impossible (a panic, caught at
    /// a boundary such as the Python bindings). The message says so and asks for a report.
    #[error("internal error (a bug in dynmesh, please report it): {0}")]
    Internal(String),
}

impl Error {
    /// The [`Error::Internal`] of a caught panic, with the panic's message when it has one.
    pub fn from_panic(payload: &(dyn std::any::Any + Send)) -> Self {
        let message = payload
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "a panic without a message".into());
        Self::Internal(message)
    }
}

impl From<InputError> for Error {
    fn from(e: InputError) -> Self {
        Self::Input(e.0)
    }
}

impl From<DecodeError> for Error {
    fn from(e: DecodeError) -> Self {
        Self::Decode { frame: e.frame, offset: Some(e.offset), reason: e.reason }
    }
}

impl From<Corrupt> for Error {
    fn from(e: Corrupt) -> Self {
        Self::Decode { frame: None, offset: None, reason: e.0 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn internal_errors_convert_to_the_public_error_and_keep_their_text() {
        let input = InputError("face 3 refers to a vertex that does not exist".into());
        assert_eq!(Error::from(input.clone()), Error::Input(input.0.clone()));
        assert_eq!(Error::from(input.clone()).to_string(), input.to_string());

        let decode = DecodeError::new(Some(4), 1234, "CRC mismatch");
        let e = Error::from(decode.clone());
        assert_eq!(e, Error::Decode { frame: Some(4), offset: Some(1234), reason: "CRC mismatch".into() });
        assert_eq!(e.to_string(), decode.to_string());
        assert_eq!(e.to_string(), "frame 4, byte offset 1234: CRC mismatch");
        let header = DecodeError::new(None, 0, "not a dynmesh stream (bad magic)");
        assert_eq!(Error::from(header.clone()).to_string(), header.to_string());

        let corrupt = Corrupt::from("UV atlas is truncated");
        assert_eq!(Error::from(corrupt.clone()), Error::Decode { frame: None, offset: None, reason: corrupt.0.clone() });
        assert_eq!(Error::from(corrupt).to_string(), "UV atlas is truncated");
    }

    #[test]
    fn a_caught_panic_is_an_internal_error_that_says_it_is_a_bug() {
        let payload = std::panic::catch_unwind(|| panic!("index {} out of range", 7)).unwrap_err();
        let e = Error::from_panic(payload.as_ref());
        assert_eq!(e, Error::Internal("index 7 out of range".into()));
        assert!(e.to_string().starts_with("internal error (a bug in dynmesh, please report it): "), "{e}");
        let payload = std::panic::catch_unwind(|| panic!("plain")).unwrap_err();
        assert_eq!(Error::from_panic(payload.as_ref()), Error::Internal("plain".into()));
    }
}
