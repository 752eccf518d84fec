//! A constraint set that changes on a kept factorization: prescribed unknowns by a
//! capacitance (Sherman–Morrison–Woodbury) correction instead of a refactorization.
//!
//! To impose k linear constraints `E' x = g` on `A x = b` (each column of `E` a sparse
//! row: a held unknown is a column of the identity, a contact the normal at a vertex), add
//! one multiplier per constraint, `A x + E r = b`. With `W = A^-1 E` (k solves with the
//! kept factorization) and the k x k capacitance `C = E' W`:
//!
//! ```text
//! y = A^-1 b,    C r = E' y - g,    x = y - W r
//! ```
//!
//! `-r` is the force each constraint applies along its row (its reaction). On the
//! bordered FFM system `C` is a block of the projected compliance
//! `K^-1 - K^-1 S (S' K^-1 S)^-1 S' K^-1`: symmetric positive definite unless the held
//! unknowns alone decide the volume, which is reported as an error.
//!
//! Cost, against refactoring with the unknowns eliminated:
//! - adding an unknown: one solve with the kept factorization (`4 d N^2` flops structured,
//!   `2 (dN+1)^2` dense) plus `k^3 / 3` for the new capacitance factor; removing one: the
//!   `k^3 / 3` refactor of `C` only;
//! - each solve afterwards: one solve plus `O(k dN)` for the correction;
//! - a refactorization instead costs `N^3 / 3` per stiffness block (structured) or
//!   `(2/3)(dN+1)^3` (dense LU), so the update wins while `k` is well below `N`.
//!
//! **Holding vertices is not done here** but by [`crate::HeldCapacitance`] over
//! [`crate::VertexResponse`] (`held.rs`), the one code path the interactive body and
//! `Simulation::respond_held` share. A held vertex is the special row `e_(c,v)` on every
//! axis, whose `W` column is fully described by one compliance column per distinct block
//! (N values) plus the shared `w` and `s`; this set keeps a dense `dN + 1` column per
//! constraint instead. What stays on it are the plate contacts: a contact row is not a hold
//! but a plate normal spread over a vertex's free axes (`n . u_v = g`), whose column could
//! be assembled from vertex columns (`W = sum_c n_c W_(c,v)`) but is not yet. Both are the
//! same Sherman–Morrison–Woodbury update and run the same code: [`crate::RowCapacitance`]
//! forms, factors and applies the capacitance through a [`crate::CapacitanceSource`],
//! here the dense columns of [`crate::ComplianceSource`] (as the finite-element holds do),
//! there [`crate::VertexSource`].

use crate::capacitance::{ComplianceSource, RowCapacitance, SparseRow};
use crate::{Factorization, FactorizationExt, LinalgError, Result};

/// Linear constraints on the unknowns, imposed on a kept factorization (see the module
/// docs). Each constraint has a key chosen by the caller.
#[derive(Clone, Debug, Default)]
pub struct PrescribedSet {
    keys: Vec<u64>,
    /// The constraint rows, sparse: (unknown, coefficient).
    rows: Vec<Vec<(usize, f64)>>,
    /// `W = A^-1 E`, one column per constraint.
    columns: Vec<Vec<f64>>,
    /// The factored capacitance `C = E' W`.
    capacitance: Option<RowCapacitance>,
}

/// A solve under a [`PrescribedSet`]: the solution and the multipliers.
#[derive(Clone, Debug, PartialEq)]
pub struct ConstrainedSolution {
    /// The solution, with the held unknowns at their values.
    pub x: Vec<f64>,
    /// Backward error of the solve with the kept factorization.
    pub relative_residual: f64,
    /// One multiplier per constraint, in the set's order: the constraint adds `-r` times
    /// its row to the right-hand side, so `-r` is its reaction along the row.
    pub multipliers: Vec<f64>,
}

impl PrescribedSet {
    /// No held unknown.
    pub fn new() -> Self {
        Self::default()
    }

    /// The constraint keys, in order.
    pub fn keys(&self) -> &[u64] {
        &self.keys
    }

    /// Number of constraints.
    pub fn len(&self) -> usize {
        self.keys.len()
    }

    /// Whether there is no constraint.
    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }

    /// Holds unknown `index` (the constraint `x[index] = value`, keyed by the index).
    pub fn add(&mut self, f: &dyn Factorization, index: usize) -> Result<()> {
        self.add_row(f, index as u64, &[(index, 1.0)])
    }

    /// Adds the constraint `row . x = value` under `key` (one solve with `f`); a key
    /// already present is left as it is.
    pub fn add_row(&mut self, f: &dyn Factorization, key: u64, row: &[(usize, f64)]) -> Result<()> {
        self.add_rows(f, &[(key, row.to_vec())])
    }

    /// Adds several constraints at once: their solves share one pass over the factor
    /// ([`solve_many`](FactorizationExt::solve_many)) and the capacitance is refactored
    /// once. Keys already present are left as they are.
    pub fn add_rows(&mut self, f: &dyn Factorization, rows: &[(u64, Vec<(usize, f64)>)]) -> Result<()> {
        let new: Vec<&(u64, Vec<(usize, f64)>)> =
            rows.iter().filter(|(k, _)| !self.keys.contains(k)).collect();
        if new.is_empty() {
            return Ok(());
        }
        let rows: Vec<&SparseRow> = new.iter().map(|(_, row)| row.as_slice()).collect();
        let solutions = f.compliance_columns(&rows)?;
        for ((key, row), w) in new.into_iter().zip(solutions) {
            self.keys.push(*key);
            self.rows.push(row.clone());
            self.columns.push(w);
        }
        self.refactor()
    }

    /// Releases unknown `index` (held by [`add`](Self::add)).
    pub fn remove(&mut self, index: usize) -> Result<()> {
        self.remove_key(index as u64)
    }

    /// Drops the constraint under `key` (a refactor of the small capacitance only).
    pub fn remove_key(&mut self, key: u64) -> Result<()> {
        if let Some(k) = self.keys.iter().position(|&i| i == key) {
            self.keys.remove(k);
            self.rows.remove(k);
            self.columns.remove(k);
            self.refactor()?;
        }
        Ok(())
    }

    fn refactor(&mut self) -> Result<()> {
        let k = self.keys.len();
        if k == 0 {
            self.capacitance = None;
            return Ok(());
        }
        let c = RowCapacitance::new(&self.rows, &self.columns, 0.0).map_err(|e| match e {
            LinalgError::CapacitanceNotPositiveDefinite { .. } => {
                LinalgError::DependentConstraints { held: k }
            }
            other => other,
        })?;
        self.capacitance = Some(c);
        Ok(())
    }

    /// Solves `A x = b` with each constraint's `row . x` at `values` (in the set's order).
    pub fn solve(&self, f: &dyn Factorization, b: &[f64], values: &[f64]) -> Result<ConstrainedSolution> {
        assert_eq!(values.len(), self.keys.len(), "one value per constraint");
        let first = f.solve(b)?;
        let relative_residual = first.relative_residual;
        let mut y = first.x;
        let Some(capacitance) = &self.capacitance else {
            return Ok(ConstrainedSolution { x: y, relative_residual, multipliers: vec![] });
        };
        let multipliers = capacitance.correct(&self.rows, &self.columns, values, &mut y);
        if let Some(i) = y.iter().position(|v| !v.is_finite()) {
            return Err(LinalgError::NonFiniteSolution { index: i });
        }
        Ok(ConstrainedSolution { x: y, relative_residual, multipliers })
    }
}
