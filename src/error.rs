//! The facade's error types.

use std::fmt;
use std::path::PathBuf;

use fibfluid_linalg::ParseChoiceError;

/// Everything that can go wrong in a fibfluid run.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A scene file is malformed or holds an invalid value.
    #[error(transparent)]
    Scene(Box<SceneError>),
    /// A mesh file could not be read or is not a valid closed surface.
    #[error(transparent)]
    Geometry(#[from] fibfluid_geometry::GeometryError),
    /// Assembling the system failed (bad material, constraints).
    #[error("assembly: {0}")]
    Assembly(#[from] fibfluid_assembly::AssemblyError),
    /// A linear solve failed (singular system, residual too large).
    #[error("linear solver: {0}")]
    Linalg(#[from] fibfluid_linalg::LinalgError),
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
    Render(#[from] fibfluid_render::RenderError),
    /// A load or query names a vertex the body does not have.
    #[error("vertex {vertex} does not exist: the body has {vertices} vertices")]
    VertexOutOfRange {
        /// The vertex asked for.
        vertex: usize,
        /// Vertex count.
        vertices: usize,
    },
    /// A vertex fixed by the scene cannot be held somewhere else.
    #[error("vertex {vertex} is fixed by the scene and cannot be held at a displacement")]
    HeldFixedVertex {
        /// The vertex.
        vertex: usize,
    },
    /// The plan needs more memory than the limit; refused before anything was allocated.
    #[error(
        "{scene}: the plan needs {needed} bytes ({:.2} GiB) at its largest stage ({stage}), but {available} bytes ({:.2} GiB) are available; {hint}",
        *needed as f64 / GIB, *available as f64 / GIB
    )]
    TooLarge {
        /// Scene name.
        scene: String,
        /// The stage that needs the most memory.
        stage: &'static str,
        /// Bytes needed.
        needed: u64,
        /// Bytes available (the machine's memory or the given limit).
        available: u64,
        /// What to change.
        hint: &'static str,
    },
    /// A numeric failure during a load step, with its likely cause in the user's terms.
    #[error("step {step} (load {from:.4} -> {to:.4}): {cause}; {hint} ({source})")]
    Step {
        /// The step (1-based).
        step: usize,
        /// Load factor at the start of the step.
        from: f64,
        /// Load factor the step was going to.
        to: f64,
        /// What went wrong, named (a vertex, a pivot).
        cause: String,
        /// What to try.
        hint: &'static str,
        /// The failure as the solver reported it.
        source: Box<Error>,
    },
    /// A step guard fired under `[guards] on_failure = "error"`.
    #[error("{0} (stopped: [guards] on_failure = \"error\")")]
    Guard(crate::guards::GuardWarning),
    /// Adaptive stepping could not meet its tolerance.
    #[error(
        "adaptive steps shrank below 1e-6 of the load at load factor {load_factor:.6} without meeting tolerance {tolerance:e}; the response may be unstable there: raise the tolerance or check the material and constraints"
    )]
    StepTooSmall {
        /// Load factor reached.
        load_factor: f64,
        /// The tolerance asked for.
        tolerance: f64,
    },
    /// The contact active set kept changing.
    #[error(
        "step {step}: the plate contacts did not settle after {iterations} active-set iterations; take more load steps"
    )]
    ContactNotConverged {
        /// The step.
        step: usize,
        /// Iterations made.
        iterations: usize,
    },
    /// Probing failed: a bad tool path (file and line) or a refused body.
    #[error(transparent)]
    Probe(#[from] crate::probe::ProbeError),
    /// Serializing a report failed.
    #[error("writing JSON: {0}")]
    Json(#[from] serde_json::Error),
}

const GIB: f64 = 1024.0 * 1024.0 * 1024.0;

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
    /// Nothing is fixed along an axis.
    #[error(
        "no vertex is fixed along {axis}; with the volume conserved the body could still translate freely (add a [[fix]] table)"
    )]
    Unconstrained {
        /// The axis.
        axis: char,
    },
    /// The ChainMail lattice at this spacing would not fit in memory (refused before
    /// anything is allocated).
    #[error(
        "spacing {spacing} needs up to {bytes} bytes ({:.2} GiB) for the ChainMail lattice, but only {available} bytes ({:.2} GiB) may be used; use a larger spacing",
        *bytes as f64 / 1073741824.0,
        *available as f64 / 1073741824.0
    )]
    ChainmailLatticeTooLarge {
        /// The spacing.
        spacing: f64,
        /// Bytes needed (upper bound: every grid node an element).
        bytes: u128,
        /// Bytes that may be used.
        available: u64,
    },
}

/// Result alias of the facade.
pub type Result<T> = std::result::Result<T, Error>;
