//! The residual of a checked solve in one pass over each stiffness block.
//!
//! For a block whose off-diagonal entries are all <= 0 (a weighted Laplacian, with
//! eliminated or penalized constraints), `|K| |x| = 2 D |x| - K |x|`, so one faer matrix
//! product `K [x_1 .. x_m, |x_1| .. |x_m|]` (AVX-512 / AVX2 kernels, rayon pool) gives both
//! ([`z_matrix_products`]). Other symmetric blocks use [`symmetric_products`].
//!
//! A checked solve needs `r = b - A x` and the denominator `|A| |x|` of the componentwise
//! backward error. Done as two matrix products, that reads every block twice, in full. The
//! kernel here reads each block once and only one triangle (the blocks are symmetric):
//! column j of the lower triangle updates rows `i > j` (`y_i += K_ij x_j`) and row j
//! (`y_j += sum_i K_ij x_i`) for `K x` and `|K| |x|` together, for every vector. A block
//! factored in place keeps `K` in its strict upper triangle and its diagonal beside it;
//! the kernel then reads column j's rows `i < j` the same way. The
//! columns are split into one range of equal triangle area per thread, each with its own
//! accumulators, summed at the end. The loop is compiled for the widest vector unit the CPU
//! has (runtime dispatch through `pulp`).

use faer::Mat;
use rayon::prelude::*;

use crate::block_view::BlockView;

/// From this N on, every block goes through [`symmetric_products`]: faer's product with a
/// thin right-hand side read K at about 3 GB/s at N = 10,242 (against 40 GB/s for a plain
/// stream of the same bytes), the column-by-column pass here reads half of K, contiguously.
pub(crate) const STREAMING_MIN_N: usize = 4096;

/// Columns per faer product in [`z_matrix_products`].
const MATVEC_COLUMNS: usize = 3;

/// `(K X, |K| |X|)` for a block with no positive off-diagonal entry, in the layout of
/// [`symmetric_products`]: one matrix product with 2 m columns.
pub(crate) fn z_matrix_products(k: &Mat<f64>, xs: &[&[f64]]) -> Vec<f64> {
    let n = k.nrows();
    let m = xs.len();
    let mut rhs = vec![0.0; 2 * m * n];
    for (c, x) in xs.iter().enumerate() {
        rhs[c * n..(c + 1) * n].copy_from_slice(x);
        for (a, v) in rhs[(m + c) * n..(m + c + 1) * n].iter_mut().zip(x.iter()) {
            *a = v.abs();
        }
    }
    let mut out = vec![0.0; 2 * m * n];
    let par = crate::parallel::stream_par(n * n * 8);
    // faer multiplies by up to MATVEC_COLUMNS columns at the speed of reading K (a
    // matrix-vector kernel); with more columns it packs K for its GEMM kernel, which for
    // a thin right-hand side is slower than a second pass.
    for (o, r) in out.chunks_mut(MATVEC_COLUMNS * n).zip(rhs.chunks(MATVEC_COLUMNS * n)) {
        let cols = r.len() / n;
        faer::linalg::matmul::matmul(
            faer::MatMut::from_column_major_slice_mut(o, n, cols),
            faer::Accum::Replace,
            k.as_ref(),
            faer::MatRef::from_column_major_slice(r, n, cols),
            1.0,
            par,
        );
    }
    for (o, a) in out[m * n..].chunks_exact_mut(n).zip(rhs[m * n..].chunks_exact(n)) {
        for (i, (oi, ai)) in o.iter_mut().zip(a).enumerate() {
            *oi = 2.0 * k[(i, i)] * ai - *oi;
        }
    }
    out
}

/// `(K X, |K| |X|)` for the vectors `xs` (each of length n) and a symmetric block `k`
/// (only one triangle is read: the lower of a full block, the strict upper and the kept
/// diagonal of one factored in place): returns `2 m n` values, `K x_c` at
/// `[c n, (c + 1) n)` and `|K| |x_c|` at `[(m + c) n, (m + c + 1) n)`.
pub(crate) fn symmetric_products(k: BlockView<'_>, xs: &[&[f64]]) -> Vec<f64> {
    let n = match k {
        BlockView::Full(k) | BlockView::Upper { upper: k, .. } => k.nrows(),
    };
    let m = xs.len();
    // One part per MiB of the triangle read, at most the compute threads.
    let parts = crate::parallel::stream_threads(n * n * 4);
    // Column ranges of equal triangle area: column j holds n - j entries of the lower
    // triangle, j of the strict upper one.
    let upper = matches!(k, BlockView::Upper { .. });
    let bound = |t: usize| -> usize {
        let share = t as f64 / parts as f64;
        let f = if upper { share.sqrt() } else { 1.0 - (1.0 - share).max(0.0).sqrt() };
        if t == parts { n } else { ((n as f64 * f) as usize).min(n) }
    };
    let run = |t: usize| -> Vec<f64> {
        let mut acc = vec![0.0; 2 * m * n];
        pulp::Arch::new().dispatch(Columns { k, xs, range: bound(t)..bound(t + 1), acc: &mut acc });
        acc
    };
    if parts == 1 {
        return run(0);
    }
    (0..parts)
        .into_par_iter()
        .map(run)
        .reduce_with(|mut a, b| {
            a.iter_mut().zip(&b).for_each(|(x, y)| *x += y);
            a
        })
        .unwrap_or_else(|| vec![0.0; 2 * m * n])
}

/// The columns `range` of the stored triangle, accumulated into `acc`.
struct Columns<'a> {
    k: BlockView<'a>,
    xs: &'a [&'a [f64]],
    range: std::ops::Range<usize>,
    acc: &'a mut [f64],
}

impl pulp::WithSimd for Columns<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, simd: S) -> Self::Output {
        let (storage, diagonal) = match self.k {
            BlockView::Full(k) => (k, None),
            BlockView::Upper { upper, diagonal } => (upper, Some(diagonal)),
        };
        let n = storage.nrows();
        let m = self.xs.len();
        let (ys, zs) = self.acc.split_at_mut(m * n);
        let kjj = |j: usize| diagonal.map_or_else(|| storage[(j, j)], |d| d[j]);
        let mut j = self.range.start;
        while j < self.range.end {
            let (c0, pair) = (storage.col_as_slice(j), j + 1 < self.range.end);
            // The rows that hold K: below the diagonal (a full block's lower triangle), or
            // above it (a block factored in place).
            let (rows, extra) = match (diagonal.is_some(), pair) {
                (false, false) => (j + 1..n, None),
                (true, false) => (0..j, None),
                // Both columns' common rows; the one entry only the longer column has.
                (false, true) => ((j + 2).min(n)..n, Some((j + 1, j, c0[j + 1]))),
                (true, true) => (0..j, Some((j, j + 1, storage.col_as_slice(j + 1)[j]))),
            };
            for (c, x) in self.xs.iter().enumerate() {
                let y = &mut ys[c * n..(c + 1) * n];
                let z = &mut zs[c * n..(c + 1) * n];
                let (xr, yr, zr) = (&x[rows.clone()], &mut y[rows.clone()], &mut z[rows.clone()]);
                if pair {
                    let c1 = storage.col_as_slice(j + 1);
                    let [(d0, e0), (d1, e1)] =
                        axpy_dot2(simd, [&c0[rows.clone()], &c1[rows.clone()]], xr, [x[j], x[j + 1]], yr, zr);
                    y[j] += d0;
                    z[j] += e0;
                    y[j + 1] += d1;
                    z[j + 1] += e1;
                } else {
                    let (d, e) = axpy_dot(simd, &c0[rows.clone()], xr, x[j], yr, zr);
                    y[j] += d;
                    z[j] += e;
                }
                if let Some((r, q, a)) = extra {
                    y[r] += a * x[q];
                    z[r] += a.abs() * x[q].abs();
                    y[q] += a * x[r];
                    z[q] += a.abs() * x[r].abs();
                }
                for i in j..if pair { j + 2 } else { j + 1 } {
                    y[i] += kjj(i) * x[i];
                    z[i] += kjj(i).abs() * x[i].abs();
                }
            }
            j += if pair { 2 } else { 1 };
        }
    }
}

/// [`axpy_dot`] for two columns `a` at once over the same rows: `y += a[0] xj[0] + a[1]
/// xj[1]` (and `z` with absolute values) with one load and one store of `y` and `z` for
/// both, and each column's `(a . x, |a| . |x|)`. Loading and storing the accumulators is
/// what bounds the one-column loop.
#[inline(always)]
fn axpy_dot2<S: pulp::Simd>(
    simd: S,
    a: [&[f64]; 2],
    x: &[f64],
    xj: [f64; 2],
    y: &mut [f64],
    z: &mut [f64],
) -> [(f64, f64); 2] {
    let len = x.len();
    let (a0, a1) = (&a[0][..len], &a[1][..len]);
    let (y, z) = (&mut y[..len], &mut z[..len]);
    let (h0, t0) = S::as_simd_f64s(a0);
    let (h1, t1) = S::as_simd_f64s(a1);
    let (xh, xt) = S::as_simd_f64s(x);
    let (yh, yt) = S::as_mut_simd_f64s(y);
    let (zh, zt) = S::as_mut_simd_f64s(z);
    let (vx0, vx1) = (simd.splat_f64s(xj[0]), simd.splat_f64s(xj[1]));
    let (va0, va1) = (simd.splat_f64s(xj[0].abs()), simd.splat_f64s(xj[1].abs()));
    let zero = simd.splat_f64s(0.0);
    let (mut d0, mut d1, mut e0, mut e1) = (zero, zero, zero, zero);
    for ((((p0, p1), xv), yv), zv) in h0.iter().zip(h1).zip(xh).zip(yh.iter_mut()).zip(zh.iter_mut()) {
        let (q0, q1, ax) = (simd.abs_f64s(*p0), simd.abs_f64s(*p1), simd.abs_f64s(*xv));
        *yv = simd.mul_add_e_f64s(*p1, vx1, simd.mul_add_e_f64s(*p0, vx0, *yv));
        *zv = simd.mul_add_e_f64s(q1, va1, simd.mul_add_e_f64s(q0, va0, *zv));
        d0 = simd.mul_add_e_f64s(*p0, *xv, d0);
        d1 = simd.mul_add_e_f64s(*p1, *xv, d1);
        e0 = simd.mul_add_e_f64s(q0, ax, e0);
        e1 = simd.mul_add_e_f64s(q1, ax, e1);
    }
    let mut out = [
        (simd.reduce_sum_f64s(d0), simd.reduce_sum_f64s(e0)),
        (simd.reduce_sum_f64s(d1), simd.reduce_sum_f64s(e1)),
    ];
    for ((((p0, p1), xv), yv), zv) in t0.iter().zip(t1).zip(xt).zip(yt.iter_mut()).zip(zt.iter_mut()) {
        *yv += p0 * xj[0] + p1 * xj[1];
        *zv += p0.abs() * xj[0].abs() + p1.abs() * xj[1].abs();
        out[0].0 += p0 * xv;
        out[0].1 += p0.abs() * xv.abs();
        out[1].0 += p1 * xv;
        out[1].1 += p1.abs() * xv.abs();
    }
    out
}

/// `y += a xj`, `z += |a| |xj|` and returns `(a . x, |a| . |x|)`, in the SIMD registers
/// of `simd` (two accumulators per sum: the dependency chains of the fused multiply-adds
/// overlap). Written with pulp's vector types: the same loop left to the autovectorizer
/// ran at the speed of scalar code (119 against 113 ms for the triangle at N = 10,242;
/// 70 ms here).
#[inline(always)]
fn axpy_dot<S: pulp::Simd>(
    simd: S,
    a: &[f64],
    x: &[f64],
    xj: f64,
    y: &mut [f64],
    z: &mut [f64],
) -> (f64, f64) {
    let len = a.len();
    let (x, y, z) = (&x[..len], &mut y[..len], &mut z[..len]);
    let (a_h, a_t) = S::as_simd_f64s(a);
    let (x_h, x_t) = S::as_simd_f64s(x);
    let (y_h, y_t) = S::as_mut_simd_f64s(y);
    let (z_h, z_t) = S::as_mut_simd_f64s(z);
    let (vx, vax) = (simd.splat_f64s(xj), simd.splat_f64s(xj.abs()));
    let zero = simd.splat_f64s(0.0);
    let mut dots = [zero; 2];
    let mut adots = [zero; 2];
    for (k, (((a, x), y), z)) in a_h.iter().zip(x_h).zip(y_h.iter_mut()).zip(z_h.iter_mut()).enumerate() {
        let aa = simd.abs_f64s(*a);
        *y = simd.mul_add_e_f64s(*a, vx, *y);
        *z = simd.mul_add_e_f64s(aa, vax, *z);
        dots[k & 1] = simd.mul_add_e_f64s(*a, *x, dots[k & 1]);
        adots[k & 1] = simd.mul_add_e_f64s(aa, simd.abs_f64s(*x), adots[k & 1]);
    }
    let mut dot = simd.reduce_sum_f64s(simd.add_f64s(dots[0], dots[1]));
    let mut adot = simd.reduce_sum_f64s(simd.add_f64s(adots[0], adots[1]));
    for (((a, x), y), z) in a_t.iter().zip(x_t).zip(y_t.iter_mut()).zip(z_t.iter_mut()) {
        *y += a * xj;
        *z += a.abs() * xj.abs();
        dot += a * x;
        adot += a.abs() * x.abs();
    }
    (dot, adot)
}
