//! The finite-element method behind the method-neutral [`Interactive`] trait: the model's
//! sparse-grid body factored once, its own loads (gravity, point forces) as the base state,
//! grabbed vertices held by a capacitance update of the kept factor
//! ([`fibfluid_fem::FemBody::respond_held`]) and pushes added to the loads. A frame costs one
//! solve on the kept factor plus the capacitance system of the held vertices; the
//! compliance columns of a grabbed vertex are computed when it is first grabbed and kept.

use std::time::Instant;

use fibfluid_fem::{FemBody, FemStats, Loads};
use fibfluid_geometry::Vec3;
use fibfluid_sim::fem_run::{build_body, full_loads};
use fibfluid_sim::{Method, Model, StageLog, memory_budget};

use crate::holds::fem_reactions;
use crate::{Holds, InteractError, Interactive, PushRule, Result, Surface};

/// A model's interactive finite-element body.
pub struct FemInteractive {
    body: FemBody,
    base_loads: Loads,
    holds: Holds,
    /// Rest shape and current frame.
    surface: Surface,
    setup_seconds: f64,
}

impl std::fmt::Debug for FemInteractive {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FemInteractive")
            .field("body", &self.body)
            .field("frame", &self.surface.frame)
            .finish()
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
        let holds = Holds::of_model(model, PushRule::Anywhere);
        let mut surface = Surface::at_rest(model.rest_positions());
        surface.set_field(base.surface_displacements);
        Ok(Self { body, base_loads, holds, surface, setup_seconds: start.elapsed().as_secs_f64() })
    }

    /// Seconds of the setup (voxelization, assembly, factorization, base solve).
    pub fn setup_seconds(&self) -> f64 {
        self.setup_seconds
    }

    /// The grid's sizes and timings.
    pub fn stats(&self) -> FemStats {
        self.body.stats()
    }
}

impl Interactive for FemInteractive {
    /// A linear response on the kept factorization: the holds decide the frame.
    fn answers_from_holds(&self) -> bool {
        true
    }

    fn method(&self) -> Method {
        Method::Fem
    }

    fn surface(&self) -> &Surface {
        &self.surface
    }

    fn holds(&self) -> &Holds {
        &self.holds
    }

    fn holds_mut(&mut self) -> &mut Holds {
        &mut self.holds
    }

    fn update(&mut self) -> Result<&[(usize, Vec3)]> {
        let (held, pushes) = self.holds.split();
        let mut loads = self.base_loads.clone();
        loads.point_forces.extend_from_slice(&pushes);
        let response = self
            .body
            .respond_holds(&loads, &held)
            .map_err(|e| InteractError::Singular { what: e.to_string() })?;
        self.surface.set_field(response.surface_displacements);
        self.surface.reactions = fem_reactions(&held, response.reactions, &pushes);
        self.surface.frame += 1;
        Ok(&self.surface.reactions)
    }

    fn memory_bytes(&self) -> usize {
        let s = self.body.stats();
        8 * s.factor_nonzeros + 12 * s.nonzeros + self.body.cached_bytes()
    }
}
