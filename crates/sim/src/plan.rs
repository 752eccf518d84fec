//! The plan of a run: which stages a scene needs, which it skips and why, and what each
//! costs in memory and floating-point operations — decided before any work is done.
//!
//! [`Plan::from_scene`] reads only the scene (the mesh is already loaded; the convexity
//! check is the one geometric test it makes, because it decides whether fibers need
//! visibility tests). [`Plan::check_memory`] refuses a plan whose peak memory exceeds a
//! limit, before anything large is allocated. The simulation follows the plan and the
//! report lists its stages.

use fibfluid_linalg::{Backend, Precision, cholesky_flops, lu_flops};
use serde::Serialize;

use crate::choices::{FiberModel, Method, Mode, Stepping};
use crate::model::{Model, Shape, VOLUME_NEWTON_ITERATIONS};
use crate::stages::{Stage, names};
use crate::{Error, Result};

/// One stage of the plan.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PlannedStage {
    /// Stage name (as in the report's stage list).
    pub name: Stage,
    /// Whether the stage runs.
    pub run: bool,
    /// Why it runs (what it is for) or why it is skipped.
    pub reason: String,
    /// Estimated bytes the stage holds at its peak (live at the same time as the
    /// earlier stages' data).
    pub bytes: u64,
    /// Estimated floating-point operations over the whole run.
    pub flops: f64,
}

/// The stages of a run, decided from the scene alone.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Plan {
    /// Every stage, in execution order, run or skipped.
    pub stages: Vec<PlannedStage>,
    /// Estimated peak memory of the run, in bytes.
    pub memory_bytes: u64,
    /// Estimated floating-point operations of the run.
    pub flops: f64,
}

/// What the plan needs to know about the body.
struct Size {
    n: f64,
    faces: f64,
    axes: usize,
    convex: bool,
    polygon: bool,
}

impl Plan {
    /// Plans the run of `scene` with its solver options and load steps.
    pub fn from_scene(scene: &Model) -> Plan {
        Self::planned(scene, |m| m.is_convex())
    }

    /// The plan from the model's counts alone: no geometric test (the body is taken as
    /// convex, which gives the smallest plan), so it costs microseconds even for a mesh
    /// whose convexity check would take minutes. A model this plan refuses is refused
    /// before anything else runs.
    pub fn from_counts(scene: &Model) -> Plan {
        Self::planned(scene, |_| true)
    }

    /// The plan with the mesh's convexity decided by `convex`.
    fn planned(scene: &Model, convex: impl Fn(&fibfluid_geometry::TriMesh) -> bool) -> Plan {
        if scene.solver.method == Method::Fem {
            return fem_plan(scene);
        }
        let size = match &scene.shape {
            Shape::Surface(m) => Size {
                n: m.mesh.n_vertices() as f64,
                faces: m.mesh.n_faces() as f64,
                axes: 3,
                convex: convex(&m.mesh),
                polygon: false,
            },
            Shape::Polygon(p) => Size {
                n: p.n_vertices() as f64,
                faces: p.n_vertices() as f64,
                axes: 2,
                convex: true,
                polygon: true,
            },
        };
        plan(scene, &size)
    }

    /// Whether stage `name` runs.
    pub fn runs(&self, name: Stage) -> bool {
        self.stages.iter().any(|s| s.name == name && s.run)
    }

    /// The skipped stages and why.
    pub fn skipped(&self) -> impl Iterator<Item = &PlannedStage> {
        self.stages.iter().filter(|s| !s.run)
    }

    /// The stage holding the most memory.
    pub fn largest_stage(&self) -> Option<&PlannedStage> {
        self.stages.iter().filter(|s| s.run).max_by_key(|s| s.bytes)
    }

    /// Refuses the plan when its peak memory exceeds `limit` bytes.
    pub fn check_memory(&self, scene: &str, limit: u64, backend: Backend) -> Result<()> {
        if self.memory_bytes <= limit {
            return Ok(());
        }
        Err(Error::TooLarge {
            scene: scene.to_string(),
            stage: self.largest_stage().map(|s| s.name).unwrap_or(names::FACTORIZATION),
            needed: self.memory_bytes,
            available: limit,
            hint: if self.runs(names::VOXELIZATION) {
                "lower [fem] resolution"
            } else if self
                .stages
                .iter()
                .any(|s| s.name == names::FACTORIZATION && s.reason.contains("projected"))
            {
                "use a coarser mesh or fibers = \"paper\" (the projected fibers' stiffness is dense 3N x 3N)"
            } else if backend.is_dense() {
                "use the `structured` backend (it never forms the dense matrix) or a coarser mesh"
            } else {
                "use a coarser mesh (the stiffness blocks are dense N x N)"
            },
        })
    }
}

fn stage(name: Stage, run: bool, reason: impl Into<String>, bytes: f64, flops: f64) -> PlannedStage {
    PlannedStage {
        name,
        run,
        reason: reason.into(),
        bytes: if run { bytes as u64 } else { 0 },
        flops: if run { flops } else { 0.0 },
    }
}

/// The sizes every stage's cost is computed from.
struct Costs {
    n: f64,
    faces: f64,
    d: f64,
    steps: f64,
    evaluations: f64,
    blocks: f64,
    block_bytes: f64,
    dim: f64,
    dense: bool,
    solve_flops: f64,
    /// Side of the projected fibers' coupled stiffness (0: paper fibers).
    projected: f64,
}

impl Costs {
    fn of(scene: &Model, size: &Size) -> Self {
        let Size { n, faces, axes, .. } = *size;
        let d = axes as f64;
        let solver = &scene.solver;
        let shared = scene.material.is_isotropic() && scene.constraints.is_uniform(axes);
        let blocks = if shared { 1.0 } else { d };
        let dim = d * n + 1.0;
        let dense = solver.backend.is_dense();
        Self {
            n,
            faces,
            d,
            steps: scene.load.steps as f64,
            evaluations: if solver.stepping == Stepping::Heun { 2.0 } else { 1.0 },
            blocks,
            block_bytes: blocks * n * n * 8.0,
            dim,
            dense,
            solve_flops: if scene.ffm.fibers == FiberModel::Projected {
                6.0 * d * d * n * n
            } else if dense {
                2.0 * dim * dim
            } else {
                4.0 * d * n * n
            },
            projected: projected_side(scene, size),
        }
    }
}

fn plan(scene: &Model, size: &Size) -> Plan {
    let costs = Costs::of(scene, size);
    let mut st = setup_stages(scene, size, &costs);
    st.push(factor_stage(scene, &costs));
    st.extend(load_stages(scene, &costs));
    st.extend(step_stages(scene, &costs));
    let memory_bytes = st.iter().map(|s| s.bytes).sum();
    let flops = st.iter().map(|s| s.flops).sum();
    Plan { stages: st, memory_bytes, flops }
}

/// Fibers, areas and assembly.
fn setup_stages(scene: &Model, size: &Size, c: &Costs) -> Vec<PlannedStage> {
    let Size { axes, convex, polygon, .. } = *size;
    let Costs { n, faces, block_bytes, .. } = *c;
    let shared = c.blocks == 1.0;
    let mut st = Vec::new();
    st.push(if polygon {
        stage(names::CONVEXITY, false, "2D polygon: every fiber is kept", 0.0, 0.0)
    } else {
        stage(names::CONVEXITY, true, "decides whether fibers need visibility tests", 0.0, 6.0 * n * faces)
    });
    let fiber_bytes = n * n / 16.0 + 4.0 * n;
    st.push(if polygon {
        stage(names::VISIBILITY, false, "2D polygon: every fiber is kept", 0.0, 0.0)
    } else if convex {
        stage(names::VISIBILITY, false, "the mesh is convex: every fiber is kept", 0.0, 0.0)
    } else {
        let tests = n * (n - 1.0) / 2.0 * (faces.max(2.0).log2() * 30.0 + 20.0);
        stage(
            names::VISIBILITY,
            true,
            "the mesh is concave: exit and crossing tests cull fibers",
            fiber_bytes,
            tests,
        )
    });
    st.push(stage(names::AREAS, true, "vertex area vectors S (Eq. 2)", 0.0, 30.0 * faces));
    let gamma = scene.material.surface_tension() > 0.0;
    let projected = projected_side(scene, size);
    let assembly_bytes =
        (1.0 + if gamma { 1.0 } else { 0.0 }) * n * n * 8.0 + block_bytes + projected * projected * 8.0;
    let blocks_reason = if shared {
        "one shared N x N block (isotropic material, the same constraints on every axis)".to_string()
    } else {
        format!("{axes} N x N blocks (anisotropic material or different constraints per axis)")
    };
    let blocks_reason = if projected > 0.0 {
        format!("{blocks_reason}; projected fibers: one coupled {projected} x {projected} matrix")
    } else {
        blocks_reason
    };
    st.push(stage(
        names::ASSEMBLY,
        true,
        format!("bulk fibers (Eq. 6); {blocks_reason}"),
        assembly_bytes,
        25.0 * n * n,
    ));
    st.push(if gamma {
        stage(
            names::SURFACE_FIBERS,
            true,
            "surface tension > 0: fibers along mesh edges (Eq. 7)",
            0.0,
            20.0 * faces,
        )
    } else {
        stage(names::SURFACE_FIBERS, false, "surface tension is 0", 0.0, 0.0)
    });

    st
}

/// The side dN of the projected fibers' coupled stiffness (0 with the paper's fibers).
fn projected_side(scene: &Model, size: &Size) -> f64 {
    if scene.ffm.fibers == FiberModel::Projected { size.axes as f64 * size.n } else { 0.0 }
}

/// The factorization: once, plus one per operator evaluation when the operator changes.
fn factor_stage(scene: &Model, c: &Costs) -> PlannedStage {
    let Costs { n, steps, evaluations, blocks, dim, dense, .. } = *c;
    let solver = &scene.solver;
    let mixed = solver.precision == Precision::Mixed;
    // Factorizations: once, plus one per operator evaluation when the operator changes
    // (nonlinear mode always; refresh mode with a dense backend, which refactors for a
    // new border).
    let refactors = match solver.mode {
        Mode::Paper => 0.0,
        Mode::Refresh if dense => steps * evaluations,
        Mode::Refresh => 0.0,
        Mode::Nonlinear => steps * evaluations,
    };
    let (factor_bytes, factor_flops, factor_reason) = if dense {
        let copies = if mixed { 1.5 } else { 2.0 };
        (
            copies * dim * dim * 8.0,
            lu_flops(dim as usize),
            format!("dense LU of the {dim} x {dim} matrix ({})", solver.backend),
        )
    } else {
        let word = if mixed { 12.0 } else { 8.0 };
        (
            blocks * n * n * word,
            blocks * cholesky_flops(n as usize),
            format!("Cholesky of {blocks} N x N block(s) and the Schur complement ({})", solver.backend),
        )
    };
    let m = c.projected;
    let (factor_bytes, factor_flops, factor_reason) = if m > 0.0 {
        (
            factor_bytes + m * m * 8.0,
            factor_flops + cholesky_flops(m as usize),
            format!(
                "{factor_reason} (the paper's operator), and the projected fibers' dense Cholesky of the {m} x {m} coupled stiffness with the Schur complement of the border"
            ),
        )
    } else {
        (factor_bytes, factor_flops, factor_reason)
    };
    let factor_reason = match solver.mode {
        Mode::Paper => format!("{factor_reason}; once, on the rest shape"),
        Mode::Refresh if dense => format!("{factor_reason}; once, and again for each new border"),
        Mode::Refresh => format!("{factor_reason}; once (a new border costs triangular solves only)"),
        Mode::Nonlinear => format!("{factor_reason}; once per operator evaluation"),
    };
    stage(names::FACTORIZATION, true, factor_reason, factor_bytes, factor_flops * (1.0 + refactors))
}

/// The loads and the operator refreshes of every step.
fn load_stages(scene: &Model, c: &Costs) -> Vec<PlannedStage> {
    let Costs { n, faces, d, steps, evaluations, block_bytes, dense, .. } = *c;
    let solver = &scene.solver;
    let mut st = Vec::new();
    let hydrostatic = scene.material.density() > 0.0 && scene.load.gravity != [0.0; 3];
    let forces = !scene.load.forces.is_empty();
    let loads_reason = match (hydrostatic, forces) {
        (true, true) => format!("hydrostatic pressure and {} point force(s)", scene.load.forces.len()),
        (true, false) => "hydrostatic pressure rho a h S".into(),
        (false, true) => format!("{} point force(s)", scene.load.forces.len()),
        (false, false) if scene.load.gravity != [0.0; 3] => {
            "nothing acts: gravity acts through the fluid, and [fluid] density is 0".into()
        }
        (false, false) => "nothing acts: no gravity, no point forces".into(),
    };
    st.push(stage(
        names::LOADS,
        hydrostatic || forces,
        loads_reason,
        d * n * 8.0,
        steps * evaluations * (10.0 + d * 2.0) * n,
    ));

    // Solves per step: one per evaluation; refresh and nonlinear add one volume
    // correction (its direction; the volume is then restored by scalar Newton steps).
    st.push(match solver.mode {
        Mode::Refresh => stage(
            names::BORDER,
            true,
            if dense {
                "new border S from the current shape (refactors the dense matrix)"
            } else {
                "new border S from the current shape: K^-1 S by triangular solves"
            },
            d * n * 8.0,
            // The projected fibers' K^-1 S: one solve with their dense factor too.
            steps * evaluations * 2.0 * (d * n * n + c.projected * c.projected),
        ),
        Mode::Paper => stage(names::BORDER, false, "paper mode keeps the rest-shape border", 0.0, 0.0),
        Mode::Nonlinear => stage(names::BORDER, false, "nonlinear mode re-assembles everything", 0.0, 0.0),
    });
    st.push(match solver.mode {
        Mode::Paper => stage(names::VOLUME, false, "paper mode asks the volume row for 0", 0.0, 0.0),
        _ => stage(
            names::VOLUME,
            true,
            "volume row asks for V0 - V of the current shape",
            0.0,
            steps * evaluations * 40.0 * faces,
        ),
    });
    st.push(match solver.mode {
        Mode::Nonlinear => stage(
            names::REASSEMBLY,
            true,
            "K, S and loads re-assembled on the current shape",
            block_bytes + n * n * 8.0,
            steps * evaluations * 25.0 * n * n,
        ),
        Mode::Paper => stage(names::REASSEMBLY, false, "paper mode factors once", 0.0, 0.0),
        Mode::Refresh => stage(names::REASSEMBLY, false, "refresh mode keeps K's factorization", 0.0, 0.0),
    });
    st
}

/// Solves, volume correction, contact, predictor and update of every step.
fn step_stages(scene: &Model, c: &Costs) -> Vec<PlannedStage> {
    let Costs { n, faces, d, steps, evaluations, dim, solve_flops, .. } = *c;
    let solver = &scene.solver;
    let heun = evaluations == 2.0;
    let mut st = Vec::new();
    st.push(stage(
        names::SOLVE,
        true,
        format!("{} solve(s) per step", if heun { "two" } else { "one" }),
        2.0 * dim * 8.0,
        steps * evaluations * solve_flops,
    ));
    st.push(match solver.mode {
        Mode::Paper => stage(names::VOLUME_CORRECTION, false, "paper mode lets the volume drift", 0.0, 0.0),
        _ => stage(
            names::VOLUME_CORRECTION,
            true,
            format!(
                "one solve per step gives the correction's direction; up to {VOLUME_NEWTON_ITERATIONS} scalar Newton steps along it restore V0"
            ),
            0.0,
            steps * (solve_flops + VOLUME_NEWTON_ITERATIONS as f64 * 60.0 * faces),
        ),
    });
    st.push(if scene.plates.is_empty() {
        stage(names::CONTACT, false, "no plates", 0.0, 0.0)
    } else {
        // A contact costs one solve when it joins the set (again after each new operator
        // outside paper mode); assume a tenth of the vertices touch.
        let contacts = (n / 10.0).max(1.0);
        let rebuilds = if solver.mode == Mode::Paper { 1.0 } else { steps * evaluations };
        stage(
            names::CONTACT,
            true,
            format!(
                "{} plate(s): frictionless contact, an active set per step, held by a capacitance update of the kept factorization",
                scene.plates.len()
            ),
            contacts * dim * 8.0,
            rebuilds * contacts * solve_flops,
        )
    });
    st.push(if heun {
        stage(
            names::PREDICTOR,
            true,
            "Heun: the step is evaluated again on the predicted shape",
            d * n * 8.0,
            0.0,
        )
    } else {
        stage(names::PREDICTOR, false, "Euler stepping", 0.0, 0.0)
    });
    st.push(stage(names::UPDATE, true, "positions += du", 0.0, steps * d * n));
    st
}

/// Newton iterations a plan expects without plates (measured: 11 for liver-hanging at
/// resolution 24, docs/performance.md).
pub const EXPECTED_NEWTON_ITERATIONS: usize = 15;
/// Newton iterations a plan expects with plates, contact augmentations included (measured:
/// 26 for breast-compression at resolution 24).
pub const EXPECTED_NEWTON_ITERATIONS_WITH_PLATES: usize = 30;

/// Newton iterations a plan expects on the grasps' optimality conditions (measured: 4 on
/// liver-grasp, 6 at resolution 12).
pub const EXPECTED_GRASP_ITERATIONS: usize = 5;

/// The voxelization of a grid estimate: its cells and their fill samples.
fn voxelization_stage(e: &fibfluid_fem::GridEstimate) -> PlannedStage {
    let cells = e.cells as f64;
    let samples = (fibfluid_fem::SUBSAMPLES as f64).powi(3);
    stage(
        names::VOXELIZATION,
        true,
        format!(
            "{} x {} x {} cells of {:.3e} m, fill from {samples} samples each",
            e.dims[0], e.dims[1], e.dims[2], e.cell_size
        ),
        cells * 80.0,
        cells * samples * 40.0,
    )
}

/// The stages of a Newton run: per iteration one assembly of the gradient and tangent (8 Gauss
/// points, a 9 x 9 tangent and the 24 x 24 cell matrix each), one numeric refactorization on
/// the kept symbolic analysis, one solve and a line search.
fn newton_stages(e: &fibfluid_fem::GridEstimate, scene: &Model) -> Vec<PlannedStage> {
    let iterations = if scene.plates.is_empty() {
        EXPECTED_NEWTON_ITERATIONS
    } else {
        EXPECTED_NEWTON_ITERATIONS_WITH_PLATES
    };
    let n = iterations as f64;
    let cells = e.cells as f64;
    // The grasps' rows and their compliance columns (hyper/grasp_kkt.rs), a few iterations.
    let rows = 3 * scene.fem.grasps.iter().map(|g| g.vertices.len()).sum::<usize>();
    let columns = (8 * rows * e.dofs).min(fibfluid_fem::hyper::GRASP_COLUMNS_BYTES) as f64;
    let grasps = if rows > 0 {
        format!(
            "; the grasps' {rows} rows met by Newton on their conditions (~{EXPECTED_GRASP_ITERATIONS} iterations), their compliance columns {:.1} MiB",
            columns / (1 << 20) as f64
        )
    } else {
        String::new()
    };
    let grasp_flops = (EXPECTED_GRASP_ITERATIONS * rows) as f64 * 4.0 * e.factor_nonzeros;
    vec![
        voxelization_stage(e),
        stage(
            names::ASSEMBLY,
            true,
            format!(
                "per Newton iteration: gradient and tangent of {} cells, {} stored nonzeros; x ~{iterations} iterations",
                e.cells, e.nonzeros
            ),
            e.nonzeros as f64 * 16.0,
            n * cells * 8.0 * 2.0 * (24.0 * 9.0 * 3.0 + 24.0 * 24.0 * 3.0),
        ),
        linear_solve_stage(e, scene, n),
        stage(
            names::SOLVE,
            true,
            format!(
                "Newton's method, load steps and contact augmentations: ~{iterations} iterations expected (docs/performance.md){grasps}"
            ),
            e.dofs as f64 * 8.0 * 4.0 + columns,
            n * 4.0 * e.factor_nonzeros + grasp_flops,
        ),
    ]
}

/// A Newton run's linear solves, `n` iterations: the sparse Cholesky's numeric
/// factorizations, or the multigrid's levels and preconditioned solves, as
/// `[fem] solver` resolves on this grid; the description names the other's cost too.
fn linear_solve_stage(e: &fibfluid_fem::GridEstimate, scene: &Model, n: f64) -> PlannedStage {
    let chosen = scene.fem.solver.resolve(e.dofs);
    let how = match scene.fem.solver {
        fibfluid_fem::FemSolver::Auto => format!(
            "[fem] solver = \"auto\" picks {chosen} ({} unknowns; multigrid from {})",
            e.dofs,
            fibfluid_fem::MULTIGRID_CROSSOVER_DOFS
        ),
        s => format!("[fem] solver = \"{s}\""),
    };
    let direct = format!(
        "direct: numeric sparse Cholesky of up to {} unknowns, ~{:.3e} factor nonzeros, {:.2e} bytes, {:.2e} flops",
        e.dofs, e.factor_nonzeros, e.factor_bytes, e.factor_flops
    );
    let multigrid = format!(
        "multigrid: Galerkin levels and ~{} preconditioned iterations, {:.2e} bytes, {:.2e} flops",
        fibfluid_fem::MULTIGRID_ITERATIONS,
        e.multigrid_bytes,
        e.multigrid_flops
    );
    let (bytes, flops) = e.solver_cost(scene.fem.solver);
    stage(
        names::FACTORIZATION,
        true,
        format!("per Newton iteration, {how}; {direct}; {multigrid}; x ~{n} iterations"),
        bytes,
        n * flops,
    )
}

/// The finite-element method's plan, from the grid's estimate (counts only): voxelization,
/// assembly, factorization and one solve; for a Newton run (a neo-Hookean tissue, plates or
/// regions) the assembly, refactorization and solve of each iteration times the expected
/// count.
fn fem_plan(scene: &Model) -> Plan {
    let positions = scene.rest_positions();
    let estimate = fibfluid_fem::GridEstimate::of(&positions, scene.fem.resolution);
    let multigrid = estimate.as_ref().is_ok_and(|e| !e.uses_direct_solver(scene.fem.solver));
    let newton = scene.tissue.is_some_and(|t| !t.is_linear())
        || multigrid
        || !scene.plates.is_empty()
        || !scene.fem.regions.is_empty()
        || !scene.fem.grasps.is_empty()
        || scene.fem.time.is_some();
    let mut st = match estimate {
        Ok(e) if newton => newton_stages(&e, scene),
        Ok(e) => {
            let cells = e.cells as f64;
            vec![
                voxelization_stage(&e),
                stage(
                    names::ASSEMBLY,
                    true,
                    format!("B-bar hexahedra: K with up to {} stored nonzeros", e.nonzeros),
                    e.nonzeros as f64 * 16.0,
                    cells * 24.0 * 24.0 * 2.0,
                ),
                stage(
                    names::FACTORIZATION,
                    true,
                    format!(
                        "sparse Cholesky of up to {} unknowns (~{:.3e} factor nonzeros, estimated)",
                        e.dofs, e.factor_nonzeros
                    ),
                    e.factor_bytes,
                    e.factor_flops,
                ),
                stage(
                    names::SOLVE,
                    true,
                    "one solve: the whole load at once (linear)",
                    e.dofs as f64 * 8.0,
                    4.0 * e.factor_nonzeros,
                ),
            ]
        }
        Err(e) => vec![stage(names::VOXELIZATION, false, format!("cannot build the grid: {e}"), 0.0, 0.0)],
    };
    st.extend(time_stage(scene, &positions, &st));
    let memory_bytes = st.iter().map(|s| s.bytes).sum();
    let flops = st.iter().map(|s| s.flops).sum();
    Plan { stages: st, memory_bytes, flops }
}

/// Newton iterations a plan expects per time step (measured: 78 over the 31 steps of
/// fixtures/scenes/block-relaxation.toml, 16 for its 10 ms push and then 2 a step while
/// held; 3 leaves room for a load that keeps moving).
pub const EXPECTED_TIME_STEP_ITERATIONS: usize = 3;

/// A timed run (`[time]`): its steps (the end over the largest step, and those the load
/// curve's points and the output times add), each ~[`EXPECTED_TIME_STEP_ITERATIONS`]
/// Newton iterations at the per-iteration cost of the Newton stages in `newton` (which
/// count the static run's expected iterations: this stage's flops are the rest); its
/// memory the laws' history, Newmark's vectors and the kept surface samples.
fn time_stage(
    scene: &Model,
    positions: &[fibfluid_geometry::Vec3],
    newton: &[PlannedStage],
) -> Option<PlannedStage> {
    let timed = scene.fem.time.as_ref()?;
    let e = fibfluid_fem::GridEstimate::of(positions, scene.fem.resolution).ok()?;
    let s = &timed.settings;
    let steps = s.planned_steps(&timed.curve);
    let counted = if scene.plates.is_empty() {
        EXPECTED_NEWTON_ITERATIONS
    } else {
        EXPECTED_NEWTON_ITERATIONS_WITH_PLATES
    };
    let per_iteration = newton
        .iter()
        .filter(|x| [names::ASSEMBLY, names::FACTORIZATION, names::SOLVE].contains(&x.name))
        .map(|x| x.flops)
        .sum::<f64>()
        / counted as f64;
    let iterations = steps * EXPECTED_TIME_STEP_ITERATIONS;
    let terms = scene.tissue.map_or(0, |t| t.relaxation().terms().len());
    let history = if terms > 0 { e.cells as f64 * 8.0 * 7.0 * (terms + 1) as f64 * 8.0 } else { 0.0 };
    let kept = s.outputs() as f64 * positions.len() as f64 * 24.0;
    Some(stage(
        names::TIME_STEPS,
        true,
        format!(
            "{} steps of {} s (end {} s / step), {steps} steps with the curve's points and the output times; x ~{EXPECTED_TIME_STEP_ITERATIONS} Newton iterations each: ~{iterations} iterations at {:.2e} flops (the Newton stages count {counted}); {} outputs",
            s.min_steps(),
            s.step,
            s.end,
            per_iteration,
            s.outputs()
        ),
        history + 6.0 * e.dofs as f64 * 8.0 + kept,
        iterations.saturating_sub(counted) as f64 * per_iteration,
    ))
}
