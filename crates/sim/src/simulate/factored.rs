//! The assembled system, its factorization and the coupled system of the projected fibers.

use fibfluid_assembly::{
    AssemblyOptions, Body, ConstraintMethod, PressureScaling, ProjectedSystem, System, assemble,
    assemble_projected,
};
use fibfluid_geometry::Vec3;
use fibfluid_linalg::{
    CoupledCholesky, FactorOptions, Factorization, HeldCapacitance, LinearSolver, PrescribedSet,
    VertexColumns,
};

use super::state::*;
use crate::Result;
use crate::model::Model;
use crate::stages::{Stage, StageLog, names};

/// The assembled system, its factorization and the shape its border describes.
pub(super) struct Factored {
    pub(super) system: System,
    pub(super) factorization: Box<dyn Factorization>,
    pub(super) solver: Box<dyn LinearSolver>,
    pub(super) options: FactorOptions,
    pub(super) border_areas: Vec<Vec3>,
    /// Vertices held by [`Simulation::respond_held`], on this factorization.
    pub(super) held: Holds,
    /// Contact constraints, on this factorization.
    pub(super) contact: PrescribedSet,
    /// With projected fibers (`[ffm] fibers = "projected"`): the coupled
    /// system and its factorization, which every step's solve uses instead of
    /// `factorization` (the paper's operator is still assembled and factored: it backs
    /// [`Simulation::system`] and [`Simulation::factorization`]).
    pub(super) coupled: Option<Coupled>,
}

/// The projected fibers' bordered system and its dense Cholesky (the stiffness lives in
/// the factorization; the system keeps what right-hand sides need).
pub(super) struct Coupled {
    pub(super) system: ProjectedSystem,
    pub(super) factor: CoupledCholesky,
}

impl Coupled {
    /// The coupled system assembled on a shape (its positions and vertex area vectors,
    /// timed as `assembly`) and its factorization.
    pub(super) fn build(
        scene: &Model,
        body: &BodyShape,
        (positions, areas): (&[Vec3], &[Vec3]),
        options: &FactorOptions,
        log: &mut StageLog,
        assembly: Stage,
    ) -> Result<Self> {
        let mut system = log.time(assembly, || assemble_projected_on(scene, body, positions, areas))?;
        let k = std::mem::replace(&mut system.stiffness, fibfluid_linalg::Mat::new());
        let border = system.border.clone();
        let factor = log.time(names::FACTORIZATION, || CoupledCholesky::factor(k, border, options))?;
        Ok(Self { system, factor })
    }
}

impl Factored {
    /// Splits a solution of the solved system into displacements and the pressure.
    pub(super) fn split(&self, x: &[f64]) -> (Vec<Vec3>, f64) {
        match &self.coupled {
            Some(c) => c.system.split_solution(x),
            None => self.system.split_solution(x),
        }
    }
}

/// Vertices held by [`Simulation::respond_held`]: the compliance columns of the vertices
/// held so far and the capacitance of the last held set, on the kept factorization.
#[derive(Default)]
pub(super) struct Holds {
    pub(super) columns: Option<VertexColumns>,
    pub(super) capacitance: Option<HeldCapacitance>,
}

/// The body's fibers and edges on a shape (its positions and vertex area vectors).
fn body_on<'a>(body: &'a BodyShape, positions: &'a [Vec3], areas: &'a [Vec3]) -> Body<'a> {
    Body {
        axes: body.boundary.axes(),
        positions,
        vertex_areas: areas,
        edges: &body.edges,
        fibers: &body.fibers,
        rest_positions: Some(&body.rest),
    }
}

/// The projected fibers' system on `positions` (the paper's constraint method).
pub(super) fn assemble_projected_on(
    scene: &Model,
    body: &BodyShape,
    positions: &[Vec3],
    areas: &[Vec3],
) -> Result<ProjectedSystem> {
    let shape = body_on(body, positions, areas);
    let opts =
        AssemblyOptions { method: scene.solver.constraint_method(), pressure_scaling: PressureScaling::None };
    Ok(assemble_projected(&shape, &scene.material, &scene.constraints, &opts)?)
}

/// The paper's per-axis system on `positions` (pressure scaled unless the penalty is asked
/// for).
pub(super) fn assemble_on(
    scene: &Model,
    body: &BodyShape,
    positions: &[Vec3],
    areas: &[Vec3],
) -> Result<System> {
    let shape = body_on(body, positions, areas);
    let method = scene.solver.constraint_method();
    let scaling = match method {
        // The paper's form is kept as published (Eq. 8) when its penalty is asked for.
        ConstraintMethod::Penalty { .. } => PressureScaling::None,
        ConstraintMethod::Eliminate => PressureScaling::Auto,
    };
    let opts = AssemblyOptions { method, pressure_scaling: scaling };
    Ok(assemble(&shape, &scene.material, &scene.constraints, &opts)?)
}
