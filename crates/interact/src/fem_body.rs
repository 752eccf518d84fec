//! The finite-element method behind the method-neutral [`Interactive`] trait: the model's
//! sparse-grid body factored once, its own loads (gravity, point forces) as the base state,
//! grabbed vertices held by a capacitance update of the kept factor
//! ([`fibfluid_fem::FemBody::respond_held`]) and pushes added to the loads. A frame costs one
//! solve on the kept factor plus the capacitance system of the held vertices; the
//! compliance columns of a grabbed vertex are computed when it is first grabbed and kept.

use std::collections::BTreeMap;
use std::time::Instant;

use fibfluid_fem::{FemBody, FemHold, FemStats, Loads};
use fibfluid_geometry::Vec3;
use fibfluid_sim::fem_run::{build_body, full_loads};
use fibfluid_sim::{Method, Model, StageLog, memory_budget};

use crate::{Hold, InteractError, Interactive, Result};

/// A model's interactive finite-element body.
pub struct FemInteractive {
    body: FemBody,
    base_loads: Loads,
    rest: Vec<Vec3>,
    fixed: Vec<Option<char>>,
    pending: BTreeMap<usize, Hold>,
    field: Vec<Vec3>,
    positions: Vec<Vec3>,
    reactions: Vec<(usize, Vec3)>,
    frame: u64,
    setup_seconds: f64,
}

impl std::fmt::Debug for FemInteractive {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FemInteractive").field("body", &self.body).field("frame", &self.frame).finish()
    }
}

impl FemInteractive {
    /// Builds the body of `model` (voxelize, assemble, factor; refused from counts above
    /// the memory budget) and solves its own loads as the base state.
    pub fn new(model: &Model, max_memory: Option<u64>) -> fibfluid_sim::Result<Self> {
        let start = Instant::now();
        fibfluid_sim::fem_run::refuse_plates(model)?;
        let mut log = StageLog::default();
        let mut body = build_body(model, memory_budget(max_memory), &mut log)?;
        let base_loads = full_loads(model);
        let base = body
            .solve(&base_loads)
            .map_err(|source| fibfluid_sim::Error::Fem { scene: model.display_name(), source })?;
        let rest = model.rest_positions();
        let fixed = (0..rest.len())
            .map(|v| {
                (0..3).find(|&a| model.constraints.get(v, a).is_some()).map(|a| fibfluid_geometry::AXES[a])
            })
            .collect();
        let field = base.surface_displacements;
        let positions = rest.iter().zip(&field).map(|(p, u)| add(*p, *u)).collect();
        Ok(Self {
            body,
            base_loads,
            rest,
            fixed,
            pending: BTreeMap::new(),
            field,
            positions,
            reactions: Vec::new(),
            frame: 0,
            setup_seconds: start.elapsed().as_secs_f64(),
        })
    }

    /// Seconds of the setup (voxelization, assembly, factorization, base solve).
    pub fn setup_seconds(&self) -> f64 {
        self.setup_seconds
    }

    /// The grid's sizes and timings.
    pub fn stats(&self) -> FemStats {
        self.body.stats()
    }

    fn check(&self, vertex: usize, value: Vec3, what: &'static str) -> Result<()> {
        if vertex >= self.rest.len() {
            return Err(InteractError::UnknownVertex { vertex, vertices: self.rest.len() });
        }
        if let Some(&value) = value.iter().find(|c| !c.is_finite()) {
            return Err(InteractError::NonFinite { vertex, what, value });
        }
        Ok(())
    }
}

fn add(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

impl Interactive for FemInteractive {
    /// A linear response on the kept factorization: the holds decide the frame.
    fn answers_from_holds(&self) -> bool {
        true
    }

    fn method(&self) -> Method {
        Method::Fem
    }

    fn n_vertices(&self) -> usize {
        self.rest.len()
    }

    fn rest_positions(&self) -> &[Vec3] {
        &self.rest
    }

    fn is_fixed(&self, vertex: usize) -> bool {
        self.fixed.get(vertex).is_some_and(Option::is_some)
    }

    fn supports_forces(&self) -> bool {
        true
    }

    fn grab(&mut self, vertex: usize, displacement: Vec3) -> Result<()> {
        self.check(vertex, displacement, "displacement")?;
        if let Some(axis) = self.fixed[vertex] {
            return Err(InteractError::FixedVertex { vertex, axis, action: "grabbed" });
        }
        self.pending.insert(vertex, Hold::Grab { displacement });
        Ok(())
    }

    fn push(&mut self, vertex: usize, force: Vec3) -> Result<()> {
        self.check(vertex, force, "force")?;
        self.pending.insert(vertex, Hold::Push { force });
        Ok(())
    }

    fn contact(&mut self, vertex: usize, normal: Vec3, along: f64) -> Result<()> {
        self.check(vertex, normal, "contact")?;
        if let Some(axis) = self.fixed[vertex] {
            return Err(InteractError::FixedVertex { vertex, axis, action: "touched" });
        }
        crate::interactive::check_normal(vertex, normal, along)?;
        self.pending.insert(vertex, Hold::Contact { normal, along });
        Ok(())
    }

    fn release(&mut self, vertex: usize) -> Result<()> {
        self.check(vertex, [0.0; 3], "displacement")?;
        self.pending.remove(&vertex);
        Ok(())
    }

    fn release_all(&mut self) {
        self.pending.clear();
    }

    fn holds(&self) -> Vec<(usize, Hold)> {
        self.pending.iter().map(|(&v, &h)| (v, h)).collect()
    }

    fn update(&mut self) -> Result<&[(usize, Vec3)]> {
        let mut loads = self.base_loads.clone();
        let mut held = Vec::new();
        for (&v, h) in &self.pending {
            match *h {
                Hold::Grab { displacement } => held.push((v, FemHold::At(displacement))),
                Hold::Contact { normal, along } => held.push((v, FemHold::Along { normal, along })),
                Hold::Push { force } => loads.point_forces.push((v, force)),
            }
        }
        let response = self
            .body
            .respond_holds(&loads, &held)
            .map_err(|e| InteractError::Singular { what: e.to_string() })?;
        self.field = response.surface_displacements;
        self.positions = self.rest.iter().zip(&self.field).map(|(p, u)| add(*p, *u)).collect();
        let mut reactions = held.iter().map(|h| h.0).zip(response.reactions).collect::<Vec<_>>();
        reactions.extend(self.pending.iter().filter_map(|(&v, h)| match *h {
            Hold::Push { force } => Some((v, force)),
            _ => None,
        }));
        reactions.sort_by_key(|r| r.0);
        self.reactions = reactions;
        self.frame += 1;
        Ok(&self.reactions)
    }

    fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    fn field(&self) -> &[Vec3] {
        &self.field
    }

    fn reactions(&self) -> &[(usize, Vec3)] {
        &self.reactions
    }

    fn frame(&self) -> u64 {
        self.frame
    }

    fn memory_bytes(&self) -> usize {
        let s = self.body.stats();
        8 * s.factor_nonzeros + 12 * s.nonzeros + 24 * self.body.cached_holds() * s.dofs
    }
}
