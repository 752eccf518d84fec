//! The geometric multigrid of the sparse voxel grid: the levels (each merges 2x2x2 cells;
//! a coarse cell is active where any of its children is), the trilinear prolongation
//! between their nodes, and the fine operator in node blocks built from the finite-element
//! matrix over the free dofs. `fibfluid_linalg::multigrid` does the rest (Galerkin coarse
//! operators, Chebyshev smoothing, the coarsest Cholesky, conjugate gradients).

use std::sync::Arc;

use faer::sparse::SparseColMatRef;
use fibfluid_linalg::multigrid::{BlockCsr, Multigrid, MultigridSettings, PcgOutcome, Prolongation};

use crate::assemble::{FIXED, node_neighbours};
use crate::error::{FemError, Result};
use crate::grid::SparseGrid;

/// A level with at most this many nodes is the coarsest (factored directly).
pub const COARSEST_NODES: usize = 500;
/// Levels at most (the finest included).
const MAX_LEVELS: usize = 10;
/// Coarsening stops when a level keeps more than this share of the finer level's nodes
/// (a thin body: merging no longer pays).
const MIN_REDUCTION: f64 = 0.6;

/// The grid's multigrid levels and the map between free dofs and node blocks: what a
/// multigrid solve needs besides the matrix. Built once per body (cheap: one pass over the
/// cells per level).
#[derive(Debug)]
pub(crate) struct GridLevels {
    transfers: Arc<Vec<Prolongation>>,
    /// The fine block pattern: each node's neighbours (nodes sharing a cell).
    pattern: Vec<Vec<u32>>,
    /// For each free dof, its node dof `3 n + a`.
    node_dof: Vec<usize>,
    /// Nodes per level, finest first.
    pub(crate) nodes: Vec<usize>,
}

impl GridLevels {
    /// The levels of `grid` with the free-dof numbering `free` (`FIXED` where fixed).
    pub(crate) fn new(grid: &SparseGrid, free: &[usize]) -> Self {
        let mut transfers = Vec::new();
        let mut nodes = vec![grid.n_nodes()];
        let mut cells: Vec<[usize; 3]> = grid.cell_coords().to_vec();
        let mut node_coords: Vec<[usize; 3]> = grid.node_coords().to_vec();
        while node_coords.len() > COARSEST_NODES && nodes.len() < MAX_LEVELS {
            let (coarse_cells, coarse_nodes, p) = coarsen(&cells, &node_coords);
            if coarse_nodes.len() as f64 > MIN_REDUCTION * node_coords.len() as f64 {
                break;
            }
            nodes.push(coarse_nodes.len());
            transfers.push(p);
            cells = coarse_cells;
            node_coords = coarse_nodes;
        }
        let pattern =
            node_neighbours(grid).into_iter().map(|l| l.into_iter().map(|n| n as u32).collect()).collect();
        let node_dof = free.iter().enumerate().filter(|(_, f)| **f != FIXED).map(|(dof, _)| dof).collect();
        Self { transfers: Arc::new(transfers), pattern, node_dof, nodes }
    }

    /// The fine operator in node blocks from the lower triangle over the free dofs (fixed
    /// dofs dead: zero rows and columns).
    pub(crate) fn fine_operator(&self, lower: SparseColMatRef<'_, usize, f64>) -> BlockCsr {
        let mut a = BlockCsr::zeros(&self.pattern);
        let (col_ptr, row_idx, val) = (lower.symbolic().col_ptr(), lower.symbolic().row_idx(), lower.val());
        for j in 0..lower.ncols() {
            let (nj, aj) = (self.node_dof[j] / 3, self.node_dof[j] % 3);
            for p in col_ptr[j]..col_ptr[j + 1] {
                let i = row_idx[p];
                let (ni, ai) = (self.node_dof[i] / 3, self.node_dof[i] % 3);
                // A coupling beyond the grid's cells (a pressure's) is left out of the
                // operator: the Newton step is then inexact, not wrong.
                let Some(at) = a.position(ni, nj) else { continue };
                a.values_mut()[at][3 * ai + aj] += val[p];
                if i != j {
                    let at = a.position(nj, ni).expect("symmetric pattern");
                    a.values_mut()[at][3 * aj + ai] += val[p];
                }
            }
        }
        a
    }

    /// The multigrid hierarchy of the lower triangle `lower` over the free dofs.
    ///
    /// Errors: [`FemError::NotPositiveDefinite`] when the coarsest operator is not.
    pub(crate) fn hierarchy(&self, lower: SparseColMatRef<'_, usize, f64>, shift: f64) -> Result<Multigrid> {
        let mut fine = self.fine_operator(lower);
        if shift > 0.0 {
            fine.shift_diagonal(shift * fine.largest_diagonal());
        }
        Multigrid::new(fine, self.transfers.clone(), MultigridSettings::default()).map_err(|e| {
            if fibfluid_linalg::multigrid::is_not_positive_definite(&e) {
                FemError::NotPositiveDefinite
            } else {
                e.into()
            }
        })
    }

    /// Solves `A x = b` over the free dofs with `multigrid` (built by
    /// [`GridLevels::hierarchy`]) to the relative `tolerance`; `x` holds `b` on entry.
    pub(crate) fn solve(&self, multigrid: &Multigrid, x: &mut [f64], tolerance: f64) -> PcgOutcome {
        let n = 3 * self.nodes[0];
        let mut b = vec![0.0; n];
        for (f, &d) in self.node_dof.iter().enumerate() {
            b[d] = x[f];
        }
        let mut y = vec![0.0; n];
        let outcome = multigrid.solve(&b, &mut y, tolerance, MAX_PCG_ITERATIONS);
        for (f, &d) in self.node_dof.iter().enumerate() {
            x[f] = y[d];
        }
        outcome
    }
}

/// Conjugate-gradient iterations allowed per solve (a V-cycle-preconditioned solve of an
/// elastic body takes tens).
pub const MAX_PCG_ITERATIONS: usize = 500;

/// The next coarser level of `cells` (lattice coordinates) and `nodes`: its cells, its
/// nodes and the trilinear prolongation from its nodes to `nodes`.
fn coarsen(cells: &[[usize; 3]], nodes: &[[usize; 3]]) -> (Vec<[usize; 3]>, Vec<[usize; 3]>, Prolongation) {
    let mut coarse_cells: Vec<[usize; 3]> = cells.iter().map(|c| c.map(|x| x / 2)).collect();
    coarse_cells.sort_unstable_by_key(|c| (c[2], c[1], c[0]));
    coarse_cells.dedup();
    let mut dims = [0usize; 3];
    for c in &coarse_cells {
        for a in 0..3 {
            dims[a] = dims[a].max(c[a] + 2);
        }
    }
    let index = |n: [usize; 3]| n[0] + dims[0] * (n[1] + dims[1] * n[2]);
    let mut id = vec![u32::MAX; dims[0] * dims[1] * dims[2]];
    let mut coarse_nodes = Vec::new();
    for c in &coarse_cells {
        for b in 0..8 {
            let n = [c[0] + (b & 1), c[1] + ((b >> 1) & 1), c[2] + ((b >> 2) & 1)];
            let slot = &mut id[index(n)];
            if *slot == u32::MAX {
                *slot = coarse_nodes.len() as u32;
                coarse_nodes.push(n);
            }
        }
    }
    let rows: Vec<Vec<(u32, f64)>> = nodes
        .iter()
        .map(|f| {
            // Per axis: an even fine coordinate sits on a coarse node, an odd one halfway.
            let axis = |a: usize| -> Vec<(usize, f64)> {
                if f[a] % 2 == 0 { vec![(f[a] / 2, 1.0)] } else { vec![(f[a] / 2, 0.5), (f[a] / 2 + 1, 0.5)] }
            };
            let (x, y, z) = (axis(0), axis(1), axis(2));
            let mut row = Vec::with_capacity(8);
            for &(k, wz) in &z {
                for &(j, wy) in &y {
                    for &(i, wx) in &x {
                        let c = id[index([i, j, k])];
                        debug_assert!(c != u32::MAX, "a fine node's coarse parents exist");
                        row.push((c, wx * wy * wz));
                    }
                }
            }
            row
        })
        .collect();
    let p = Prolongation::new(&rows, coarse_nodes.len());
    (coarse_cells, coarse_nodes, p)
}

/// The linear solver of the finite-element method (`[fem] solver`, `--fem-solver`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FemSolver {
    /// The direct solver below [`MULTIGRID_CROSSOVER_DOFS`] unknowns of the grid's
    /// bounding box ([`crate::GridEstimate::dofs`], known before voxelizing), multigrid
    /// from there.
    #[default]
    Auto,
    /// The sparse Cholesky factor (memory and time grow faster than the cells).
    Direct,
    /// Conjugate gradients preconditioned by the grid's geometric multigrid.
    Multigrid,
}

impl fibfluid_linalg::Choice for FemSolver {
    const WHAT: &'static str = "FEM solver";
    const ALL: &'static [Self] = &[FemSolver::Auto, FemSolver::Direct, FemSolver::Multigrid];
    fn name(self) -> &'static str {
        match self {
            FemSolver::Auto => "auto",
            FemSolver::Direct => "direct",
            FemSolver::Multigrid => "multigrid",
        }
    }
}
fibfluid_linalg::impl_choice!(FemSolver);

/// Unknowns from which `auto` picks multigrid (measured with `fibfluid bench --fem-solvers`
/// on the hanging sphere and liver: see docs/fem.md).
pub const MULTIGRID_CROSSOVER_DOFS: usize = 10_000;

impl FemSolver {
    /// The solver used on a grid whose bounding box has `dofs` unknowns
    /// ([`crate::GridEstimate::dofs`]): `Direct` or `Multigrid`.
    pub fn resolve(self, dofs: usize) -> Self {
        match self {
            FemSolver::Auto if dofs >= MULTIGRID_CROSSOVER_DOFS => FemSolver::Multigrid,
            FemSolver::Auto => FemSolver::Direct,
            other => other,
        }
    }
}

impl GridLevels {
    /// The free dofs (unknowns of the systems solved).
    pub(crate) fn free_dofs(&self) -> usize {
        self.node_dof.len()
    }
}
