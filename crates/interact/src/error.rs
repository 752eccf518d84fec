//! The error type of interactive bodies.

/// What can go wrong while building or driving an interactive body.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InteractError {
    /// A vertex index beyond the body.
    #[error("vertex {vertex} does not exist (the body has {vertices} vertices, 0-based)")]
    UnknownVertex {
        /// The vertex asked for.
        vertex: usize,
        /// Number of vertices of the body.
        vertices: usize,
    },
    /// A grab (or a push) on a vertex the scene fixes: a tool cannot move it.
    #[error("vertex {vertex} is fixed along {axis} by the scene; it cannot be {action}")]
    FixedVertex {
        /// The vertex.
        vertex: usize,
        /// The first fixed axis (`x`, `y` or `z`).
        axis: char,
        /// `grabbed` or `pushed`.
        action: &'static str,
    },
    /// A displacement or force with a NaN or infinite component.
    #[error("vertex {vertex}: the {what} has a non-finite component ({value})")]
    NonFinite {
        /// The vertex.
        vertex: usize,
        /// `displacement` or `force`.
        what: &'static str,
        /// The offending value.
        value: f64,
    },
    /// This method has no forces (a displacement-driven method such as ChainMail).
    #[error("{method} does not support {what}")]
    Unsupported {
        /// The method.
        method: fibfluid_sim::Method,
        /// What was asked for (`forces`).
        what: &'static str,
    },
    /// The precomputed response would not fit in memory; nothing was allocated.
    #[error(
        "the precomputed response needs {bytes} bytes ({:.2} GiB) at its peak, but only {available} bytes ({:.2} GiB) may be used; use f32 storage or a coarser mesh",
        *bytes as f64 / GIB,
        *available as f64 / GIB
    )]
    OutOfMemory {
        /// Bytes needed at the peak of the precompute.
        bytes: u64,
        /// Bytes that may be used.
        available: u64,
    },
    /// A stiffness block is not positive definite (not enough vertices fixed), or the grabbed
    /// set over-determines the body (for instance every free vertex grabbed while the volume
    /// is conserved).
    #[error("singular system: {what}")]
    Singular {
        /// What is singular and where.
        what: String,
    },
    /// A tool radius that is not positive and finite.
    #[error("the tool's radius {radius} must be positive and finite")]
    BadRadius {
        /// The radius given (metres).
        radius: f64,
    },
    /// A tool at least as large as the body (the diagonal of its bounding box).
    #[error("a tool of radius {radius} m is larger than the body (its bounding-box diagonal is {size} m)")]
    ToolTooLarge {
        /// The radius given (metres).
        radius: f64,
        /// The body's size (metres).
        size: f64,
    },
    /// A grasp patch that holds vertices the scene fixes.
    #[error(
        "the grasp of radius {radius} m around vertex {vertex} holds {count} vertices the scene fixes (vertex {fixed} first); a tool cannot move them"
    )]
    PatchHoldsFixed {
        /// The picked vertex.
        vertex: usize,
        /// The radius (metres).
        radius: f64,
        /// The first fixed vertex of the patch.
        fixed: usize,
        /// How many patch vertices are fixed.
        count: usize,
    },
    /// A tip that reaches vertices the scene fixes: it cannot move them.
    #[error(
        "the tip of radius {radius} m centred at [{}, {}, {}] reaches {count} vertices the scene fixes (vertex {fixed} first); a tool cannot move them",
        centre[0],
        centre[1],
        centre[2]
    )]
    TipReachesFixed {
        /// The tip's radius (metres).
        radius: f64,
        /// The tip's centre (metres).
        centre: [f64; 3],
        /// The first fixed vertex inside the tip.
        fixed: usize,
        /// How many fixed vertices are inside the tip.
        count: usize,
    },
    /// Two grasps whose patches share a vertex: each patch moves rigidly with its own tool,
    /// so no vertex can follow both.
    #[error(
        "the grasps around vertices {first} and {second} both hold vertex {shared}; a vertex can be held by one grasp only"
    )]
    GraspsOverlap {
        /// The picked vertex of the grasp already in place.
        first: usize,
        /// The picked vertex of the new grasp.
        second: usize,
        /// A vertex both patches hold.
        shared: usize,
    },
    /// A press whose contact set did not settle.
    #[error(
        "the tip's contact set did not settle in {iterations} iterations ({inside} vertices still inside the tip)"
    )]
    PressUnsettled {
        /// Iterations made.
        iterations: usize,
        /// Free vertices still inside (neither fixed nor held by another tool; at least
        /// one).
        inside: usize,
    },
    /// A tip centre with a NaN or infinite component.
    #[error("the tip's centre has a non-finite component ({value})")]
    NonFiniteCentre {
        /// The offending component.
        value: f64,
    },
    /// Inputs of inconsistent sizes (rest positions, base state) or non-finite system data.
    #[error("{0}")]
    Invalid(String),
}

const GIB: f64 = 1024.0 * 1024.0 * 1024.0;

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, InteractError>;
