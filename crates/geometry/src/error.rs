//! Errors of the geometry crate.

use std::path::PathBuf;

/// A problem with a mesh's data or topology (no file attached).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeshError {
    /// No vertices or no faces.
    #[error("the mesh is empty ({vertices} vertices, {faces} faces)")]
    Empty {
        /// Vertex count.
        vertices: usize,
        /// Face count.
        faces: usize,
    },
    /// A face refers to a vertex that does not exist.
    #[error("face {face} refers to vertex {index}, but there are only {vertices} vertices")]
    IndexOutOfRange {
        /// Face index.
        face: usize,
        /// The bad vertex index.
        index: i64,
        /// Vertex count.
        vertices: usize,
    },
    /// A vertex coordinate is NaN or infinite.
    #[error("vertex {vertex} has a non-finite coordinate")]
    NonFiniteVertex {
        /// Vertex index.
        vertex: usize,
    },
    /// A face uses the same vertex twice or has (numerically) zero area.
    #[error("face {face} is degenerate (area {area:e})")]
    DegenerateFace {
        /// Face index.
        face: usize,
        /// Its area.
        area: f64,
    },
    /// The same triangle appears twice.
    #[error("faces {first} and {second} are duplicates")]
    DuplicateFace {
        /// First face.
        first: usize,
        /// Second face.
        second: usize,
    },
    /// An edge is shared by more than two faces.
    #[error("edge ({a}, {b}) is shared by {faces} faces (non-manifold)")]
    NonManifoldEdge {
        /// One end.
        a: u32,
        /// Other end.
        b: u32,
        /// Number of faces using it.
        faces: usize,
    },
    /// The faces around a vertex do not form one fan.
    #[error("vertex {vertex} is non-manifold (its faces form {fans} separate fans)")]
    NonManifoldVertex {
        /// Vertex index.
        vertex: u32,
        /// Number of fans.
        fans: usize,
    },
    /// Edges used by one face only: the surface is not closed.
    #[error("the surface is open: {count} boundary edges, e.g. ({a}, {b})")]
    OpenBoundary {
        /// Number of boundary edges.
        count: usize,
        /// One end of the first boundary edge.
        a: u32,
        /// Other end.
        b: u32,
    },
    /// Two faces traverse a shared edge in the same direction.
    #[error("faces around edge ({a}, {b}) are inconsistently oriented")]
    InconsistentOrientation {
        /// One end.
        a: u32,
        /// Other end.
        b: u32,
    },
    /// The faces form several disconnected pieces.
    #[error("the mesh has {count} disconnected components; one closed body is expected")]
    MultipleComponents {
        /// Number of components.
        count: usize,
    },
    /// The enclosed volume is zero: the body is flat.
    #[error("the enclosed volume is zero (a flat body)")]
    ZeroVolume,
}

/// An error reading or writing a mesh file.
#[derive(Debug, thiserror::Error)]
pub enum GeometryError {
    /// The file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The file's content could not be parsed.
    #[error("{path}:{line}: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line (0 when the problem is not tied to one line).
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// The file parsed but the mesh is not a valid closed surface.
    #[error("{path}: {source}")]
    Mesh {
        /// The file.
        path: PathBuf,
        /// The problem.
        source: MeshError,
    },
    /// The file has an extension this crate does not read.
    #[error("{path}: unsupported mesh format (expected .obj or .stl)")]
    UnsupportedFormat {
        /// The file.
        path: PathBuf,
    },
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, GeometryError>;
