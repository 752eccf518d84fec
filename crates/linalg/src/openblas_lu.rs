//! LAPACK LU (getrf/getrs) through ndarray-linalg's LAPACK layer, linked to the system
//! OpenBLAS (feature `openblas`; Debian: `libopenblas-dev`).
//!
//! The factorization goes through `lax` (the crate under ndarray-linalg that wraps LAPACK)
//! rather than ndarray-linalg's `LUFactorized`, because the latter keeps the factors
//! private and the pivots must be checked to name a singular one.

use lax::layout::MatrixLayout;
use lax::{Lapack, Pivot, Transpose};

use crate::dense::{DenseFactorization, DenseKernel, SINGLE_WHAT, try_collect};
use crate::solver::check_pivots;
use crate::{BorderedMatrix, FactorOptions, Factorization, LinalgError, LinearSolver, Precision, Result};

// ndarray-linalg is what selects and links the LAPACK implementation (openblas-system).
use ndarray_linalg as _;

/// Dense LU from LAPACK (OpenBLAS's getrf/getrs).
#[derive(Clone, Copy, Debug, Default)]
pub struct OpenblasLu;

/// The column-major packed factors and pivots, in the precision they were made in.
enum OpenblasKernel {
    F64(Vec<f64>, Pivot),
    F32(Vec<f32>, Pivot),
}

impl LinearSolver for OpenblasLu {
    fn name(&self) -> &'static str {
        OpenblasKernel::NAME
    }

    fn supports(&self, _precision: Precision) -> bool {
        true
    }

    fn factorize(&self, a: &BorderedMatrix, opts: &FactorOptions) -> Result<Box<dyn Factorization>> {
        DenseFactorization::<OpenblasKernel>::boxed(a, opts)
    }
}

fn layout(dim: usize) -> MatrixLayout {
    MatrixLayout::F { col: dim as i32, lda: dim as i32 }
}

fn lapack_err(e: lax::error::Error, dim: usize) -> LinalgError {
    match e {
        lax::error::Error::LapackComputationalFailure { return_code } if return_code > 0 => {
            LinalgError::SingularPivot { index: (return_code as usize - 1).min(dim - 1), pivot: 0.0 }
        }
        other => LinalgError::Lapack(other.to_string()),
    }
}

/// Stack reserved for the LAPACK factorization (virtual memory; only what is used is committed).
///
/// OpenBLAS's threaded getrf keeps a job array of about 0.5 MiB on the stack at every level
/// of its recursion (Debian's build, 0.3.21), so a few hundred unknowns already overflow the
/// 2 MiB stack of a Rust spawned thread (test threads, rayon workers) and crash the process.
const GETRF_STACK_BYTES: usize = 64 << 20;

/// Runs `f` on a scoped thread with [`GETRF_STACK_BYTES`] of stack.
fn on_large_stack<T: Send>(f: impl FnOnce() -> T + Send) -> Result<T> {
    std::thread::scope(|s| {
        let handle = std::thread::Builder::new()
            .name("openblas-getrf".into())
            .stack_size(GETRF_STACK_BYTES)
            .spawn_scoped(s, f)
            .map_err(|e| LinalgError::Lapack(format!("cannot start the factorization thread: {e}")))?;
        Ok(handle.join().unwrap_or_else(|panic| std::panic::resume_unwind(panic)))
    })
}

impl DenseKernel for OpenblasKernel {
    const NAME: &'static str = "openblas-lu";

    fn factor(a: &BorderedMatrix, precision: Precision) -> Result<Self> {
        let dim = a.dim();
        // Column-major, as LAPACK takes it, factored in place.
        let dense = a.try_to_dense_col_major()?;
        Ok(match precision {
            Precision::F64 => {
                let mut buf = dense;
                let piv =
                    on_large_stack(|| f64::lu(layout(dim), &mut buf))?.map_err(|e| lapack_err(e, dim))?;
                check_pivots(a, (0..dim).map(|i| (i, buf[i * dim + i])))?;
                OpenblasKernel::F64(buf, piv)
            }
            Precision::Mixed => {
                let mut buf = try_collect(dense.len(), dense.iter().map(|v| *v as f32), SINGLE_WHAT)?;
                drop(dense);
                let piv =
                    on_large_stack(|| f32::lu(layout(dim), &mut buf))?.map_err(|e| lapack_err(e, dim))?;
                check_pivots(a, (0..dim).map(|i| (i, buf[i * dim + i] as f64)))?;
                OpenblasKernel::F32(buf, piv)
            }
        })
    }

    fn solve(&self, rhs: &mut [f64]) {
        let dim = rhs.len();
        // getrs only fails on argument errors, which the shapes rule out; a failure leaves
        // NaN so the checked solve reports it.
        match self {
            OpenblasKernel::F64(buf, piv) => {
                if f64::solve(layout(dim), Transpose::No, buf, piv, rhs).is_err() {
                    rhs.iter_mut().for_each(|v| *v = f64::NAN);
                }
            }
            OpenblasKernel::F32(buf, piv) => {
                let mut b: Vec<f32> = rhs.iter().map(|v| *v as f32).collect();
                if f32::solve(layout(dim), Transpose::No, buf, piv, &mut b).is_err() {
                    b.iter_mut().for_each(|v| *v = f32::NAN);
                }
                rhs.iter_mut().zip(&b).for_each(|(d, s)| *d = *s as f64);
            }
        }
    }
}

// The C entry point OpenBLAS exports to change its thread count at run time.
#[allow(unsafe_code)]
unsafe extern "C" {
    fn openblas_set_num_threads(num_threads: std::ffi::c_int);
}

/// Sets OpenBLAS's thread count (it reads `OPENBLAS_NUM_THREADS` only when it loads).
#[allow(unsafe_code)]
pub(crate) fn set_openblas_threads(n: usize) {
    let n = n.clamp(1, std::ffi::c_int::MAX as usize) as std::ffi::c_int;
    // SAFETY: a plain setter in the linked OpenBLAS; it takes any positive count.
    unsafe { openblas_set_num_threads(n) }
}
