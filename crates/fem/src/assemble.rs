//! Assembly of the lower triangle of K over the free degrees of freedom, in compressed
//! sparse columns.

use faer::sparse::{SparseColMat, SymbolicSparseColMat};

use crate::element::{CELL_DOFS, CellMatrix, unit_cell_matrices};
use crate::grid::{Element, SparseGrid};
use crate::tissue::Tissue;

/// Marks a fixed degree of freedom in the dof-to-free map.
pub(crate) const FIXED: usize = usize::MAX;

/// Maps each dof `3 n + a` to its free index (in increasing dof order) or [`FIXED`].
pub(crate) fn number_free_dofs(fixed_dof: &[bool]) -> (Vec<usize>, usize) {
    let mut next = 0;
    let map = fixed_dof
        .iter()
        .map(|&f| {
            if f {
                FIXED
            } else {
                next += 1;
                next - 1
            }
        })
        .collect();
    (map, next)
}

/// For every node, the sorted nodes that share an active cell with it (itself included).
pub(crate) fn node_neighbours(grid: &SparseGrid) -> Vec<Vec<usize>> {
    let mut nb: Vec<Vec<usize>> = vec![Vec::new(); grid.n_nodes()];
    for cell in grid.cell_nodes() {
        for &a in cell {
            nb[a].extend_from_slice(cell);
        }
    }
    for list in &mut nb {
        list.sort_unstable();
        list.dedup();
    }
    nb
}

/// The symbolic lower triangle of K over the free dofs: column `f` holds every free row
/// `g >= f` whose node shares a cell with `f`'s node.
pub(crate) fn lower_pattern(grid: &SparseGrid, free: &[usize], n_free: usize) -> SymbolicSparseColMat<usize> {
    lower_pattern_coupled(grid, free, n_free, &[])
}

/// [`lower_pattern`] with the node pairs `extra` coupled too (each both ways): the
/// couplings of a load between nodes that share no cell (a pressure's faces).
pub(crate) fn lower_pattern_coupled(
    grid: &SparseGrid,
    free: &[usize],
    n_free: usize,
    extra: &[(usize, usize)],
) -> SymbolicSparseColMat<usize> {
    let mut nb = node_neighbours(grid);
    if !extra.is_empty() {
        for &(a, b) in extra {
            nb[a].push(b);
            nb[b].push(a);
        }
        for list in &mut nb {
            list.sort_unstable();
            list.dedup();
        }
    }
    let mut col_ptr = Vec::with_capacity(n_free + 1);
    let mut row_idx = Vec::new();
    col_ptr.push(0);
    for (dof, &f) in free.iter().enumerate() {
        if f == FIXED {
            continue;
        }
        for &m in &nb[dof / 3] {
            for a in 0..3 {
                let g = free[3 * m + a];
                if g != FIXED && g >= f {
                    row_idx.push(g);
                }
            }
        }
        col_ptr.push(row_idx.len());
    }
    SymbolicSparseColMat::new_checked(n_free, n_free, col_ptr, None, row_idx)
}

/// The cell matrix of a full cell of `grid` for `tissue`: `h (mu D + kappa V)`.
pub(crate) fn cell_matrix(grid: &SparseGrid, tissue: &Tissue, element: Element) -> CellMatrix {
    let (dev, vol) = unit_cell_matrices(element);
    let (mu, kappa, h) = (tissue.shear_modulus(), tissue.bulk_modulus(), grid.cell_size());
    std::array::from_fn(|r| std::array::from_fn(|c| h * (mu * dev[r][c] + kappa * vol[r][c])))
}

/// Assembles `sum over cells of fill * K_cell` restricted to the free dofs (lower triangle).
pub(crate) fn assemble_lower(
    grid: &SparseGrid,
    cell: &CellMatrix,
    free: &[usize],
    n_free: usize,
) -> SparseColMat<usize, f64> {
    let pattern = lower_pattern(grid, free, n_free);
    let mut values = vec![0.0; pattern.row_idx().len()];
    {
        let (col_ptr, row_idx) = (pattern.col_ptr(), pattern.row_idx());
        for (nodes, &fill) in grid.cell_nodes().iter().zip(grid.fill()) {
            let global: [usize; CELL_DOFS] = std::array::from_fn(|l| free[3 * nodes[l / 3] + l % 3]);
            for (c, &gc) in global.iter().enumerate() {
                if gc == FIXED {
                    continue;
                }
                let col = &row_idx[col_ptr[gc]..col_ptr[gc + 1]];
                for (r, &gr) in global.iter().enumerate() {
                    if gr == FIXED || gr < gc {
                        continue;
                    }
                    // The pattern holds every pair of dofs sharing a cell.
                    if let Ok(pos) = col.binary_search(&gr) {
                        values[col_ptr[gc] + pos] += fill * cell[r][c];
                    }
                }
            }
        }
    }
    SparseColMat::new(pattern, values)
}

/// `y = K x` for K given by its lower triangle.
pub(crate) fn symmetric_mul(k_lower: &SparseColMat<usize, f64>, x: &[f64]) -> Vec<f64> {
    let mut y = vec![0.0; x.len()];
    let (col_ptr, row_idx, val) = (k_lower.symbolic().col_ptr(), k_lower.symbolic().row_idx(), k_lower.val());
    for j in 0..x.len() {
        for p in col_ptr[j]..col_ptr[j + 1] {
            let i = row_idx[p];
            y[i] += val[p] * x[j];
            if i != j {
                y[j] += val[p] * x[i];
            }
        }
    }
    y
}

/// Adds `coef(point) * w w^T` on the point's axis for every clamp point (lower triangle).
/// The pattern already holds every pair of nodes of a cell.
pub(crate) fn add_penalty(
    k_lower: &mut SparseColMat<usize, f64>,
    free: &[usize],
    points: &[crate::clamp::ClampPoint],
    coef: impl Fn(&crate::clamp::ClampPoint) -> f64,
) {
    let (symbolic, values) = k_lower.parts_mut();
    let (col_ptr, row_idx) = (symbolic.col_ptr(), symbolic.row_idx());
    for p in points {
        let beta = coef(p);
        for c in 0..8 {
            let gc = free[3 * p.nodes[c] + p.axis];
            if gc == FIXED || p.weights[c] == 0.0 {
                continue;
            }
            let col = &row_idx[col_ptr[gc]..col_ptr[gc + 1]];
            for r in 0..8 {
                let gr = free[3 * p.nodes[r] + p.axis];
                if gr == FIXED || gr < gc || p.weights[r] == 0.0 {
                    continue;
                }
                if let Ok(pos) = col.binary_search(&gr) {
                    values[col_ptr[gc] + pos] += beta * p.weights[r] * p.weights[c];
                }
            }
        }
    }
}
