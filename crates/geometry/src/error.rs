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
    /// Two vertices (nearly) at the same place: a crack, a pinch or a sliver that the
    /// fibers and the solvers cannot resolve.
    #[error(
        "vertices {a} and {b} are {distance:.2e} apart, {relative:.2e} of the body's size: a near-duplicate vertex (merge the two or remove the sliver)"
    )]
    NearDuplicateVertices {
        /// One vertex.
        a: usize,
        /// The other.
        b: usize,
        /// Their distance.
        distance: f64,
        /// Their distance over the bounding box's diagonal.
        relative: f64,
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
    /// A closed component lies outside the outer surface (the one of largest volume): two
    /// bodies, where one (with cavities inside it) is expected.
    #[error(
        "component {component} lies outside the outer surface: two disjoint bodies (one body, with any cavities inside it, is expected)"
    )]
    DisjointBodies {
        /// The component (numbered like the cavities: the outer surface is 0).
        component: usize,
    },
    /// A cavity has vertices both inside and outside the outer surface.
    #[error("cavity {cavity} crosses the outer surface (some of its vertices lie outside it)")]
    CavityCrossesOuter {
        /// The cavity (1-based).
        cavity: usize,
    },
    /// Two cavities cross each other.
    #[error("cavities {a} and {b} cross each other (some vertices of one lie inside the other)")]
    CavitiesCross {
        /// One cavity (1-based).
        a: usize,
        /// The other.
        b: usize,
    },
    /// A closed component lies inside a cavity: a body floating in a hole.
    #[error("cavity {inner} lies inside cavity {outer}: a body inside a cavity is not supported")]
    CavityInCavity {
        /// The inner component.
        inner: usize,
        /// The cavity around it.
        outer: usize,
    },
    /// The enclosed volume is zero: the body is flat.
    #[error("the enclosed volume is zero (a flat body)")]
    ZeroVolume,
    /// The coordinates are so large that the products validation forms (face areas, the
    /// volume) overflow f64, although the shape itself is fine.
    #[error(
        "{site}: the coordinates overflow f64 when multiplied (vertex {vertex} has |coordinate| = {magnitude:e}); scale the mesh down, e.g. `[mesh].scale = {suggested_scale:e}`"
    )]
    CoordinateOverflow {
        /// Where the overflow showed up.
        site: ScaleSite,
        /// The vertex with the largest coordinate there.
        vertex: u32,
        /// Its largest absolute coordinate.
        magnitude: f64,
        /// A power of ten that brings the largest coordinate of the mesh to between 1 and 10.
        suggested_scale: f64,
    },
    /// The coordinates are so small that a face area or the volume underflows to zero (or to
    /// a subnormal number), although the shape itself is fine.
    #[error(
        "{site}: the coordinates are too small, {} underflows to {value:e} (vertex {vertex} has |coordinate| = {magnitude:e}); scale the mesh up, e.g. `[mesh].scale = {suggested_scale:e}`",
        .site.quantity()
    )]
    CoordinateUnderflow {
        /// Where the underflow showed up.
        site: ScaleSite,
        /// The vertex with the largest coordinate there.
        vertex: u32,
        /// Its largest absolute coordinate.
        magnitude: f64,
        /// The area or volume computed.
        value: f64,
        /// A power of ten that brings the largest coordinate of the mesh to between 1 and 10.
        suggested_scale: f64,
    },
}

/// Where a problem with the scale of the coordinates showed up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScaleSite {
    /// The area of this face (0-based).
    Face(usize),
    /// The enclosed volume.
    Volume,
}

impl ScaleSite {
    /// What was computed there ("its area", "the volume").
    pub fn quantity(&self) -> &'static str {
        match self {
            ScaleSite::Face(_) => "its area",
            ScaleSite::Volume => "the volume",
        }
    }
}

impl std::fmt::Display for ScaleSite {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ScaleSite::Face(k) => write!(f, "face {k}"),
            ScaleSite::Volume => write!(f, "the enclosed volume"),
        }
    }
}

/// What a file of the wrong kind is (only regular files are read).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FileKind {
    /// A directory.
    Directory,
    /// A FIFO (named pipe): reading it blocks until a writer comes.
    Fifo,
    /// A character device such as `/dev/zero`, which never ends.
    CharDevice,
    /// A block device.
    BlockDevice,
    /// A Unix socket.
    Socket,
    /// Anything else that is not a regular file.
    Other,
}

impl std::fmt::Display for FileKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            FileKind::Directory => "a directory",
            FileKind::Fifo => "a FIFO (named pipe)",
            FileKind::CharDevice => "a character device",
            FileKind::BlockDevice => "a block device",
            FileKind::Socket => "a socket",
            FileKind::Other => "not a regular file",
        })
    }
}

/// Why an input file could not be read into memory (see [`read_file_limited`](crate::read_file_limited)).
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    /// The path is a directory, FIFO, device or socket: refused before it is opened.
    #[error("is {kind}, not a regular file (pipes and devices are not read: they can block or never end)")]
    NotARegularFile {
        /// What it is.
        kind: FileKind,
    },
    /// The file is larger than the limit.
    #[error(
        "is {size} bytes, more than the limit of {}; raise it with --max-file-bytes or {}",
        byte_text(*.limit),
        crate::limits::MAX_FILE_BYTES_ENV
    )]
    TooLarge {
        /// The file's size.
        size: u64,
        /// The limit in force.
        limit: u64,
    },
    /// The file grew past the limit while it was read.
    #[error(
        "grew past the limit of {} while it was read; raise it with --max-file-bytes or {}",
        byte_text(*.limit),
        crate::limits::MAX_FILE_BYTES_ENV
    )]
    GrewPastLimit {
        /// The limit in force.
        limit: u64,
    },
    /// Memory for the file's bytes could not be reserved.
    #[error("cannot allocate {bytes} bytes to read it")]
    OutOfMemory {
        /// Bytes asked for.
        bytes: u64,
    },
    /// The limit given in the environment is not a byte count.
    #[error(
        "{} = `{value}` is not a byte count (e.g. 1073741824, 512M, 4G)",
        crate::limits::MAX_FILE_BYTES_ENV
    )]
    BadLimit {
        /// The value found.
        value: String,
    },
    /// The operating system refused the read.
    #[error(transparent)]
    Io(#[from] std::io::Error),
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
    /// The file could not be read into memory (not a regular file, too large, ...).
    #[error("{path}: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        source: ReadError,
    },
    /// The file has an extension this crate does not read.
    #[error("{path}: unsupported mesh format (expected .obj, .stl, .ply or .off)")]
    UnsupportedFormat {
        /// The file.
        path: PathBuf,
    },
}

/// A byte count as a user would write it: `2 GiB` when it is a whole number of a binary
/// unit, else `2530 bytes`.
fn byte_text(bytes: u64) -> String {
    for (shift, unit) in [(40, "TiB"), (30, "GiB"), (20, "MiB"), (10, "KiB")] {
        if bytes >= 1 << shift && bytes.is_multiple_of(1 << shift) {
            return format!("{} {unit}", bytes >> shift);
        }
    }
    format!("{bytes} bytes")
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, GeometryError>;
