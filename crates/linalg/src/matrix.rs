//! The bordered matrix of the fiber–fluid method, in structured form.

use std::borrow::Cow;
use std::sync::Arc;

use faer::Mat;

use crate::block_view::BlockView;
use crate::{LinalgError, Result};

/// The stiffness blocks `K_c` of the bordered system, one per axis or one shared by all axes.
#[derive(Clone, Debug)]
pub enum Blocks {
    /// One N x N block used for every axis (isotropic material, identical constraints).
    Shared(Mat<f64>),
    /// One N x N block per axis, in axis order (x, y[, z]).
    PerAxis(Vec<Mat<f64>>),
}

/// The (dN+1) x (dN+1) bordered matrix, `d` = number of axes (2 or 3):
///
/// ```text
/// [ K_x  0    0    b_x ]
/// [ 0    K_y  0    b_y ]
/// [ 0    0    K_z  b_z ]
/// [ b_x' b_y' b_z' 0   ]
/// ```
///
/// Unknowns are ordered as the paper stores them: all x, all y, all z, then the pressure.
/// The border `b_c` is the vertex area vector component `S_c` multiplied by
/// [`pressure_scale`](Self::pressure_scale): the last unknown is `P / pressure_scale` and
/// the last right-hand side entry is `pressure_scale * volume_target`. The matrix is never
/// stored densely unless [`to_dense`](Self::to_dense) is called.
///
/// The blocks are immutable once built and shared between clones (a clone copies the
/// border only), so a factorization keeps the matrix it factors without copying N^2 values.
///
/// **Factored in place.** A backend may overwrite the lower triangle of each block with its
/// Cholesky factor while it owns the blocks alone
/// ([`LinearSolver::factorize_in_place`](crate::LinearSolver::factorize_in_place)): the
/// strict upper triangle still holds `K` and the diagonal of `K` is kept beside it, so one
/// N x N buffer per block serves both the factor and the residual checks. Every method
/// here reads `K` from whichever form the block is in; only [`block`](Self::block) and
/// [`blocks`](Self::blocks), which hand out the raw storage, refuse such a matrix.
#[derive(Clone, Debug)]
pub struct BorderedMatrix {
    n: usize,
    blocks: Arc<Blocks>,
    border: Vec<Vec<f64>>,
    pressure_scale: f64,
    /// Absolute row sums of each block (without the border), cached for `norm_inf`.
    block_row_sums: Arc<Vec<Vec<f64>>>,
    /// Per block: every off-diagonal entry is <= 0 and every diagonal one >= 0 (a weighted
    /// Laplacian with constraints), so `|K| |x| = 2 D |x| - K |x|` needs one matrix product.
    block_is_z_matrix: Vec<bool>,
    /// When the blocks hold their Cholesky factor in the lower triangle: `K`'s diagonal per
    /// block (the strict upper triangle is still `K`'s).
    packed_diagonals: Option<Arc<Vec<Vec<f64>>>>,
}

impl BorderedMatrix {
    /// Builds the matrix from its blocks, the *physical* border (`S_c`, one vector of
    /// length N per axis) and the pressure scale that multiplies it.
    ///
    /// # Panics
    /// On inconsistent shapes (a programming error, not a data error).
    #[track_caller]
    pub fn new(blocks: Blocks, border: Vec<Vec<f64>>, pressure_scale: f64) -> Self {
        let axes = border.len();
        assert!(axes == 2 || axes == 3, "the border must have 2 or 3 axes");
        let n = border[0].len();
        assert!(border.iter().all(|b| b.len() == n), "border rows differ in length");
        match &blocks {
            Blocks::Shared(k) => assert!(k.nrows() == n && k.ncols() == n, "block shape"),
            Blocks::PerAxis(ks) => {
                assert_eq!(ks.len(), axes, "one block per axis");
                assert!(ks.iter().all(|k| k.nrows() == n && k.ncols() == n), "block shape");
            }
        }
        let border =
            border.into_iter().map(|b| b.into_iter().map(|v| v * pressure_scale).collect()).collect();
        let summaries: Vec<(Vec<f64>, bool)> = match &blocks {
            Blocks::Shared(k) => vec![block_summary(k)],
            Blocks::PerAxis(ks) => ks.iter().map(block_summary).collect(),
        };
        let block_is_z_matrix = summaries.iter().map(|s| s.1).collect();
        let block_row_sums = Arc::new(summaries.into_iter().map(|s| s.0).collect());
        Self {
            n,
            blocks: Arc::new(blocks),
            border,
            pressure_scale,
            block_row_sums,
            block_is_z_matrix,
            packed_diagonals: None,
        }
    }

    /// Number of vertices N.
    pub fn n_vertices(&self) -> usize {
        self.n
    }

    /// Number of axes d (2 for the paper's planar example, 3 otherwise).
    pub fn axes(&self) -> usize {
        self.border.len()
    }

    /// Size of the system, dN + 1.
    pub fn dim(&self) -> usize {
        self.axes() * self.n + 1
    }

    /// The stiffness blocks.
    ///
    /// # Panics
    /// If the matrix was [factored in place](Self::is_factored_in_place) (its blocks'
    /// lower triangles hold the factor): read `K` through [`block_full`](Self::block_full).
    #[track_caller]
    pub fn blocks(&self) -> &Blocks {
        assert!(self.packed_diagonals.is_none(), "the blocks hold their factor: use block_full");
        &self.blocks
    }

    /// The stiffness block of one axis.
    ///
    /// # Panics
    /// If the matrix was [factored in place](Self::is_factored_in_place): read `K` through
    /// [`block_full`](Self::block_full), [`block_entry`](Self::block_entry) or
    /// [`block_column`](Self::block_column).
    #[track_caller]
    pub fn block(&self, axis: usize) -> &Mat<f64> {
        assert!(self.packed_diagonals.is_none(), "the blocks hold their factor: use block_full");
        self.stored_block(axis)
    }

    /// The storage of one axis's block, whatever it holds.
    pub(crate) fn stored_block(&self, axis: usize) -> &Mat<f64> {
        match &*self.blocks {
            Blocks::Shared(k) => k,
            Blocks::PerAxis(ks) => &ks[axis],
        }
    }

    /// One axis's block as `K` is stored in it.
    pub(crate) fn view(&self, axis: usize) -> BlockView<'_> {
        let upper = self.stored_block(axis);
        match &self.packed_diagonals {
            None => BlockView::Full(upper),
            Some(d) => BlockView::Upper { upper, diagonal: &d[if self.is_shared() { 0 } else { axis }] },
        }
    }

    /// Whether a backend wrote its factor over the blocks' lower triangles (see the type's
    /// docs); `K` is still readable through every method but [`block`](Self::block).
    pub fn is_factored_in_place(&self) -> bool {
        self.packed_diagonals.is_some()
    }

    /// `K_c[i, j]` of axis `c`'s block, in either storage.
    pub fn block_entry(&self, axis: usize, i: usize, j: usize) -> f64 {
        self.view(axis).entry(i, j)
    }

    /// Column `j` of axis `c`'s block (equal to its row `j`), in either storage.
    pub fn block_column(&self, axis: usize, j: usize) -> Vec<f64> {
        let mut out = vec![0.0; self.n];
        self.view(axis).column_into(j, &mut out);
        out
    }

    /// Axis `c`'s whole block `K_c`: borrowed, or rebuilt (an N x N copy) when the matrix
    /// was factored in place.
    pub fn block_full(&self, axis: usize) -> Cow<'_, Mat<f64>> {
        match self.view(axis) {
            BlockView::Full(k) => Cow::Borrowed(k),
            view => Cow::Owned(Mat::from_fn(self.n, self.n, |i, j| view.entry(i, j))),
        }
    }

    /// Exclusive access to the blocks, for a factorization in place: `None` when a clone
    /// shares them. Whatever the caller writes, it must leave `K` readable: either the
    /// whole block, or (after [`set_factored_in_place`](Self::set_factored_in_place)) its
    /// strict upper triangle.
    pub(crate) fn blocks_mut(&mut self) -> Option<&mut Blocks> {
        Arc::get_mut(&mut self.blocks)
    }

    /// `K`'s diagonal of axis `c`'s block, in either storage.
    pub(crate) fn block_diagonal(&self, axis: usize) -> Vec<f64> {
        (0..self.n).map(|i| self.view(axis).entry(i, i)).collect()
    }

    /// Records that the blocks' lower triangles hold a factor (`Some`, with `K`'s diagonal
    /// per distinct block) or hold `K` again (`None`).
    pub(crate) fn set_factored_in_place(&mut self, diagonals: Option<Vec<Vec<f64>>>) {
        self.packed_diagonals = diagonals.map(Arc::new);
    }

    /// Whether one block serves every axis.
    pub fn is_shared(&self) -> bool {
        matches!(*self.blocks, Blocks::Shared(_))
    }

    /// The border column of one axis as stored in the matrix (already scaled).
    pub fn border(&self, axis: usize) -> &[f64] {
        &self.border[axis]
    }

    /// The factor that multiplies the physical border (and divides the pressure unknown).
    pub fn pressure_scale(&self) -> f64 {
        self.pressure_scale
    }

    /// Replaces the border by a new physical border `S` (same shape), keeping the scale.
    #[track_caller]
    pub fn set_border(&mut self, border: &[Vec<f64>]) {
        assert_eq!(border.len(), self.axes(), "border axes");
        for (dst, src) in self.border.iter_mut().zip(border) {
            assert_eq!(src.len(), self.n, "border length");
            for (d, s) in dst.iter_mut().zip(src) {
                *d = s * self.pressure_scale;
            }
        }
    }

    /// The dense (dN+1)^2 matrix in the paper's layout (for tests and small systems).
    ///
    /// # Panics
    /// If the matrix cannot be allocated (with [`LinalgError::OutOfMemory`]'s message);
    /// [`try_to_dense`](Self::try_to_dense) returns that error instead.
    #[track_caller]
    pub fn to_dense(&self) -> Mat<f64> {
        self.try_to_dense().unwrap_or_else(|e| panic!("{e}"))
    }

    /// The dense (dN+1)^2 matrix in the paper's layout, or [`LinalgError::OutOfMemory`] when
    /// it cannot be allocated.
    pub fn try_to_dense(&self) -> Result<Mat<f64>> {
        let (n, d) = (self.n, self.axes());
        let dim = self.dim();
        crate::memory::check_alloc::<f64>(dim.saturating_mul(dim), crate::memory::DENSE_WHAT)?;
        let mut a = Mat::<f64>::zeros(dim, dim);
        for c in 0..d {
            let k = self.view(c);
            let off = c * n;
            for j in 0..n {
                k.column_into(j, &mut a.col_as_slice_mut(off + j)[off..off + n]);
            }
            a.col_as_slice_mut(dim - 1)[off..off + n].copy_from_slice(&self.border[c]);
            for i in 0..n {
                a[(dim - 1, off + i)] = self.border[c][i];
            }
        }
        Ok(a)
    }

    /// The dense (dN+1)^2 matrix in the paper's layout, column-major in one `Vec` (the
    /// layout LAPACK, nalgebra and the faer backend factor in place), written directly
    /// without an intermediate matrix.
    ///
    /// The columns are filled in parallel (rayon's pool) and each is written whole, zeros
    /// included: for a large fresh allocation the cost is the first touch of every page, and
    /// this spreads those page faults over the threads instead of leaving them to the
    /// factorization.
    ///
    /// # Panics
    /// If the matrix cannot be allocated;
    /// [`try_to_dense_col_major`](Self::try_to_dense_col_major) returns the error instead.
    #[track_caller]
    pub fn to_dense_col_major(&self) -> Vec<f64> {
        self.try_to_dense_col_major().unwrap_or_else(|e| panic!("{e}"))
    }

    /// [`to_dense_col_major`](Self::to_dense_col_major), or [`LinalgError::OutOfMemory`]
    /// (naming the bytes needed) when the matrix cannot be allocated. The dense backends
    /// use this one.
    pub fn try_to_dense_col_major(&self) -> Result<Vec<f64>> {
        use rayon::prelude::*;
        let (n, d) = (self.n, self.axes());
        let dim = self.dim();
        let mut a = crate::memory::try_zeroed(dim.saturating_mul(dim), crate::memory::DENSE_WHAT)?;
        a.par_chunks_mut(dim).enumerate().for_each(|(j, col)| {
            if j == dim - 1 {
                for c in 0..d {
                    col[c * n..(c + 1) * n].copy_from_slice(&self.border[c]);
                }
                col[dim - 1] = 0.0;
            } else {
                let (c, jj) = (j / n, j % n);
                let off = c * n;
                col[..off].fill(0.0);
                self.view(c).column_into(jj, &mut col[off..off + n]);
                col[off + n..dim - 1].fill(0.0);
                col[dim - 1] = self.border[c][jj];
            }
        });
        Ok(a)
    }

    /// Bytes the dense form would take.
    pub fn dense_bytes(&self) -> usize {
        self.dim() * self.dim() * std::mem::size_of::<f64>()
    }

    /// `y = A x` without forming the dense matrix (one matrix product per block; the
    /// unknowns of all axes form an n x d column-major matrix, so a shared block is a
    /// single product).
    #[track_caller]
    pub fn apply(&self, x: &[f64], y: &mut [f64]) {
        use faer::{Accum, MatMut, MatRef};
        let (n, d, dim) = (self.n, self.axes(), self.dim());
        assert!(x.len() == dim && y.len() == dim, "apply: vector length");
        let par = crate::parallel::stream_par(n * n * 8);
        match &*self.blocks {
            _ if self.is_factored_in_place() => {
                let slices: Vec<(usize, &[f64])> = (0..d).map(|c| (c, &x[c * n..(c + 1) * n])).collect();
                for (c, kx) in self.triangle_products(&slices, false).into_iter().enumerate() {
                    y[c * n..(c + 1) * n].copy_from_slice(&kx);
                }
            }
            Blocks::Shared(k) => {
                let xm = MatRef::from_column_major_slice(&x[..d * n], n, d);
                let ym = MatMut::from_column_major_slice_mut(&mut y[..d * n], n, d);
                faer::linalg::matmul::matmul(ym, Accum::Replace, k.as_ref(), xm, 1.0, par);
            }
            Blocks::PerAxis(ks) => {
                for (c, k) in ks.iter().enumerate() {
                    let xm = MatRef::from_column_major_slice(&x[c * n..(c + 1) * n], n, 1);
                    let ym = MatMut::from_column_major_slice_mut(&mut y[c * n..(c + 1) * n], n, 1);
                    faer::linalg::matmul::matmul(ym, Accum::Replace, k.as_ref(), xm, 1.0, par);
                }
            }
        }
        let p = x[dim - 1];
        let mut last = 0.0;
        for c in 0..d {
            let b = &self.border[c];
            let (xc, yc) = (&x[c * n..(c + 1) * n], &mut y[c * n..(c + 1) * n]);
            for i in 0..n {
                yc[i] += b[i] * p;
                last += b[i] * xc[i];
            }
        }
        y[dim - 1] = last;
    }

    /// `K_c x` (or `|K_c| |x|` with `abs`) for each `(axis c, x)` of `slices`, in order, by the
    /// one-triangle kernel of [`crate::residual`]: one pass over each distinct block for all
    /// the slices it multiplies. Serves every storage, and is the only product for a matrix
    /// factored in place.
    fn triangle_products(&self, slices: &[(usize, &[f64])], abs: bool) -> Vec<Vec<f64>> {
        let n = self.n;
        let nblocks = if self.is_shared() { 1 } else { self.axes() };
        let mut out = vec![Vec::new(); slices.len()];
        for bi in 0..nblocks {
            let mine: Vec<usize> = (0..slices.len()).filter(|&s| nblocks == 1 || slices[s].0 == bi).collect();
            if mine.is_empty() {
                continue;
            }
            let xs: Vec<&[f64]> = mine.iter().map(|&s| slices[s].1).collect();
            let prod = crate::residual::symmetric_products(self.view(bi), &xs);
            let half = if abs { mine.len() * n } else { 0 };
            for (v, &s) in mine.iter().enumerate() {
                out[s] = prod[half + v * n..half + (v + 1) * n].to_vec();
            }
        }
        out
    }

    /// `y_k = A x_k` for `count` vectors stored one after another (each [`dim`](Self::dim)
    /// long): one matrix product per block for all of them (the axes of every vector form
    /// an N x (d * count) matrix for a shared block), so the blocks are read once, not
    /// `count` times.
    #[track_caller]
    pub fn apply_many(&self, x: &[f64], y: &mut [f64], count: usize) {
        self.apply_many_with(x, y, count, false);
    }

    /// `y_k = |A| |x_k|` for `count` vectors stored one after another, as
    /// [`apply_abs`](Self::apply_abs) does each, in one pass over a shared block of a
    /// weighted Laplacian (otherwise vector by vector).
    #[track_caller]
    pub fn apply_abs_many(&self, x: &[f64], y: &mut [f64], count: usize) {
        let dim = self.dim();
        assert!(x.len() == count * dim && y.len() == count * dim, "apply_abs_many: vector length");
        if self.is_shared() && self.block_is_z_matrix[0] {
            self.apply_many_with(x, y, count, true);
        } else {
            for (xk, yk) in x.chunks_exact(dim).zip(y.chunks_exact_mut(dim)) {
                self.apply_abs(xk, yk);
            }
        }
    }

    /// `A x` (or, with `abs`, `|A| |x|` for a shared weighted Laplacian, through
    /// `2 D |x| - K |x|`) for several vectors in one product per block.
    fn apply_many_with(&self, x: &[f64], y: &mut [f64], count: usize, abs: bool) {
        use faer::{Accum, Mat};
        let (n, d, dim) = (self.n, self.axes(), self.dim());
        assert!(x.len() == count * dim && y.len() == count * dim, "apply_many: vector length");
        let val = |v: f64| if abs { v.abs() } else { v };
        let par = crate::parallel::stream_par(n * n * 8);
        let sign = if abs { -1.0 } else { 1.0 };
        match &*self.blocks {
            _ if self.is_factored_in_place() => {
                let slices: Vec<(usize, &[f64])> = (0..count * d)
                    .map(|j| (j % d, &x[(j / d) * dim + (j % d) * n..(j / d) * dim + (j % d + 1) * n]))
                    .collect();
                for (j, kx) in self.triangle_products(&slices, abs).into_iter().enumerate() {
                    let (kk, c) = (j / d, j % d);
                    y[kk * dim + c * n..kk * dim + (c + 1) * n].copy_from_slice(&kx);
                }
            }
            Blocks::Shared(k) => {
                let xm = Mat::<f64>::from_fn(n, d * count, |i, j| val(x[(j / d) * dim + (j % d) * n + i]));
                let mut ym = Mat::<f64>::zeros(n, d * count);
                faer::linalg::matmul::matmul(ym.as_mut(), Accum::Replace, k.as_ref(), xm.as_ref(), sign, par);
                for j in 0..d * count {
                    let (kk, c) = (j / d, j % d);
                    let out = &mut y[kk * dim + c * n..kk * dim + (c + 1) * n];
                    for i in 0..n {
                        out[i] = ym[(i, j)] + if abs { 2.0 * k[(i, i)] * xm[(i, j)] } else { 0.0 };
                    }
                }
            }
            Blocks::PerAxis(ks) => {
                for (c, k) in ks.iter().enumerate() {
                    let xm = Mat::<f64>::from_fn(n, count, |i, kk| val(x[kk * dim + c * n + i]));
                    let mut ym = Mat::<f64>::zeros(n, count);
                    faer::linalg::matmul::matmul(
                        ym.as_mut(),
                        Accum::Replace,
                        k.as_ref(),
                        xm.as_ref(),
                        1.0,
                        par,
                    );
                    for kk in 0..count {
                        for i in 0..n {
                            y[kk * dim + c * n + i] = ym[(i, kk)];
                        }
                    }
                }
            }
        }
        for (xk, yk) in x.chunks_exact(dim).zip(y.chunks_exact_mut(dim)) {
            let p = val(xk[dim - 1]);
            let mut last = 0.0;
            for c in 0..d {
                let b = &self.border[c];
                for i in 0..n {
                    yk[c * n + i] += val(b[i]) * p;
                    last += val(b[i]) * val(xk[c * n + i]);
                }
            }
            yk[dim - 1] = last;
        }
    }

    /// `r = b - A x` and `abs_ax = |A| |x|` (the numerator and denominator of the
    /// componentwise backward error) in one pass over each block: one matrix product
    /// `K [x, |x|]` for a weighted Laplacian (`|K| |x| = 2 D |x| - K |x|`), otherwise one
    /// pass over the lower triangle. [`apply`](Self::apply) followed by
    /// [`apply_abs`](Self::apply_abs) reads each block twice.
    #[track_caller]
    pub fn residual(&self, x: &[f64], b: &[f64], r: &mut [f64], abs_ax: &mut [f64]) {
        self.residual_many(x, b, r, abs_ax, 1);
    }

    /// [`residual`](Self::residual) for `count` vectors stored one after another (each
    /// [`dim`](Self::dim) long): every vector's axes against a shared block in one pass, or
    /// each per-axis block once for all vectors.
    #[track_caller]
    pub fn residual_many(&self, x: &[f64], b: &[f64], r: &mut [f64], abs_ax: &mut [f64], count: usize) {
        let (n, d, dim) = (self.n, self.axes(), self.dim());
        let len = count * dim;
        assert!(
            x.len() == len && b.len() == len && r.len() == len && abs_ax.len() == len,
            "residual: vector length"
        );
        let nblocks = if self.is_shared() { 1 } else { d };
        for bi in 0..nblocks {
            // The (vector, axis) pairs this block multiplies.
            let pairs: Vec<(usize, usize)> = (0..count)
                .flat_map(|k| (0..d).filter(move |&c| nblocks == 1 || c == bi).map(move |c| (k, c)))
                .collect();
            let xs: Vec<&[f64]> =
                pairs.iter().map(|&(k, c)| &x[k * dim + c * n..k * dim + (c + 1) * n]).collect();
            let prod = match self.view(bi) {
                BlockView::Full(k) if self.block_is_z_matrix[bi] && n < crate::residual::STREAMING_MIN_N => {
                    crate::residual::z_matrix_products(k, &xs)
                }
                view => crate::residual::symmetric_products(view, &xs),
            };
            let m = pairs.len();
            for (v, &(k, c)) in pairs.iter().enumerate() {
                let (kx, kax) = (&prod[v * n..(v + 1) * n], &prod[(m + v) * n..(m + v + 1) * n]);
                let p = x[k * dim + dim - 1];
                let s = &self.border[c];
                let off = k * dim + c * n;
                for i in 0..n {
                    r[off + i] = b[off + i] - (kx[i] + s[i] * p);
                    abs_ax[off + i] = kax[i] + s[i].abs() * p.abs();
                }
            }
        }
        for k in 0..count {
            let xk = &x[k * dim..(k + 1) * dim];
            let (mut last, mut abs_last) = (0.0, 0.0);
            for c in 0..d {
                for (s, xi) in self.border[c].iter().zip(&xk[c * n..(c + 1) * n]) {
                    last += s * xi;
                    abs_last += s.abs() * xi.abs();
                }
            }
            r[k * dim + dim - 1] = b[k * dim + dim - 1] - last;
            abs_ax[k * dim + dim - 1] = abs_last;
        }
    }

    /// `y = |A| |x|` (entrywise absolute values), the denominator of the componentwise
    /// backward error.
    #[track_caller]
    pub fn apply_abs(&self, x: &[f64], y: &mut [f64]) {
        let (n, d, dim) = (self.n, self.axes(), self.dim());
        assert!(x.len() == dim && y.len() == dim, "apply_abs: vector length");
        let ax: Vec<f64> = x.iter().map(|v| v.abs()).collect();
        if self.is_factored_in_place() {
            let slices: Vec<(usize, &[f64])> = (0..d).map(|c| (c, &x[c * n..(c + 1) * n])).collect();
            for (c, kx) in self.triangle_products(&slices, true).into_iter().enumerate() {
                y[c * n..(c + 1) * n].copy_from_slice(&kx);
            }
        } else if self.is_shared() && self.block_is_z_matrix[0] {
            // One product for every axis (one pass over the shared block, as in `apply`):
            // Y = 2 D |X| - K |X| with |X| the n x d matrix of the axes' unknowns.
            let k = self.block(0);
            let par = crate::parallel::stream_par(n * n * 8);
            let xm = faer::MatRef::from_column_major_slice(&ax[..d * n], n, d);
            let ym = faer::MatMut::from_column_major_slice_mut(&mut y[..d * n], n, d);
            faer::linalg::matmul::matmul(ym, faer::Accum::Replace, k.as_ref(), xm, -1.0, par);
            for c in 0..d {
                for i in 0..n {
                    y[c * n + i] += 2.0 * k[(i, i)] * ax[c * n + i];
                }
            }
        } else {
            for c in 0..d {
                let bi = if self.is_shared() { 0 } else { c };
                let k = self.block(c);
                let (xc, yc) = (&ax[c * n..(c + 1) * n], &mut y[c * n..(c + 1) * n]);
                if self.block_is_z_matrix[bi] {
                    let par = crate::parallel::stream_par(n * n * 8);
                    let xm = faer::MatRef::from_column_major_slice(xc, n, 1);
                    let ym = faer::MatMut::from_column_major_slice_mut(yc, n, 1);
                    faer::linalg::matmul::matmul(ym, faer::Accum::Replace, k.as_ref(), xm, -1.0, par);
                    for i in 0..n {
                        yc[i] += 2.0 * k[(i, i)] * xc[i];
                    }
                } else {
                    yc.iter_mut().for_each(|v| *v = 0.0);
                    for j in 0..n {
                        let col = k.col(j);
                        for (i, v) in col.iter().enumerate() {
                            yc[i] += v.abs() * xc[j];
                        }
                    }
                }
            }
        }
        let p = ax[dim - 1];
        let mut last = 0.0;
        for c in 0..d {
            let b = &self.border[c];
            for i in 0..n {
                y[c * n + i] += b[i].abs() * p;
                last += b[i].abs() * ax[c * n + i];
            }
        }
        y[dim - 1] = last;
    }

    /// The infinity norm (largest absolute row sum), equal to the 1-norm since A is symmetric.
    pub fn norm_inf(&self) -> f64 {
        let mut best = self.border.iter().flatten().map(|v| v.abs()).sum::<f64>();
        for c in 0..self.axes() {
            let sums = &self.block_row_sums[if self.is_shared() { 0 } else { c }];
            for (s, b) in sums.iter().zip(&self.border[c]) {
                best = best.max(s + b.abs());
            }
        }
        best
    }

    /// The largest absolute entry of column `j` of the dense form (equal to row `j`).
    pub fn column_max(&self, j: usize) -> f64 {
        let (n, dim) = (self.n, self.dim());
        if j == dim - 1 {
            return self.border.iter().flatten().fold(0.0, |m, v| m.max(v.abs()));
        }
        let (c, i) = (j / n, j % n);
        self.block_column(c, i).iter().fold(self.border[c][i].abs(), |m, v| m.max(v.abs()))
    }

    /// Returns an error naming the first non-finite entry, if any.
    pub fn check_finite(&self) -> Result<()> {
        let (n, dim) = (self.n, self.dim());
        let nblocks = if self.is_shared() { 1 } else { self.axes() };
        let mut column = vec![0.0; n];
        for c in 0..nblocks {
            // The cached absolute row sums are finite exactly when every entry is (barring
            // an overflow of the sum, which the scan below then rules out): then no scan.
            if self.block_row_sums[c].iter().all(|v| v.is_finite()) {
                continue;
            }
            for j in 0..n {
                self.view(c).column_into(j, &mut column);
                if let Some(i) = column.iter().position(|v| !v.is_finite()) {
                    return Err(LinalgError::NonFinite { row: c * n + i, col: c * n + j });
                }
            }
        }
        for (c, b) in self.border.iter().enumerate() {
            if let Some(i) = b.iter().position(|v| !v.is_finite()) {
                return Err(LinalgError::NonFinite { row: c * n + i, col: dim - 1 });
            }
        }
        Ok(())
    }
}

/// The absolute row sums of a symmetric block (its column sums: columns are contiguous)
/// and whether every off-diagonal entry is <= 0 and every diagonal one >= 0, in one pass,
/// columns in parallel.
fn block_summary(k: &Mat<f64>) -> (Vec<f64>, bool) {
    use rayon::prelude::*;
    let n = k.nrows();
    let column = |j: usize| {
        let col = k.col_as_slice(j);
        let sum = col.iter().map(|v| v.abs()).sum::<f64>();
        // `|K| |x| = 2 D |x| - K |x|` also needs a diagonal that is not negative.
        let z = col.iter().enumerate().all(|(i, v)| if i == j { *v >= 0.0 } else { *v <= 0.0 });
        (sum, z)
    };
    let cols: Vec<(f64, bool)> =
        if n >= 256 { (0..n).into_par_iter().map(column).collect() } else { (0..n).map(column).collect() };
    let z = cols.iter().all(|c| c.1);
    (cols.into_iter().map(|c| c.0).collect(), z)
}
