//! Errors of the FEM crate.

use fibfluid_geometry::MeshError;
use fibfluid_linalg::LinalgError;

/// Everything that can go wrong when building or solving a finite-element body.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FemError {
    /// A material parameter is out of its range.
    #[error("tissue parameter {name} = {value} is invalid: {reason}")]
    InvalidTissue {
        /// The parameter.
        name: crate::TissueParameter,
        /// Its value.
        value: f64,
        /// What is required.
        reason: &'static str,
    },
    /// A viscoelastic law's relaxation terms are out of range.
    #[error("the relaxation is invalid: {reason}")]
    InvalidRelaxation {
        /// What is wrong.
        reason: String,
    },
    /// A timed solve's settings or load curve are out of range.
    #[error("the time settings are invalid: {reason}")]
    InvalidTime {
        /// What is wrong.
        reason: String,
    },
    /// The resolution is 0 or above [`crate::MAX_RESOLUTION`].
    #[error("resolution {resolution} is outside 1..={max}")]
    InvalidResolution {
        /// The resolution asked for.
        resolution: usize,
        /// The largest resolution allowed.
        max: usize,
    },
    /// The body's extent along an axis is below one cell.
    #[error(
        "the body is {thickness:.3e} m thick along {axis}, thinner than a cell ({cell:.3e} m); raise the resolution"
    )]
    ThinnerThanCell {
        /// The axis (`x`, `y` or `z`).
        axis: char,
        /// The body's extent along that axis.
        thickness: f64,
        /// The cell size.
        cell: f64,
    },
    /// The grid would exceed [`crate::MAX_CELLS`] cells.
    #[error(
        "the grid needs {cells} cells at [fem] resolution {resolution}, more than the limit {limit}: lower [fem] resolution (or --resolution) to {fits} or less"
    )]
    TooManyCells {
        /// Cells of the full grid.
        cells: u128,
        /// The limit.
        limit: usize,
        /// The resolution asked for.
        resolution: usize,
        /// The largest resolution whose grid fits the limit.
        fits: usize,
    },
    /// The surface has no vertex or no triangle.
    #[error("the surface is empty ({vertices} vertices, {triangles} triangles)")]
    EmptySurface {
        /// Vertex count.
        vertices: usize,
        /// Triangle count.
        triangles: usize,
    },
    /// The surface data is malformed (index out of range, non-finite vertex).
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// A per-vertex array has the wrong length.
    #[error("{what} has {found} entries, expected {expected} (one per surface vertex)")]
    LengthMismatch {
        /// Which array.
        what: &'static str,
        /// Expected length.
        expected: usize,
        /// Actual length.
        found: usize,
    },
    /// A surface vertex index is out of range.
    #[error("surface vertex {vertex} does not exist ({vertices} vertices)")]
    VertexOutOfRange {
        /// The index.
        vertex: usize,
        /// Vertex count.
        vertices: usize,
    },
    /// A load or target value is NaN or infinite.
    #[error("{what} has a non-finite value")]
    NonFinite {
        /// Which input.
        what: &'static str,
    },
    /// No degree of freedom is fixed, or too few to stop rigid motion: the stiffness is
    /// singular.
    #[error("the stiffness matrix is not positive definite (too few fixed vertices to stop rigid motion?)")]
    NotPositiveDefinite,
    /// The fixed vertices leave the body free to move rigidly (found from the constraints
    /// before anything is assembled).
    #[error(
        "the fixed vertices ({fixed_vertices} of them) leave the body free to move: {mode} costs no energy (fix vertices that do not all lie on one line, or more axes)"
    )]
    RigidModeFree {
        /// The first free rigid motion found.
        mode: crate::RigidMode,
        /// Vertices with at least one fixed axis.
        fixed_vertices: usize,
    },
    /// A sensitivity asked of what it does not cover (grasps, a tissue that is not there).
    #[error("sensitivities: {reason}")]
    Sensitivity {
        /// What was asked and why it cannot be answered.
        reason: String,
    },
    /// A grasp with no vertex in its patch.
    #[error("grasp {grasp} holds no vertex")]
    EmptyGrasp {
        /// The grasp (0-based).
        grasp: usize,
    },
    /// Every node is fixed: nothing to solve.
    #[error("every degree of freedom is fixed")]
    NothingFree,
    /// A held vertex's axis is carried only by fixed nodes, and its target there is not 0.
    #[error("held vertex {vertex} cannot move along axis {axis}: every node carrying it is fixed")]
    HeldOnFixed {
        /// The vertex.
        vertex: usize,
        /// The axis (0, 1, 2).
        axis: usize,
    },
    /// The same vertex is held twice, or the held vertices' constraints are linearly
    /// dependent (more held vertices in a cell than the cell has nodes).
    #[error("the held vertices' constraints are dependent (vertex {vertex})")]
    DependentHolds {
        /// A vertex involved.
        vertex: usize,
    },
    /// The solution's residual `|K u - f| / |f|` is above the limit.
    #[error("solve residual {residual:e} is above {limit:e}")]
    Residual {
        /// The measured residual.
        residual: f64,
        /// The limit.
        limit: f64,
    },
    /// A region of different tissue holds no part of the body.
    #[error("region {region} lies outside the body: none of its points is inside the surface")]
    RegionOutsideBody {
        /// The region (1-based, in the order given).
        region: usize,
    },
    /// Newton's method could not reach a load: the increment was cut below its minimum.
    #[error(
        "Newton's method did not converge at load step {step} (load factor {load:.4}): relative residual {residual:.3e}; {why}"
    )]
    NotConverged {
        /// The load step (1-based) that failed.
        step: usize,
        /// The load factor it aimed for (1: the full load).
        load: f64,
        /// The relative residual when it stopped.
        residual: f64,
        /// What the last iterations saw.
        why: NotConvergedWhy,
    },
    /// A time step could not converge even when cut to its smallest length.
    #[error(
        "Newton's method did not converge at t = {time:.6} s (a step of {step:.3e} s, load factor {load:.4}): relative residual {residual:.3e}; the body may be inverting or the load changing too fast"
    )]
    NotConvergedInTime {
        /// The time reached (s).
        time: f64,
        /// The last step tried (s).
        step: f64,
        /// The load factor aimed for.
        load: f64,
        /// The relative residual when it stopped.
        residual: f64,
    },
    /// A state inverts a cell (`J <= 0`): no step toward it could be taken.
    #[error("the body would invert (a cell's volume would reach zero); move the tool less far per step")]
    Inverted,
    /// The sparse factorization could not allocate or failed for a non-numerical reason.
    #[error("sparse factorization failed: {reason}")]
    Factorization {
        /// faer's message.
        reason: String,
    },
}

/// Result with [`FemError`].
pub type Result<T, E = FemError> = std::result::Result<T, E>;

/// The sparse factorization's errors in this crate's terms: a non-positive pivot is
/// [`FemError::NotPositiveDefinite`], anything else [`FemError::Factorization`] with the
/// linear algebra crate's message.
impl From<LinalgError> for FemError {
    fn from(e: LinalgError) -> Self {
        match e {
            LinalgError::SparseNotPositiveDefinite { .. } => FemError::NotPositiveDefinite,
            other => FemError::Factorization { reason: other.to_string() },
        }
    }
}

/// What the last Newton iterations of a failed load step saw.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NotConvergedWhy {
    /// The tangent was positive definite: the steps inverted cells or stalled.
    Stalled,
    /// The tangent was indefinite (factored only with a diagonal shift): the equilibrium
    /// is unstable there.
    Indefinite,
    /// A cell at least half inside the body grew its volume `j` times, past `e`: the load
    /// pulls the tissue apart there (no tissue dilates so far; a support or a grasp too
    /// small for its load concentrates it).
    Dilatation {
        /// The largest volume ratio `J` over those cells.
        j: f64,
    },
}

impl std::fmt::Display for NotConvergedWhy {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            NotConvergedWhy::Stalled => "the body may be inverting or the load too large",
            NotConvergedWhy::Dilatation { j } => {
                return write!(
                    f,
                    "a cell's volume grew {j:.2} times, past e = 2.72: the load pulls the tissue apart there (a support or grasp too small for it); support it more, or load it less"
                );
            }
            NotConvergedWhy::Indefinite => {
                "the tangent stiffness was indefinite (the body buckles, swings about its supports or snaps there: an unstable equilibrium that load stepping cannot pass); support it more, or load it less"
            }
        })
    }
}
