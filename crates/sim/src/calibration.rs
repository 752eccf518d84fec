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
    let u_fem = displacements(&fem_run.positions, &fem_run.rest);
    let mut ffm = model.clone();
    ffm.ffm.calibrate = false;
    ffm.solver.method = Method::Ffm;
    ffm.solver.mode = Mode::Paper;
    ffm.load.steps = 1;
    ffm.load.tolerance = None;
    // The probe run: a fiber modulus numerically equal to E (the answer scales with its
    // inverse, so any value would do).
    ffm.material.set_fiber_modulus([tissue.young(); 3])?;
    ffm.material.set_surface_tension(0.0)?;
    let setup = SetupOptions { max_memory, ..Default::default() };
    let mut sim = Simulation::setup(ffm, None, &setup, StageLog::default(), Instant::now())?;
    sim.run(&RunOptions::default())?;
    let u_ffm = displacements(sim.positions(), sim.rest_positions());
    let (scale, error_vs_fem) = best_scale(&u_ffm, &u_fem);
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
        surface_tension: 0.0,
        scale,
        error_vs_fem,
        fem_resolution: resolution,
        seconds: start.elapsed().as_secs_f64(),
    })
}
