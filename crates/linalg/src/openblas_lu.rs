//! LAPACK LU on ndarray arrays through ndarray-linalg, linked to the system OpenBLAS
//! (feature `openblas`; Debian: `libopenblas-dev`).
//!
//! What goes through ndarray-linalg's own API:
//! - the factors live in an ndarray `Array2` in column-major order (the dense form written
//!   once by `BorderedMatrix::to_dense_col_major` and moved in without a copy), and
//!   ndarray-linalg's `AllocatedArray` checks its strides and gives LAPACK its layout;
//! - every solve: the row interchanges, then ndarray-linalg's `SolveTriangularInplace` with
//!   `UPLO::Lower` + `Diag::Unit` (L) and `UPLO::Upper` + `Diag::NonUnit` (U) on the packed
//!   factors. That is what LAPACK's getrs does (laswp, then the two triangular solves), with
//!   the same flops.
//!
//! Where it cannot serve, and why:
//! - **The factorization is `Lapack::lu` (getrf) on the array's memory, not
//!   `FactorizeInto::factorize_into`.** The `LUFactorized` that the latter returns keeps the
//!   factors and the pivots in private fields (ndarray-linalg 0.18.1 has no accessor and no
//!   constructor from parts), and the singular-pivot check reads U's diagonal: like the
//!   other dense backends, a pivot that is zero to working precision is reported with its
//!   index and value instead of being passed on to a meaningless solve. getrf itself only
//!   reports pivots that are exactly zero. `Lapack` is ndarray-linalg's public re-export of
//!   the trait of its LAPACK layer (`lax`), so no other crate is named for it.
//! - **Hence the solves cannot be `LUFactorized::solve_inplace`** either: there is no
//!   `LUFactorized` to call it on. The triangular solves above are the closest
//!   ndarray-linalg call.
//! - **The factorization runs on a thread with a 64 MiB stack** ([`GETRF_STACK_BYTES`]),
//!   which no ndarray-linalg call arranges: OpenBLAS 0.3.21's threaded getrf overflows the
//!   2 MiB stack of Rust's spawned threads.
//!
//! Mixed precision is no obstacle: the same calls run on an `Array2<f32>` (sgetrf, strtrs).

use ndarray::{Array2, ShapeBuilder};
use ndarray_linalg::layout::{AllocatedArray, AllocatedArrayMut};
use ndarray_linalg::{Diag, Lapack, Pivot, SolveTriangularInplace, UPLO};

use crate::dense::{DenseFactorization, DenseKernel};
use crate::memory::{SINGLE_WHAT, try_collect};
use crate::solver::check_pivots;
use crate::{BorderedMatrix, FactorOptions, Factorization, LinalgError, LinearSolver, Precision, Result};

/// Dense LU from LAPACK (OpenBLAS's getrf, then triangular solves).
#[derive(Clone, Copy, Debug, Default)]
pub struct OpenblasLu;

/// The factors in the precision they were made in.
enum OpenblasKernel {
    F64(LuFactors<f64>),
    F32(LuFactors<f32>),
}

/// getrf's output: L (unit diagonal not stored) below the diagonal and U on and above it,
/// packed in one column-major array, and the 1-based row interchanges.
struct LuFactors<A> {
    lu: Array2<A>,
    pivots: Pivot,
}

impl LinearSolver for OpenblasLu {
    fn backend(&self) -> crate::Backend {
        crate::Backend::OpenblasLu
    }

    fn supports(&self, _precision: Precision) -> bool {
        true
    }

    fn factorize(&self, a: &BorderedMatrix, opts: &FactorOptions) -> Result<Box<dyn Factorization>> {
        DenseFactorization::<OpenblasKernel>::boxed(a, opts)
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

fn lapack_err(e: impl std::fmt::Display) -> LinalgError {
    LinalgError::Lapack(e.to_string())
}

impl<A: Lapack + Copy + Send + Into<f64>> LuFactors<A> {
    /// Factors `m`, the dense form of `a` in column-major order, in place and checks the
    /// pivots against `a`'s columns.
    fn factor(a: &BorderedMatrix, mut m: Array2<A>) -> Result<Self> {
        let layout = m.square_layout().map_err(lapack_err)?;
        let buf = m.as_allocated_mut().map_err(lapack_err)?;
        let factored = on_large_stack(|| A::lu(layout, buf))?;
        // getrf reports an exactly zero pivot (info > 0) as an error but completes the
        // factors, so the check below names it; the shapes rule out argument errors.
        check_pivots(a, m.diag().iter().enumerate().map(|(i, p)| (i, (*p).into())))?;
        Ok(Self { lu: m, pivots: factored.map_err(lapack_err)? })
    }

    /// Solves in place: `P A = L U`, so `x = U^-1 L^-1 P b`.
    fn solve(&self, b: &mut [A]) -> std::result::Result<(), ndarray_linalg::error::LinalgError> {
        for (i, &p) in self.pivots.iter().enumerate() {
            b.swap(i, p as usize - 1);
        }
        // An n x 1 column-major array has the factors' layout: no transposed copy inside.
        let mut col = Array2::from_shape_vec((b.len(), 1).f(), b.to_vec())?;
        self.lu.solve_triangular_inplace(UPLO::Lower, Diag::Unit, &mut col)?;
        self.lu.solve_triangular_inplace(UPLO::Upper, Diag::NonUnit, &mut col)?;
        b.iter_mut().zip(col.iter()).for_each(|(d, s)| *d = *s);
        Ok(())
    }
}

impl DenseKernel for OpenblasKernel {
    const NAME: &'static str = "openblas-lu";

    fn factor(a: &BorderedMatrix, precision: Precision) -> Result<Self> {
        let dim = a.dim();
        // Column-major, as LAPACK takes it, factored in place.
        let dense = a.try_to_dense_col_major()?;
        let shape = (dim, dim).f();
        let shape_err = |e: ndarray::ShapeError| LinalgError::Lapack(e.to_string());
        Ok(match precision {
            Precision::F64 => {
                let m = Array2::from_shape_vec(shape, dense).map_err(shape_err)?;
                OpenblasKernel::F64(LuFactors::factor(a, m)?)
            }
            Precision::Mixed => {
                let single = try_collect(dense.len(), dense.iter().map(|v| *v as f32), SINGLE_WHAT)?;
                drop(dense);
                let m = Array2::from_shape_vec(shape, single).map_err(shape_err)?;
                OpenblasKernel::F32(LuFactors::factor(a, m)?)
            }
        })
    }

    fn solve(&self, rhs: &mut [f64]) {
        // The solves only fail on argument errors, which the shapes rule out, or on an exactly
        // zero diagonal, which the pivot check rules out; a failure leaves NaN so the checked
        // solve reports it.
        match self {
            OpenblasKernel::F64(f) => {
                if f.solve(rhs).is_err() {
                    rhs.iter_mut().for_each(|v| *v = f64::NAN);
                }
            }
            OpenblasKernel::F32(f) => {
                let mut b: Vec<f32> = rhs.iter().map(|v| *v as f32).collect();
                if f.solve(&mut b).is_err() {
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
