//! The load stepping of a hyperelastic solve and its contact augmentations.

use fibfluid_geometry::Vec3;
use fibfluid_geometry::vec3::{cross, dot, norm, scale, sub};

use super::body::{HyperBody, HyperSolution, HyperStats, LoadStep};

use super::contact::{
    CONTACT_FORCE_TOLERANCE, CONTACT_GAP_TOLERANCE, MAX_AUGMENTATIONS, RigidPlate, check_plates,
};
use super::grasp::GRASP_TOLERANCE;
use super::grasp_kkt::GraspKkt;
use super::linear_solve::LinearSolver;
use super::terms::{ContactTerm, LoadState};
use crate::assemble::FIXED;
use crate::body::Loads;
use crate::error::{FemError, NotConvergedWhy, Result};

/// The state of a solve between load steps.
pub(super) struct Progress {
    pub(super) x: Vec<f64>,
    /// The load factor reached.
    pub(super) t: f64,
    pub(super) steps: Vec<LoadStep>,
    pub(super) stats: HyperStats,
    /// The linear solve of every Newton iteration of the solve.
    pub(super) solver: LinearSolver,
}

impl Progress {
    /// At rest, at the load factor `t`, with `n` free dofs, solving with `solver`.
    pub(super) fn at(n: usize, t: f64, solver: LinearSolver) -> Self {
        Self { x: vec![0.0; n], t, steps: Vec::new(), stats: HyperStats::default(), solver }
    }

    /// The stats with the linear solver's counts.
    pub(super) fn final_stats(&self) -> HyperStats {
        let (iterations, solves) = self.solver.iterations();
        let solver = match self.solver {
            LinearSolver::Direct(_) => crate::FemSolver::Direct,
            LinearSolver::Multigrid(_) => crate::FemSolver::Multigrid,
        };
        HyperStats { linear_iterations: iterations, linear_solves: solves, solver, ..self.stats }
    }
}

/// The multipliers of the force terms' augmented Lagrangians during a solve.
#[derive(Clone)]
pub(super) struct Multipliers {
    /// Per plate, per sample: the contact pressure of the last augmentation (Pa).
    pub(super) contact: Vec<Vec<f64>>,
    /// Per grasped vertex: the force of the last augmentation (N).
    pub(super) grasps: Vec<Vec3>,
}

impl Multipliers {
    /// None yet: `samples` contact samples under `plates` plates, `grasped` grasped points.
    pub(super) fn zero(samples: usize, plates: usize, grasped: usize) -> Self {
        Self { contact: vec![vec![0.0; samples]; plates], grasps: vec![[0.0; 3]; grasped] }
    }

    /// The load state at load factor `t` with these multipliers.
    pub(super) fn state<'a>(
        &'a self,
        t: f64,
        external: &'a [f64],
        plates: &'a [RigidPlate],
    ) -> LoadState<'a> {
        LoadState { t, external, plates, multipliers: &self.contact, grasp_multipliers: &self.grasps }
    }
}

/// How far the augmentations have met the contact and the grasps.
#[derive(Default)]
pub(super) struct Augmenting {
    /// Contact is settled when nothing penetrates or the plate forces stopped changing.
    pub(super) contact_settled: bool,
    /// Whether Newton's method on the grasps' optimality conditions was tried.
    pub(super) newton_tried: bool,
    /// The plate forces after the last augmentation (N).
    pub(super) force: Vec<f64>,
}

impl HyperBody {
    /// The static large-deformation response to `loads` (dead loads, scaled by the load
    /// factor), the `plates` (moving with it) and the body's grasps (moving with it).
    ///
    /// Errors: a vertex out of range or a non-finite load or plate, a plate driven by a force
    /// (timed solves only); a load step that
    /// cannot converge ([`FemError::NotConverged`], with the step, the load factor and the
    /// residual).
    pub fn solve(&mut self, loads: &Loads, plates: &[RigidPlate]) -> Result<HyperSolution> {
        check_plates(plates)?;
        if plates.iter().any(|p| p.force.is_some()) {
            return Err(FemError::InvalidTime {
                reason: "a plate driven by a force needs a timed solve ([time]); a static solve drives plates by their travel".into(),
            });
        }
        let external = self.external_loads(loads)?;
        let mut duals =
            Multipliers::zero(self.terms.contact.samples.len(), plates.len(), self.terms.grasps.points.len());
        let solver = self.stage.linear_solver(&self.model, self.settings.solver)?;
        let mut run = Progress::at(self.model.n_free, 0.0, solver);
        self.step_to_full_load(&mut run, &duals.state(0.0, &external, plates))?;
        let force = run.steps.last().map(|s| s.plate_forces.clone()).unwrap_or_default();
        let mut progress = Augmenting { force, ..Augmenting::default() };
        for augmentation in 1..=MAX_AUGMENTATIONS {
            if !self.augment_once(&mut run, &external, plates, &mut duals, &mut progress, augmentation)? {
                break;
            }
        }
        let state = duals.state(1.0, &external, plates);
        let support_force = self.support_force(&run.x, &state, loads);
        Ok(self.finish(run, &state, support_force))
    }

    /// One augmentation of the contact and grasp multipliers and the Newton solve after
    /// it; `false` once both are met (or the grasps could be met no further).
    pub(super) fn augment_once(
        &mut self,
        run: &mut Progress,
        external: &[f64],
        plates: &[RigidPlate],
        duals: &mut Multipliers,
        progress: &mut Augmenting,
        augmentation: usize,
    ) -> Result<bool> {
        let h = self.model.grid.cell_size();
        // A force-driven plate keeps the plain penalty: its penetration moves the plate
        // (found for its force), not the load the body carries.
        let deepest = self.deepest_penetration(&run.x, plates, run.t);
        let shallow =
            deepest.iter().zip(plates).all(|(&d, p)| p.force.is_some() || d <= CONTACT_GAP_TOLERANCE * h);
        let contact_done = shallow || progress.contact_settled;
        let u = self.node_field(&run.x);
        let grasp_done = self.terms.grasps.largest_error(&u, run.t) <= GRASP_TOLERANCE * h;
        if contact_done && grasp_done {
            return Ok(false);
        }
        // With the contact settled, Newton's method meets the grasps (once: should it
        // fail, Uzawa's augmentations go on from where it started).
        if contact_done && !progress.newton_tried {
            progress.newton_tried = true;
            let saved = (run.x.clone(), duals.grasps.clone(), run.stats.final_shift);
            let fixed = GraspKkt { external, plates, multipliers: &duals.contact, t: run.t };
            let mut history = Vec::new();
            let met = self.meet_grasps(
                &mut run.x,
                &fixed,
                &mut duals.grasps,
                &mut run.solver,
                &mut history,
                &mut run.stats,
            );
            if let Some(iterations) = met {
                run.stats.augmentations += 1;
                self.record_step(run, plates, &duals.contact, augmentation, iterations, history);
                return Ok(true);
            }
            (run.x, duals.grasps, run.stats.final_shift) = saved;
        }
        let before = (run.x.clone(), duals.clone());
        if !contact_done {
            self.augment(&run.x, plates, run.t, &mut duals.contact);
        }
        if !grasp_done {
            self.terms.grasps.augment(&u, run.t, &mut duals.grasps);
        }
        let mut history = Vec::new();
        let state = duals.state(run.t, external, plates);
        match self.newton(&mut run.x, &state, &mut run.solver, &mut history, &mut run.stats)? {
            Ok(iterations) => {
                run.stats.augmentations += 1;
                let next =
                    self.record_step(run, plates, &duals.contact, augmentation, iterations, history).to_vec();
                let change = next.iter().zip(&progress.force).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
                let largest = next.iter().fold(0.0_f64, |m, f| m.max(f.abs()));
                progress.force = next;
                if !contact_done {
                    progress.contact_settled = change <= CONTACT_FORCE_TOLERANCE * largest;
                }
                Ok(true)
            }
            Err(f) if !contact_done => Err(FemError::NotConverged {
                step: run.steps.len() + 1,
                load: run.t,
                residual: f.residual,
                why: self.failure_why(&run.x, &f),
            }),
            Err(_) => {
                // Only the grasps were left to meet: the last converged state stands (the
                // load stepping's, or an earlier augmentation's), its grasps met as far as
                // its record says (each grasp's error is reported, and guarded by the
                // `grasp` result guard).
                (run.x, *duals) = before;
                run.stats.failed_augmentations += 1;
                Ok(false)
            }
        }
    }

    /// Load steps from 0 to 1: an increment halves when Newton fails and doubles after an
    /// easy step.
    fn step_to_full_load(&mut self, run: &mut Progress, base: &LoadState<'_>) -> Result<()> {
        let largest = self.settings.max_increment.clamp(self.settings.min_increment, 1.0);
        let mut increment = self.settings.first_increment.clamp(self.settings.min_increment, largest);
        // The last converged increment (load and displacement), for the secant predictor.
        let mut last: Option<(f64, Vec<f64>)> = None;
        while run.t < 1.0 {
            // Within rounding of the full load is the full load (no empty last step).
            let target = if run.t + increment >= 1.0 - 1e-9 { 1.0 } else { run.t + increment };
            let state = LoadState { t: target, ..*base };
            let mut trial = self.predict(&run.x, last.as_ref(), target - run.t, &state);
            let mut history = Vec::new();
            match self.newton(&mut trial, &state, &mut run.solver, &mut history, &mut run.stats)? {
                Ok(iterations) => {
                    let step: Vec<f64> = trial.iter().zip(&run.x).map(|(a, b)| a - b).collect();
                    last = Some((target - run.t, step));
                    run.x = trial;
                    run.t = target;
                    run.stats.load_steps += 1;
                    self.record_step(run, state.plates, state.multipliers, 0, iterations, history);
                    if iterations <= self.settings.easy_iterations {
                        increment = (2.0 * increment).min(largest);
                    }
                }
                Err(f) => {
                    run.stats.cut_steps += 1;
                    increment *= 0.5;
                    if increment < self.settings.min_increment {
                        return Err(FemError::NotConverged {
                            step: run.steps.len() + 1,
                            load: target,
                            residual: f.residual,
                            why: self.failure_why(&trial, &f),
                        });
                    }
                }
            }
        }
        Ok(())
    }

    /// Why Newton failed at the state `x` it stopped at: a tissue cell dilated past the
    /// volumetric energy's pressure peak, or the tangent it saw.
    fn failure_why(&self, x: &[f64], failure: &super::newton::Failure) -> NotConvergedWhy {
        let largest = self.cell_states(&self.node_field(x)).1.j_max;
        if largest > std::f64::consts::E {
            NotConvergedWhy::Dilatation { j: largest }
        } else {
            NotConvergedWhy::of(failure)
        }
    }

    /// The secant predictor: the last converged increment scaled to this one, when the
    /// cells stay uninverted there; the current state otherwise.
    fn predict(
        &self,
        x: &[f64],
        last: Option<&(f64, Vec<f64>)>,
        increment: f64,
        state: &LoadState<'_>,
    ) -> Vec<f64> {
        if let Some((dt, dx)) = last {
            let ratio = increment / dt;
            let guess: Vec<f64> = x.iter().zip(dx).map(|(a, d)| a + ratio * d).collect();
            if self.energy(&guess, state).is_some() {
                return guess;
            }
        }
        x.to_vec()
    }

    /// Per plate, the deepest penetration (m, 0 when none) at the load factor `t`.
    pub(super) fn deepest_penetration(&self, x: &[f64], plates: &[RigidPlate], t: f64) -> Vec<f64> {
        let u = self.node_field(x);
        plates
            .iter()
            .map(|p| self.terms.contact.samples.iter().map(|s| -p.gap(s.position(&u), t)).fold(0.0, f64::max))
            .collect()
    }

    /// Per plate, the contact force on the body along its normal (N) at load factor `t`.
    pub(super) fn plate_forces(
        &self,
        x: &[f64],
        plates: &[RigidPlate],
        multipliers: &[Vec<f64>],
        t: f64,
    ) -> Vec<f64> {
        let u = self.node_field(x);
        let law = ContactTerm::law(&self.model);
        plates
            .iter()
            .zip(multipliers)
            .map(|(p, m)| {
                self.terms
                    .contact
                    .samples
                    .iter()
                    .zip(m)
                    .map(|(s, &l)| s.area * law.pressure(law.argument(l, p.gap(s.position(&u), t))))
                    .sum()
            })
            .collect()
    }

    /// Records the step `run` just converged (at `run.t`, from `run.x`) with each plate's
    /// force there; returns those forces.
    pub(super) fn record_step<'a>(
        &self,
        run: &'a mut Progress,
        plates: &[RigidPlate],
        multipliers: &[Vec<f64>],
        augmentation: usize,
        iterations: usize,
        residuals: Vec<f64>,
    ) -> &'a [f64] {
        let plate_forces = self.plate_forces(&run.x, plates, multipliers, run.t);
        run.steps.push(LoadStep { load: run.t, augmentation, iterations, residuals, plate_forces });
        &run.steps[run.steps.len() - 1].plate_forces
    }

    /// `per_vertex` (one value per surface vertex) over each vertex's area (a third of its
    /// triangles' rest areas); zero where a vertex has no area.
    fn per_vertex_area(&self, mut per_vertex: Vec<f64>) -> Vec<f64> {
        let pos = self.model.grid.surface_positions();
        let mut area = vec![0.0; pos.len()];
        for t in self.model.grid.surface_triangles() {
            let c = t.map(|v| pos[v as usize]);
            let a = 0.5 * norm(cross(sub(c[1], c[0]), sub(c[2], c[0])));
            t.iter().for_each(|&v| area[v as usize] += a / 3.0);
        }
        for (f, a) in per_vertex.iter_mut().zip(area) {
            *f = if a > 0.0 { *f / a } else { 0.0 };
        }
        per_vertex
    }

    /// Uzawa's update of the contact pressures: `lambda <- max(0, lambda - beta g)`.
    fn augment(&self, x: &[f64], plates: &[RigidPlate], t: f64, multipliers: &mut [Vec<f64>]) {
        let u = self.node_field(x);
        let law = ContactTerm::law(&self.model);
        for (p, m) in plates.iter().zip(multipliers).filter(|(p, _)| p.force.is_none()) {
            for (s, lambda) in self.terms.contact.samples.iter().zip(m.iter_mut()) {
                *lambda = law.pressure(law.argument(*lambda, p.gap(s.position(&u), t)));
            }
        }
    }

    /// The total force the supports (the clamp's penalty and the eliminated degrees of
    /// freedom) put on the body at load factor `t`: the clamp's penalty forces on free
    /// dofs, plus at every fixed dof the internal force less the loads, grasps and
    /// contact acting there.
    pub(super) fn support_force(&self, x: &[f64], state: &LoadState<'_>, loads: &Loads) -> Vec3 {
        let u = self.node_field(x);
        let fixed = |n: usize, a: usize| self.model.free[3 * n + a] == FIXED;
        let mut r = [0.0; 3];
        for p in &self.terms.clamp.points {
            let d: f64 = (0..8).map(|b| p.weights[b] * u[p.nodes[b]][p.axis]).sum();
            for b in (0..8).filter(|&b| !fixed(p.nodes[b], p.axis)) {
                r[p.axis] -= self.terms.clamp.beta * p.area * d * p.weights[b];
            }
        }
        let node_volume = self.model.grid.cell_size().powi(3) / 8.0;
        for (c, nodes) in self.model.grid.cell_nodes().iter().enumerate() {
            let fill = self.model.grid.cell_fill(c);
            let local = nodes.map(|n| u[n]);
            let law_state = self.states.cell(c);
            let Some(t) =
                self.model.cell.tangent_with(&self.model.materials[c], &local, fill, false, law_state)
            else {
                continue;
            };
            for (l, g) in t.gradient.iter().enumerate() {
                let (n, a) = (nodes[l / 3], l % 3);
                if fixed(n, a) {
                    r[a] +=
                        g - state.t * fill.mean() * self.model.densities[c] * node_volume * loads.gravity[a];
                }
            }
        }
        let mut at_fixed = |nodes: &[usize; 8], weights: &[f64; 8], f: Vec3| {
            for b in 0..8 {
                (0..3).filter(|&a| fixed(nodes[b], a)).for_each(|a| r[a] -= weights[b] * f[a]);
            }
        };
        for &(v, f) in &loads.point_forces {
            if let Some(e) = self.model.grid.embedding().get(v) {
                at_fixed(&e.nodes, &e.weights, scale(f, state.t));
            }
        }
        let forces = self.terms.grasps.forces(&u, state.t, state.grasp_multipliers);
        for (p, f) in self.terms.grasps.points.iter().zip(&forces) {
            at_fixed(&p.nodes, &p.weights, scale(*f, -1.0));
        }
        let law = ContactTerm::law(&self.model);
        for (k, plate) in state.plates.iter().enumerate() {
            for (s, sample) in self.terms.contact.samples.iter().enumerate() {
                let lambda = state.multipliers[k][s];
                let pr = law.pressure(law.argument(lambda, plate.gap(sample.position(&u), state.t)));
                at_fixed(&sample.nodes, &sample.weights, scale(plate.normal, sample.area * pr));
            }
        }
        r
    }

    /// The solution record of a converged solve (`state` at the full load).
    pub(super) fn finish(&self, run: Progress, state: &LoadState<'_>, support_force: Vec3) -> HyperSolution {
        let (plates, multipliers) = (state.plates, state.multipliers);
        let u = self.node_field(&run.x);
        let law = ContactTerm::law(&self.model);
        let mut plate_forces = vec![0.0; plates.len()];
        let mut plate_contacts = vec![0; plates.len()];
        let mut contact_pressure = Vec::with_capacity(plates.len());
        let (triangles, surface) = (self.model.grid.surface_triangles(), self.model.grid.surface_positions());
        for (k, p) in plates.iter().enumerate() {
            let mut vertex_force = vec![0.0; surface.len()];
            for (s, sample) in self.terms.contact.samples.iter().enumerate() {
                let pr = law.pressure(law.argument(multipliers[k][s], p.gap(sample.position(&u), state.t)));
                plate_forces[k] += sample.area * pr;
                plate_contacts[k] += usize::from(pr > 0.0);
                let t = triangles[sample.triangle];
                let weights = barycentric(sample.rest, t.map(|v| surface[v as usize]));
                for (&v, w) in t.iter().zip(weights) {
                    vertex_force[v as usize] += w * sample.area * pr;
                }
            }
            contact_pressure.push(self.per_vertex_area(vertex_force));
        }
        let plate_penetration = self.deepest_penetration(&run.x, plates, run.t);
        let grasps = self.terms.grasps.records(&u, state.t, state.grasp_multipliers);
        let (cells, summary) = self.cell_states(&u);
        let residual = run.steps.last().and_then(|s| s.residuals.last().copied()).unwrap_or(0.0);
        let stats = run.final_stats();
        HyperSolution {
            surface_displacements: self.model.grid.interpolate(&u),
            node_displacements: u,
            residual,
            steps: run.steps,
            plate_forces,
            plate_contacts,
            plate_penetration,
            contact_pressure,
            grasps,
            support_force,
            cells,
            summary,
            stats,
        }
    }
}

impl HyperBody {
    /// The multigrid V-cycle's contraction on this body's tangent at rest: the mean
    /// factor by which each of `sweeps` stationary cycles shrinks the residual (see
    /// `fibfluid_linalg::multigrid::Multigrid::contraction`). A diagnostic of the
    /// hierarchy: below 1 the cycle converges alone, and conjugate gradients need about
    /// `ln(tolerance) / ln(contraction)` iterations at most.
    ///
    /// Errors: an inverted cell at rest (never for a valid body), a tangent that is not
    /// positive definite ([`FemError::NotPositiveDefinite`]).
    pub fn multigrid_contraction(&mut self, sweeps: usize) -> Result<f64> {
        let external = vec![0.0; self.model.n_free];
        let duals = Multipliers::zero(self.terms.contact.samples.len(), 0, self.terms.grasps.points.len());
        let x = vec![0.0; self.model.n_free];
        self.evaluate(&x, &duals.state(1.0, &external, &[]), true).ok_or(FemError::NotPositiveDefinite)?;
        let levels = crate::multigrid::GridLevels::new(&self.model.grid, &self.model.free);
        let multigrid = levels.hierarchy(self.stage.tangent.as_ref(), 0.0)?;
        Ok(multigrid.contraction(sweeps))
    }

    /// Levels of the multigrid hierarchy of this body's grid (the finest included).
    pub fn multigrid_levels(&self) -> usize {
        crate::multigrid::GridLevels::new(&self.model.grid, &self.model.free).nodes.len()
    }
}

/// The barycentric coordinates of `p` (in the triangle's plane) in the triangle `c`; equal
/// thirds for a degenerate triangle.
fn barycentric(p: Vec3, c: [Vec3; 3]) -> [f64; 3] {
    let n = cross(sub(c[1], c[0]), sub(c[2], c[0]));
    let twice = dot(n, n);
    if twice <= 0.0 {
        return [1.0 / 3.0; 3];
    }
    let w = |a: Vec3, b: Vec3| dot(n, cross(sub(a, p), sub(b, p))) / twice;
    [w(c[1], c[2]), w(c[2], c[0]), w(c[0], c[1])]
}
