//! Setting a simulation up: fibers, areas, assembly and the first factorization.

use std::time::Instant;

use fibfluid_geometry::vec3::{norm, sub};
use fibfluid_geometry::{Boundary, FiberSet, VisibilityOptions, cull_fibers};
use fibfluid_linalg::PrescribedSet;

use super::core::Simulation;
use super::factored::*;
use super::state::*;
use crate::choices::{FiberModel, Method};
use crate::contact::PlateRecord;
use crate::fit::Calibration;
use crate::model::{Model, Shape};
use crate::plan::Plan;
use crate::stages::{StageLog, names};
use crate::{Error, Result};

impl Simulation {
    /// Builds a simulation of a model whose fiber modulus is known (no calibration left
    /// to do: [`crate::pipeline`] runs it first): the plan, fibers, areas, assembly and the
    /// first factorization. `log` and `started` carry what ran before (the calibration).
    pub(crate) fn setup(
        scene: Model,
        calibration: Option<Calibration>,
        opts: &SetupOptions,
        mut log: StageLog,
        started: Instant,
    ) -> Result<Self> {
        if scene.ffm.calibrate {
            return Err(Error::MethodNeeds {
                scene: scene.display_name(),
                method: Method::Ffm,
                problem: "has no fiber modulus yet: calibrate it first (`Simulation::new` does)",
            });
        }
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
        check_every_vertex_is_held(&scene, &fibers)?;
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
            contact: PlateContact { records: vec![PlateRecord::default(); plates], ..Default::default() },
            calibration,
            log,
            started,
        })
    }
}

/// Refuses, with one line, what the projected fibers do not run: they run every mode on a
/// surface, in f64, without plates.
pub(crate) fn refuse_projected(scene: &Model) -> Result<()> {
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

/// Refuses fibers that leave a vertex with nothing to hold it: no bulk fiber kept inside the
/// body after culling (a vertex in a deep crevice of a concave mesh) and no surface fibers
/// (surface tension 0). Its stiffness row would be empty and the factorization would blame
/// the constraints; this names the vertices (file order) and what would hold them.
pub fn check_every_vertex_is_held(scene: &Model, fibers: &FiberSet) -> Result<()> {
    if scene.material.surface_tension() > 0.0 {
        return Ok(());
    }
    let lonely: Vec<usize> =
        fibers.per_vertex().iter().enumerate().filter(|(_, c)| **c == 0).map(|(v, _)| v).collect();
    if lonely.is_empty() {
        return Ok(());
    }
    let file = |v: usize| match &scene.shape {
        Shape::Surface(m) => m.to_file.get(v).map(|&f| f as usize).unwrap_or(v),
        Shape::Polygon(_) => v,
    };
    let named: Vec<String> = lonely.iter().take(5).map(|&v| file(v).to_string()).collect();
    let more = if lonely.len() > 5 { format!(" and {} more", lonely.len() - 5) } else { String::new() };
    Err(Error::UnheldVertices {
        scene: scene.display_name(),
        vertices: named.join(", ") + &more,
        count: lonely.len(),
    })
}
