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
//! - [`CapacitanceSource`]: how `C = E' W` is formed, `E' x` read and `x -= W r` applied
//!   for rows of the source's own type, in whatever compact form it keeps `W`. Two
//!   implementations: dense compliance columns (`[W]`, one column of every unknown per
//!   sparse row, [`SparseRow`]), and the vertex holds of the bordered system
//!   (`crate::VertexSource` over a `crate::VertexResponse`: one N-length compliance column
//!   per distinct block and held vertex plus the shared `w` and `s`, so a hold costs N
//!   values per block instead of a `dN + 1` column, and the correction is a point-force
//!   field);
//! - [`ComplianceSource`]: where dense columns `W` come from (a dense or structured
//!   factorization of the bordered system, a sparse Cholesky factor);
//! - [`CapacitanceFactor`]: the Cholesky factor of a k x k capacitance and its solves, the
//!   one small dense factor-and-solve; a pivot that is not positive (or below an optional
//!   tolerance) is [`LinalgError::CapacitanceNotPositiveDefinite`] naming the constraint,
//!   which each user maps to its own error (`DependentConstraints`, `SingularHold`,
//!   `DependentHolds`);
//! - [`RowCapacitance`]: `C` formed from a source ([`RowCapacitance::from_source`], with
//!   an optional ridge and pivot tolerance), factored, the multipliers
//!   ([`RowCapacitance::multipliers`]) and the correction `x = y - W r`
//!   ([`RowCapacitance::correct_with`]): the one code path of every user.

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

/// Where a capacitance update reads `C = E' W` and applies `x -= W r` for constraint rows
/// of type `Row`, in whatever form the source keeps `W` (see the module docs).
///
/// Dense compliance columns (`[W]` for `W: AsRef<[f64]>`, one column of every unknown per
/// row) implement it for sparse rows; the vertex holds of the bordered system
/// (`crate::VertexSource`) from one N-length compliance column per distinct block and the
/// shared `w` and `s`, without forming the `dN + 1` columns.
pub trait CapacitanceSource<Row> {
    /// `C = E' W` of `rows` (k x k, symmetric).
    fn capacitance(&self, rows: &[Row]) -> Mat<f64>;

    /// `E' x`: each row applied to the unknowns `x`.
    fn row_values(&self, rows: &[Row], x: &[f64]) -> Vec<f64>;

    /// `x -= W r` (one multiplier per row).
    fn correct(&self, rows: &[Row], r: &[f64], x: &mut [f64]);
}

/// Dense compliance columns, one per sparse row: `C[i, j] = (row_i . W_j + row_j . W_i) / 2`
/// (symmetric to rounding) and `x -= W r` column after column.
impl<R: AsRef<SparseRow>, W: AsRef<[f64]>> CapacitanceSource<R> for [W] {
    #[track_caller]
    fn capacitance(&self, rows: &[R]) -> Mat<f64> {
        let k = rows.len();
        assert_eq!(self.len(), k, "one compliance column per row");
        let entry = |i: usize, j: usize| row_dot(rows[i].as_ref(), self[j].as_ref());
        Mat::from_fn(k, k, |i, j| 0.5 * (entry(i, j) + entry(j, i)))
    }

    fn row_values(&self, rows: &[R], x: &[f64]) -> Vec<f64> {
        rows.iter().map(|row| row_dot(row.as_ref(), x)).collect()
    }

    #[track_caller]
    fn correct(&self, rows: &[R], r: &[f64], x: &mut [f64]) {
        assert!(
            rows.len() == self.len() && r.len() == self.len(),
            "one row, column and multiplier per constraint"
        );
        for (w, &ri) in self.iter().zip(r) {
            let w = w.as_ref();
            assert_eq!(w.len(), x.len(), "a column per unknown");
            for (xi, wi) in x.iter_mut().zip(w) {
                *xi -= wi * ri;
            }
        }
    }
}

/// The factored capacitance `C = E' W` of a set of constraint rows (see the module docs),
/// read from any [`CapacitanceSource`]. The rows and the source stay with the caller and
/// are passed again to [`correct`](Self::correct) /
/// [`correct_with`](Self::correct_with).
#[derive(Clone, Debug)]
pub struct RowCapacitance {
    /// `C` itself (without any ridge).
    matrix: Mat<f64>,
    factor: CapacitanceFactor,
}

impl RowCapacitance {
    /// Forms `C[i, j] = (row_i . W_j + row_j . W_i) / 2` (symmetric to rounding) from sparse
    /// rows and their dense compliance columns and factors `C + ridge * max_i C_ii * I`
    /// (`ridge = 0`: `C` itself). Errors as [`CapacitanceFactor::new`] without a pivot
    /// tolerance.
    ///
    /// # Panics
    /// If there are not as many columns as rows.
    #[track_caller]
    pub fn new<R: AsRef<SparseRow>, W: AsRef<[f64]>>(rows: &[R], columns: &[W], ridge: f64) -> Result<Self> {
        Self::from_source(columns, rows, ridge, None)
    }

    /// Forms `C` of `rows` with `source` and factors `C + ridge * max_i C_ii * I`, with the
    /// pivot tolerance of [`CapacitanceFactor::new`]; errors as it does.
    pub fn from_source<Row, S: CapacitanceSource<Row> + ?Sized>(
        source: &S,
        rows: &[Row],
        ridge: f64,
        pivot_tolerance: Option<f64>,
    ) -> Result<Self> {
        let matrix = source.capacitance(rows);
        let k = matrix.nrows();
        let shift = ridge * (0..k).map(|i| matrix[(i, i)]).fold(0.0, f64::max);
        let factor = if shift == 0.0 {
            CapacitanceFactor::new(matrix.as_ref(), pivot_tolerance)?
        } else {
            let shifted = Mat::from_fn(k, k, |i, j| matrix[(i, j)] + if i == j { shift } else { 0.0 });
            CapacitanceFactor::new(shifted.as_ref(), pivot_tolerance)?
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

    /// The multipliers `r` of `C r = gap` (`gap = E' y - g`, one entry per constraint).
    ///
    /// # Panics
    /// If `gap` does not have one entry per constraint.
    #[track_caller]
    pub fn multipliers(&self, gap: &[f64]) -> Vec<f64> {
        self.factor.solve(gap)
    }

    /// [`multipliers`](Self::multipliers) refined `refinements` times against `C`
    /// itself: `r += (C + ridge)^-1 (gap - C r)`. A ridged factor of a singular `C`
    /// (dependent rows) leaves a fraction `ridge / mu` of a consistent gap along each
    /// eigenvalue `mu` of `C`; each refinement multiplies it by that fraction again. An
    /// inconsistent gap is not met by any number (the caller checks the rows).
    ///
    /// # Panics
    /// As [`multipliers`](Self::multipliers).
    #[track_caller]
    pub fn refined_multipliers(&self, gap: &[f64], refinements: usize) -> Vec<f64> {
        let mut r = self.factor.solve(gap);
        for _ in 0..refinements {
            let mut residual = Mat::<f64>::from_fn(gap.len(), 1, |i, _| gap[i]);
            let current = Mat::<f64>::from_fn(r.len(), 1, |i, _| r[i]);
            faer::linalg::matmul::matmul(
                residual.as_mut(),
                faer::Accum::Add,
                self.matrix.as_ref(),
                current.as_ref(),
                -1.0,
                Par::Seq,
            );
            let correction = self.factor.solve(residual.col_as_slice(0));
            r.iter_mut().zip(&correction).for_each(|(a, b)| *a += b);
        }
        r
    }

    /// Imposes `row_i . x = values[i]` on `y = A^-1 b` in place with dense compliance
    /// columns: [`correct_with`](Self::correct_with) the columns as the source.
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
        assert_eq!(columns.len(), self.factor.len(), "one row, column and value per constraint");
        self.correct_with(columns, rows, values, y)
    }

    /// Imposes `row_i . x = values[i]` on `y = A^-1 b` in place: solves
    /// `C r = E' y - values` and sets `y -= W r`, both through `source`. Returns the
    /// multipliers `r`.
    ///
    /// # Panics
    /// If the rows and values do not match the factored capacitance, or the source refuses
    /// `y` (a length that is not its unknowns').
    #[track_caller]
    pub fn correct_with<Row, S: CapacitanceSource<Row> + ?Sized>(
        &self,
        source: &S,
        rows: &[Row],
        values: &[f64],
        y: &mut [f64],
    ) -> Vec<f64> {
        let k = self.factor.len();
        assert!(rows.len() == k && values.len() == k, "one row, column and value per constraint");
        let gap: Vec<f64> = source.row_values(rows, y).iter().zip(values).map(|(e, v)| e - v).collect();
        let r = self.factor.solve(&gap);
        source.correct(rows, &r, y);
        r
    }
}
