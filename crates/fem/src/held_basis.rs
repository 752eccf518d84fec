//! The compliance columns a set of constraint rows is answered from.
//!
//! A held vertex's rows are combinations of the free dofs of its cell's nodes. Rows are
//! written `C = A B` over a *basis* `B` whose compliance columns `G = K^-1 B^T` are solved
//! and cached: either each held vertex's three axis rows (3 columns per vertex, the rows
//! themselves for holds along the axes) or the free dofs the rows touch (one column per
//! dof). A patch of many vertices in a few cells (a grasp on a surface finer than the grid)
//! touches fewer dofs than it has rows: 113 grasped vertices of the bundled liver are 339
//! rows over about a third as many dofs. The smaller basis is taken, so a refresh solves
//! and a frame reads `min(3 x vertices, dofs)` columns, not one per row.
//!
//! With `H = B G` (symmetric), the capacitance is `C Z = A H A^T`, `C x = A (B x)`, and the
//! correction `x -= Z r` is `x -= G (A^T r)` ([`Combined`], the capacitance source).

use std::collections::HashMap;

use faer::Mat;
use fibfluid_linalg::{CapacitanceSource, SparseRow, row_dot};

use crate::assemble::FIXED;
use crate::grid::Embedded;
use crate::held_rows::Row;

/// One compliance column's identity: an axis of a held vertex (its trilinear row on that
/// axis) or a free dof.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) enum BasisKey {
    /// The row of vertex `vertex` along axis `axis`.
    Axis {
        /// The surface vertex.
        vertex: usize,
        /// 0, 1 or 2.
        axis: usize,
    },
    /// The unit row of one free dof.
    Dof(usize),
}

/// A basis row's entries: `(free dof, coefficient)`.
pub(crate) fn basis_row(key: BasisKey, embedding: &[Embedded], free: &[usize]) -> Vec<(usize, f64)> {
    match key {
        BasisKey::Axis { vertex, axis } => {
            let e = embedding[vertex];
            (0..8)
                .filter(|&b| e.weights[b] > 0.0)
                .map(|b| (free[3 * e.nodes[b] + axis], e.weights[b]))
                .filter(|&(dof, _)| dof != FIXED)
                .collect()
        }
        BasisKey::Dof(d) => vec![(d, 1.0)],
    }
}

/// Constraint rows written over a basis: `C = A B`.
#[derive(Debug, Clone)]
pub(crate) struct Combination {
    /// The basis, in column order.
    pub(crate) basis: Vec<BasisKey>,
    /// Per constraint row, its `(basis index, coefficient)` pairs (a row of `A`).
    pub(crate) rows: Vec<Vec<(usize, f64)>>,
}

impl Combination {
    /// The rows over the smaller basis: their vertices' axes, or the dofs they touch.
    pub(crate) fn of(rows: &[Row]) -> Self {
        let mut vertices: HashMap<usize, usize> = HashMap::new();
        let mut dofs: HashMap<usize, usize> = HashMap::new();
        let mut dof_order = Vec::new();
        let mut vertex_order = Vec::new();
        for row in rows {
            vertices.entry(row.vertex).or_insert_with(|| {
                vertex_order.push(row.vertex);
                vertex_order.len() - 1
            });
            for &(d, _) in &row.entries {
                dofs.entry(d).or_insert_with(|| {
                    dof_order.push(d);
                    dof_order.len() - 1
                });
            }
        }
        if dof_order.len() < 3 * vertex_order.len() {
            let rows = rows.iter().map(|r| r.entries.iter().map(|&(d, w)| (dofs[&d], w)).collect()).collect();
            return Self { basis: dof_order.into_iter().map(BasisKey::Dof).collect(), rows };
        }
        let basis =
            vertex_order.iter().flat_map(|&vertex| (0..3).map(move |axis| BasisKey::Axis { vertex, axis }));
        let rows = rows
            .iter()
            .map(|r| {
                let first = 3 * vertices[&r.vertex];
                (0..3).filter(|&a| r.direction[a] != 0.0).map(|a| (first + a, r.direction[a])).collect()
            })
            .collect();
        Self { basis: basis.collect(), rows }
    }

    /// `A^T r`: the basis coefficients of the rows' combination with weights `r`.
    pub(crate) fn transpose_times(&self, r: &[f64]) -> Vec<f64> {
        transpose_times(&self.rows, r, self.basis.len())
    }
}

/// `A^T r` for the rows `rows` of `A` over a basis of `size` elements.
fn transpose_times<R: AsRef<SparseRow>>(rows: &[R], r: &[f64], size: usize) -> Vec<f64> {
    let mut v = vec![0.0; size];
    for (row, &ri) in rows.iter().zip(r) {
        for &(k, c) in row.as_ref() {
            v[k] += c * ri;
        }
    }
    v
}

/// The capacitance source of rows over a basis: the basis rows and their compliance
/// columns (see the module docs). Its rows are those of `A`.
pub(crate) struct Combined<'a> {
    /// `B`, one sparse row per basis element.
    basis_rows: &'a [Vec<(usize, f64)>],
    /// `G`, one column of every unknown per basis element.
    pub(crate) columns: Vec<&'a [f64]>,
}

impl<'a> Combined<'a> {
    /// The source of the basis rows `basis_rows` of `basis`, on its cached `columns`.
    pub(crate) fn new(
        basis_rows: &'a [Vec<(usize, f64)>],
        basis: &[BasisKey],
        columns: &'a HashMap<BasisKey, Vec<f64>>,
    ) -> Self {
        Self { basis_rows, columns: basis.iter().map(|k| columns[k].as_slice()).collect() }
    }
}

impl Combined<'_> {
    /// `H = B G`, symmetrized.
    fn basis_capacitance(&self) -> Mat<f64> {
        let b = self.columns.len();
        let h = Mat::from_fn(b, b, |k, l| row_dot(&self.basis_rows[k], self.columns[l]));
        Mat::from_fn(b, b, |k, l| 0.5 * (h[(k, l)] + h[(l, k)]))
    }
}

impl<R: AsRef<SparseRow>> CapacitanceSource<R> for Combined<'_> {
    fn capacitance(&self, rows: &[R]) -> Mat<f64> {
        let h = self.basis_capacitance();
        let m = rows.len();
        // T = H A^T, then A T.
        let t = Mat::from_fn(h.nrows(), m, |k, i| {
            rows[i].as_ref().iter().map(|&(l, c)| c * h[(k, l)]).sum::<f64>()
        });
        let a_t = |i: usize, j: usize| -> f64 { rows[i].as_ref().iter().map(|&(k, c)| c * t[(k, j)]).sum() };
        let full = Mat::from_fn(m, m, a_t);
        Mat::from_fn(m, m, |i, j| 0.5 * (full[(i, j)] + full[(j, i)]))
    }

    fn row_values(&self, rows: &[R], x: &[f64]) -> Vec<f64> {
        let at_basis: Vec<f64> = self.basis_rows.iter().map(|b| row_dot(b, x)).collect();
        rows.iter().map(|row| row.as_ref().iter().map(|&(k, c)| c * at_basis[k]).sum()).collect()
    }

    fn correct(&self, rows: &[R], r: &[f64], x: &mut [f64]) {
        let v = transpose_times(rows, r, self.columns.len());
        for (column, &vk) in self.columns.iter().zip(&v).filter(|(_, v)| **v != 0.0) {
            x.iter_mut().zip(column.iter()).for_each(|(xi, ci)| *xi -= vk * ci);
        }
    }
}
