//! nalgebra LU of the dense bordered matrix.

use nalgebra::{DMatrix, DVector, Dyn, LU};

use crate::dense::{DenseFactorization, DenseKernel};
use crate::memory::{SINGLE_WHAT, try_collect};
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
    fn backend(&self) -> crate::Backend {
        crate::Backend::NalgebraLu
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
        let dense = a.try_to_dense_col_major()?;
        // The pivots are read from the packed factors (`lu_internal`, public though hidden
        // from nalgebra's docs) rather than from `u()`, which would copy the whole n x n
        // upper triangle just to read its diagonal.
        Ok(match precision {
            Precision::F64 => {
                let lu = DMatrix::<f64>::from_vec(dim, dim, dense).lu();
                let packed = lu.lu_internal();
                check_pivots(a, (0..dim).map(|i| (i, packed[(i, i)])))?;
                NalgebraKernel::F64(lu)
            }
            Precision::Mixed => {
                let single = try_collect(dense.len(), dense.iter().map(|v| *v as f32), SINGLE_WHAT)?;
                drop(dense);
                let lu = DMatrix::<f32>::from_vec(dim, dim, single).lu();
                let packed = lu.lu_internal();
                check_pivots(a, (0..dim).map(|i| (i, packed[(i, i)] as f64)))?;
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
