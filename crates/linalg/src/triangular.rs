//! `L L' X = B` for a few right-hand sides, split over the factor's rows.
//!
//! With a handful of right-hand sides a triangular solve reads each entry of L once and
//! does two flops with it: it runs at the speed of memory. faer's parallel triangular
//! solve recurses on the triangle and parallelizes its small products; on 16 cores it
//! took 2.4 times as long as on 2 (N = 10,242, one right-hand side). Here L is taken in
//! blocks of [`BLOCK`] columns: the block's triangle is solved on one thread, and the
//! rectangle below it (all the rest of the work) is split into row ranges, one task per
//! [`MIN_TASK_BYTES`](crate::parallel::MIN_TASK_BYTES) of it, at most the threads allowed
//! ([`stream_tasks`]). Forward, each range updates its own rows (`y_R -= L_RB x_B`);
//! backward, each range adds its share of `L_RB' x_R` and the shares are summed.

use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::{solve_lower_triangular_in_place, solve_upper_triangular_in_place};
use faer::{Accum, Mat, MatMut, MatRef, Par};
use rayon::prelude::*;

use crate::parallel::stream_tasks;

/// Columns of L per block: its triangle (256 KiB in f64) stays in cache while solved.
pub(crate) const BLOCK: usize = 256;

/// Up to this many right-hand sides the solve is memory-bound and goes through
/// [`llt_solve_in_place`]; with more, faer's blocked solve (matrix products) is faster.
pub(crate) const MAX_STREAM_RHS: usize = 8;

/// The scalars of the factors (f64, and f32 in mixed precision).
pub(crate) trait Scalar:
    faer::traits::RealField + Copy + Send + Sync + std::ops::AddAssign + std::ops::SubAssign
{
    /// 1.
    const ONE: Self;
    /// -1.
    const MINUS_ONE: Self;
}

impl Scalar for f64 {
    const ONE: Self = 1.0;
    const MINUS_ONE: Self = -1.0;
}

impl Scalar for f32 {
    const ONE: Self = 1.0;
    const MINUS_ONE: Self = -1.0;
}

/// Solves `L L' X = B` in place for the columns of `b` (n x k), with `l` lower triangular
/// (only its lower triangle is read) and at most `threads` tasks per block.
pub(crate) fn llt_solve_in_place<T: Scalar>(l: MatRef<'_, T>, mut b: MatMut<'_, T>, threads: usize) {
    let n = l.nrows();
    let mut j0 = 0;
    while j0 < n {
        let j1 = (j0 + BLOCK).min(n);
        let (top, below) = b.as_mut().split_at_row_mut(j1);
        let mut x = top.subrows_mut(j0, j1 - j0);
        solve_lower_triangular_in_place(l.submatrix(j0, j0, j1 - j0, j1 - j0), x.as_mut(), Par::Seq);
        forward_update(l.submatrix(j1, j0, n - j1, j1 - j0), x.as_ref(), below, threads);
        j0 = j1;
    }
    let mut j1 = n;
    while j1 > 0 {
        let j0 = j1 - ((j1 - 1) % BLOCK + 1);
        let (top, below) = b.as_mut().split_at_row_mut(j1);
        let mut x = top.subrows_mut(j0, j1 - j0);
        backward_update(l.submatrix(j1, j0, n - j1, j1 - j0), below.as_ref(), x.as_mut(), threads);
        solve_upper_triangular_in_place(l.submatrix(j0, j0, j1 - j0, j1 - j0).transpose(), x, Par::Seq);
        j1 = j0;
    }
}

/// Row ranges of a `rows` x `cols` rectangle of `T`, one per task.
fn row_ranges<T>(rows: usize, cols: usize, threads: usize) -> Vec<std::ops::Range<usize>> {
    let tasks = stream_tasks(rows * cols * std::mem::size_of::<T>(), threads).min(rows.max(1));
    (0..tasks).map(|t| rows * t / tasks..rows * (t + 1) / tasks).collect()
}

/// `y -= panel x`, the rows of `y` split over tasks.
fn forward_update<T: Scalar>(panel: MatRef<'_, T>, x: MatRef<'_, T>, y: MatMut<'_, T>, threads: usize) {
    let ranges = row_ranges::<T>(panel.nrows(), panel.ncols(), threads);
    if ranges.len() <= 1 {
        matmul(y, Accum::Add, panel, x, T::MINUS_ONE, Par::Seq);
        return;
    }
    let mut parts = Vec::with_capacity(ranges.len());
    let mut rest = y;
    for r in ranges.iter().rev() {
        let (head, tail) = rest.split_at_row_mut(r.start);
        parts.push((r.clone(), tail));
        rest = head;
    }
    parts.into_par_iter().for_each(|(r, part)| {
        matmul(part, Accum::Add, panel.subrows(r.start, r.len()), x, T::MINUS_ONE, Par::Seq);
    });
}

/// `x -= panel' y`, the rows of `panel` and `y` split over tasks and their shares summed.
fn backward_update<T: Scalar>(panel: MatRef<'_, T>, y: MatRef<'_, T>, mut x: MatMut<'_, T>, threads: usize) {
    let ranges = row_ranges::<T>(panel.nrows(), panel.ncols(), threads);
    if ranges.len() <= 1 {
        matmul(x, Accum::Add, panel.transpose(), y, T::MINUS_ONE, Par::Seq);
        return;
    }
    let (m, k) = (x.nrows(), x.ncols());
    let share = |r: &std::ops::Range<usize>| {
        let mut s = Mat::<T>::zeros(m, k);
        let rows = panel.subrows(r.start, r.len());
        matmul(s.as_mut(), Accum::Replace, rows.transpose(), y.subrows(r.start, r.len()), T::ONE, Par::Seq);
        s
    };
    let sum = ranges.par_iter().map(share).reduce_with(|mut a, b| {
        for j in 0..k {
            for i in 0..m {
                a[(i, j)] += b[(i, j)];
            }
        }
        a
    });
    if let Some(sum) = sum {
        for j in 0..k {
            for i in 0..m {
                x[(i, j)] -= sum[(i, j)];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A random lower-triangular factor with a dominant diagonal.
    fn factor(n: usize) -> Mat<f64> {
        let mut s = 12345u64;
        let mut next = move || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        Mat::from_fn(n, n, |i, j| match i.cmp(&j) {
            std::cmp::Ordering::Less => 7.0, // above the diagonal: must never be read
            std::cmp::Ordering::Equal => 2.0 + next().abs(),
            std::cmp::Ordering::Greater => next() / (n as f64).sqrt(),
        })
    }

    /// Against faer's own sequential triangular solves, for sizes around the block and
    /// every task count: the row split changes only the order of the sums.
    #[test]
    fn row_split_solve_matches_faers_solve() {
        for n in [1, 5, BLOCK - 1, BLOCK, BLOCK + 1, 3 * BLOCK + 17, 1500] {
            let l = factor(n);
            let b = Mat::from_fn(n, 3, |i, j| ((i * 7 + j * 13) % 11) as f64 - 5.0);
            let mut want = b.clone();
            solve_lower_triangular_in_place(l.as_ref(), want.as_mut(), Par::Seq);
            solve_upper_triangular_in_place(l.as_ref().transpose(), want.as_mut(), Par::Seq);
            let scale = want.norm_max();
            let pool = rayon::ThreadPoolBuilder::new().num_threads(4).build().expect("pool");
            for threads in [1, 2, 4] {
                let mut got = b.clone();
                pool.install(|| llt_solve_in_place(l.as_ref(), got.as_mut(), threads));
                let err = (&got - &want).norm_max();
                assert!(err <= 1e-12 * scale, "n = {n}, threads = {threads}: error {err:e} of {scale:e}");
            }
        }
    }

    /// The thread count of a one-right-hand-side solve follows the factor's size and
    /// blocking (one task per MiB of the panel below a block), not the threads allowed.
    #[test]
    fn tasks_per_block_follow_the_factor_not_the_cores() {
        // N = 1,000: the largest panel, 744 x 256 f64, is 1.45 MiB: one task on 2 or 64 threads.
        assert_eq!(row_ranges::<f64>(1000 - BLOCK, BLOCK, 2).len(), 1);
        assert_eq!(row_ranges::<f64>(1000 - BLOCK, BLOCK, 64).len(), 1);
        // N = 10,242: 9,986 x 256 f64 is 19.5 MiB: 19 tasks where 64 threads are allowed,
        // 2 where 2 are; in f32 half the bytes, 9 tasks.
        assert_eq!(row_ranges::<f64>(10_242 - BLOCK, BLOCK, 64).len(), 19);
        assert_eq!(row_ranges::<f64>(10_242 - BLOCK, BLOCK, 2).len(), 2);
        assert_eq!(row_ranges::<f32>(10_242 - BLOCK, BLOCK, 64).len(), 9);
        // The last panels of any factor are small: one task.
        assert_eq!(row_ranges::<f64>(100, BLOCK, 64).len(), 1);
    }

    #[test]
    fn row_ranges_cover_the_rows_once() {
        for (rows, threads) in [(0, 4), (1, 4), (10, 1), (5000, 3), (100_000, 16)] {
            let r = row_ranges::<f64>(rows, BLOCK, threads);
            assert!(r.len() <= threads.max(1));
            assert_eq!(r.first().map(|r| r.start), Some(0));
            assert_eq!(r.last().map(|r| r.end), Some(rows));
            assert!(r.windows(2).all(|w| w[0].end == w[1].start));
        }
    }
}
