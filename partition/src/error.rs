//! The single error type of this crate.
//!
//! Every fallible function returns [`PartitionError`]; its `Display` output is
//! one line that names what was wrong (and, for files, the path and line) so it
//! can be shown to the user as is.

use std::fmt;
use std::path::PathBuf;

/// Everything that can go wrong while building, partitioning, measuring or
/// reading/writing a grain partition.
#[derive(Debug, Clone, PartialEq)]
pub enum PartitionError {
    /// The requested number of parts cannot be used for this graph
    /// (zero parts, or more parts than grains).
    InvalidPartCount {
        /// Number of parts that was requested.
        parts: usize,
        /// Number of grains (graph vertices) available.
        grains: usize,
    },
    /// A grain description is unusable (non-finite centre, negative radius, ...).
    InvalidGrain {
        /// Index of the offending grain in the input slice.
        grain: usize,
        /// What is wrong with it.
        reason: String,
    },
    /// A graph, cost model or part assignment is internally inconsistent.
    InvalidInput(String),
    /// The graph does not fit METIS' 32-bit integer types.
    TooLarge(String),
    /// METIS itself reported an error.
    Metis(String),
    /// A partition file could not be opened, read or written.
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The operating-system error message.
        message: String,
    },
    /// A partition file was read but its contents are malformed.
    Parse {
        /// The file concerned.
        path: PathBuf,
        /// 1-based line number, or `None` when the problem concerns the whole
        /// file (e.g. a grain that never appears).
        line: Option<usize>,
        /// What is wrong.
        message: String,
    },
}

impl fmt::Display for PartitionError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::InvalidPartCount { parts, grains } => {
                if *parts == 0 {
                    write!(f, "cannot partition into 0 parts; at least 1 is required")
                } else {
                    write!(
                        f,
                        "cannot partition {grains} grains into {parts} parts: \
                         every part needs at least one grain (use at most {grains} parts)"
                    )
                }
            }
            Self::InvalidGrain { grain, reason } => write!(f, "grain {grain}: {reason}"),
            Self::InvalidInput(message) => write!(f, "invalid input: {message}"),
            Self::TooLarge(message) => write!(f, "graph too large for METIS: {message}"),
            Self::Metis(message) => write!(f, "METIS failed: {message}"),
            Self::Io { path, message } => write!(f, "{}: {message}", path.display()),
            Self::Parse {
                path,
                line: Some(line),
                message,
            } => write!(f, "{}:{line}: {message}", path.display()),
            Self::Parse {
                path,
                line: None,
                message,
            } => write!(f, "{}: {message}", path.display()),
        }
    }
}

impl std::error::Error for PartitionError {}
