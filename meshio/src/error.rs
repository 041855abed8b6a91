//! The one error of the readers: a message and, when one line is to blame, its number.
//! The bindings hand both to Python as `MeshFormatError(message, line)`, which `dynmesh.io`
//! turns into `MeshError(path, message, line)`, so the texts here are what users read.

use std::fmt;

/// Why a mesh file cannot be read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FormatError {
    /// What is wrong, in a sentence without the file's name (the caller knows it).
    pub message: String,
    /// The 1-based line to blame, or None when the file as a whole is at fault (or, in a
    /// binary PLY, when the message names the record instead).
    pub line: Option<usize>,
}

/// What a reader returns.
pub type Result<T> = std::result::Result<T, FormatError>;

pub(crate) fn at_line(line: usize, message: String) -> FormatError {
    FormatError { message, line: Some(line) }
}

pub(crate) fn whole_file(message: String) -> FormatError {
    FormatError { message, line: None }
}

impl fmt::Display for FormatError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(line) => write!(f, "line {line}: {}", self.message),
            None => f.write_str(&self.message),
        }
    }
}

impl std::error::Error for FormatError {}
