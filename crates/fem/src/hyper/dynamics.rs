//! Inertia and Rayleigh damping over one time step, as a force term: the energy
//! `1 / (2 beta h^2) (x - x~)' M (x - x~) + 1 / h (x - x_n)' C (x - x_n) - (C v_n)' x`
//! whose gradient is `M a_n+1 + C v_n+1` under Newmark's updates (see [`super::time`]).

use fibfluid_geometry::Vec3;

use super::model::{HyperModel, free_vector};
use super::terms::{Assembly, ForceTerm, LoadState, add_cell_matrix};
use crate::assemble::FIXED;
use crate::element::CELL_DOFS;

/// Inertia and Rayleigh damping over one step (see [`super::time`]'s docs), on the free
/// dofs.
pub(crate) struct DynamicsTerm {
    /// Lumped mass per free dof, kg.
    pub(crate) mass: Vec<f64>,
    /// `1 / (beta h^2)` (0: quasi-static, damping only).
    pub(crate) inertia: f64,
    /// Newmark's predictor `x~`.
    pub(crate) predictor: Vec<f64>,
    /// The step's start `x_n` and velocity `v_n`.
    pub(crate) start: Vec<f64>,
    pub(crate) velocity: Vec<f64>,
    /// `[a_m, a_k]`.
    pub(crate) damping: [f64; 2],
    /// The step, s.
    pub(crate) h: f64,
}

impl DynamicsTerm {
    /// The free-dof state at node displacements `u`.
    fn x(model: &HyperModel, u: &[Vec3]) -> Vec<f64> {
        free_vector(&model.free, model.n_free, u)
    }

    /// The inertia and mass damping's energy and (with `out`) gradient and Hessian.
    fn mass_part(&self, x: &[f64], out: Option<&mut Assembly<'_>>) -> f64 {
        let (inertia, damp) = (self.inertia, self.damping[0] / self.h);
        let mut energy = 0.0;
        let mut diagonal = Vec::new();
        for (i, &m) in self.mass.iter().enumerate() {
            let (a, d) = (x[i] - self.predictor[i], x[i] - self.start[i]);
            energy +=
                0.5 * inertia * m * a * a + damp * m * d * d - self.damping[0] * m * self.velocity[i] * x[i];
            diagonal.push(inertia * m * a + 2.0 * damp * m * d - self.damping[0] * m * self.velocity[i]);
        }
        if let Some(out) = out {
            for (g, d) in out.gradient.iter_mut().zip(&diagonal) {
                *g += d;
            }
            if let Some(tangent) = out.tangent.as_deref_mut() {
                let (symbolic, values) = tangent.parts_mut();
                for (j, &m) in self.mass.iter().enumerate() {
                    values[symbolic.col_ptr()[j]] += (inertia + 2.0 * damp) * m;
                }
            }
        }
        energy
    }

    /// The stiffness damping's energy `a_k (dx' K_0 dx / h - (K_0 v_n)' x)` and (with
    /// `out`) its gradient and Hessian, cell by cell.
    fn stiffness_part(&self, model: &HyperModel, x: &[f64], mut out: Option<&mut Assembly<'_>>) -> f64 {
        let a_k = self.damping[1];
        if a_k == 0.0 {
            return 0.0;
        }
        let at = |v: &[f64], d: usize| if d == FIXED { 0.0 } else { v[d] };
        let mut energy = 0.0;
        for (c, nodes) in model.grid.cell_nodes().iter().enumerate() {
            let dofs = model.cell_dofs(nodes);
            let k0 = model.cell.linear_matrix(&model.materials[c], model.grid.fill()[c]);
            let dx: [f64; CELL_DOFS] = std::array::from_fn(|l| at(x, dofs[l]) - at(&self.start, dofs[l]));
            let v: [f64; CELL_DOFS] = std::array::from_fn(|l| at(&self.velocity, dofs[l]));
            for r in 0..CELL_DOFS {
                let (kdx, kv): (f64, f64) = (0..CELL_DOFS)
                    .map(|s| (k0[r][s] * dx[s], k0[r][s] * v[s]))
                    .fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
                energy += a_k * (dx[r] * kdx / self.h - kv * at(x, dofs[r]));
                if let Some(out) = out.as_deref_mut()
                    && dofs[r] != FIXED
                {
                    out.gradient[dofs[r]] += a_k * (2.0 * kdx / self.h - kv);
                }
            }
            if let Some(tangent) = out.as_deref_mut().and_then(|o| o.tangent.as_deref_mut()) {
                add_cell_matrix(tangent, &dofs, &k0, 2.0 * a_k / self.h);
            }
        }
        energy
    }
}

impl ForceTerm for DynamicsTerm {
    fn energy(&self, model: &HyperModel, u: &[Vec3], _state: &LoadState<'_>) -> f64 {
        let x = Self::x(model, u);
        self.mass_part(&x, None) + self.stiffness_part(model, &x, None)
    }

    fn add(&self, model: &HyperModel, u: &[Vec3], _state: &LoadState<'_>, out: &mut Assembly<'_>) -> f64 {
        let x = Self::x(model, u);
        self.mass_part(&x, Some(out)) + self.stiffness_part(model, &x, Some(out))
    }
}
