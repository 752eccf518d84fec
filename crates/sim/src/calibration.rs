//! Calibrating FFM's fiber modulus on a body against the finite-element method, for a scene
//! that gives only `[tissue]` (Young's modulus E in Pa, Poisson's ratio, density).
//!
//! FFM's fibers have no Young's modulus: their modulus maps to a tissue's by a factor that
//! depends on the body (1x to 72x measured across the fixtures). So on the scene's own body,
//! clamps and loads:
//!
//! 1. the FEM runs at [`CALIBRATION_RESOLUTION`] (coarse: seconds), or at the scene's
//!    `[fem] resolution` when that is higher, with the tissue: `u_fem`;
//! 2. FFM runs in paper mode, one step, with fiber modulus E and no surface tension:
//!    `u_ffm` (linear in the loads and in 1 / modulus, so one run gives every modulus);
//! 3. the fiber modulus becomes `s E` with the best scale `s = (u_ffm . u_ffm) / (u_ffm .
//!    u_fem)` (the least-squares fit of `u_ffm / s` to `u_fem` over the surface vertices);
//! 4. `error_vs_fem` is the shape error left after that scale, `|u_ffm / s - u_fem| /
//!    |u_fem|` (relative L2 over the surface).
//!
//! With `[ffm] surface_tension > 0` (surface fibers: they hold the vertices that culling
//! leaves without a bulk fiber) the runs keep that tension, and the answer is no longer
//! proportional to 1 / modulus: the scale is sought by secant steps on the best fit's
//! factor `c(s)` (whose inverse is affine in `s` when both kinds of fibers deform alike),
//! until it is 1 within [`TENSION_FIT_TOLERANCE`], at most [`TENSION_FIT_RUNS`] runs. A
//! tension stiffer on its own than the tissue leaves no modulus to find and is refused.
//!
//! The scene then runs as written (its mode, steps, fibers) with the calibrated modulus.

use std::time::Instant;

use crate::choices::{Method, Mode};
use crate::fem_run::FemRun;
use crate::model::{Model, Shape};
use crate::simulate::{RunOptions, SetupOptions, Simulation};
use crate::stages::StageLog;
use crate::{Error, Result};

pub use crate::fit::{CALIBRATION_RESOLUTION, Calibration, best_scale, displacements, relative_l2};

/// The FEM resolution of a calibration: [`CALIBRATION_RESOLUTION`], or the coarsest that
/// puts a cell across the body's thinnest extent (`longest / thinnest` cells along the
/// longest side, so a thin slab calibrates instead of failing with advice about a
/// resolution the calibration would not use), whichever is finer, at most
/// [`fibfluid_fem::MAX_RESOLUTION`].
pub fn calibration_resolution(model: &Model) -> usize {
    let Shape::Surface(file) = &model.shape else { return CALIBRATION_RESOLUTION };
    let (lo, hi) = fibfluid_geometry::bounding_box(file.mesh.positions());
    let extent: [f64; 3] = std::array::from_fn(|a| hi[a] - lo[a]);
    let longest = extent.iter().fold(0.0_f64, |m, &e| m.max(e));
    let thinnest = extent.iter().fold(f64::INFINITY, |m, &e| m.min(e));
    let needed = longest / thinnest;
    if !(needed.is_finite() && needed > CALIBRATION_RESOLUTION as f64) {
        return CALIBRATION_RESOLUTION;
    }
    // One more cell than the ratio asks: the grid check allows no body thinner than a cell.
    (needed.ceil() as usize + 1).min(fibfluid_fem::MAX_RESOLUTION)
}

/// Calibrates the model's fiber modulus against the FEM (see the module docs). The model
/// needs a `[tissue]`.
pub fn calibrate(model: &Model, max_memory: Option<u64>) -> Result<Calibration> {
    let start = Instant::now();
    let tissue = crate::fem_run::tissue_of(model)?;
    let mut fem = model.clone();
    fem.solver.method = Method::Fem;
    let resolution = calibration_resolution(model);
    fem.fem.resolution = resolution;
    let fem_run = FemRun::new(fem, max_memory)?;
    let u_fem = fem_run.displacements_clamped_exactly();
    let mut ffm = model.clone();
    ffm.ffm.calibrate = false;
    ffm.solver.method = Method::Ffm;
    ffm.solver.mode = Mode::Paper;
    ffm.load.steps = 1;
    ffm.load.tolerance = None;
    let tension = model.material.surface_tension();
    let setup = SetupOptions { max_memory, ..Default::default() };
    // One FFM run at fiber modulus `scale E` (and the scene's surface tension).
    let mut probe = |scale: f64| -> Result<Vec<fibfluid_geometry::Vec3>> {
        ffm.material.set_fiber_modulus([scale * tissue.young(); 3])?;
        ffm.material.set_surface_tension(tension)?;
        let mut sim = Simulation::setup(ffm.clone(), None, &setup, StageLog::default(), Instant::now())?;
        sim.run(&RunOptions::default())?;
        Ok(displacements(sim.positions(), sim.rest_positions()))
    };
    // Without tension the answer scales with 1 / modulus: one run at E gives the scale.
    let (scale, error_vs_fem) = if tension > 0.0 {
        scale_with_tension(model, &u_fem, &mut probe)?
    } else {
        best_scale(&probe(1.0)?, &u_fem)
    };
    if !scale.is_finite() {
        return Err(Error::MethodNeeds {
            scene: model.display_name(),
            method: Method::Ffm,
            problem: "cannot be calibrated against the FEM: the two answers point in opposite directions",
        });
    }
    Ok(Calibration {
        fibers: model.ffm.fibers,
        tissue_young: tissue.young(),
        fiber_modulus: scale * tissue.young(),
        surface_tension: tension,
        scale,
        error_vs_fem,
        fem_resolution: resolution,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Most FFM runs of a calibration with surface tension (see the module docs).
pub const TENSION_FIT_RUNS: usize = 12;

/// A calibration with surface tension stops when the best fit's factor is this close to 1.
pub const TENSION_FIT_TOLERANCE: f64 = 1e-6;

/// The scale of the fiber modulus whose run (with the scene's surface tension) fits `u_fem`
/// with a factor of 1, and the shape error left: secant steps on `1 / c(s)` from `s = 1`
/// (see the module docs).
fn scale_with_tension(
    model: &Model,
    u_fem: &[fibfluid_geometry::Vec3],
    probe: &mut dyn FnMut(f64) -> Result<Vec<fibfluid_geometry::Vec3>>,
) -> Result<(f64, f64)> {
    let refuse = |problem| Error::MethodNeeds { scene: model.display_name(), method: Method::Ffm, problem };
    let (mut s0, mut c0) = (1.0, best_scale(&probe(1.0)?, u_fem).0);
    // The next guess as if the tension were not there.
    let mut s1 = s0 * c0;
    for _ in 1..TENSION_FIT_RUNS {
        let (c1, error) = best_scale(&probe(s1)?, u_fem);
        if (c1 - 1.0).abs() <= TENSION_FIT_TOLERANCE {
            return Ok((s1, error));
        }
        let (r0, r1) = (1.0 / c0, 1.0 / c1);
        let next = s1 + (1.0 - r1) * (s1 - s0) / (r1 - r0);
        if !(next.is_finite() && next > 0.0) {
            return Err(refuse(
                "cannot be calibrated against the FEM with this [ffm] surface_tension: the surface fibers alone are stiffer than the tissue; lower it",
            ));
        }
        (s0, c0, s1) = (s1, c1, next);
    }
    Err(refuse(
        "cannot be calibrated against the FEM with this [ffm] surface_tension: the fiber modulus did not settle; lower the tension",
    ))
}
