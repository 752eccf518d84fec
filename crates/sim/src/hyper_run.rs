//! The finite-element run of a neo-Hookean tissue (`[tissue] model = "neo-hookean"`): the
//! same grid, clamp and loads as the linear run, solved by Newton's method with load steps
//! (`fibfluid_fem::hyper`); plates are frictionless unilateral contact inside the Newton
//! loop, sampled over the surface's triangles, moving from their rest position (load
//! factor 0) to their final one (load factor 1).

use std::time::Instant;

use fibfluid_fem::hyper::{
    Grasp, HyperBody, HyperSolution, HyperStats, LoadStep, NewtonSettings, RigidPlate, TimeFields, TimeSample,
};
use fibfluid_fem::{FemOptions, FemStats, Tissue};
use serde::Serialize;

use crate::fem_inputs::{FemPlate, estimate, fixed_axes, full_loads};
use crate::model::{Model, Shape};
use crate::stages::{StageLog, names};
use crate::{Error, Result};

/// Newton's record in `report.json`: every load step with its residual history, the
/// counts and times, and a timed run's series.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct NewtonRecord {
    /// Each converged load step (and contact augmentation) with its relative residuals.
    pub steps: Vec<LoadStep>,
    /// Iterations, steps, cuts, augmentations and seconds.
    pub stats: HyperStats,
    /// A timed run's state at each output time (`[time]`; empty for one equilibrium).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub series: Vec<SeriesRow>,
}

/// One output time of a timed run (SI units).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SeriesRow {
    /// Time, s.
    pub time: f64,
    /// The load factor then.
    pub load: f64,
    /// The largest surface displacement, m.
    pub max_displacement: f64,
    /// The volume the deformed surface encloses, m^3.
    pub volume: f64,
    /// Kinetic energy, J (0 without inertia).
    pub kinetic_energy: f64,
    /// Elastic energy stored in the tissue, J.
    pub strain_energy: f64,
    /// Per plate, its contact force on the body along its normal, N.
    pub plate_forces: Vec<f64>,
    /// Per grasp, the force the tissue exerts on the grasper, N.
    pub grasp_forces: Vec<fibfluid_geometry::Vec3>,
}

impl From<&TimeSample> for SeriesRow {
    fn from(s: &TimeSample) -> Self {
        Self {
            time: s.time,
            load: s.load,
            max_displacement: s.max_displacement,
            volume: s.volume,
            kinetic_energy: s.kinetic_energy,
            strain_energy: s.strain_energy,
            plate_forces: s.plate_forces.clone(),
            grasp_forces: s.grasp_forces.clone(),
        }
    }
}

/// The plates of a model as the hyperelastic body takes them.
pub fn rigid_plates(model: &Model) -> Vec<RigidPlate> {
    model
        .plates
        .iter()
        .map(|p| RigidPlate {
            force: p.force,
            start: p.point_at(0.0),
            end: p.point_at(1.0),
            normal: p.normal,
        })
        .collect()
}

/// A timed run's state at one output time, handed to the caller as it is made (for
/// progress, and to write each time's volume without keeping them all).
#[derive(Debug, Clone, Copy)]
pub struct TimeFrame<'a> {
    /// The output's number, from 0 (`t = 0`) in time order.
    pub index: usize,
    /// The outputs the run makes in all.
    pub outputs: usize,
    /// The run's end, s.
    pub end: f64,
    /// Steps taken so far.
    pub steps: usize,
    /// Steps cut so far (after a failed Newton solve).
    pub cut_steps: usize,
    /// The output's row of the series.
    pub row: &'a SeriesRow,
    /// The whole body then: grid, node displacements (m), cells, region ids.
    pub fields: &'a TimeFields<'a>,
    /// The tissue solved (its law named in outputs).
    pub tissue: &'a Tissue,
}

/// Builds the model's hyperelastic body (refused from counts first, as the linear one)
/// and solves it; returns the grid's body, its solution and its stats.
pub fn solve(
    model: &Model,
    tissue: &Tissue,
    limit: u64,
    log: &mut StageLog,
) -> Result<(HyperBody, HyperSolution, FemStats, Vec<SeriesRow>)> {
    solve_observed(model, tissue, limit, log, &mut |_| {})
}

/// [`solve`], a timed run showing `observer` each output time as it is made.
pub fn solve_observed(
    model: &Model,
    tissue: &Tissue,
    limit: u64,
    log: &mut StageLog,
    observer: &mut dyn FnMut(&TimeFrame<'_>),
) -> Result<(HyperBody, HyperSolution, FemStats, Vec<SeriesRow>)> {
    let mut body = build(model, tissue, &model.fem.grasps, limit, log)?;
    let plates = rigid_plates(model);
    let failed = |source| Error::Fem { scene: model.display_name(), source };
    let (solution, series) = match &model.fem.time {
        None => {
            (log.time(names::SOLVE, || body.solve(&full_loads(model), &plates)).map_err(failed)?, Vec::new())
        }
        Some(timed) => {
            let (settings, outputs) = (&timed.settings, timed.settings.outputs());
            let mut series = Vec::new();
            let mut on_sample = |s: &TimeSample, fields: &TimeFields<'_>| {
                let row = SeriesRow::from(s);
                observer(&TimeFrame {
                    index: series.len(),
                    outputs,
                    end: settings.end,
                    steps: s.steps,
                    cut_steps: s.cut_steps,
                    row: &row,
                    fields,
                    tissue,
                });
                series.push(row);
            };
            let loads = full_loads(model);
            let run = log
                .time(names::SOLVE, || {
                    body.solve_in_time(&loads, &plates, settings, &timed.curve, &mut on_sample)
                })
                .map_err(failed)?;
            (run.last, series)
        }
    };
    let stats = fem_stats(&body, &solution.stats);
    Ok((body, solution, stats, series))
}

/// The grid's sizes and a Newton solve's summed timings, as the linear body reports them.
pub fn fem_stats(body: &HyperBody, newton: &HyperStats) -> FemStats {
    let grid = body.grid();
    FemStats {
        resolution: grid.resolution(),
        cells: grid.n_cells(),
        nodes: grid.n_nodes(),
        dofs: body.dofs(),
        nonzeros: body.nonzeros(),
        factor_nonzeros: body.factor_nonzeros(),
        assembly_seconds: newton.assembly_seconds,
        factor_seconds: newton.factor_seconds,
        solve_seconds: newton.solve_seconds,
    }
}

/// Voxelizes the model's surface into its hyperelastic body with `grasps` and its regions
/// (refused from counts first, as the linear one).
pub fn build(
    model: &Model,
    tissue: &Tissue,
    grasps: &[Grasp],
    limit: u64,
    log: &mut StageLog,
) -> Result<HyperBody> {
    let grid = estimate(model, limit)?;
    let fixed = fixed_axes(model)?;
    let Shape::Surface(file) = &model.shape else { unreachable!("estimate refused a polygon") };
    let failed = |source| Error::Fem { scene: model.display_name(), source };
    let options = FemOptions { resolution: model.fem.resolution, ..FemOptions::default() };
    let start = Instant::now();
    let regions: Vec<_> = model.fem.regions.iter().map(|r| r.region.clone()).collect();
    let (positions, triangles) = (file.mesh.positions(), file.mesh.triangles());
    // The grasps' compliance columns get what the memory limit leaves beside the factor.
    let spare = (limit as f64 - grid.solver_cost(model.fem.solver).0).max(0.0) as usize;
    let settings = NewtonSettings {
        grasp_columns_bytes: spare.min(fibfluid_fem::hyper::GRASP_COLUMNS_BYTES),
        solver: model.fem.solver,
        max_increment: plate_increment(model),
        ..NewtonSettings::default()
    };
    let body = HyperBody::from_surface_grasped(positions, triangles, tissue, &fixed, grasps, &options)
        .and_then(|b| b.with_regions(&regions))
        .map_err(|source| match source {
            fibfluid_fem::FemError::RegionOutsideBody { region } => {
                let named = &model.fem.regions[region - 1];
                Error::RegionOutsideBody {
                    scene: model.display_name(),
                    name: named.name.clone(),
                    origin: named.origin.clone(),
                }
            }
            source => failed(source),
        })?
        .with_settings(settings)
        .with_pressures(&model.fem.pressures.iter().map(|p| p.pressure.clone()).collect::<Vec<_>>())
        .map_err(failed)?;
    log.add(names::VOXELIZATION, start.elapsed().as_secs_f64());
    Ok(body)
}

/// The largest load increment of a static run with plates: `1 / [load] steps`, so each
/// plate's force is recorded at least that often along its travel (`compression.png`); 1
/// otherwise (Newton's method picks its increments).
fn plate_increment(model: &Model) -> f64 {
    if model.plates.is_empty() || model.fem.time.is_some() {
        1.0
    } else {
        1.0 / model.load.steps.max(1) as f64
    }
}

/// Each plate's contact from a hyperelastic solution (contacts counted in surface samples).
pub fn plate_records(solution: &HyperSolution) -> Vec<FemPlate> {
    (0..solution.plate_forces.len())
        .map(|k| FemPlate {
            force: solution.plate_forces[k],
            contact_samples: solution.plate_contacts[k],
            penetration: solution.plate_penetration[k],
            augmentations: solution.stats.augmentations,
            pressure: solution.contact_pressure[k].clone(),
        })
        .collect()
}
