//! What the finite-element runs take from a model: its tissue, fixed axes and loads, the
//! refusal from counts, the linear body, and the record of a plate's contact. Shared by the
//! linear and the Newton runs ([`crate::fem_run`], [`crate::hyper_run`]).

use std::time::Instant;

use fibfluid_fem::{FemBody, FemOptions, GridEstimate, Loads, Tissue};
use serde::Serialize;

use crate::choices::Method;
use crate::model::{Model, Shape};
use crate::stages::{StageLog, names};
use crate::{Error, Result};

/// A failure of the finite-element crate, with the scene named.
pub(crate) fn failed(model: &Model) -> impl Fn(fibfluid_fem::FemError) -> Error + '_ {
    move |source| Error::Fem { scene: model.display_name(), source }
}

/// The problem of a model that the finite-element method cannot run.
pub(crate) fn needs(model: &Model, problem: &'static str) -> Error {
    Error::MethodNeeds { scene: model.display_name(), method: Method::Fem, problem }
}

/// The model's tissue, or the error that names the missing `[tissue]` section.
pub fn tissue_of(model: &Model) -> Result<Tissue> {
    // A `Tissue` is valid by construction: nothing to check again here.
    model
        .tissue
        .ok_or_else(|| needs(model, "needs a [tissue] section (young in Pa, poisson, density in kg/m^3)"))
}

/// The grid the model would get, from counts, refused when its estimated factor would not
/// fit in `limit` bytes.
pub fn estimate(model: &Model, limit: u64) -> Result<GridEstimate> {
    let Shape::Surface(file) = &model.shape else {
        return Err(needs(model, "needs a surface mesh (this scene is a 2D polygon)"));
    };
    let est = GridEstimate::of(file.mesh.positions(), model.fem.resolution).map_err(failed(model))?;
    let (bytes, _) = est.solver_cost(model.fem.solver);
    if bytes > limit as f64 {
        return Err(Error::TooLarge {
            scene: model.display_name(),
            stage: names::FACTORIZATION,
            needed: bytes as u64,
            available: limit,
            hint: "lower [fem] resolution",
        });
    }
    Ok(est)
}

/// Per surface vertex, the axes the model fixes. A prescribed non-zero displacement is
/// refused (the FEM holds fixed vertices at zero).
pub fn fixed_axes(model: &Model) -> Result<Vec<[bool; 3]>> {
    if model.constraints.has_nonzero() {
        return Err(needs(
            model,
            "holds fixed vertices at zero: prescribed non-zero displacements are not supported",
        ));
    }
    Ok((0..model.n_vertices())
        .map(|v| std::array::from_fn(|a| model.constraints.get(v, a).is_some()))
        .collect())
}

/// The model's loads in full: gravity and every point force (their timing is a stepping
/// matter; the linear FEM applies the whole load at once).
pub fn full_loads(model: &Model) -> Loads {
    Loads {
        gravity: model.load.gravity,
        point_forces: model.load.forces.iter().map(|f| (f.vertex, f.value)).collect(),
    }
}

/// Builds the model's finite-element body (voxelized, assembled, factored), refusing from
/// counts first. Plates are the caller's ([`FemRun`] carries them).
pub fn build_body(model: &Model, limit: u64, log: &mut StageLog) -> Result<FemBody> {
    let tissue = tissue_of(model)?;
    estimate(model, limit)?;
    let fixed = fixed_axes(model)?;
    let Shape::Surface(file) = &model.shape else { unreachable!("estimate refused a polygon") };
    let options = FemOptions { resolution: model.fem.resolution, ..FemOptions::default() };
    let start = Instant::now();
    let body = FemBody::from_surface(file.mesh.positions(), file.mesh.triangles(), &tissue, &fixed, &options)
        .map_err(failed(model))?;
    let total = start.elapsed().as_secs_f64();
    let stats = body.stats();
    log.add(names::VOXELIZATION, (total - stats.assembly_seconds - stats.factor_seconds).max(0.0));
    log.add(names::ASSEMBLY, stats.assembly_seconds);
    log.add(names::FACTORIZATION, stats.factor_seconds);
    Ok(body)
}

/// Refuses a model with plates for an interactive finite-element body (its base state is
/// one solve without contact).
pub fn refuse_plates(model: &Model) -> Result<()> {
    if model.plates.is_empty() {
        return Ok(());
    }
    Err(needs(model, "does not carry [[plate]] contact in an interactive body (use `run --method fem`)"))
}

/// One plate's contact in a finite-element run (at its final position).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FemPlate {
    /// Total contact force on the body along the plate's normal (N).
    pub force: f64,
    /// Surface samples in contact (the surface is sampled at most half a cell apart).
    pub contact_samples: usize,
    /// The deepest remaining penetration of a sample (m).
    pub penetration: f64,
    /// Contact augmentations (shared by all plates).
    pub augmentations: usize,
    /// The contact pressure at each surface vertex (Pa, the grid's surface order; for
    /// pictures, not in `report.json`).
    #[serde(skip)]
    pub pressure: Vec<f64>,
}
