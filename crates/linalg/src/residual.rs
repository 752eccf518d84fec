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

use crate::matrix::BlockView;

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
    let par = if n >= 512 { faer::get_global_parallelism() } else { faer::Par::Seq };
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
    let parts = if n >= 512 { rayon::current_num_threads().max(1) } else { 1 };
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
    fn with_simd<S: pulp::Simd>(self, _simd: S) -> Self::Output {
        let (storage, diagonal) = match self.k {
            BlockView::Full(k) => (k, None),
            BlockView::Upper { upper, diagonal } => (upper, Some(diagonal)),
        };
        let n = storage.nrows();
        let m = self.xs.len();
        let (ys, zs) = self.acc.split_at_mut(m * n);
        for j in self.range {
            let col = storage.col_as_slice(j);
            // The rows of column j that hold K: below the diagonal, or above it.
            let (kjj, rows) = match diagonal {
                None => (col[j], j + 1..n),
                Some(d) => (d[j], 0..j),
            };
            let part = &col[rows.clone()];
            for (c, x) in self.xs.iter().enumerate() {
                let xj = x[j];
                let y = &mut ys[c * n..(c + 1) * n];
                let z = &mut zs[c * n..(c + 1) * n];
                let (dot, adot) =
                    axpy_dot(part, &x[rows.clone()], xj, &mut y[rows.clone()], &mut z[rows.clone()]);
                y[j] += kjj * xj + dot;
                z[j] += kjj.abs() * xj.abs() + adot;
            }
        }
    }
}

/// `y += a xj`, `z += |a| |xj|` and returns `(a . x, |a| . |x|)`, eight lanes at a time.
#[inline(always)]
fn axpy_dot(a: &[f64], x: &[f64], xj: f64, y: &mut [f64], z: &mut [f64]) -> (f64, f64) {
    const L: usize = 8;
    let axj = xj.abs();
    let len = a.len();
    let (x, y, z) = (&x[..len], &mut y[..len], &mut z[..len]);
    let (a8, ar) = a.as_chunks::<L>();
    let (x8, xr) = x.as_chunks::<L>();
    let (y8, yr) = y.as_chunks_mut::<L>();
    let (z8, zr) = z.as_chunks_mut::<L>();
    let mut d = [0.0f64; L];
    let mut ad = [0.0f64; L];
    for (((a, x), y), z) in a8.iter().zip(x8).zip(y8.iter_mut()).zip(z8.iter_mut()) {
        for l in 0..L {
            let (av, aa) = (a[l], a[l].abs());
            y[l] += av * xj;
            z[l] += aa * axj;
            d[l] += av * x[l];
            ad[l] += aa * x[l].abs();
        }
    }
    let (mut dot, mut adot) = (d.iter().sum::<f64>(), ad.iter().sum::<f64>());
    for (((a, x), y), z) in ar.iter().zip(xr).zip(yr.iter_mut()).zip(zr.iter_mut()) {
        *y += a * xj;
        *z += a.abs() * axj;
        dot += a * x;
        adot += a.abs() * x.abs();
    }
    (dot, adot)
}
