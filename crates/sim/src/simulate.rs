//! Load stepping: the simulation of one scene.
//!
//! A [`Simulation`] holds four things: the [`BodyShape`] (boundary, fibers, rest shape;
//! fixed once set up), the [`State`] (positions, pressure, how much of the load is
//! applied), the factored system (assembled matrix, its factorization, the border it
//! describes) and the [`Counters`] (solves, factorizations, residuals). Loads move through
//! one call, [`Simulation::step_load`], which takes the load factor from where it is to a
//! new value; [`Simulation::run`] and [`Simulation::run_steps`] are equal steps of it.

use std::time::Instant;

use fibfluid_assembly::{
    AssemblyOptions, Body, ConstraintMethod, Loads, PressureScaling, ProjectedSystem, System, assemble,
    assemble_projected, load_vector,
};
use fibfluid_geometry::vec3::{add, dot, norm, scale, sub};
use fibfluid_geometry::{Boundary, FiberSet, Vec3, VisibilityOptions, cull_fibers};
use fibfluid_linalg::{
    CoupledCholesky, FactorOptions, Factorization, FactorizationExt, HeldCapacitance, LinearSolver,
    PrescribedSet, VertexColumns, VertexResponse,
};
use serde::Serialize;

use crate::choices::{FiberModel, ForceTiming, Method, Mode, Stepping};
use crate::contact::{
    Contact, MAX_ACTIVE_SET_ITERATIONS, PENETRATION_TOLERANCE, PlateRecord, TENSION_TOLERANCE,
};
use crate::guards::{Guard, GuardWarning, OnFailure, inverted_faces};
use crate::model::{Model, Shape, VOLUME_NEWTON_ITERATIONS, VOLUME_TOLERANCE};
use crate::plan::Plan;
use crate::stages::{Stage, StageLog, names};
use crate::{Error, Result};

/// Options that are not part of a scene.
#[derive(Clone, Default)]
pub struct RunOptions {
    /// Called after each step with (step, total).
    pub progress: Option<std::sync::Arc<dyn Fn(usize, usize) + Send + Sync>>,
}

impl std::fmt::Debug for RunOptions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RunOptions").field("progress", &self.progress.is_some()).finish()
    }
}

/// How a simulation is set up, besides the scene.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SetupOptions {
    /// Factorization options (the precision is taken from the scene).
    pub factor: FactorOptions,
    /// Refuse the scene when its plan needs more bytes than this (default: the machine's
    /// total memory).
    pub max_memory: Option<u64>,
}

/// Where a run of steps takes the load: from 0 to the full load, or back.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    /// Apply the loads (load factor 0 -> 1).
    Load,
    /// Remove them again (load factor 1 -> 0, the same steps with the opposite sign).
    Unload,
}

/// The body being simulated: its boundary, kept fibers and rest shape.
#[derive(Clone, Debug)]
pub struct BodyShape {
    /// Triangles or polygon.
    pub boundary: Boundary,
    /// Mesh edges (surface fibers).
    pub edges: Vec<[u32; 2]>,
    /// Kept bulk fibers.
    pub fibers: FiberSet,
    /// Whether the body was found convex.
    pub convex: bool,
    /// Rest positions.
    pub rest: Vec<Vec3>,
    /// Rest volume (area for a polygon).
    pub volume0: f64,
    /// Diagonal of the rest shape's bounding box (the body's size).
    pub diagonal: f64,
}

/// The state that load steps change.
#[derive(Clone, Debug, PartialEq)]
pub struct State {
    /// Current positions.
    pub positions: Vec<Vec3>,
    /// Accumulated pressure change.
    pub pressure: f64,
    /// Fraction of the scene's load applied (0 at rest, 1 after [`Simulation::run`]).
    pub load_factor: f64,
    /// Fraction of the forces applied at the last step (`at = "last"`) now acting.
    pub last_forces: f64,
    /// Vertices in contact with a plate, and the plates' forces on them.
    pub contacts: Vec<Contact>,
}

/// What the solves cost and how accurate they were.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Counters {
    /// Factorizations made (a dense backend's refactorization for a new border counts).
    pub factorizations: usize,
    /// Linear solves made.
    pub solves: usize,
    /// Largest componentwise backward error of any solve.
    pub residual_max: f64,
    /// Largest number of refinement steps of any solve.
    pub refinement_steps_max: usize,
}

/// Load steps so far.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct StepStats {
    /// Steps taken (accepted).
    pub taken: usize,
    /// Adaptive steps rejected (undone, halved and retried).
    pub rejected: usize,
    /// Steps skipped because their load did not change (no solve needed).
    pub skipped: usize,
    /// Sum of the accepted adaptive steps' error estimates (largest vertex distance
    /// between the Euler and Heun evaluations), in length units.
    pub error_estimate: f64,
}

/// The increments of one step.
#[derive(Clone)]
struct Increment {
    da: Vec3,
    forces: Vec<(usize, Vec3)>,
    prescribed: f64,
    /// Load factor after the step.
    to: f64,
    /// Fraction of the last-step forces applied after the step.
    last_to: f64,
}

/// One evaluation of a step from the current shape.
struct Evaluation {
    /// Displacement increments.
    du: Vec<Vec3>,
    /// Pressure increment.
    dp: f64,
    /// Euler/Heun difference, when estimated.
    estimate: Option<f64>,
}

/// What a step did.
struct StepOutcome {
    /// Euler/Heun difference, when estimated.
    estimate: Option<f64>,
}

/// Smallest adaptive step (a fraction of the load) before the stepper gives up.
#[doc(alias = "tolerance")]
pub const MIN_ADAPTIVE_STEP: f64 = 1e-6;

/// The assembled system, its factorization and the shape its border describes.
struct Factored {
    system: System,
    factorization: Box<dyn Factorization>,
    solver: Box<dyn LinearSolver>,
    options: FactorOptions,
    border_areas: Vec<Vec3>,
    /// Vertices held by [`Simulation::respond_held`], on this factorization.
    held: Holds,
    /// Contact constraints, on this factorization.
    contact: PrescribedSet,
    /// With projected fibers (`[ffm] fibers = "projected"`): the coupled
    /// system and its factorization, which every step's solve uses instead of
    /// `factorization` (the paper's operator is still assembled and factored: it backs
    /// [`Simulation::system`] and [`Simulation::factorization`]).
    coupled: Option<Coupled>,
}

/// The projected fibers' bordered system and its dense Cholesky (the stiffness lives in
/// the factorization; the system keeps what right-hand sides need).
struct Coupled {
    system: ProjectedSystem,
    factor: CoupledCholesky,
}

impl Coupled {
    /// The coupled system assembled on a shape (its positions and vertex area vectors,
    /// timed as `assembly`) and its factorization.
    fn build(
        scene: &Model,
        body: &BodyShape,
        (positions, areas): (&[Vec3], &[Vec3]),
        options: &FactorOptions,
        log: &mut StageLog,
        assembly: Stage,
    ) -> Result<Self> {
        let mut system = log.time(assembly, || assemble_projected_on(scene, body, positions, areas))?;
        let k = std::mem::replace(&mut system.stiffness, fibfluid_linalg::Mat::new());
        let border = system.border.clone();
        let factor = log.time(names::FACTORIZATION, || CoupledCholesky::factor(k, border, options))?;
        Ok(Self { system, factor })
    }
}

impl Factored {
    /// Splits a solution of the solved system into displacements and the pressure.
    fn split(&self, x: &[f64]) -> (Vec<Vec3>, f64) {
        match &self.coupled {
            Some(c) => c.system.split_solution(x),
            None => self.system.split_solution(x),
        }
    }
}

/// Vertices held by [`Simulation::respond_held`]: the compliance columns of the vertices
/// held so far and the capacitance of the last held set, on the kept factorization.
#[derive(Default)]
struct Holds {
    columns: Option<VertexColumns>,
    capacitance: Option<HeldCapacitance>,
}

/// The static response of a factored body to forces and held vertices.
#[derive(Clone, Debug, PartialEq)]
pub struct Response {
    /// Displacement of every vertex.
    pub displacements: Vec<Vec3>,
    /// Pressure change.
    pub pressure: f64,
    /// The force each held vertex needs to stay where it is held, in the order given.
    pub reactions: Vec<(usize, Vec3)>,
}

/// A scene being simulated.
pub struct Simulation {
    model: Model,
    plan: Plan,
    body: BodyShape,
    state: State,
    factored: Factored,
    counters: Counters,
    stats: StepStats,
    warnings: Vec<GuardWarning>,
    /// Contacts of the current solves: (plate, vertex) and the step's normal motion onto
    /// the plate.
    contact_active: Vec<(usize, usize)>,
    contact_values: Vec<f64>,
    plate_records: Vec<PlateRecord>,
    calibration: Option<crate::calibration::Calibration>,
    log: StageLog,
    started: Instant,
}

impl Simulation {
    /// Plans the scene and prepares it: fibers, assembly and the first factorization.
    /// Only the stages the plan runs are done; a plan that needs more memory than the
    /// machine has is refused before anything large is allocated.
    pub fn new(model: impl Into<Model>) -> Result<Self> {
        Self::with_options(model, &SetupOptions::default())
    }

    /// [`new`](Self::new) with explicit setup options.
    pub fn with_options(model: impl Into<Model>, opts: &SetupOptions) -> Result<Self> {
        let scene: Model = model.into();
        if scene.solver.method != Method::Ffm {
            return Err(Error::MethodNeeds {
                scene: scene.display_name(),
                method: scene.solver.method,
                problem: "is not run by the fiber-fluid Simulation (fem: `fem_run::FemRun`; ChainMail: interactive bodies)",
            });
        }
        refuse_projected(&scene)?;
        let started = Instant::now();
        let limit = fibfluid_linalg::memory_budget(opts.max_memory);
        // From counts first: a body too large is refused before its convexity check.
        Plan::from_counts(&scene).check_memory(&scene.name, limit, scene.solver.backend)?;
        let mut log = StageLog::default();
        let mut scene = scene;
        let calibration = if scene.ffm.calibrate {
            let c =
                log.time(names::CALIBRATION, || crate::calibration::calibrate(&scene, opts.max_memory))?;
            scene.material.young = [c.fiber_modulus; 3];
            scene.material.surface_tension = c.surface_tension;
            scene.ffm.calibrate = false;
            Some(c)
        } else {
            None
        };
        let plan = match scene.shape {
            Shape::Surface(_) => log.time(names::CONVEXITY, || Plan::from_scene(&scene)),
            Shape::Polygon(_) => Plan::from_scene(&scene),
        };
        plan.check_memory(
            &scene.name,
            fibfluid_linalg::memory_budget(opts.max_memory),
            scene.solver.backend,
        )?;
        let mut factor_options = opts.factor;
        factor_options.precision = scene.solver.precision;
        let solver = scene.solver.backend.solver()?;
        let rest = scene.rest_positions();
        let n = rest.len();
        let (boundary, edges, fibers) = match &scene.shape {
            Shape::Surface(file) => {
                let mesh = &file.mesh;
                let fibers = if plan.runs(names::VISIBILITY) {
                    let opts = VisibilityOptions { force_tests: true, ..Default::default() };
                    log.time(names::VISIBILITY, || cull_fibers(mesh, &opts).0)
                } else {
                    FiberSet::all(n)
                };
                let boundary = Boundary::Surface { triangles: mesh.triangles().to_vec() };
                (boundary, mesh.adjacency().edges(), fibers)
            }
            Shape::Polygon(p) => (Boundary::Polygon, p.edges(), FiberSet::all(n)),
        };
        let convex = !plan.runs(names::VISIBILITY);
        let areas = log.time(names::AREAS, || boundary.vertex_area_vectors(&rest));
        let volume0 = boundary.volume(&rest);
        let (lo, hi) = fibfluid_geometry::bounding_box(&rest);
        let diagonal = norm(sub(hi, lo));
        let body = BodyShape { boundary, edges, fibers, convex, rest, volume0, diagonal };
        let mut system = log.time(names::ASSEMBLY, || assemble_on(&scene, &body, &body.rest, &areas))?;
        // The factor takes the assembled blocks' storage where the backend can (one N x N
        // buffer per block instead of two); the system still reads as K.
        let factorization = log
            .time(names::FACTORIZATION, || solver.factorize_in_place(&mut system.matrix, &factor_options))?;
        let coupled = if scene.ffm.fibers == FiberModel::Projected {
            let on_rest = (&body.rest[..], &areas[..]);
            Some(Coupled::build(&scene, &body, on_rest, &factor_options, &mut log, names::ASSEMBLY)?)
        } else {
            None
        };
        let state = State {
            positions: body.rest.clone(),
            pressure: 0.0,
            load_factor: 0.0,
            last_forces: 0.0,
            contacts: vec![],
        };
        let factored = Factored {
            system,
            factorization,
            solver,
            options: factor_options,
            border_areas: areas,
            held: Holds::default(),
            contact: PrescribedSet::new(),
            coupled,
        };
        let factorizations = if factored.coupled.is_some() { 2 } else { 1 };
        let counters = Counters { factorizations, ..Default::default() };
        let plates = scene.plates.len();
        Ok(Self {
            model: scene,
            plan,
            body,
            state,
            factored,
            counters,
            stats: StepStats::default(),
            warnings: vec![],
            contact_active: vec![],
            contact_values: vec![],
            plate_records: vec![PlateRecord::default(); plates],
            calibration,
            log,
            started,
        })
    }

    /// The calibration of the fiber modulus against the FEM, when the scene asked for one
    /// (it gave only `[tissue]`).
    pub fn calibration(&self) -> Option<&crate::calibration::Calibration> {
        self.calibration.as_ref()
    }

    /// The model being simulated.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The plan this simulation follows.
    pub fn plan(&self) -> &Plan {
        &self.plan
    }

    /// The body: boundary, fibers, rest shape.
    pub fn body(&self) -> &BodyShape {
        &self.body
    }

    /// The current state: positions, pressure, load factor.
    pub fn state(&self) -> &State {
        &self.state
    }

    /// Current positions.
    pub fn positions(&self) -> &[Vec3] {
        &self.state.positions
    }

    /// Rest positions.
    pub fn rest_positions(&self) -> &[Vec3] {
        &self.body.rest
    }

    /// Accumulated pressure change.
    pub fn pressure(&self) -> f64 {
        self.state.pressure
    }

    /// Volume (area for a polygon) of the rest shape.
    pub fn volume_initial(&self) -> f64 {
        self.body.volume0
    }

    /// Volume of the current shape.
    pub fn volume(&self) -> f64 {
        self.body.boundary.volume(&self.state.positions)
    }

    /// The kept fibers.
    pub fn fibers(&self) -> &FiberSet {
        &self.body.fibers
    }

    /// Whether the body was found convex.
    pub fn convex(&self) -> bool {
        self.body.convex
    }

    /// The assembled system currently factored. With projected fibers this is the paper's
    /// per-axis operator on the same body, not the coupled one the steps solve.
    pub fn system(&self) -> &System {
        &self.factored.system
    }

    /// The current factorization (with projected fibers: of [`system`](Self::system), the
    /// paper's operator).
    pub fn factorization(&self) -> &dyn Factorization {
        self.factored.factorization.as_ref()
    }

    /// Ends the simulation and keeps its assembled system and factorization, for a caller
    /// that solves on with them (the interactive body's compliance columns are computed
    /// with the factorization of the base solve, not a second one). Everything else (the
    /// state, the fibers, the held and contact sets) is dropped. With projected fibers
    /// these are the paper's operator: callers must refuse such scenes.
    pub fn into_factored(self) -> (System, Box<dyn Factorization>) {
        (self.factored.system, self.factored.factorization)
    }

    /// What the solves cost so far.
    pub fn counters(&self) -> &Counters {
        &self.counters
    }

    /// Stage times so far.
    pub fn log(&self) -> &StageLog {
        &self.log
    }

    /// Seconds since the simulation was created.
    pub fn elapsed(&self) -> f64 {
        self.started.elapsed().as_secs_f64()
    }

    /// Number of axes (2 for a polygon).
    pub fn axes(&self) -> usize {
        self.body.boundary.axes()
    }

    /// Runs the scene's loads to full: `steps` equal steps, or adaptive steps when the
    /// scene sets a `tolerance`.
    pub fn run(&mut self, opts: &RunOptions) -> Result<()> {
        match self.model.tolerance {
            Some(tolerance) => self.adaptive(Direction::Load, tolerance, opts),
            None => self.run_steps(self.model.steps, Direction::Load, opts),
        }
    }

    /// Runs `steps` equal load steps in one direction.
    pub fn run_steps(&mut self, steps: usize, direction: Direction, opts: &RunOptions) -> Result<()> {
        for k in 0..steps {
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
        match self.model.tolerance {
            Some(tolerance) => self.adaptive(Direction::Unload, tolerance, opts),
            None => self.run_steps(self.model.steps, Direction::Unload, opts),
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

    fn adaptive(&mut self, direction: Direction, tolerance: f64, opts: &RunOptions) -> Result<()> {
        #[derive(Clone, Copy, PartialEq)]
        enum Phase {
            Ramp,
            Last,
        }
        let has_last = self.model.forces.iter().any(|f| f.timing == ForceTiming::Last);
        let (sign, phases) = match (direction, has_last) {
            (Direction::Load, true) => (1.0, vec![Phase::Ramp, Phase::Last]),
            (Direction::Unload, true) => (-1.0, vec![Phase::Last, Phase::Ramp]),
            (Direction::Load, false) => (1.0, vec![Phase::Ramp]),
            (Direction::Unload, false) => (-1.0, vec![Phase::Ramp]),
        };
        let count = phases.len();
        let mut h = 1.0 / self.model.steps.max(1) as f64;
        for (k, phase) in phases.into_iter().enumerate() {
            let (lambda0, last0) = (self.state.load_factor, self.state.last_forces);
            let mut done = 0.0;
            while done < 1.0 {
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
                let saved =
                    (self.state.clone(), self.stats.clone(), self.warnings.len(), self.plate_records.clone());
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
                    self.plate_records = saved.3;
                    self.stats.rejected += 1;
                    h *= 0.5;
                }
            }
        }
        Ok(())
    }

    /// The increments of one fixed step: `ramp` of gravity, ramped forces and
    /// prescribed displacements, `last` of the forces applied at the last step.
    fn increment(&self, ramp: f64, last: f64, to: f64, last_to: f64) -> Increment {
        let forces = self
            .model
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
        Increment { da: scale(self.model.gravity, ramp), forces, prescribed: ramp, to, last_to }
    }

    fn last_forces(&self, fraction: f64) -> Vec<(usize, Vec3)> {
        self.model
            .forces
            .iter()
            .filter(|f| f.timing == ForceTiming::Last)
            .map(|f| (f.vertex, scale(f.value, fraction)))
            .collect()
    }

    /// Takes one step of increments `inc` (with the Euler/Heun error estimate when
    /// `estimate`), then checks the guards. With plates, the step is repeated until its
    /// contact active set is stable. Numeric failures are explained.
    fn take_step(&mut self, inc: &Increment, estimate: bool) -> Result<StepOutcome> {
        let step = self.stats.taken + 1;
        let from = self.state.load_factor;
        let moves_prescribed = inc.prescribed != 0.0 && self.model.constraints.has_nonzero();
        let acts = inc.da != [0.0; 3] && self.model.material.density > 0.0;
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

    /// The contacts for the next solves: their constraint rows (free axes of the vertex,
    /// the plate's normal) and the normal displacement that puts each vertex on its
    /// plate at load factor `to`.
    fn set_contacts(&mut self, active: &[Contact], to: f64) {
        self.contact_values = active
            .iter()
            .map(|c| -self.model.plates[c.plate].gap(self.state.positions[c.vertex], to))
            .collect();
        self.contact_active = active.iter().map(|c| (c.plate, c.vertex)).collect();
    }

    /// Sets each contact's force from the current state: the force on the body at the
    /// contact's vertex, `K u + P S - f` (u the displacement from rest, P the pressure, f
    /// the loads at the state), over the vertex's free axes, along the plate's normal.
    /// This is minus the reaction that holds the vertex on the plate, whatever path the
    /// steps took. `K` and `S` are the operator of the state as the mode defines it:
    /// paper mode's rest operator (the one it factors), refresh mode's rest `K` with `S`
    /// of the current shape, nonlinear mode's `K` and `S` assembled on the current shape.
    fn contact_forces(&mut self, contacts: &mut [Contact]) -> Result<()> {
        if contacts.is_empty() {
            return Ok(());
        }
        let s = &self.state.positions;
        let (n, axes) = (s.len(), self.axes());
        let current = self.log.time(names::AREAS, || self.body.boundary.vertex_area_vectors(s));
        let reassembled = match self.model.solver.mode {
            Mode::Nonlinear => {
                Some(self.log.time(names::REASSEMBLY, || assemble_on(&self.model, &self.body, s, &current))?)
            }
            Mode::Paper | Mode::Refresh => None,
        };
        let (system, border) = match (self.model.solver.mode, &reassembled) {
            (Mode::Paper, _) => (&self.factored.system, &self.factored.border_areas),
            (_, Some(system)) => (system, &current),
            (_, None) => (&self.factored.system, &current),
        };
        let u: Vec<Vec3> = s.iter().zip(&self.body.rest).map(|(p, r)| sub(*p, *r)).collect();
        let (lambda, last) = (self.state.load_factor, self.state.last_forces);
        let forces: Vec<(usize, Vec3)> = self
            .model
            .forces
            .iter()
            .map(|f| {
                let k = match f.timing {
                    ForceTiming::Ramp => lambda,
                    ForceTiming::Last => last,
                };
                (f.vertex, scale(f.value, k))
            })
            .collect();
        let loads = Loads {
            acceleration: scale(self.model.gravity, lambda),
            down: Some(self.model.gravity),
            density: self.model.material.density,
            forces: &forces,
        };
        let f = load_vector(axes, s, &current, &loads)?;
        let pressure = self.state.pressure;
        for c in contacts.iter_mut() {
            let normal = self.model.plates[c.plate].normal;
            c.force = (0..axes)
                .filter(|&a| self.model.constraints.get(c.vertex, a).is_none())
                .map(|a| {
                    let own = system.stiffness_force(c.vertex, a, &u) + pressure * border[c.vertex][a];
                    normal[a] * (own - f[a * n + c.vertex])
                })
                .sum();
        }
        Ok(())
    }

    /// The next active set after a step: contacts turned tensile are released, vertices
    /// through a plate join. Returns whether it changed, the new set and the released
    /// (plate, vertex) pairs.
    fn update_active_set(&self, active: &[Contact], to: f64) -> (bool, Vec<Contact>, Vec<(usize, usize)>) {
        let largest = active.iter().map(|c| c.force.abs()).fold(0.0, f64::max);
        let (keep, drop): (Vec<Contact>, Vec<Contact>) =
            active.iter().partition(|c| c.force >= -TENSION_TOLERANCE * largest.max(f64::MIN_POSITIVE));
        let mut next = keep;
        let depth = PENETRATION_TOLERANCE * self.body.diagonal;
        let axes = self.axes();
        for (k, plate) in self.model.plates.iter().enumerate() {
            for (v, x) in self.state.positions.iter().enumerate() {
                let fully_fixed = (0..axes).all(|c| self.model.constraints.get(v, c).is_some());
                if fully_fixed || active.iter().any(|c| c.plate == k && c.vertex == v) {
                    continue;
                }
                if plate.gap(*x, to) < -depth {
                    next.push(Contact { plate: k, vertex: v, force: 0.0 });
                }
            }
        }
        let released: Vec<(usize, usize)> = drop.iter().map(|c| (c.plate, c.vertex)).collect();
        (next.len() != active.len() || !released.is_empty(), next, released)
    }

    /// Appends this step's force, contact area, contacts and gap to each plate's record.
    fn record_plates(&mut self, iterations: usize) {
        let areas = self.body.boundary.vertex_area_vectors(&self.state.positions);
        let lambda = self.state.load_factor;
        let plates = &self.model.plates;
        for (k, plate) in plates.iter().enumerate() {
            let mine: Vec<&Contact> = self.state.contacts.iter().filter(|c| c.plate == k).collect();
            let gap = match plates.get((k + 1) % plates.len()).filter(|_| plates.len() > 1) {
                Some(other) => dot(plate.normal, sub(other.point_at(lambda), plate.point_at(lambda))).abs(),
                None => {
                    let h: Vec<f64> = self.state.positions.iter().map(|x| dot(plate.normal, *x)).collect();
                    h.iter().copied().fold(f64::MIN, f64::max) - h.iter().copied().fold(f64::MAX, f64::min)
                }
            };
            let r = &mut self.plate_records[k];
            r.force.push(mine.iter().fold(0.0, |f, c| f + c.force));
            r.contact_area.push(mine.iter().fold(0.0, |a, c| a + norm(areas[c.vertex])));
            r.contact_vertices.push(mine.len());
            r.gap.push(gap);
            r.active_set_iterations.push(iterations);
        }
    }

    /// The guards after step `step`; with `on_failure = "error"` the first one that fires
    /// is returned as an error.
    fn check_guards(&mut self, step: usize, increment: f64, residual: f64) -> Result<()> {
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
    fn evaluate(&mut self, inc: &Increment, estimate: bool) -> Result<Evaluation> {
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

    /// Guard warnings so far.
    pub fn warnings(&self) -> &[GuardWarning] {
        &self.warnings
    }

    /// Steps taken, rejected and skipped, and the error estimate of adaptive steps.
    pub fn step_stats(&self) -> &StepStats {
        &self.stats
    }

    /// Each plate's force, contact area, contacts and gap after every step.
    pub fn plate_records(&self) -> &[PlateRecord] {
        &self.plate_records
    }

    /// The static response of the current factorization to point forces alone (no
    /// stepping, no position update): the interactive use of a factored body.
    pub fn respond(&mut self, forces: &[(usize, Vec3)]) -> Result<(Vec<Vec3>, f64)> {
        self.refuse_coupled()?;
        let n = self.state.positions.len();
        if let Some(&(v, _)) = forces.iter().find(|(v, _)| *v >= n) {
            return Err(Error::VertexOutOfRange { vertex: v, vertices: n });
        }
        let loads = Loads { forces, ..Default::default() };
        let b = load_vector(self.axes(), &self.state.positions, &self.factored.border_areas, &loads)?;
        let x = self.solve(&b, 0.0, 1.0, false)?;
        Ok(self.factored.split(&x))
    }

    /// The static response of the current factorization to point forces with vertices
    /// held at given displacements (no stepping, no position update): a tool grabbing the
    /// body. The held set is a change of the constraints on the kept factorization, imposed
    /// by the capacitance of the held vertices over their compliance columns, the same code
    /// as the interactive body ([`fibfluid_linalg::HeldCapacitance`] over
    /// [`fibfluid_linalg::VertexColumns`]): a vertex held for the first time costs one
    /// bordered solve per distinct stiffness block (its columns are then cached until the
    /// operator changes), a new held set a `(dk)^3 / 3` Cholesky, and each call one checked
    /// solve plus `O(k N)`, where refactoring with the vertices eliminated would cost
    /// `N^3 / 3` per stiffness block. A vertex listed twice is held once (at its first
    /// displacement).
    pub fn respond_held(&mut self, forces: &[(usize, Vec3)], held: &[(usize, Vec3)]) -> Result<Response> {
        self.refuse_coupled()?;
        let n = self.state.positions.len();
        let axes = self.axes();
        if let Some(&(v, _)) = forces.iter().chain(held).find(|(v, _)| *v >= n) {
            return Err(Error::VertexOutOfRange { vertex: v, vertices: n });
        }
        if let Some(&(v, _)) =
            held.iter().find(|(v, _)| (0..axes).any(|c| self.model.constraints.get(*v, c).is_some()))
        {
            return Err(Error::HeldFixedVertex { vertex: v });
        }
        let mut targets: Vec<(usize, Vec3)> = Vec::with_capacity(held.len());
        for &(v, d) in held {
            if !targets.iter().any(|t| t.0 == v) {
                targets.push((v, d));
            }
        }
        let vertices: Vec<usize> = targets.iter().map(|t| t.0).collect();
        let f = &mut self.factored;
        let loads = Loads { forces, ..Default::default() };
        let b = load_vector(axes, &self.state.positions, &f.border_areas, &loads)?;
        let rhs = f.system.rhs(&b, 0.0, &f.border_areas, 1.0);
        let start = Instant::now();
        let sol = f.factorization.solve(&rhs)?;
        let mut x = sol.x;
        let mut reactions = vec![];
        if !vertices.is_empty() {
            let columns = match &mut f.held.columns {
                Some(c) => c,
                None => f.held.columns.insert(VertexColumns::new(f.factorization.as_ref())?),
            };
            columns.touch(f.factorization.as_ref(), &vertices)?;
            if f.held.capacitance.as_ref().is_none_or(|c| c.vertices() != vertices) {
                f.held.capacitance = Some(HeldCapacitance::new(&*columns, &vertices)?);
            }
            let cap = f.held.capacitance.as_ref().expect("built above");
            let gap: Vec<f64> = targets
                .iter()
                .flat_map(|&(v, d)| (0..axes).map(move |c| (v, c, d[c])))
                .map(|(v, c, d)| d - x[c * n + v])
                .collect();
            reactions = cap.reactions(&gap)?;
            let p = columns.pressure_of(&reactions);
            columns.add_field_axes(&reactions, p, &mut x[..axes * n]);
            x[axes * n] += p / f.system.matrix.pressure_scale();
        }
        self.log.add(names::SOLVE, start.elapsed().as_secs_f64());
        self.counters.solves += 1;
        let (displacements, pressure) = self.factored.split(&x);
        let reactions = held
            .iter()
            .map(|&(v, _)| *reactions.iter().find(|r| r.0 == v).expect("every held vertex has a reaction"))
            .collect();
        Ok(Response { displacements, pressure, reactions })
    }

    /// The interactive responses are built on the paper's per-axis operator only.
    fn refuse_coupled(&self) -> Result<()> {
        if self.factored.coupled.is_some() {
            return Err(Error::MethodNeeds {
                scene: self.model.display_name(),
                method: Method::Ffm,
                problem: "with fibers = \"projected\" has no interactive response yet (use fibers = \"paper\")",
            });
        }
        Ok(())
    }

    /// Makes the factored operator describe shape `s` as the mode requires; returns the
    /// volume target for the last row.
    fn prepare_operator(&mut self, s: &[Vec3]) -> Result<f64> {
        let mode = self.model.solver.mode;
        if mode == Mode::Paper {
            return Ok(0.0);
        }
        // The held and contact sets were built on the operator about to change.
        self.factored.held = Holds::default();
        self.factored.contact = PrescribedSet::new();
        let areas = self.log.time(names::AREAS, || self.body.boundary.vertex_area_vectors(s));
        match mode {
            Mode::Paper => unreachable!("handled above"),
            Mode::Refresh => {
                let f = &mut self.factored;
                let border = f.system.border_for(&areas);
                let start = Instant::now();
                f.system.matrix.set_border(&border);
                f.factorization.set_border(&border)?;
                if let Some(c) = &mut f.coupled {
                    let border = c.system.border_for(&areas);
                    c.factor.set_border(border.clone())?;
                    c.system.border = border;
                }
                // A dense backend refactors the whole matrix for a new border: say so.
                if f.factorization.border_update_refactors() {
                    self.counters.factorizations += 1;
                    self.log.add(names::FACTORIZATION, start.elapsed().as_secs_f64());
                } else {
                    self.log.add(names::BORDER, start.elapsed().as_secs_f64());
                }
            }
            Mode::Nonlinear => {
                let mut system =
                    self.log.time(names::REASSEMBLY, || assemble_on(&self.model, &self.body, s, &areas))?;
                let f = &mut self.factored;
                let start = Instant::now();
                f.factorization = f.solver.factorize_in_place(&mut system.matrix, &f.options)?;
                self.log.add(names::FACTORIZATION, start.elapsed().as_secs_f64());
                self.counters.factorizations += 1;
                f.system = system;
                if self.factored.coupled.is_some() {
                    self.refactor_coupled(s, &areas)?;
                }
            }
        }
        let start = Instant::now();
        let target = self.volume_target(s, &areas);
        self.log.add(names::VOLUME, start.elapsed().as_secs_f64());
        self.factored.border_areas = areas;
        Ok(target)
    }

    /// Nonlinear mode with projected fibers: the coupled operator assembled on shape `s`
    /// (its fibers' directions and lengths, its border `areas`) and factored again.
    fn refactor_coupled(&mut self, s: &[Vec3], areas: &[Vec3]) -> Result<()> {
        // The old matrix and factor go first: the plan counts one of each.
        self.factored.coupled = None;
        let options = self.factored.options;
        let coupled =
            Coupled::build(&self.model, &self.body, (s, areas), &options, &mut self.log, names::REASSEMBLY)?;
        self.counters.factorizations += 1;
        self.factored.coupled = Some(coupled);
        Ok(())
    }

    /// The volume row's target on shape `s` with border `areas`: the row asks
    /// `sum S_i . u_i = t`, while the volume changes by `sum G_i . u_i` to first order with
    /// `G` the exact gradient, parallel to `S` (`G = S / (3C)` on a surface, `S / (2C)` on a
    /// polygon). So `t = (V0 - V) / r` with `r = sum |G_i| / sum |S_i|`.
    fn volume_target(&self, s: &[Vec3], areas: &[Vec3]) -> f64 {
        let v = self.body.boundary.volume(s);
        let sum_g: f64 = self.body.boundary.volume_gradient(s).iter().map(|g| norm(*g)).sum();
        let sum_s: f64 = areas.iter().map(|a| norm(*a)).sum();
        let r = if sum_s > 0.0 && sum_g > 0.0 { sum_g / sum_s } else { 1.0 };
        (self.body.volume0 - v) / r
    }

    /// Pulls the volume back to V0 after a step (refresh and nonlinear modes) with one
    /// solve: the response `w` of the current factorization to a unit volume target (no
    /// load) is the direction every correction solve would move along, so the volume is
    /// restored by a scalar Newton iteration on `V(s + alpha w) = V0` (volume and gradient
    /// evaluations only, at most [`VOLUME_NEWTON_ITERATIONS`]), to [`VOLUME_TOLERANCE`].
    fn correct_volume(&mut self) -> Result<()> {
        let v0 = self.body.volume0;
        if (self.volume() / v0 - 1.0).abs() <= VOLUME_TOLERANCE {
            return Ok(());
        }
        let open = self.log.begin(names::VOLUME_CORRECTION);
        let zero = vec![0.0; self.axes() * self.state.positions.len()];
        let solved = self.solve(&zero, 1.0, 0.0, false);
        self.log.end(open);
        let xw = solved?;
        let (w, pw) = self.factored.split(&xw);
        let start = self.state.positions.clone();
        let along = |alpha: f64| -> Vec<Vec3> {
            start.iter().zip(&w).map(|(p, d)| add(*p, scale(*d, alpha))).collect()
        };
        let mut alpha = 0.0;
        for _ in 0..VOLUME_NEWTON_ITERATIONS {
            let p = along(alpha);
            let f = self.body.boundary.volume(&p) - v0;
            if (f / v0).abs() <= VOLUME_TOLERANCE {
                break;
            }
            let slope: f64 =
                self.body.boundary.volume_gradient(&p).iter().zip(&w).map(|(g, d)| dot(*g, *d)).sum();
            if !(slope.abs() > 0.0) {
                break;
            }
            alpha -= f / slope;
        }
        self.state.positions = along(alpha);
        self.state.pressure += alpha * pw;
        Ok(())
    }

    /// Load increment on shape `s`: `rho (da . down) h_i S_i` plus the point-force
    /// increments, through [`load_vector`]. Paper mode keeps the rest border, so the load
    /// needs S of `s`; the other modes have just made the border describe `s`.
    fn load_increment(&mut self, s: &[Vec3], da: Vec3, forces: &[(usize, Vec3)]) -> Result<Vec<f64>> {
        let loads = Loads {
            acceleration: da,
            down: Some(self.model.gravity),
            density: self.model.material.density,
            forces,
        };
        let computed;
        let areas: &[Vec3] = if self.model.solver.mode == Mode::Paper && loads.has_hydrostatic() {
            computed = self.log.time(names::AREAS, || self.body.boundary.vertex_area_vectors(s));
            &computed
        } else {
            &self.factored.border_areas
        };
        let axes = self.axes();
        Ok(self.log.time(names::LOADS, || load_vector(axes, s, areas, &loads))?)
    }

    /// One solve with the current factorization; with active contacts, under their
    /// constraints (`step`: each contact's vertex moves onto its plate; otherwise it
    /// keeps its normal position). The contacts' forces are not taken from the
    /// multipliers: see [`contact_forces`](Self::contact_forces).
    fn solve(&mut self, b: &[f64], target: f64, prescribed_scale: f64, step: bool) -> Result<Vec<f64>> {
        if !self.contact_active.is_empty() {
            self.sync_contact_set()?;
        }
        let f = &self.factored;
        if let Some(c) = &f.coupled {
            let rhs = c.system.rhs(b, target, &f.border_areas, prescribed_scale);
            let start = Instant::now();
            let sol = c.factor.solve(&rhs)?;
            self.log.add(names::SOLVE, start.elapsed().as_secs_f64());
            self.counters.residual_max = self.counters.residual_max.max(sol.relative_residual);
            self.counters.refinement_steps_max = self.counters.refinement_steps_max.max(sol.refinement_steps);
            self.counters.solves += 1;
            return Ok(sol.x);
        }
        let rhs = f.system.rhs(b, target, &f.border_areas, prescribed_scale);
        let start = Instant::now();
        let x = if self.contact_active.is_empty() {
            let sol = f.factorization.solve(&rhs)?;
            self.counters.residual_max = self.counters.residual_max.max(sol.relative_residual);
            self.counters.refinement_steps_max = self.counters.refinement_steps_max.max(sol.refinement_steps);
            sol.x
        } else {
            // The set's order is its insertion order; the values follow it.
            let keys = f.contact.keys();
            let order: Vec<usize> = self
                .contact_active
                .iter()
                .map(|&(p, v)| keys.iter().position(|&k| k == Contact::key(p, v)).expect("synced"))
                .collect();
            let mut values = vec![0.0; keys.len()];
            if step {
                for (i, &j) in order.iter().enumerate() {
                    values[j] = self.contact_values[i];
                }
            }
            let sol = f.contact.solve(f.factorization.as_ref(), &rhs, &values)?;
            self.counters.residual_max = self.counters.residual_max.max(sol.relative_residual);
            sol.x
        };
        self.log.add(names::SOLVE, start.elapsed().as_secs_f64());
        self.counters.solves += 1;
        Ok(x)
    }

    /// Makes the factorization's contact constraints those of the active contacts.
    fn sync_contact_set(&mut self) -> Result<()> {
        let n = self.state.positions.len();
        let axes = self.axes();
        let wanted: Vec<u64> = self.contact_active.iter().map(|&(p, v)| Contact::key(p, v)).collect();
        let f = &mut self.factored;
        for key in f.contact.keys().to_vec().into_iter().filter(|k| !wanted.contains(k)) {
            f.contact.remove_key(key)?;
        }
        let start = Instant::now();
        let rows: Vec<(u64, Vec<(usize, f64)>)> = self
            .contact_active
            .iter()
            .map(|&(p, v)| {
                let normal = self.model.plates[p].normal;
                let row = (0..axes)
                    .filter(|&c| self.model.constraints.get(v, c).is_none())
                    .map(|c| (c * n + v, normal[c]))
                    .collect();
                (Contact::key(p, v), row)
            })
            .collect();
        f.contact.add_rows(f.factorization.as_ref(), &rows)?;
        self.log.add(names::CONTACT, start.elapsed().as_secs_f64());
        Ok(())
    }
}

/// Refuses, with one line, what the projected fibers do not run: they run every mode on a
/// surface, in f64, without plates.
fn refuse_projected(scene: &Model) -> Result<()> {
    if scene.ffm.fibers != FiberModel::Projected {
        return Ok(());
    }
    let problem = if !scene.plates.is_empty() {
        "with fibers = \"projected\" does not run plates yet (use fibers = \"paper\")"
    } else if matches!(scene.shape, Shape::Polygon(_)) {
        "with fibers = \"projected\" needs a surface mesh (2D polygons are not built)"
    } else if scene.solver.precision != fibfluid_linalg::Precision::F64 {
        "with fibers = \"projected\" factors in f64 only (precision = \"mixed\" is not built)"
    } else {
        return Ok(());
    };
    Err(Error::MethodNeeds { scene: scene.display_name(), method: Method::Ffm, problem })
}

/// The projected fibers' system on `positions` (the paper's constraint method).
fn assemble_projected_on(
    scene: &Model,
    body: &BodyShape,
    positions: &[Vec3],
    areas: &[Vec3],
) -> Result<ProjectedSystem> {
    let shape = Body {
        axes: body.boundary.axes(),
        positions,
        vertex_areas: areas,
        edges: &body.edges,
        fibers: &body.fibers,
        rest_positions: Some(&body.rest),
    };
    let opts =
        AssemblyOptions { method: scene.solver.constraint_method(), pressure_scaling: PressureScaling::None };
    Ok(assemble_projected(&shape, &scene.material, &scene.constraints, &opts)?)
}

fn assemble_on(scene: &Model, body: &BodyShape, positions: &[Vec3], areas: &[Vec3]) -> Result<System> {
    let shape = Body {
        axes: body.boundary.axes(),
        positions,
        vertex_areas: areas,
        edges: &body.edges,
        fibers: &body.fibers,
        rest_positions: Some(&body.rest),
    };
    let method = scene.solver.constraint_method();
    let scaling = match method {
        // The paper's form is kept as published (Eq. 8) when its penalty is asked for.
        ConstraintMethod::Penalty { .. } => PressureScaling::None,
        ConstraintMethod::Eliminate => PressureScaling::Auto,
    };
    let opts = AssemblyOptions { method, pressure_scaling: scaling };
    Ok(assemble(&shape, &scene.material, &scene.constraints, &opts)?)
}

/// Puts a numeric failure of step `step` in the user's terms: the likely cause and what
/// to try.
fn explain(e: Error, step: usize, from: f64, to: f64, n: usize) -> Error {
    use fibfluid_linalg::LinalgError as L;
    let soft = "the body may have folded or collapsed under this load (material too soft, or steps too large): raise young, take more load steps, or set [load] tolerance";
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
fn unknown(index: usize, n: usize) -> String {
    if n == 0 || index >= 3 * n {
        return "the pressure".into();
    }
    format!("vertex {} ({})", index % n, fibfluid_geometry::AXES[index / n])
}
