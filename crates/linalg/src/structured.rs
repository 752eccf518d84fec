//! The structured solver: block Cholesky plus a scalar Schur complement.

use std::time::Instant;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{LltError, cholesky_in_place, cholesky_in_place_scratch};
use faer::linalg::triangular_solve::{solve_lower_triangular_in_place, solve_upper_triangular_in_place};
use faer::{Mat, MatMut, MatRef};
use rayon::prelude::*;

use crate::block_view::BlockView;
use crate::in_place::cholesky_keeping_upper;
use crate::triangular::{MAX_STREAM_RHS, Scalar, llt_solve_in_place};
use crate::{
    Blocks, BorderedMatrix, FactorCost, FactorOptions, Factorization, LinalgError, LinearSolver, Precision,
    Result, cholesky_flops,
};

/// Never forms the dense matrix. Each stiffness block `K_c` is factored by Cholesky (one
/// factorization when the blocks are shared) and the pressure is eliminated through the
/// scalar Schur complement `sigma = sum_c S_c . K_c^-1 S_c`:
///
/// ```text
/// z_c = K_c^-1 S_c                       (kept; recomputed when the border changes)
/// y_c = K_c^-1 b_c
/// P   = (sum_c S_c . y_c - t) / sigma
/// u_c = y_c - P z_c
/// ```
///
/// A new border (or a new volume target) costs triangular solves only.
///
/// Storage and passes: each factor `L` is one N x N column-major buffer (lower triangle),
/// in f64, or in f32 with [`Precision::Mixed`] (half the bytes to stream; the checked
/// solve refines with f64 residuals). A solve reads each factor once forward and once
/// backward for every axis and right-hand side together: with a shared block the N x d
/// columns of all axes go through one blocked triangular solve (faer, several right-hand
/// sides); with per-axis blocks each axis's factor is read once for its columns, and the
/// axes run in parallel on the rayon pool.
#[derive(Clone, Copy, Debug, Default)]
pub struct Structured;

/// One Cholesky factor: the lower triangle of an N x N column-major buffer.
enum Factor {
    F64(Vec<f64>),
    F32(Vec<f32>),
    /// In the lower triangle of the matrix's own block (factored in place, f64).
    InPlace,
}

impl Factor {
    /// The diagonal entry `L_ii` of a factor of order `n` held in its own buffer.
    fn diag(&self, n: usize, i: usize) -> f64 {
        match self {
            Factor::F64(v) => v[i * n + i],
            Factor::F32(v) => v[i * n + i] as f64,
            Factor::InPlace => unreachable!("an in-place factor is checked where it is made"),
        }
    }

    /// Solves `K X = B` in place for the columns of `b` (n x k): one blocked forward and
    /// one blocked backward triangular solve over all k columns (each reads L once), with
    /// at most `threads` threads. `stored` is the matrix's block, which holds the factor
    /// when it was made in place (only the lower triangle is read).
    fn solve(&self, stored: &Mat<f64>, b: MatMut<'_, f64>, threads: usize) {
        let n = stored.nrows();
        match self {
            Factor::InPlace => llt_solve(stored.as_ref(), b, threads),
            Factor::F64(v) => llt_solve(MatRef::from_column_major_slice(v, n, n), b, threads),
            Factor::F32(v) => {
                let l = MatRef::from_column_major_slice(v, n, n);
                let mut s = Mat::<f32>::from_fn(n, b.ncols(), |i, j| b[(i, j)] as f32);
                llt_solve(l, s.as_mut(), threads);
                let mut b = b;
                for j in 0..b.ncols() {
                    for i in 0..n {
                        b[(i, j)] = s[(i, j)] as f64;
                    }
                }
            }
        }
    }
}

/// `L L' X = B` in place: split over L's rows for a few right-hand sides (memory-bound),
/// faer's blocked solve with the compute threads for many (matrix products).
fn llt_solve<T: Scalar>(l: MatRef<'_, T>, mut b: MatMut<'_, T>, threads: usize) {
    if b.ncols() <= MAX_STREAM_RHS {
        llt_solve_in_place(l, b, threads);
    } else {
        let par = crate::parallel::par_of(threads);
        solve_lower_triangular_in_place(l, b.as_mut(), par);
        solve_upper_triangular_in_place(l.transpose(), b, par);
    }
}

struct StructuredFactorization {
    matrix: BorderedMatrix,
    opts: FactorOptions,
    factors: Vec<Factor>,
    /// z_c = K_c^-1 S_c, one column per axis.
    z: Mat<f64>,
    schur: f64,
    cost: FactorCost,
}

impl LinearSolver for Structured {
    fn backend(&self) -> crate::Backend {
        crate::Backend::Structured
    }

    fn supports(&self, _precision: Precision) -> bool {
        true
    }

    fn factorize(&self, a: &BorderedMatrix, opts: &FactorOptions) -> Result<Box<dyn Factorization>> {
        a.check_finite()?;
        let start = Instant::now();
        let n = a.n_vertices();
        let nblocks = if a.is_shared() { 1 } else { a.axes() };
        let factors =
            (0..nblocks).map(|c| factor_block(a.view(c), c, opts.precision)).collect::<Result<_>>()?;
        let bytes = nblocks * n * n * if opts.precision == Precision::F64 { 8 } else { 4 };
        StructuredFactorization::finish(a, opts, factors, start, bytes)
    }

    /// In f64, when nothing else shares `a`'s blocks, writes each block's Cholesky factor
    /// over its lower triangle (`K` stays in the strict upper triangle, its diagonal is
    /// kept beside it): the factorization then needs no second N x N buffer. Otherwise,
    /// or in mixed precision, factors a copy as [`factorize`](Self::factorize) does.
    fn factorize_in_place(
        &self,
        a: &mut BorderedMatrix,
        opts: &FactorOptions,
    ) -> Result<Box<dyn Factorization>> {
        if opts.precision != Precision::F64 || a.blocks_mut().is_none() {
            return self.factorize(a, opts);
        }
        a.check_finite()?;
        let start = Instant::now();
        let diagonals = factor_blocks_in_place(a)?;
        let nblocks = diagonals.len();
        a.set_factored_in_place(Some(diagonals));
        let n = a.n_vertices();
        let factors = (0..nblocks).map(|_| Factor::InPlace).collect();
        StructuredFactorization::finish(a, opts, factors, start, nblocks * n * n * 8)
    }
}

impl StructuredFactorization {
    /// The factorization of `a` with its blocks' `factors` (made since `start`, holding
    /// `bytes`): the Schur complement of the border, and the cost. The blocks are shared
    /// with `a`, not copied.
    fn finish(
        a: &BorderedMatrix,
        opts: &FactorOptions,
        factors: Vec<Factor>,
        start: Instant,
        bytes: usize,
    ) -> Result<Box<dyn Factorization>> {
        let (n, nblocks) = (a.n_vertices(), factors.len());
        let mut f = StructuredFactorization {
            matrix: a.clone(),
            opts: *opts,
            factors,
            z: Mat::zeros(n, a.axes()),
            schur: 0.0,
            cost: FactorCost::default(),
        };
        f.update_schur()?;
        f.cost = FactorCost {
            flops: nblocks as f64 * cholesky_flops(n) + 2.0 * (a.axes() * n * n) as f64,
            seconds: start.elapsed().as_secs_f64(),
            bytes,
        };
        Ok(Box::new(f))
    }
}

/// Factors every distinct block of `a` (whose blocks it must own alone) over its lower
/// triangle and returns `K`'s diagonals. A matrix already factored in place gets its lower
/// triangles back from the upper ones first. On failure every block holds `K` again.
fn factor_blocks_in_place(a: &mut BorderedMatrix) -> Result<Vec<Vec<f64>>> {
    let n = a.n_vertices();
    let previous: Option<Vec<Vec<f64>>> =
        a.is_factored_in_place().then(|| (0..a.axes()).map(|c| a.block_diagonal(c)).collect());
    a.set_factored_in_place(None);
    let blocks = a.blocks_mut().expect("the caller checked that the blocks are not shared");
    let mut ks: Vec<&mut Mat<f64>> = match blocks {
        Blocks::Shared(k) => vec![k],
        Blocks::PerAxis(ks) => ks.iter_mut().collect(),
    };
    let mut diagonals: Vec<Vec<f64>> = Vec::with_capacity(ks.len());
    let tol = n as f64 * f64::EPSILON;
    for c in 0..ks.len() {
        if let Some(d) = &previous {
            restore_lower(ks[c], &d[c]);
        }
        diagonals.push((0..n).map(|i| ks[c][(i, i)]).collect());
        let result = cholesky_keeping_upper(ks[c].as_mut(), crate::parallel::compute_par()).and_then(|()| {
            // As for a copied factor: a tiny positive pivot is a singular block.
            (0..n).find(|&i| !(ks[c][(i, i)].powi(2) > tol * diagonals[c][i].abs())).map_or(Ok(()), Err)
        });
        if let Err(index) = result {
            for (k, d) in ks.iter_mut().zip(&diagonals) {
                restore_lower(k, d);
            }
            for (k, d) in ks.iter_mut().zip(previous.iter().flatten()).skip(c + 1) {
                restore_lower(k, d);
            }
            return Err(LinalgError::NotPositiveDefinite { axis: c, index });
        }
    }
    Ok(diagonals)
}

/// Writes `K` back into the lower triangle of a block from its strict upper triangle and
/// its diagonal, in 64 x 64 tiles (the strided reads stay in cache).
fn restore_lower(k: &mut Mat<f64>, diagonal: &[f64]) {
    const TILE: usize = 64;
    let n = k.nrows();
    for j0 in (0..n).step_by(TILE) {
        for i0 in (j0..n).step_by(TILE) {
            for j in j0..(j0 + TILE).min(n) {
                for i in i0.max(j + 1)..(i0 + TILE).min(n) {
                    k[(i, j)] = k[(j, i)];
                }
            }
        }
    }
    for (i, d) in diagonal.iter().enumerate() {
        k[(i, i)] = *d;
    }
}

/// Copies the lower triangle of `K` (upper triangle zero) into a fresh column-major buffer,
/// columns in parallel (this also spreads the first touch of the pages over the threads),
/// or reports that it cannot be allocated. A block factored in place gives its `K` from
/// the upper triangle (strided reads).
fn lower_copy<T: Copy + Send + Default>(k: BlockView<'_>, cast: impl Fn(f64) -> T + Sync) -> Result<Vec<T>> {
    let n = match k {
        BlockView::Full(k) | BlockView::Upper { upper: k, .. } => k.nrows(),
    };
    crate::dense::check_alloc::<T>(n.saturating_mul(n), "the Cholesky factors")?;
    let mut v = vec![T::default(); n * n];
    let fill = |(j, col): (usize, &mut [T])| {
        col[..j].fill(T::default());
        match k {
            BlockView::Full(k) => {
                for (d, s) in col[j..].iter_mut().zip(&k.col_as_slice(j)[j..]) {
                    *d = cast(*s);
                }
            }
            view => {
                for (i, d) in col.iter_mut().enumerate().skip(j) {
                    *d = cast(view.entry(i, j));
                }
            }
        }
    };
    if n >= 256 {
        v.par_chunks_mut(n).enumerate().for_each(fill);
    } else {
        v.chunks_mut(n).enumerate().for_each(fill);
    }
    Ok(v)
}

/// Factors `a` (n x n, column-major, lower triangle) in place with faer's global
/// parallelism; returns the index of a non-positive pivot.
fn cholesky<T: faer::traits::RealField>(a: &mut [T], n: usize) -> std::result::Result<(), usize> {
    let par = crate::parallel::compute_par();
    let mut mem = MemBuffer::new(cholesky_in_place_scratch::<T>(n, par, Default::default()));
    let m = MatMut::from_column_major_slice_mut(a, n, n);
    cholesky_in_place(m, Default::default(), par, MemStack::new(&mut mem), Default::default())
        .map(|_| ())
        .map_err(|LltError::NonPositivePivot { index }| index)
}

fn factor_block(k: BlockView<'_>, axis: usize, precision: Precision) -> Result<Factor> {
    let n = match k {
        BlockView::Full(k) | BlockView::Upper { upper: k, .. } => k.nrows(),
    };
    let not_pd = |index| LinalgError::NotPositiveDefinite { axis, index };
    let factor = match precision {
        Precision::F64 => {
            let mut v = lower_copy(k, |x| x)?;
            cholesky(&mut v, n).map_err(not_pd)?;
            Factor::F64(v)
        }
        Precision::Mixed => {
            let mut v = lower_copy(k, |x| x as f32)?;
            cholesky(&mut v, n).map_err(not_pd)?;
            Factor::F32(v)
        }
    };
    // A Laplacian with nothing fixed is singular, but rounding can leave a tiny positive
    // last pivot: compare each pivot L_ii^2 with its diagonal entry.
    let tol = n as f64 * eps(precision);
    for i in 0..n {
        let lii = factor.diag(n, i);
        if !(lii * lii > tol * k.entry(i, i).abs()) {
            return Err(not_pd(i));
        }
    }
    Ok(factor)
}

fn eps(p: Precision) -> f64 {
    match p {
        Precision::F64 => f64::EPSILON,
        Precision::Mixed => f32::EPSILON as f64,
    }
}

impl StructuredFactorization {
    /// Solves `K_c X_c = B_c` for every axis c; `cols[c]` holds axis c's columns (n x k).
    /// A shared factor takes one matrix of every column (`cols` of length 1).
    fn solve_blocks(&self, cols: &mut [MatMut<'_, f64>]) {
        let m = &self.matrix;
        let threads = crate::parallel::compute_threads();
        if self.factors.len() == 1 {
            for b in cols.iter_mut() {
                self.factors[0].solve(m.stored_block(0), b.as_mut(), threads);
            }
        } else if threads > 1 {
            // Three different factors, each streamed once for its own columns; the axes
            // share the threads.
            let per_axis = (threads / self.factors.len()).max(1);
            cols.par_iter_mut()
                .zip(&self.factors)
                .enumerate()
                .for_each(|(c, (b, f))| f.solve(m.stored_block(c), b.as_mut(), per_axis));
        } else {
            for (c, (b, f)) in cols.iter_mut().zip(&self.factors).enumerate() {
                f.solve(m.stored_block(c), b.as_mut(), 1);
            }
        }
    }

    /// Solves the N x m blocks of `y` (n x (d * count), column `k d + c` = axis c of
    /// right-hand side k) by one pass over each factor.
    fn solve_columns(&self, y: &mut Mat<f64>, count: usize) {
        let (n, d) = (self.matrix.n_vertices(), self.matrix.axes());
        if self.factors.len() == 1 {
            self.solve_blocks(&mut [y.as_mut()]);
            return;
        }
        let mut per_axis: Vec<Mat<f64>> =
            (0..d).map(|c| Mat::from_fn(n, count, |i, k| y[(i, k * d + c)])).collect();
        let mut views: Vec<MatMut<'_, f64>> = per_axis.iter_mut().map(|m| m.as_mut()).collect();
        self.solve_blocks(&mut views);
        for (c, m) in per_axis.iter().enumerate() {
            for k in 0..count {
                y.col_mut(k * d + c).copy_from(m.col(k));
            }
        }
    }

    fn update_schur(&mut self) -> Result<()> {
        let (n, d) = (self.matrix.n_vertices(), self.matrix.axes());
        let mut z = Mat::<f64>::from_fn(n, d, |i, c| self.matrix.border(c)[i]);
        self.solve_columns(&mut z, 1);
        let mut schur = 0.0;
        for c in 0..d {
            let s = self.matrix.border(c);
            for i in 0..n {
                schur += s[i] * z[(i, c)];
            }
        }
        // sigma = S' K^-1 S is positive for a non-zero border; compare with |S|^2 / |K|.
        let s2: f64 = (0..d).map(|c| self.matrix.border(c).iter().map(|v| v * v).sum::<f64>()).sum();
        let kmax = (0..d).map(|c| self.matrix.column_max(c * n)).fold(0.0, f64::max).max(1e-300);
        let floor = (n * d) as f64 * eps(self.opts.precision) * s2 / kmax;
        if !(schur > floor) || !schur.is_finite() {
            return Err(LinalgError::SingularPivot { index: self.matrix.dim() - 1, pivot: schur });
        }
        if z.col(0).iter().any(|v| v.is_nan()) {
            return Err(LinalgError::NonFiniteSolution { index: 0 });
        }
        self.z = z;
        self.schur = schur;
        Ok(())
    }

    /// The Schur step of one right-hand side: `out` gets `u_c = y_c - P z_c` and `P`, with
    /// `y_c` column `c` of `y` (n x d, already `K_c^-1 b_c`) and `t` the volume target.
    fn schur_step(&self, y: MatRef<'_, f64>, t: f64, out: &mut [f64]) {
        let (n, d) = (self.matrix.n_vertices(), self.matrix.axes());
        let mut sy = 0.0;
        for c in 0..d {
            sy += self.matrix.border(c).iter().zip(y.col(c).iter()).map(|(s, v)| s * v).sum::<f64>();
        }
        let p = (sy - t) / self.schur;
        for c in 0..d {
            let (yc, zc) = (y.col(c), self.z.col(c));
            for (i, o) in out[c * n..(c + 1) * n].iter_mut().enumerate() {
                *o = yc[i] - p * zc[i];
            }
        }
        out[d * n] = p;
    }
}

impl Factorization for StructuredFactorization {
    fn backend(&self) -> &'static str {
        "structured"
    }

    fn matrix(&self) -> &BorderedMatrix {
        &self.matrix
    }

    fn options(&self) -> &FactorOptions {
        &self.opts
    }

    fn cost(&self) -> FactorCost {
        self.cost
    }

    /// The axes of the right-hand side form an N x d matrix in place (the paper's layout
    /// stores all x, then all y, then all z): one pass over a shared factor for the three
    /// columns, without a copy.
    fn solve_unrefined(&self, rhs: &mut [f64]) {
        let (n, d) = (self.matrix.n_vertices(), self.matrix.axes());
        assert_eq!(rhs.len(), d * n + 1, "solve: rhs length");
        if self.factors.len() > 1 {
            return self.solve_many_unrefined(rhs, 1);
        }
        let t = rhs[d * n];
        {
            let (u, _) = rhs.split_at_mut(d * n);
            let m = MatMut::from_column_major_slice_mut(u, n, d);
            self.solve_blocks(&mut [m]);
        }
        // u_c = y_c - P z_c, in place.
        let ym = MatRef::from_column_major_slice(&rhs[..d * n], n, d);
        let mut sy = 0.0;
        for c in 0..d {
            sy += self.matrix.border(c).iter().zip(ym.col(c).iter()).map(|(s, v)| s * v).sum::<f64>();
        }
        let p = (sy - t) / self.schur;
        for c in 0..d {
            let zc = self.z.col(c);
            for (i, o) in rhs[c * n..(c + 1) * n].iter_mut().enumerate() {
                *o -= p * zc[i];
            }
        }
        rhs[d * n] = p;
    }

    /// Every axis of every right-hand side in one pass over each factor: the columns form
    /// an N x (d * count) block (column `k d + c` is axis c of right-hand side k), solved at
    /// once by the shared Cholesky factor, or per axis (N x count) by per-axis factors;
    /// then one scalar Schur step per right-hand side.
    fn solve_many_unrefined(&self, rhs: &mut [f64], count: usize) {
        let (n, d) = (self.matrix.n_vertices(), self.matrix.axes());
        let dim = d * n + 1;
        assert_eq!(rhs.len(), count * dim, "solve_many: rhs length");
        let mut y = Mat::<f64>::from_fn(n, d * count, |i, j| rhs[(j / d) * dim + (j % d) * n + i]);
        self.solve_columns(&mut y, count);
        for (k, out) in rhs.chunks_exact_mut(dim).enumerate() {
            let t = out[d * n];
            self.schur_step(y.subcols(k * d, d), t, out);
        }
    }

    fn set_border(&mut self, border: &[Vec<f64>]) -> Result<FactorCost> {
        let start = Instant::now();
        self.matrix.set_border(border);
        self.update_schur()?;
        let n = self.matrix.n_vertices();
        Ok(FactorCost {
            flops: 2.0 * (self.matrix.axes() * n * n) as f64,
            seconds: start.elapsed().as_secs_f64(),
            bytes: 0,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Blocks, FactorizationExt};

    /// A factorization of a 3-axis system with a shared SPD block (a path Laplacian plus
    /// the identity) whose factor is then corrupted by `corrupt`.
    fn corrupted(opts: FactorOptions, corrupt: impl Fn(&mut Vec<f64>, usize)) -> StructuredFactorization {
        let n = 40;
        let k = Mat::from_fn(n, n, |i, j| match i.abs_diff(j) {
            0 => 3.0,
            1 => -1.0,
            _ => 0.0,
        });
        let border = (0..3).map(|c| (0..n).map(|i| 1.0 + ((i + c) % 5) as f64).collect()).collect();
        let a = BorderedMatrix::new(Blocks::Shared(k), border, 1.0);
        let mut factor = factor_block(a.view(0), 0, Precision::F64).unwrap();
        if let Factor::F64(v) = &mut factor {
            corrupt(v, n);
        }
        let mut f = StructuredFactorization {
            matrix: a,
            opts,
            factors: vec![factor],
            z: Mat::zeros(n, 3),
            schur: 0.0,
            cost: FactorCost::default(),
        };
        f.update_schur().unwrap();
        f
    }

    #[test]
    fn an_intact_factor_passes_the_check() {
        let f = corrupted(FactorOptions { max_refinement_steps: 0, ..FactorOptions::default() }, |_, _| {});
        let b: Vec<f64> = (0..f.matrix.dim()).map(|i| (i % 7) as f64 - 3.0).collect();
        let s = f.solve(&b).unwrap();
        assert!(s.relative_residual <= crate::DEFAULT_TARGET_RESIDUAL, "{}", s.relative_residual);
    }

    #[test]
    fn a_corrupted_factor_is_caught_by_the_residual_check() {
        let b: Vec<f64> = (0..3 * 40 + 1).map(|i| (i % 7) as f64 - 3.0).collect();
        // One entry of L off by 1 %: without refinement the residual check rejects it.
        let f = corrupted(FactorOptions { max_refinement_steps: 0, ..FactorOptions::default() }, |v, n| {
            v[5 * n + 6] *= 1.01
        });
        let e = f.solve(&b).expect_err("a wrong factor");
        assert!(matches!(e, LinalgError::ResidualTooLarge { .. }), "{e:?}");
        // Grossly wrong (a pivot 100 times too large): refinement cannot repair it either.
        let f = corrupted(FactorOptions::default(), |v, n| v[7 * n + 7] *= 100.0);
        let e = f.solve(&b).expect_err("a wrong factor");
        assert!(
            matches!(e, LinalgError::ResidualTooLarge { .. } | LinalgError::NonFiniteSolution { .. }),
            "{e:?}"
        );
    }
}
