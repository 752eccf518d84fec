//! The facade's error type.

use std::path::PathBuf;

/// Everything that can go wrong in a fibfluid run.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A scene file is malformed or holds an invalid value.
    #[error("{path}: {message}")]
    Scene {
        /// The scene file.
        path: PathBuf,
        /// What is wrong, naming the key.
        message: String,
    },
    /// A mesh file could not be read or is not a valid closed surface.
    #[error(transparent)]
    Geometry(#[from] fibfluid_geometry::GeometryError),
    /// Assembling the system failed (bad material, constraints).
    #[error("assembly: {0}")]
    Assembly(#[from] fibfluid_assembly::AssemblyError),
    /// A linear solve failed (singular system, residual too large).
    #[error("linear solver: {0}")]
    Linalg(#[from] fibfluid_linalg::LinalgError),
    /// Writing an output failed.
    #[error("{path}: {source}")]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// Rendering a picture failed.
    #[error("render: {0}")]
    Render(#[from] fibfluid_render::RenderError),
    /// Probing failed: a bad tool path (file and line) or a refused body.
    #[error(transparent)]
    Probe(#[from] crate::probe::ProbeError),
    /// An option given in code or on the command line is invalid.
    #[error("{0}")]
    Invalid(String),
}

/// Result alias of the facade.
pub type Result<T> = std::result::Result<T, Error>;
