//! Load stepping: the simulation of one scene.

use std::time::Instant;

use fibfluid_assembly::{AssemblyOptions, Body, ConstraintMethod, PressureScaling, System, assemble, depths};
use fibfluid_geometry::{
    FiberSet, Polygon, Vec3, VisibilityOptions, cull_fibers, vertex_area_vectors, volume,
};
use fibfluid_linalg::{FactorOptions, Factorization, FactorizationExt, LinearSolver, backend_by_name};

use crate::scene::{ForceTiming, Mode, Scene, Shape, Stepping};
use crate::stages::{StageLog, names};
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

/// The geometry a simulation needs besides positions.
#[derive(Clone, Debug)]
enum Topology {
    Surface { triangles: Vec<[u32; 3]> },
    Polygon,
}

/// A scene being simulated: the current shape, pressure and factorization.
pub struct Simulation {
    scene: Scene,
    topology: Topology,
    axes: usize,
    edges: Vec<[u32; 2]>,
    fibers: FiberSet,
    convex: bool,
    rest: Vec<Vec3>,
    positions: Vec<Vec3>,
    pressure: f64,
    volume0: f64,
    system: System,
    factorization: Box<dyn Factorization>,
    solver: Box<dyn LinearSolver>,
    factor_options: FactorOptions,
    /// Which shape the operator currently describes (for refresh/nonlinear).
    border_areas: Vec<Vec3>,
    log: StageLog,
    residual_max: f64,
    refinement_steps_max: usize,
    factorizations: usize,
    solves: usize,
    started: Instant,
}

/// Where a step's loads point: compression (+1) or decompression (-1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    /// Apply the loads.
    Load,
    /// Remove them again (same steps, opposite sign).
    Unload,
}

impl Simulation {
    /// Prepares a scene: fibers, assembly and the first factorization. Only the stages the
    /// scene needs run; the others are recorded as skipped with the reason.
    pub fn new(scene: Scene) -> Result<Self> {
        Self::with_factor_options(scene, FactorOptions::default())
    }

    /// [`new`](Self::new) with explicit factorization options (precision is taken from the
    /// scene's solver options).
    pub fn with_factor_options(scene: Scene, mut factor_options: FactorOptions) -> Result<Self> {
        let started = Instant::now();
        let mut log = StageLog::default();
        factor_options.precision = scene.solver.precision;
        let solver = backend_by_name(&scene.solver.backend)?;
        let rest = scene.rest_positions();
        let n = rest.len();
        let (topology, axes, edges, fibers, convex) = match &scene.shape {
            Shape::Surface(file) => {
                let mesh = &file.mesh;
                let convex = log.time(names::CONVEXITY, || mesh.is_convex());
                let fibers = if convex {
                    log.skip(names::VISIBILITY, "the mesh is convex: every fiber is kept");
                    FiberSet::all(n)
                } else {
                    let opts = VisibilityOptions { force_tests: true, ..Default::default() };
                    log.time(names::VISIBILITY, || cull_fibers(mesh, &opts).0)
                };
                let edges = mesh.adjacency().edges();
                (Topology::Surface { triangles: mesh.triangles().to_vec() }, 3, edges, fibers, convex)
            }
            Shape::Polygon(p) => {
                log.skip(names::CONVEXITY, "2D polygon: every fiber is kept");
                log.skip(names::VISIBILITY, "2D polygon: every fiber is kept");
                (Topology::Polygon, 2, p.edges(), FiberSet::all(n), true)
            }
        };
        if scene.material.surface_tension == 0.0 {
            log.skip(names::SURFACE_FIBERS, "surface tension is 0");
        }
        let has_gravity = scene.gravity != [0.0; 3] && scene.material.density > 0.0;
        if !has_gravity {
            let why = if scene.gravity == [0.0; 3] { "no gravity" } else { "fluid density is 0" };
            log.skip(names::DEPTHS, why);
            log.skip(names::HYDROSTATIC, why);
        }
        if scene.forces.is_empty() {
            log.skip(names::FORCES, "no point forces");
        }
        match scene.solver.mode {
            Mode::Paper => {
                log.skip(names::BORDER, "paper mode keeps the rest-shape border");
                log.skip(names::VOLUME, "paper mode asks the volume row for 0");
                log.skip(names::REASSEMBLY, "paper mode factors once");
            }
            Mode::Refresh => log.skip(names::REASSEMBLY, "refresh mode keeps K's factorization"),
            Mode::Nonlinear => log.skip(names::BORDER, "nonlinear mode re-assembles everything"),
        }
        if scene.solver.stepping == Stepping::Euler {
            log.skip(names::PREDICTOR, "Euler stepping");
        }
        let areas = log.time(names::AREAS, || areas_of(&topology, &rest));
        let volume0 = volume_of(&topology, &rest);
        let system =
            log.time(names::ASSEMBLY, || assemble_on(&scene, axes, &edges, &fibers, &rest, &rest, &areas))?;
        if system.stats.blocks == 1 {
            log.skip(
                "factorization of separate x, y, z blocks",
                "isotropic material with the same constraints on every axis: one block",
            );
        }
        let factorization =
            log.time(names::FACTORIZATION, || solver.factorize(&system.matrix, &factor_options))?;
        Ok(Self {
            topology,
            axes,
            edges,
            fibers,
            convex,
            positions: rest.clone(),
            rest,
            pressure: 0.0,
            volume0,
            system,
            factorization,
            solver,
            factor_options,
            border_areas: areas,
            log,
            residual_max: 0.0,
            refinement_steps_max: 0,
            factorizations: 1,
            solves: 0,
            started,
            scene,
        })
    }

    /// The scene.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// Current positions.
    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    /// Rest positions.
    pub fn rest_positions(&self) -> &[Vec3] {
        &self.rest
    }

    /// Accumulated pressure change.
    pub fn pressure(&self) -> f64 {
        self.pressure
    }

    /// Volume (area for a polygon) of the rest shape.
    pub fn volume_initial(&self) -> f64 {
        self.volume0
    }

    /// Volume of the current shape.
    pub fn volume(&self) -> f64 {
        volume_of(&self.topology, &self.positions)
    }

    /// The kept fibers.
    pub fn fibers(&self) -> &FiberSet {
        &self.fibers
    }

    /// Whether the body was found convex.
    pub fn convex(&self) -> bool {
        self.convex
    }

    /// The assembled system currently factored.
    pub fn system(&self) -> &System {
        &self.system
    }

    /// The current factorization.
    pub fn factorization(&self) -> &dyn Factorization {
        self.factorization.as_ref()
    }

    /// Stage log so far.
    pub fn log(&self) -> &StageLog {
        &self.log
    }

    /// Largest relative residual of any solve so far.
    pub fn residual_max(&self) -> f64 {
        self.residual_max
    }

    /// Number of factorizations so far.
    pub fn factorizations(&self) -> usize {
        self.factorizations
    }

    /// Number of solves so far.
    pub fn solves(&self) -> usize {
        self.solves
    }

    /// Largest refinement step count of any solve.
    pub fn refinement_steps_max(&self) -> usize {
        self.refinement_steps_max
    }

    /// Seconds since the simulation was created.
    pub fn elapsed(&self) -> f64 {
        self.started.elapsed().as_secs_f64()
    }

    /// Number of axes (2 for a polygon).
    pub fn axes(&self) -> usize {
        self.axes
    }

    /// Runs all the scene's load steps (compression).
    pub fn run(&mut self, opts: &RunOptions) -> Result<()> {
        self.run_steps(self.scene.steps, Direction::Load, opts)
    }

    /// Runs `steps` load steps in one direction.
    pub fn run_steps(&mut self, steps: usize, direction: Direction, opts: &RunOptions) -> Result<()> {
        for k in 0..steps {
            self.step(k, steps, direction)?;
            if let Some(p) = &opts.progress {
                p(k + 1, steps);
            }
        }
        Ok(())
    }

    /// The static response of the current factorization to point forces alone (no
    /// stepping, no position update): the interactive use of a factored body.
    pub fn respond(&mut self, forces: &[(usize, Vec3)]) -> Result<(Vec<Vec3>, f64)> {
        let n = self.positions.len();
        if let Some(&(v, _)) = forces.iter().find(|(v, _)| *v >= n) {
            return Err(Error::Invalid(format!("force on vertex {v}, but the body has {n} vertices")));
        }
        let mut b = vec![0.0; self.axes * n];
        for &(v, f) in forces {
            for c in 0..self.axes {
                b[c * n + v] += f[c];
            }
        }
        let x = self.solve(&b, 0.0, 1.0)?;
        Ok(self.system.split_solution(&x))
    }

    /// One load step `k` of `steps`.
    pub fn step(&mut self, k: usize, steps: usize, direction: Direction) -> Result<()> {
        let sign = if direction == Direction::Load { 1.0 } else { -1.0 };
        let da = self.scene.gravity.map(|g| sign * g / steps as f64);
        let force_inc: Vec<(usize, Vec3)> = self
            .scene
            .forces
            .iter()
            .filter_map(|f| match f.timing {
                ForceTiming::Ramp => Some((f.vertex, f.value.map(|c| sign * c / steps as f64))),
                ForceTiming::Last => {
                    let now = match direction {
                        Direction::Load => k + 1 == steps,
                        Direction::Unload => k == 0,
                    };
                    now.then(|| (f.vertex, f.value.map(|c| sign * c)))
                }
            })
            .collect();
        let prescribed = sign / steps as f64;
        let s = self.positions.clone();
        let target = self.prepare_operator(&s)?;
        let b1 = self.load_increment(&s, da, &force_inc);
        let du = match self.scene.solver.stepping {
            Stepping::Euler => {
                let x = self.solve(&b1, target, prescribed)?;
                self.system.split_solution(&x)
            }
            Stepping::Heun => {
                let xb = self.solve(&b1, 0.0, prescribed)?;
                let (ub, pb) = self.system.split_solution(&xb);
                let (ut, pt) = if target != 0.0 {
                    let zero = vec![0.0; b1.len()];
                    let xt = self.solve(&zero, target, 0.0)?;
                    self.system.split_solution(&xt)
                } else {
                    (vec![[0.0; 3]; s.len()], 0.0)
                };
                let predicted: Vec<Vec3> = (0..s.len()).map(|i| add3(add3(s[i], ub[i]), ut[i])).collect();
                let start = Instant::now();
                self.prepare_operator(&predicted)?;
                let b2 = self.load_increment(&predicted, da, &force_inc);
                let x2 = self.solve(&b2, 0.0, prescribed)?;
                let (u2, p2) = self.system.split_solution(&x2);
                self.log.add(names::PREDICTOR, start.elapsed().as_secs_f64());
                let u =
                    (0..s.len()).map(|i| add3(add3(scale3(ub[i], 0.5), scale3(u2[i], 0.5)), ut[i])).collect();
                (u, 0.5 * pb + 0.5 * p2 + pt)
            }
        };
        self.log.time(names::UPDATE, || {
            for (p, d) in self.positions.iter_mut().zip(&du.0) {
                *p = add3(*p, *d);
            }
        });
        self.pressure += du.1;
        if self.scene.solver.mode != Mode::Paper {
            self.correct_volume()?;
        }
        Ok(())
    }

    /// Makes the factored operator describe shape `s` as the mode requires; returns the
    /// volume target for the last row.
    fn prepare_operator(&mut self, s: &[Vec3]) -> Result<f64> {
        match self.scene.solver.mode {
            Mode::Paper => Ok(0.0),
            Mode::Refresh => {
                let areas = self.log.time(names::AREAS, || areas_of(&self.topology, s));
                let border = self.system.border_for(&areas);
                let start = Instant::now();
                self.system.matrix.set_border(&border);
                self.factorization.set_border(&border)?;
                // A dense backend refactors the whole matrix for a new border: say so.
                if self.factorization.border_update_refactors() {
                    self.factorizations += 1;
                    self.log.add(names::FACTORIZATION, start.elapsed().as_secs_f64());
                } else {
                    self.log.add(names::BORDER, start.elapsed().as_secs_f64());
                }
                let start = Instant::now();
                let target = self.volume_target(s, &areas);
                self.log.add(names::VOLUME, start.elapsed().as_secs_f64());
                self.border_areas = areas;
                Ok(target)
            }
            Mode::Nonlinear => {
                let areas = self.log.time(names::AREAS, || areas_of(&self.topology, s));
                let start = Instant::now();
                let system =
                    assemble_on(&self.scene, self.axes, &self.edges, &self.fibers, s, &self.rest, &areas)?;
                self.log.add(names::REASSEMBLY, start.elapsed().as_secs_f64());
                let start = Instant::now();
                self.factorization = self.solver.factorize(&system.matrix, &self.factor_options)?;
                self.log.add(names::FACTORIZATION, start.elapsed().as_secs_f64());
                self.factorizations += 1;
                self.system = system;
                let start = Instant::now();
                let target = self.volume_target(s, &areas);
                self.log.add(names::VOLUME, start.elapsed().as_secs_f64());
                self.border_areas = areas;
                Ok(target)
            }
        }
    }

    /// The volume row's target on shape `s` with border `areas`: the row asks
    /// `sum S_i . u_i = t`, while the volume changes by `sum G_i . u_i` to first order with
    /// `G` the exact gradient, parallel to `S` (`G = S / (3C)` on a surface, `S / (2C)` on a
    /// polygon). So `t = (V0 - V) / r` with `r = sum |G_i| / sum |S_i|`.
    fn volume_target(&self, s: &[Vec3], areas: &[Vec3]) -> f64 {
        let v = volume_of(&self.topology, s);
        let g = gradient_of(&self.topology, s);
        let sum_g: f64 = g.iter().map(|v| norm3(*v)).sum();
        let sum_s: f64 = areas.iter().map(|v| norm3(*v)).sum();
        let r = if sum_s > 0.0 && sum_g > 0.0 { sum_g / sum_s } else { 1.0 };
        (self.volume0 - v) / r
    }

    /// Pulls the volume back to V0 after a step (refresh and nonlinear modes): up to
    /// [`VOLUME_CORRECTIONS`] solves with no load and the volume target of the new shape,
    /// using the current factorization.
    fn correct_volume(&mut self) -> Result<()> {
        for _ in 0..VOLUME_CORRECTIONS {
            let v = volume_of(&self.topology, &self.positions);
            if (v / self.volume0 - 1.0).abs() <= VOLUME_TOLERANCE {
                break;
            }
            let start = Instant::now();
            let areas = areas_of(&self.topology, &self.positions);
            let target = self.volume_target(&self.positions.clone(), &areas);
            let zero = vec![0.0; self.axes * self.positions.len()];
            let x = self.solve(&zero, target, 0.0)?;
            let (du, dp) = self.system.split_solution(&x);
            for (p, d) in self.positions.iter_mut().zip(&du) {
                *p = add3(*p, *d);
            }
            self.pressure += dp;
            self.log.add(names::VOLUME_CORRECTION, start.elapsed().as_secs_f64());
        }
        Ok(())
    }

    /// Load increment on shape `s`: `rho |da| h_i S_i` plus the point-force increments.
    fn load_increment(&mut self, s: &[Vec3], da: Vec3, forces: &[(usize, Vec3)]) -> Vec<f64> {
        let n = s.len();
        let axes = self.axes;
        let mut b = vec![0.0; axes * n];
        let mag = (da[0] * da[0] + da[1] * da[1] + da[2] * da[2]).sqrt();
        let rho = self.scene.material.density;
        if mag > 0.0 && rho > 0.0 {
            // Depth is measured along the scene's gravity; an unloading step has the
            // opposite increment but the same "down".
            let g = self.scene.gravity;
            let h = self.log.time(names::DEPTHS, || depths(s, g));
            // Paper mode keeps the rest border, so the load needs S of `s`; the other modes
            // have just made the border describe `s` (prepare_operator runs first).
            let computed;
            let areas: &[Vec3] = if self.scene.solver.mode == Mode::Paper {
                computed = self.log.time(names::AREAS, || areas_of(&self.topology, s));
                &computed
            } else {
                &self.border_areas
            };
            let gdot = g[0] * da[0] + g[1] * da[1] + g[2] * da[2];
            let signed = if gdot >= 0.0 { mag } else { -mag };
            self.log.time(names::HYDROSTATIC, || {
                for i in 0..n {
                    let w = rho * signed * h[i];
                    for c in 0..axes {
                        b[c * n + i] += w * areas[i][c];
                    }
                }
            });
        }
        if !forces.is_empty() {
            self.log.time(names::FORCES, || {
                for &(v, f) in forces {
                    for c in 0..axes {
                        b[c * n + v] += f[c];
                    }
                }
            });
        }
        b
    }

    fn solve(&mut self, b: &[f64], target: f64, prescribed_scale: f64) -> Result<Vec<f64>> {
        let rhs = self.system.rhs(b, target, &self.border_areas, prescribed_scale);
        let start = Instant::now();
        let sol = self.factorization.solve(&rhs)?;
        self.log.add(names::SOLVE, start.elapsed().as_secs_f64());
        self.solves += 1;
        self.residual_max = self.residual_max.max(sol.relative_residual);
        self.refinement_steps_max = self.refinement_steps_max.max(sol.refinement_steps);
        Ok(sol.x)
    }
}

/// At most this many volume-correction solves follow each step in refresh and nonlinear
/// modes.
pub const VOLUME_CORRECTIONS: usize = 6;

/// Relative volume error below which no correction solve is made.
pub const VOLUME_TOLERANCE: f64 = 1e-12;

fn norm3(a: Vec3) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

/// Exact gradient of the volume (area for a polygon) with respect to each vertex.
fn gradient_of(topology: &Topology, s: &[Vec3]) -> Vec<Vec3> {
    match topology {
        Topology::Surface { triangles } => fibfluid_geometry::raw_vertex_vectors(s, triangles)
            .into_iter()
            .map(|r| scale3(r, 1.0 / 3.0))
            .collect(),
        Topology::Polygon => {
            let n = s.len();
            let sign = polygon_at(s).map(|p| p.signed_area().signum()).unwrap_or(1.0);
            (0..n)
                .map(|i| {
                    let (a, b) = (s[(i + n - 1) % n], s[(i + 1) % n]);
                    // d(area)/d(s_i) = 1/2 perp(s_{i+1} - s_{i-1}) for a counter-clockwise polygon.
                    [0.5 * sign * (b[1] - a[1]), -0.5 * sign * (b[0] - a[0]), 0.0]
                })
                .collect()
        }
    }
}

fn add3(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn scale3(a: Vec3, s: f64) -> Vec3 {
    [a[0] * s, a[1] * s, a[2] * s]
}

fn polygon_at(s: &[Vec3]) -> Option<Polygon> {
    Polygon::new(s.iter().map(|p| [p[0], p[1]]).collect())
}

fn areas_of(topology: &Topology, s: &[Vec3]) -> Vec<Vec3> {
    match topology {
        Topology::Surface { triangles } => vertex_area_vectors(s, triangles),
        Topology::Polygon => match polygon_at(s) {
            Some(p) => p.vertex_area_vectors().into_iter().map(|v| [v[0], v[1], 0.0]).collect(),
            None => vec![[0.0; 3]; s.len()],
        },
    }
}

fn volume_of(topology: &Topology, s: &[Vec3]) -> f64 {
    match topology {
        Topology::Surface { triangles } => volume(s, triangles),
        Topology::Polygon => polygon_at(s).map(|p| p.signed_area().abs()).unwrap_or(0.0),
    }
}

fn assemble_on(
    scene: &Scene,
    axes: usize,
    edges: &[[u32; 2]],
    fibers: &FiberSet,
    positions: &[Vec3],
    rest: &[Vec3],
    areas: &[Vec3],
) -> Result<System> {
    let body = Body { axes, positions, vertex_areas: areas, edges, fibers, rest_positions: Some(rest) };
    let scaling = match scene.solver.constraints {
        // The paper's form is kept as published (Eq. 8) when its penalty is asked for.
        ConstraintMethod::Penalty { .. } => PressureScaling::None,
        ConstraintMethod::Eliminate => PressureScaling::Auto,
    };
    let opts = AssemblyOptions { method: scene.solver.constraints, pressure_scaling: scaling };
    Ok(assemble(&body, &scene.material, &scene.constraints, &opts)?)
}
