//! The errors of the command line's library: the library's own, and writing outputs.

use std::path::PathBuf;

/// Everything that can go wrong in a command: the library's errors and the outputs'.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An error of the library (scene, engine, probe).
    #[error(transparent)]
    Fibfluid(#[from] fibfluid::Error),
    /// Reading or writing a file failed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// An output cannot be written where it should go.
    #[error("{}: {problem}", path.display())]
    OutputBlocked {
        /// The path in the way.
        path: PathBuf,
        /// What is in the way.
        problem: &'static str,
    },
    /// Rendering a picture failed.
    #[error("render: {0}")]
    Render(#[from] fibfluid::render::RenderError),
    /// Serializing a report failed.
    #[error("writing JSON: {0}")]
    Json(#[from] serde_json::Error),
    /// A comparison whose ChainMail replays would update the lattice at too many frames.
    #[error(
        "{}: {frames} frames: a comparison replays every frame with ChainMail, whose lattice carries each frame to the next (no frame comes free), and takes at most {limit}; use fewer frames",
        path.display()
    )]
    CompareTooLong {
        /// The path file.
        path: PathBuf,
        /// Frames the path declares.
        frames: usize,
        /// The most frames a comparison with ChainMail replays.
        limit: usize,
    },
    /// The accuracy study's grab comparison has no vertex to grab: every vertex is fixed.
    #[error("{scene}: every vertex is fixed along some axis, so the grab comparison has no vertex to grab")]
    NoFreeVertex {
        /// The scene file (or the scene's name when built in code).
        scene: String,
    },
}

impl From<fibfluid::sim::Error> for Error {
    fn from(e: fibfluid::sim::Error) -> Self {
        Error::Fibfluid(e.into())
    }
}

impl From<fibfluid::interact::ProbeError> for Error {
    fn from(e: fibfluid::interact::ProbeError) -> Self {
        Error::Fibfluid(e.into())
    }
}

impl From<fibfluid::geometry::GeometryError> for Error {
    fn from(e: fibfluid::geometry::GeometryError) -> Self {
        Error::Fibfluid(fibfluid::sim::Error::from(e).into())
    }
}

impl From<fibfluid::assembly::AssemblyError> for Error {
    fn from(e: fibfluid::assembly::AssemblyError) -> Self {
        Error::Fibfluid(fibfluid::sim::Error::from(e).into())
    }
}

impl From<fibfluid::linalg::LinalgError> for Error {
    fn from(e: fibfluid::linalg::LinalgError) -> Self {
        Error::Fibfluid(fibfluid::sim::Error::from(e).into())
    }
}

/// Result alias of the command line's library.
pub type Result<T> = std::result::Result<T, Error>;
