//! The viewer's error type.

use fibfluid_interact::{InteractError, Method};

/// What can go wrong while starting or running the viewer.
#[derive(Debug, thiserror::Error)]
pub enum ViewerError {
    /// The address cannot be resolved or bound.
    #[error("cannot listen on {addr}: {source}")]
    Bind {
        /// The address asked for.
        addr: String,
        /// Why.
        source: std::io::Error,
    },
    /// A method this server cannot build.
    #[error("method `{method}` is not available in this viewer (available: {available})")]
    UnsupportedMethod {
        /// The method asked for.
        method: String,
        /// The methods it can build, comma separated.
        available: String,
    },
    /// The body of a method could not be built.
    #[error("cannot build the {method} body: {source}")]
    Body {
        /// The method.
        method: Method,
        /// Why.
        source: InteractError,
    },
    /// The body of a method could not be built for a reason of the method's own.
    #[error("cannot build the {method} body: {source}")]
    Build {
        /// The method.
        method: Method,
        /// Why.
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// The mesh and the body do not describe the same surface.
    #[error("the mesh and the body disagree: {problem}")]
    Mismatch {
        /// What differs.
        problem: String,
    },
    /// Accepting a connection failed.
    #[error("viewer: {0}")]
    Io(#[from] std::io::Error),
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, ViewerError>;
