//! Energy, gradient and tangent of the whole body; Newton's method with a line search;
//! load stepping and the contact augmentations.

use std::time::Instant;

use faer::Mat;
use fibfluid_geometry::Vec3;

use faer::sparse::SparseColMat;

use super::body::{HyperBody, HyperStats};
use super::linear_solve::TangentSolver;
use super::model::HyperModel;
use super::terms::{Assembly, LoadState, add_cell_matrix};
use crate::assemble::FIXED;
use crate::error::{FemError, Result};
use crate::law::LawStates;

/// Armijo's sufficient-decrease constant of the line search.
const ARMIJO: f64 = 1e-4;
/// Halvings of the step the line search tries before the Newton solve fails.
const MAX_BACKTRACKS: usize = 30;
/// Energy changes below this fraction of the energy's terms are rounding.
const ENERGY_ROUNDING: f64 = 1e-12;
/// A full step whose energy change is below this fraction of the energy's terms is judged
/// by the residual instead (the energy no longer resolves progress there).
const NEAR_SOLUTION: f64 = 1e-8;
/// A force below `RESIDUAL_FLOOR * E h^2` is zero (the residual's scale when nothing loads
/// the body).
const RESIDUAL_FLOOR: f64 = 1e-9;
/// The internal forces of a nonlinear law are computed to about this many machine epsilons
/// of `mu h^2` per dof (the stress `mu J^(-2/3) (F - I1 / 3 F^-T)` cancels to its strain's
/// size): a residual below `STRESS_ROUNDING * mu h^2 sqrt(dofs)` is rounding, whatever the
/// load. It matters only where the strains are near the rounding (a body of bone under
/// gravity: strains of 1e-10); below it, Newton's tolerance could not be met.
const STRESS_ROUNDING: f64 = 64.0 * f64::EPSILON;

/// A Newton iteration that cut the residual by at least this factor is converging fast:
/// past the iteration limit, Newton goes on after it.
const FAST_PROGRESS: f64 = 0.1;
/// Iterations Newton may go on past the limit while it converges fast.
const EXTRA_ITERATIONS: usize = 10;

/// The body's energy and gradient at one point.
pub(super) struct Evaluation {
    energy: f64,
    /// The size of the energy's terms (for the rounding bound).
    magnitude: f64,
    pub(super) gradient: Vec<f64>,
    /// `max(|t f|, |f_int|)`: the residual's scale.
    pub(super) scale: f64,
}

/// Why a Newton solve stopped without converging.
pub(super) struct Failure {
    pub(super) residual: f64,
    /// Whether the last tangent was indefinite (factored only with a shift): the
    /// equilibrium sought is unstable there (buckling, a swing, a snap).
    pub(super) indefinite: bool,
}

impl crate::error::NotConvergedWhy {
    /// What `failure` saw.
    pub(super) fn of(failure: &Failure) -> Self {
        if failure.indefinite { Self::Indefinite } else { Self::Stalled }
    }
}

/// The tissue's energy and its gradient at node displacements `u`, the Hessian added to
/// `tangent` when given. `None` when a cell is inverted (`J <= 0`).
pub(super) fn add_tissue(
    model: &HyperModel,
    states: &LawStates,
    u: &[Vec3],
    gradient: &mut [f64],
    mut tangent: Option<&mut SparseColMat<usize, f64>>,
) -> Option<f64> {
    let mut elastic = 0.0;
    for (c, nodes) in model.grid.cell_nodes().iter().enumerate() {
        let fill = model.grid.cell_fill(c);
        let local = nodes.map(|n| u[n]);
        let dofs = model.cell_dofs(nodes);
        let (material, law_state) = (&model.materials[c], states.cell(c));
        elastic += model.cell.energy_with(material, &local, fill, law_state)?;
        let t = model.cell.tangent_with(material, &local, fill, tangent.is_some(), law_state)?;
        for (l, &g) in dofs.iter().enumerate() {
            if g != FIXED {
                gradient[g] += t.gradient[l];
            }
        }
        if let (Some(k), Some(tangent)) = (t.hessian, tangent.as_deref_mut()) {
            add_cell_matrix(tangent, &dofs, &k, 1.0);
        }
    }
    Some(elastic)
}

impl HyperBody {
    /// Energy and gradient at `x` (free dofs); with `tangent`, the Hessian is assembled into
    /// the stage's tangent. `None` when a cell is inverted (`J <= 0`).
    pub(super) fn evaluate(&mut self, x: &[f64], state: &LoadState<'_>, tangent: bool) -> Option<Evaluation> {
        let u = self.node_field(x);
        let mut stage_tangent = tangent.then_some(&mut self.stage.tangent);
        if let Some(t) = stage_tangent.as_deref_mut() {
            t.val_mut().fill(0.0);
        }
        let mut gradient = vec![0.0; self.model.n_free];
        let (model, terms) = (&*self.model, &self.terms);
        let elastic = add_tissue(model, &self.states, &u, &mut gradient, stage_tangent.as_deref_mut())?;
        let internal = gradient.iter().map(|v| v * v).sum::<f64>().sqrt();
        let mut out = Assembly { gradient: &mut gradient, tangent: stage_tangent };
        let supports = terms.each().iter().fold(0.0, |e, term| e + term.add(model, &u, state, &mut out));
        let mut work = 0.0;
        for (g, (f, xi)) in gradient.iter_mut().zip(state.external.iter().zip(x)) {
            *g -= state.t * f;
            work += state.t * f * xi;
        }
        let external = state.t * state.external.iter().map(|v| v * v).sum::<f64>().sqrt();
        let (e, h) = (model.tissue.young(), model.grid.cell_size());
        // A body moved only by grasps has no load: the elastic force of a cell moved by the
        // grasps' largest motion is the scale then (a rigid motion leaves only rounding).
        let floor = (RESIDUAL_FLOOR * e * h * h)
            .max(e * h * terms.grasps.largest_motion(state.t))
            .max(self.rounding_scale());
        Some(Evaluation {
            energy: elastic + supports - work,
            magnitude: elastic.abs() + supports.abs() + work.abs(),
            gradient,
            scale: internal.max(external).max(floor),
        })
    }

    /// The residual's scale below which Newton's tolerance is rounding
    /// ([`STRESS_ROUNDING`], divided by the tolerance); 0 for a linear law (its forces are a
    /// product with the stiffness, without cancellation).
    fn rounding_scale(&self) -> f64 {
        let model = &*self.model;
        let mu = model.materials.iter().filter(|m| !m.law.is_linear()).map(|m| m.mu).fold(0.0, f64::max);
        let h = model.grid.cell_size();
        STRESS_ROUNDING * mu * h * h * (model.n_free as f64).sqrt() / self.settings.tolerance
    }

    /// Newton's method at one load state from `x`; pushes each relative residual on
    /// `history`. Returns the iterations on convergence.
    pub(super) fn newton(
        &mut self,
        x: &mut [f64],
        state: &LoadState<'_>,
        solver: &mut impl TangentSolver,
        history: &mut Vec<f64>,
        stats: &mut HyperStats,
    ) -> Result<std::result::Result<usize, Failure>> {
        let mut indefinite = false;
        let linear = self.model.materials.iter().all(|m| m.law.is_linear());
        for iteration in 0..=self.settings.max_iterations + EXTRA_ITERATIONS {
            let start = Instant::now();
            let Some(eval) = self.evaluate(x, state, true) else {
                return Ok(Err(Failure { residual: f64::INFINITY, indefinite }));
            };
            stats.assembly_seconds += start.elapsed().as_secs_f64();
            let residual = norm(&eval.gradient) / eval.scale;
            history.push(residual);
            if residual <= self.settings.tolerance {
                return Ok(Ok(iteration));
            }
            // Past the iteration limit, Newton goes on only while it converges fast (its
            // quadratic phase had just begun), up to EXTRA_ITERATIONS more.
            let fast = history.len() >= 2 && residual <= FAST_PROGRESS * history[history.len() - 2];
            let limit = self.settings.max_iterations;
            if (iteration >= limit && !fast) || iteration == limit + EXTRA_ITERATIONS || !residual.is_finite()
            {
                return Ok(Err(Failure { residual, indefinite }));
            }
            let start = Instant::now();
            match solver.prepare(&self.stage.tangent) {
                Ok(shift) => {
                    indefinite = shift > 0.0;
                    stats.final_shift = shift;
                }
                Err(FemError::NotPositiveDefinite) => return Ok(Err(Failure { residual, indefinite: true })),
                Err(e) => return Err(e),
            }
            stats.factor_seconds += start.elapsed().as_secs_f64();
            stats.newton_iterations += 1;
            let start = Instant::now();
            let mut d = Mat::<f64>::from_fn(self.model.n_free, 1, |i, _| -eval.gradient[i]);
            solver.set_tolerance(linear_tolerance(residual, self.settings.tolerance, linear));
            solver.solve_in_place(d.as_mut());
            indefinite |= solver.take_negative_curvature();
            let d: Vec<f64> = (0..self.model.n_free).map(|i| d[(i, 0)]).collect();
            let accepted = self.line_search(x, &d, &eval, state);
            stats.solve_seconds += start.elapsed().as_secs_f64();
            if !accepted {
                return Ok(Err(Failure { residual, indefinite }));
            }
        }
        unreachable!("the loop returns at its last iteration")
    }

    /// Backtracking on the energy from `x` along `d`; moves `x` and returns true when a
    /// step is accepted.
    fn line_search(&mut self, x: &mut [f64], d: &[f64], eval: &Evaluation, state: &LoadState<'_>) -> bool {
        let slope: f64 = eval.gradient.iter().zip(d).map(|(g, v)| g * v).sum();
        let rounding = ENERGY_ROUNDING * eval.magnitude;
        let mut alpha = 1.0;
        let mut trial = x.to_vec();
        for _ in 0..MAX_BACKTRACKS {
            for ((t, xi), di) in trial.iter_mut().zip(x.iter()).zip(d) {
                *t = xi + alpha * di;
            }
            let Some(e) = self.energy(&trial, state) else {
                alpha *= 0.5;
                continue;
            };
            // Near the solution the energy's change is below its rounding: a full step that
            // lowers the residual is taken then (Newton's own measure of progress).
            let decreases = e <= eval.energy + ARMIJO * alpha * slope.min(0.0) + rounding;
            let near = alpha == 1.0 && (e - eval.energy).abs() <= NEAR_SOLUTION * eval.magnitude;
            if decreases
                || (near && self.residual_norm(&trial, state).is_some_and(|r| r < norm(&eval.gradient)))
            {
                x.copy_from_slice(&trial);
                return true;
            }
            alpha *= 0.5;
        }
        false
    }

    /// `|gradient|` at `x` (no tangent), `None` when a cell is inverted.
    fn residual_norm(&mut self, x: &[f64], state: &LoadState<'_>) -> Option<f64> {
        self.evaluate(x, state, false).map(|e| norm(&e.gradient))
    }

    /// The energy alone (no gradient), `None` when a cell is inverted.
    pub(super) fn energy(&self, x: &[f64], state: &LoadState<'_>) -> Option<f64> {
        let u = self.node_field(x);
        let model = &*self.model;
        let mut e = 0.0;
        for (c, nodes) in model.grid.cell_nodes().iter().enumerate() {
            e += model.cell.energy_with(
                &model.materials[c],
                &nodes.map(|n| u[n]),
                model.grid.cell_fill(c),
                self.states.cell(c),
            )?;
        }
        for term in self.terms.each() {
            e += term.energy(model, &u, state);
        }
        let work: f64 = state.external.iter().zip(x).map(|(f, xi)| f * xi).sum();
        Some(e - state.t * work)
    }
}

/// The largest relative residual an iterative linear solve may leave at a Newton
/// iteration (inexact Newton).
const MAX_LINEAR_TOLERANCE: f64 = 1e-2;

/// The relative residual an iterative solve of a Newton step stops at, from the relative
/// nonlinear `residual` (inexact Newton, Eisenstat and Walker's idea): loose far from the
/// answer, as tight as the residual near it (superlinear convergence), and never much
/// tighter than the Newton `tolerance` needs. For a `linear` body (every law linear) the
/// step is the answer: it is solved to the tolerance at once.
fn linear_tolerance(residual: f64, tolerance: f64, linear: bool) -> f64 {
    let needed = 0.1 * tolerance / residual.max(f64::MIN_POSITIVE);
    if linear { needed.min(MAX_LINEAR_TOLERANCE) } else { residual.max(needed).min(MAX_LINEAR_TOLERANCE) }
}

/// The Euclidean norm of `v`.
pub(super) fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}
