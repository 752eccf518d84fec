//! faer partial-pivot LU of the dense bordered matrix.
//!
//! The LU is computed in place in the dense matrix built from the bordered one and kept
//! packed (unit L strictly below the diagonal, U on and above it) with its row
//! permutation: no copy of the n^2 matrix besides the dense form itself. (faer's
//! `PartialPivLu` would copy the input and then split L and U into two more matrices,
//! about a third of the factorization time at n = 3001 on two cores.)

use std::time::Instant;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::lu::partial_pivoting::factor::{lu_in_place, lu_in_place_scratch};
use faer::linalg::lu::partial_pivoting::solve::{solve_in_place, solve_in_place_scratch};
use faer::perm::Perm;
use faer::traits::ComplexField;
use faer::{Mat, MatMut};

use crate::dense::{check_dense_memory, dense_lu_cost};
use crate::solver::{check_pivots, ensure_supported};
use crate::{BorderedMatrix, FactorCost, FactorOptions, Factorization, LinearSolver, Precision, Result};

/// Dense LU with partial pivoting from faer (the default dense backend).
#[derive(Clone, Copy, Debug, Default)]
pub struct FaerLu;

/// A packed LU and its row permutation.
struct Packed<T> {
    lu: Mat<T>,
    perm: Perm<usize>,
}

impl<T: ComplexField> Packed<T> {
    /// Factors `a` in place (partial pivoting, faer's global parallelism).
    fn factor(mut a: Mat<T>) -> Self {
        let n = a.nrows();
        let par = faer::get_global_parallelism();
        let mut fwd = vec![0usize; n];
        let mut inv = vec![0usize; n];
        let mut mem = MemBuffer::new(lu_in_place_scratch::<usize, T>(n, n, par, Default::default()));
        lu_in_place(a.as_mut(), &mut fwd, &mut inv, par, MemStack::new(&mut mem), Default::default());
        let perm = Perm::new_checked(fwd.into_boxed_slice(), inv.into_boxed_slice(), n);
        Self { lu: a, perm }
    }

    /// Solves in place for the columns of `rhs`.
    fn solve(&self, rhs: MatMut<'_, T>) {
        let par = faer::get_global_parallelism();
        let mut mem = MemBuffer::new(solve_in_place_scratch::<usize, T>(self.lu.nrows(), rhs.ncols(), par));
        // The unit lower solve reads only the strict lower triangle, the upper solve only
        // the upper one, so the packed matrix serves as both.
        solve_in_place(
            self.lu.as_ref(),
            self.lu.as_ref(),
            self.perm.as_ref(),
            rhs,
            par,
            MemStack::new(&mut mem),
        );
    }
}

enum Lu {
    F64(Packed<f64>),
    F32(Packed<f32>),
}

struct FaerLuFactorization {
    matrix: BorderedMatrix,
    opts: FactorOptions,
    lu: Lu,
    cost: FactorCost,
}

impl LinearSolver for FaerLu {
    fn name(&self) -> &'static str {
        "faer-lu"
    }

    fn supports(&self, _precision: Precision) -> bool {
        true
    }

    fn factorize(&self, a: &BorderedMatrix, opts: &FactorOptions) -> Result<Box<dyn Factorization>> {
        ensure_supported(self.name(), true, opts.precision)?;
        let (lu, cost) = factor(a, opts.precision)?;
        Ok(Box::new(FaerLuFactorization { matrix: a.clone(), opts: *opts, lu, cost }))
    }
}

fn factor(a: &BorderedMatrix, precision: Precision) -> Result<(Lu, FactorCost)> {
    let dim = a.dim();
    // Before anything touches the matrix: a system too large to hold densely fails at once.
    check_dense_memory(dim, 2)?;
    a.check_finite()?;
    let start = Instant::now();
    let dense = a.to_dense();
    let lu = match precision {
        Precision::F64 => {
            let lu = Packed::factor(dense);
            check_pivots(a, (0..dim).map(|i| (i, lu.lu[(i, i)])))?;
            Lu::F64(lu)
        }
        Precision::Mixed => {
            let single = Mat::<f32>::from_fn(dim, dim, |i, j| dense[(i, j)] as f32);
            drop(dense);
            let lu = Packed::factor(single);
            check_pivots(a, (0..dim).map(|i| (i, lu.lu[(i, i)] as f64)))?;
            Lu::F32(lu)
        }
    };
    let word = if precision == Precision::F64 { 8 } else { 4 };
    Ok((lu, dense_lu_cost(dim, start.elapsed().as_secs_f64(), word)))
}

impl Factorization for FaerLuFactorization {
    fn backend(&self) -> &'static str {
        "faer-lu"
    }

    fn matrix(&self) -> &BorderedMatrix {
        &self.matrix
    }

    fn options(&self) -> &FactorOptions {
        &self.opts
    }

    fn cost(&self) -> FactorCost {
        self.cost
    }

    fn solve_unrefined(&self, rhs: &mut [f64]) {
        let n = rhs.len();
        match &self.lu {
            Lu::F64(lu) => lu.solve(MatMut::from_column_major_slice_mut(rhs, n, 1)),
            Lu::F32(lu) => {
                let mut b: Vec<f32> = rhs.iter().map(|v| *v as f32).collect();
                lu.solve(MatMut::from_column_major_slice_mut(&mut b, n, 1));
                rhs.iter_mut().zip(&b).for_each(|(d, s)| *d = *s as f64);
            }
        }
    }

    fn set_border(&mut self, border: &[Vec<f64>]) -> Result<FactorCost> {
        self.matrix.set_border(border);
        let (lu, cost) = factor(&self.matrix, self.opts.precision)?;
        self.lu = lu;
        self.cost = cost;
        Ok(cost)
    }
}
