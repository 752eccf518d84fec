//! Held surface vertices by a capacitance (Schur complement) update of the kept factor.
//!
//! Holding vertex `v` at displacement `d_v` adds the constraint rows `C_v u = d_v` (row
//! `(v, a)`: the trilinear weights of `v` on axis `a` of its cell's free nodes) and the
//! unknown reactions `lambda`: `K u = f + C^T lambda`. With `u0 = K^-1 f` and the
//! compliance columns `Z = K^-1 C^T`, `(C Z) lambda = d - C u0` and `u = u0 + Z lambda`.
//! `Z` costs one solve per new held axis and is cached per vertex; each frame then costs
//! one solve for `u0`, the dense `m x m` capacitance `C Z` (8 m^2 flops from the sparse
//! rows) and its Cholesky (`m^3 / 3`), against a refactorization of K (its factor flops,
//! see [`crate::FemStats`]) for eliminating the held dofs.

use faer::{Mat, Side};
use fibfluid_geometry::Vec3;

use crate::assemble::FIXED;
use crate::body::{FemBody, Loads};
use crate::error::{FemError, Result};

/// A target below this (relative to the largest target, or absolute when all are 0) counts
/// as 0 on an axis whose nodes are all fixed.
const ZERO_TARGET: f64 = 1e-12;

/// The response with some surface vertices held.
#[derive(Debug, Clone, PartialEq)]
pub struct HeldResponse {
    /// Displacement of every grid node.
    pub node_displacements: Vec<Vec3>,
    /// Displacement of every surface vertex.
    pub surface_displacements: Vec<Vec3>,
    /// The force each held vertex receives from its holder, in the order given (applied as
    /// a point force in [`FemBody::solve`], it reproduces the same displacement). An axis
    /// carried only by fixed nodes reports 0 (its reaction goes to the supports).
    pub reactions: Vec<Vec3>,
}

/// One constraint row: a held vertex's axis as a combination of free dofs.
struct Row {
    vertex: usize,
    axis: usize,
    target: f64,
    entries: Vec<(usize, f64)>,
}

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
        let rows = self.constraint_rows(held)?;
        self.cache_compliance(held)?;
        let f = self.load_vector(loads)?;
        let u0 = match &self.unheld {
            Some((last, u0)) if last == loads => u0.clone(),
            _ => {
                let mut u0 = Mat::<f64>::from_fn(self.n_free, 1, |i, _| f[i]);
                self.factor.solve_in_place(u0.as_mut());
                self.unheld = Some((loads.clone(), u0.clone()));
                u0
            }
        };
        let m = rows.len();
        let column = |r: &Row| &self.compliance[&r.vertex][r.axis];
        let capacitance = Mat::<f64>::from_fn(m, m, |i, j| {
            rows[i].entries.iter().map(|&(d, w)| w * column(&rows[j])[d]).sum()
        });
        let gap = Mat::<f64>::from_fn(m, 1, |i, _| {
            rows[i].target - rows[i].entries.iter().map(|&(d, w)| w * u0[(d, 0)]).sum::<f64>()
        });
        let lambda = if m == 0 {
            gap
        } else {
            let llt = capacitance
                .llt(Side::Lower)
                .map_err(|_| FemError::DependentHolds { vertex: rows[0].vertex })?;
            use faer::linalg::solvers::Solve;
            llt.solve(&gap)
        };
        let mut u: Vec<f64> = (0..self.n_free).map(|i| u0[(i, 0)]).collect();
        let mut reactions = vec![[0.0; 3]; held.len()];
        for (r, row) in rows.iter().enumerate() {
            let z = column(row);
            for (ui, zi) in u.iter_mut().zip(z) {
                *ui += lambda[(r, 0)] * zi;
            }
            let k = held.iter().position(|h| h.0 == row.vertex).unwrap_or(0);
            reactions[k][row.axis] = lambda[(r, 0)];
        }
        let mut applied = f;
        for (row, r) in rows.iter().zip(0..) {
            for &(d, w) in &row.entries {
                applied[d] += w * lambda[(r, 0)];
            }
        }
        self.residual(&u, &applied)?;
        let node_displacements = self.node_values(&u);
        let surface_displacements = self.grid.interpolate(&node_displacements);
        Ok(HeldResponse { node_displacements, surface_displacements, reactions })
    }

    /// Drops the cached compliance columns of every held vertex.
    pub fn release_all(&mut self) {
        self.compliance.clear();
    }

    /// Number of vertices whose compliance columns are cached.
    pub fn cached_holds(&self) -> usize {
        self.compliance.len()
    }

    /// The constraint rows of `held`, skipping axes carried only by fixed nodes (whose
    /// target must then be 0).
    fn constraint_rows(&self, held: &[(usize, Vec3)]) -> Result<Vec<Row>> {
        let scale = held.iter().flat_map(|h| h.1).fold(0.0_f64, |a, b| a.max(b.abs()));
        let mut rows = Vec::new();
        for (k, &(v, d)) in held.iter().enumerate() {
            let e = self
                .grid
                .embedding()
                .get(v)
                .ok_or(FemError::VertexOutOfRange { vertex: v, vertices: self.grid.n_vertices() })?;
            if d.iter().any(|x| !x.is_finite()) {
                return Err(FemError::NonFinite { what: "held displacement" });
            }
            if held[..k].iter().any(|h| h.0 == v) {
                return Err(FemError::DependentHolds { vertex: v });
            }
            for a in 0..3 {
                let entries: Vec<(usize, f64)> = (0..8)
                    .filter(|&b| e.weights[b] > 0.0)
                    .map(|b| (self.free[3 * e.nodes[b] + a], e.weights[b]))
                    .filter(|&(dof, _)| dof != FIXED)
                    .collect();
                if entries.is_empty() {
                    if d[a].abs() > ZERO_TARGET * scale.max(1.0) {
                        return Err(FemError::HeldOnFixed { vertex: v, axis: a });
                    }
                    continue;
                }
                rows.push(Row { vertex: v, axis: a, target: d[a], entries });
            }
        }
        Ok(rows)
    }

    /// Computes `K^-1 C_v^T` for every held vertex not cached yet, in one solve pass.
    fn cache_compliance(&mut self, held: &[(usize, Vec3)]) -> Result<()> {
        let new: Vec<usize> = held.iter().map(|h| h.0).filter(|v| !self.compliance.contains_key(v)).collect();
        if new.is_empty() {
            return Ok(());
        }
        let mut rhs = Mat::<f64>::zeros(self.n_free, 3 * new.len());
        for (k, &v) in new.iter().enumerate() {
            let e = self.grid.embedding()[v];
            for b in 0..8 {
                for a in 0..3 {
                    let dof = self.free[3 * e.nodes[b] + a];
                    if dof != FIXED {
                        rhs[(dof, 3 * k + a)] += e.weights[b];
                    }
                }
            }
        }
        self.factor.solve_in_place(rhs.as_mut());
        for (k, &v) in new.iter().enumerate() {
            let col = |a: usize| (0..self.n_free).map(|i| rhs[(i, 3 * k + a)]).collect::<Vec<f64>>();
            self.compliance.insert(v, [col(0), col(1), col(2)]);
        }
        Ok(())
    }
}
