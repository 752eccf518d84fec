//! Calibrating FFM's fiber modulus on a body against the finite-element method, for a scene
//! that gives only `[tissue]` (Young's modulus E in Pa, Poisson's ratio, density).
//!
//! FFM's fibers have no Young's modulus: their modulus maps to a tissue's by a factor that
//! depends on the body (1x to 72x measured across the fixtures). So on the scene's own body,
//! clamps and loads:
//!
//! 1. the FEM runs at [`CALIBRATION_RESOLUTION`] (coarse: seconds) with the tissue: `u_fem`;
//! 2. FFM runs in paper mode, one step, with fiber modulus E and no surface tension:
//!    `u_ffm` (linear in the loads and in 1 / modulus, so one run gives every modulus);
//! 3. the fiber modulus becomes `s E` with the best scale `s = (u_ffm . u_ffm) / (u_ffm .
//!    u_fem)` (the least-squares fit of `u_ffm / s` to `u_fem` over the surface vertices);
//! 4. `error_vs_fem` is the shape error left after that scale, `|u_ffm / s - u_fem| /
//!    |u_fem|` (relative L2 over the surface).
//!
//! The scene then runs as written (its mode, steps, fibers) with the calibrated modulus.

use std::time::Instant;

use fibfluid_geometry::Vec3;
use serde::Serialize;

use crate::choices::{FiberModel, Method, Mode};
use crate::fem_run::FemRun;
use crate::model::Model;
use crate::simulate::{RunOptions, SetupOptions, Simulation};
use crate::{Error, Result};

/// The FEM's resolution for a calibration: coarse enough to take seconds, within ~5 % of
/// the FEM's default on the reference bodies (docs/fem.md).
pub const CALIBRATION_RESOLUTION: usize = 16;

/// What a calibration found (`report.json`'s `calibration` block).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Calibration {
    /// The fiber model calibrated.
    pub fibers: FiberModel,
    /// The tissue's Young's modulus (Pa) the calibration started from.
    pub tissue_young: f64,
    /// The fiber modulus found (the scene's `[ffm] young` that matches the FEM; a fiber
    /// modulus, not a Young's modulus).
    pub fiber_modulus: f64,
    /// The fiber surface tension used (0: the calibration fits the modulus alone).
    pub surface_tension: f64,
    /// `fiber_modulus / tissue_young`.
    pub scale: f64,
    /// Relative L2 shape error of FFM against the FEM after the scale.
    pub error_vs_fem: f64,
    /// The FEM's resolution.
    pub fem_resolution: usize,
    /// Seconds of the two runs.
    pub seconds: f64,
}

/// `positions - rest`, vertex by vertex.
pub fn displacements(positions: &[Vec3], rest: &[Vec3]) -> Vec<Vec3> {
    positions.iter().zip(rest).map(|(p, r)| [p[0] - r[0], p[1] - r[1], p[2] - r[2]]).collect()
}

fn dot(a: &[Vec3], b: &[Vec3]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x[0] * y[0] + x[1] * y[1] + x[2] * y[2]).sum()
}

/// `|u - reference| / |reference|` over the vertices, no scaling (L2 norms of the stacked
/// displacements; `|u - reference|` alone when the reference is zero).
pub fn relative_l2(u: &[Vec3], reference: &[Vec3]) -> f64 {
    let diff: Vec<Vec3> =
        u.iter().zip(reference).map(|(a, b)| [a[0] - b[0], a[1] - b[1], a[2] - b[2]]).collect();
    let (dd, rr) = (dot(&diff, &diff), dot(reference, reference));
    if rr > 0.0 { (dd / rr).sqrt() } else { dd.sqrt() }
}

/// The best scale `s` of `u_ffm / s` against `u_fem` and the relative L2 error left.
/// Without any displacement to fit (no load) the scale is 1 and the error 0.
pub fn best_scale(u_ffm: &[Vec3], u_fem: &[Vec3]) -> (f64, f64) {
    let (aa, ab, bb) = (dot(u_ffm, u_ffm), dot(u_ffm, u_fem), dot(u_fem, u_fem));
    if !(aa > 0.0 && ab > 0.0 && bb > 0.0) {
        return (1.0, if bb > 0.0 { 1.0 } else { 0.0 });
    }
    let s = aa / ab;
    let diff: f64 =
        u_ffm.iter().zip(u_fem).map(|(a, b)| (0..3).map(|c| (a[c] / s - b[c]).powi(2)).sum::<f64>()).sum();
    (s, (diff / bb).sqrt())
}

/// Calibrates the model's fiber modulus against the FEM (see the module docs). The model
/// needs a `[tissue]`.
pub fn calibrate(model: &Model, max_memory: Option<u64>) -> Result<Calibration> {
    let start = Instant::now();
    let tissue = crate::fem_run::tissue_of(model)?;
    let mut fem = model.clone();
    fem.solver.method = Method::Fem;
    fem.fem.resolution = CALIBRATION_RESOLUTION;
    let fem_run = FemRun::new(fem, max_memory)?;
    let u_fem = displacements(&fem_run.positions, &fem_run.rest);
    let mut ffm = model.clone();
    ffm.ffm.calibrate = false;
    ffm.solver.method = Method::Ffm;
    ffm.solver.mode = Mode::Paper;
    ffm.steps = 1;
    ffm.tolerance = None;
    ffm.material.young = [tissue.young; 3];
    ffm.material.surface_tension = 0.0;
    let mut sim = Simulation::with_options(ffm, &SetupOptions { max_memory, ..Default::default() })?;
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
        tissue_young: tissue.young,
        fiber_modulus: scale * tissue.young,
        surface_tension: 0.0,
        scale,
        error_vs_fem,
        fem_resolution: CALIBRATION_RESOLUTION,
        seconds: start.elapsed().as_secs_f64(),
    })
}
