//! Linear algebra for the fiber–fluid method.
//!
//! The FFM equilibrium is a bordered system of size dN+1 (d = 2 or 3 axes, N vertices):
//! one weighted graph Laplacian `K_c` per axis (symmetric, positive definite once a vertex
//! is fixed), coupled only through a border column and row holding the vertex area vectors
//! `S` (volume conservation), with the pressure change as the last unknown:
//!
//! ```text
//! K_c u_c + S_c P = b_c      (c = x, y, z)
//! sum_c S_c . u_c = t        (t = 0 in the paper, V0 - V to correct volume drift)
//! ```
//!
//! [`BorderedMatrix`] holds that system without forming it densely. A [`LinearSolver`]
//! factorizes it once and returns a [`Factorization`] that solves many right-hand sides;
//! [`FactorizationExt`] adds checked solves (residuals are always computed, and refined in
//! mixed precision) and a condition estimate.
//!
//! Backends (each behind a Cargo feature, selectable at run time through [`Backend`]):
//! - `faer-lu` ([`FaerLu`]): faer partial-pivot LU of the dense matrix;
//! - `nalgebra-lu` ([`NalgebraLu`]): nalgebra LU of the dense matrix;
//! - `openblas-lu` (`OpenblasLu`, feature `openblas`): LAPACK getrf of the system OpenBLAS
//!   on ndarray arrays, solved with ndarray-linalg's triangular solves;
//! - `structured` ([`Structured`], always built): a Cholesky per block (one when shared) plus
//!   a scalar Schur complement for the pressure, `P = (S.K^-1 b - t) / (S.K^-1 S)`, so a new
//!   border costs triangular solves only and the dense matrix is never formed.
//!
//! [`CoupledCholesky`] solves the same bordered form when the stiffness couples the axes
//! (a dense dN x dN `K`, the projected fibers): a Cholesky of `K` and the Schur complement
//! of the border.
//!
//! [`SparseCholesky`] factors a sparse symmetric positive definite matrix given by its lower
//! triangle (faer's supernodal or simplicial Cholesky, the finite-element stiffness). The
//! symbolic analysis ([`SparseSymbolic`]: fill-reducing ordering, given or AMD, and the
//! structure of the factor) is kept and shared, so new values on the same pattern cost a
//! numeric [`refactor`](SparseCholesky::refactor) only; a matrix on another pattern is
//! refused with a typed error.
//!
//! Constraints imposed on a kept factorization instead of refactoring (held vertices,
//! contact rows, the finite-element holds) share one capacitance (Sherman–Morrison–Woodbury)
//! update: [`RowCapacitance`] forms `E' W` through a [`CapacitanceSource`], factors it
//! with [`CapacitanceFactor`] (the one small dense Cholesky) and applies `x -= W r` through
//! the source; the sources are dense columns `W = A^-1 E` ([`ComplianceSource`], from any
//! kept factorization: [`PrescribedSet`], the finite-element holds) and the vertex
//! compliance columns ([`VertexSource`] over a [`VertexResponse`]: [`HeldCapacitance`]).

// Without a dense backend the shared dense helpers are unused.
#![cfg_attr(not(any(feature = "faer-lu", feature = "nalgebra-lu", feature = "openblas")), allow(dead_code))]

mod block_view;
mod capacitance;
mod choice;
mod coupled;
mod dense;
mod error;
mod held;
mod in_place;
mod matrix;
mod memory;
pub mod multigrid;
pub mod parallel;
mod prescribed;
mod residual;
mod solver;
mod sparse;
mod structured;
pub mod threads;
mod triangular;

#[cfg(feature = "faer-lu")]
mod faer_lu;
#[cfg(feature = "nalgebra-lu")]
mod nalgebra_lu;
#[cfg(feature = "openblas")]
mod openblas_lu;

pub use capacitance::{
    CapacitanceFactor, CapacitanceSource, ComplianceSource, RowCapacitance, SparseRow, row_dot,
};
pub use choice::{Choice, ParseChoiceError};
pub use coupled::CoupledCholesky;
pub use error::{LinalgError, Result};
pub use held::{
    CAPACITANCE_PIVOT_FACTOR, HeldCapacitance, HeldRow, VertexColumns, VertexForce, VertexResponse,
    VertexSource, add_field_by_columns,
};
pub use matrix::{Blocks, BorderedMatrix};
pub use memory::{
    DENSE_MEMORY_FRACTION, available_memory_bytes, check_dense_memory, memory_budget, total_memory_bytes,
};
pub use prescribed::{ConstrainedSolution, PrescribedSet};
pub use solver::{
    DEFAULT_MAX_RESIDUAL, DEFAULT_TARGET_RESIDUAL, FactorCost, FactorOptions, Factorization,
    FactorizationExt, LinearSolver, LinearSolverExt, Precision, Solution, TARGET_RESIDUAL_PER_UNKNOWN,
    componentwise_backward_error,
};
pub use sparse::{SparseCholesky, SparseOrdering, SparseSymbolic};
pub use structured::Structured;

#[cfg(feature = "faer-lu")]
pub use faer_lu::FaerLu;
#[cfg(feature = "nalgebra-lu")]
pub use nalgebra_lu::NalgebraLu;
#[cfg(feature = "openblas")]
pub use openblas_lu::OpenblasLu;

/// Re-export of the dense matrix type used throughout (faer's `Mat<f64>`).
pub use faer::Mat;

/// A linear backend, by name. Every backend is named here whether or not its Cargo
/// feature is compiled in, so asking for a missing one says how to get it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Backend {
    /// Cholesky of the stiffness blocks + Schur complement ([`Structured`], always built).
    #[default]
    Structured,
    /// faer partial-pivot LU of the dense matrix (feature `faer-lu`).
    FaerLu,
    /// nalgebra LU of the dense matrix (feature `nalgebra-lu`).
    NalgebraLu,
    /// LAPACK getrf of the system OpenBLAS, solves through ndarray-linalg (feature `openblas`).
    OpenblasLu,
}

impl Choice for Backend {
    const WHAT: &'static str = "backend";
    const ALL: &'static [Self] =
        &[Backend::Structured, Backend::FaerLu, Backend::NalgebraLu, Backend::OpenblasLu];
    fn name(self) -> &'static str {
        match self {
            Backend::Structured => "structured",
            Backend::FaerLu => "faer-lu",
            Backend::NalgebraLu => "nalgebra-lu",
            Backend::OpenblasLu => "openblas-lu",
        }
    }
}
impl_choice!(Backend);

impl Backend {
    /// The Cargo feature that compiles this backend in (`None`: always built).
    pub fn feature(self) -> Option<&'static str> {
        match self {
            Backend::Structured => None,
            Backend::FaerLu => Some("faer-lu"),
            Backend::NalgebraLu => Some("nalgebra-lu"),
            Backend::OpenblasLu => Some("openblas"),
        }
    }

    /// What the backend's feature needs besides Rust, with a leading separator (empty
    /// when nothing).
    pub fn requirement(self) -> &'static str {
        match self {
            Backend::OpenblasLu => " (needs the system OpenBLAS: Debian/Ubuntu package libopenblas-dev)",
            _ => "",
        }
    }

    /// Whether this build has the backend.
    pub fn is_compiled(self) -> bool {
        match self {
            Backend::Structured => true,
            Backend::FaerLu => cfg!(feature = "faer-lu"),
            Backend::NalgebraLu => cfg!(feature = "nalgebra-lu"),
            Backend::OpenblasLu => cfg!(feature = "openblas"),
        }
    }

    /// Whether the backend forms and factors the dense (dN+1)^2 matrix.
    pub fn is_dense(self) -> bool {
        self != Backend::Structured
    }

    /// The backends compiled into this build, in a stable order.
    pub fn compiled() -> Vec<Backend> {
        Backend::ALL.iter().copied().filter(|b| b.is_compiled()).collect()
    }

    /// The solver, or [`LinalgError::NotCompiled`] naming the feature to enable.
    pub fn solver(self) -> Result<Box<dyn LinearSolver>> {
        match self {
            Backend::Structured => Ok(Box::new(Structured)),
            #[cfg(feature = "faer-lu")]
            Backend::FaerLu => Ok(Box::new(FaerLu)),
            #[cfg(feature = "nalgebra-lu")]
            Backend::NalgebraLu => Ok(Box::new(NalgebraLu)),
            #[cfg(feature = "openblas")]
            Backend::OpenblasLu => Ok(Box::new(OpenblasLu)),
            #[allow(unreachable_patterns)]
            other => Err(LinalgError::NotCompiled {
                backend: other.name(),
                feature: other.feature().unwrap_or_default(),
                requirement: other.requirement(),
                compiled: Backend::compiled().iter().map(|b| b.name()).collect::<Vec<_>>().join(", "),
            }),
        }
    }
}

/// Every backend compiled into this build.
pub fn all_backends() -> Vec<Box<dyn LinearSolver>> {
    Backend::compiled().into_iter().filter_map(|b| b.solver().ok()).collect()
}

/// Model flop count of a dense LU of an n x n matrix, (2/3) n^3.
pub fn lu_flops(n: usize) -> f64 {
    2.0 / 3.0 * (n as f64).powi(3)
}

/// Model flop count of a Cholesky of an n x n matrix, (1/3) n^3.
pub fn cholesky_flops(n: usize) -> f64 {
    (n as f64).powi(3) / 3.0
}
