//! nalgebra LU of the dense bordered matrix.

use std::time::Instant;

use nalgebra::{DMatrix, DVector, LU};

use crate::dense::{check_dense_memory, dense_lu_cost};
use crate::solver::{check_pivots, ensure_supported};
use crate::{BorderedMatrix, FactorCost, FactorOptions, Factorization, LinearSolver, Precision, Result};

/// Dense LU with partial pivoting from nalgebra (single-threaded).
#[derive(Clone, Copy, Debug, Default)]
pub struct NalgebraLu;

enum Lu {
    F64(LU<f64, nalgebra::Dyn, nalgebra::Dyn>),
    F32(LU<f32, nalgebra::Dyn, nalgebra::Dyn>),
}

struct NalgebraFactorization {
    matrix: BorderedMatrix,
    opts: FactorOptions,
    lu: Lu,
    cost: FactorCost,
}

impl LinearSolver for NalgebraLu {
    fn name(&self) -> &'static str {
        "nalgebra-lu"
    }

    fn supports(&self, _precision: Precision) -> bool {
        true
    }

    fn factorize(&self, a: &BorderedMatrix, opts: &FactorOptions) -> Result<Box<dyn Factorization>> {
        ensure_supported(self.name(), true, opts.precision)?;
        let (lu, cost) = factor(a, opts.precision)?;
        Ok(Box::new(NalgebraFactorization { matrix: a.clone(), opts: *opts, lu, cost }))
    }
}

fn factor(a: &BorderedMatrix, precision: Precision) -> Result<(Lu, FactorCost)> {
    let dim = a.dim();
    // Before anything touches the matrix: a system too large to hold densely fails at once.
    check_dense_memory(dim, 2)?;
    a.check_finite()?;
    let start = Instant::now();
    // Column-major, nalgebra's storage order: no intermediate matrix.
    let dense = a.to_dense_col_major();
    let lu = match precision {
        Precision::F64 => {
            let m = DMatrix::<f64>::from_vec(dim, dim, dense);
            let lu = m.lu();
            let u = lu.u();
            check_pivots(a, (0..dim).map(|i| (i, u[(i, i)])))?;
            Lu::F64(lu)
        }
        Precision::Mixed => {
            let m = DMatrix::<f32>::from_iterator(dim, dim, dense.iter().map(|v| *v as f32));
            drop(dense);
            let lu = m.lu();
            let u = lu.u();
            check_pivots(a, (0..dim).map(|i| (i, u[(i, i)] as f64)))?;
            Lu::F32(lu)
        }
    };
    let word = if precision == Precision::F64 { 8 } else { 4 };
    Ok((lu, dense_lu_cost(dim, start.elapsed().as_secs_f64(), word)))
}

impl Factorization for NalgebraFactorization {
    fn backend(&self) -> &'static str {
        "nalgebra-lu"
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
        match &self.lu {
            Lu::F64(lu) => {
                let mut b = DVector::from_column_slice(rhs);
                // Pivots were checked at factorization, so the solve cannot report singular.
                let _ = lu.solve_mut(&mut b);
                rhs.copy_from_slice(b.as_slice());
            }
            Lu::F32(lu) => {
                let mut b = DVector::from_iterator(rhs.len(), rhs.iter().map(|v| *v as f32));
                let _ = lu.solve_mut(&mut b);
                rhs.iter_mut().zip(b.iter()).for_each(|(d, s)| *d = *s as f64);
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
