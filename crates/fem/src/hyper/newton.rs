//! Energy, gradient and tangent of the whole body; Newton's method with a line search;
//! load stepping and the contact augmentations.

use std::time::Instant;

use faer::Mat;
use fibfluid_geometry::Vec3;
use fibfluid_linalg::SparseCholesky;

use super::body::{HyperBody, HyperStats};
use super::contact::{CONTACT_PENALTY, CONTACT_SMOOTHING, ContactLaw, RigidPlate};
use crate::assemble::FIXED;
use crate::element::CELL_DOFS;
use crate::error::{FemError, Result};

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

/// A Newton iteration that cut the residual by at least this factor is converging fast:
/// past the iteration limit, Newton goes on after it.
const FAST_PROGRESS: f64 = 0.1;
/// Iterations Newton may go on past the limit while it converges fast.
const EXTRA_ITERATIONS: usize = 10;

/// What a solve at one load factor works with.
pub(super) struct LoadState<'a> {
    pub(super) t: f64,
    pub(super) external: &'a [f64],
    pub(super) plates: &'a [RigidPlate],
    /// Per plate, per sample: the contact pressure of the last augmentation (Pa).
    pub(super) multipliers: &'a [Vec<f64>],
    /// Per grasped vertex: the force of the last augmentation (N).
    pub(super) grasp_multipliers: &'a [fibfluid_geometry::Vec3],
}

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

impl HyperBody {
    /// The contact law: `beta = CONTACT_PENALTY * E / h`, smoothed over
    /// `CONTACT_SMOOTHING * E`.
    pub(super) fn contact_law(&self) -> ContactLaw {
        let e = self.tissue.young();
        ContactLaw { beta: CONTACT_PENALTY * e / self.grid.cell_size(), width: CONTACT_SMOOTHING * e }
    }

    fn cell_dofs(&self, nodes: &[usize; 8]) -> [usize; CELL_DOFS] {
        std::array::from_fn(|l| self.free[3 * nodes[l / 3] + l % 3])
    }

    /// Adds `coef * v v^T` on `dofs` to the tangent's lower triangle.
    pub(super) fn add_rank_one(&mut self, dofs: &[usize; CELL_DOFS], v: &[f64; CELL_DOFS], coef: f64) {
        let (symbolic, values) = self.tangent.parts_mut();
        let (col_ptr, row_idx) = (symbolic.col_ptr(), symbolic.row_idx());
        for (c, &gc) in dofs.iter().enumerate() {
            if gc == FIXED || v[c] == 0.0 {
                continue;
            }
            let col = &row_idx[col_ptr[gc]..col_ptr[gc + 1]];
            for (r, &gr) in dofs.iter().enumerate() {
                if gr == FIXED || gr < gc || v[r] == 0.0 {
                    continue;
                }
                if let Ok(pos) = col.binary_search(&gr) {
                    values[col_ptr[gc] + pos] += coef * v[r] * v[c];
                }
            }
        }
    }

    /// Adds a cell matrix on `dofs` to the tangent's lower triangle.
    fn add_cell_matrix(&mut self, dofs: &[usize; CELL_DOFS], k: &crate::element::CellMatrix) {
        let (symbolic, values) = self.tangent.parts_mut();
        let (col_ptr, row_idx) = (symbolic.col_ptr(), symbolic.row_idx());
        for (c, &gc) in dofs.iter().enumerate() {
            if gc == FIXED {
                continue;
            }
            let col = &row_idx[col_ptr[gc]..col_ptr[gc + 1]];
            for (r, &gr) in dofs.iter().enumerate() {
                if gr == FIXED || gr < gc {
                    continue;
                }
                if let Ok(pos) = col.binary_search(&gr) {
                    values[col_ptr[gc] + pos] += k[r][c];
                }
            }
        }
    }

    /// Energy and gradient at `x` (free dofs); with `tangent`, the Hessian is assembled into
    /// `self.tangent`. `None` when a cell is inverted (`J <= 0`).
    pub(super) fn evaluate(&mut self, x: &[f64], state: &LoadState<'_>, tangent: bool) -> Option<Evaluation> {
        let u = self.node_field(x);
        if tangent {
            self.tangent.val_mut().fill(0.0);
        }
        let mut gradient = vec![0.0; self.n_free];
        let mut elastic = 0.0;
        let cells = self.grid.cell_nodes().len();
        for c in 0..cells {
            let nodes = self.grid.cell_nodes()[c];
            let fill = self.grid.fill()[c];
            let local = nodes.map(|n| u[n]);
            let dofs = self.cell_dofs(&nodes);
            let (material, law_state) = (&self.materials[c], self.states.cell(c));
            elastic += self.cell.energy_with(material, &local, fill, law_state)?;
            let t = self.cell.tangent_with(material, &local, fill, tangent, law_state)?;
            for (l, &g) in dofs.iter().enumerate() {
                if g != FIXED {
                    gradient[g] += t.gradient[l];
                }
            }
            if let Some(k) = t.hessian {
                self.add_cell_matrix(&dofs, &k);
            }
        }
        let internal = gradient.iter().map(|v| v * v).sum::<f64>().sqrt();
        let supports = self.add_clamp(&u, &mut gradient, tangent)
            + self.add_contact(&u, state, &mut gradient, tangent)
            + self.add_grasps(&u, state, &mut gradient, tangent);
        let mut work = 0.0;
        for (g, (f, xi)) in gradient.iter_mut().zip(state.external.iter().zip(x)) {
            *g -= state.t * f;
            work += state.t * f * xi;
        }
        let external = state.t * state.external.iter().map(|v| v * v).sum::<f64>().sqrt();
        let (e, h) = (self.tissue.young(), self.grid.cell_size());
        // A body moved only by grasps has no load: the elastic force of a cell moved by the
        // grasps' largest motion is the scale then (a rigid motion leaves only rounding).
        let floor = (RESIDUAL_FLOOR * e * h * h).max(e * h * self.grasps.largest_motion(state.t));
        Some(Evaluation {
            energy: elastic + supports - work,
            magnitude: elastic.abs() + supports.abs() + work.abs(),
            gradient,
            scale: internal.max(external).max(floor),
        })
    }

    /// The clamp's penalty energy; its gradient added to `gradient`, its Hessian to the
    /// tangent.
    fn add_clamp(&mut self, u: &[Vec3], gradient: &mut [f64], tangent: bool) -> f64 {
        let mut energy = 0.0;
        for i in 0..self.clamp.len() {
            let p = self.clamp[i];
            let coef = self.clamp_beta * p.area;
            let d: f64 = (0..8).map(|b| p.weights[b] * u[p.nodes[b]][p.axis]).sum();
            energy += 0.5 * coef * d * d;
            let mut dofs = [FIXED; CELL_DOFS];
            let mut v = [0.0; CELL_DOFS];
            for b in 0..8 {
                dofs[3 * b + p.axis] = self.free[3 * p.nodes[b] + p.axis];
                v[3 * b + p.axis] = p.weights[b];
                if let Some(g) = gradient.get_mut(dofs[3 * b + p.axis]) {
                    *g += coef * d * p.weights[b];
                }
            }
            if tangent {
                self.add_rank_one(&dofs, &v, coef);
            }
        }
        energy
    }

    /// The plates' augmented-Lagrangian contact energy (see [`super::contact`]); gradient
    /// and Hessian added as [`HyperBody::add_clamp`] does.
    fn add_contact(&mut self, u: &[Vec3], state: &LoadState<'_>, gradient: &mut [f64], tangent: bool) -> f64 {
        let law = self.contact_law();
        let mut energy = 0.0;
        for (k, plate) in state.plates.iter().enumerate() {
            for s in 0..self.samples.len() {
                let sample = self.samples[s];
                let lambda = state.multipliers[k][s];
                let x = law.argument(lambda, plate.gap(sample.position(u), state.t));
                energy += law.energy(sample.area, lambda, x);
                let p = law.pressure(x);
                if p == 0.0 {
                    continue;
                }
                let dofs = self.cell_dofs(&sample.nodes);
                let v: [f64; CELL_DOFS] =
                    std::array::from_fn(|l| sample.weights[l / 3] * plate.normal[l % 3]);
                for (l, &g) in dofs.iter().enumerate() {
                    if g != FIXED {
                        gradient[g] -= sample.area * p * v[l];
                    }
                }
                if tangent {
                    self.add_rank_one(&dofs, &v, sample.area * law.beta * law.slope(x));
                }
            }
        }
        energy
    }

    /// The grasps' energy; its gradient added to `gradient`, its Hessian (`k w w^T` per
    /// axis) to the tangent.
    pub(super) fn add_grasps(
        &mut self,
        u: &[Vec3],
        state: &LoadState<'_>,
        gradient: &mut [f64],
        tangent: bool,
    ) -> f64 {
        let forces = self.grasps.forces(u, state.t, state.grasp_multipliers);
        for (i, f) in forces.iter().enumerate() {
            let p = self.grasps.points[i];
            for a in 0..3 {
                let mut dofs = [FIXED; crate::element::CELL_DOFS];
                let mut v = [0.0; crate::element::CELL_DOFS];
                for b in 0..8 {
                    dofs[3 * b + a] = self.free[3 * p.nodes[b] + a];
                    v[3 * b + a] = p.weights[b];
                    if let Some(g) = gradient.get_mut(dofs[3 * b + a]) {
                        *g += f[a] * p.weights[b];
                    }
                }
                if tangent {
                    self.add_rank_one(&dofs, &v, p.stiffness);
                }
            }
        }
        self.grasps.energy(u, state.t, state.grasp_multipliers)
    }

    /// Factors the assembled tangent; a tangent that is not positive definite (far from
    /// equilibrium) is shifted by a growing multiple of its largest diagonal entry (up to the
    /// entry itself: a scaled gradient step); beyond that the load step is cut.
    /// Returns the shift used (relative to the largest diagonal entry; 0: none).
    pub(super) fn factor_tangent(&self, factor: &mut Option<SparseCholesky>) -> Result<f64> {
        let mut matrix = self.tangent.clone();
        let diagonal: Vec<usize> = (0..self.n_free).map(|j| matrix.symbolic().col_ptr()[j]).collect();
        let largest = diagonal.iter().map(|&p| matrix.val()[p].abs()).fold(0.0, f64::max);
        for shift in [0.0, 1e-8, 1e-6, 1e-4, 1e-2, 1.0] {
            if shift > 0.0 {
                let values = matrix.val_mut();
                for &p in &diagonal {
                    values[p] += shift * largest;
                }
            }
            let result = match factor.as_mut() {
                Some(f) => f.refactor(matrix.as_ref()),
                None => SparseCholesky::factor(&self.symbolic, matrix.as_ref()).map(|f| {
                    *factor = Some(f);
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

    /// Newton's method at one load state from `x`; pushes each relative residual on
    /// `history`. Returns the iterations on convergence.
    pub(super) fn newton(
        &mut self,
        x: &mut [f64],
        state: &LoadState<'_>,
        factor: &mut Option<SparseCholesky>,
        history: &mut Vec<f64>,
        stats: &mut HyperStats,
    ) -> Result<std::result::Result<usize, Failure>> {
        let mut indefinite = false;
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
            match self.factor_tangent(factor) {
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
            let mut d = Mat::<f64>::from_fn(self.n_free, 1, |i, _| -eval.gradient[i]);
            factor.as_ref().expect("factored above").solve_in_place(d.as_mut());
            let d: Vec<f64> = (0..self.n_free).map(|i| d[(i, 0)]).collect();
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
        let mut e = 0.0;
        for (c, (nodes, &fill)) in self.grid.cell_nodes().iter().zip(self.grid.fill()).enumerate() {
            e +=
                self.cell.energy_with(&self.materials[c], &nodes.map(|n| u[n]), fill, self.states.cell(c))?;
        }
        for p in &self.clamp {
            let d: f64 = (0..8).map(|b| p.weights[b] * u[p.nodes[b]][p.axis]).sum();
            e += 0.5 * self.clamp_beta * p.area * d * d;
        }
        let law = self.contact_law();
        for (k, plate) in state.plates.iter().enumerate() {
            for (s, sample) in self.samples.iter().enumerate() {
                let lambda = state.multipliers[k][s];
                let x = law.argument(lambda, plate.gap(sample.position(&u), state.t));
                e += law.energy(sample.area, lambda, x);
            }
        }
        e += self.grasps.energy(&u, state.t, state.grasp_multipliers);
        let work: f64 = state.external.iter().zip(x).map(|(f, xi)| f * xi).sum();
        Some(e - state.t * work)
    }
}

/// The Euclidean norm of `v`.
pub(super) fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}
