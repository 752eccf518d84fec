//! The finite-element method as a batch run: a model's surface voxelized into a sparse
//! grid of hexahedra (`fibfluid-fem`), its clamps, gravity and point forces. A linear
//! tissue without plates is one factorization and one solve of the B-bar body; a
//! neo-Hookean tissue, or any tissue pressed by plates, is solved by Newton's method with
//! load steps ([`crate::hyper_run`]).
//!
//! The model's `[tissue]` (Young's modulus in Pa, Poisson's ratio, density in kg/m^3) is the
//! material; positions are in metres (the scene converts the mesh's declared unit). A
//! vertex fixed along an axis holds the grid nodes that carry it (`fibfluid_fem::FemBody`
//! states the rule); a prescribed non-zero displacement is not carried yet and is refused by
//! name. Plates are rigid, frictionless and unilateral, moving with the load factor; their
//! contact is sampled over the surface's triangles inside the Newton loop
//! (`fibfluid_fem::hyper`'s contact, an augmented Lagrangian), for both laws.

use std::time::Instant;

use fibfluid_fem::hyper::{CellMaterial, CellState, GraspRecord, StrainSummary, cell_states};
use fibfluid_fem::{FemStats, SparseGrid, Tissue};
use fibfluid_geometry::{Boundary, LengthUnit, Vec3};
use serde::Serialize;

use crate::accuracy::{AccuracyStudy, MAX_STUDY_RUNS};
use crate::choices::Method;
use crate::fem_inputs::failed;
pub use crate::fem_inputs::{
    FemPlate, build_body, estimate, fixed_axes, full_loads, refuse_plates, tissue_of,
};
use crate::model::{Model, Shape};
use crate::result_guards::{
    DILATATION_LIMIT, GRASP_ERROR_LIMIT, LINEAR_STRAIN_LIMIT, ResultChecks, ResultGuard, ResultWarning,
    check_answer,
};
use crate::stages::{StageLog, StageRecord, names};
use crate::{Error, Result};

/// A finished finite-element run.
#[derive(Debug)]
pub struct FemRun {
    /// The model.
    pub model: Model,
    /// Rest positions (metres).
    pub rest: Vec<Vec3>,
    /// Deformed positions (metres): the finite-element surface as computed. A fixed vertex
    /// moves along its fixed axes by the clamp's penalty slip ([`fibfluid_fem::CLAMP_PENALTY`];
    /// [`FemRun::clamp_slip`]), which vanishes like the cell size; putting it back at rest
    /// would add a step at the clamp's rim and change the enclosed volume by the slip times
    /// the clamp's area.
    pub positions: Vec<Vec3>,
    /// The tissue.
    pub tissue: Tissue,
    /// The body's sizes and timings.
    pub stats: FemStats,
    /// The solve's measured relative residual (the last Newton residual for a
    /// hyperelastic tissue).
    pub residual: f64,
    /// Each plate's contact (empty without plates).
    pub plates: Vec<FemPlate>,
    /// Each grasp's force, moment and constraint error (empty without grasps).
    pub grasps: Vec<GraspRecord>,
    /// Largest strain, `J` extremes and stress of the answer's cells.
    pub strain: StrainSummary,
    /// Inside the tissue: the grid, its nodes' displacements and its cells' states.
    pub volume: VolumeAnswer,
    /// Newton's record (hyperelastic tissue only).
    pub newton: Option<crate::hyper_run::NewtonRecord>,
    /// The result guards that fired ([`crate::result_guards`]).
    pub warnings: Vec<ResultWarning>,
    /// What the run decided on its own: the law `model = "auto"` chose, the resolution
    /// `[fem] tolerance` chose.
    pub decided: Decisions,
    /// Stage times.
    pub log: StageLog,
    /// Wall-clock seconds.
    pub seconds: f64,
}

impl FemRun {
    /// The largest displacement of a fixed vertex along one of its fixed axes (m): the
    /// clamp's penalty slip (0 without fixed vertices).
    pub fn clamp_slip(&self) -> f64 {
        self.fixed_axes().map(|(v, a)| (self.positions[v][a] - self.rest[v][a]).abs()).fold(0.0, f64::max)
    }

    /// Each vertex's displacement (m) with its fixed axes at 0, as an exact clamp has them
    /// (what the fiber–fluid method, whose clamp is exact, is calibrated against).
    pub fn displacements_clamped_exactly(&self) -> Vec<Vec3> {
        let mut u: Vec<Vec3> = self
            .positions
            .iter()
            .zip(&self.rest)
            .map(|(p, r)| std::array::from_fn(|a| p[a] - r[a]))
            .collect();
        for (v, a) in self.fixed_axes() {
            u[v][a] = 0.0;
        }
        u
    }

    /// The fixed `(vertex, axis)` pairs.
    fn fixed_axes(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        (0..self.rest.len())
            .flat_map(|v| (0..3).map(move |a| (v, a)))
            .filter(|&(v, a)| self.model.constraints.get(v, a).is_some())
    }

    /// Runs the model with the finite-element method; `max_memory` as for FFM's setup.
    pub fn new(model: impl Into<Model>, max_memory: Option<u64>) -> Result<Self> {
        Self::observed(model, max_memory, &mut |_| {})
    }

    /// [`FemRun::new`], a timed run (`[time]`) showing `observer` each output time as it
    /// is made. A `[tissue] model = "auto"` solved again neo-Hookean shows its outputs
    /// again from the first.
    pub fn observed(
        model: impl Into<Model>,
        max_memory: Option<u64>,
        observer: &mut dyn FnMut(&crate::hyper_run::TimeFrame<'_>),
    ) -> Result<Self> {
        let mut model: Model = model.into();
        crate::contact::refuse_crossing_plates(&model)?;
        let start = Instant::now();
        let limit = fibfluid_linalg::memory_budget(max_memory);
        let mut log = StageLog::default();
        let mut tissue = tissue_of(&model)?;
        let rest = model.rest_positions();
        let scene_resolution = model.fem.resolution;
        let (mut answer, mut accuracy) = solve_studied(&mut model, &tissue, limit, &mut log, observer)?;
        let mut notes = Vec::new();
        let strain = answer.strain.max_strain_magnitude;
        if model.fem.auto_model && tissue.is_linear() && strain > LINEAR_STRAIN_LIMIT {
            notes.push(format!(
                "[tissue] model = \"auto\": the linear answer's largest strain {strain:.3} is above {LINEAR_STRAIN_LIMIT}; solved again neo-Hookean"
            ));
            tissue = tissue.nonlinear();
            log = StageLog::default();
            model.fem.resolution = scene_resolution;
            (answer, accuracy) = solve_studied(&mut model, &tissue, limit, &mut log, observer)?;
        }
        let positions: Vec<Vec3> = rest
            .iter()
            .zip(&answer.surface_displacements)
            .map(|(p, u)| std::array::from_fn(|a| p[a] + u[a]))
            .collect();
        let small_strain = tissue.is_linear();
        let mut warnings = answer_guards(&model, &rest, &positions, answer.residual, small_strain)?;
        let strain = answer.strain.max_strain_magnitude;
        if small_strain && strain > LINEAR_STRAIN_LIMIT {
            warnings.push(ResultWarning {
                guard: ResultGuard::Strain,
                value: strain,
                limit: LINEAR_STRAIN_LIMIT,
            });
        }
        warnings.extend(newton_guards(&answer, small_strain));
        warnings.extend(support_guards(&model, &answer.plates));
        if let Some(study) = accuracy.as_ref().filter(|s| !s.met) {
            let value = study.estimated_error.unwrap_or(f64::INFINITY);
            warnings.push(ResultWarning { guard: ResultGuard::Accuracy, value, limit: study.tolerance });
        }
        Ok(Self {
            warnings,
            decided: Decisions { notes, accuracy },
            tissue,
            stats: answer.stats,
            residual: answer.residual,
            plates: answer.plates,
            grasps: answer.grasps,
            strain: answer.strain,
            volume: VolumeAnswer {
                region_ids: answer.region_ids,
                cells: answer.cells,
                grid: answer.grid,
                node_displacements: answer.node_displacements,
            },
            newton: answer.newton,
            rest,
            positions,
            log,
            seconds: start.elapsed().as_secs_f64(),
            model,
        })
    }
}

/// What a finite-element run decided on its own.
#[derive(Debug, Clone, Default)]
pub struct Decisions {
    /// One line per decision (the law `[tissue] model = "auto"` chose).
    pub notes: Vec<String>,
    /// The resolutions `[fem] tolerance` ran and their estimate (none without it).
    pub accuracy: Option<AccuracyStudy>,
}

/// [`solve_answer`] at `model`'s resolution, or with `[fem] tolerance` at growing
/// resolutions until the estimate meets it ([`crate::accuracy`]): `model`'s resolution is
/// then the answer's, and `log` holds the answer's stages.
fn solve_studied(
    model: &mut Model,
    tissue: &Tissue,
    limit: u64,
    log: &mut StageLog,
    observer: &mut dyn FnMut(&crate::hyper_run::TimeFrame<'_>),
) -> Result<(FemAnswer, Option<AccuracyStudy>)> {
    let Some(tolerance) = model.fem.tolerance else {
        return Ok((solve_answer(model, tissue, limit, log, observer)?, None));
    };
    let mut study = AccuracyStudy::new(tolerance);
    let mut best: Option<FemAnswer> = None;
    let mut resolution = model.fem.resolution;
    loop {
        let answered = model.fem.resolution;
        model.fem.resolution = resolution;
        let mut run_log = StageLog::default();
        let started = Instant::now();
        let answer = match (solve_answer(model, tissue, limit, &mut run_log, observer), &best) {
            (Ok(answer), _) => answer,
            // A finer grid that does not fit ends the study at the last one that did.
            (Err(e @ Error::TooLarge { .. }), Some(_)) => {
                model.fem.resolution = answered;
                study.stopped = Some(format!("resolution {resolution} is refused: {e}"));
                break;
            }
            (Err(e), _) => return Err(e),
        };
        *log = run_log;
        let previous = best.as_ref().map(|b| b.surface_displacements.as_slice());
        let seconds = started.elapsed().as_secs_f64();
        let met = study.record(resolution, &answer.surface_displacements, previous, seconds);
        best = Some(answer);
        let next = AccuracyStudy::next_resolution(resolution);
        if met {
            break;
        } else if study.resolutions.len() == MAX_STUDY_RUNS {
            study.stopped = Some(format!("{MAX_STUDY_RUNS} runs, the most one study makes"));
            break;
        } else if next > fibfluid_fem::MAX_RESOLUTION {
            study.stopped = Some(format!("resolution {next} is above {}", fibfluid_fem::MAX_RESOLUTION));
            break;
        }
        resolution = next;
    }
    Ok((best.expect("the first run is made or its error returned"), Some(study)))
}

/// Solves the model with `tissue`'s law. Plates, grasps, pressures and regions need the Newton solver
/// (contact and grasps inside the solve, per-cell materials), for the linear law too
/// (one iteration per change of the contact set); a plain linear body is one solve. A
/// timed run shows `observer` each output time.
fn solve_answer(
    model: &Model,
    tissue: &Tissue,
    limit: u64,
    log: &mut StageLog,
    observer: &mut dyn FnMut(&crate::hyper_run::TimeFrame<'_>),
) -> Result<FemAnswer> {
    let plain = model.plates.is_empty()
        && model.fem.regions.is_empty()
        && model.fem.grasps.is_empty()
        && model.fem.pressures.is_empty();
    // The linear body solves with the sparse Cholesky only: above the crossover the
    // Newton solver (one iteration for a linear law) brings the multigrid.
    let direct = crate::fem_inputs::estimate(model, limit)?.uses_direct_solver(model.fem.solver);
    if tissue.is_linear() && plain && model.fem.time.is_none() && direct {
        return solve_linear(model, limit, log);
    }
    let (body, sol, stats, series) = crate::hyper_run::solve_observed(model, tissue, limit, log, observer)?;
    Ok(FemAnswer {
        plates: crate::hyper_run::plate_records(&sol),
        grasps: sol.grasps.clone(),
        newton: Some(crate::hyper_run::NewtonRecord { steps: sol.steps.clone(), stats: sol.stats, series }),
        strain: sol.summary,
        cells: sol.cells,
        residual: sol.residual,
        stats,
        grid: body.grid().clone(),
        region_ids: body.region_ids().to_vec(),
        node_displacements: sol.node_displacements,
        surface_displacements: sol.surface_displacements,
    })
}

/// The answer inside the tissue: what `volume.vtu` shows.
#[derive(Debug, Clone)]
pub struct VolumeAnswer {
    /// The grid the answer lives on.
    pub grid: SparseGrid,
    /// The displacement of every grid node (m).
    pub node_displacements: Vec<Vec3>,
    /// Each active cell's strain, `J` and stress (grid order).
    pub cells: Vec<CellState>,
    /// Each active cell's region id: 0 the `[tissue]`, `k` the `k`-th `[[region]]` (the
    /// region holding most of the cell; `material_id` in `volume.vtu`).
    pub region_ids: Vec<u16>,
}

/// What a solve of either model hands to [`FemRun`].
struct FemAnswer {
    surface_displacements: Vec<Vec3>,
    node_displacements: Vec<Vec3>,
    grid: SparseGrid,
    region_ids: Vec<u16>,
    residual: f64,
    plates: Vec<FemPlate>,
    grasps: Vec<GraspRecord>,
    strain: StrainSummary,
    cells: Vec<CellState>,
    newton: Option<crate::hyper_run::NewtonRecord>,
    stats: FemStats,
}

/// The linear run without plates: one factorization and one solve.
fn solve_linear(model: &Model, limit: u64, log: &mut StageLog) -> Result<FemAnswer> {
    let mut body = build_body(model, limit, log)?;
    let loads = full_loads(model);
    let s = log.time(names::SOLVE, || body.solve(&loads)).map_err(failed(model))?;
    let (surface, nodes, residual, plates) =
        (s.surface_displacements, s.node_displacements, s.residual, Vec::new());
    let materials = vec![CellMaterial::of(body.tissue()); body.grid().n_cells()];
    let (cells, strain) = cell_states(body.grid(), &materials, &nodes);
    Ok(FemAnswer {
        surface_displacements: surface,
        node_displacements: nodes,
        grid: body.grid().clone(),
        region_ids: vec![0; body.grid().n_cells()],
        residual,
        plates,
        grasps: Vec::new(),
        strain,
        cells,
        newton: None,
        stats: body.stats(),
    })
}

/// The result guards only a Newton solve has: an unstable equilibrium, a cell torn apart
/// (neo-Hookean), a grasp left short of its target.
fn newton_guards(answer: &FemAnswer, small_strain: bool) -> Vec<ResultWarning> {
    let mut warnings = Vec::new();
    if let Some(shift) = answer.newton.as_ref().map(|n| n.stats.final_shift).filter(|&s| s > 0.0) {
        warnings.push(ResultWarning { guard: ResultGuard::Unstable, value: shift, limit: 0.0 });
    }
    if !small_strain && answer.strain.j_max > DILATATION_LIMIT {
        warnings.push(ResultWarning {
            guard: ResultGuard::Dilatation,
            value: answer.strain.j_max,
            limit: DILATATION_LIMIT,
        });
    }
    let cells = answer.grasps.iter().map(|g| g.error).fold(0.0, f64::max) / answer.grid.cell_size();
    if cells > GRASP_ERROR_LIMIT {
        warnings.push(ResultWarning { guard: ResultGuard::Grasp, value: cells, limit: GRASP_ERROR_LIMIT });
    }
    warnings
}

/// The result guards of a finite-element answer's supports: each moving plate that never
/// touched the body, and a body with no fixed vertex and no plate in contact (held only by its
/// grasps' penalties, or by nothing).
fn support_guards(model: &Model, plates: &[FemPlate]) -> Vec<ResultWarning> {
    let mut warnings = Vec::new();
    // A support that stays put (travel 0) may carry nothing by design; a moving plate that
    // never reaches the body is a plate set in the wrong place.
    for (k, (p, plate)) in plates.iter().zip(&model.plates).enumerate() {
        if p.contact_samples == 0 && p.force == 0.0 && plate.travel != 0.0 {
            warnings.push(ResultWarning { guard: ResultGuard::Untouched, value: (k + 1) as f64, limit: 0.0 });
        }
    }
    let fixed = (0..3).any(|axis| model.constraints.count(axis) > 0);
    let pressed = plates.iter().any(|p| p.contact_samples > 0);
    if !fixed && !pressed {
        let grasps = model.fem.grasps.len() as f64;
        warnings.push(ResultWarning { guard: ResultGuard::Unheld, value: grasps, limit: 0.0 });
    }
    warnings
}

/// The result guards of a finite-element answer (every one of them: the FEM has no step
/// guards; the small-strain validity guard only for a linear answer, `small_strain`); a
/// non-finite position is [`Error::NonFiniteAnswer`].
pub fn answer_guards(
    model: &Model,
    rest: &[Vec3],
    positions: &[Vec3],
    residual: f64,
    small_strain: bool,
) -> Result<Vec<ResultWarning>> {
    let Shape::Surface(file) = &model.shape else { return Ok(vec![]) };
    let boundary = Boundary::Surface { triangles: file.mesh.triangles().to_vec() };
    let checks = ResultChecks { inverted: true, residual: Some(residual), linear: small_strain };
    check_answer(&boundary, rest, positions, checks).map_err(|e| Error::NonFiniteAnswer {
        scene: model.display_name(),
        method: Method::Fem,
        vertex: e.vertex,
    })
}

/// The units every number of a report is in.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Units {
    /// Lengths, positions and displacements inside the report (SI).
    pub length: &'static str,
    /// The mesh file's unit (output meshes are written back in it).
    pub mesh: LengthUnit,
    /// Forces.
    pub force: &'static str,
    /// Stresses, pressures and moduli.
    pub pressure: &'static str,
    /// Volumes.
    pub volume: &'static str,
}

impl Units {
    /// SI, with the mesh file's unit.
    pub fn si(mesh: LengthUnit) -> Self {
        Self { length: "m", mesh, force: "N", pressure: "Pa", volume: "m^3" }
    }
}

/// The deformed body of a finite-element run.
#[derive(Clone, Debug, Serialize)]
pub struct FemResultFacts {
    /// Largest displacement (m).
    pub max_displacement: f64,
    /// Mean displacement (m).
    pub mean_displacement: f64,
    /// Volume enclosed by the surface before (m^3).
    pub volume_initial: f64,
    /// Volume after (m^3).
    pub volume_final: f64,
    /// The answer's largest strain, `J` extremes and largest von Mises stress.
    pub strain: StrainSummary,
    /// Each cavity's volume at the end (m^3; omitted for a body without cavities).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub cavity_volumes: Vec<f64>,
}

/// A region of other tissue in `report.json`.
#[derive(Clone, Debug, Serialize)]
pub struct RegionRecord {
    /// Its name.
    pub name: String,
    /// Its tissue (Pa, -, kg/m^3).
    pub tissue: Tissue,
    /// Cells whose samples are mostly in it.
    pub cells: usize,
    /// The mean displacement of those cells' centres (m).
    pub mean_displacement: Vec3,
}

impl RegionRecord {
    /// The regions of a run, from its cells' region ids.
    pub fn of(run: &FemRun) -> Vec<Self> {
        let volume = &run.volume;
        let u = &volume.node_displacements;
        let mut sums = vec![([0.0; 3], 0usize); run.model.fem.regions.len()];
        for (nodes, &id) in volume.grid.cell_nodes().iter().zip(&volume.region_ids) {
            if id == 0 {
                continue;
            }
            let (sum, count) = &mut sums[id as usize - 1];
            for n in nodes {
                for a in 0..3 {
                    sum[a] += u[*n][a] / 8.0;
                }
            }
            *count += 1;
        }
        run.model
            .fem
            .regions
            .iter()
            .zip(sums)
            .map(|(r, (sum, cells))| RegionRecord {
                name: r.name.clone(),
                tissue: r.region.tissue,
                cells,
                mean_displacement: sum.map(|x| x / cells.max(1) as f64),
            })
            .collect()
    }
}

/// What the plates and grasps of a finite-element run did.
#[derive(Clone, Debug, Serialize)]
pub struct FemSupports {
    /// Each plate's contact at its final position (omitted without plates).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub plates: Vec<FemPlate>,
    /// Each grasp's force (N) and moment (N m) on the grasper and its largest constraint
    /// error (m) (omitted without grasps).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub grasps: Vec<GraspRecord>,
    /// Each pressure's resultant force on the body at the end (omitted without pressures).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub pressures: Vec<PressureRecord>,
    /// The largest displacement of a fixed vertex along a fixed axis (m): the clamp's
    /// penalty slip ([`FemRun::clamp_slip`]; 0 without fixed vertices).
    pub clamp_slip: f64,
}

/// A pressure in `report.json`.
#[derive(Clone, Debug, Serialize)]
pub struct PressureRecord {
    /// The surface it acts on (`outer`, `cavity K`, `box`).
    pub surface: String,
    /// The pressure at the end (Pa: the scene's value times the final load factor).
    pub value: f64,
    /// Its resultant force on the body (N): on the deformed surface for a follower
    /// pressure, on the rest surface for a dead one (0 on a closed surface either way).
    pub resultant: Vec3,
}

impl PressureRecord {
    /// The pressures of a run at its end.
    pub fn of(run: &FemRun) -> Vec<Self> {
        let load = run.model.fem.time.as_ref().map_or(1.0, |t| t.curve.factor(t.settings.end));
        let dead = run.tissue.is_linear();
        run.model
            .fem
            .pressures
            .iter()
            .map(|p| {
                let follows = !dead && p.pressure.is_closed();
                let at = if follows { &run.positions } else { &run.rest };
                let r = p.pressure.resultant(at);
                PressureRecord {
                    surface: p.surface.clone(),
                    value: p.pressure.value * load,
                    resultant: r.map(|c| c * load),
                }
            })
            .collect()
    }
}

/// `report.json` of a finite-element run.
#[derive(Clone, Debug, Serialize)]
pub struct FemReport {
    /// Scene name.
    pub scene: String,
    /// `fem`.
    pub method: Method,
    /// The units of the numbers below.
    pub units: Units,
    /// The tissue (Pa, -, kg/m^3).
    pub tissue: Tissue,
    /// Vertices of the surface.
    pub vertices: usize,
    /// Grid, sizes and timings.
    pub fem: FemStats,
    /// Displacements and volumes (flattened into `report.json`).
    #[serde(flatten)]
    pub result: FemResultFacts,
    /// The solve's measured relative residual `|K u - f| / |f|` (the last Newton residual
    /// for a hyperelastic tissue).
    pub residual: f64,
    /// Newton's steps, residual histories, counts and times (hyperelastic tissue only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub newton: Option<crate::hyper_run::NewtonRecord>,
    /// Each plate's contact, each grasp's force and the clamp's slip (flattened into
    /// `report.json`: `plates`, `grasps`, `pressures`, `clamp_slip`).
    #[serde(flatten)]
    pub supports: FemSupports,
    /// Each region of other tissue: its cells and how far they moved (omitted without
    /// regions).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub regions: Vec<RegionRecord>,
    /// The result guards that fired (empty: the answer passed them).
    pub warnings: Vec<ResultWarning>,
    /// Stages with their seconds.
    pub stages: Vec<StageRecord>,
    /// Notes and the settings that had no effect (flattened into `report.json`: `notes`,
    /// `ineffective`).
    #[serde(flatten)]
    pub remarks: FemRemarks,
    /// Wall-clock seconds of the whole run.
    pub seconds_total: f64,
}

/// What `report.json` of a finite-element run says besides its numbers.
#[derive(Clone, Debug, Serialize)]
pub struct FemRemarks {
    /// Notes (mesh warnings, etc.).
    pub notes: Vec<String>,
    /// Settings of the scene that had no effect ([`crate::ineffective`]), one line each.
    pub ineffective: Vec<String>,
    /// `[fem] tolerance`'s runs and estimate ([`AccuracyStudy`]; omitted without it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub accuracy: Option<AccuracyStudy>,
}

impl FemReport {
    /// The report of a run, with the caller's extra stage records (reading the scene) and
    /// notes.
    pub fn of(run: &FemRun, extra_stages: &[StageRecord], notes: Vec<String>) -> Self {
        let disp: Vec<f64> =
            run.positions.iter().zip(&run.rest).map(|(p, r)| fibfluid_geometry::vec3::dist(*p, *r)).collect();
        let (volume_initial, volume_final) = match &run.model.shape {
            Shape::Surface(m) => (
                fibfluid_geometry::volume(&run.rest, m.mesh.triangles()),
                fibfluid_geometry::volume(&run.positions, m.mesh.triangles()),
            ),
            Shape::Polygon(_) => (0.0, 0.0),
        };
        let mut stages = extra_stages.to_vec();
        let notes: Vec<String> = run.decided.notes.iter().cloned().chain(notes).collect();
        stages.extend_from_slice(run.log.records());
        Self {
            scene: run.model.name.clone(),
            method: Method::Fem,
            units: Units::si(run.model.unit),
            tissue: run.tissue,
            vertices: run.rest.len(),
            fem: run.stats,
            result: FemResultFacts {
                max_displacement: disp.iter().copied().fold(0.0, f64::max),
                mean_displacement: disp.iter().sum::<f64>() / disp.len().max(1) as f64,
                volume_initial,
                volume_final,
                strain: run.strain,
                cavity_volumes: cavity_volumes(run),
            },
            residual: run.residual,
            newton: run.newton.clone(),
            supports: FemSupports {
                plates: run.plates.clone(),
                grasps: run.grasps.clone(),
                pressures: PressureRecord::of(run),
                clamp_slip: run.clamp_slip(),
            },
            regions: RegionRecord::of(run),
            warnings: run.warnings.clone(),
            stages,
            remarks: FemRemarks {
                accuracy: run.decided.accuracy.clone(),
                notes,
                ineffective: crate::ineffective(&run.model).iter().map(ToString::to_string).collect(),
            },
            seconds_total: run.seconds + extra_stages.iter().map(|s| s.seconds).sum::<f64>(),
        }
    }
}

/// Each cavity's volume at the end of a run (m^3).
fn cavity_volumes(run: &FemRun) -> Vec<f64> {
    let Shape::Surface(m) = &run.model.shape else { return Vec::new() };
    let shells = m.mesh.shells();
    shells[1..]
        .iter()
        .map(|s| {
            let faces: Vec<[u32; 3]> = s.faces.iter().map(|&f| m.mesh.triangles()[f]).collect();
            -fibfluid_geometry::volume(&run.positions, &faces)
        })
        .collect()
}
