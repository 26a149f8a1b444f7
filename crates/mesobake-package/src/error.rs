//! The crate's error type: every way a package, a grid or a file can be refused, with a
//! message that names the problem.

use std::path::PathBuf;

/// Everything that can go wrong reading, validating or writing a package.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A parameter (resolution, direction grid, option value) is out of its valid range.
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
    /// Reading a package would take more memory than the caller allows; refused before
    /// allocating.
    #[error("{what} would need {needed} bytes, over the memory limit of {limit} bytes")]
    MemoryLimit {
        /// What was about to be allocated.
        what: String,
        /// Bytes it would take.
        needed: u64,
        /// The caller's limit.
        limit: u64,
    },
    /// A package is malformed, corrupt or of an unsupported version.
    #[error("package: {0}")]
    Package(String),
    /// Reading a file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file involved.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
}

/// Result with this crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
