//! The transfer between two levels: a prolongation `P` from coarse to fine nodes with
//! scalar weights (the same for the three components), its transpose for restriction, and
//! the Galerkin coarse operator `P^T A P`.

use rayon::prelude::*;

use super::block::{Block, BlockCsr};

/// Coarse rows handed to one task at least in the Galerkin product.
const GALERKIN_ROWS_PER_TASK: usize = 64;

/// A node-to-node prolongation in compressed rows: fine node `i` takes
/// `sum_J weights[i, J] * coarse[J]` on each component.
#[derive(Debug, Clone)]
pub struct Prolongation {
    coarse: usize,
    row_ptr: Vec<usize>,
    cols: Vec<u32>,
    weights: Vec<f64>,
    /// The transpose (rows: coarse nodes), for restriction and the Galerkin product.
    transpose: Transposed,
}

#[derive(Debug, Clone)]
struct Transposed {
    row_ptr: Vec<usize>,
    cols: Vec<u32>,
    weights: Vec<f64>,
}

impl Prolongation {
    /// From each fine node's `(coarse node, weight)` pairs; `coarse` is the coarse node count.
    ///
    /// # Panics
    /// If a coarse node is out of range (a programming error).
    pub fn new(rows: &[Vec<(u32, f64)>], coarse: usize) -> Self {
        let mut row_ptr = vec![0];
        let mut cols = Vec::new();
        let mut weights = Vec::new();
        for row in rows {
            for &(c, w) in row {
                assert!((c as usize) < coarse, "coarse node in range");
                cols.push(c);
                weights.push(w);
            }
            row_ptr.push(cols.len());
        }
        let mut counts = vec![0usize; coarse + 1];
        for &c in &cols {
            counts[c as usize + 1] += 1;
        }
        for j in 0..coarse {
            counts[j + 1] += counts[j];
        }
        let mut next = counts.clone();
        let mut t_cols = vec![0u32; cols.len()];
        let mut t_weights = vec![0.0; cols.len()];
        for i in 0..rows.len() {
            for p in row_ptr[i]..row_ptr[i + 1] {
                let slot = &mut next[cols[p] as usize];
                t_cols[*slot] = i as u32;
                t_weights[*slot] = weights[p];
                *slot += 1;
            }
        }
        let transpose = Transposed { row_ptr: counts, cols: t_cols, weights: t_weights };
        Self { coarse, row_ptr, cols, weights, transpose }
    }

    /// Fine nodes.
    pub fn fine_nodes(&self) -> usize {
        self.row_ptr.len() - 1
    }

    /// Coarse nodes.
    pub fn coarse_nodes(&self) -> usize {
        self.coarse
    }

    /// `fine += P coarse`, skipping the fine level's `dead` dofs.
    pub(crate) fn prolong_add(&self, coarse: &[f64], fine: &mut [f64], dead: &[bool]) {
        fine.par_chunks_mut(3).enumerate().with_min_len(512).for_each(|(i, f)| {
            for p in self.row_ptr[i]..self.row_ptr[i + 1] {
                let (c, w) = (self.cols[p] as usize, self.weights[p]);
                for a in 0..3 {
                    if !dead[3 * i + a] {
                        f[a] += w * coarse[3 * c + a];
                    }
                }
            }
        });
    }

    /// `coarse = P^T fine`, zero on the coarse level's `dead` dofs.
    pub(crate) fn restrict(&self, fine: &[f64], coarse: &mut [f64], dead: &[bool]) {
        let t = &self.transpose;
        coarse.par_chunks_mut(3).enumerate().with_min_len(512).for_each(|(j, c)| {
            let mut acc = [0.0; 3];
            for p in t.row_ptr[j]..t.row_ptr[j + 1] {
                let (i, w) = (t.cols[p] as usize, t.weights[p]);
                for a in 0..3 {
                    acc[a] += w * fine[3 * i + a];
                }
            }
            for a in 0..3 {
                c[a] = if dead[3 * j + a] { 0.0 } else { acc[a] };
            }
        });
    }

    /// The Galerkin coarse operator `P^T A P` (Gustavson's row-by-row product, coarse rows
    /// in parallel).
    pub fn galerkin(&self, a: &BlockCsr) -> BlockCsr {
        let t = &self.transpose;
        let rows: Vec<Vec<(u32, Block)>> = (0..self.coarse)
            .into_par_iter()
            .with_min_len(GALERKIN_ROWS_PER_TASK)
            .map_init(
                || (vec![u32::MAX; self.coarse], Vec::<(u32, Block)>::new()),
                |(slot, acc), coarse_row| {
                    acc.clear();
                    for p in t.row_ptr[coarse_row]..t.row_ptr[coarse_row + 1] {
                        let (i, wi) = (t.cols[p] as usize, t.weights[p]);
                        let (cols, blocks) = a.row(i);
                        for (&j, b) in cols.iter().zip(blocks) {
                            let j = j as usize;
                            for q in self.row_ptr[j]..self.row_ptr[j + 1] {
                                let (coarse_col, w) = (self.cols[q], wi * self.weights[q]);
                                let s = &mut slot[coarse_col as usize];
                                if *s == u32::MAX {
                                    *s = acc.len() as u32;
                                    acc.push((coarse_col, [0.0; 9]));
                                }
                                let target = &mut acc[*s as usize].1;
                                for (x, y) in target.iter_mut().zip(b) {
                                    *x += w * y;
                                }
                            }
                        }
                    }
                    for (c, _) in acc.iter() {
                        slot[*c as usize] = u32::MAX;
                    }
                    let mut row = acc.clone();
                    row.sort_unstable_by_key(|(c, _)| *c);
                    row
                },
            )
            .collect();
        BlockCsr::from_rows(rows)
    }
}
