//! Symmetric matrices of 3x3 blocks in compressed rows (both triangles stored): the
//! operator of one multigrid level, one block row per grid node.

use rayon::prelude::*;

/// A 3x3 block, row-major.
pub type Block = [f64; 9];

/// Rows handed to one task at least (a few microseconds of work against the cost of a
/// task).
const ROWS_PER_TASK: usize = 512;

/// A symmetric matrix of 3x3 blocks in compressed rows, both triangles stored, each row's
/// columns sorted. A degree of freedom whose row is zero (its diagonal entry 0) is *dead*:
/// every operation keeps it at zero (fixed dofs of the finite-element grid, coarse dofs
/// with no live child).
#[derive(Debug, Clone)]
pub struct BlockCsr {
    row_ptr: Vec<usize>,
    cols: Vec<u32>,
    values: Vec<Block>,
}

impl BlockCsr {
    /// The matrix with these rows' sorted, distinct columns and zero values.
    ///
    /// # Panics
    /// If a row's columns are not sorted and distinct or exceed the row count (a
    /// programming error).
    pub fn zeros(rows: &[Vec<u32>]) -> Self {
        let mut row_ptr = Vec::with_capacity(rows.len() + 1);
        row_ptr.push(0);
        let mut cols = Vec::with_capacity(rows.iter().map(Vec::len).sum());
        for row in rows {
            assert!(row.windows(2).all(|w| w[0] < w[1]), "sorted, distinct columns");
            assert!(row.iter().all(|&c| (c as usize) < rows.len()), "square");
            cols.extend_from_slice(row);
            row_ptr.push(cols.len());
        }
        let values = vec![[0.0; 9]; cols.len()];
        Self { row_ptr, cols, values }
    }

    /// Builds from rows of `(column, block)` pairs, each row sorted by column.
    pub(crate) fn from_rows(rows: Vec<Vec<(u32, Block)>>) -> Self {
        let mut row_ptr = Vec::with_capacity(rows.len() + 1);
        row_ptr.push(0);
        let total = rows.iter().map(Vec::len).sum();
        let mut cols = Vec::with_capacity(total);
        let mut values = Vec::with_capacity(total);
        for row in rows {
            for (c, b) in row {
                cols.push(c);
                values.push(b);
            }
            row_ptr.push(cols.len());
        }
        Self { row_ptr, cols, values }
    }

    /// Block rows (nodes); the matrix has three times as many rows.
    pub fn nodes(&self) -> usize {
        self.row_ptr.len() - 1
    }

    /// Stored blocks.
    pub fn blocks(&self) -> usize {
        self.cols.len()
    }

    /// Bytes held by the matrix.
    pub fn bytes(&self) -> usize {
        self.values.len() * std::mem::size_of::<Block>() + self.cols.len() * 4 + self.row_ptr.len() * 8
    }

    /// Where block `(row, col)` is stored, `None` outside the pattern.
    pub fn position(&self, row: usize, col: usize) -> Option<usize> {
        let range = self.row_ptr[row]..self.row_ptr[row + 1];
        let found = self.cols[range.clone()].binary_search(&(col as u32)).ok()?;
        Some(range.start + found)
    }

    /// The stored blocks, to fill (positions from [`BlockCsr::position`]).
    pub fn values_mut(&mut self) -> &mut [Block] {
        &mut self.values
    }

    /// Row `i`'s columns and blocks.
    pub(crate) fn row(&self, i: usize) -> (&[u32], &[Block]) {
        let range = self.row_ptr[i]..self.row_ptr[i + 1];
        (&self.cols[range.clone()], &self.values[range])
    }

    /// Node `i`'s diagonal block (zero when not stored).
    pub fn diagonal(&self, i: usize) -> Block {
        self.position(i, i).map_or([0.0; 9], |p| self.values[p])
    }

    /// Adds `shift` to every diagonal entry that is not dead (zero).
    pub fn shift_diagonal(&mut self, shift: f64) {
        for i in 0..self.nodes() {
            if let Some(p) = self.position(i, i) {
                for a in 0..3 {
                    if self.values[p][4 * a] != 0.0 {
                        self.values[p][4 * a] += shift;
                    }
                }
            }
        }
    }

    /// The largest diagonal entry's magnitude.
    pub fn largest_diagonal(&self) -> f64 {
        (0..self.nodes())
            .map(|i| self.diagonal(i))
            .flat_map(|d| [d[0], d[4], d[8]])
            .fold(0.0, |m, v| m.max(v.abs()))
    }

    /// Which of the `3 * nodes` dofs are dead (zero diagonal entry).
    pub fn dead(&self) -> Vec<bool> {
        (0..self.nodes())
            .flat_map(|i| {
                let d = self.diagonal(i);
                [d[0] == 0.0, d[4] == 0.0, d[8] == 0.0]
            })
            .collect()
    }

    /// `y = A x`, in parallel over block rows.
    pub fn mul(&self, x: &[f64], y: &mut [f64]) {
        y.par_chunks_mut(3).with_min_len(ROWS_PER_TASK).enumerate().for_each(|(i, yi)| {
            let (cols, blocks) = self.row(i);
            let mut acc = [0.0; 3];
            for (&c, b) in cols.iter().zip(blocks) {
                let xc = &x[3 * c as usize..3 * c as usize + 3];
                for a in 0..3 {
                    acc[a] += b[3 * a] * xc[0] + b[3 * a + 1] * xc[1] + b[3 * a + 2] * xc[2];
                }
            }
            yi.copy_from_slice(&acc);
        });
    }

    /// `r = b - A x`, in parallel over block rows.
    pub fn residual(&self, b: &[f64], x: &[f64], r: &mut [f64]) {
        self.mul(x, r);
        r.par_iter_mut()
            .zip(b.par_iter())
            .with_min_len(3 * ROWS_PER_TASK)
            .for_each(|(ri, bi)| *ri = bi - *ri);
    }

    /// The lower triangle in compressed columns with 1 on dead diagonal entries (so the
    /// matrix can be factored; a dead dof then solves to its right-hand side, zero).
    pub(crate) fn lower_csc(&self) -> faer::sparse::SparseColMat<usize, f64> {
        let n = 3 * self.nodes();
        let dead = self.dead();
        let mut triplets = Vec::with_capacity(5 * self.blocks());
        for i in 0..self.nodes() {
            let (cols, blocks) = self.row(i);
            for (&c, b) in cols.iter().zip(blocks) {
                let c = c as usize;
                for a in 0..3 {
                    for e in 0..3 {
                        let (row, col) = (3 * i + a, 3 * c + e);
                        if row >= col && b[3 * a + e] != 0.0 {
                            triplets.push(faer::sparse::Triplet::new(row, col, b[3 * a + e]));
                        }
                    }
                }
            }
        }
        for (d, _) in dead.iter().enumerate().filter(|(_, dead)| **dead) {
            triplets.push(faer::sparse::Triplet::new(d, d, 1.0));
        }
        faer::sparse::SparseColMat::try_new_from_triplets(n, n, &triplets).expect("indices within the matrix")
    }
}

/// The inverse of a symmetric 3x3 block on its live components (dead ones, with a zero
/// diagonal entry, get zero rows and columns); a block that is singular on its live
/// components falls back to the reciprocals of its diagonal.
pub(crate) fn block_inverse(b: &Block) -> Block {
    let live = [b[0] != 0.0, b[4] != 0.0, b[8] != 0.0];
    let mut m = *b;
    for a in 0..3 {
        if !live[a] {
            for e in 0..3 {
                m[3 * a + e] = 0.0;
                m[3 * e + a] = 0.0;
            }
            m[4 * a] = 1.0;
        }
    }
    let cof = [
        m[4] * m[8] - m[5] * m[7],
        m[5] * m[6] - m[3] * m[8],
        m[3] * m[7] - m[4] * m[6],
        m[2] * m[7] - m[1] * m[8],
        m[0] * m[8] - m[2] * m[6],
        m[1] * m[6] - m[0] * m[7],
        m[1] * m[5] - m[2] * m[4],
        m[2] * m[3] - m[0] * m[5],
        m[0] * m[4] - m[1] * m[3],
    ];
    let det = m[0] * cof[0] + m[1] * cof[1] + m[2] * cof[2];
    let scale = m[0].abs().max(m[4].abs()).max(m[8].abs());
    let mut inv = [0.0; 9];
    if det > 1e-12 * scale * scale * scale {
        // The cofactor matrix's transpose over the determinant.
        for a in 0..3 {
            for e in 0..3 {
                inv[3 * a + e] = cof[3 * e + a] / det;
            }
        }
    } else {
        for a in 0..3 {
            inv[4 * a] = if m[4 * a] > 0.0 { 1.0 / m[4 * a] } else { 0.0 };
        }
    }
    for a in 0..3 {
        if !live[a] {
            for e in 0..3 {
                inv[3 * a + e] = 0.0;
                inv[3 * e + a] = 0.0;
            }
        }
    }
    inv
}

/// `y = B x` for a 3x3 block.
pub(crate) fn block_apply(b: &Block, x: &[f64]) -> [f64; 3] {
    std::array::from_fn(|a| b[3 * a] * x[0] + b[3 * a + 1] * x[1] + b[3 * a + 2] * x[2])
}

/// The dot product, in parallel.
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.par_iter().zip(b.par_iter()).with_min_len(3 * ROWS_PER_TASK).map(|(x, y)| x * y).sum()
}
