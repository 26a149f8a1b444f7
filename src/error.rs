//! The one error type of the library. Every failure that input can cause is a variant here,
//! with a message that names the problem; nothing reachable from input panics.

use std::path::PathBuf;

/// Everything that can go wrong in mesobake's library code.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A parameter (resolution, direction grid, option value) is out of its valid range.
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
    /// An allocation would exceed the configured memory limit; refused before allocating.
    #[error(
        "{what} would need {needed} bytes, over the memory limit of {limit} bytes \
         (raise it with --memory-limit or MESOBAKE_MEMORY_LIMIT)"
    )]
    MemoryLimit {
        /// What was about to be allocated.
        what: String,
        /// Bytes it would take.
        needed: u64,
        /// The configured limit.
        limit: u64,
    },
    /// A mesostructure volume file is malformed.
    #[error("volume file: {0}")]
    VolumeFormat(String),
    /// An OBJ mesostructure tile is malformed or unusable.
    #[error("OBJ tile: {0}")]
    MeshTile(String),
    /// A base mesh (OBJ file or built-in) is malformed, unusable or has invalid parameters.
    #[error("base mesh: {0}")]
    BaseMesh(String),
    /// A scene file is malformed or names something unusable.
    #[error("scene: {0}")]
    Scene(String),
    /// A `.mbpkg` package is malformed, corrupt or of an unsupported version.
    #[error("package: {0}")]
    Package(String),
    /// Reading or writing a file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file involved.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// No GPU adapter, or the GPU refused a resource or a pipeline.
    #[error("GPU: {0}")]
    Gpu(String),
    /// The database refused or failed a query.
    #[error("database: {0}")]
    Database(String),
    /// The caller asked the operation to stop.
    #[error("cancelled")]
    Cancelled,
}

/// Result with mesobake's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// Wraps an I/O error with the path it concerns.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
}
