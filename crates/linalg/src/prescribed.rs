//! A constraint set that changes on a kept factorization: prescribed unknowns by a
//! capacitance (Sherman–Morrison–Woodbury) correction instead of a refactorization.
//!
//! To hold unknowns `P = {p_1 .. p_k}` of `A x = b` at values `g`, add one multiplier per
//! held unknown, `A x + E r = b`, `E' x = g`, where `E` holds the columns of the identity
//! at `P`. With `W = A^-1 E` (k solves with the kept factorization) and the k x k
//! capacitance `C = E' W`:
//!
//! ```text
//! y = A^-1 b,    C r = E' y - g,    x = y - W r
//! ```
//!
//! `-r` is the force the constraint applies to hold each unknown (its reaction). On the
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

use faer::linalg::solvers::Solve;
use faer::{Mat, Side};

use crate::{Factorization, FactorizationExt, LinalgError, Result};

/// Unknowns held at prescribed values on a kept factorization (see the module docs).
#[derive(Clone, Debug, Default)]
pub struct PrescribedSet {
    indices: Vec<usize>,
    /// `W = A^-1 E`, one column per held unknown.
    columns: Vec<Vec<f64>>,
    /// Cholesky factor of the capacitance `C = E' W`.
    capacitance: Option<faer::linalg::solvers::Llt<f64>>,
}

/// A solve under a [`PrescribedSet`]: the solution and the multipliers.
#[derive(Clone, Debug, PartialEq)]
pub struct ConstrainedSolution {
    /// The solution, with the held unknowns at their values.
    pub x: Vec<f64>,
    /// One multiplier per held unknown, in the set's order: the constraint adds `-r` to
    /// the right-hand side row of that unknown, so `-r` is its reaction force.
    pub multipliers: Vec<f64>,
}

impl PrescribedSet {
    /// No held unknown.
    pub fn new() -> Self {
        Self::default()
    }

    /// The held unknowns, in order.
    pub fn indices(&self) -> &[usize] {
        &self.indices
    }

    /// Number of held unknowns.
    pub fn len(&self) -> usize {
        self.indices.len()
    }

    /// Whether nothing is held.
    pub fn is_empty(&self) -> bool {
        self.indices.is_empty()
    }

    /// Holds unknown `index` (one solve with `f`); holding it twice is a no-op.
    pub fn add(&mut self, f: &dyn Factorization, index: usize) -> Result<()> {
        if self.indices.contains(&index) {
            return Ok(());
        }
        let dim = f.matrix().dim();
        assert!(index < dim, "unknown {index} of a {dim}-unknown system");
        let mut e = vec![0.0; dim];
        e[index] = 1.0;
        let w = f.solve(&e)?.x;
        self.indices.push(index);
        self.columns.push(w);
        self.refactor()
    }

    /// Releases unknown `index` (a refactor of the small capacitance only).
    pub fn remove(&mut self, index: usize) -> Result<()> {
        if let Some(k) = self.indices.iter().position(|&i| i == index) {
            self.indices.remove(k);
            self.columns.remove(k);
            self.refactor()?;
        }
        Ok(())
    }

    fn refactor(&mut self) -> Result<()> {
        let k = self.indices.len();
        if k == 0 {
            self.capacitance = None;
            return Ok(());
        }
        let c = Mat::from_fn(k, k, |i, j| {
            0.5 * (self.columns[j][self.indices[i]] + self.columns[i][self.indices[j]])
        });
        let llt = c.llt(Side::Lower).map_err(|_| LinalgError::DependentConstraints { held: k })?;
        self.capacitance = Some(llt);
        Ok(())
    }

    /// Solves `A x = b` with the held unknowns at `values` (in the set's order).
    pub fn solve(&self, f: &dyn Factorization, b: &[f64], values: &[f64]) -> Result<ConstrainedSolution> {
        assert_eq!(values.len(), self.indices.len(), "one value per held unknown");
        let mut y = f.solve(b)?.x;
        let Some(llt) = &self.capacitance else {
            return Ok(ConstrainedSolution { x: y, multipliers: vec![] });
        };
        let k = self.indices.len();
        let rhs = Mat::from_fn(k, 1, |i, _| y[self.indices[i]] - values[i]);
        let r = llt.solve(&rhs);
        let multipliers: Vec<f64> = (0..k).map(|i| r[(i, 0)]).collect();
        for (w, &ri) in self.columns.iter().zip(&multipliers) {
            for (yi, wi) in y.iter_mut().zip(w) {
                *yi -= wi * ri;
            }
        }
        // The held unknowns are exact up to rounding; set them to their values.
        for (&i, &v) in self.indices.iter().zip(values) {
            y[i] = v;
        }
        if let Some(i) = y.iter().position(|v| !v.is_finite()) {
            return Err(LinalgError::NonFiniteSolution { index: i });
        }
        Ok(ConstrainedSolution { x: y, multipliers })
    }
}
