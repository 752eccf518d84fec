//! A Cholesky factorization that writes `L` over the lower triangle of a symmetric matrix
//! and never touches its strict upper triangle, so one N x N buffer holds both the factor
//! and the matrix it factors (with the diagonal of the matrix saved beside it).
//!
//! faer's `cholesky_in_place` uses the strict upper triangle as scratch (it keeps
//! `L_10 D_0` there), so it cannot be used on the whole buffer. This is the right-looking
//! blocked algorithm built from faer's kernels, each of which stays in its triangle:
//!
//! ```text
//! for each diagonal block j (BLOCK columns):
//!     L_jj      = chol(A_jj)                 faer, on a BLOCK x BLOCK copy
//!     L_ij      = A_ij L_jj^-T               faer triangular solve, rows below j
//!     A_trail  -= L_ij L_ij^T                faer product, lower triangle of the trailing block only
//! ```
//!
//! The flops are those of any Cholesky, `N^3 / 3`, almost all in the trailing products.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{LltError, cholesky_in_place, cholesky_in_place_scratch};
use faer::linalg::matmul::triangular::{BlockStructure, matmul};
use faer::linalg::triangular_solve::solve_lower_triangular_in_place;
use faer::prelude::{Reborrow, ReborrowMut};
use faer::{Accum, Mat, MatMut, Par};

/// Columns per diagonal block: large enough for the trailing products to run at GEMM
/// speed, small enough that the diagonal factorizations (sequential) stay cheap.
const BLOCK: usize = 256;

/// Factors the symmetric positive definite matrix whose lower triangle (diagonal included)
/// is in `a`: on success the lower triangle holds `L` with `A = L L^T`, and the strict upper
/// triangle is exactly as it was. On failure returns the index of the first pivot that is
/// not positive; the lower triangle is then partly overwritten.
pub(crate) fn cholesky_keeping_upper(mut a: MatMut<'_, f64>, par: Par) -> Result<(), usize> {
    let n = a.nrows();
    assert_eq!(a.ncols(), n, "a square matrix");
    let mut diag = Mat::<f64>::zeros(BLOCK.min(n), BLOCK.min(n));
    let mut mem =
        MemBuffer::new(cholesky_in_place_scratch::<f64>(BLOCK.min(n), Par::Seq, Default::default()));
    let mut j = 0;
    while j < n {
        let b = BLOCK.min(n - j);
        let mut d = diag.as_mut().submatrix_mut(0, 0, b, b);
        for c in 0..b {
            for r in c..b {
                d[(r, c)] = a[(j + r, j + c)];
            }
        }
        cholesky_in_place(
            d.rb_mut(),
            Default::default(),
            Par::Seq,
            MemStack::new(&mut mem),
            Default::default(),
        )
        .map_err(|LltError::NonPositivePivot { index }| j + index)?;
        for c in 0..b {
            for r in c..b {
                a[(j + r, j + c)] = d[(r, c)];
            }
        }
        if j + b < n {
            let (panel, trailing) = a.rb_mut().get_mut(j + b.., j..).split_at_col_mut(b);
            let mut panel = panel;
            // L_ij L_jj^T = A_ij  <=>  L_jj L_ij^T = A_ij^T.
            solve_lower_triangular_in_place(d.rb(), panel.rb_mut().transpose_mut(), par);
            let trailing = trailing.subcols_mut(0, n - j - b);
            matmul(
                trailing,
                BlockStructure::TriangularLower,
                Accum::Add,
                panel.rb(),
                BlockStructure::Rectangular,
                panel.rb().transpose(),
                BlockStructure::Rectangular,
                -1.0,
                par,
            );
        }
        j += b;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A symmetric positive definite matrix with a known spread of scales.
    fn spd(n: usize) -> Mat<f64> {
        let g = Mat::<f64>::from_fn(n, n, |i, j| (((i * 7 + j * 13) % 17) as f64 - 8.0) / 17.0);
        let mut a = &g * g.transpose();
        for i in 0..n {
            a[(i, i)] += n as f64 * 0.1;
        }
        a
    }

    /// Against faer's own Cholesky (an independent implementation), with NaN in the strict
    /// upper triangle: a single read of it would spread NaN into L, a write would change it.
    #[test]
    fn factors_like_faer_and_leaves_the_upper_triangle_alone() {
        for n in [1, 5, BLOCK - 1, BLOCK, BLOCK + 1, 2 * BLOCK + 37] {
            let a = spd(n);
            let expected = a.llt(faer::Side::Lower).expect("spd").L().to_owned();
            let mut packed = a.clone();
            for j in 0..n {
                for i in 0..j {
                    packed[(i, j)] = f64::NAN;
                }
            }
            for par in [Par::Seq, Par::rayon(2)] {
                let mut m = packed.clone();
                cholesky_keeping_upper(m.as_mut(), par).expect("spd");
                let scale = expected.norm_max();
                for j in 0..n {
                    for i in 0..j {
                        assert!(m[(i, j)].is_nan(), "n = {n}: upper ({i}, {j}) was written");
                    }
                    for i in j..n {
                        let diff = (m[(i, j)] - expected[(i, j)]).abs();
                        assert!(diff <= 1e-12 * scale, "n = {n}: L({i}, {j}) off by {diff}");
                    }
                }
            }
        }
    }

    /// The structured backend solves with faer's triangular solves on the packed block:
    /// they must read only the factor's triangle (NaN in the other would spread).
    #[test]
    fn triangular_solves_read_only_the_factors_triangle() {
        use faer::linalg::triangular_solve::solve_upper_triangular_in_place;
        let n = BLOCK + 37;
        let a = spd(n);
        let mut m = a.clone();
        for j in 0..n {
            for i in 0..j {
                m[(i, j)] = f64::NAN;
            }
        }
        cholesky_keeping_upper(m.as_mut(), Par::Seq).expect("spd");
        let b = Mat::<f64>::from_fn(n, 3, |i, j| ((i + 3 * j) % 11) as f64 - 5.0);
        for par in [Par::Seq, Par::rayon(2)] {
            let mut x = b.clone();
            solve_lower_triangular_in_place(m.as_ref(), x.as_mut(), par);
            solve_upper_triangular_in_place(m.as_ref().transpose(), x.as_mut(), par);
            let r = &a * &x - &b;
            assert!(r.norm_max() <= 1e-10 * b.norm_max(), "residual {}", r.norm_max());
        }
    }

    #[test]
    fn names_the_first_pivot_that_is_not_positive() {
        let n = BLOCK + 20;
        let mut a = spd(n);
        // Make the leading (k+1) x (k+1) block indefinite: row/column k copies row/column 3.
        let k = BLOCK + 5;
        for i in 0..n {
            a[(k, i)] = a[(3, i)];
            a[(i, k)] = a[(i, 3)];
        }
        // The pivot of row k is then a[(k, k)] - a[(3, 3)] = -1.
        a[(k, k)] = a[(3, 3)] - 1.0;
        let e = cholesky_keeping_upper(a.as_mut(), Par::Seq).expect_err("singular");
        assert_eq!(e, k);
    }
}
