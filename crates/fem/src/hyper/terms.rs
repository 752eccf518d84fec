//! The forces on a hyperelastic body besides its tissue's: each is a [`ForceTerm`] with an
//! energy, a gradient on the free dofs and a Hessian, evaluated at a load state. The clamp
//! (a penalty holding the fixed part of the surface), the plates' contact (an augmented
//! Lagrangian) and the grasps (an augmented Lagrangian) are the terms today; a new load
//! (a pressure) is one more type implementing the trait and one more entry in
//! [`ForceTerms::each`].

use faer::sparse::SparseColMat;
use fibfluid_geometry::Vec3;

use super::contact::{CONTACT_PENALTY, CONTACT_SMOOTHING, ContactLaw, ContactSample};
use super::grasp::GraspSet;
use super::model::HyperModel;
use crate::assemble::FIXED;
use crate::clamp::ClampPoint;
use crate::element::CELL_DOFS;

/// What a solve at one load factor works with.
pub(crate) struct LoadState<'a> {
    pub(super) t: f64,
    pub(super) external: &'a [f64],
    pub(super) plates: &'a [super::contact::RigidPlate],
    /// Per plate, per sample: the contact pressure of the last augmentation (Pa).
    pub(super) multipliers: &'a [Vec<f64>],
    /// Per grasped vertex: the force of the last augmentation (N).
    pub(super) grasp_multipliers: &'a [fibfluid_geometry::Vec3],
}

/// Where a term adds its gradient (free dofs) and, while a tangent is assembled, its
/// Hessian (the tangent's lower triangle).
pub(crate) struct Assembly<'a> {
    pub(crate) gradient: &'a mut [f64],
    pub(crate) tangent: Option<&'a mut SparseColMat<usize, f64>>,
}

impl Assembly<'_> {
    /// Adds `coef * v v^T` on `dofs` to the tangent's lower triangle (when assembling it).
    pub(crate) fn add_rank_one(&mut self, dofs: &[usize; CELL_DOFS], v: &[f64; CELL_DOFS], coef: f64) {
        if let Some(tangent) = self.tangent.as_deref_mut() {
            add_rank_one(tangent, dofs, v, coef);
        }
    }
}

/// Adds `coef * k` on `dofs` (a cell's 24 dofs, [`FIXED`] where fixed) to `tangent`'s lower
/// triangle.
pub(crate) fn add_cell_matrix(
    tangent: &mut SparseColMat<usize, f64>,
    dofs: &[usize; CELL_DOFS],
    k: &crate::element::CellMatrix,
    coef: f64,
) {
    let (symbolic, values) = tangent.parts_mut();
    let (col_ptr, row_idx) = (symbolic.col_ptr(), symbolic.row_idx());
    for (c, &gc) in dofs.iter().enumerate() {
        if gc == FIXED {
            continue;
        }
        let col = &row_idx[col_ptr[gc]..col_ptr[gc + 1]];
        for (r, &gr) in dofs.iter().enumerate() {
            if gr == FIXED || gr < gc {
                continue;
            }
            if let Ok(pos) = col.binary_search(&gr) {
                values[col_ptr[gc] + pos] += coef * k[r][c];
            }
        }
    }
}

/// Adds `coef * v v^T` on `dofs` to `tangent`'s lower triangle.
pub(crate) fn add_rank_one(
    tangent: &mut SparseColMat<usize, f64>,
    dofs: &[usize; CELL_DOFS],
    v: &[f64; CELL_DOFS],
    coef: f64,
) {
    let (symbolic, values) = tangent.parts_mut();
    let (col_ptr, row_idx) = (symbolic.col_ptr(), symbolic.row_idx());
    for (c, &gc) in dofs.iter().enumerate() {
        if gc == FIXED || v[c] == 0.0 {
            continue;
        }
        let col = &row_idx[col_ptr[gc]..col_ptr[gc + 1]];
        for (r, &gr) in dofs.iter().enumerate() {
            if gr == FIXED || gr < gc || v[r] == 0.0 {
                continue;
            }
            if let Ok(pos) = col.binary_search(&gr) {
                values[col_ptr[gc] + pos] += coef * v[r] * v[c];
            }
        }
    }
}

/// A force on the body besides its tissue's (see the module docs).
pub(crate) trait ForceTerm {
    /// The term's energy alone at node displacements `u` (J): what the line search reads.
    fn energy(&self, model: &HyperModel, u: &[Vec3], state: &LoadState<'_>) -> f64;

    /// The term's energy (J); its gradient added to `out.gradient` and its Hessian to
    /// `out.tangent` when that is assembled.
    fn add(&self, model: &HyperModel, u: &[Vec3], state: &LoadState<'_>, out: &mut Assembly<'_>) -> f64;
}

/// The clamp: `beta area / 2 d^2` per sample of the fixed part of the surface, `d` its
/// displacement along the fixed axis.
#[derive(Debug, Clone)]
pub(crate) struct ClampTerm {
    pub(crate) points: Vec<ClampPoint>,
    /// The penalty per unit area (N/m^3).
    pub(crate) beta: f64,
}

impl ForceTerm for ClampTerm {
    fn energy(&self, _model: &HyperModel, u: &[Vec3], _state: &LoadState<'_>) -> f64 {
        let mut e = 0.0;
        for p in &self.points {
            let d: f64 = (0..8).map(|b| p.weights[b] * u[p.nodes[b]][p.axis]).sum();
            e += 0.5 * self.beta * p.area * d * d;
        }
        e
    }

    fn add(&self, model: &HyperModel, u: &[Vec3], _state: &LoadState<'_>, out: &mut Assembly<'_>) -> f64 {
        let mut energy = 0.0;
        for p in &self.points {
            let coef = self.beta * p.area;
            let d: f64 = (0..8).map(|b| p.weights[b] * u[p.nodes[b]][p.axis]).sum();
            energy += 0.5 * coef * d * d;
            let mut dofs = [FIXED; CELL_DOFS];
            let mut v = [0.0; CELL_DOFS];
            for b in 0..8 {
                dofs[3 * b + p.axis] = model.free[3 * p.nodes[b] + p.axis];
                v[3 * b + p.axis] = p.weights[b];
                if let Some(g) = out.gradient.get_mut(dofs[3 * b + p.axis]) {
                    *g += coef * d * p.weights[b];
                }
            }
            out.add_rank_one(&dofs, &v, coef);
        }
        energy
    }
}

/// The plates' contact on the body's surface samples (see [`super::contact`]); the plates
/// and their multipliers come with the load state.
#[derive(Debug, Clone)]
pub(crate) struct ContactTerm {
    pub(crate) samples: Vec<ContactSample>,
}

impl ContactTerm {
    /// The contact law: `beta = CONTACT_PENALTY * E / h`, smoothed over
    /// `CONTACT_SMOOTHING * E`.
    pub(crate) fn law(model: &HyperModel) -> ContactLaw {
        let e = model.tissue.young();
        ContactLaw { beta: CONTACT_PENALTY * e / model.grid.cell_size(), width: CONTACT_SMOOTHING * e }
    }
}

impl ForceTerm for ContactTerm {
    fn energy(&self, model: &HyperModel, u: &[Vec3], state: &LoadState<'_>) -> f64 {
        let law = Self::law(model);
        let mut e = 0.0;
        for (k, plate) in state.plates.iter().enumerate() {
            for (s, sample) in self.samples.iter().enumerate() {
                let lambda = state.multipliers[k][s];
                let x = law.argument(lambda, plate.gap(sample.position(u), state.t));
                e += law.energy(sample.area, lambda, x);
            }
        }
        e
    }

    fn add(&self, model: &HyperModel, u: &[Vec3], state: &LoadState<'_>, out: &mut Assembly<'_>) -> f64 {
        let law = Self::law(model);
        let mut energy = 0.0;
        for (k, plate) in state.plates.iter().enumerate() {
            for (s, sample) in self.samples.iter().enumerate() {
                let lambda = state.multipliers[k][s];
                let x = law.argument(lambda, plate.gap(sample.position(u), state.t));
                energy += law.energy(sample.area, lambda, x);
                let p = law.pressure(x);
                if p == 0.0 {
                    continue;
                }
                let dofs = model.cell_dofs(&sample.nodes);
                let v: [f64; CELL_DOFS] =
                    std::array::from_fn(|l| sample.weights[l / 3] * plate.normal[l % 3]);
                for (l, &g) in dofs.iter().enumerate() {
                    if g != FIXED {
                        out.gradient[g] -= sample.area * p * v[l];
                    }
                }
                out.add_rank_one(&dofs, &v, sample.area * law.beta * law.slope(x));
            }
        }
        energy
    }
}

impl ForceTerm for GraspSet {
    fn energy(&self, _model: &HyperModel, u: &[Vec3], state: &LoadState<'_>) -> f64 {
        GraspSet::energy(self, u, state.t, state.grasp_multipliers)
    }

    /// The grasps' Hessian is `k w w^T` per point and axis.
    fn add(&self, model: &HyperModel, u: &[Vec3], state: &LoadState<'_>, out: &mut Assembly<'_>) -> f64 {
        let forces = self.forces(u, state.t, state.grasp_multipliers);
        for (i, f) in forces.iter().enumerate() {
            let p = self.points[i];
            for a in 0..3 {
                let mut dofs = [FIXED; CELL_DOFS];
                let mut v = [0.0; CELL_DOFS];
                for b in 0..8 {
                    dofs[3 * b + a] = model.free[3 * p.nodes[b] + a];
                    v[3 * b + a] = p.weights[b];
                    if let Some(g) = out.gradient.get_mut(dofs[3 * b + a]) {
                        *g += f[a] * p.weights[b];
                    }
                }
                out.add_rank_one(&dofs, &v, p.stiffness);
            }
        }
        GraspSet::energy(self, u, state.t, state.grasp_multipliers)
    }
}
