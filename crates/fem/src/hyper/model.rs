//! The hyperelastic body's model: what it is, fixed once it is built and shared by the
//! body and every linearization made from it.

use fibfluid_geometry::Vec3;

use super::cell::{CellMaterial, HyperCell};
use crate::element::CELL_DOFS;
use crate::grid::SparseGrid;
use crate::tissue::Tissue;

/// What a hyperelastic body is, fixed once it is built: the grid with its embedded surface,
/// the free-dof numbering and each cell's law, moduli and density. Shared (behind an
/// `Arc`) by the body and every linearization made from it.
#[derive(Debug, Clone)]
pub(crate) struct HyperModel {
    pub(crate) grid: SparseGrid,
    pub(crate) tissue: Tissue,
    pub(crate) free: Vec<usize>,
    pub(crate) n_free: usize,
    pub(crate) cell: HyperCell,
    /// Each cell's law and moduli.
    pub(crate) materials: Vec<CellMaterial>,
    /// Each cell's mass density (kg/m^3).
    pub(crate) densities: Vec<f64>,
    /// Each cell's region id (0: the body's tissue, `k`: region `k`).
    pub(crate) region_ids: Vec<u16>,
    /// The tissues the cells blend: the body's, then each region's.
    pub(crate) tissues: Vec<Tissue>,
    /// Per cell, the share of each of `tissues` in it (`tissues.len()` values per cell).
    pub(crate) shares: Vec<f64>,
}

impl HyperModel {
    /// The free-dof numbers of a cell's 24 local dofs ([`FIXED`] where fixed).
    pub(crate) fn cell_dofs(&self, nodes: &[usize; 8]) -> [usize; CELL_DOFS] {
        std::array::from_fn(|l| self.free[3 * nodes[l / 3] + l % 3])
    }
}

/// Free-dof vector of node displacements (the inverse of the body's node field).
pub(crate) fn free_vector(free: &[usize], n_free: usize, u: &[Vec3]) -> Vec<f64> {
    let mut x = vec![0.0; n_free];
    for (n, d) in u.iter().enumerate() {
        for a in 0..3 {
            if let Some(xi) = x.get_mut(free[3 * n + a]) {
                *xi = d[a];
            }
        }
    }
    x
}
