//! The errors of reading scenes and path files, and the library's error type above the
//! engine.

use std::fmt;
use std::path::PathBuf;

use fibfluid_interact::ProbeError;
use fibfluid_linalg::ParseChoiceError;

/// Everything that can go wrong from a scene file to a finished run or probe.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A scene file is malformed or holds an invalid value (file, line, key).
    #[error(transparent)]
    Scene(Box<SceneError>),
    /// The engine failed: a mesh, the assembly, a solve, a step, a guard, the memory plan.
    #[error(transparent)]
    Sim(#[from] fibfluid_sim::Error),
    /// Probing failed: a bad tool path (file and line) or a refused body.
    #[error(transparent)]
    Probe(#[from] ProbeError),
    /// Reading a file failed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
}

/// Errors of the lower crates reach [`Error`] through the engine's error.
macro_rules! through_sim {
    ($($t:ty),*) => {$(
        impl From<$t> for Error {
            fn from(e: $t) -> Self {
                Error::Sim(e.into())
            }
        }
    )*};
}
through_sim!(
    fibfluid_geometry::GeometryError,
    fibfluid_assembly::AssemblyError,
    fibfluid_linalg::LinalgError
);

impl From<SceneError> for Error {
    fn from(e: SceneError) -> Self {
        Error::Scene(Box::new(e))
    }
}

/// A problem in a scene file: the file, the line when it can be found, the key
/// (`[load].steps`, `[[fix]] #2.vertices`) and what is wrong.
#[derive(Debug)]
pub struct SceneError {
    /// The scene file.
    pub path: PathBuf,
    /// 1-based line of the key or of the syntax error, when known.
    pub line: Option<usize>,
    /// The table and key concerned, when there is one.
    pub key: Option<String>,
    /// What is wrong.
    pub problem: SceneProblem,
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.path.display())?;
        if let Some(l) = self.line {
            write!(f, ":{l}")?;
        }
        f.write_str(": ")?;
        if let Some(k) = &self.key {
            write!(f, "{k}: ")?;
        }
        write!(f, "{}", self.problem)
    }
}

impl std::error::Error for SceneError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match &self.problem {
            SceneProblem::Mesh(e) => Some(e),
            SceneProblem::Image(e) => Some(e),
            SceneProblem::Constraint(e) => Some(e),
            SceneProblem::Choice(e) => Some(e),
            _ => None,
        }
    }
}

/// What is wrong in a scene file.
#[derive(Debug, thiserror::Error)]
pub enum SceneProblem {
    /// The path is a directory.
    #[error("is a directory, not a scene file")]
    IsDirectory,
    /// The file is not UTF-8 text.
    #[error("not a text file (invalid UTF-8)")]
    NotUtf8,
    /// The file cannot be read: not a regular file, or over the size limit.
    #[error(transparent)]
    Read(fibfluid_geometry::ReadError),
    /// TOML syntax or a value of the wrong type.
    #[error("{message}{}", column.map(|c| format!(" (column {c})")).unwrap_or_default())]
    Toml {
        /// The parser's message, on one line.
        message: String,
        /// 1-based column, when known.
        column: Option<usize>,
    },
    /// A name that is not one of the accepted choices.
    #[error(transparent)]
    Choice(ParseChoiceError),
    /// A backend this build does not have.
    #[error(transparent)]
    Backend(fibfluid_linalg::LinalgError),
    /// A number out of its range.
    #[error("must be {rule}, got {value}")]
    Range {
        /// The rule (`positive`, `>= 0`).
        rule: &'static str,
        /// The value given.
        value: String,
    },
    /// An axis name that is not x, y or z.
    #[error("`{given}` is not an axis (x, y or z)")]
    NotAnAxis {
        /// The name given.
        given: String,
    },
    /// Keys that contradict each other, or a missing table.
    #[error("{0}")]
    Conflict(&'static str),
    /// The mesh file does not exist.
    #[error("`{given}` does not exist (resolved to {})", resolved.display())]
    MeshNotFound {
        /// The path as written.
        given: String,
        /// The path it resolved to.
        resolved: PathBuf,
    },
    /// The mesh file is not a valid closed surface.
    #[error(transparent)]
    Mesh(fibfluid_geometry::GeometryError),
    /// The label image could not be read.
    #[error(transparent)]
    Image(fibfluid_geometry::ImageError),
    /// The label image's surface could not be extracted.
    #[error("{}: {source}", path.display())]
    Surface {
        /// The image.
        path: PathBuf,
        /// Why.
        source: fibfluid_geometry::SurfaceError,
    },
    /// A vertex index beyond the mesh file's vertices.
    #[error("vertex {vertex} is out of range (the mesh file has {count} vertices, 0-based)")]
    VertexOutOfRange {
        /// The index given.
        vertex: i64,
        /// Vertices in the file.
        count: usize,
    },
    /// A vertex no face uses.
    #[error("vertex {vertex} is not used by any face")]
    VertexUnused {
        /// The index given.
        vertex: i64,
    },
    /// A constraint that cannot be applied.
    #[error(transparent)]
    Constraint(fibfluid_assembly::AssemblyError),
    /// A `[tissue]` value the finite-element method refuses.
    #[error(transparent)]
    Tissue(fibfluid_fem::FemError),
    /// A `[fit]` key names what the scene does not have, or its bounds do not fit.
    #[error("{0}")]
    Fit(String),
    /// A plate whose normal points away from the body.
    #[error("the plate faces away from the body (its normal must point towards the body)")]
    PlateFacesAway,
    /// A plate that cuts the body at rest.
    #[error("the plate already cuts the body at rest: vertex {vertex} is {depth:e} through it")]
    PlateCutsBody {
        /// The deepest vertex (file order).
        vertex: usize,
        /// How far through.
        depth: f64,
    },
    /// A pressure on a cavity the body does not have.
    #[error("the body has no cavity {cavity} (it has {count}; `fibfluid mesh-info` lists them)")]
    NoSuchCavity {
        /// The cavity named (1-based).
        cavity: usize,
        /// The body's cavities.
        count: usize,
    },
    /// A pressure's box holds no whole face.
    #[error(
        "selects no face (a face is selected when its three vertices lie in the box, in the mesh's unit)"
    )]
    EmptyPressureBox,
    /// Nothing is fixed along an axis.
    #[error(
        "no vertex is fixed along {axis}: the body could translate freely along it (add a [[fix]] table; a frictionless plate does not hold a body sideways)"
    )]
    Unconstrained {
        /// The axis.
        axis: char,
    },
}

/// Result alias of the scene crate (and of the `fibfluid` facade).
pub type Result<T> = std::result::Result<T, Error>;
