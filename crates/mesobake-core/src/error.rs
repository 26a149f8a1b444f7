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
    /// The adapter cuts loops short (see `Gpu::loop_budget`), and the render needed or
    /// may need more.
    #[error(
        "GPU: {adapter} runs at most {budget} loop iterations per shader invocation, and \
         {what}; the image would be wrong"
    )]
    LoopBudget {
        /// The adapter.
        adapter: String,
        /// Its budget.
        budget: u32,
        /// What needed more: "150 pixels needed more (…)".
        what: String,
    },
    /// The database refused or failed a query.
    #[error("database: {0}")]
    Database(String),
    /// The storage of the database or the files is full (or below the reserve kept free).
    #[error("storage full: {0}")]
    StorageFull(String),
    /// The caller asked the operation to stop.
    #[error("cancelled")]
    Cancelled,
}

impl From<mesobake_package::Error> for Error {
    fn from(e: mesobake_package::Error) -> Self {
        match e {
            mesobake_package::Error::InvalidParameter(m) => Error::InvalidParameter(m),
            mesobake_package::Error::Package(m) => Error::Package(m),
            mesobake_package::Error::MemoryLimit {
                what,
                needed,
                limit,
            } => Error::MemoryLimit {
                what,
                needed,
                limit,
            },
            mesobake_package::Error::Io { path, source } => Error::Io { path, source },
        }
    }
}

/// Result with mesobake's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// The same error with `context` (the file it concerns, say) before its message, the
    /// kind's prefix said once: "scene: a.json: …", not "scene: a.json: scene: …". Errors
    /// that already name their subject (memory limit, I/O) and cancellations are unchanged.
    pub fn context(self, context: impl std::fmt::Display) -> Self {
        let with = |m: String| format!("{context}: {m}");
        match self {
            Error::InvalidParameter(m) => Error::InvalidParameter(with(m)),
            Error::VolumeFormat(m) => Error::VolumeFormat(with(m)),
            Error::MeshTile(m) => Error::MeshTile(with(m)),
            Error::BaseMesh(m) => Error::BaseMesh(with(m)),
            Error::Scene(m) => Error::Scene(with(m)),
            Error::Package(m) => Error::Package(with(m)),
            Error::Gpu(m) => Error::Gpu(with(m)),
            Error::Database(m) => Error::Database(with(m)),
            Error::StorageFull(m) => Error::StorageFull(with(m)),
            e @ (Error::MemoryLimit { .. }
            | Error::Io { .. }
            | Error::LoopBudget { .. }
            | Error::Cancelled) => e,
        }
    }

    /// Wraps an I/O error with the path it concerns.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Error;

    #[test]
    fn context_says_the_kind_once() {
        let e = Error::Scene("resolution must be positive".into()).context("a.json");
        assert_eq!(e.to_string(), "scene: a.json: resolution must be positive");
        let e = Error::InvalidParameter("height field PNG: 16-bit".into()).context("h.png");
        assert_eq!(
            e.to_string(),
            "invalid parameter: h.png: height field PNG: 16-bit"
        );
        let io = Error::io("x", std::io::Error::other("gone")).context("ignored");
        assert_eq!(io.to_string(), "x: gone");
    }
}
