//! The capacitance update (`ComplianceSource`, `RowCapacitance`, `CapacitanceFactor`)
//! against an independent computation: the dense saddle-point system
//! `[A E; E' 0] [x; r] = [b; g]` solved by faer's partial-pivot LU.

use faer::linalg::solvers::Solve;
use faer::{Mat, Side};
use fibfluid_linalg::{
    CapacitanceFactor, ComplianceSource, LinalgError, RowCapacitance, SparseCholesky, SparseOrdering,
    SparseRow,
};

use crate::sparse::{SIDE, grid_pattern, rhs, spd_on};

mod vertex;

/// Constraint rows on the grid's unknowns: a held unknown, a combination of three, a
/// difference of two.
fn rows() -> Vec<Vec<(usize, f64)>> {
    vec![vec![(5, 1.0)], vec![(20, 0.6), (21, -0.8), (40, 0.3)], vec![(70, 1.0), (100, -1.0)]]
}

/// `[x; r]` of the saddle-point system, dense.
fn saddle_point(a: &Mat<f64>, rows: &[Vec<(usize, f64)>], b: &[f64], g: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let (n, k) = (a.nrows(), rows.len());
    let mut m = Mat::<f64>::zeros(n + k, n + k);
    m.as_mut().submatrix_mut(0, 0, n, n).copy_from(a);
    for (j, row) in rows.iter().enumerate() {
        for &(i, c) in row {
            m[(i, n + j)] += c;
            m[(n + j, i)] += c;
        }
    }
    let rhs = Mat::<f64>::from_fn(n + k, 1, |i, _| if i < n { b[i] } else { g[i - n] });
    let sol = m.partial_piv_lu().solve(&rhs);
    ((0..n).map(|i| sol[(i, 0)]).collect(), (0..k).map(|j| sol[(n + j, 0)]).collect())
}

fn max_diff(x: &[f64], y: &[f64]) -> f64 {
    x.iter().zip(y).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max)
}

#[test]
fn the_update_on_a_sparse_factor_solves_the_saddle_point_system() {
    let pattern = grid_pattern();
    let n = SIDE * SIDE;
    let (k_lower, dense) = spd_on(&pattern, 11);
    let factor = SparseCholesky::new(k_lower.as_ref(), SparseOrdering::Amd).expect("factorization");
    let rows = rows();
    let refs: Vec<&SparseRow> = rows.iter().map(Vec::as_slice).collect();
    let columns = factor.compliance_columns(&refs).expect("columns");
    assert_eq!(columns.len(), rows.len());
    let capacitance = RowCapacitance::new(&refs, &columns, 0.0).expect("independent rows");
    let b: Vec<f64> = rhs(n, 1, 12).col_as_slice(0).to_vec();
    let g = [0.3, -0.2, 0.05];
    let mut y = b.clone();
    let mut y_mat = Mat::<f64>::from_fn(n, 1, |i, _| y[i]);
    factor.solve_in_place(y_mat.as_mut());
    y.copy_from_slice(y_mat.col_as_slice(0));
    let r = capacitance.correct(&refs, &columns, &g, &mut y);
    let (x_ref, r_ref) = saddle_point(&dense, &rows, &b, &g);
    let scale = x_ref.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
    assert!(max_diff(&y, &x_ref) <= 1e-10 * scale, "x differs by {:e}", max_diff(&y, &x_ref));
    let rscale = r_ref.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
    assert!(max_diff(&r, &r_ref) <= 1e-10 * rscale, "r differs by {:e}", max_diff(&r, &r_ref));
    // The constraints hold on the corrected solution.
    for (row, gi) in rows.iter().zip(g) {
        let got: f64 = row.iter().map(|&(i, c)| c * y[i]).sum();
        assert!((got - gi).abs() <= 1e-10, "constraint {got} vs {gi}");
    }
}

#[test]
fn dependent_rows_name_the_constraint() {
    let pattern = grid_pattern();
    let (k_lower, _) = spd_on(&pattern, 13);
    let factor = SparseCholesky::new(k_lower.as_ref(), SparseOrdering::Amd).expect("factorization");
    // The third row constrains nothing (its column and its capacitance row are exactly 0):
    // its pivot is 0. (An exactly repeated row leaves a pivot of rounding size, which only
    // a pivot tolerance catches.)
    let rows = [vec![(3, 1.0)], vec![(9, 2.0)], vec![]];
    let refs: Vec<&SparseRow> = rows.iter().map(Vec::as_slice).collect();
    let columns = factor.compliance_columns(&refs).expect("columns");
    let err = RowCapacitance::new(&refs, &columns, 0.0).expect_err("a repeated row");
    assert_eq!(err, LinalgError::CapacitanceNotPositiveDefinite { constraint: 2, constraints: 3 });
}

#[test]
fn the_factor_solves_and_refuses_as_documented() {
    // An SPD 3 x 3 capacitance: the solve against faer's dense LLT.
    let c = Mat::<f64>::from_fn(3, 3, |i, j| if i == j { 4.0 } else { 1.0 / (1 + i + j) as f64 });
    let factor = CapacitanceFactor::new(c.as_ref(), Some(1e-12)).expect("SPD");
    assert_eq!(factor.len(), 3);
    let x = factor.solve(&[1.0, -2.0, 0.5]);
    let reference =
        c.llt(Side::Lower).expect("SPD").solve(Mat::<f64>::from_fn(3, 1, |i, _| [1.0, -2.0, 0.5][i]));
    assert!(max_diff(&x, reference.col_as_slice(0)) < 1e-14);
    // Nearly singular: positive pivots, but the last one below the tolerance.
    let mut near = Mat::<f64>::from_fn(2, 2, |_, _| 1.0);
    near[(1, 1)] = 1.0 + 1e-14;
    CapacitanceFactor::new(near.as_ref(), None).expect("positive pivots without a tolerance");
    let err = CapacitanceFactor::new(near.as_ref(), Some(1e-10)).expect_err("below the tolerance");
    assert_eq!(err, LinalgError::CapacitanceNotPositiveDefinite { constraint: 1, constraints: 2 });
}

/// Three dependent rows over two unknowns whose compliances differ by 1e6 (a strongly
/// penalized direction, as a held tangent with a hold penalty has), and a consistent gap
/// (`C x` for a known `x`, the reference): the ridged solve alone misses it by about
/// `ridge / 1e-6` of the gap; refined twice, to the rounding of `C r` (1e-10).
#[test]
fn refined_multipliers_meet_a_consistent_gap_of_dependent_rows() {
    let rows: Vec<Vec<(usize, f64)>> = vec![vec![(0, 1.0)], vec![(1, 1.0)], vec![(0, 1.0), (1, 1.0)]];
    let compliance = [1.0, 1e-6];
    let column = |r: &Vec<(usize, f64)>| -> Vec<f64> {
        (0..2).map(|i| r.iter().filter(|e| e.0 == i).map(|e| e.1 * compliance[i]).sum()).collect()
    };
    let columns: Vec<Vec<f64>> = rows.iter().map(column).collect();
    assert!(RowCapacitance::new(&rows, &columns, 0.0).is_err(), "the rows are dependent");
    let capacitance = RowCapacitance::new(&rows, &columns, 1e-12).unwrap();
    let c = capacitance.matrix();
    // A large multiplier on the stiff row, as a hold penalty's push: a gap of order 1 along
    // the eigenvalue near 1e-6.
    let x = [0.3, 1e6, -0.2];
    let gap: Vec<f64> = (0..3).map(|i| (0..3).map(|j| c[(i, j)] * x[j]).sum()).collect();
    let scale = gap.iter().fold(0.0_f64, |a, g| a.max(g.abs()));
    let miss = |r: &[f64]| -> f64 {
        let row = |i: usize| ((0..3).map(|j| c[(i, j)] * r[j]).sum::<f64>() - gap[i]).abs();
        (0..3).map(row).fold(0.0, f64::max) / scale
    };
    let plain = miss(&capacitance.multipliers(&gap));
    let refined = miss(&capacitance.refined_multipliers(&gap, 2));
    assert!(plain > 1e-7, "the ridge alone misses by {plain:e}");
    // Rounding floor: eps |C| |r| with multipliers near 1e6, about 1e-10 of the gap.
    assert!(refined < 1e-9 && refined < 1e-3 * plain, "refined: {refined:e} (plain {plain:e})");
}
