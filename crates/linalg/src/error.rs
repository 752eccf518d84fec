//! The error type of the linear algebra crate.

/// What can go wrong when factorizing or solving.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LinalgError {
    /// A pivot is zero or negligible against its column: the system is singular.
    #[error("singular system: pivot {index} is {pivot:e} (is any vertex fixed? is the border non-zero?)")]
    SingularPivot {
        /// Row/column of the system (0-based, paper layout).
        index: usize,
        /// The pivot value found.
        pivot: f64,
    },
    /// A stiffness block is not positive definite (structured backend).
    #[error(
        "stiffness block {axis} is not positive definite at vertex {index} (fix at least one vertex along every axis)"
    )]
    NotPositiveDefinite {
        /// Axis of the block (0 = x).
        axis: usize,
        /// Vertex index where the Cholesky factorization failed.
        index: usize,
    },
    /// The matrix holds NaN or infinity.
    #[error("the matrix has a non-finite entry at ({row}, {col})")]
    NonFinite {
        /// Row index.
        row: usize,
        /// Column index.
        col: usize,
    },
    /// The right-hand side holds NaN or infinity.
    #[error("the right-hand side has a non-finite entry at {index}")]
    NonFiniteRhs {
        /// Index in the right-hand side.
        index: usize,
    },
    /// The solve produced NaN or infinity.
    #[error("the solution has a non-finite entry at {index}")]
    NonFiniteSolution {
        /// Index in the solution.
        index: usize,
    },
    /// The residual stayed above the accepted limit.
    #[error("relative residual {residual:e} exceeds the limit {limit:e}")]
    ResidualTooLarge {
        /// The relative residual reached.
        residual: f64,
        /// The limit.
        limit: f64,
    },
    /// The backend exists but its Cargo feature is not compiled into this build.
    #[error(
        "backend `{backend}` is not compiled into this build; rebuild with `cargo build --features {feature}`{requirement} (compiled in: {compiled})"
    )]
    NotCompiled {
        /// The backend asked for.
        backend: &'static str,
        /// The Cargo feature that compiles it in.
        feature: &'static str,
        /// What else the feature needs (a system library), with its leading separator.
        requirement: &'static str,
        /// The backends this build has.
        compiled: String,
    },
    /// Memory for a buffer could not be allocated (the allocation was refused, not aborted).
    #[error(
        "cannot allocate {bytes} bytes ({:.2} GiB) for {what}; use the `structured` backend, which never forms the dense matrix",
        *.bytes as f64 / 1073741824.0
    )]
    OutOfMemory {
        /// Bytes asked for (`usize::MAX` when the size itself overflows).
        bytes: usize,
        /// What the buffer is for.
        what: &'static str,
    },
    /// A thread count of zero was asked for.
    #[error("the thread count must be at least 1")]
    ZeroThreads,
    /// The thread pool could not be started.
    #[error("cannot start a pool of {threads} threads: {message}")]
    ThreadPool {
        /// Threads asked for.
        threads: usize,
        /// The system's reason.
        message: String,
    },
    /// The dense matrix would not fit in memory.
    #[error(
        "the dense {dim} x {dim} matrix needs {gib:.1} GiB, more than the {limit_gib:.1} GiB allowed; use the `structured` backend"
    )]
    TooLarge {
        /// System size.
        dim: usize,
        /// GiB needed.
        gib: f64,
        /// GiB allowed.
        limit_gib: f64,
    },
    /// Held unknowns that cannot be prescribed independently (their capacitance matrix is
    /// singular: together they decide the volume, or repeat a fixed unknown).
    #[error(
        "the {held} held unknowns are not independent (together they fix the volume or a fixed degree of freedom)"
    )]
    DependentConstraints {
        /// How many unknowns were held.
        held: usize,
    },
    /// The held vertices over-determine the body: the capacitance matrix of the held set
    /// has a (numerically) non-positive pivot at this vertex and axis.
    #[error(
        "the {held} held vertices over-determine the body (capacitance pivot at vertex {vertex} along {}); release some",
        ["x", "y", "z"][*axis % 3]
    )]
    SingularHold {
        /// How many vertices were held.
        held: usize,
        /// The vertex of the failing pivot.
        vertex: usize,
        /// Its axis (0 = x).
        axis: usize,
    },
    /// A capacitance matrix (constraints imposed on a kept factorization) is not positive
    /// definite: the constraint of this row depends on the ones before it.
    #[error(
        "the capacitance of {constraints} constraints is not positive definite at constraint {constraint}"
    )]
    CapacitanceNotPositiveDefinite {
        /// The constraint (row of the capacitance) whose pivot failed.
        constraint: usize,
        /// How many constraints there are.
        constraints: usize,
    },
    /// A sparse matrix is not (numerically) positive definite: the sparse Cholesky
    /// factorization met a non-positive pivot.
    #[error("the sparse matrix is not positive definite (non-positive pivot at elimination step {step})")]
    SparseNotPositiveDefinite {
        /// The elimination step (the position in the fill-reducing ordering).
        step: usize,
    },
    /// A matrix given for a sparse refactorization does not have the analysed pattern.
    #[error("the matrix's sparsity pattern differs from the analysed one ({what})")]
    SparsePatternMismatch {
        /// What differs first (size, column pointers, column counts, row indices).
        what: &'static str,
    },
    /// A buffer of a sparse factorization could not be allocated.
    #[error("cannot allocate {what} of the sparse factorization")]
    SparseOutOfMemory {
        /// What the buffer is for.
        what: &'static str,
    },
    /// A sparse factorization's sizes overflow its index type.
    #[error("{what} of the sparse factorization overflows its index type")]
    SparseIndexOverflow {
        /// The stage that overflowed.
        what: &'static str,
    },
    /// A LAPACK routine reported a failure.
    #[error("LAPACK failed: {0}")]
    Lapack(String),
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, LinalgError>;
