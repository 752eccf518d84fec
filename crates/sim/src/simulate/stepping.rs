//! Load steps: fixed and adaptive, with guards after each step.

use fibfluid_geometry::Vec3;
use fibfluid_geometry::vec3::{add, norm, scale, sub};

use super::core::Simulation;
use super::state::*;
use crate::choices::{ForceTiming, Mode, Stepping};
use crate::contact::MAX_ACTIVE_SET_ITERATIONS;
use crate::guards::{Guard, GuardWarning, OnFailure, inverted_faces};
use crate::stages::names;
use crate::{Error, Result};

impl Simulation {
    /// Runs the scene's loads to full: `steps` equal steps, or adaptive steps when the
    /// scene sets a `tolerance`.
    pub fn run(&mut self, opts: &RunOptions) -> Result<()> {
        match self.model.load.tolerance {
            Some(tolerance) => self.adaptive(Direction::Load, tolerance, opts),
            None => self.run_steps(self.model.load.steps, Direction::Load, opts),
        }
    }

    /// Runs `steps` equal load steps in one direction.
    pub fn run_steps(&mut self, steps: usize, direction: Direction, opts: &RunOptions) -> Result<()> {
        for k in 0..steps {
            if opts.cancelled() {
                return Err(Error::Cancelled { load_factor: self.state.load_factor });
            }
            let done = (k + 1) as f64 / steps as f64;
            let to = match direction {
                Direction::Load => done,
                Direction::Unload => 1.0 - done,
            };
            self.step_load(to)?;
            if let Some(p) = &opts.progress {
                p(k + 1, steps);
            }
        }
        Ok(())
    }

    /// One load step: takes the load factor from its current value to `to` (1 = the
    /// scene's full load). Gravity, ramped forces and prescribed displacements change by
    /// `to - from` of their full value; forces applied at the last step act while the
    /// factor is 1. A step whose load does not change needs no solve: it is skipped
    /// and counted ([`StepStats::skipped`]). The guards are checked after the step.
    pub fn step_load(&mut self, to: f64) -> Result<()> {
        let from = self.state.load_factor;
        let last_to = if to >= 1.0 { 1.0 } else { 0.0 };
        let inc = self.increment(to - from, last_to - self.state.last_forces, to, last_to);
        self.take_step(&inc, false).map(|_| ())
    }

    /// Removes the loads again: the reverse of [`run`](Self::run), with the same kind of
    /// steps (equal ones, or adaptive ones when the scene sets a `tolerance`).
    pub fn unload(&mut self, opts: &RunOptions) -> Result<()> {
        match self.model.load.tolerance {
            Some(tolerance) => self.adaptive(Direction::Unload, tolerance, opts),
            None => self.run_steps(self.model.load.steps, Direction::Unload, opts),
        }
    }

    /// Adaptive load steps (`[load] tolerance`) in one direction: each step is evaluated
    /// with Euler and Heun (an embedded pair); their difference estimates the step's
    /// error, which must stay below `tolerance` times the body's size (the bounding-box
    /// diagonal). The step taken is Heun's, whatever `stepping` says (local
    /// extrapolation: the estimate bounds the Euler error, so it is conservative for
    /// Heun). A rejected step is undone, halved and retried; an accepted one sets the next
    /// size from the estimate (`h * 0.9 sqrt(tol / est)`, between half and double).
    /// Loading ramps gravity, ramped forces and prescribed displacements first, then the
    /// forces the scene applies at the last step in a second phase, so their effect is
    /// controlled too; unloading runs the phases backwards.
    pub fn run_adaptive(&mut self, tolerance: f64, opts: &RunOptions) -> Result<()> {
        self.adaptive(Direction::Load, tolerance, opts)
    }

    pub(super) fn adaptive(&mut self, direction: Direction, tolerance: f64, opts: &RunOptions) -> Result<()> {
        #[derive(Clone, Copy, PartialEq)]
        enum Phase {
            Ramp,
            Last,
        }
        let has_last = self.model.load.forces.iter().any(|f| f.timing == ForceTiming::Last);
        let (sign, phases) = match (direction, has_last) {
            (Direction::Load, true) => (1.0, vec![Phase::Ramp, Phase::Last]),
            (Direction::Unload, true) => (-1.0, vec![Phase::Last, Phase::Ramp]),
            (Direction::Load, false) => (1.0, vec![Phase::Ramp]),
            (Direction::Unload, false) => (-1.0, vec![Phase::Ramp]),
        };
        let count = phases.len();
        let mut h = 1.0 / self.model.load.steps.max(1) as f64;
        for (k, phase) in phases.into_iter().enumerate() {
            let (lambda0, last0) = (self.state.load_factor, self.state.last_forces);
            let mut done = 0.0;
            while done < 1.0 {
                if opts.cancelled() {
                    return Err(Error::Cancelled { load_factor: self.state.load_factor });
                }
                h = h.min(1.0 - done);
                if h < MIN_ADAPTIVE_STEP {
                    return Err(Error::StepTooSmall { load_factor: self.state.load_factor, tolerance });
                }
                let next = if 1.0 - (done + h) < 1e-12 { 1.0 } else { done + h };
                let inc = match phase {
                    Phase::Ramp => self.increment(sign * h, 0.0, lambda0 + sign * next, last0),
                    Phase::Last => Increment {
                        da: [0.0; 3],
                        forces: self.last_forces(sign * h),
                        prescribed: 0.0,
                        to: lambda0,
                        last_to: last0 + sign * next,
                    },
                };
                let saved = (
                    self.state.clone(),
                    self.stats.clone(),
                    self.warnings.len(),
                    self.contact.records.clone(),
                );
                let outcome = self.take_step(&inc, true)?;
                let estimate = outcome.estimate.unwrap_or(0.0);
                let allowed = tolerance * self.body.diagonal;
                if estimate <= allowed {
                    done = next;
                    self.stats.error_estimate += estimate;
                    let grow = if estimate > 0.0 { 0.9 * (allowed / estimate).sqrt() } else { 2.0 };
                    h *= grow.clamp(0.5, 2.0);
                    if let Some(p) = &opts.progress {
                        p(((k as f64 + done) * 1000.0) as usize, 1000 * count);
                    }
                } else {
                    self.state = saved.0;
                    self.stats = saved.1;
                    self.warnings.truncate(saved.2);
                    // A rejected step leaves no plate record either.
                    self.contact.records = saved.3;
                    self.stats.rejected += 1;
                    h *= 0.5;
                }
            }
        }
        Ok(())
    }

    /// The increments of one fixed step: `ramp` of gravity, ramped forces and
    /// prescribed displacements, `last` of the forces applied at the last step.
    pub(super) fn increment(&self, ramp: f64, last: f64, to: f64, last_to: f64) -> Increment {
        let forces = self
            .model
            .load
            .forces
            .iter()
            .filter_map(|f| {
                let k = match f.timing {
                    ForceTiming::Ramp => ramp,
                    ForceTiming::Last => last,
                };
                (k != 0.0).then(|| (f.vertex, scale(f.value, k)))
            })
            .collect();
        Increment { da: scale(self.model.load.gravity, ramp), forces, prescribed: ramp, to, last_to }
    }

    pub(super) fn last_forces(&self, fraction: f64) -> Vec<(usize, Vec3)> {
        self.model
            .load
            .forces
            .iter()
            .filter(|f| f.timing == ForceTiming::Last)
            .map(|f| (f.vertex, scale(f.value, fraction)))
            .collect()
    }

    /// Takes one step of increments `inc` (with the Euler/Heun error estimate when
    /// `estimate`), then checks the guards. With plates, the step is repeated until its
    /// contact active set is stable. Numeric failures are explained.
    pub(super) fn take_step(&mut self, inc: &Increment, estimate: bool) -> Result<StepOutcome> {
        let step = self.stats.taken + 1;
        let from = self.state.load_factor;
        let moves_prescribed = inc.prescribed != 0.0 && self.model.constraints.has_nonzero();
        let acts = inc.da != [0.0; 3] && self.model.material.density() > 0.0;
        let plates_move = from != inc.to && self.model.plates.iter().any(|p| p.travel != 0.0);
        if !acts && inc.forces.is_empty() && !moves_prescribed && !plates_move {
            self.state.load_factor = inc.to;
            self.state.last_forces = inc.last_to;
            self.stats.skipped += 1;
            return Ok(StepOutcome { estimate: Some(0.0) });
        }
        let before = self.state.clone();
        let n = before.positions.len();
        let explained = |e| explain(e, step, from, inc.to, n);
        let mut active = before.contacts.clone();
        let mut released: Vec<(usize, Vec3)> = vec![];
        let mut iterations = 0;
        let (est, step_residual) = loop {
            iterations += 1;
            self.state = before.clone();
            let mut inc_here = inc.clone();
            inc_here.forces.extend_from_slice(&released);
            self.set_contacts(&active, inc.to);
            let residual_before = self.counters.residual_max;
            self.counters.residual_max = 0.0;
            let result = self.evaluate(&inc_here, estimate);
            let step_residual = self.counters.residual_max;
            self.counters.residual_max = residual_before.max(step_residual);
            let Evaluation { du, dp, estimate: est } = result.map_err(explained)?;
            self.log.time(names::UPDATE, || {
                for (p, d) in self.state.positions.iter_mut().zip(&du) {
                    *p = add(*p, *d);
                }
            });
            self.state.pressure += dp;
            self.state.load_factor = inc.to;
            self.state.last_forces = inc.last_to;
            if self.model.solver.mode != Mode::Paper {
                self.correct_volume().map_err(explained)?;
            }
            if self.model.plates.is_empty() {
                break (est, step_residual);
            }
            // The contacts' forces are those of the state this iteration reached: a
            // rejected iteration leaves nothing behind.
            self.contact_forces(&mut active).map_err(explained)?;
            let (changed, next, newly_released) = self.update_active_set(&active, inc.to);
            if !changed {
                self.state.contacts = active;
                break (est, step_residual);
            }
            if iterations >= MAX_ACTIVE_SET_ITERATIONS {
                return Err(Error::ContactNotConverged { step, iterations });
            }
            // Released contacts stop pushing: their force before the step is taken off.
            for (plate, vertex) in newly_released {
                if let Some(c) = before.contacts.iter().find(|c| c.plate == plate && c.vertex == vertex) {
                    released.push((vertex, scale(self.model.plates[plate].normal, -c.force)));
                }
            }
            active = next;
        };
        self.stats.taken += 1;
        if !self.model.plates.is_empty() {
            self.record_plates(iterations);
        }
        let increment = self
            .state
            .positions
            .iter()
            .zip(&before.positions)
            .map(|(p, q)| norm(sub(*p, *q)))
            .fold(0.0, f64::max);
        self.check_guards(step, increment, step_residual)?;
        Ok(StepOutcome { estimate: est })
    }

    /// The guards after step `step`; with `on_failure = "error"` the first one that fires
    /// is returned as an error.
    pub(super) fn check_guards(&mut self, step: usize, increment: f64, residual: f64) -> Result<()> {
        let mode = self.model.solver.mode;
        let guards = self.model.guards;
        let volume = (self.volume() / self.body.volume0 - 1.0).abs();
        let inverted = inverted_faces(&self.body.boundary, &self.body.rest, &self.state.positions) as f64;
        let measured = [
            (Guard::Volume, volume),
            (Guard::Increment, increment / self.body.diagonal),
            (Guard::Inverted, inverted),
            (Guard::Residual, residual),
        ];
        for (guard, value) in measured {
            let limit = guards.limit(guard, mode);
            if !(value <= limit) {
                let w = GuardWarning { step, guard, value, limit };
                if guards.on_failure == OnFailure::Error {
                    return Err(Error::Guard(w));
                }
                self.warnings.push(w);
            }
        }
        Ok(())
    }

    /// Evaluates a step from the current shape: the displacement and pressure increments
    /// of the stepping scheme and, when asked, the Euler/Heun difference (largest vertex
    /// distance) that estimates the step's error.
    pub(super) fn evaluate(&mut self, inc: &Increment, estimate: bool) -> Result<Evaluation> {
        let s = self.state.positions.clone();
        let target = self.prepare_operator(&s)?;
        let b1 = self.load_increment(&s, inc.da, &inc.forces)?;
        if self.model.solver.stepping == Stepping::Euler && !estimate {
            let x = self.solve(&b1, target, inc.prescribed, true)?;
            let (u, p) = self.factored.split(&x);
            return Ok(Evaluation { du: u, dp: p, estimate: None });
        }
        let xb = self.solve(&b1, 0.0, inc.prescribed, true)?;
        let (ub, pb) = self.factored.split(&xb);
        let (ut, pt) = if target != 0.0 {
            let zero = vec![0.0; b1.len()];
            let xt = self.solve(&zero, target, 0.0, false)?;
            self.factored.split(&xt)
        } else {
            (vec![[0.0; 3]; s.len()], 0.0)
        };
        let predicted: Vec<Vec3> = (0..s.len()).map(|i| add(add(s[i], ub[i]), ut[i])).collect();
        let open = self.log.begin(names::PREDICTOR);
        let corrected = self.prepare_operator(&predicted).and_then(|_| {
            let b2 = self.load_increment(&predicted, inc.da, &inc.forces)?;
            self.solve(&b2, 0.0, inc.prescribed, true)
        });
        self.log.end(open);
        let x2 = corrected?;
        let (u2, p2) = self.factored.split(&x2);
        // Heun minus Euler: half the difference of the two slopes.
        let est =
            estimate.then(|| ub.iter().zip(&u2).map(|(a, b)| 0.5 * norm(sub(*b, *a))).fold(0.0, f64::max));
        let u = (0..s.len()).map(|i| add(scale(add(ub[i], u2[i]), 0.5), ut[i])).collect();
        Ok(Evaluation { du: u, dp: 0.5 * (pb + p2) + pt, estimate: est })
    }
}

/// Puts a numeric failure of step `step` in the user's terms: the likely cause and what
/// to try.
pub(super) fn explain(e: Error, step: usize, from: f64, to: f64, n: usize) -> Error {
    use fibfluid_linalg::LinalgError as L;
    let soft = "the body may have folded or collapsed under this load (material too soft, or steps too large): raise fiber_modulus, take more load steps, or set [load] tolerance";
    let (cause, hint): (String, &'static str) = match &e {
        Error::Linalg(L::NonFiniteRhs { index }) | Error::Linalg(L::NonFiniteSolution { index }) => {
            (format!("a non-finite value at {}", unknown(*index, n)), soft)
        }
        Error::Linalg(L::NonFinite { row, .. }) => {
            (format!("a non-finite stiffness at {}", unknown(*row, n)), soft)
        }
        Error::Assembly(fibfluid_assembly::AssemblyError::CoincidentVertices { i, j, .. }) => {
            (format!("vertices {i} and {j} met"), soft)
        }
        Error::Linalg(L::NotPositiveDefinite { index, axis }) => (
            format!(
                "the stiffness is not positive definite at vertex {index} along {}",
                fibfluid_geometry::AXES[*axis % 3]
            ),
            "a vertex may be left free, or the deformed shape is degenerate: check the [[fix]] tables, or take smaller steps",
        ),
        Error::Linalg(L::SingularPivot { index, .. }) => (
            format!("a zero pivot at {}", unknown(*index, n)),
            "a vertex may be left free (add a [[fix]]), or a step is too large",
        ),
        Error::Linalg(L::ResidualTooLarge { .. }) => (
            "the solve did not reach its accuracy".into(),
            "the system is ill-conditioned: use constraints = \"eliminate\" and precision = \"f64\"",
        ),
        _ => return e,
    };
    Error::Step { step, from, to, cause, hint, source: Box::new(e) }
}

/// An unknown of the bordered system, named: `vertex 12 (y)` or `the pressure`.
pub(super) fn unknown(index: usize, n: usize) -> String {
    if n == 0 || index >= 3 * n {
        return "the pressure".into();
    }
    format!("vertex {} ({})", index % n, fibfluid_geometry::AXES[index / n])
}
