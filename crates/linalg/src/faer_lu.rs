//! faer partial-pivot LU of the dense bordered matrix.

use std::time::Instant;

use faer::Mat;
use faer::linalg::solvers::{PartialPivLu, Solve};

use crate::dense::{check_dense_memory, dense_lu_cost};
use crate::solver::{check_pivots, ensure_supported};
use crate::{BorderedMatrix, FactorCost, FactorOptions, Factorization, LinearSolver, Precision, Result};

/// Dense LU with partial pivoting from faer (the default dense backend).
#[derive(Clone, Copy, Debug, Default)]
pub struct FaerLu;

enum Lu {
    F64(PartialPivLu<f64>),
    F32(PartialPivLu<f32>),
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
            let lu = dense.partial_piv_lu();
            check_pivots(a, (0..dim).map(|i| (i, lu.U()[(i, i)])))?;
            Lu::F64(lu)
        }
        Precision::Mixed => {
            let single = Mat::<f32>::from_fn(dim, dim, |i, j| dense[(i, j)] as f32);
            drop(dense);
            let lu = single.partial_piv_lu();
            check_pivots(a, (0..dim).map(|i| (i, lu.U()[(i, i)] as f64)))?;
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
            Lu::F64(lu) => {
                let mut b = Mat::<f64>::from_fn(n, 1, |i, _| rhs[i]);
                lu.solve_in_place(b.as_mut());
                rhs.iter_mut().enumerate().for_each(|(i, v)| *v = b[(i, 0)]);
            }
            Lu::F32(lu) => {
                let mut b = Mat::<f32>::from_fn(n, 1, |i, _| rhs[i] as f32);
                lu.solve_in_place(b.as_mut());
                rhs.iter_mut().enumerate().for_each(|(i, v)| *v = b[(i, 0)] as f64);
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
