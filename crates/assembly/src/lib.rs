//! Assembly of the fiber–fluid bordered system (REFERENCE §2–3).
//!
//! For a body with N vertices, vertex area vectors `S_i` and kept fibers, each axis
//! c in {x, y, z} gets a weighted graph Laplacian
//!
//! ```text
//! K_c[i][j] = -(Y_c w_ij + t_ij)   (i != j),     K_c[i][i] = -sum_{j != i} K_c[i][j]
//! w_ij = (|S_i| + |S_j|) / (2 n_eff d_ij)       bulk fiber (Eq. 6), kept fibers only
//! t_ij = gamma (|S_i| + |S_j|) / (2 d_ij^2)      surface fiber (Eq. 7), mesh edges only
//! ```
//!
//! where `n_eff = 2 F_kept / N` (N - 1 for a convex body) and the bulk and surface terms
//! add on edges. The border is `S`, the right-hand side `b_i = F_i + rho a h_i S_i` with
//! `h_i` the depth below the current top along the acceleration, and the last row asks
//! `sum S_i . u_i = t` (t = 0 in the paper).
//!
//! Fixed degrees of freedom are imposed by the paper's penalty (a diagonal entry `big`) or
//! by elimination (identity-replaced rows and columns scaled to the block's mean diagonal,
//! keeping the matrix symmetric and well conditioned). With [`PressureScaling::Auto`] the
//! border is multiplied by `lambda_S / |S|` (`lambda_S = S' K S / S' S`, free degrees of
//! freedom) so the pressure unknown has the same scale as the displacements.
//!
//! [`assemble_projected`] builds the projected fiber model instead (each fiber's spring
//! acts along the fiber, `k d d'` blocks that couple the axes): one dense dN x dN matrix.

mod block;
mod body;
mod constraints;
mod loads;
mod material;
mod projected;
mod synthetic;
mod system;

pub use body::Body;
pub use constraints::{ConstraintKind, ConstraintMethod, Constraints, DEFAULT_PENALTY, Selector};
pub use loads::{Loads, depths, load_vector};
pub use material::{KERNEL_EXPONENT_RANGE, Material, MaterialParameter, PAPER_KERNEL_EXPONENT, StiffnessLaw};
pub use projected::{ProjectedSystem, assemble_projected, projected_stiffness};
pub use system::{AssemblyOptions, AssemblyStats, PressureScaling, System, assemble};

/// What can go wrong while assembling.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AssemblyError {
    /// A material parameter is out of its range.
    #[error("material: {parameter} must be {}, got {value}", parameter.rule())]
    InvalidMaterial {
        /// The parameter.
        parameter: MaterialParameter,
        /// Its value.
        value: f64,
    },
    /// A material the method cannot use as a whole.
    #[error("material: {0}")]
    Material(String),
    /// A constraint refers to a vertex that does not exist.
    #[error("constraint refers to vertex {vertex}, but the body has {vertices} vertices")]
    VertexOutOfRange {
        /// The vertex.
        vertex: usize,
        /// Vertex count.
        vertices: usize,
    },
    /// A constraint selects no vertex.
    #[error("constraint `{selector}` selects no vertex")]
    EmptySelection {
        /// The selector, as text.
        selector: String,
    },
    /// Nothing is fixed along an axis: the body can translate freely along it.
    #[error("no vertex is fixed along {axis}: the body can translate freely and the system is singular")]
    Unconstrained {
        /// Axis name.
        axis: char,
    },
    /// Two vertices coincide, so a fiber has zero length.
    #[error("vertices {i} and {j} coincide (distance {distance:e}); fibers between them have no length")]
    CoincidentVertices {
        /// One vertex.
        i: usize,
        /// The other.
        j: usize,
        /// Their distance.
        distance: f64,
    },
    /// Every degree of freedom is fixed.
    #[error("every degree of freedom is fixed; nothing can move")]
    EverythingFixed,
    /// A dense matrix does not fit (the projected fibers' dN x dN stiffness).
    #[error(transparent)]
    Linalg(#[from] fibfluid_linalg::LinalgError),
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, AssemblyError>;

/// The axis names (defined once, in geometry).
pub use fibfluid_geometry::AXES;
pub use synthetic::synthetic_system;
