//! Sample models for benches and tests.

use fibfluid_assembly::{ConstraintKind, Material, Selector};
use fibfluid_geometry::{GeometryError, MeshFile, icosphere};

use crate::{Model, Result};

/// The benches' body: an icosphere of radius 1 at subdivision `level` with the paper's
/// material, the cap y > 0.8 fixed by elimination and gravity (0, -10, 0), one load step,
/// default solver options.
pub fn hanging_sphere(level: u32) -> Result<Model> {
    let mesh = icosphere(level, 1.0);
    let n = mesh.n_vertices();
    let path = format!("icosphere-{level}");
    let file = MeshFile::from_mesh(&path, mesh)
        .map_err(|source| GeometryError::Mesh { path: path.into(), source })?;
    let mut scene = Model::from_mesh(format!("sphere-{n}"), file, Material::default());
    let positions = scene.rest_positions();
    scene.constraints.fix_selected(&Selector::Above { axis: 1, value: 0.8 }, &positions, [true; 3])?;
    scene.load.gravity = [0.0, -10.0, 0.0];
    scene.solver.constraints = ConstraintKind::Eliminate;
    Ok(scene)
}
