//! Conformance harness: every backend compiled into this build (`all_backends()`; the
//! `openblas` feature adds `openblas-lu`) solves the same bordered systems, and every result
//! is checked independently of the backend that produced it.
//!
//! Systems: seeded random well-conditioned bordered systems (shared and per-axis blocks,
//! 2 and 3 axes, SPD blocks built as Laplacian + diagonal or as `B B^T + n I`), the paper's
//! Eq. 8 rectangle typed in from the paper, and systems assembled on icospheres (the
//! paper's sphere case) with `fibfluid-assembly`.
//!
//! Tolerances, all growing with the system size `dim`:
//! - [`residual_tol`]: the checked solve refines until its componentwise backward error
//!   `max_i |b - A x|_i / (|A| |x| + |b|)_i` is at most `FactorOptions::target_for(dim)`, the
//!   larger of `DEFAULT_TARGET_RESIDUAL` and `dim * eps` (which also bounds the normwise
//!   `|b - A x|_inf / (|A|_inf |x|_inf + |b|_inf)`); the test recomputes both from the dense
//!   matrix, which adds about `dim * eps` of its own rounding. Bound:
//!   `target_for(dim) + RESIDUAL_C * dim * eps`.
//! - [`agreement_tol`]: a solution with normwise backward error `eta` has forward error at
//!   most about `2 cond eta`; two of them differ by at most twice that. Bound:
//!   `AGREEMENT_C * cond * residual_tol(dim)`, with `cond` the exact 1-norm condition number
//!   computed from an explicit inverse (faer), not the crate's estimator.

use faer::Mat;
use faer::linalg::solvers::DenseSolveCore;
use fibfluid_assembly::{
    AssemblyOptions, Body, ConstraintMethod, Constraints, Loads, Material, PressureScaling, Selector, System,
    assemble, load_vector,
};
use fibfluid_geometry::{FiberSet, TriMesh, icosphere};
use fibfluid_linalg::{
    Backend, Blocks, BorderedMatrix, Choice, FactorOptions, FactorizationExt, LinalgError, LinearSolver,
    LinearSolverExt, Precision, all_backends,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

mod capacitance;
mod sparse;

const EPS: f64 = f64::EPSILON;

/// Rounding of the test's own dense residual evaluation, in units of `dim * eps`.
const RESIDUAL_C: f64 = 4.0;

/// Forward-error factor: 2 (forward vs backward error) times 2 (two solutions).
const AGREEMENT_C: f64 = 4.0;

/// Relative residual every accepted solve must reach, checked independently.
fn residual_tol(dim: usize) -> f64 {
    FactorOptions::default().target_for(dim) + RESIDUAL_C * dim as f64 * EPS
}

/// Largest relative difference `|x - y|_inf / |x|_inf` two backends may show.
fn agreement_tol(dim: usize, cond: f64) -> f64 {
    AGREEMENT_C * cond * residual_tol(dim)
}

fn inf_norm(v: &[f64]) -> f64 {
    v.iter().fold(0.0, |m, x| m.max(x.abs()))
}

/// Induced 1-norm (largest absolute column sum) of a dense matrix.
fn norm1(m: &Mat<f64>) -> f64 {
    (0..m.ncols()).map(|j| (0..m.nrows()).map(|i| m[(i, j)].abs()).sum::<f64>()).fold(0.0, f64::max)
}

/// Induced inf-norm (largest absolute row sum) of a dense matrix.
fn norm_inf(m: &Mat<f64>) -> f64 {
    (0..m.nrows()).map(|i| (0..m.ncols()).map(|j| m[(i, j)].abs()).sum::<f64>()).fold(0.0, f64::max)
}

/// Exact 1-norm condition number `|A|_1 |A^-1|_1` from an explicit inverse (faer LU).
fn cond1(d: &Mat<f64>) -> f64 {
    let inv = d.partial_piv_lu().inverse();
    norm1(d) * norm1(&inv)
}

/// `|b - A x|_inf / (|A|_inf |x|_inf + |b|_inf)` computed from the dense matrix.
fn dense_relative_residual(d: &Mat<f64>, x: &[f64], b: &[f64]) -> f64 {
    let n = d.nrows();
    let mut r = b.to_vec();
    for j in 0..n {
        for i in 0..n {
            r[i] -= d[(i, j)] * x[j];
        }
    }
    inf_norm(&r) / (norm_inf(d) * inf_norm(x) + inf_norm(b))
}

/// `max_i |b - A x|_i / (sum_j |A_ij| |x_j| + |b_i|)`: the componentwise backward error.
fn rowwise_residual(d: &Mat<f64>, x: &[f64], b: &[f64]) -> f64 {
    let n = d.nrows();
    (0..n)
        .map(|i| {
            let (mut r, mut mag) = (b[i], b[i].abs());
            for j in 0..n {
                r -= d[(i, j)] * x[j];
                mag += (d[(i, j)] * x[j]).abs();
            }
            if mag > 0.0 { r.abs() / mag } else { 0.0 }
        })
        .fold(0.0, f64::max)
}

fn relative_difference(x: &[f64], y: &[f64]) -> f64 {
    let diff = x.iter().zip(y).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    diff / inf_norm(x).max(inf_norm(y))
}

/// One system of the harness.
struct Case {
    name: String,
    matrix: BorderedMatrix,
    rhs: Vec<f64>,
}

#[derive(Clone, Copy, Debug)]
enum Spd {
    /// Weighted graph Laplacian of a random graph plus a positive diagonal.
    LaplacianPlusDiagonal,
    /// `B B^T + n I` with B uniform in [-1, 1].
    Gram,
}

/// Weighted graph Laplacian of a random connected graph (a path plus random chords).
fn random_laplacian(rng: &mut ChaCha8Rng, n: usize) -> Mat<f64> {
    let mut k = Mat::<f64>::zeros(n, n);
    for i in 0..n {
        for j in i + 1..n {
            if j == i + 1 || rng.random_bool(0.4) {
                let w = rng.random_range(0.1..2.0);
                k[(i, j)] = -w;
                k[(j, i)] = -w;
                k[(i, i)] += w;
                k[(j, j)] += w;
            }
        }
    }
    k
}

fn random_spd(rng: &mut ChaCha8Rng, n: usize, kind: Spd) -> Mat<f64> {
    match kind {
        Spd::LaplacianPlusDiagonal => {
            let mut k = random_laplacian(rng, n);
            for i in 0..n {
                k[(i, i)] += rng.random_range(0.5..2.0);
            }
            k
        }
        Spd::Gram => {
            let b = Mat::<f64>::from_fn(n, n, |_, _| rng.random_range(-1.0..1.0));
            // Same summation order for (i, j) and (j, i): exactly symmetric.
            Mat::<f64>::from_fn(n, n, |i, j| {
                (0..n).map(|k| b[(i, k)] * b[(j, k)]).sum::<f64>() + if i == j { n as f64 } else { 0.0 }
            })
        }
    }
}

fn random_border(rng: &mut ChaCha8Rng, n: usize, axes: usize) -> Vec<Vec<f64>> {
    (0..axes).map(|_| (0..n).map(|_| rng.random_range(-1.0..1.0)).collect()).collect()
}

fn random_case(seed: u64, n: usize, axes: usize, shared: bool, kind: Spd, scale: f64) -> Case {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let blocks = if shared {
        Blocks::Shared(random_spd(&mut rng, n, kind))
    } else {
        Blocks::PerAxis((0..axes).map(|_| random_spd(&mut rng, n, kind)).collect())
    };
    let border = random_border(&mut rng, n, axes);
    let matrix = BorderedMatrix::new(blocks, border, scale);
    let rhs = (0..matrix.dim()).map(|_| rng.random_range(-1.0..1.0)).collect();
    let name = format!(
        "random(seed {seed}, n {n}, axes {axes}, {}, {kind:?}, scale {scale})",
        if shared { "shared" } else { "per-axis" }
    );
    Case { name, matrix, rhs }
}

fn random_cases() -> Vec<Case> {
    use Spd::*;
    vec![
        random_case(1, 5, 2, true, LaplacianPlusDiagonal, 1.0),
        random_case(2, 5, 2, false, Gram, 1.0),
        random_case(3, 12, 3, true, Gram, 2.5),
        random_case(4, 12, 3, false, LaplacianPlusDiagonal, 0.3),
        random_case(5, 40, 2, false, LaplacianPlusDiagonal, 1.0),
        random_case(6, 40, 3, true, LaplacianPlusDiagonal, 7.0),
        random_case(7, 60, 3, false, Gram, 1.0),
        random_case(8, 60, 2, true, Gram, 0.5),
    ]
}

/// Runs every backend on a case: each solve's residual is checked against the dense
/// matrix, then every pair of backends is compared. Returns (largest residual, largest
/// pairwise difference) and every backend's solution.
fn run_all_backends(case: &Case, cond: f64) -> (f64, f64, Vec<(&'static str, Vec<f64>)>) {
    let dense = case.matrix.to_dense();
    let dim = case.matrix.dim();
    let backends = all_backends();
    assert_eq!(backends.len(), Backend::compiled().len(), "every compiled backend is exercised");
    let mut worst_residual = 0.0f64;
    let mut sols = Vec::new();
    for backend in &backends {
        let name = backend.name();
        let f = backend
            .factorize_default(&case.matrix)
            .unwrap_or_else(|e| panic!("{}: {name} failed to factorize: {e}", case.name));
        let sol = f.solve(&case.rhs).unwrap_or_else(|e| panic!("{}: {name} failed to solve: {e}", case.name));
        let res = dense_relative_residual(&dense, &sol.x, &case.rhs);
        let rowwise = rowwise_residual(&dense, &sol.x, &case.rhs);
        assert!(
            res <= residual_tol(dim) && rowwise <= residual_tol(dim),
            "{}: {name} relative residual {res:e}, componentwise {rowwise:e} > {:e}",
            case.name,
            residual_tol(dim)
        );
        worst_residual = worst_residual.max(res);
        sols.push((name, sol.x));
    }
    let tol = agreement_tol(dim, cond);
    let mut worst_diff = 0.0f64;
    for a in 0..sols.len() {
        for b in a + 1..sols.len() {
            let diff = relative_difference(&sols[a].1, &sols[b].1);
            assert!(
                diff <= tol,
                "{}: {} and {} differ by {diff:e} > {tol:e} (cond {cond:e})",
                case.name,
                sols[a].0,
                sols[b].0
            );
            worst_diff = worst_diff.max(diff);
        }
    }
    (worst_residual, worst_diff, sols)
}

#[test]
fn every_compiled_backend_is_listed_and_reachable_by_name() {
    let names: Vec<&str> = all_backends().iter().map(|b| b.name()).collect();
    let compiled: Vec<&str> = Backend::compiled().into_iter().map(Backend::name).collect();
    assert_eq!(names, compiled);
    assert!(names.contains(&"structured"), "the structured backend is always built");
    assert_eq!(names.contains(&"faer-lu"), cfg!(feature = "faer-lu"));
    assert_eq!(names.contains(&"nalgebra-lu"), cfg!(feature = "nalgebra-lu"));
    assert_eq!(names.contains(&"openblas-lu"), cfg!(feature = "openblas"));
    for name in &names {
        let backend: Backend = name.parse().unwrap();
        assert_eq!(backend.solver().unwrap().name(), *name);
        assert_eq!(backend.to_string(), *name, "one name for parsing and printing");
    }
    let unknown = "no-such-backend".parse::<Backend>().unwrap_err();
    assert!(unknown.to_string().contains("structured, faer-lu, nalgebra-lu, openblas-lu"), "{unknown}");
    // A backend that exists but is not compiled in says which feature brings it.
    for backend in Backend::ALL.iter().filter(|b| !b.is_compiled()) {
        let Err(e) = backend.solver() else { panic!("{backend} is not compiled in") };
        assert!(matches!(e, LinalgError::NotCompiled { .. }), "{e:?}");
        assert!(e.to_string().contains(&format!("--features {}", backend.feature().unwrap())), "{e}");
    }
    if !cfg!(feature = "openblas") {
        let msg = Backend::OpenblasLu.solver().err().unwrap().to_string();
        assert!(msg.contains("libopenblas-dev"), "{msg}");
    }
}

/// A thread count of 0 is an error (checked before anything global changes).
#[test]
fn zero_threads_is_an_error() {
    assert_eq!(fibfluid_linalg::threads::try_set_threads(0), Err(LinalgError::ZeroThreads));
    let cap = fibfluid_linalg::threads::thread_cap();
    assert!((1..=fibfluid_linalg::threads::MAX_THREADS).contains(&cap));
}

#[test]
fn apply_and_to_dense_agree() {
    for case in random_cases() {
        let dense = case.matrix.to_dense();
        let dim = case.matrix.dim();
        let mut y = vec![0.0; dim];
        case.matrix.apply(&case.rhs, &mut y);
        for i in 0..dim {
            let (mut exact, mut mag) = (0.0, 0.0);
            for j in 0..dim {
                exact += dense[(i, j)] * case.rhs[j];
                mag += (dense[(i, j)] * case.rhs[j]).abs();
            }
            // Two summation orders of the same dim products.
            assert!((y[i] - exact).abs() <= 2.0 * dim as f64 * EPS * mag, "{}: row {i}", case.name);
        }
        // The dense form is the paper's layout: symmetric, zero corner.
        for i in 0..dim {
            for j in 0..dim {
                assert_eq!(dense[(i, j)].to_bits(), dense[(j, i)].to_bits(), "{}: ({i}, {j})", case.name);
            }
        }
        assert_eq!(dense[(dim - 1, dim - 1)], 0.0);
        assert!((case.matrix.norm_inf() - norm_inf(&dense)).abs() <= dim as f64 * EPS * norm_inf(&dense));
        // |A| |x| (the componentwise backward error's denominator) against the dense form.
        let mut z = vec![0.0; dim];
        case.matrix.apply_abs(&case.rhs, &mut z);
        for i in 0..dim {
            let exact: f64 = (0..dim).map(|j| dense[(i, j)].abs() * case.rhs[j].abs()).sum();
            assert!((z[i] - exact).abs() <= 4.0 * dim as f64 * EPS * exact, "{}: |A||x| row {i}", case.name);
        }
        // The column-major form (LAPACK, nalgebra) holds the same entries.
        let flat = case.matrix.to_dense_col_major();
        assert_eq!(flat.len(), dim * dim);
        for j in 0..dim {
            for i in 0..dim {
                assert_eq!(flat[j * dim + i].to_bits(), dense[(i, j)].to_bits(), "{}: ({i}, {j})", case.name);
            }
        }
    }
}

#[test]
fn random_bordered_systems_agree_across_backends() {
    for case in random_cases() {
        let cond = cond1(&case.matrix.to_dense());
        let (res, diff, _) = run_all_backends(&case, cond);
        eprintln!("{}: cond_1 {cond:.3e}, worst residual {res:.2e}, worst difference {diff:.2e}", case.name);
    }
}

/// The paper's Eq. 8, typed in from the paper's text (REFERENCE §4): unknowns
/// (u_x of vertices 0..4, u_y of vertices 0..4, P).
const EQ8: [[f64; 9]; 9] = [
    [329.0, -105.0, -84.0, -140.0, 0.0, 0.0, 0.0, 0.0, 28.0],
    [-105.0, 329.0, -140.0, -84.0, 0.0, 0.0, 0.0, 0.0, 28.0],
    [-84.0, -140.0, 1e9, -105.0, 0.0, 0.0, 0.0, 0.0, -28.0],
    [-140.0, -84.0, -105.0, 329.0, 0.0, 0.0, 0.0, 0.0, -28.0],
    [0.0, 0.0, 0.0, 0.0, 329.0, -105.0, -84.0, -140.0, 21.0],
    [0.0, 0.0, 0.0, 0.0, -105.0, 1e9, -140.0, -84.0, -21.0],
    [0.0, 0.0, 0.0, 0.0, -84.0, -140.0, 1e9, -105.0, -21.0],
    [0.0, 0.0, 0.0, 0.0, -140.0, -84.0, -105.0, 329.0, 21.0],
    [28.0, 28.0, -28.0, -28.0, 21.0, -21.0, -21.0, 21.0, 0.0],
];

fn eq8_case() -> Case {
    let block = |off: usize| Mat::<f64>::from_fn(4, 4, |i, j| EQ8[off + i][off + j]);
    let border = vec![(0..4).map(|i| EQ8[i][8]).collect(), (0..4).map(|i| EQ8[4 + i][8]).collect()];
    let matrix = BorderedMatrix::new(Blocks::PerAxis(vec![block(0), block(4)]), border, 1.0);
    // A force +1680 in y on vertices 0 and 3 (the paper's vertices 1 and 4).
    let rhs = vec![0.0, 0.0, 0.0, 0.0, 1680.0, 0.0, 0.0, 1680.0, 0.0];
    Case { name: "paper Eq. 8".into(), matrix, rhs }
}

#[test]
fn paper_eq8_is_solved_by_every_backend() {
    let case = eq8_case();
    let dense = case.matrix.to_dense();
    for i in 0..9 {
        for j in 0..9 {
            assert_eq!(dense[(i, j)], EQ8[i][j], "to_dense reproduces the typed-in matrix at ({i}, {j})");
        }
    }
    let cond = cond1(&dense);
    let (res, diff, sols) = run_all_backends(&case, cond);
    eprintln!("Eq. 8: cond_1 {cond:.3e}, worst residual {res:.2e}, worst difference {diff:.2e}");
    // The penalty 1e9 leaves the fixed dofs at O(F / big) ~ 1.7e-6 and shifts the others
    // by as much; the paper's values are the big -> infinity limit.
    let penalty_tol = 4.0 * 1680.0 / 1e9;
    for (name, x) in sols {
        // Paper: u_x = -4 on the right corners (0, 1), u_y = 16/3 on the upper corners
        // (0, 3), P = 32.
        assert!((x[0] + 4.0).abs() < penalty_tol && (x[1] + 4.0).abs() < penalty_tol, "{name}: {x:?}");
        assert!(
            (x[4] - 16.0 / 3.0).abs() < penalty_tol && (x[7] - 16.0 / 3.0).abs() < penalty_tol,
            "{name}: {x:?}"
        );
        assert!((x[8] - 32.0).abs() < 32.0 * penalty_tol, "{name}: P = {}", x[8]);
        // The fixed dofs (x of vertex 2, y of vertices 1 and 2) stay at ~0.
        for k in [2, 5, 6] {
            assert!(x[k].abs() < penalty_tol, "{name}: fixed dof {k} = {}", x[k]);
        }
    }
}

// ----- singular and non-finite input -----

/// Factorizes and solves; the whole chain must fail with an error, never return a
/// solution (with NaN or otherwise).
fn expect_error(backend: &dyn LinearSolver, m: &BorderedMatrix, rhs: &[f64], what: &str) -> LinalgError {
    match backend.factorize_default(m) {
        Err(e) => e,
        Ok(f) => match f.solve(rhs) {
            Err(e) => e,
            Ok(sol) => panic!(
                "{what}: {} returned a solution (|x| = {:e}, residual {:e})",
                backend.name(),
                inf_norm(&sol.x),
                sol.relative_residual
            ),
        },
    }
}

#[test]
fn singular_systems_are_errors_in_every_backend() {
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    for &(n, axes, shared) in &[(4usize, 2usize, true), (9, 3, false), (30, 3, true), (60, 2, false)] {
        let nb = if shared { 1 } else { axes };
        let lap: Vec<Mat<f64>> = (0..nb).map(|_| random_laplacian(&mut rng, n)).collect();
        let spd: Vec<Mat<f64>> =
            (0..nb).map(|_| random_spd(&mut rng, n, Spd::LaplacianPlusDiagonal)).collect();
        let blocks = |ks: &[Mat<f64>]| {
            if shared { Blocks::Shared(ks[0].clone()) } else { Blocks::PerAxis(ks.to_vec()) }
        };
        let zero = vec![vec![0.0; n]; axes];
        let cases = [
            // No vertex fixed (each block a Laplacian, singular) and no border.
            ("Laplacian blocks, zero border", BorderedMatrix::new(blocks(&lap), zero.clone(), 1.0)),
            // SPD blocks but no border: the pressure row is zero.
            ("SPD blocks, zero border", BorderedMatrix::new(blocks(&spd), zero, 1.0)),
            // Laplacian blocks with a border: one border row cannot fix `axes` translations.
            (
                "Laplacian blocks, random border",
                BorderedMatrix::new(blocks(&lap), random_border(&mut rng, n, axes), 1.0),
            ),
        ];
        for (what, m) in &cases {
            let rhs: Vec<f64> = (0..m.dim()).map(|_| rng.random_range(-1.0..1.0)).collect();
            for backend in all_backends() {
                let e = expect_error(backend.as_ref(), m, &rhs, what);
                eprintln!("{what} (n {n}, axes {axes}): {} -> {e}", backend.name());
            }
        }
    }
}

#[test]
fn non_finite_input_is_an_error_in_every_backend() {
    let base_shared = random_case(11, 8, 3, true, Spd::Gram, 1.0);
    let base_per_axis = random_case(12, 8, 3, false, Spd::LaplacianPlusDiagonal, 2.0);
    let with_block = |case: &Case, axis: usize, (i, j): (usize, usize), v: f64| {
        let mut blocks = case.matrix.blocks().clone();
        match &mut blocks {
            Blocks::Shared(k) => {
                k[(i, j)] = v;
                k[(j, i)] = v;
            }
            Blocks::PerAxis(ks) => {
                ks[axis][(i, j)] = v;
                ks[axis][(j, i)] = v;
            }
        }
        let border = (0..3).map(|c| case.matrix.border(c).to_vec()).collect();
        BorderedMatrix::new(blocks, border, 1.0)
    };
    let with_border = |case: &Case, axis: usize, i: usize, v: f64| {
        let mut border: Vec<Vec<f64>> = (0..3).map(|c| case.matrix.border(c).to_vec()).collect();
        border[axis][i] = v;
        BorderedMatrix::new(case.matrix.blocks().clone(), border, 1.0)
    };
    let bad = [
        ("NaN in the shared block", with_block(&base_shared, 0, (2, 5), f64::NAN)),
        ("+inf on the shared block's diagonal", with_block(&base_shared, 0, (7, 7), f64::INFINITY)),
        ("NaN in the z block", with_block(&base_per_axis, 2, (0, 3), f64::NAN)),
        ("-inf in the y block", with_block(&base_per_axis, 1, (6, 1), f64::NEG_INFINITY)),
        ("NaN in the x border (shared)", with_border(&base_shared, 0, 4, f64::NAN)),
        ("+inf in the z border (shared)", with_border(&base_shared, 2, 7, f64::INFINITY)),
        ("NaN in the y border (per-axis)", with_border(&base_per_axis, 1, 0, f64::NAN)),
        ("a pressure scale that overflows the border", {
            // |S| up to 4 times f64::MAX: some border entries become infinite.
            let border = (0..3).map(|c| base_per_axis.matrix.border(c).iter().map(|v| v * 4.0).collect());
            BorderedMatrix::new(base_per_axis.matrix.blocks().clone(), border.collect(), f64::MAX)
        }),
    ];
    for (what, m) in &bad {
        let rhs = vec![1.0; m.dim()];
        for backend in all_backends() {
            let e = expect_error(backend.as_ref(), m, &rhs, what);
            assert!(matches!(e, LinalgError::NonFinite { .. }), "{what}: {} gave {e:?}", backend.name());
        }
    }
    for base in [&base_shared, &base_per_axis] {
        for backend in all_backends() {
            let f = backend.factorize_default(&base.matrix).unwrap();
            for (index, v) in [(0usize, f64::NAN), (13, f64::INFINITY), (24, f64::NEG_INFINITY)] {
                let mut rhs = base.rhs.clone();
                rhs[index] = v;
                let e = f.solve(&rhs).expect_err("non-finite rhs");
                assert_eq!(e, LinalgError::NonFiniteRhs { index }, "{}", backend.name());
            }
        }
    }
}

// ----- condition estimate -----

#[test]
fn rcond_estimate_is_within_a_factor_10_of_the_exact_value() {
    let mut cases: Vec<Case> = random_cases().into_iter().filter(|c| c.matrix.dim() <= 130).collect();
    cases.push(eq8_case());
    // An ill-conditioned random case: one tiny diagonal shift on a Laplacian block.
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    let mut k = random_laplacian(&mut rng, 15);
    k[(3, 3)] += 1e-6;
    cases.push(Case {
        name: "grounded Laplacian, shift 1e-6".into(),
        matrix: BorderedMatrix::new(Blocks::Shared(k), random_border(&mut rng, 15, 3), 1.0),
        rhs: vec![],
    });
    for (method, scaling) in [
        (ConstraintMethod::Eliminate, PressureScaling::Auto),
        (ConstraintMethod::Penalty { big: 1e9 }, PressureScaling::None),
    ] {
        let (sys, rhs) = sphere_system(1, method, scaling, [3000.0; 3]);
        cases.push(Case {
            name: format!("sphere level 1, {method:?}, {scaling:?}"),
            matrix: sys.matrix,
            rhs,
        });
    }
    for case in &cases {
        let exact = 1.0 / cond1(&case.matrix.to_dense());
        for backend in all_backends() {
            let f = backend.factorize_default(&case.matrix).unwrap();
            let est = f.rcond_estimate();
            let ratio = est / exact;
            eprintln!(
                "{}: {} rcond {est:.3e}, exact {exact:.3e}, ratio {ratio:.3}",
                case.name,
                backend.name()
            );
            assert!((0.1..=10.0).contains(&ratio), "{}: {} ratio {ratio}", case.name, backend.name());
        }
    }
}

// ----- border replacement -----

/// After `set_border`, a factorization must solve exactly what a fresh factorization of
/// the matrix with the new border solves.
fn check_set_border(case: &Case, new_border: &[Vec<f64>]) {
    let mut fresh_matrix = case.matrix.clone();
    fresh_matrix.set_border(new_border);
    // The same matrix built from scratch: set_border keeps the pressure scale.
    let rebuilt =
        BorderedMatrix::new(case.matrix.blocks().clone(), new_border.to_vec(), case.matrix.pressure_scale());
    let dense = rebuilt.to_dense();
    let fresh_dense = fresh_matrix.to_dense();
    for i in 0..dense.nrows() {
        for j in 0..dense.ncols() {
            assert_eq!(dense[(i, j)].to_bits(), fresh_dense[(i, j)].to_bits());
        }
    }
    let dim = rebuilt.dim();
    let tol = agreement_tol(dim, cond1(&dense));
    for backend in all_backends() {
        let name = backend.name();
        let mut updated = backend.factorize_default(&case.matrix).unwrap();
        updated.set_border(new_border).unwrap_or_else(|e| panic!("{}: {name} set_border: {e}", case.name));
        for c in 0..rebuilt.axes() {
            assert_eq!(updated.matrix().border(c), rebuilt.border(c), "{}: {name} border {c}", case.name);
        }
        let fresh = backend.factorize_default(&rebuilt).unwrap();
        let a = updated.solve(&case.rhs).unwrap();
        let b = fresh.solve(&case.rhs).unwrap();
        let res =
            dense_relative_residual(&dense, &a.x, &case.rhs).max(rowwise_residual(&dense, &a.x, &case.rhs));
        assert!(res <= residual_tol(dim), "{}: {name} residual after set_border {res:e}", case.name);
        let diff = relative_difference(&a.x, &b.x);
        assert!(diff <= tol, "{}: {name} set_border vs fresh differ by {diff:e} > {tol:e}", case.name);
        // And the old border's solution is not what comes out (the update took effect).
        let old = backend.factorize_default(&case.matrix).unwrap().solve(&case.rhs).unwrap();
        assert!(relative_difference(&old.x, &a.x) > 1e3 * tol, "{}: {name} border unchanged?", case.name);
    }
}

#[test]
fn set_border_matches_a_fresh_factorization() {
    for (k, case) in random_cases().iter().enumerate() {
        let mut rng = ChaCha8Rng::seed_from_u64(1000 + k as u64);
        let new_border = random_border(&mut rng, case.matrix.n_vertices(), case.matrix.axes());
        check_set_border(case, &new_border);
    }
    // Assembled sphere: the border of the deformed shape (the volume-drift correction of
    // REFERENCE §5 keeps K and replaces S).
    let (sys, rhs) = sphere_system(2, ConstraintMethod::Eliminate, PressureScaling::Auto, [3000.0; 3]);
    let f = Backend::Structured.solver().unwrap().factorize_default(&sys.matrix).unwrap();
    let (u, _) = sys.split_solution(&f.solve(&rhs).unwrap().x);
    let mesh = icosphere(2, 1.0);
    let moved: Vec<[f64; 3]> =
        mesh.positions().iter().zip(&u).map(|(p, d)| [p[0] + d[0], p[1] + d[1], p[2] + d[2]]).collect();
    let deformed = TriMesh::new(moved, mesh.triangles().to_vec()).unwrap();
    let new_border = sys.border_for(&deformed.vertex_area_vectors());
    let case = Case { name: "sphere level 2, deformed border".into(), matrix: sys.matrix.clone(), rhs };
    check_set_border(&case, &new_border);
    // A zero border makes the system singular: the update must fail, not divide by zero.
    let zero = vec![vec![0.0; sys.matrix.n_vertices()]; 3];
    for backend in all_backends() {
        let mut f = backend.factorize_default(&sys.matrix).unwrap();
        let bad = f.set_border(&zero).map(|_| ()).and_then(|_| f.solve(&case.rhs).map(|_| ()));
        assert!(bad.is_err(), "{}: a zero border was accepted", backend.name());
    }
}

// ----- systems assembled on icospheres -----

/// The paper's sphere case (REFERENCE §4): icosphere of radius 1, vertices with y > 0.8
/// fixed in x, y, z, gamma = 3000, rho = 1000, gravity 10 along -y and the force
/// (-300, -300, -300) on vertex 0. `young` may be anisotropic (per-axis blocks).
fn sphere_system(
    level: u32,
    method: ConstraintMethod,
    pressure_scaling: PressureScaling,
    young: [f64; 3],
) -> (System, Vec<f64>) {
    let mesh = icosphere(level, 1.0);
    let n = mesh.n_vertices();
    let pos = mesh.positions();
    let s = mesh.vertex_area_vectors();
    let edges = mesh.adjacency().edges();
    let fibers = FiberSet::all(n);
    let body = Body {
        axes: 3,
        positions: pos,
        vertex_areas: &s,
        edges: &edges,
        fibers: &fibers,
        rest_positions: None,
    };
    let material = Material::new(young, 3000.0, 1000.0).unwrap();
    let mut c = Constraints::new(n);
    c.fix_selected(&Selector::Above { axis: 1, value: 0.8 }, pos, [true; 3]).unwrap();
    let sys = assemble(&body, &material, &c, &AssemblyOptions { method, pressure_scaling }).unwrap();
    let b = load_vector(
        3,
        pos,
        &s,
        &Loads { acceleration: [0.0, -10.0, 0.0], down: None, density: 1000.0, forces: &[(0, [-300.0; 3])] },
    )
    .unwrap();
    let rhs = sys.rhs(&b, 0.0, &s, 1.0);
    (sys, rhs)
}

#[test]
fn assembled_spheres_agree_across_backends() {
    let configs = [
        (1, ConstraintMethod::Eliminate, PressureScaling::Auto, [3000.0; 3]),
        (1, ConstraintMethod::Penalty { big: 1e9 }, PressureScaling::None, [3000.0; 3]),
        (2, ConstraintMethod::Eliminate, PressureScaling::Auto, [3000.0; 3]),
        (2, ConstraintMethod::Eliminate, PressureScaling::None, [3000.0; 3]),
        (2, ConstraintMethod::Penalty { big: 1e9 }, PressureScaling::None, [3000.0; 3]),
        (2, ConstraintMethod::Eliminate, PressureScaling::Auto, [3000.0, 1500.0, 6000.0]),
    ];
    for (level, method, scaling, young) in configs {
        let (sys, rhs) = sphere_system(level, method, scaling, young);
        assert_eq!(sys.matrix.is_shared(), young[0] == young[1] && young[1] == young[2]);
        let name = format!("sphere level {level}, {method:?}, {scaling:?}, Y {young:?}");
        let case = Case { name, matrix: sys.matrix, rhs };
        let cond = cond1(&case.matrix.to_dense());
        let (res, diff, _) = run_all_backends(&case, cond);
        eprintln!(
            "{} (dim {}): cond_1 {cond:.3e}, worst residual {res:.2e}, worst difference {diff:.2e}",
            case.name,
            case.matrix.dim()
        );
    }
}

// ----- mixed precision -----

#[test]
fn mixed_precision_refines_to_the_f64_target_on_the_eliminated_sphere() {
    let opts = FactorOptions { precision: Precision::Mixed, ..FactorOptions::default() };
    let (sys, rhs) = sphere_system(2, ConstraintMethod::Eliminate, PressureScaling::Auto, [3000.0; 3]);
    let dense = sys.matrix.to_dense();
    let dim = sys.matrix.dim();
    let cond = cond1(&dense);
    let reference = Backend::Structured.solver().unwrap().factorize_default(&sys.matrix).unwrap();
    let x64 = reference.solve(&rhs).unwrap().x;
    let mut tested = 0;
    for backend in all_backends() {
        if !backend.supports(Precision::Mixed) {
            eprintln!("{}: no mixed precision", backend.name());
            continue;
        }
        tested += 1;
        let f = backend.factorize(&sys.matrix, &opts).unwrap();
        let sol = f.solve(&rhs).unwrap_or_else(|e| panic!("{}: {e}", backend.name()));
        let res = dense_relative_residual(&dense, &sol.x, &rhs).max(rowwise_residual(&dense, &sol.x, &rhs));
        eprintln!(
            "mixed, eliminated sphere (cond_1 {cond:.2e}): {} {} refinement steps, residual {res:.2e}",
            backend.name(),
            sol.refinement_steps
        );
        assert!(sol.refinement_steps <= 3, "{}: {} steps", backend.name(), sol.refinement_steps);
        assert!(res <= residual_tol(dim), "{}: residual {res:e}", backend.name());
        let diff = relative_difference(&x64, &sol.x);
        assert!(diff <= agreement_tol(dim, cond), "{}: differs from f64 by {diff:e}", backend.name());
    }
    assert!(tested > 0, "the structured backend supports mixed precision");
}

#[test]
fn mixed_precision_on_the_penalty_sphere_is_reported() {
    // cond ~1e12 is beyond what an f32 factorization can refine (cond * eps_f32 >> 1), so
    // nothing is asserted about success; whatever happens must not be a NaN solution.
    let opts = FactorOptions { precision: Precision::Mixed, ..FactorOptions::default() };
    let (sys, rhs) =
        sphere_system(2, ConstraintMethod::Penalty { big: 1e9 }, PressureScaling::None, [3000.0; 3]);
    let dense = sys.matrix.to_dense();
    eprintln!("penalty sphere: cond_1 {:.2e}", cond1(&dense));
    let n3 = 3 * sys.matrix.n_vertices();
    let x64 =
        Backend::Structured.solver().unwrap().factorize_default(&sys.matrix).unwrap().solve(&rhs).unwrap().x;
    for backend in all_backends().into_iter().filter(|b| b.supports(Precision::Mixed)) {
        match backend.factorize(&sys.matrix, &opts).and_then(|f| f.solve(&rhs)) {
            Ok(sol) => {
                assert!(sol.x.iter().all(|v| v.is_finite()));
                // The normwise residual is dominated by the 1e9 penalty rows; the row-wise
                // residual and the displacement error show what the solve is worth.
                eprintln!(
                    "mixed, penalty sphere: {} accepted after {} steps, reported backward error {:.2e}; \
                     normwise residual {:.2e}, row-wise {:.2e}, displacement error vs f64 {:.2e}",
                    backend.name(),
                    sol.refinement_steps,
                    sol.relative_residual,
                    dense_relative_residual(&dense, &sol.x, &rhs),
                    rowwise_residual(&dense, &sol.x, &rhs),
                    relative_difference(&x64[..n3], &sol.x[..n3]),
                );
            }
            Err(e) => eprintln!("mixed, penalty sphere: {} failed: {e}", backend.name()),
        }
    }
}

#[test]
fn backends_factor_on_a_default_sized_thread_stack() {
    // Rust spawns threads (test threads, rayon workers) with 2 MiB of stack; a backend must
    // not need more (OpenBLAS's threaded getrf recurses with ~0.5 MiB frames; how deep
    // depends on its thread schedule, hence the repetitions).
    let case = random_case(21, 250, 3, false, Spd::LaplacianPlusDiagonal, 1.0);
    let dense = case.matrix.to_dense();
    for _ in 0..6 {
        std::thread::scope(|s| {
            std::thread::Builder::new()
                .stack_size(2 << 20)
                .spawn_scoped(s, || {
                    for backend in all_backends() {
                        let f = backend.factorize_default(&case.matrix).unwrap();
                        let x = f.solve(&case.rhs).unwrap().x;
                        let res = dense_relative_residual(&dense, &x, &case.rhs);
                        assert!(res <= residual_tol(case.matrix.dim()), "{}: {res:e}", backend.name());
                    }
                })
                .unwrap()
                .join()
                .unwrap();
        });
    }
}

#[test]
fn solve_many_matches_separate_solves_in_every_backend() {
    // Three right-hand sides at once (the structured backend reads each factor once for all
    // of them) against three separate checked solves, on shared and per-axis blocks.
    for case in random_cases() {
        let dim = case.matrix.dim();
        let mut rng = ChaCha8Rng::seed_from_u64(99);
        let mut b = case.rhs.clone();
        for _ in 0..2 {
            b.extend((0..dim).map(|_| rng.random_range(-1.0..1.0)));
        }
        let dense = case.matrix.to_dense();
        for backend in all_backends() {
            let name = backend.name();
            let f = backend.factorize_default(&case.matrix).unwrap();
            let many = f.solve_many(&b, 3).unwrap_or_else(|e| panic!("{}: {name}: {e}", case.name));
            assert_eq!(many.len(), 3);
            for (k, sol) in many.iter().enumerate() {
                let bk = &b[k * dim..(k + 1) * dim];
                let one = f.solve(bk).unwrap();
                let diff = relative_difference(&sol.x, &one.x);
                assert!(diff <= 1e-12, "{}: {name}, rhs {k}: solve_many vs solve {diff:e}", case.name);
                let res = dense_relative_residual(&dense, &sol.x, bk);
                assert!(res <= residual_tol(dim), "{}: {name}, rhs {k}: residual {res:e}", case.name);
            }
        }
    }
}

#[test]
fn apply_many_matches_apply_per_vector() {
    // Against the one-vector products, which `apply_and_to_dense_agree` pins to the dense
    // matrix; shared and per-axis blocks, Laplacian (z-matrix) and Gram blocks.
    for case in random_cases() {
        let dim = case.matrix.dim();
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let x: Vec<f64> = (0..3 * dim).map(|_| rng.random_range(-1.0..1.0)).collect();
        let (mut y, mut ya) = (vec![0.0; 3 * dim], vec![0.0; 3 * dim]);
        case.matrix.apply_many(&x, &mut y, 3);
        case.matrix.apply_abs_many(&x, &mut ya, 3);
        for k in 0..3 {
            let (mut y1, mut ya1) = (vec![0.0; dim], vec![0.0; dim]);
            case.matrix.apply(&x[k * dim..(k + 1) * dim], &mut y1);
            case.matrix.apply_abs(&x[k * dim..(k + 1) * dim], &mut ya1);
            assert!(
                relative_difference(&y[k * dim..(k + 1) * dim], &y1) <= 1e-14,
                "{}: apply, vector {k}",
                case.name
            );
            assert!(
                relative_difference(&ya[k * dim..(k + 1) * dim], &ya1) <= 1e-14,
                "{}: apply_abs, vector {k}",
                case.name
            );
        }
    }
}

/// Reads `m` three ways (dense form, `A x`, `|A| |x|` and the residual) and compares each
/// with the dense matrix `dense` built before any factorization.
fn assert_reads_as(m: &BorderedMatrix, dense: &Mat<f64>, what: &str) {
    let dim = m.dim();
    assert!(m.to_dense() == *dense, "{what}: the dense form changed");
    let x: Vec<f64> = (0..dim).map(|i| ((i * 7) % 13) as f64 / 13.0 - 0.4).collect();
    let b: Vec<f64> = (0..dim).map(|i| ((i * 5) % 11) as f64 / 11.0).collect();
    let xm = Mat::<f64>::from_fn(dim, 1, |i, _| x[i]);
    let ax_dense = dense * &xm;
    let abs_dense = Mat::<f64>::from_fn(dim, dim, |i, j| dense[(i, j)].abs())
        * Mat::<f64>::from_fn(dim, 1, |i, _| x[i].abs());
    let (mut ax, mut abs_ax) = (vec![0.0; dim], vec![0.0; dim]);
    m.apply(&x, &mut ax);
    m.apply_abs(&x, &mut abs_ax);
    let (mut r, mut abs_r) = (vec![0.0; dim], vec![0.0; dim]);
    m.residual(&x, &b, &mut r, &mut abs_r);
    // Different summation orders: a few ulps of |A| |x| per entry.
    let tol = |i: usize| RESIDUAL_C * dim as f64 * EPS * abs_dense[(i, 0)];
    for i in 0..dim {
        assert!((ax[i] - ax_dense[(i, 0)]).abs() <= tol(i), "{what}: (A x)_{i}");
        assert!((abs_ax[i] - abs_dense[(i, 0)]).abs() <= tol(i), "{what}: (|A| |x|)_{i}");
        assert!((r[i] - (b[i] - ax_dense[(i, 0)])).abs() <= tol(i), "{what}: r_{i}");
        assert!((abs_r[i] - abs_dense[(i, 0)]).abs() <= tol(i), "{what}: residual's |A| |x|_{i}");
    }
}

/// `factorize_in_place` in every backend, on matrices nobody else holds (the random cases,
/// one past the in-place kernel's block size of 256 with the threaded product, and two of
/// odd order): the
/// solution passes the independent dense residual check, the matrix reads as before, a
/// second factorization while the first is alive and one after it is dropped both solve,
/// and a clone held elsewhere keeps the blocks from being written.
#[test]
#[ignore = "long run: CI runs it with `cargo test --workspace -- --ignored long_`"]
fn long_factoring_in_place_keeps_the_matrix_and_solves() {
    let mut cases = random_cases();
    cases.push(random_case(9, 600, 3, true, Spd::LaplacianPlusDiagonal, 1.0));
    // Odd orders (the residual kernel takes columns in pairs), one past the threaded split.
    cases.push(random_case(10, 601, 2, false, Spd::Gram, 1.0));
    cases.push(random_case(11, 33, 3, true, Spd::Gram, 1.0));
    for backend in all_backends() {
        let name = backend.name();
        for case in &cases {
            let what = format!("{}: {name}", case.name);
            let dense = case.matrix.to_dense();
            let dim = case.matrix.dim();
            let mut m = BorderedMatrix::new(
                if case.matrix.is_shared() {
                    Blocks::Shared(case.matrix.block(0).clone())
                } else {
                    Blocks::PerAxis((0..case.matrix.axes()).map(|c| case.matrix.block(c).clone()).collect())
                },
                (0..case.matrix.axes())
                    .map(|c| case.matrix.border(c).iter().map(|v| v / case.matrix.pressure_scale()).collect())
                    .collect(),
                case.matrix.pressure_scale(),
            );
            let check = |f: &dyn fibfluid_linalg::Factorization, when: &str| {
                let sol = f.solve(&case.rhs).unwrap_or_else(|e| panic!("{what} {when}: {e}"));
                let res = rowwise_residual(&dense, &sol.x, &case.rhs);
                assert!(res <= residual_tol(dim), "{what} {when}: residual {res:e}");
            };
            let opts = FactorOptions::default();
            assert_reads_as(&m, &dense, &format!("{what}, before"));
            let first = backend.factorize_in_place(&mut m, &opts).unwrap_or_else(|e| panic!("{what}: {e}"));
            assert_eq!(m.is_factored_in_place(), name == "structured", "{what}: who writes in place");
            assert_reads_as(&m, &dense, &what);
            check(first.as_ref(), "in place");
            let second = backend.factorize_in_place(&mut m, &opts).expect("a shared matrix is copied");
            check(second.as_ref(), "while the first is alive");
            drop((first, second));
            let third = backend.factorize_in_place(&mut m, &opts).expect("factored again");
            assert_reads_as(&m, &dense, &what);
            check(third.as_ref(), "after the first was dropped");
        }
    }
    let case = random_case(10, 30, 3, false, Spd::Gram, 1.0);
    let (mut m, held) = (case.matrix.clone(), case.matrix);
    fibfluid_linalg::Structured.factorize_in_place(&mut m, &FactorOptions::default()).expect("spd");
    assert!(!m.is_factored_in_place() && !held.is_factored_in_place(), "a shared matrix is not written");
}

/// A block that is not positive definite fails `factorize_in_place` with the same error
/// as `factorize`, and leaves the matrix as it was (read back in full).
#[test]
fn a_failed_factorization_in_place_leaves_the_matrix_whole() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for shared in [true, false] {
        let n = 300;
        let mut ks: Vec<Mat<f64>> =
            (0..3).map(|_| random_spd(&mut rng, n, Spd::LaplacianPlusDiagonal)).collect();
        // The last block is indefinite at row 280: its diagonal entry is far below the
        // off-diagonal weights, past the first 256-column block.
        let last = if shared { 0 } else { 2 };
        ks[last][(280, 280)] = -1.0;
        let blocks = if shared { Blocks::Shared(ks[0].clone()) } else { Blocks::PerAxis(ks) };
        let mut m = BorderedMatrix::new(blocks, random_border(&mut rng, n, 3), 1.0);
        let dense = m.to_dense();
        let copied =
            fibfluid_linalg::Structured.factorize(&m, &FactorOptions::default()).err().expect("indefinite");
        let e = fibfluid_linalg::Structured
            .factorize_in_place(&mut m, &FactorOptions::default())
            .err()
            .expect("indefinite");
        assert_eq!(e.to_string(), copied.to_string());
        assert!(!m.is_factored_in_place());
        assert_reads_as(&m, &dense, "after a failed factorization in place");
    }
}
