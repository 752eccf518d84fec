//! The linear solve inside Newton's method, behind one seam: [`TangentSolver`] prepares
//! for an assembled tangent (the direct solver factors it, the multigrid builds its levels)
//! and then solves for steps and for the grasps' compliance columns.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use faer::MatMut;
use faer::sparse::SparseColMat;
use fibfluid_linalg::multigrid::Multigrid;
use fibfluid_linalg::{ComplianceSource, SparseCholesky, SparseRow, SparseSymbolic};

use crate::error::{FemError, Result};
use crate::multigrid::GridLevels;

/// Diagonal shifts tried, in turn, on a tangent that is not positive definite (times its
/// largest diagonal entry; the last one makes the step a scaled gradient step).
pub(crate) const SHIFTS_TRIED: [f64; 6] = [0.0, 1e-8, 1e-6, 1e-4, 1e-2, 1.0];

/// Relative residual of the multigrid solves for the grasps' compliance columns.
const COLUMN_TOLERANCE: f64 = 1e-10;

/// The linear solve of Newton's iterations (see the module docs).
pub(crate) trait TangentSolver: ComplianceSource {
    /// Makes the solver ready for `tangent` (lower triangle); a tangent that is not
    /// positive definite is shifted by a growing multiple of its largest diagonal entry
    /// ([`SHIFTS_TRIED`]). Returns the shift used (0: none).
    ///
    /// Errors: [`FemError::NotPositiveDefinite`] past the last shift.
    fn prepare(&mut self, tangent: &SparseColMat<usize, f64>) -> Result<f64>;

    /// Solves the prepared system for each column of `rhs`, in place.
    ///
    /// # Panics
    /// Before [`TangentSolver::prepare`] succeeded (a programming error).
    fn solve_in_place(&self, rhs: MatMut<'_, f64>);

    /// The relative residual an iterative solver stops at (inexact Newton: it follows the
    /// nonlinear residual); a direct solver ignores it.
    fn set_tolerance(&mut self, _relative: f64) {}

    /// Whether a solve since the last call met a direction of non-positive curvature (an
    /// iterative solver's sign of an indefinite tangent; the direct solver shifts instead).
    fn take_negative_curvature(&self) -> bool {
        false
    }
}

/// The direct solver: the tangent's sparse Cholesky factor, refactored numerically on the
/// kept symbolic analysis at every [`TangentSolver::prepare`].
pub(crate) struct DirectSolver {
    symbolic: Arc<SparseSymbolic>,
    pub(crate) factor: Option<SparseCholesky>,
}

impl DirectSolver {
    /// The direct solver on the tangent's symbolic analysis.
    pub(crate) fn new(symbolic: Arc<SparseSymbolic>) -> Self {
        Self { symbolic, factor: None }
    }
}

impl ComplianceSource for DirectSolver {
    fn unknowns(&self) -> usize {
        self.symbolic.dim()
    }

    fn compliance_columns(&self, rows: &[&SparseRow]) -> fibfluid_linalg::Result<Vec<Vec<f64>>> {
        self.factor.as_ref().expect("prepared before use").compliance_columns(rows)
    }
}

impl TangentSolver for DirectSolver {
    fn prepare(&mut self, tangent: &SparseColMat<usize, f64>) -> Result<f64> {
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
                None => SparseCholesky::factor(&self.symbolic, matrix.as_ref()).map(|f| {
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

/// Conjugate gradients preconditioned by the grid's multigrid: the levels are rebuilt at
/// every [`TangentSolver::prepare`] (Galerkin products of the new tangent), and each solve
/// stops at the relative residual [`TangentSolver::set_tolerance`] asked for.
pub(crate) struct MultigridSolver {
    levels: Arc<GridLevels>,
    multigrid: Option<Multigrid>,
    tolerance: f64,
    /// Conjugate-gradient iterations and solves since the solver was made.
    pub(crate) iterations: AtomicUsize,
    pub(crate) solves: AtomicUsize,
    /// Whether a solve met a direction of non-positive curvature.
    pub(crate) negative_curvature: AtomicBool,
}

impl MultigridSolver {
    /// The multigrid solver on a body's grid levels.
    pub(crate) fn new(levels: Arc<GridLevels>) -> Self {
        Self {
            levels,
            multigrid: None,
            tolerance: 1e-8,
            iterations: AtomicUsize::new(0),
            solves: AtomicUsize::new(0),
            negative_curvature: AtomicBool::new(false),
        }
    }

    fn solve_one(&self, x: &mut [f64], tolerance: f64) {
        let multigrid = self.multigrid.as_ref().expect("prepared before use");
        let outcome = self.levels.solve(multigrid, x, tolerance);
        self.iterations.fetch_add(outcome.iterations, Ordering::Relaxed);
        self.solves.fetch_add(1, Ordering::Relaxed);
        if outcome.negative_curvature {
            self.negative_curvature.store(true, Ordering::Relaxed);
        }
    }
}

impl ComplianceSource for MultigridSolver {
    fn unknowns(&self) -> usize {
        self.levels.free_dofs()
    }

    fn compliance_columns(&self, rows: &[&SparseRow]) -> fibfluid_linalg::Result<Vec<Vec<f64>>> {
        let n = self.unknowns();
        Ok(rows
            .iter()
            .map(|row| {
                let mut x = vec![0.0; n];
                for &(i, c) in row.iter() {
                    x[i] += c;
                }
                self.solve_one(&mut x, COLUMN_TOLERANCE);
                x
            })
            .collect())
    }
}

impl TangentSolver for MultigridSolver {
    fn prepare(&mut self, tangent: &SparseColMat<usize, f64>) -> Result<f64> {
        self.multigrid = None;
        for shift in SHIFTS_TRIED {
            match self.levels.hierarchy(tangent.as_ref(), shift) {
                Ok(m) => {
                    self.multigrid = Some(m);
                    return Ok(shift);
                }
                Err(FemError::NotPositiveDefinite) => continue,
                Err(e) => return Err(e),
            }
        }
        Err(FemError::NotPositiveDefinite)
    }

    fn solve_in_place(&self, mut rhs: MatMut<'_, f64>) {
        for j in 0..rhs.ncols() {
            let mut x: Vec<f64> = (0..rhs.nrows()).map(|i| rhs[(i, j)]).collect();
            self.solve_one(&mut x, self.tolerance);
            for (i, v) in x.into_iter().enumerate() {
                rhs[(i, j)] = v;
            }
        }
    }

    fn set_tolerance(&mut self, relative: f64) {
        self.tolerance = relative;
    }

    fn take_negative_curvature(&self) -> bool {
        self.negative_curvature.swap(false, Ordering::Relaxed)
    }
}

/// The linear solver a solve uses: direct or multigrid ([`crate::FemSolver::resolve`]).
pub(crate) enum LinearSolver {
    /// The sparse Cholesky.
    Direct(DirectSolver),
    /// Multigrid-preconditioned conjugate gradients.
    Multigrid(MultigridSolver),
}

impl LinearSolver {
    /// Conjugate-gradient iterations and solves so far (0, 0 for the direct solver).
    pub(crate) fn iterations(&self) -> (usize, usize) {
        match self {
            LinearSolver::Direct(_) => (0, 0),
            LinearSolver::Multigrid(m) => {
                (m.iterations.load(Ordering::Relaxed), m.solves.load(Ordering::Relaxed))
            }
        }
    }
}

impl ComplianceSource for LinearSolver {
    fn unknowns(&self) -> usize {
        match self {
            LinearSolver::Direct(d) => d.unknowns(),
            LinearSolver::Multigrid(m) => m.unknowns(),
        }
    }

    fn compliance_columns(&self, rows: &[&SparseRow]) -> fibfluid_linalg::Result<Vec<Vec<f64>>> {
        match self {
            LinearSolver::Direct(d) => d.compliance_columns(rows),
            LinearSolver::Multigrid(m) => m.compliance_columns(rows),
        }
    }
}

impl TangentSolver for LinearSolver {
    fn prepare(&mut self, tangent: &SparseColMat<usize, f64>) -> Result<f64> {
        match self {
            LinearSolver::Direct(d) => d.prepare(tangent),
            LinearSolver::Multigrid(m) => m.prepare(tangent),
        }
    }

    fn solve_in_place(&self, rhs: MatMut<'_, f64>) {
        match self {
            LinearSolver::Direct(d) => d.solve_in_place(rhs),
            LinearSolver::Multigrid(m) => m.solve_in_place(rhs),
        }
    }

    fn set_tolerance(&mut self, relative: f64) {
        if let LinearSolver::Multigrid(m) = self {
            m.set_tolerance(relative);
        }
    }

    fn take_negative_curvature(&self) -> bool {
        match self {
            LinearSolver::Direct(_) => false,
            LinearSolver::Multigrid(m) => m.take_negative_curvature(),
        }
    }
}
