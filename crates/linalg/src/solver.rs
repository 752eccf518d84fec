//! The solver traits and what a factorization reports.

use std::fmt::Debug;

use crate::{BorderedMatrix, LinalgError, Result};

/// Working precision of a factorization.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Precision {
    /// Factor and solve in f64.
    #[default]
    F64,
    /// Factor in f32, then refine the f64 solution with f64 residuals (iterative refinement).
    Mixed,
}

impl crate::Choice for Precision {
    const WHAT: &'static str = "precision";
    const ALL: &'static [Self] = &[Precision::F64, Precision::Mixed];
    fn name(self) -> &'static str {
        match self {
            Precision::F64 => "f64",
            Precision::Mixed => "mixed",
        }
    }
}
crate::impl_choice!(Precision);

/// Options of a factorization and of the solves made with it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FactorOptions {
    /// Working precision of the factorization.
    pub precision: Precision,
    /// At most this many refinement steps per solve (f64 factorizations rarely need any).
    pub max_refinement_steps: usize,
    /// A solve is accepted when its componentwise backward error
    /// `max_i |b - A x|_i / (|A| |x| + |b|)_i` is at most this, or at most
    /// `target_residual_per_unknown` times the system's size when that is larger
    /// ([`target_for`](Self::target_for)).
    pub target_residual: f64,
    /// The accepted backward error per unknown of the system: a backward-stable
    /// factorization guarantees a componentwise backward error of order `dim * eps` (its
    /// rounding accumulates along each row), so a fixed target below that would buy a
    /// refinement step at every large solve for digits no model has. 0 keeps only
    /// `target_residual`.
    pub target_residual_per_unknown: f64,
    /// A solve whose backward error stays above this after refinement is an error.
    pub max_residual: f64,
}

impl Default for FactorOptions {
    fn default() -> Self {
        Self {
            precision: Precision::F64,
            max_refinement_steps: 10,
            target_residual: DEFAULT_TARGET_RESIDUAL,
            target_residual_per_unknown: TARGET_RESIDUAL_PER_UNKNOWN,
            max_residual: DEFAULT_MAX_RESIDUAL,
        }
    }
}

impl FactorOptions {
    /// The backward error a solve of a system of `dim` unknowns refines towards: the larger
    /// of `target_residual` and `target_residual_per_unknown * dim`.
    pub fn target_for(&self, dim: usize) -> f64 {
        self.target_residual.max(self.target_residual_per_unknown * dim as f64)
    }
}

/// Default relative residual a solve refines towards: a few hundred f64 ulps (the floor;
/// see [`TARGET_RESIDUAL_PER_UNKNOWN`]).
pub const DEFAULT_TARGET_RESIDUAL: f64 = 256.0 * f64::EPSILON;
/// Default accepted backward error per unknown: one f64 ulp (at N = 10,242 vertices,
/// 30,727 unknowns, 6.8e-12; one Cholesky solve there reaches 5e-13).
pub const TARGET_RESIDUAL_PER_UNKNOWN: f64 = f64::EPSILON;
/// Default relative residual above which a solve is reported as failed.
pub const DEFAULT_MAX_RESIDUAL: f64 = 1e-8;

/// What a factorization cost.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FactorCost {
    /// Floating point operations of the factorization (model count).
    pub flops: f64,
    /// Wall-clock seconds of the factorization.
    pub seconds: f64,
    /// Bytes held by the factorization.
    pub bytes: usize,
}

/// A linear backend: factorizes a bordered system once.
pub trait LinearSolver: Send + Sync + Debug {
    /// Which backend this is.
    fn backend(&self) -> crate::Backend;
    /// The backend's run-time name (`faer-lu`, `nalgebra-lu`, `openblas-lu`, `structured`).
    fn name(&self) -> &'static str {
        crate::Choice::name(self.backend())
    }
    /// Whether this backend can factor in the given precision.
    fn supports(&self, precision: Precision) -> bool;
    /// Factorizes `a`. Singular or non-finite input is an error naming the pivot or entry.
    fn factorize(&self, a: &BorderedMatrix, opts: &FactorOptions) -> Result<Box<dyn Factorization>>;
    /// Factorizes `a` as [`factorize`](Self::factorize) does, and may keep the factor in
    /// `a`'s own storage when nothing else shares it: the structured backend in f64 writes
    /// each block's Cholesky factor over the block's lower triangle, so the system and its
    /// factorization take one N x N buffer per block instead of two. `a` stays the same
    /// matrix for every reader (see [`BorderedMatrix`]). The default factors a copy.
    fn factorize_in_place(
        &self,
        a: &mut BorderedMatrix,
        opts: &FactorOptions,
    ) -> Result<Box<dyn Factorization>> {
        self.factorize(a, opts)
    }
}

/// A factorized system that solves many right-hand sides.
pub trait Factorization: Send + Sync {
    /// The backend that made it.
    fn backend(&self) -> &'static str;
    /// The matrix it factors (used for residuals and refinement).
    fn matrix(&self) -> &BorderedMatrix;
    /// The options it was made with.
    fn options(&self) -> &FactorOptions;
    /// What the factorization cost.
    fn cost(&self) -> FactorCost;
    /// One solve in the factorization's own precision, in place, without refinement.
    fn solve_unrefined(&self, rhs: &mut [f64]);
    /// Solves `count` right-hand sides stored one after another in `rhs` (each `dim()` long,
    /// the layout of one [`solve_unrefined`](Self::solve_unrefined) call), in place,
    /// without refinement. A backend that can read its factor once for all of them
    /// overrides this: the structured backend solves the N x (d * count) block of every
    /// axis and right-hand side in one pass over a shared Cholesky factor (each triangular
    /// solve is bound by reading the factor, so k right-hand sides cost about one). The
    /// default solves them one by one.
    ///
    /// # Panics
    /// If `rhs.len() != count * dim()` (a programming error).
    #[track_caller]
    fn solve_many_unrefined(&self, rhs: &mut [f64], count: usize) {
        let dim = self.matrix().dim();
        assert_eq!(rhs.len(), count * dim, "solve_many: rhs length");
        for r in rhs.chunks_exact_mut(dim) {
            self.solve_unrefined(r);
        }
    }
    /// Whether [`set_border`](Self::set_border) refactors the whole matrix (dense backends)
    /// rather than updating a Schur complement.
    fn border_update_refactors(&self) -> bool {
        false
    }
    /// Replaces the border (a new *physical* `S`) and updates the factorization.
    /// The structured backend only redoes triangular solves; dense backends refactor.
    /// Returns what the update cost.
    fn set_border(&mut self, border: &[Vec<f64>]) -> Result<FactorCost>;
}

/// One solve's result.
#[derive(Clone, Debug, PartialEq)]
pub struct Solution {
    /// The solution vector (last entry: the scaled pressure unknown).
    pub x: Vec<f64>,
    /// The final componentwise backward error `max_i |b - A x|_i / (|A| |x| + |b|)_i`.
    pub relative_residual: f64,
    /// Refinement steps taken.
    pub refinement_steps: usize,
}

/// Conveniences for every [`Factorization`]: checked solves with refinement, and a
/// condition estimate.
pub trait FactorizationExt: Factorization {
    /// Solves `A x = b`, refining until the residual reaches the target, and returns an
    /// error if it stays above [`FactorOptions::max_residual`] or anything is not finite.
    fn solve(&self, b: &[f64]) -> Result<Solution> {
        crate::parallel::on_cores(|| checked_solve(self, b))
    }

    /// Solves `count` right-hand sides stored one after another in `b` (each `dim()` long)
    /// as [`solve`](Self::solve) does each of them (same refinement, same checks), with
    /// every solve and refinement round made by one
    /// [`solve_many_unrefined`](Factorization::solve_many_unrefined) call, and every
    /// residual check by one [`residual_many`](BorderedMatrix::residual_many) pass, over
    /// the right-hand sides that still need it.
    ///
    /// # Panics
    /// If `b.len() != count * dim()` (a programming error).
    #[track_caller]
    fn solve_many(&self, b: &[f64], count: usize) -> Result<Vec<Solution>> {
        crate::parallel::on_cores(|| checked_solve_many(self, b, count))
    }

    /// Estimates the reciprocal condition number in the 1-norm (Hager–Higham estimator,
    /// a handful of solves; the matrix is symmetric so no transposed solve is needed).
    fn rcond_estimate(&self) -> f64 {
        let a = self.matrix();
        let n = a.dim();
        let norm_a = a.norm_inf();
        let mut x = vec![1.0 / n as f64; n];
        let mut est = 0.0f64;
        let mut last_j = usize::MAX;
        for _ in 0..5 {
            let mut y = x.clone();
            self.solve_unrefined(&mut y);
            est = est.max(y.iter().map(|v| v.abs()).sum());
            let mut z: Vec<f64> = y.iter().map(|v| if *v >= 0.0 { 1.0 } else { -1.0 }).collect();
            self.solve_unrefined(&mut z);
            let (j, zmax) = z
                .iter()
                .enumerate()
                .fold((0, 0.0f64), |(bj, bm), (i, v)| if v.abs() > bm { (i, v.abs()) } else { (bj, bm) });
            let ztx: f64 = z.iter().zip(&x).map(|(a, b)| a * b).sum();
            if zmax <= ztx || j == last_j {
                break;
            }
            last_j = j;
            x.iter_mut().for_each(|v| *v = 0.0);
            x[j] = 1.0;
        }
        // Higham's extra test vector guards against the estimator's known blind spots.
        let mut alt: Vec<f64> = (0..n)
            .map(|i| {
                let s = if i % 2 == 0 { 1.0 } else { -1.0 };
                s * (1.0 + i as f64 / (n.max(2) - 1) as f64)
            })
            .collect();
        self.solve_unrefined(&mut alt);
        let alt_est = 2.0 * alt.iter().map(|v| v.abs()).sum::<f64>() / (3.0 * n as f64);
        let inv_norm = est.max(alt_est);
        if inv_norm == 0.0 || norm_a == 0.0 || !inv_norm.is_finite() {
            0.0
        } else {
            1.0 / (norm_a * inv_norm)
        }
    }
}

impl<F: Factorization + ?Sized> FactorizationExt for F {}

/// Conveniences for every [`LinearSolver`].
pub trait LinearSolverExt: LinearSolver {
    /// Factorizes with default options (f64).
    fn factorize_default(&self, a: &BorderedMatrix) -> Result<Box<dyn Factorization>> {
        self.factorize(a, &FactorOptions::default())
    }
}

impl<S: LinearSolver + ?Sized> LinearSolverExt for S {}

/// The Oettli–Prager componentwise backward error `max_i |r_i| / (|A| |x| + |b|)_i`: the
/// smallest relative perturbation of each entry of A and b that makes x exact. Unlike the
/// normwise measure it is not hidden by a few huge entries (the 1e9 penalty).
pub fn componentwise_backward_error(r: &[f64], abs_ax: &[f64], b: &[f64]) -> f64 {
    r.iter().zip(abs_ax).zip(b).fold(0.0f64, |m, ((ri, di), bi)| {
        let den = di + bi.abs();
        let e = if den > 0.0 {
            ri.abs() / den
        } else if *ri == 0.0 {
            0.0
        } else {
            f64::INFINITY
        };
        m.max(e)
    })
}

/// Pivot threshold: a pivot at most this times `n eps` times its column's largest entry is
/// treated as zero.
pub(crate) const PIVOT_TOLERANCE_FACTOR: f64 = 1.0;

/// Checks LU or Cholesky pivots against their column scale; returns the first bad index.
pub(crate) fn check_pivots(a: &BorderedMatrix, pivots: impl Iterator<Item = (usize, f64)>) -> Result<()> {
    let n = a.dim() as f64;
    for (i, p) in pivots {
        if !p.is_finite() {
            return Err(LinalgError::SingularPivot { index: i, pivot: p });
        }
        let scale = a.column_max(i);
        if p.abs() <= PIVOT_TOLERANCE_FACTOR * n * f64::EPSILON * scale || p == 0.0 {
            return Err(LinalgError::SingularPivot { index: i, pivot: p });
        }
    }
    Ok(())
}

/// [`FactorizationExt::solve`], run by [`on_cores`](crate::parallel::on_cores).
fn checked_solve<F: Factorization + ?Sized>(f: &F, b: &[f64]) -> Result<Solution> {
    let a = f.matrix();
    let dim = a.dim();
    assert_eq!(b.len(), dim, "rhs length");
    if let Some(i) = b.iter().position(|v| !v.is_finite()) {
        return Err(LinalgError::NonFiniteRhs { index: i });
    }
    let opts = *f.options();
    let mut x = b.to_vec();
    f.solve_unrefined(&mut x);
    let mut r = vec![0.0; dim];
    let mut denom = vec![0.0; dim];
    let mut steps = 0;
    let mut rel;
    loop {
        if let Some(i) = x.iter().position(|v| !v.is_finite()) {
            return Err(LinalgError::NonFiniteSolution { index: i });
        }
        a.residual(&x, b, &mut r, &mut denom);
        rel = componentwise_backward_error(&r, &denom, b);
        if rel <= opts.target_for(dim) || steps >= opts.max_refinement_steps {
            break;
        }
        f.solve_unrefined(&mut r);
        for (xi, di) in x.iter_mut().zip(&r) {
            *xi += di;
        }
        steps += 1;
    }
    if !(rel <= opts.max_residual) {
        return Err(LinalgError::ResidualTooLarge { residual: rel, limit: opts.max_residual });
    }
    Ok(Solution { x, relative_residual: rel, refinement_steps: steps })
}

/// [`FactorizationExt::solve_many`], run by [`on_cores`](crate::parallel::on_cores).
fn checked_solve_many<F: Factorization + ?Sized>(f: &F, b: &[f64], count: usize) -> Result<Vec<Solution>> {
    let a = f.matrix();
    let dim = a.dim();
    assert_eq!(b.len(), count * dim, "solve_many: rhs length");
    if let Some(i) = b.iter().position(|v| !v.is_finite()) {
        return Err(LinalgError::NonFiniteRhs { index: i % dim });
    }
    let opts = *f.options();
    let mut x = b.to_vec();
    f.solve_many_unrefined(&mut x, count);
    let mut rel = vec![f64::INFINITY; count];
    let mut steps = vec![0usize; count];
    let mut active: Vec<usize> = (0..count).collect();
    loop {
        // Residuals of every active right-hand side in one pass over the blocks.
        let mut xs = Vec::with_capacity(active.len() * dim);
        for &k in &active {
            let xk = &x[k * dim..(k + 1) * dim];
            if let Some(i) = xk.iter().position(|v| !v.is_finite()) {
                return Err(LinalgError::NonFiniteSolution { index: i });
            }
            xs.extend_from_slice(xk);
        }
        let bs: Vec<f64> = active.iter().flat_map(|&k| b[k * dim..(k + 1) * dim].iter().copied()).collect();
        let mut r = vec![0.0; xs.len()];
        let mut denom = vec![0.0; xs.len()];
        a.residual_many(&xs, &bs, &mut r, &mut denom, active.len());
        let mut corrections = Vec::new();
        let mut refine = Vec::new();
        for (j, &k) in active.iter().enumerate() {
            let bk = &b[k * dim..(k + 1) * dim];
            let rk = &r[j * dim..(j + 1) * dim];
            rel[k] = componentwise_backward_error(rk, &denom[j * dim..(j + 1) * dim], bk);
            if rel[k] > opts.target_for(dim) && steps[k] < opts.max_refinement_steps {
                corrections.extend_from_slice(rk);
                refine.push(k);
            }
        }
        if refine.is_empty() {
            break;
        }
        f.solve_many_unrefined(&mut corrections, refine.len());
        for (j, &k) in refine.iter().enumerate() {
            for (xi, di) in x[k * dim..(k + 1) * dim].iter_mut().zip(&corrections[j * dim..(j + 1) * dim]) {
                *xi += di;
            }
            steps[k] += 1;
        }
        active = refine;
    }
    if let Some(k) = (0..count).find(|&k| !(rel[k] <= opts.max_residual)) {
        return Err(LinalgError::ResidualTooLarge { residual: rel[k], limit: opts.max_residual });
    }
    Ok((0..count)
        .map(|k| Solution {
            x: x[k * dim..(k + 1) * dim].to_vec(),
            relative_residual: rel[k],
            refinement_steps: steps[k],
        })
        .collect())
}
