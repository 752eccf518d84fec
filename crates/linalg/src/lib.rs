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
//! Backends (each behind a Cargo feature, selectable at run time with [`backend_by_name`]):
//! - `faer-lu` ([`FaerLu`]): faer partial-pivot LU of the dense matrix;
//! - `nalgebra-lu` ([`NalgebraLu`]): nalgebra LU of the dense matrix;
//! - `openblas-lu` (`OpenblasLu`, feature `openblas`): LAPACK getrf/getrs via ndarray-linalg,
//!   linked to the system OpenBLAS;
//! - `structured` ([`Structured`], always built): a Cholesky per block (one when shared) plus
//!   a scalar Schur complement for the pressure, `P = (S.K^-1 b - t) / (S.K^-1 S)`, so a new
//!   border costs triangular solves only and the dense matrix is never formed.

// Without a dense backend the shared dense helpers are unused.
#![cfg_attr(not(any(feature = "faer-lu", feature = "nalgebra-lu", feature = "openblas")), allow(dead_code))]

mod dense;
mod error;
mod matrix;
mod solver;
mod structured;
pub mod threads;

#[cfg(feature = "faer-lu")]
mod faer_lu;
#[cfg(feature = "nalgebra-lu")]
mod nalgebra_lu;
#[cfg(feature = "openblas")]
mod openblas_lu;

pub use dense::{DENSE_MEMORY_FRACTION, available_memory_bytes, check_dense_memory};
pub use error::{LinalgError, Result};
pub use matrix::{Blocks, BorderedMatrix};
pub use solver::{
    DEFAULT_MAX_RESIDUAL, DEFAULT_TARGET_RESIDUAL, FactorCost, FactorOptions, Factorization,
    FactorizationExt, LinearSolver, LinearSolverExt, Precision, Solution, componentwise_backward_error,
};
pub use structured::Structured;

#[cfg(feature = "faer-lu")]
pub use faer_lu::FaerLu;
#[cfg(feature = "nalgebra-lu")]
pub use nalgebra_lu::NalgebraLu;
#[cfg(feature = "openblas")]
pub use openblas_lu::OpenblasLu;

/// Re-export of the dense matrix type used throughout (faer's `Mat<f64>`).
pub use faer::Mat;

/// Names of the backends compiled into this build, in a stable order.
pub fn backend_names() -> Vec<&'static str> {
    let mut v = vec!["structured"];
    if cfg!(feature = "faer-lu") {
        v.push("faer-lu");
    }
    if cfg!(feature = "nalgebra-lu") {
        v.push("nalgebra-lu");
    }
    if cfg!(feature = "openblas") {
        v.push("openblas-lu");
    }
    v
}

/// Every backend compiled into this build.
pub fn all_backends() -> Vec<Box<dyn LinearSolver>> {
    backend_names().into_iter().filter_map(|n| backend_by_name(n).ok()).collect()
}

/// Every backend this crate knows, compiled in or not: (run-time name, Cargo feature that
/// builds it, what the feature needs besides Rust). `structured` is always built.
pub const KNOWN_BACKENDS: [(&str, &str, &str); 4] = [
    ("structured", "", ""),
    ("faer-lu", "faer-lu", ""),
    ("nalgebra-lu", "nalgebra-lu", ""),
    ("openblas-lu", "openblas", " (needs the system OpenBLAS: Debian/Ubuntu package libopenblas-dev)"),
];

/// The backend with this run-time name. A known backend left out of this build is
/// [`LinalgError::NotCompiledIn`] (naming the Cargo feature that builds it); any other name
/// is [`LinalgError::UnknownBackend`]. Both list the compiled-in backends.
pub fn backend_by_name(name: &str) -> Result<Box<dyn LinearSolver>> {
    match name {
        "structured" => Ok(Box::new(Structured)),
        #[cfg(feature = "faer-lu")]
        "faer-lu" => Ok(Box::new(FaerLu)),
        #[cfg(feature = "nalgebra-lu")]
        "nalgebra-lu" => Ok(Box::new(NalgebraLu)),
        #[cfg(feature = "openblas")]
        "openblas-lu" => Ok(Box::new(OpenblasLu)),
        _ => {
            let available = backend_names().join(", ");
            Err(match KNOWN_BACKENDS.iter().find(|(known, _, _)| *known == name) {
                Some(&(_, feature, requirement)) => {
                    LinalgError::NotCompiledIn { name: name.to_string(), feature, requirement, available }
                }
                None => LinalgError::UnknownBackend { name: name.to_string(), available },
            })
        }
    }
}

/// Model flop count of a dense LU of an n x n matrix, (2/3) n^3.
pub fn lu_flops(n: usize) -> f64 {
    2.0 / 3.0 * (n as f64).powi(3)
}

/// Model flop count of a Cholesky of an n x n matrix, (1/3) n^3.
pub fn cholesky_flops(n: usize) -> f64 {
    (n as f64).powi(3) / 3.0
}
