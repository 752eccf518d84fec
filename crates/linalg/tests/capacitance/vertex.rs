//! Vertex holds on a bordered system: the vertex-response source (`VertexColumns` read
//! through `VertexSource`, N-length columns per distinct block plus `w` and `s`) and the
//! dense-column source (`ComplianceSource` of the factorization, one `dN + 1` column per
//! row) go through the same `RowCapacitance`; both are checked against the constrained
//! system `[A E; E' 0] [x; r] = [b; g]` solved whole by faer's dense partial-pivot LU.

use fibfluid_linalg::{
    ComplianceSource, Factorization, FactorizationExt, HeldCapacitance, HeldRow, LinearSolverExt,
    RowCapacitance, SparseRow, VertexColumns, VertexForce, VertexSource, all_backends,
};

use super::{max_diff, saddle_point};
use crate::{Spd, random_case};

/// Agreement per unknown of the constrained system, relative to the largest entry: the
/// solves are refined to about `dim * eps` and the systems here are well conditioned.
const TOL_PER_UNKNOWN: f64 = 1e-12;

/// Two vertices held on every axis and a frictionless contact along a unit normal.
fn held_rows(axes: usize) -> Vec<HeldRow> {
    let mut rows: Vec<HeldRow> = HeldRow::all_axes(2, axes).chain(HeldRow::all_axes(7, axes)).collect();
    let normal = if axes == 3 { [0.48, -0.6, 0.64] } else { [0.6, -0.8, 0.0] };
    rows.push(HeldRow { vertex: 5, direction: normal });
    rows
}

/// The held rows as sparse rows of the bordered unknowns (`u[c * N + v]`).
fn sparse_rows(rows: &[HeldRow], n: usize, axes: usize) -> Vec<Vec<(usize, f64)>> {
    rows.iter()
        .map(|r| {
            (0..axes).filter(|&a| r.direction[a] != 0.0).map(|a| (a * n + r.vertex, r.direction[a])).collect()
        })
        .collect()
}

/// The forces of multipliers `r` (the constraint adds `-r` times its row): per vertex, in
/// the rows' order.
fn forces_of(rows: &[HeldRow], r: &[f64]) -> Vec<VertexForce> {
    let mut out: Vec<VertexForce> = Vec::new();
    for (row, ri) in rows.iter().zip(r) {
        if out.last().is_none_or(|l| l.0 != row.vertex) {
            out.push((row.vertex, [0.0; 3]));
        }
        let f = &mut out.last_mut().expect("pushed").1;
        for a in 0..3 {
            f[a] -= ri * row.direction[a];
        }
    }
    out
}

fn flat(forces: &[VertexForce]) -> Vec<f64> {
    forces.iter().flat_map(|f| f.1).collect()
}

fn largest(x: &[f64]) -> f64 {
    x.iter().fold(0.0_f64, |a, v| a.max(v.abs()))
}

#[test]
fn vertex_held_and_dense_column_paths_match_the_whole_constrained_system() {
    for (seed, axes, shared) in [(21, 3, false), (22, 3, true), (23, 2, false)] {
        let case = random_case(seed, 12, axes, shared, Spd::Gram, 2.5);
        let (m, n) = (&case.matrix, case.matrix.n_vertices());
        let dim = m.dim();
        let rows = held_rows(axes);
        let sparse = sparse_rows(&rows, n, axes);
        let targets: Vec<f64> = (0..rows.len()).map(|i| 0.05 * (i as f64 - 2.0)).collect();
        let (x_ref, r_ref) = saddle_point(&m.to_dense(), &sparse, &case.rhs, &targets);
        let reactions_ref = flat(&forces_of(&rows, &r_ref));
        let tol = TOL_PER_UNKNOWN * dim as f64;
        for backend in all_backends() {
            let what = format!("{} on {}", backend.name(), case.name);
            let f = backend.factorize_default(m).expect("factorization");
            let f: &dyn Factorization = f.as_ref();
            // Dense columns, one per row.
            let refs: Vec<&SparseRow> = sparse.iter().map(Vec::as_slice).collect();
            let columns = f.compliance_columns(&refs).expect("columns");
            let dense = RowCapacitance::new(&refs, &columns, 0.0).expect("independent rows");
            let mut x_dense = f.solve(&case.rhs).expect("solve").x;
            let r_dense = dense.correct(&refs, &columns, &targets, &mut x_dense);
            // Vertex columns: N values per block and vertex.
            let mut vertex = VertexColumns::new(f).expect("border terms");
            vertex.touch(f, &[2, 5, 7]).expect("columns");
            let held = HeldCapacitance::from_rows(&vertex, &rows).expect("independent holds");
            let mut x_vertex = f.solve(&case.rhs).expect("solve").x;
            let source = VertexSource::bordered(&vertex, m.pressure_scale());
            let reactions = held.impose(&source, &targets, &mut x_vertex).expect("finite");
            // Both capacitances are E' W.
            let (gd, gv) = (dense.matrix(), held.capacitance().matrix());
            let g_diff = (0..rows.len())
                .flat_map(|i| (0..rows.len()).map(move |j| (gd[(i, j)] - gv[(i, j)]).abs()))
                .fold(0.0, f64::max);
            let g_scale = (0..rows.len()).map(|i| gd[(i, i)].abs()).fold(0.0, f64::max);
            assert!(g_diff <= tol * g_scale, "{what}: capacitances differ by {g_diff:e}");
            let scale = largest(&x_ref);
            for (name, x) in [("dense", &x_dense), ("vertex", &x_vertex)] {
                let d = max_diff(x, &x_ref);
                assert!(d <= tol * scale, "{what}: {name} displacements differ by {d:e} (scale {scale:e})");
            }
            let rscale = largest(&reactions_ref);
            for (name, r) in [("dense", flat(&forces_of(&rows, &r_dense))), ("vertex", flat(&reactions))] {
                let d = max_diff(&r, &reactions_ref);
                assert!(d <= tol * rscale, "{what}: {name} reactions differ by {d:e} (scale {rscale:e})");
            }
            // The holds are met, and the field layout gives the same displacements.
            for (row, (e, t)) in sparse.iter().zip(&targets).enumerate() {
                let got: f64 = e.iter().map(|&(i, c)| c * x_vertex[i]).sum();
                assert!((got - t).abs() <= tol * scale, "{what}: row {row} at {got}, target {t}");
            }
            let mut u = f.solve(&case.rhs).expect("solve").x[..dim - 1].to_vec();
            let field = held.impose(&VertexSource::field(&vertex), &targets, &mut u).expect("finite");
            assert_eq!(field, reactions, "{what}: the same reactions in either layout");
            assert!(max_diff(&u, &x_vertex[..dim - 1]) <= tol * scale, "{what}: field layout");
        }
    }
}
