//! Held surface vertices on the linear body: [`FemBody::respond_holds`], by the
//! capacitance update of `crate::held_system` on the kept factor of K.

use fibfluid_geometry::Vec3;

use crate::body::{FemBody, Loads};
use crate::error::Result;
use crate::held_rows::FemHold;
use crate::held_system::{HeldResponse, HeldSystem};

impl FemBody {
    /// The response to `loads` with each `(vertex, displacement)` of `held` moved exactly to
    /// its displacement. Compliance columns of a vertex are computed when it is first held
    /// and kept; [`FemBody::release_all`] drops them.
    ///
    /// Errors: a vertex out of range or held twice, a non-finite target, dependent holds
    /// (more held vertices in a cell than it has nodes: [`FemError::DependentHolds`]), a
    /// nonzero target on an axis carried only by fixed nodes ([`FemError::HeldOnFixed`]),
    /// and those of [`FemBody::solve`].
    pub fn respond_held(&mut self, loads: &Loads, held: &[(usize, Vec3)]) -> Result<HeldResponse> {
        let holds: Vec<(usize, FemHold)> = held.iter().map(|&(v, d)| (v, FemHold::At(d))).collect();
        self.respond_holds(loads, &holds)
    }

    /// The response to `loads` with each vertex held as its [`FemHold`] says: moved exactly
    /// to a displacement, or in frictionless contact along a normal. The reactions are in
    /// the order given; a contact's is along its normal. Errors as
    /// [`respond_held`](Self::respond_held).
    pub fn respond_holds(&mut self, loads: &Loads, holds: &[(usize, FemHold)]) -> Result<HeldResponse> {
        let f = self.load_vector(loads)?;
        let system = HeldSystem {
            factor: &self.factor,
            embedding: self.grid.embedding(),
            free: &self.free,
            rest: self.grid.surface_positions(),
        };
        let solved = system.solve(&mut self.held, f, holds, None, None)?;
        let residual = self.residual(&solved.u, &solved.applied)?;
        let node_displacements = self.node_values(&solved.u);
        let surface_displacements = self.grid.interpolate(&node_displacements);
        Ok(HeldResponse { node_displacements, surface_displacements, reactions: solved.reactions, residual })
    }

    /// Drops the cached compliance columns of every held vertex.
    pub fn release_all(&mut self) {
        self.held.clear_columns();
    }

    /// Number of vertices whose compliance columns are cached.
    pub fn cached_holds(&self) -> usize {
        self.held.vertices()
    }

    /// Bytes of the cached compliance columns (one solve each: a held vertex's three axes,
    /// or, for many vertices in few cells, the free dofs their rows touch).
    pub fn cached_bytes(&self) -> usize {
        self.held.bytes()
    }
}
