//! Meeting the grasps exactly: Newton's method on the augmented Lagrangian's optimality
//! conditions, the grasps' forces as unknowns beside the state.
//!
//! Uzawa's update (`lambda <- lambda + k g`, [`super::grasp`]) converges linearly, at a rate
//! set by how stiffly the body answers the grasp's rows against the penalty `k`: on a patch
//! of many vertices in few cells (rows nearly dependent) it took all 20 augmentations, two
//! Newton iterations each, to bring the error from 5e-5 to 5e-6 m on a liver (each
//! augmentation about 0.95 of the one before). Once the contact is settled, the grasps are
//! met instead by Newton's method on
//!
//! ```text
//! grad E(x) + C^T (lambda + k g) = 0,      g = C x - d = 0,
//! ```
//!
//! (`C` the grasped vertices' rows over the free dofs, `d` their targets), whose step solves
//! `A dx + C^T dlambda = -r`, `C dx = -g` with `A` the assembled tangent (`k C^T C`
//! included): `dlambda = S^-1 (g - C A^-1 r)`, `S = C A^-1 C^T` (one multi-column solve for
//! the rows' compliance columns), `dx = -A^-1 r - A^-1 C^T dlambda`. It converges
//! quadratically: on the same liver, 4 iterations to the tolerance. Dependent rows (more
//! grasped vertices in a cell than its nodes can move independently) make `S` singular; a
//! ridge of [`RIDGES`] times its largest diagonal entry regularizes it (consistent targets,
//! a rigid motion, keep the solution; the ridge picks the smallest multipliers).

use std::time::Instant;

use faer::Mat;
use fibfluid_linalg::{CapacitanceFactor, row_dot};

use super::body::{HyperBody, HyperStats};
use super::grasp::GRASP_TOLERANCE;
use super::linear_solve::TangentSolver;
use super::newton::norm;
use super::terms::LoadState;
use crate::assemble::FIXED;

/// Newton iterations on the grasps' optimality conditions at most, before Uzawa's
/// augmentations take over (a grasp pulled far from where the penalty left it can need
/// a dozen damped ones on shifted tangents before the quadratic ones).
pub const GRASP_NEWTON_ITERATIONS: usize = 30;

/// Ridges tried, in turn, on the grasps' capacitance `S` (times its largest diagonal
/// entry): none first, then growing ones for dependent rows.
const RIDGES: [f64; 4] = [0.0, 1e-12, 1e-9, 1e-6];

/// Halvings of a step that would invert a cell.
const STEP_HALVINGS: usize = 10;

/// What the grasps' Newton iterations need beside the body: the load state's parts that
/// stay fixed, and the grasps' forces, which the iterations update.
pub(super) struct GraspKkt<'a> {
    pub(super) external: &'a [f64],
    pub(super) plates: &'a [super::contact::RigidPlate],
    pub(super) multipliers: &'a [Vec<f64>],
    /// The load factor the grasps are met at.
    pub(super) t: f64,
}

impl<'a> GraspKkt<'a> {
    /// The load state at the full load with the grasps' forces `held`.
    fn state<'s>(&self, held: &'s [fibfluid_geometry::Vec3]) -> LoadState<'s>
    where
        'a: 's,
    {
        LoadState {
            t: self.t,
            external: self.external,
            plates: self.plates,
            multipliers: self.multipliers,
            grasp_multipliers: held,
        }
    }
}

impl HyperBody {
    /// The grasped vertices' rows over the free dofs: per point, per axis, the weights of
    /// its position on the free nodal dofs.
    fn grasp_rows(&self) -> Vec<Vec<(usize, f64)>> {
        let mut rows = Vec::with_capacity(3 * self.terms.grasps.points.len());
        for p in &self.terms.grasps.points {
            for a in 0..3 {
                let row = (0..8)
                    .map(|b| (self.model.free[3 * p.nodes[b] + a], p.weights[b]))
                    .filter(|&(d, w)| d != FIXED && w != 0.0)
                    .collect();
                rows.push(row);
            }
        }
        rows
    }

    /// Newton's method on the grasps' optimality conditions from `x` at the full load
    /// (see the module docs), updating `x` and the grasps' forces `held`; pushes each
    /// relative residual on `history`. `Some(iterations)` once the residual and every
    /// grasp's error are within tolerance; `None` when it cannot get there (too large, a
    /// tangent no shift makes positive definite, a step that inverts at every halving, no
    /// convergence): the caller then restores the state and goes on with Uzawa's
    /// augmentations.
    pub(super) fn meet_grasps(
        &mut self,
        x: &mut [f64],
        fixed: &GraspKkt<'_>,
        held: &mut [fibfluid_geometry::Vec3],
        solver: &mut impl TangentSolver,
        history: &mut Vec<f64>,
        stats: &mut HyperStats,
    ) -> Option<usize> {
        let rows = self.grasp_rows();
        let (n, m) = (self.model.n_free, rows.len());
        if m == 0 || 8 * m * n > self.settings.grasp_columns_bytes {
            return None;
        }
        let refs: Vec<&[(usize, f64)]> = rows.iter().map(Vec::as_slice).collect();
        let tolerance = GRASP_TOLERANCE * self.model.grid.cell_size();
        for iteration in 0..=GRASP_NEWTON_ITERATIONS {
            let state = fixed.state(held);
            let start = Instant::now();
            let eval = self.evaluate(x, &state, true)?;
            stats.assembly_seconds += start.elapsed().as_secs_f64();
            let residual = norm(&eval.gradient) / eval.scale;
            history.push(residual);
            let u = self.node_field(x);
            if residual <= self.settings.tolerance
                && self.terms.grasps.largest_error(&u, fixed.t) <= tolerance
            {
                return Some(iteration);
            }
            let start = Instant::now();
            if iteration == GRASP_NEWTON_ITERATIONS {
                return None;
            }
            // An indefinite tangent is factored shifted, as in Newton's solves: a damped
            // step that still meets the grasps' rows (their capacitance takes the shift).
            stats.final_shift = solver.prepare(&self.stage.tangent).ok()?;
            stats.factor_seconds += start.elapsed().as_secs_f64();
            stats.newton_iterations += 1;
            let start = Instant::now();
            let columns = solver.compliance_columns(&refs).ok()?;
            let mut free = Mat::<f64>::from_fn(n, 1, |i, _| -eval.gradient[i]);
            solver.solve_in_place(free.as_mut());
            let free = free.col_as_slice(0);
            let errors: Vec<f64> = self.terms.grasps.errors(&u, fixed.t).into_iter().flatten().collect();
            let rhs: Vec<f64> = rows.iter().zip(&errors).map(|(row, g)| g + row_dot(row, free)).collect();
            let dlambda = capacitance(&rows, &columns)?.solve(&rhs);
            let dx: Vec<f64> = (0..n)
                .map(|i| free[i] - columns.iter().zip(&dlambda).map(|(z, l)| z[i] * l).sum::<f64>())
                .collect();
            self.take_step(x, &dx, held, &dlambda, fixed)?;
            stats.solve_seconds += start.elapsed().as_secs_f64();
        }
        None
    }

    /// Moves `x` by `dx` and the grasps' forces by `dlambda`, halved while the step would
    /// invert a cell; `None` when even the last halving does.
    fn take_step(
        &self,
        x: &mut [f64],
        dx: &[f64],
        held: &mut [fibfluid_geometry::Vec3],
        dlambda: &[f64],
        fixed: &GraspKkt<'_>,
    ) -> Option<()> {
        let mut alpha = 1.0;
        for _ in 0..=STEP_HALVINGS {
            let trial: Vec<f64> = x.iter().zip(dx).map(|(a, d)| a + alpha * d).collect();
            if self.energy(&trial, &fixed.state(held)).is_some() {
                x.copy_from_slice(&trial);
                for (p, force) in held.iter_mut().enumerate() {
                    (0..3).for_each(|a| force[a] += alpha * dlambda[3 * p + a]);
                }
                return Some(());
            }
            alpha *= 0.5;
        }
        None
    }
}

/// The factored capacitance `S = C Z` of the rows and their compliance columns, ridged when
/// the rows are dependent.
fn capacitance(rows: &[Vec<(usize, f64)>], columns: &[Vec<f64>]) -> Option<CapacitanceFactor> {
    let m = rows.len();
    let s = Mat::<f64>::from_fn(m, m, |i, j| row_dot(&rows[i], &columns[j]));
    let largest = (0..m).map(|i| s[(i, i)].abs()).fold(0.0, f64::max);
    RIDGES.iter().find_map(|&ridge| {
        let mut ridged = s.clone();
        (0..m).for_each(|i| ridged[(i, i)] += ridge * largest);
        CapacitanceFactor::new(ridged.as_ref(), None).ok()
    })
}
