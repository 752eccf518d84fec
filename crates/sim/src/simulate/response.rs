//! The interactive response of a factored body: forces and held vertices.

use std::time::Instant;

use fibfluid_assembly::{Loads, load_vector};
use fibfluid_geometry::Vec3;
use fibfluid_linalg::{FactorizationExt, HeldCapacitance, VertexColumns, VertexSource};

use super::core::Simulation;
use super::state::*;
use crate::choices::Method;
use crate::stages::names;
use crate::{Error, Result};

impl Simulation {
    /// The static response of the current factorization to point forces alone (no
    /// stepping, no position update): the interactive use of a factored body.
    pub fn respond(&mut self, forces: &[(usize, Vec3)]) -> Result<(Vec<Vec3>, f64)> {
        self.refuse_coupled()?;
        let n = self.state.positions.len();
        if let Some(&(v, _)) = forces.iter().find(|(v, _)| *v >= n) {
            return Err(Error::VertexOutOfRange { vertex: v, vertices: n });
        }
        let loads = Loads { forces, ..Default::default() };
        let b = load_vector(self.axes(), &self.state.positions, &self.factored.border_areas, &loads)?;
        let x = self.solve(&b, 0.0, 1.0, false)?;
        Ok(self.factored.split(&x))
    }

    /// The static response of the current factorization to point forces with vertices
    /// held at given displacements (no stepping, no position update): a tool grabbing the
    /// body. The held set is a change of the constraints on the kept factorization, imposed
    /// by the capacitance of the held vertices over their compliance columns, the same code
    /// as the interactive body ([`fibfluid_linalg::HeldCapacitance`] over
    /// [`fibfluid_linalg::VertexColumns`]): a vertex held for the first time costs one
    /// bordered solve per distinct stiffness block (its columns are then cached until the
    /// operator changes), a new held set a `(dk)^3 / 3` Cholesky, and each call one checked
    /// solve plus `O(k N)`, where refactoring with the vertices eliminated would cost
    /// `N^3 / 3` per stiffness block. A vertex listed twice is held once (at its first
    /// displacement).
    pub fn respond_held(&mut self, forces: &[(usize, Vec3)], held: &[(usize, Vec3)]) -> Result<Response> {
        self.refuse_coupled()?;
        let n = self.state.positions.len();
        let axes = self.axes();
        if let Some(&(v, _)) = forces.iter().chain(held).find(|(v, _)| *v >= n) {
            return Err(Error::VertexOutOfRange { vertex: v, vertices: n });
        }
        if let Some(&(v, _)) =
            held.iter().find(|(v, _)| (0..axes).any(|c| self.model.constraints.get(*v, c).is_some()))
        {
            return Err(Error::HeldFixedVertex { vertex: v });
        }
        let mut targets: Vec<(usize, Vec3)> = Vec::with_capacity(held.len());
        for &(v, d) in held {
            if !targets.iter().any(|t| t.0 == v) {
                targets.push((v, d));
            }
        }
        let vertices: Vec<usize> = targets.iter().map(|t| t.0).collect();
        let f = &mut self.factored;
        let loads = Loads { forces, ..Default::default() };
        let b = load_vector(axes, &self.state.positions, &f.border_areas, &loads)?;
        let rhs = f.system.rhs(&b, 0.0, &f.border_areas, 1.0);
        let start = Instant::now();
        let sol = f.factorization.solve(&rhs)?;
        let mut x = sol.x;
        let mut reactions = vec![];
        if !vertices.is_empty() {
            let columns = match &mut f.held.columns {
                Some(c) => c,
                None => f.held.columns.insert(VertexColumns::new(f.factorization.as_ref())?),
            };
            columns.touch(f.factorization.as_ref(), &vertices)?;
            if f.held.capacitance.as_ref().is_none_or(|c| c.vertices() != vertices) {
                f.held.capacitance = Some(HeldCapacitance::new(&*columns, &vertices)?);
            }
            let cap = f.held.capacitance.as_ref().expect("built above");
            let values: Vec<f64> = targets.iter().flat_map(|&(_, d)| d.into_iter().take(axes)).collect();
            let source = VertexSource::bordered(&*columns, f.system.matrix.pressure_scale());
            reactions = cap.impose(&source, &values, &mut x)?;
        }
        self.log.add(names::SOLVE, start.elapsed().as_secs_f64());
        self.counters.solves += 1;
        let (displacements, pressure) = self.factored.split(&x);
        let reactions = held
            .iter()
            .map(|&(v, _)| *reactions.iter().find(|r| r.0 == v).expect("every held vertex has a reaction"))
            .collect();
        Ok(Response { displacements, pressure, reactions })
    }

    /// The interactive responses are built on the paper's per-axis operator only.
    pub(super) fn refuse_coupled(&self) -> Result<()> {
        if self.factored.coupled.is_some() {
            return Err(Error::MethodNeeds {
                scene: self.model.display_name(),
                method: Method::Ffm,
                problem: "with fibers = \"projected\" has no interactive response yet (use fibers = \"paper\")",
            });
        }
        Ok(())
    }
}
