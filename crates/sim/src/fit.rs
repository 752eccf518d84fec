//! The fit behind a calibration: the best scale of one displacement field against another,
//! the relative L2 error of two fields, and the [`Calibration`] record of `report.json`.
//! Pure data and arithmetic: the step that runs the two methods is
//! [`crate::calibration`].

use fibfluid_geometry::Vec3;
use serde::Serialize;

use fibfluid_assembly::Material;

use crate::choices::FiberModel;

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
    /// The fiber modulus found (the scene's `[ffm] fiber_modulus` that matches the FEM; a fiber
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

impl Calibration {
    /// Puts the calibrated fibers (its fiber modulus on every axis and its surface tension)
    /// in `material`.
    pub fn apply(&self, material: &mut Material) -> Result<(), fibfluid_assembly::AssemblyError> {
        material.set_fiber_modulus([self.fiber_modulus; 3])?;
        material.set_surface_tension(self.surface_tension)
    }
}
