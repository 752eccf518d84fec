//! Sparse Cholesky with a kept symbolic analysis: every solve is checked against a dense
//! Cholesky solve of the same matrix (faer's dense `llt`, an independent code path) and by
//! its residual computed from the dense matrix.

use std::sync::Arc;

use faer::linalg::solvers::Solve;
use faer::sparse::{SparseColMat, Triplet};
use faer::{Mat, Side};
use fibfluid_linalg::{LinalgError, SparseCholesky, SparseOrdering, SparseSymbolic};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Side of the grid whose 5-point Laplacian (random positive edge weights, plus a positive
/// diagonal) is the test matrix.
pub(crate) const SIDE: usize = 12;

/// The lower-triangle entries `(row, col)` of the grid matrix, in a fixed order.
pub(crate) fn grid_pattern() -> Vec<(usize, usize)> {
    let id = |i: usize, j: usize| i * SIDE + j;
    let mut entries = Vec::new();
    for i in 0..SIDE {
        for j in 0..SIDE {
            entries.push((id(i, j), id(i, j)));
            if i + 1 < SIDE {
                entries.push((id(i + 1, j), id(i, j)));
            }
            if j + 1 < SIDE {
                entries.push((id(i, j + 1), id(i, j)));
            }
        }
    }
    entries
}

/// A symmetric positive definite matrix on `pattern` (diagonally dominant: random
/// negative off-diagonal weights, diagonal the row sum of their magnitudes plus a random
/// positive shift), as its sparse lower triangle and its dense full form.
pub(crate) fn spd_on(pattern: &[(usize, usize)], seed: u64) -> (SparseColMat<usize, f64>, Mat<f64>) {
    let n = SIDE * SIDE;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut dense = Mat::<f64>::zeros(n, n);
    for &(r, c) in pattern.iter().filter(|(r, c)| r != c) {
        let w = rng.random_range(0.5..2.0);
        dense[(r, c)] = -w;
        dense[(c, r)] = -w;
        dense[(r, r)] += w;
        dense[(c, c)] += w;
    }
    for i in 0..n {
        dense[(i, i)] += rng.random_range(0.01..1.0);
    }
    (lower_of(pattern, &dense), dense)
}

fn lower_of(pattern: &[(usize, usize)], dense: &Mat<f64>) -> SparseColMat<usize, f64> {
    let n = dense.nrows();
    let triplets: Vec<Triplet<usize, usize, f64>> =
        pattern.iter().map(|&(r, c)| Triplet::new(r, c, dense[(r, c)])).collect();
    SparseColMat::try_new_from_triplets(n, n, &triplets).expect("valid triplets")
}

pub(crate) fn rhs(n: usize, cols: usize, seed: u64) -> Mat<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    Mat::from_fn(n, cols, |_, _| rng.random_range(-1.0..1.0))
}

/// Solves with `factor` and checks the result against the dense Cholesky solve of `dense`
/// and by its normwise residual.
fn check_solve(factor: &SparseCholesky, dense: &Mat<f64>, b: &Mat<f64>) {
    let mut x = b.clone();
    factor.solve_in_place(x.as_mut());
    let reference = dense.llt(Side::Lower).expect("the test matrix is SPD").solve(b);
    let n = dense.nrows();
    let r = dense * &x - b;
    for j in 0..b.ncols() {
        let (mut rmax, mut xmax, mut bmax, mut diff, mut refmax) =
            (0.0_f64, 0.0_f64, 0.0_f64, 0.0_f64, 0.0_f64);
        for i in 0..n {
            rmax = rmax.max(r[(i, j)].abs());
            xmax = xmax.max(x[(i, j)].abs());
            bmax = bmax.max(b[(i, j)].abs());
            diff = diff.max((x[(i, j)] - reference[(i, j)]).abs());
            refmax = refmax.max(reference[(i, j)].abs());
        }
        let anorm = (0..n).map(|i| (0..n).map(|k| dense[(i, k)].abs()).sum::<f64>()).fold(0.0, f64::max);
        let residual = rmax / (anorm * xmax + bmax);
        assert!(residual < 1e3 * n as f64 * f64::EPSILON, "column {j}: relative residual {residual:e}");
        assert!(
            diff <= 1e-9 * refmax,
            "column {j}: differs from the dense solve by {diff:e} (max {refmax:e})"
        );
    }
}

fn orderings(n: usize) -> Vec<(Vec<usize>, Vec<usize>)> {
    // Reverse order as a custom permutation (the identity's mirror: a real ordering to honour).
    let fwd: Vec<usize> = (0..n).rev().collect();
    let mut inv = vec![0; n];
    for (k, &c) in fwd.iter().enumerate() {
        inv[c] = k;
    }
    vec![(fwd, inv)]
}

#[test]
fn refactorization_on_the_same_pattern_solves_the_new_matrix() {
    let pattern = grid_pattern();
    let n = SIDE * SIDE;
    let (k1, d1) = spd_on(&pattern, 1);
    let (k2, d2) = spd_on(&pattern, 2);
    let b = rhs(n, 3, 3);
    let custom = orderings(n);
    let mut cases = vec![SparseOrdering::Amd];
    cases.extend(custom.iter().map(|(fwd, inv)| SparseOrdering::Custom { fwd, inv }));
    for ordering in cases {
        let symbolic = Arc::new(SparseSymbolic::new(k1.symbolic(), ordering).expect("analysis"));
        assert_eq!(symbolic.dim(), n);
        let mut factor = SparseCholesky::factor(&symbolic, k1.as_ref()).expect("first factorization");
        assert!(factor.nonzeros() >= pattern.len(), "the factor holds at least K's lower triangle");
        check_solve(&factor, &d1, &b);
        factor.refactor(k2.as_ref()).expect("refactorization");
        check_solve(&factor, &d2, &b);
        // The analysis is shared: a second factor on it solves the first matrix still.
        let other = SparseCholesky::factor(&symbolic, k1.as_ref()).expect("second factor");
        assert!(Arc::ptr_eq(other.symbolic(), factor.symbolic()));
        check_solve(&other, &d1, &b);
    }
}

#[test]
fn a_different_pattern_is_refused() {
    let pattern = grid_pattern();
    let n = SIDE * SIDE;
    let (k1, _) = spd_on(&pattern, 4);
    let mut factor = SparseCholesky::new(k1.as_ref(), SparseOrdering::Amd).expect("factorization");
    // One more off-diagonal entry (a diagonal neighbour of the grid).
    let mut wider = pattern.clone();
    wider.push((SIDE + 1, 0));
    let (k2, _) = spd_on(&wider, 5);
    let err = factor.refactor(k2.as_ref()).expect_err("another pattern");
    assert!(matches!(err, LinalgError::SparsePatternMismatch { .. }), "{err:?}");
    // Another size.
    let small: Vec<(usize, usize)> =
        pattern.iter().copied().filter(|&(r, c)| r < n - 1 && c < n - 1).collect();
    let mut dense = Mat::<f64>::identity(n - 1, n - 1);
    dense[(1, 0)] = 0.1;
    let err = factor.refactor(lower_of(&small, &dense).as_ref()).expect_err("another size");
    assert_eq!(err, LinalgError::SparsePatternMismatch { what: "size" });
}

#[test]
fn a_matrix_that_is_not_positive_definite_is_a_typed_error() {
    let pattern = grid_pattern();
    let n = SIDE * SIDE;
    let (k1, d1) = spd_on(&pattern, 6);
    let mut bad = d1.clone();
    bad[(n / 2, n / 2)] = -1.0;
    let err = SparseCholesky::new(lower_of(&pattern, &bad).as_ref(), SparseOrdering::Amd)
        .expect_err("a negative diagonal entry");
    assert!(matches!(err, LinalgError::SparseNotPositiveDefinite { .. }), "{err:?}");
    // The same on a refactorization, which then recovers with SPD values.
    let mut factor = SparseCholesky::new(k1.as_ref(), SparseOrdering::Amd).expect("factorization");
    let err = factor.refactor(lower_of(&pattern, &bad).as_ref()).expect_err("refactor of a non-SPD matrix");
    assert!(matches!(err, LinalgError::SparseNotPositiveDefinite { .. }), "{err:?}");
    factor.refactor(k1.as_ref()).expect("SPD values again");
    check_solve(&factor, &d1, &rhs(n, 1, 7));
}
