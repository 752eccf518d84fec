//! faer partial-pivot LU of the dense bordered matrix.
//!
//! The LU is computed in place in the column-major dense form of the bordered matrix
//! ([`BorderedMatrix::to_dense_col_major`], filled in parallel) and kept packed (unit L
//! strictly below the diagonal, U on and above it) with its row permutation: no copy of
//! the n^2 matrix besides the dense form itself. (faer's `PartialPivLu` would copy the input
//! and then split L and U into two more matrices, about a third of the factorization time
//! at n = 3001 on two cores.)

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::lu::partial_pivoting::factor::{lu_in_place, lu_in_place_scratch};
use faer::linalg::lu::partial_pivoting::solve::{solve_in_place, solve_in_place_scratch};
use faer::perm::Perm;
use faer::traits::ComplexField;
use faer::{MatMut, MatRef};

use crate::dense::{DenseFactorization, DenseKernel};
use crate::memory::{SINGLE_WHAT, try_collect};
use crate::solver::check_pivots;
use crate::{BorderedMatrix, FactorOptions, Factorization, LinearSolver, Precision, Result};

/// Dense LU with partial pivoting from faer (the default dense backend).
#[derive(Clone, Copy, Debug, Default)]
pub struct FaerLu;

/// A packed LU (n x n, column-major) and its row permutation.
struct Packed<T> {
    lu: Vec<T>,
    n: usize,
    perm: Perm<usize>,
}

impl<T: ComplexField> Packed<T> {
    /// Factors the column-major n x n matrix `a` in place (partial pivoting, faer's global
    /// parallelism).
    /// The scratch memory and the permutation are allocated fallibly
    /// ([`LinalgError::OutOfMemory`](crate::LinalgError::OutOfMemory)).
    fn factor(mut a: Vec<T>, n: usize) -> Result<Self> {
        let par = crate::parallel::compute_par();
        let mut fwd = try_collect(n, std::iter::repeat(0usize), "the LU permutation")?;
        let mut inv = try_collect(n, std::iter::repeat(0usize), "the LU permutation")?;
        let req = lu_in_place_scratch::<usize, T>(n, n, par, Default::default());
        let mut mem = MemBuffer::try_new(req).map_err(|_| crate::LinalgError::OutOfMemory {
            bytes: req.size_bytes(),
            what: "the LU scratch space",
        })?;
        let view = MatMut::from_column_major_slice_mut(&mut a, n, n);
        lu_in_place(view, &mut fwd, &mut inv, par, MemStack::new(&mut mem), Default::default());
        let perm = Perm::new_checked(fwd.into_boxed_slice(), inv.into_boxed_slice(), n);
        Ok(Self { lu: a, n, perm })
    }

    /// The pivot U_ii.
    fn pivot(&self, i: usize) -> &T {
        &self.lu[i * self.n + i]
    }

    /// Solves in place for the columns of `rhs`.
    fn solve(&self, rhs: MatMut<'_, T>) {
        let par = if rhs.ncols() <= crate::triangular::MAX_STREAM_RHS {
            crate::parallel::stream_par(self.n * self.n * std::mem::size_of::<T>())
        } else {
            crate::parallel::compute_par()
        };
        let mut mem = MemBuffer::new(solve_in_place_scratch::<usize, T>(self.n, rhs.ncols(), par));
        let lu = MatRef::from_column_major_slice(&self.lu, self.n, self.n);
        // The unit lower solve reads only the strict lower triangle, the upper solve only
        // the upper one, so the packed matrix serves as both.
        solve_in_place(lu, lu, self.perm.as_ref(), rhs, par, MemStack::new(&mut mem));
    }
}

/// The factors in the precision they were made in.
enum FaerKernel {
    F64(Packed<f64>),
    F32(Packed<f32>),
}

impl LinearSolver for FaerLu {
    fn backend(&self) -> crate::Backend {
        crate::Backend::FaerLu
    }

    fn supports(&self, _precision: Precision) -> bool {
        true
    }

    fn factorize(&self, a: &BorderedMatrix, opts: &FactorOptions) -> Result<Box<dyn Factorization>> {
        DenseFactorization::<FaerKernel>::boxed(a, opts)
    }
}

impl DenseKernel for FaerKernel {
    const NAME: &'static str = "faer-lu";

    fn factor(a: &BorderedMatrix, precision: Precision) -> Result<Self> {
        let dim = a.dim();
        let dense = a.try_to_dense_col_major()?;
        Ok(match precision {
            Precision::F64 => {
                let lu = Packed::factor(dense, dim)?;
                check_pivots(a, (0..dim).map(|i| (i, *lu.pivot(i))))?;
                FaerKernel::F64(lu)
            }
            Precision::Mixed => {
                let single = try_collect(dense.len(), dense.iter().map(|v| *v as f32), SINGLE_WHAT)?;
                drop(dense);
                let lu = Packed::factor(single, dim)?;
                check_pivots(a, (0..dim).map(|i| (i, *lu.pivot(i) as f64)))?;
                FaerKernel::F32(lu)
            }
        })
    }

    fn solve(&self, rhs: &mut [f64]) {
        let n = rhs.len();
        match self {
            FaerKernel::F64(lu) => lu.solve(MatMut::from_column_major_slice_mut(rhs, n, 1)),
            FaerKernel::F32(lu) => {
                let mut b: Vec<f32> = rhs.iter().map(|v| *v as f32).collect();
                lu.solve(MatMut::from_column_major_slice_mut(&mut b, n, 1));
                rhs.iter_mut().zip(&b).for_each(|(d, s)| *d = *s as f64);
            }
        }
    }
}
