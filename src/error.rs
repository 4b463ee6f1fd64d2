//! Errors that reach the user. Every user-facing failure is one line naming the file,
//! the field or item, and what is wrong; the CLI maps input errors to exit code 2.

use std::fmt;

/// An error caused by bad input (scene, mesh, checkpoint, command line): exit code 2.
#[derive(Debug, Clone, PartialEq)]
pub struct InputError {
    /// File the problem is in (scene path, mesh path, checkpoint), or `<command line>`.
    pub file: String,
    /// Dotted field path or item name (`grains[2].radius`, `element 17`).
    pub item: String,
    /// What is wrong, in words, with the offending value where it helps.
    pub message: String,
}

impl InputError {
    pub fn new(
        file: impl Into<String>,
        item: impl Into<String>,
        message: impl Into<String>,
    ) -> Self {
        Self {
            file: file.into(),
            item: item.into(),
            message: message.into(),
        }
    }
}

impl fmt::Display for InputError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.item.is_empty() {
            write!(f, "{}: {}", self.file, self.message)
        } else {
            write!(f, "{}: {}: {}", self.file, self.item, self.message)
        }
    }
}

impl std::error::Error for InputError {}

/// Any failure of a run. `Input` → exit 2; everything else → exit 1.
#[derive(Debug)]
pub enum MufeError {
    Input(InputError),
    /// The simulation itself failed (blow-up, tunnelling detected, ...): names time, step, item.
    Run(String),
    /// I/O or HDF5 failure while writing results.
    Io(String),
}

impl fmt::Display for MufeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MufeError::Input(e) => write!(f, "{e}"),
            MufeError::Run(m) => write!(f, "{m}"),
            MufeError::Io(m) => write!(f, "{m}"),
        }
    }
}

impl std::error::Error for MufeError {}

impl From<InputError> for MufeError {
    fn from(e: InputError) -> Self {
        MufeError::Input(e)
    }
}

impl MufeError {
    /// Process exit code for this error (DESIGN.md §1: bad input → 2).
    pub fn exit_code(&self) -> i32 {
        match self {
            MufeError::Input(_) => 2,
            _ => 1,
        }
    }
}

pub type Result<T, E = MufeError> = std::result::Result<T, E>;
