//! The linear solve inside Newton's method, behind one seam: [`TangentSolver`] prepares
//! for an assembled tangent (the direct solver factors it) and then solves for steps and
//! for the grasps' compliance columns. The sparse Cholesky with the kept symbolic analysis
//! is the implementation today; an iterative solver (a multigrid-preconditioned conjugate
//! gradient) is another implementation of the same trait.

use std::sync::Arc;

use faer::MatMut;
use faer::sparse::SparseColMat;
use fibfluid_linalg::{ComplianceSource, SparseCholesky, SparseSymbolic};

use crate::error::{FemError, Result};

/// Diagonal shifts tried, in turn, on a tangent that is not positive definite (times its
/// largest diagonal entry; the last one makes the step a scaled gradient step).
pub(crate) const SHIFTS_TRIED: [f64; 6] = [0.0, 1e-8, 1e-6, 1e-4, 1e-2, 1.0];

/// The linear solve of Newton's iterations (see the module docs).
pub(crate) trait TangentSolver: ComplianceSource {
    /// Makes the solver ready for `tangent` (lower triangle, on the pattern `symbolic`
    /// analysed); a tangent that is not positive definite is shifted by a growing multiple
    /// of its largest diagonal entry ([`SHIFTS_TRIED`]). Returns the shift used (0: none).
    ///
    /// Errors: [`FemError::NotPositiveDefinite`] past the last shift.
    fn prepare(&mut self, tangent: &SparseColMat<usize, f64>, symbolic: &Arc<SparseSymbolic>) -> Result<f64>;

    /// Solves the prepared system for each column of `rhs`, in place.
    ///
    /// # Panics
    /// Before [`TangentSolver::prepare`] succeeded (a programming error).
    fn solve_in_place(&self, rhs: MatMut<'_, f64>);
}

/// The direct solver: the tangent's sparse Cholesky factor, refactored numerically on the
/// kept symbolic analysis at every [`TangentSolver::prepare`].
#[derive(Default)]
pub(crate) struct DirectSolver {
    pub(crate) factor: Option<SparseCholesky>,
}

impl ComplianceSource for DirectSolver {
    fn unknowns(&self) -> usize {
        self.factor.as_ref().map_or(0, ComplianceSource::unknowns)
    }

    fn compliance_columns(
        &self,
        rows: &[&fibfluid_linalg::SparseRow],
    ) -> fibfluid_linalg::Result<Vec<Vec<f64>>> {
        self.factor.as_ref().expect("prepared before use").compliance_columns(rows)
    }
}

impl TangentSolver for DirectSolver {
    fn prepare(&mut self, tangent: &SparseColMat<usize, f64>, symbolic: &Arc<SparseSymbolic>) -> Result<f64> {
        let mut matrix = tangent.clone();
        let n = matrix.ncols();
        let diagonal: Vec<usize> = (0..n).map(|j| matrix.symbolic().col_ptr()[j]).collect();
        let largest = diagonal.iter().map(|&p| matrix.val()[p].abs()).fold(0.0, f64::max);
        for shift in SHIFTS_TRIED {
            if shift > 0.0 {
                let values = matrix.val_mut();
                for &p in &diagonal {
                    values[p] += shift * largest;
                }
            }
            let result = match self.factor.as_mut() {
                Some(f) => f.refactor(matrix.as_ref()),
                None => SparseCholesky::factor(symbolic, matrix.as_ref()).map(|f| {
                    self.factor = Some(f);
                }),
            };
            match result {
                Ok(()) => return Ok(shift),
                Err(fibfluid_linalg::LinalgError::SparseNotPositiveDefinite { .. }) => continue,
                Err(e) => return Err(e.into()),
            }
        }
        Err(FemError::NotPositiveDefinite)
    }

    fn solve_in_place(&self, rhs: MatMut<'_, f64>) {
        self.factor.as_ref().expect("prepared before use").solve_in_place(rhs);
    }
}
