//! nalgebra LU of the dense bordered matrix.

use nalgebra::{DMatrix, DVector, Dyn, LU};

use crate::dense::{DenseFactorization, DenseKernel};
use crate::solver::check_pivots;
use crate::{BorderedMatrix, FactorOptions, Factorization, LinearSolver, Precision, Result};

/// Dense LU with partial pivoting from nalgebra (single-threaded).
#[derive(Clone, Copy, Debug, Default)]
pub struct NalgebraLu;

/// The factors in the precision they were made in.
enum NalgebraKernel {
    F64(LU<f64, Dyn, Dyn>),
    F32(LU<f32, Dyn, Dyn>),
}

impl LinearSolver for NalgebraLu {
    fn name(&self) -> &'static str {
        NalgebraKernel::NAME
    }

    fn supports(&self, _precision: Precision) -> bool {
        true
    }

    fn factorize(&self, a: &BorderedMatrix, opts: &FactorOptions) -> Result<Box<dyn Factorization>> {
        DenseFactorization::<NalgebraKernel>::boxed(a, opts)
    }
}

impl DenseKernel for NalgebraKernel {
    const NAME: &'static str = "nalgebra-lu";

    fn factor(a: &BorderedMatrix, precision: Precision) -> Result<Self> {
        let dim = a.dim();
        // Column-major, nalgebra's storage order: no intermediate matrix.
        let dense = a.to_dense_col_major();
        Ok(match precision {
            Precision::F64 => {
                let lu = DMatrix::<f64>::from_vec(dim, dim, dense).lu();
                let u = lu.u();
                check_pivots(a, (0..dim).map(|i| (i, u[(i, i)])))?;
                NalgebraKernel::F64(lu)
            }
            Precision::Mixed => {
                let m = DMatrix::<f32>::from_iterator(dim, dim, dense.iter().map(|v| *v as f32));
                drop(dense);
                let lu = m.lu();
                let u = lu.u();
                check_pivots(a, (0..dim).map(|i| (i, u[(i, i)] as f64)))?;
                NalgebraKernel::F32(lu)
            }
        })
    }

    fn solve(&self, rhs: &mut [f64]) {
        // Pivots were checked at factorization, so the solves cannot report singular.
        match self {
            NalgebraKernel::F64(lu) => {
                let mut b = DVector::from_column_slice(rhs);
                let _ = lu.solve_mut(&mut b);
                rhs.copy_from_slice(b.as_slice());
            }
            NalgebraKernel::F32(lu) => {
                let mut b = DVector::from_iterator(rhs.len(), rhs.iter().map(|v| *v as f32));
                let _ = lu.solve_mut(&mut b);
                rhs.iter_mut().zip(b.iter()).for_each(|(d, s)| *d = *s as f64);
            }
        }
    }
}
