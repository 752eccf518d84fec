//! Time: a hyperelastic body stepped through a load history, quasi-statically (each step
//! an equilibrium, the laws' state carried between steps: viscoelastic relaxation and
//! creep) or with inertia (Newmark's average acceleration, `beta = 1/4`, `gamma = 1/2`:
//! unconditionally stable and without numerical damping, so an undamped linear body keeps
//! its energy), with Rayleigh damping `C = a_m M + a_k K_0` (`M` the lumped mass, `K_0`
//! the tangent at rest).
//!
//! Each step is a minimization, so the Newton solver, its line search and its
//! augmentations serve it unchanged: the inertia and damping enter as one more force term
//! ([`DynamicsTerm`]) whose energy is
//!
//! ```text
//! 1 / (2 beta h^2) (x - x~)' M (x - x~) + 1 / h (x - x_n)' C (x - x_n) - (C v_n)' x,
//! x~ = x_n + h v_n + h^2 (1/2 - beta) a_n
//! ```
//!
//! (`h` the step), whose gradient is `M a_n+1 + C v_n+1` with Newmark's updates. The load
//! factor of every load the static solve ramps (gravity, forces, plate travel, grasp
//! motion) follows a piecewise-linear [`LoadCurve`]. A step whose Newton solve fails is
//! halved, down to 1/1024 of the largest step, then reported with its time.

use fibfluid_geometry::Vec3;

use super::body::{HyperBody, HyperSolution};
use super::cell::CellState;
use super::contact::{MAX_AUGMENTATIONS, RigidPlate, check_plates};
use super::dynamics::DynamicsTerm;
use super::plate_drive::PlateDrive;
use super::solve::{Augmenting, Multipliers, Progress};
use super::terms::LoadState;
use crate::assemble::FIXED;
use crate::body::Loads;
use crate::error::{FemError, Result};
use crate::grid::SparseGrid;

/// Newmark's `beta` (average acceleration).
const BETA: f64 = 0.25;
/// Newmark's `gamma` (average acceleration).
const GAMMA: f64 = 0.5;
/// The smallest step, as a fraction of the largest, before a failing step is reported.
const MIN_STEP_FRACTION: f64 = 1.0 / 1024.0;
/// Times closer than this fraction of the largest step are the same time.
const TIME_ROUNDING: f64 = 1e-9;
/// The step length the laws are asked at when a state is reported (s): too short to
/// relax anything, so a viscoelastic law answers with its stress now, its history
/// included (a step of 0 asks for the instantaneous elastic response instead).
const NOW: f64 = 1e-300;

/// A piecewise-linear load factor over time: `(time s, factor)` points, times increasing;
/// constant before the first point and after the last.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadCurve {
    points: Vec<(f64, f64)>,
}

impl LoadCurve {
    /// A validated curve.
    ///
    /// Errors ([`FemError::InvalidTime`]): no point, a non-finite value, times not
    /// strictly increasing.
    pub fn new(points: Vec<(f64, f64)>) -> Result<Self> {
        let bad = |reason: String| Err(FemError::InvalidTime { reason });
        if points.is_empty() {
            return bad("the load curve has no point".into());
        }
        if let Some(k) = points.iter().position(|(t, f)| !(t.is_finite() && f.is_finite())) {
            return bad(format!("load curve point {} is not finite", k + 1));
        }
        if let Some(k) = points.windows(2).position(|w| w[1].0 <= w[0].0) {
            return bad(format!("load curve point {}: its time does not follow the one before", k + 2));
        }
        Ok(Self { points })
    }

    /// The ramp from 0 at `t = 0` to 1 at `end` (the curve of a scene that gives none).
    pub fn ramp(end: f64) -> Result<Self> {
        Self::new(vec![(0.0, 0.0), (end, 1.0)])
    }

    /// The factor at time `t`.
    pub fn factor(&self, t: f64) -> f64 {
        let (first, last) = (self.points[0], self.points[self.points.len() - 1]);
        if t <= first.0 {
            return first.1;
        }
        if t >= last.0 {
            return last.1;
        }
        let k = self.points.partition_point(|p| p.0 <= t);
        let ((t0, f0), (t1, f1)) = (self.points[k - 1], self.points[k]);
        f0 + (f1 - f0) * (t - t0) / (t1 - t0)
    }

    /// The curve's points.
    pub fn points(&self) -> &[(f64, f64)] {
        &self.points
    }
}

/// How a timed solve steps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimeSettings {
    /// The end time, s.
    pub end: f64,
    /// The largest step, s (steps are cut when Newton fails and grow back after easy ones).
    pub step: f64,
    /// Dynamics (mass from density, Newmark's average acceleration); `false`:
    /// quasi-static in time.
    pub inertia: bool,
    /// Rayleigh damping `[a_m (1/s), a_k (s)]`: `C = a_m M + a_k K_0`.
    pub damping: [f64; 2],
    /// Output every this many seconds (a sample at each multiple, and at the end).
    pub output_every: f64,
}

impl TimeSettings {
    /// Checks the settings.
    ///
    /// Errors ([`FemError::InvalidTime`]): a non-finite or non-positive end, step or
    /// output interval, a step longer than the run, negative damping.
    pub fn validate(&self) -> Result<()> {
        let bad = |reason: String| Err(FemError::InvalidTime { reason });
        for (name, v) in [("end", self.end), ("step", self.step), ("output_every", self.output_every)] {
            if !(v.is_finite() && v > 0.0) {
                return bad(format!("{name} = {v} s must be finite and > 0"));
            }
        }
        if self.step > self.end {
            return bad(format!("step = {} s is longer than the run (end = {} s)", self.step, self.end));
        }
        if self.damping.iter().any(|d| !(d.is_finite() && *d >= 0.0)) {
            return bad(format!("damping = {:?} must be finite and >= 0", self.damping));
        }
        Ok(())
    }

    /// Steps the run takes at least (the end over the largest step, rounded up).
    pub fn min_steps(&self) -> usize {
        (self.end / self.step - TIME_ROUNDING).ceil().max(1.0) as usize
    }

    /// The samples a run makes: one at `t = 0`, one at each multiple of `output_every`
    /// before the end, one at the end.
    pub fn outputs(&self) -> usize {
        let eps = TIME_ROUNDING * self.step;
        let mut count = 2;
        let mut next = self.output_every;
        while self.end - next > eps {
            count += 1;
            next += self.output_every;
        }
        count
    }

    /// The steps a run along `curve` takes when no step is cut: the largest step, ended
    /// early on each output time and each point of the curve (as the solve steps).
    pub fn planned_steps(&self, curve: &LoadCurve) -> usize {
        let mut clock =
            Clock { time: 0.0, step: self.step, steps: 0, cut: 0, next_output: self.output_every };
        while !clock.finished(self) {
            let to = clock.next_time(self, curve);
            clock.advance(to, self);
            if (to - clock.next_output).abs() <= TIME_ROUNDING * self.step {
                clock.next_output += self.output_every;
            }
        }
        clock.steps
    }
}

/// The state of a timed solve at one output time.
#[derive(Debug, Clone, PartialEq)]
pub struct TimeSample {
    /// Time, s.
    pub time: f64,
    /// The load factor then.
    pub load: f64,
    /// The largest surface displacement, m.
    pub max_displacement: f64,
    /// The volume the deformed surface encloses, m^3.
    pub volume: f64,
    /// Kinetic energy `v' M v / 2`, J (0 without inertia).
    pub kinetic_energy: f64,
    /// The elastic energy stored in the tissue (its laws' instantaneous response), J.
    pub strain_energy: f64,
    /// Per plate, the contact force on the body along its normal, N.
    pub plate_forces: Vec<f64>,
    /// Per grasp, the force the tissue exerts on the grasper, N.
    pub grasp_forces: Vec<Vec3>,
    /// Displacement of every surface vertex, m.
    pub surface_displacements: Vec<Vec3>,
    /// Steps taken to reach it.
    pub steps: usize,
    /// Steps cut (after a failed Newton solve) on the way.
    pub cut_steps: usize,
}

/// The whole body at an output time, handed to a timed solve's observer beside the sample
/// and not kept: a [`TimeSolution`] keeps the surface only, so an observer that writes
/// each state as it comes keeps memory bounded however many outputs a run makes.
#[derive(Debug, Clone, Copy)]
pub struct TimeFields<'a> {
    /// The grid.
    pub grid: &'a SparseGrid,
    /// Each cell's region id (0: the body's tissue, `k`: the `k`-th region).
    pub region_ids: &'a [u16],
    /// Displacement of every grid node, m.
    pub node_displacements: &'a [Vec3],
    /// Each cell's strain, `J` and stress (its law's, its history included), Pa.
    pub cells: &'a [CellState],
}

/// A timed solve's record: its samples and the final state as a static solve reports it.
#[derive(Debug, Clone, PartialEq)]
pub struct TimeSolution {
    /// One sample per output time (the first at `t = 0`).
    pub samples: Vec<TimeSample>,
    /// The state at the end.
    pub last: HyperSolution,
    /// Steps taken.
    pub steps: usize,
    /// Steps cut after a failed Newton solve.
    pub cut_steps: usize,
}

/// Newmark's kinematics between steps (free dofs).
struct Motion {
    velocity: Vec<f64>,
    acceleration: Vec<f64>,
}

impl HyperBody {
    /// The lumped mass of each free dof: each cell's `fill rho h^3` shared by its 8 nodes.
    fn lumped_mass(&self) -> Vec<f64> {
        let model = &*self.model;
        let share = model.grid.cell_size().powi(3) / 8.0;
        let mut mass = vec![0.0; model.n_free];
        for (c, nodes) in model.grid.cell_nodes().iter().enumerate() {
            let m = share * model.grid.fill()[c] * model.densities[c];
            for d in model.cell_dofs(nodes) {
                if d != FIXED {
                    mass[d] += m;
                }
            }
        }
        mass
    }

    /// The static large-deformation response stepped through time: `loads`, `plates` and
    /// the body's grasps scaled by `curve`'s factor, the laws' state carried between steps
    /// (see the module docs). `on_sample` sees each sample as it is made, with the whole
    /// body then ([`TimeFields`]: for progress, and to write each state as it comes).
    ///
    /// Errors: invalid settings ([`FemError::InvalidTime`]); inertia on a body without mass;
    /// a step that cannot converge even at the smallest step ([`FemError::NotConverged`],
    /// its `load` the load factor, its `step` the step count); those of
    /// [`HyperBody::solve`].
    pub fn solve_in_time(
        &mut self,
        loads: &Loads,
        plates: &[RigidPlate],
        settings: &TimeSettings,
        curve: &LoadCurve,
        on_sample: &mut dyn FnMut(&TimeSample, &TimeFields<'_>),
    ) -> Result<TimeSolution> {
        settings.validate()?;
        check_plates(plates)?;
        let external = self.external_loads(loads)?;
        let mass = self.lumped_mass();
        if settings.inertia && !mass.iter().any(|&m| m > 0.0) {
            return Err(FemError::InvalidTime { reason: "inertia needs a tissue density > 0".into() });
        }
        let mut duals =
            Multipliers::zero(self.terms.contact.samples.len(), plates.len(), self.terms.grasps.points.len());
        let solver = self.stage.linear_solver(&self.model, self.settings.solver)?;
        let mut run = Progress::at(self.model.n_free, curve.factor(0.0), solver);
        let mut drive = PlateDrive::new(plates);
        let mut motion = Motion { velocity: vec![0.0; mass.len()], acceleration: vec![0.0; mass.len()] };
        if settings.inertia {
            motion.acceleration = self.initial_acceleration(
                &run.x,
                &duals.state(run.t, &external, &drive.place(plates)),
                &mass,
            );
        }
        let mut clock =
            Clock { time: 0.0, step: settings.step, steps: 0, cut: 0, next_output: settings.output_every };
        let mut samples = vec![self.sample(0.0, &run, &duals, &drive.place(plates), &motion, &mass, &clock)];
        self.observe(&samples[0], &run.x, on_sample);
        while settings.end - clock.time > TIME_ROUNDING * settings.step {
            let to = clock.next_time(settings, curve);
            let h = to - clock.time;
            run.t = curve.factor(to);
            self.states.set_dt(h);
            self.terms.dynamics = self.dynamics_term(settings, &run.x, &motion, &mass, h);
            let saved = (run.x.clone(), duals.clone());
            match self.driven_step(&mut run, &external, plates, &mut drive, &mut duals)? {
                None => {
                    let u = self.node_field(&run.x);
                    self.commit_law_states(&u, h);
                    if settings.inertia {
                        motion.advance(&run.x, &saved.0, h);
                    } else if settings.damping != [0.0; 2] {
                        motion.velocity = run.x.iter().zip(&saved.0).map(|(a, b)| (a - b) / h).collect();
                    }
                    clock.advance(to, settings);
                    if (to - clock.next_output).abs() <= TIME_ROUNDING * settings.step
                        || clock.finished(settings)
                    {
                        let placed = drive.place(plates);
                        let sample = self.sample(to, &run, &duals, &placed, &motion, &mass, &clock);
                        self.observe(&sample, &run.x, on_sample);
                        samples.push(sample);
                        clock.next_output += settings.output_every;
                    }
                }
                Some(residual) => {
                    (run.x, duals) = saved;
                    clock.cut(settings, run.t, residual)?;
                }
            }
        }
        self.terms.dynamics = None;
        // The final state as the laws answer now (their history included).
        self.states.set_dt(NOW);
        let placed = drive.place(plates);
        let state = duals.state(run.t, &external, &placed);
        let support_force = self.support_force(&run.x, &state, loads);
        let (steps, cut_steps) = (clock.steps, clock.cut);
        let last = self.finish(run, &state, support_force);
        self.states.set_dt(0.0);
        Ok(TimeSolution { samples, last, steps, cut_steps })
    }

    /// Hands `sample` and the body's fields at the state `x` to `on_sample` (each cell's
    /// stress as its law answers now, its history included).
    fn observe(
        &mut self,
        sample: &TimeSample,
        x: &[f64],
        on_sample: &mut dyn FnMut(&TimeSample, &TimeFields<'_>),
    ) {
        let u = self.node_field(x);
        let stepping = self.states.dt();
        self.states.set_dt(NOW);
        let (cells, _) = self.cell_states(&u);
        self.states.set_dt(stepping);
        let model = &*self.model;
        let fields = TimeFields {
            grid: &model.grid,
            region_ids: &model.region_ids,
            node_displacements: &u,
            cells: &cells,
        };
        on_sample(sample, &fields);
    }

    /// `M^-1 (f - grad E)` at the start: the acceleration the loads give the body at rest.
    fn initial_acceleration(&mut self, x: &[f64], state: &LoadState<'_>, mass: &[f64]) -> Vec<f64> {
        let Some(eval) = self.evaluate(x, state, false) else { return vec![0.0; mass.len()] };
        eval.gradient.iter().zip(mass).map(|(g, &m)| if m > 0.0 { -g / m } else { 0.0 }).collect()
    }

    /// The dynamics term of a step of `h` from `x` (none for a quasi-static, undamped run).
    fn dynamics_term(
        &self,
        settings: &TimeSettings,
        x: &[f64],
        motion: &Motion,
        mass: &[f64],
        h: f64,
    ) -> Option<DynamicsTerm> {
        if !settings.inertia && settings.damping == [0.0; 2] {
            return None;
        }
        let predictor = if settings.inertia {
            (0..x.len())
                .map(|i| x[i] + h * motion.velocity[i] + h * h * (0.5 - BETA) * motion.acceleration[i])
                .collect()
        } else {
            x.to_vec()
        };
        Some(DynamicsTerm {
            mass: mass.to_vec(),
            inertia: if settings.inertia { 1.0 / (BETA * h * h) } else { 0.0 },
            predictor,
            start: x.to_vec(),
            velocity: motion.velocity.clone(),
            damping: settings.damping,
            h,
        })
    }

    /// One step's Newton solve and augmentations at the load factor `run.t`; the relative
    /// residual where Newton stopped when it failed (the caller cuts the step).
    pub(super) fn time_step(
        &mut self,
        run: &mut Progress,
        external: &[f64],
        plates: &[RigidPlate],
        duals: &mut Multipliers,
    ) -> Result<Option<f64>> {
        let mut history = Vec::new();
        let state = duals.state(run.t, external, plates);
        let force = match self.newton(&mut run.x, &state, &mut run.solver, &mut history, &mut run.stats)? {
            Ok(iterations) => {
                run.stats.load_steps += 1;
                self.record_step(run, plates, &duals.contact, 0, iterations, history).to_vec()
            }
            Err(f) => return Ok(Some(f.residual)),
        };
        let mut progress = Augmenting { force, ..Augmenting::default() };
        for augmentation in 1..=MAX_AUGMENTATIONS {
            match self.augment_once(run, external, plates, duals, &mut progress, augmentation) {
                Ok(true) => continue,
                Ok(false) => break,
                Err(FemError::NotConverged { residual, .. }) => return Ok(Some(residual)),
                Err(e) => return Err(e),
            }
        }
        Ok(None)
    }

    /// The sample at time `t` of the state `run`, reached after `clock`'s steps.
    fn sample(
        &self,
        time: f64,
        run: &Progress,
        duals: &Multipliers,
        plates: &[RigidPlate],
        motion: &Motion,
        mass: &[f64],
        clock: &Clock,
    ) -> TimeSample {
        let u = self.node_field(&run.x);
        let surface = self.model.grid.interpolate(&u);
        let moved: Vec<Vec3> = self
            .model
            .grid
            .surface_positions()
            .iter()
            .zip(&surface)
            .map(|(p, d)| std::array::from_fn(|a| p[a] + d[a]))
            .collect();
        let model = &*self.model;
        let strain_energy = model
            .grid
            .cell_nodes()
            .iter()
            .enumerate()
            .filter_map(|(c, nodes)| {
                let elastic = crate::law::CellLawState::ELASTIC;
                model.cell.energy_with(
                    &model.materials[c],
                    &nodes.map(|n| u[n]),
                    model.grid.cell_fill(c),
                    elastic,
                )
            })
            .sum();
        let grasps = self.terms.grasps.records(&u, run.t, &duals.grasps);
        TimeSample {
            time,
            load: run.t,
            max_displacement: surface.iter().map(|d| fibfluid_geometry::vec3::norm(*d)).fold(0.0, f64::max),
            volume: fibfluid_geometry::volume(&moved, model.grid.surface_triangles()),
            kinetic_energy: 0.5 * motion.velocity.iter().zip(mass).map(|(v, m)| m * v * v).sum::<f64>(),
            strain_energy,
            plate_forces: self.plate_forces(&run.x, plates, &duals.contact, run.t),
            grasp_forces: grasps.iter().map(|g| g.force).collect(),
            surface_displacements: surface,
            steps: clock.steps,
            cut_steps: clock.cut,
        }
    }
}

impl Motion {
    /// Newmark's velocity and acceleration at the end of a step of `h` from `start` to `x`.
    fn advance(&mut self, x: &[f64], start: &[f64], h: f64) {
        for i in 0..x.len() {
            let predicted = start[i] + h * self.velocity[i] + h * h * (0.5 - BETA) * self.acceleration[i];
            let a = (x[i] - predicted) / (BETA * h * h);
            self.velocity[i] += h * ((1.0 - GAMMA) * self.acceleration[i] + GAMMA * a);
            self.acceleration[i] = a;
        }
    }
}

/// The time stepping's clock: the time reached, the next step's length and the counts.
struct Clock {
    time: f64,
    step: f64,
    steps: usize,
    cut: usize,
    next_output: f64,
}

impl Clock {
    /// The next step's end: a step on, not past the next output time, the next point of
    /// the load curve or the end.
    fn next_time(&self, settings: &TimeSettings, curve: &LoadCurve) -> f64 {
        let eps = TIME_ROUNDING * settings.step;
        let breakpoint =
            curve.points().iter().map(|p| p.0).find(|&t| t > self.time + eps).unwrap_or(f64::INFINITY);
        let limit = self.next_output.min(breakpoint).min(settings.end);
        // A step that ends within rounding of the limit ends on it.
        if self.time + self.step >= limit - eps { limit } else { self.time + self.step }
    }

    /// A converged step to `to`: the step grows back toward the largest.
    fn advance(&mut self, to: f64, settings: &TimeSettings) {
        self.time = to;
        self.steps += 1;
        self.step = (2.0 * self.step).min(settings.step);
    }

    /// Whether the run has reached its end.
    fn finished(&self, settings: &TimeSettings) -> bool {
        settings.end - self.time <= TIME_ROUNDING * settings.step
    }

    /// A failed step: halved, or the error past the smallest step.
    fn cut(&mut self, settings: &TimeSettings, load: f64, residual: f64) -> Result<()> {
        self.cut += 1;
        self.step *= 0.5;
        if self.step < MIN_STEP_FRACTION * settings.step {
            return Err(FemError::NotConvergedInTime {
                time: self.time,
                step: self.step * 2.0,
                load,
                residual,
            });
        }
        Ok(())
    }
}
