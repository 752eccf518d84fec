//! The run report (`report.json`) and the round-trip measure (Eq. 9).

use fibfluid_assembly::ConstraintKind;
use fibfluid_linalg::{Backend, Precision};
use serde::Serialize;

use crate::choices::{Mode, Stepping};
use crate::simulate::Simulation;
use crate::stages::{Stage, StageRecord};

/// A stage the plan left out, and why.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct SkippedStage {
    /// The stage.
    pub name: Stage,
    /// Why it was not needed.
    pub reason: String,
}

/// What a run did and how accurate it was: `report.json`. The groups are flattened into one
/// JSON object (the file reads as it always has); in code each group is a struct of its own.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Report {
    /// Model name.
    pub scene: String,
    /// The units of every number below (SI; the mesh file's unit for the written meshes).
    pub units: crate::fem_run::Units,
    /// The solver choices a run used.
    #[serde(flatten)]
    pub solver: SolverFacts,
    /// The body: its size and shape class.
    #[serde(flatten)]
    pub body: BodyFacts,
    /// The fiber–fluid method's fibers.
    #[serde(flatten)]
    pub ffm: FfmFacts,
    /// The load steps asked for and taken.
    #[serde(flatten)]
    pub load: StepFacts,
    /// What the guards found.
    #[serde(flatten)]
    pub guards: GuardFacts,
    /// Each plate's force, contact area, contacts and gap after every step (empty
    /// without plates).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub plates: Vec<crate::contact::PlateRecord>,
    /// The fiber modulus calibrated against the FEM (a scene with only `[tissue]`;
    /// omitted otherwise).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub calibration: Option<crate::fit::Calibration>,
    /// The deformed body: volume, displacements, pressure.
    #[serde(flatten)]
    pub result: ResultFacts,
    /// What the run cost: solves, factorizations, memory and stage times.
    #[serde(flatten)]
    pub cost: CostFacts,
    /// Notes (mesh warnings, etc.).
    pub notes: Vec<String>,
    /// Settings of the scene that had no effect ([`crate::ineffective`]), one line each.
    pub ineffective: Vec<String>,
    /// Wall-clock seconds of the whole run.
    pub seconds_total: f64,
}

/// The solver choices a run used. (flattened into `report.json`).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct SolverFacts {
    /// Linear backend.
    pub backend: Backend,
    /// Stepping mode.
    pub mode: Mode,
    /// Stepping scheme.
    pub stepping: Stepping,
    /// Factorization precision.
    pub precision: Precision,
    /// Constraint method (`penalty` or `eliminate`).
    pub constraints: ConstraintKind,
    /// The penalty's diagonal value, when `constraints` is `penalty`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub penalty: Option<f64>,
}

/// The body: its size and shape class. (flattened into `report.json`).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct BodyFacts {
    /// Vertex count.
    pub vertices: usize,
    /// Face count (edges for a polygon).
    pub faces: usize,
    /// Whether the body was found convex.
    pub convex: bool,
}

/// The fiber–fluid method's fibers. (flattened into `report.json`).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct FfmFacts {
    /// FFM's fiber model (`paper` or `projected`).
    pub fibers: crate::FiberModel,
    /// How the bulk fibers' weights fall with length: `1 / d^p` (the paper's p = 1).
    pub kernel_exponent: f64,
    /// Candidate fibers N(N-1)/2.
    pub fibers_total: usize,
    /// Kept fibers.
    pub fibers_kept: usize,
}

/// The load steps asked for and taken. (flattened into `report.json`).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct StepFacts {
    /// Load steps asked for (with a tolerance: the first step's fraction is 1/steps).
    pub steps: usize,
    /// Adaptive stepping tolerance, when set.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<f64>,
    /// Steps taken (accepted).
    pub steps_taken: usize,
    /// Adaptive steps rejected and retried at half the size.
    pub steps_rejected: usize,
    /// Steps skipped because their load did not change.
    pub steps_skipped: usize,
    /// Adaptive steps: the summed Euler/Heun error estimate over the largest
    /// displacement (compare with `tolerance`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error_estimate: Option<f64>,
}

/// What the guards found. (flattened into `report.json`).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct GuardFacts {
    /// Step guards that fired.
    pub warnings: Vec<crate::guards::GuardWarning>,
    /// Faces inverted against the rest shape at the end.
    pub inverted_faces: usize,
    /// The result guards that fired on the final answer ([`crate::result_guards`]).
    pub result_warnings: Vec<crate::result_guards::ResultWarning>,
}

/// The deformed body: volume, displacements, pressure. (flattened into `report.json`).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ResultFacts {
    /// Volume before.
    pub volume_initial: f64,
    /// Volume after.
    pub volume_final: f64,
    /// |V_final / V_initial - 1|.
    pub volume_drift: f64,
    /// Largest displacement magnitude.
    pub max_displacement: f64,
    /// Mean displacement magnitude.
    pub mean_displacement: f64,
    /// Largest displacement of a fully fixed vertex.
    pub fixed_max_displacement: f64,
    /// Accumulated pressure change.
    pub pressure: f64,
}

/// What the run cost: solves, factorizations, memory and stage times. (flattened into `report.json`).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct CostFacts {
    /// Largest relative residual of any solve.
    pub residual_max: f64,
    /// Largest number of refinement steps of any solve.
    pub refinement_steps_max: usize,
    /// Factorizations made.
    pub factorizations: usize,
    /// K blocks per factorization (1 when shared by x, y, z).
    pub blocks_factored: usize,
    /// Linear solves made.
    pub solves: usize,
    /// Peak memory the plan estimated, in bytes.
    pub memory_bytes_planned: u64,
    /// Stages that ran, with their seconds; a stage with a `parent` ran inside it, so the
    /// top-level seconds add up to at most `seconds_total`.
    pub stages: Vec<StageRecord>,
    /// Stages the plan left out, with the reason.
    pub skipped: Vec<SkippedStage>,
}

impl Report {
    /// Builds the report of a simulation in its current state.
    pub fn of(sim: &Simulation, extra_stages: &[StageRecord], notes: Vec<String>) -> Self {
        let scene = sim.model();
        let rest = sim.rest_positions();
        let disp: Vec<f64> = sim
            .positions()
            .iter()
            .zip(rest)
            .map(|(p, r)| ((p[0] - r[0]).powi(2) + (p[1] - r[1]).powi(2) + (p[2] - r[2]).powi(2)).sqrt())
            .collect();
        let fixed = scene.constraints.fully_fixed_vertices(sim.axes());
        let (v0, v1) = (sim.volume_initial(), sim.volume());
        let mut stages: Vec<StageRecord> = extra_stages.to_vec();
        stages.extend(sim.log().records().iter().cloned());
        let faces = match &scene.shape {
            crate::Shape::Surface(m) => m.mesh.n_faces(),
            crate::Shape::Polygon(p) => p.n_vertices(),
        };
        Report {
            scene: scene.name.clone(),
            units: crate::fem_run::Units::si(scene.unit),
            solver: SolverFacts {
                backend: scene.solver.backend,
                mode: scene.solver.mode,
                stepping: scene.solver.stepping,
                precision: scene.solver.precision,
                constraints: scene.solver.constraints,
                penalty: (scene.solver.constraints == ConstraintKind::Penalty)
                    .then_some(scene.solver.penalty),
            },
            body: BodyFacts { vertices: rest.len(), faces, convex: sim.convex() },
            ffm: FfmFacts {
                fibers: scene.ffm.fibers,
                kernel_exponent: scene.material.kernel_exponent(),
                fibers_total: sim.fibers().total(),
                fibers_kept: sim.fibers().kept(),
            },
            load: StepFacts {
                steps: scene.load.steps,
                tolerance: scene.load.tolerance,
                steps_taken: sim.step_stats().taken,
                steps_rejected: sim.step_stats().rejected,
                steps_skipped: sim.step_stats().skipped,
                error_estimate: scene.load.tolerance.map(|_| {
                    sim.step_stats().error_estimate
                        / disp.iter().copied().fold(0.0, f64::max).max(f64::MIN_POSITIVE)
                }),
            },
            guards: GuardFacts {
                warnings: sim.warnings().to_vec(),
                inverted_faces: crate::guards::inverted_faces(&sim.body().boundary, rest, sim.positions()),
                result_warnings: sim.answer_guards().unwrap_or_default(),
            },
            plates: sim.plate_records().to_vec(),
            calibration: sim.calibration().copied(),
            result: ResultFacts {
                volume_initial: v0,
                volume_final: v1,
                volume_drift: (v1 / v0 - 1.0).abs(),
                max_displacement: disp.iter().copied().fold(0.0, f64::max),
                mean_displacement: disp.iter().sum::<f64>() / disp.len().max(1) as f64,
                fixed_max_displacement: fixed.iter().map(|&i| disp[i]).fold(0.0, f64::max),
                pressure: sim.pressure(),
            },
            cost: CostFacts {
                residual_max: sim.counters().residual_max,
                refinement_steps_max: sim.counters().refinement_steps_max,
                factorizations: sim.counters().factorizations,
                blocks_factored: sim.system().stats.blocks,
                solves: sim.counters().solves,
                memory_bytes_planned: sim.plan().memory_bytes,
                stages,
                skipped: sim
                    .plan()
                    .skipped()
                    .map(|s| SkippedStage { name: s.name, reason: s.reason.clone() })
                    .collect(),
            },
            notes,
            ineffective: crate::ineffective(scene).iter().map(ToString::to_string).collect(),
            seconds_total: sim.elapsed() + extra_stages.iter().map(|s| s.seconds).sum::<f64>(),
        }
    }
}

/// The paper's Eq. 9: `sum_i |s_i(final) - s_i(initial)| / (N * diagonal of the initial
/// bounding box)`.
pub fn roundtrip_error(initial: &[[f64; 3]], finals: &[[f64; 3]]) -> f64 {
    let (lo, hi) = fibfluid_geometry::bounding_box(initial);
    let diag = ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2) + (hi[2] - lo[2]).powi(2)).sqrt();
    let sum: f64 = initial
        .iter()
        .zip(finals)
        .map(|(a, b)| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt())
        .sum();
    sum / (initial.len() as f64 * diag)
}

/// Result of a compression–decompression round trip.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct RoundTrip {
    /// Steps each way (with a tolerance: the first step's fraction is 1/steps).
    pub steps: usize,
    /// Adaptive stepping tolerance, when set.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<f64>,
    /// Steps taken, both ways.
    pub steps_taken: usize,
    /// Mode.
    pub mode: Mode,
    /// Stepping scheme.
    pub stepping: Stepping,
    /// Backend.
    pub backend: Backend,
    /// Precision.
    pub precision: Precision,
    /// Eq. 9 error (a fraction).
    pub roundtrip_error: f64,
    /// |V/V0 - 1| at the end of compression.
    pub volume_drift: f64,
    /// Largest displacement at the end of compression.
    pub max_displacement: f64,
    /// Positions at the end of compression.
    #[serde(skip)]
    pub compressed: Vec<[f64; 3]>,
    /// Largest relative residual of any solve.
    pub residual_max: f64,
    /// Factorizations made.
    pub factorizations: usize,
    /// Wall-clock seconds of the simulation (setup, both ways).
    pub seconds: f64,
    /// Wall-clock seconds of the setup and the compression alone (what a plain run of the
    /// scene costs).
    pub compress_seconds: f64,
}

/// Runs compression then decompression (REFERENCE §4): `steps` equal steps each way, or
/// adaptive steps when the scene sets a `tolerance`.
pub fn roundtrip(model: impl Into<crate::Model>, opts: &crate::RunOptions) -> crate::Result<RoundTrip> {
    let scene: crate::Model = model.into();
    let steps = scene.load.steps;
    let mut sim = Simulation::new(scene)?;
    sim.run(opts)?;
    let compress_seconds = sim.elapsed();
    let compressed = sim.positions().to_vec();
    let volume_drift = (sim.volume() / sim.volume_initial() - 1.0).abs();
    let max_displacement = compressed
        .iter()
        .zip(sim.rest_positions())
        .map(|(p, r)| ((p[0] - r[0]).powi(2) + (p[1] - r[1]).powi(2) + (p[2] - r[2]).powi(2)).sqrt())
        .fold(0.0, f64::max);
    sim.unload(opts)?;
    let s = sim.model();
    Ok(RoundTrip {
        steps,
        tolerance: s.load.tolerance,
        steps_taken: sim.step_stats().taken,
        mode: s.solver.mode,
        stepping: s.solver.stepping,
        backend: s.solver.backend,
        precision: s.solver.precision,
        roundtrip_error: roundtrip_error(sim.rest_positions(), sim.positions()),
        volume_drift,
        max_displacement,
        compressed,
        residual_max: sim.counters().residual_max,
        factorizations: sim.counters().factorizations,
        seconds: sim.elapsed(),
        compress_seconds,
    })
}
