//! A multigrid preconditioner for symmetric positive definite systems of 3x3 node blocks
//! (linear elasticity on a grid), and the conjugate gradients it preconditions.
//!
//! The caller gives the finest operator ([`BlockCsr`]) and the transfers between levels
//! ([`Prolongation`]: the finite-element crate builds them from its voxel grid, trilinear
//! between the nodes of 2x2x2-merged cells). Every coarser operator is the Galerkin product
//! `P^T A P`, so whatever the fine operator holds (cut cells, penalties, regions) carries
//! down. Each level smooths with a Chebyshev iteration over its node-block Jacobi; the
//! coarsest is factored by the sparse Cholesky. One V-cycle is the preconditioner of
//! [`Multigrid::solve`]'s conjugate gradients.
//!
//! Dofs whose diagonal entry is zero (fixed dofs, coarse dofs with no live child) are
//! *dead*: they stay zero through every operation.

mod block;
mod smoother;
mod transfer;

use std::sync::Arc;

use rayon::prelude::*;

pub use block::{Block, BlockCsr};
pub use transfer::Prolongation;

use block::dot;
use smoother::Chebyshev;

use crate::{LinalgError, Result, SparseCholesky, SparseOrdering};

/// How the V-cycle smooths.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MultigridSettings {
    /// Matrix products per smoothing (the Chebyshev polynomial's degree), before and after
    /// the coarse correction.
    pub degree: usize,
    /// The smoothed part of each level's spectrum: from its largest eigenvalue over this
    /// ratio up to it.
    pub smoothing_range: f64,
}

impl Default for MultigridSettings {
    fn default() -> Self {
        Self { degree: 3, smoothing_range: 15.0 }
    }
}

/// One level below the coarsest: its operator, dead dofs and smoother.
#[derive(Debug)]
struct Level {
    matrix: BlockCsr,
    dead: Vec<bool>,
    smoother: Chebyshev,
}

/// A multigrid hierarchy ready to precondition (see the module docs).
#[derive(Debug)]
pub struct Multigrid {
    levels: Vec<Level>,
    transfers: Arc<Vec<Prolongation>>,
    coarsest: SparseCholesky,
    coarsest_dead: Vec<bool>,
}

/// What a preconditioned conjugate-gradient solve did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PcgOutcome {
    /// Iterations made.
    pub iterations: usize,
    /// `|b - A x| / |b|` at the end.
    pub relative_residual: f64,
    /// Whether a direction of non-positive curvature stopped the iterations (the matrix is
    /// not positive definite); `x` is then the last iterate, a descent direction.
    pub negative_curvature: bool,
}

impl Multigrid {
    /// The hierarchy of `fine` over `transfers` (finest first; each maps the next coarser
    /// level's nodes to this one's). The coarsest operator is factored.
    ///
    /// Errors: the coarsest operator not positive definite
    /// ([`LinalgError::SparseNotPositiveDefinite`]: so is the fine one, or nearly), or its
    /// factor out of memory.
    ///
    /// # Panics
    /// If the transfers' node counts do not chain from `fine` (a programming error).
    pub fn new(
        fine: BlockCsr,
        transfers: Arc<Vec<Prolongation>>,
        settings: MultigridSettings,
    ) -> Result<Self> {
        let mut levels = Vec::with_capacity(transfers.len());
        let mut matrix = fine;
        for p in transfers.iter() {
            assert_eq!(p.fine_nodes(), matrix.nodes(), "transfers chain from the fine level");
            let coarse = p.galerkin(&matrix);
            let dead = matrix.dead();
            let smoother = Chebyshev::new(&matrix, &dead, settings.degree, settings.smoothing_range);
            levels.push(Level { matrix, dead, smoother });
            matrix = coarse;
        }
        let coarsest_dead = matrix.dead();
        let lower = matrix.lower_csc();
        let coarsest = SparseCholesky::new(lower.as_ref(), SparseOrdering::Amd)?;
        Ok(Self { levels, transfers, coarsest, coarsest_dead })
    }

    /// Levels, the coarsest included.
    pub fn depth(&self) -> usize {
        self.levels.len() + 1
    }

    /// Unknowns (three per fine node).
    pub fn unknowns(&self) -> usize {
        self.levels.first().map_or(self.coarsest_dead.len(), |l| l.dead.len())
    }

    /// Bytes held by the levels' operators and the coarsest factor.
    pub fn bytes(&self) -> usize {
        self.levels.iter().map(|l| l.matrix.bytes() + l.dead.len() * 80).sum::<usize>()
            + 8 * self.coarsest.nonzeros()
    }

    /// The fine operator.
    pub fn fine(&self) -> Option<&BlockCsr> {
        self.levels.first().map(|l| &l.matrix)
    }

    /// `z = M^-1 r` for one V-cycle `M^-1` from level `at` down.
    fn vcycle(&self, at: usize, r: &[f64], z: &mut [f64]) {
        let Some(level) = self.levels.get(at) else {
            z.copy_from_slice(r);
            for (zi, &d) in z.iter_mut().zip(&self.coarsest_dead) {
                if d {
                    *zi = 0.0;
                }
            }
            let mut m = faer::MatMut::from_column_major_slice_mut(z, r.len(), 1);
            self.coarsest.solve_in_place(m.as_mut());
            return;
        };
        z.fill(0.0);
        level.smoother.smooth(&level.matrix, r, z, true);
        let mut residual = vec![0.0; r.len()];
        level.matrix.residual(r, z, &mut residual);
        let p = &self.transfers[at];
        let n_coarse = 3 * p.coarse_nodes();
        let coarse_dead = self.levels.get(at + 1).map_or(&self.coarsest_dead, |l| &l.dead);
        let mut coarse_r = vec![0.0; n_coarse];
        p.restrict(&residual, &mut coarse_r, coarse_dead);
        let mut coarse_z = vec![0.0; n_coarse];
        self.vcycle(at + 1, &coarse_r, &mut coarse_z);
        p.prolong_add(&coarse_z, z, &level.dead);
        level.smoother.smooth(&level.matrix, r, z, false);
    }

    /// One V-cycle: `z = M^-1 r`.
    pub fn precondition(&self, r: &[f64], z: &mut [f64]) {
        self.vcycle(0, r, z);
    }

    /// The V-cycle's contraction: the mean factor by which `sweeps` stationary iterations
    /// `x += M^-1 (b - A x)` shrink the residual of a fixed pseudo-random right-hand side
    /// (below 1: the cycle converges on its own; conjugate gradients do better).
    pub fn contraction(&self, sweeps: usize) -> f64 {
        let Some(fine) = self.fine() else { return 0.0 };
        let dead = &self.levels[0].dead;
        let mut seed = 0x2545_f491_4f6c_dd1d_u64;
        let b: Vec<f64> = dead
            .iter()
            .map(|&d| {
                seed ^= seed << 13;
                seed ^= seed >> 7;
                seed ^= seed << 17;
                if d { 0.0 } else { (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5 }
            })
            .collect();
        let n = b.len();
        let (mut x, mut r, mut z) = (vec![0.0; n], b.clone(), vec![0.0; n]);
        let first = dot(&r, &r).sqrt();
        for _ in 0..sweeps {
            self.precondition(&r, &mut z);
            x.iter_mut().zip(&z).for_each(|(xi, zi)| *xi += zi);
            fine.residual(&b, &x, &mut r);
        }
        (dot(&r, &r).sqrt() / first).powf(1.0 / sweeps.max(1) as f64)
    }

    /// Solves `A x = b` by conjugate gradients preconditioned with one V-cycle, from `x`,
    /// until `|b - A x| <= tolerance * |b|` or `max_iterations`. Without finer levels
    /// (one level) the coarsest factor solves it directly.
    pub fn solve(&self, b: &[f64], x: &mut [f64], tolerance: f64, max_iterations: usize) -> PcgOutcome {
        let Some(fine) = self.fine() else {
            self.vcycle(0, b, x);
            return PcgOutcome::default();
        };
        pcg(|v, out| fine.mul(v, out), |r, z| self.precondition(r, z), b, x, tolerance, max_iterations)
    }
}

/// Preconditioned conjugate gradients on `apply` with `precondition` from `x` (see
/// [`Multigrid::solve`]).
pub fn pcg(
    apply: impl Fn(&[f64], &mut [f64]),
    precondition: impl Fn(&[f64], &mut [f64]),
    b: &[f64],
    x: &mut [f64],
    tolerance: f64,
    max_iterations: usize,
) -> PcgOutcome {
    let n = b.len();
    let b_norm = dot(b, b).sqrt();
    if b_norm == 0.0 {
        x.fill(0.0);
        return PcgOutcome::default();
    }
    let mut r = vec![0.0; n];
    apply(x, &mut r);
    r.par_iter_mut().zip(b.par_iter()).for_each(|(ri, bi)| *ri = bi - *ri);
    let mut z = vec![0.0; n];
    precondition(&r, &mut z);
    let mut p = z.clone();
    let mut q = vec![0.0; n];
    let mut rz = dot(&r, &z);
    let mut outcome = PcgOutcome { relative_residual: dot(&r, &r).sqrt() / b_norm, ..Default::default() };
    while outcome.relative_residual > tolerance && outcome.iterations < max_iterations {
        apply(&p, &mut q);
        let pq = dot(&p, &q);
        if !(pq > 0.0) {
            outcome.negative_curvature = true;
            if outcome.iterations == 0 {
                // Nothing better than the preconditioned residual: a descent direction.
                x.par_iter_mut().zip(z.par_iter()).for_each(|(xi, zi)| *xi += zi);
            }
            break;
        }
        let alpha = rz / pq;
        x.par_iter_mut().zip(p.par_iter()).for_each(|(xi, pi)| *xi += alpha * pi);
        r.par_iter_mut().zip(q.par_iter()).for_each(|(ri, qi)| *ri -= alpha * qi);
        outcome.iterations += 1;
        outcome.relative_residual = dot(&r, &r).sqrt() / b_norm;
        precondition(&r, &mut z);
        let rz_new = dot(&r, &z);
        let beta = rz_new / rz;
        rz = rz_new;
        p.par_iter_mut().zip(z.par_iter()).for_each(|(pi, zi)| *pi = zi + beta * *pi);
    }
    outcome
}

/// Whether an error of [`Multigrid::new`] says the operator is not positive definite.
pub fn is_not_positive_definite(e: &LinalgError) -> bool {
    matches!(e, LinalgError::SparseNotPositiveDefinite { .. })
}
