//! The capacitance (Sherman–Morrison–Woodbury) update, once: holding some unknowns or
//! rows on a kept factorization instead of refactoring.
//!
//! To impose k linear constraints `E' x = g` on `A x = b` (each column of `E` a sparse
//! row), add one multiplier per constraint, `A x + E r = b`. With the compliance columns
//! `W = A^-1 E` (k solves with the kept factorization) and the k x k capacitance
//! `C = E' W` (symmetric positive definite for an SPD `A` and independent rows):
//!
//! ```text
//! y = A^-1 b,    C r = E' y - g,    x = y - W r
//! ```
//!
//! `-r` is the force each constraint applies along its row.
//!
//! The pieces, shared by every user (the bordered system's contact rows,
//! `crate::PrescribedSet`; its vertex holds, `crate::HeldCapacitance`; the finite-element
//! holds of `fibfluid-fem`):
//!
//! - [`ComplianceSource`]: where the columns `W` come from (a dense or structured
//!   factorization of the bordered system, a sparse Cholesky factor);
//! - [`CapacitanceFactor`]: the Cholesky factor of a k x k capacitance and its solves, the
//!   one small dense factor-and-solve; a pivot that is not positive is
//!   [`LinalgError::CapacitanceNotPositiveDefinite`] naming the constraint;
//! - [`RowCapacitance`]: `C = E' W` formed from sparse rows and their columns, factored,
//!   and the correction `x = y - W r`.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{LltError, cholesky_in_place, cholesky_in_place_scratch};
use faer::linalg::cholesky::llt::solve::{solve_in_place, solve_in_place_scratch};
use faer::{Mat, MatRef, Par};

use crate::{Factorization, FactorizationExt, LinalgError, Result, SparseCholesky};

/// One constraint row of `E'`, sparse: `(unknown, coefficient)` pairs (a repeated unknown
/// adds up).
pub type SparseRow = [(usize, f64)];

/// `row . x`.
pub fn row_dot(row: &SparseRow, x: &[f64]) -> f64 {
    row.iter().map(|&(i, c)| c * x[i]).sum()
}

/// A kept factorization that gives the compliance columns `W = A^-1 E` of sparse rows.
pub trait ComplianceSource {
    /// Number of unknowns of `A`.
    fn unknowns(&self) -> usize;

    /// `A^-1 e` for each row `e` of `rows`, one dense column of [`unknowns`](Self::unknowns)
    /// values each, all in one pass over the factor.
    ///
    /// # Panics
    /// If a row names an unknown out of range (a programming error).
    fn compliance_columns(&self, rows: &[&SparseRow]) -> Result<Vec<Vec<f64>>>;
}

/// The right-hand sides `E`, column after column.
#[track_caller]
fn dense_rows(dim: usize, rows: &[&SparseRow]) -> Vec<f64> {
    let mut e = vec![0.0; dim * rows.len()];
    for (j, row) in rows.iter().enumerate() {
        for &(i, c) in row.iter() {
            assert!(i < dim, "unknown {i} of a {dim}-unknown system");
            e[j * dim + i] += c;
        }
    }
    e
}

/// The bordered system's factorizations (dense or structured): checked, refined solves
/// ([`FactorizationExt::solve_many`]).
impl ComplianceSource for dyn Factorization + '_ {
    fn unknowns(&self) -> usize {
        self.matrix().dim()
    }

    fn compliance_columns(&self, rows: &[&SparseRow]) -> Result<Vec<Vec<f64>>> {
        let e = dense_rows(self.unknowns(), rows);
        Ok(self.solve_many(&e, rows.len())?.into_iter().map(|s| s.x).collect())
    }
}

/// A sparse Cholesky factor: one multi-column solve.
impl ComplianceSource for SparseCholesky {
    fn unknowns(&self) -> usize {
        self.symbolic().dim()
    }

    fn compliance_columns(&self, rows: &[&SparseRow]) -> Result<Vec<Vec<f64>>> {
        let dim = self.unknowns();
        let e = dense_rows(dim, rows);
        let mut x = Mat::<f64>::from_fn(dim, rows.len(), |i, j| e[j * dim + i]);
        self.solve_in_place(x.as_mut());
        Ok((0..rows.len()).map(|j| x.col_as_slice(j).to_vec()).collect())
    }
}

/// The Cholesky factor of a k x k capacitance matrix (see the module docs).
#[derive(Clone, Debug)]
pub struct CapacitanceFactor {
    /// Lower Cholesky factor (k square; the strict upper triangle is scratch).
    l: Mat<f64>,
}

impl CapacitanceFactor {
    /// Factors the symmetric `c` (its lower triangle is read). A non-positive pivot, or
    /// with `pivot_tolerance = Some(tol)` a pivot `l_ii` with `l_ii^2 <= tol |c_ii|`, is
    /// [`LinalgError::CapacitanceNotPositiveDefinite`] naming the constraint (its row).
    ///
    /// # Panics
    /// If `c` is not square.
    #[track_caller]
    pub fn new(c: MatRef<'_, f64>, pivot_tolerance: Option<f64>) -> Result<Self> {
        let k = c.nrows();
        assert_eq!(c.ncols(), k, "a square capacitance");
        let refuse =
            |constraint: usize| LinalgError::CapacitanceNotPositiveDefinite { constraint, constraints: k };
        let mut l = c.to_owned();
        let mut mem = MemBuffer::new(cholesky_in_place_scratch::<f64>(k, Par::Seq, Default::default()));
        cholesky_in_place(
            l.as_mut(),
            Default::default(),
            Par::Seq,
            MemStack::new(&mut mem),
            Default::default(),
        )
        .map_err(|LltError::NonPositivePivot { index }| refuse(index))?;
        if let Some(tol) = pivot_tolerance {
            for i in 0..k {
                let lii = l[(i, i)];
                if !(lii * lii > tol * c[(i, i)].abs()) {
                    return Err(refuse(i));
                }
            }
        }
        Ok(Self { l })
    }

    /// Number of constraints k.
    pub fn len(&self) -> usize {
        self.l.nrows()
    }

    /// Whether there is no constraint.
    pub fn is_empty(&self) -> bool {
        self.l.nrows() == 0
    }

    /// Bytes of the factor.
    pub fn memory_bytes(&self) -> usize {
        self.l.nrows() * self.l.ncols() * 8
    }

    /// Solves `C r = rhs`.
    ///
    /// # Panics
    /// If `rhs` does not have k entries.
    #[track_caller]
    pub fn solve(&self, rhs: &[f64]) -> Vec<f64> {
        let k = self.len();
        assert_eq!(rhs.len(), k, "one right-hand side entry per constraint");
        let mut x = Mat::<f64>::from_fn(k, 1, |i, _| rhs[i]);
        let mut mem = MemBuffer::new(solve_in_place_scratch::<f64>(k, 1, Par::Seq));
        solve_in_place(self.l.as_ref(), x.as_mut(), Par::Seq, MemStack::new(&mut mem));
        x.col_as_slice(0).to_vec()
    }
}

/// The capacitance `C = E' W` of sparse rows and their compliance columns, factored (see
/// the module docs). The rows and columns stay with the caller and are passed again to
/// [`correct`](Self::correct).
#[derive(Clone, Debug)]
pub struct RowCapacitance {
    /// `C` itself (without any ridge).
    matrix: Mat<f64>,
    factor: CapacitanceFactor,
}

impl RowCapacitance {
    /// Forms `C[i, j] = (row_i . W_j + row_j . W_i) / 2` (symmetric to rounding) and
    /// factors `C + ridge * max_i C_ii * I` (`ridge = 0`: `C` itself). Errors as
    /// [`CapacitanceFactor::new`] without a pivot tolerance.
    ///
    /// # Panics
    /// If there are not as many columns as rows.
    #[track_caller]
    pub fn new<R: AsRef<SparseRow>, W: AsRef<[f64]>>(rows: &[R], columns: &[W], ridge: f64) -> Result<Self> {
        let k = rows.len();
        assert_eq!(columns.len(), k, "one compliance column per row");
        let entry = |i: usize, j: usize| row_dot(rows[i].as_ref(), columns[j].as_ref());
        let matrix = Mat::from_fn(k, k, |i, j| 0.5 * (entry(i, j) + entry(j, i)));
        let shift = ridge * (0..k).map(|i| matrix[(i, i)]).fold(0.0, f64::max);
        let factor = if shift == 0.0 {
            CapacitanceFactor::new(matrix.as_ref(), None)?
        } else {
            let shifted = Mat::from_fn(k, k, |i, j| matrix[(i, j)] + if i == j { shift } else { 0.0 });
            CapacitanceFactor::new(shifted.as_ref(), None)?
        };
        Ok(Self { matrix, factor })
    }

    /// `C` (without the ridge).
    pub fn matrix(&self) -> MatRef<'_, f64> {
        self.matrix.as_ref()
    }

    /// The factor.
    pub fn factor(&self) -> &CapacitanceFactor {
        &self.factor
    }

    /// Imposes `row_i . x = values[i]` on `y = A^-1 b` in place: solves
    /// `C r = E' y - values` and sets `y -= W r`. Returns the multipliers `r`.
    ///
    /// # Panics
    /// If the rows, columns and values do not match the factored capacitance, or a column
    /// does not have `y`'s length.
    #[track_caller]
    pub fn correct<R: AsRef<SparseRow>, W: AsRef<[f64]>>(
        &self,
        rows: &[R],
        columns: &[W],
        values: &[f64],
        y: &mut [f64],
    ) -> Vec<f64> {
        let k = self.factor.len();
        assert!(
            rows.len() == k && columns.len() == k && values.len() == k,
            "one row, column and value per constraint"
        );
        let gap: Vec<f64> = (0..k).map(|i| row_dot(rows[i].as_ref(), y) - values[i]).collect();
        let r = self.factor.solve(&gap);
        for (w, &ri) in columns.iter().zip(&r) {
            let w = w.as_ref();
            assert_eq!(w.len(), y.len(), "a column per unknown");
            for (yi, wi) in y.iter_mut().zip(w) {
                *yi -= wi * ri;
            }
        }
        r
    }
}
