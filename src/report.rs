//! The run report (`report.json`) and the round-trip measure (Eq. 9).

use serde::Serialize;

use crate::simulate::Simulation;
use crate::stages::{SkippedStage, StageRecord};

/// What a run did and how accurate it was.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Report {
    /// Scene name.
    pub scene: String,
    /// Linear backend.
    pub backend: String,
    /// Stepping mode.
    pub mode: String,
    /// Stepping scheme.
    pub stepping: String,
    /// Factorization precision.
    pub precision: String,
    /// Constraint method (`penalty` or `eliminate`).
    pub constraints: String,
    /// Vertex count.
    pub vertices: usize,
    /// Face count (edges for a polygon).
    pub faces: usize,
    /// Whether the body was found convex.
    pub convex: bool,
    /// Candidate fibers N(N-1)/2.
    pub fibers_total: usize,
    /// Kept fibers.
    pub fibers_kept: usize,
    /// Load steps.
    pub steps: usize,
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
    /// Stages that ran, with their seconds.
    pub stages: Vec<StageRecord>,
    /// Stages the plan left out, with the reason.
    pub skipped: Vec<SkippedStage>,
    /// Notes (mesh warnings, etc.).
    pub notes: Vec<String>,
    /// Settings of the scene that had no effect ([`crate::ineffective`]), one line each.
    pub warnings: Vec<String>,
    /// Wall-clock seconds of the whole run.
    pub seconds_total: f64,
}

impl Report {
    /// Builds the report of a simulation in its current state.
    pub fn of(sim: &Simulation, extra_stages: &[StageRecord], notes: Vec<String>) -> Self {
        let scene = sim.scene();
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
        stages.extend(sim.log().stages.iter().cloned());
        let faces = match &scene.shape {
            crate::Shape::Surface(m) => m.mesh.n_faces(),
            crate::Shape::Polygon(p) => p.n_vertices(),
        };
        Report {
            scene: scene.name.clone(),
            backend: scene.solver.backend.clone(),
            mode: scene.solver.mode.name().into(),
            stepping: scene.solver.stepping.name().into(),
            precision: scene.solver.precision.name().into(),
            constraints: match scene.solver.constraints {
                fibfluid_assembly::ConstraintMethod::Penalty { .. } => "penalty".into(),
                fibfluid_assembly::ConstraintMethod::Eliminate => "eliminate".into(),
            },
            vertices: rest.len(),
            faces,
            convex: sim.convex(),
            fibers_total: sim.fibers().total(),
            fibers_kept: sim.fibers().kept(),
            steps: scene.steps,
            volume_initial: v0,
            volume_final: v1,
            volume_drift: (v1 / v0 - 1.0).abs(),
            max_displacement: disp.iter().copied().fold(0.0, f64::max),
            mean_displacement: disp.iter().sum::<f64>() / disp.len().max(1) as f64,
            fixed_max_displacement: fixed.iter().map(|&i| disp[i]).fold(0.0, f64::max),
            pressure: sim.pressure(),
            residual_max: sim.residual_max(),
            refinement_steps_max: sim.refinement_steps_max(),
            factorizations: sim.factorizations(),
            blocks_factored: sim.system().stats.blocks,
            solves: sim.solves(),
            stages,
            skipped: sim.log().skipped.clone(),
            notes,
            warnings: crate::ineffective(scene).iter().map(ToString::to_string).collect(),
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
    /// Steps each way.
    pub steps: usize,
    /// Mode.
    pub mode: String,
    /// Stepping scheme.
    pub stepping: String,
    /// Backend.
    pub backend: String,
    /// Precision.
    pub precision: String,
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
}

/// Runs compression then decompression with `steps` steps each (REFERENCE §4).
pub fn roundtrip(scene: crate::Scene, opts: &crate::RunOptions) -> crate::Result<RoundTrip> {
    let steps = scene.steps;
    let mut sim = Simulation::new(scene)?;
    sim.run_steps(steps, crate::Direction::Load, opts)?;
    let compressed = sim.positions().to_vec();
    let volume_drift = (sim.volume() / sim.volume_initial() - 1.0).abs();
    let max_displacement = compressed
        .iter()
        .zip(sim.rest_positions())
        .map(|(p, r)| ((p[0] - r[0]).powi(2) + (p[1] - r[1]).powi(2) + (p[2] - r[2]).powi(2)).sqrt())
        .fold(0.0, f64::max);
    sim.run_steps(steps, crate::Direction::Unload, opts)?;
    let s = sim.scene();
    Ok(RoundTrip {
        steps,
        mode: s.solver.mode.name().into(),
        stepping: s.solver.stepping.name().into(),
        backend: s.solver.backend.clone(),
        precision: s.solver.precision.name().into(),
        roundtrip_error: roundtrip_error(sim.rest_positions(), sim.positions()),
        volume_drift,
        max_displacement,
        compressed,
        residual_max: sim.residual_max(),
        factorizations: sim.factorizations(),
        seconds: sim.elapsed(),
    })
}
