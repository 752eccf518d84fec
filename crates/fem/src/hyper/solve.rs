//! The load stepping of a hyperelastic solve and its contact augmentations.

use fibfluid_geometry::Vec3;
use fibfluid_geometry::vec3::scale;
use fibfluid_linalg::SparseCholesky;

use super::body::{HyperBody, HyperSolution, HyperStats, LoadStep};

use super::contact::{CONTACT_FORCE_TOLERANCE, CONTACT_GAP_TOLERANCE, MAX_AUGMENTATIONS, RigidPlate};
use super::grasp::GRASP_TOLERANCE;
use super::grasp_kkt::GraspKkt;
use super::newton::LoadState;
use crate::assemble::FIXED;
use crate::body::Loads;
use crate::error::{FemError, NotConvergedWhy, Result};

/// The state of a solve between load steps.
struct Progress {
    x: Vec<f64>,
    t: f64,
    steps: Vec<LoadStep>,
    stats: HyperStats,
    factor: Option<SparseCholesky>,
}

impl HyperBody {
    /// The static large-deformation response to `loads` (dead loads, scaled by the load
    /// factor), the `plates` (moving with it) and the body's grasps (moving with it).
    ///
    /// Errors: a vertex out of range or a non-finite load or plate; a load step that
    /// cannot converge ([`FemError::NotConverged`], with the step, the load factor and the
    /// residual).
    pub fn solve(&mut self, loads: &Loads, plates: &[RigidPlate]) -> Result<HyperSolution> {
        if plates.iter().any(|p| p.start.iter().chain(&p.end).chain(&p.normal).any(|v| !v.is_finite())) {
            return Err(FemError::NonFinite { what: "plate" });
        }
        let external = self.external_loads(loads)?;
        let mut multipliers = vec![vec![0.0; self.samples.len()]; plates.len()];
        let mut held = vec![[0.0; 3]; self.grasps.points.len()];
        let mut run = Progress {
            x: vec![0.0; self.n_free],
            t: 0.0,
            steps: Vec::new(),
            stats: HyperStats::default(),
            factor: None,
        };
        let state = LoadState {
            t: 0.0,
            external: &external,
            plates,
            multipliers: &multipliers,
            grasp_multipliers: &held,
        };
        self.step_to_full_load(&mut run, &state)?;
        let mut force = self.plate_forces(&run.x, plates, &multipliers);
        // Contact is settled when nothing penetrates or the plate forces stopped changing.
        let mut contact_settled = false;
        let mut newton_tried = false;
        for augmentation in 1..=MAX_AUGMENTATIONS {
            let h = self.grid.cell_size();
            let shallow =
                self.deepest_penetration(&run.x, plates).iter().all(|&d| d <= CONTACT_GAP_TOLERANCE * h);
            let contact_done = shallow || contact_settled;
            let u = self.node_field(&run.x);
            let grasp_done = self.grasps.largest_error(&u) <= GRASP_TOLERANCE * h;
            if contact_done && grasp_done {
                break;
            }
            // With the contact settled, Newton's method meets the grasps (once: should it
            // fail, Uzawa's augmentations go on from where it started).
            if contact_done && !newton_tried {
                newton_tried = true;
                let saved = (run.x.clone(), held.clone(), run.stats.final_shift);
                let fixed = GraspKkt { external: &external, plates, multipliers: &multipliers };
                let mut history = Vec::new();
                let met = self.meet_grasps(
                    &mut run.x,
                    &fixed,
                    &mut held,
                    &mut run.factor,
                    &mut history,
                    &mut run.stats,
                );
                if let Some(iterations) = met {
                    run.stats.augmentations += 1;
                    run.steps.push(LoadStep { load: 1.0, augmentation, iterations, residuals: history });
                    continue;
                }
                (run.x, held, run.stats.final_shift) = saved;
            }
            let before = (run.x.clone(), multipliers.clone(), held.clone());
            if !contact_done {
                self.augment(&run.x, plates, &mut multipliers);
            }
            if !grasp_done {
                self.grasps.augment(&u, &mut held);
            }
            let state = LoadState {
                t: 1.0,
                external: &external,
                plates,
                multipliers: &multipliers,
                grasp_multipliers: &held,
            };
            let mut history = Vec::new();
            match self.newton(&mut run.x, &state, &mut run.factor, &mut history, &mut run.stats)? {
                Ok(iterations) => {
                    run.stats.augmentations += 1;
                    run.steps.push(LoadStep { load: 1.0, augmentation, iterations, residuals: history });
                    let next = self.plate_forces(&run.x, plates, &multipliers);
                    let change = next.iter().zip(&force).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
                    let largest = next.iter().fold(0.0_f64, |m, f| m.max(f.abs()));
                    force = next;
                    if !contact_done {
                        contact_settled = change <= CONTACT_FORCE_TOLERANCE * largest;
                    }
                }
                Err(f) if !contact_done => {
                    return Err(FemError::NotConverged {
                        step: run.steps.len() + 1,
                        load: 1.0,
                        residual: f.residual,
                        why: self.failure_why(&run.x, &f),
                    });
                }
                Err(_) => {
                    // Only the grasps were left to meet: the last converged state stands
                    // (the load stepping's, or an earlier augmentation's), its grasps met as
                    // far as its record says (each grasp's error is reported, and guarded by
                    // the `grasp` result guard).
                    (run.x, multipliers, held) = before;
                    run.stats.failed_augmentations += 1;
                    break;
                }
            }
        }
        let state = LoadState {
            t: 1.0,
            external: &external,
            plates,
            multipliers: &multipliers,
            grasp_multipliers: &held,
        };
        let support_force = self.support_force(&run.x, &state, loads);
        Ok(self.finish(run, &state, support_force))
    }

    /// Load steps from 0 to 1: an increment halves when Newton fails and doubles after an
    /// easy step.
    fn step_to_full_load(&mut self, run: &mut Progress, base: &LoadState<'_>) -> Result<()> {
        let mut increment = self.settings.first_increment.clamp(self.settings.min_increment, 1.0);
        // The last converged increment (load and displacement), for the secant predictor.
        let mut last: Option<(f64, Vec<f64>)> = None;
        while run.t < 1.0 {
            let target = (run.t + increment).min(1.0);
            let state = LoadState { t: target, ..*base };
            let mut trial = self.predict(&run.x, last.as_ref(), target - run.t, &state);
            let mut history = Vec::new();
            match self.newton(&mut trial, &state, &mut run.factor, &mut history, &mut run.stats)? {
                Ok(iterations) => {
                    let step: Vec<f64> = trial.iter().zip(&run.x).map(|(a, b)| a - b).collect();
                    last = Some((target - run.t, step));
                    run.x = trial;
                    run.t = target;
                    run.stats.load_steps += 1;
                    run.steps.push(LoadStep {
                        load: target,
                        augmentation: 0,
                        iterations,
                        residuals: history,
                    });
                    if iterations <= self.settings.easy_iterations {
                        increment = (2.0 * increment).min(1.0);
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

    /// Per plate, the deepest penetration (m, 0 when none) at the full load.
    fn deepest_penetration(&self, x: &[f64], plates: &[RigidPlate]) -> Vec<f64> {
        let u = self.node_field(x);
        plates
            .iter()
            .map(|p| self.samples.iter().map(|s| -p.gap(s.position(&u), 1.0)).fold(0.0, f64::max))
            .collect()
    }

    /// Per plate, the contact force on the body along its normal (N) at the full load.
    fn plate_forces(&self, x: &[f64], plates: &[RigidPlate], multipliers: &[Vec<f64>]) -> Vec<f64> {
        let u = self.node_field(x);
        let law = self.contact_law();
        plates
            .iter()
            .zip(multipliers)
            .map(|(p, m)| {
                self.samples
                    .iter()
                    .zip(m)
                    .map(|(s, &l)| s.area * law.pressure(law.argument(l, p.gap(s.position(&u), 1.0))))
                    .sum()
            })
            .collect()
    }

    /// Uzawa's update of the contact pressures: `lambda <- max(0, lambda - beta g)`.
    fn augment(&self, x: &[f64], plates: &[RigidPlate], multipliers: &mut [Vec<f64>]) {
        let u = self.node_field(x);
        let law = self.contact_law();
        for (p, m) in plates.iter().zip(multipliers) {
            for (s, lambda) in self.samples.iter().zip(m.iter_mut()) {
                *lambda = law.pressure(law.argument(*lambda, p.gap(s.position(&u), 1.0)));
            }
        }
    }

    /// The total force the supports (the clamp's penalty and the eliminated degrees of
    /// freedom) put on the body at load factor `t`: the clamp's penalty forces on free
    /// dofs, plus at every fixed dof the internal force less the loads, grasps and
    /// contact acting there.
    fn support_force(&self, x: &[f64], state: &LoadState<'_>, loads: &Loads) -> Vec3 {
        let u = self.node_field(x);
        let fixed = |n: usize, a: usize| self.free[3 * n + a] == FIXED;
        let mut r = [0.0; 3];
        for p in &self.clamp {
            let d: f64 = (0..8).map(|b| p.weights[b] * u[p.nodes[b]][p.axis]).sum();
            for b in (0..8).filter(|&b| !fixed(p.nodes[b], p.axis)) {
                r[p.axis] -= self.clamp_beta * p.area * d * p.weights[b];
            }
        }
        let node_volume = self.grid.cell_size().powi(3) / 8.0;
        for (c, nodes) in self.grid.cell_nodes().iter().enumerate() {
            let fill = self.grid.fill()[c];
            let local = nodes.map(|n| u[n]);
            let law_state = self.states.cell(c);
            let Some(t) = self.cell.tangent_with(&self.materials[c], &local, fill, false, law_state) else {
                continue;
            };
            for (l, g) in t.gradient.iter().enumerate() {
                let (n, a) = (nodes[l / 3], l % 3);
                if fixed(n, a) {
                    r[a] += g - state.t * fill * self.densities[c] * node_volume * loads.gravity[a];
                }
            }
        }
        let mut at_fixed = |nodes: &[usize; 8], weights: &[f64; 8], f: Vec3| {
            for b in 0..8 {
                (0..3).filter(|&a| fixed(nodes[b], a)).for_each(|a| r[a] -= weights[b] * f[a]);
            }
        };
        for &(v, f) in &loads.point_forces {
            if let Some(e) = self.grid.embedding().get(v) {
                at_fixed(&e.nodes, &e.weights, scale(f, state.t));
            }
        }
        let forces = self.grasps.forces(&u, state.t, state.grasp_multipliers);
        for (p, f) in self.grasps.points.iter().zip(&forces) {
            at_fixed(&p.nodes, &p.weights, scale(*f, -1.0));
        }
        let law = self.contact_law();
        for (k, plate) in state.plates.iter().enumerate() {
            for (s, sample) in self.samples.iter().enumerate() {
                let lambda = state.multipliers[k][s];
                let pr = law.pressure(law.argument(lambda, plate.gap(sample.position(&u), state.t)));
                at_fixed(&sample.nodes, &sample.weights, scale(plate.normal, sample.area * pr));
            }
        }
        r
    }

    /// The solution record of a converged solve (`state` at the full load).
    fn finish(&self, run: Progress, state: &LoadState<'_>, support_force: Vec3) -> HyperSolution {
        let (plates, multipliers) = (state.plates, state.multipliers);
        let u = self.node_field(&run.x);
        let law = self.contact_law();
        let mut plate_forces = vec![0.0; plates.len()];
        let mut plate_contacts = vec![0; plates.len()];
        for (k, p) in plates.iter().enumerate() {
            for (s, sample) in self.samples.iter().enumerate() {
                let pr = law.pressure(law.argument(multipliers[k][s], p.gap(sample.position(&u), 1.0)));
                plate_forces[k] += sample.area * pr;
                plate_contacts[k] += usize::from(pr > 0.0);
            }
        }
        let plate_penetration = self.deepest_penetration(&run.x, plates);
        let grasps = self.grasps.records(&u, state.grasp_multipliers);
        let (cells, summary) = self.cell_states(&u);
        let residual = run.steps.last().and_then(|s| s.residuals.last().copied()).unwrap_or(0.0);
        HyperSolution {
            surface_displacements: self.grid.interpolate(&u),
            node_displacements: u,
            residual,
            steps: run.steps,
            plate_forces,
            plate_contacts,
            plate_penetration,
            grasps,
            support_force,
            cells,
            summary,
            stats: run.stats,
        }
    }
}
