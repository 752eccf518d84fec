//! The paper's golden cases (REFERENCE §4), built through the public API.

use fibfluid_assembly::{
    AssemblyOptions, Body, ConstraintMethod, Constraints, Loads, Material, PressureScaling, assemble,
    load_vector,
};
use fibfluid_geometry::{FiberSet, Polygon, icosphere};
use fibfluid_linalg::{Backend, FactorizationExt, LinearSolverExt};

fn rectangle() -> (Polygon, fibfluid_assembly::System) {
    // Vertices in the paper's order: (15, 20), (15, -20), (-15, -20), (-15, 20).
    let poly = Polygon::new(vec![[15.0, 20.0], [15.0, -20.0], [-15.0, -20.0], [-15.0, 20.0]]).unwrap();
    let pos = poly.positions_3d();
    let s: Vec<[f64; 3]> = poly.vertex_area_vectors().iter().map(|v| [v[0], v[1], 0.0]).collect();
    let fibers = FiberSet::all(4);
    let edges = poly.edges();
    let body = Body {
        axes: 2,
        positions: &pos,
        vertex_areas: &s,
        edges: &edges,
        fibers: &fibers,
        rest_positions: None,
    };
    let material = Material::new([360.0; 3], 0.0, 0.0).unwrap();
    let mut c = Constraints::new(4);
    c.fix(2, [true, true, false]).unwrap(); // lower left: x and y
    c.fix(1, [false, true, false]).unwrap(); // lower right: y only
    let opts = AssemblyOptions {
        method: ConstraintMethod::Penalty { big: 1e9 },
        pressure_scaling: PressureScaling::None,
    };
    let sys = assemble(&body, &material, &c, &opts).unwrap();
    (poly, sys)
}

/// Eq. 8 of the paper, typed in from the paper's text.
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

#[test]
fn rectangle_matrix_is_the_papers_eq8() {
    let (poly, sys) = rectangle();
    let s = poly.vertex_area_vectors();
    for v in &s {
        assert!((v[0].hypot(v[1]) - 35.0).abs() < 1e-12, "|S_i| = 35 (paper)");
    }
    let a = sys.matrix.to_dense();
    assert_eq!((a.nrows(), a.ncols()), (9, 9));
    for i in 0..9 {
        for j in 0..9 {
            // 1e-12 relative: the entries are sums of a few rounded terms.
            let tol = 1e-12 * EQ8[i][j].abs().max(1.0);
            assert!(
                (a[(i, j)] - EQ8[i][j]).abs() <= tol,
                "entry ({i}, {j}) = {} expected {}",
                a[(i, j)],
                EQ8[i][j]
            );
        }
    }
}

#[test]
fn rectangle_solution_matches_the_paper() {
    let (poly, sys) = rectangle();
    let pos = poly.positions_3d();
    let s: Vec<[f64; 3]> = poly.vertex_area_vectors().iter().map(|v| [v[0], v[1], 0.0]).collect();
    let forces = [(0, [0.0, 1680.0, 0.0]), (3, [0.0, 1680.0, 0.0])];
    let b = load_vector(
        2,
        &pos,
        &s,
        &Loads { acceleration: [0.0; 3], down: None, density: 0.0, forces: &forces },
    )
    .unwrap();
    let rhs = sys.rhs(&b, 0.0, &s, 1.0);
    for backend in fibfluid_linalg::Backend::compiled() {
        let f = backend.solver().unwrap().factorize_default(&sys.matrix).unwrap();
        let sol = f.solve(&rhs).unwrap();
        let (u, p) = sys.split_solution(&sol.x);
        // Paper: u_x = -4 on the right corners, u_y = 16/3 on the upper corners, P = 32.
        // The penalty leaves the fixed dofs at O(F / big) = 1.7e-6, which shifts the rest by as much.
        let tol = 4.0 * 1680.0 / 1e9;
        assert!(
            (u[0][0] + 4.0).abs() < tol && (u[1][0] + 4.0).abs() < tol,
            "{backend}: u_x right = {:?}",
            (u[0][0], u[1][0])
        );
        assert!(
            (u[0][1] - 16.0 / 3.0).abs() < tol && (u[3][1] - 16.0 / 3.0).abs() < tol,
            "{backend}: u_y top {:?}",
            (u[0][1], u[3][1], u[1][1], u[2][1])
        );
        assert!((p - 32.0).abs() < 1e-5, "{backend}: P = {p}");
        let vol_row: f64 = (0..4).map(|i| s[i][0] * u[i][0] + s[i][1] * u[i][1]).sum();
        assert!(vol_row.abs() < 1e-9, "{backend}: volume row {vol_row}");
    }
}

#[test]
fn rectangle_eliminate_gives_exact_fixed_dofs() {
    let poly = Polygon::new(vec![[15.0, 20.0], [15.0, -20.0], [-15.0, -20.0], [-15.0, 20.0]]).unwrap();
    let pos = poly.positions_3d();
    let s: Vec<[f64; 3]> = poly.vertex_area_vectors().iter().map(|v| [v[0], v[1], 0.0]).collect();
    let fibers = FiberSet::all(4);
    let edges = poly.edges();
    let body = Body {
        axes: 2,
        positions: &pos,
        vertex_areas: &s,
        edges: &edges,
        fibers: &fibers,
        rest_positions: None,
    };
    let material = Material::new([360.0; 3], 0.0, 0.0).unwrap();
    let mut c = Constraints::new(4);
    c.fix(2, [true, true, false]).unwrap();
    c.fix(1, [false, true, false]).unwrap();
    let opts =
        AssemblyOptions { method: ConstraintMethod::Eliminate, pressure_scaling: PressureScaling::Auto };
    let sys = assemble(&body, &material, &c, &opts).unwrap();
    let b = load_vector(
        2,
        &pos,
        &s,
        &Loads {
            acceleration: [0.0; 3],
            down: None,
            density: 0.0,
            forces: &[(0, [0.0, 1680.0, 0.0]), (3, [0.0, 1680.0, 0.0])],
        },
    )
    .unwrap();
    let f = Backend::Structured.solver().unwrap().factorize_default(&sys.matrix).unwrap();
    let (u, p) = sys.split_solution(&f.solve(&sys.rhs(&b, 0.0, &s, 1.0)).unwrap().x);
    assert_eq!(u[2], [0.0, 0.0, 0.0]);
    assert_eq!(u[1][1], 0.0);
    assert!((u[0][0] + 4.0).abs() < 1e-10 && (u[3][1] - 16.0 / 3.0).abs() < 1e-10 && (p - 32.0).abs() < 1e-9);
}

#[test]
fn icosphere_level1_matches_golden_vertex_layout() {
    let m = icosphere(1, 1.0);
    assert_eq!((m.n_vertices(), m.n_faces()), (42, 80));
}

/// The load path pinned to a case computed by hand: three vertices at heights 0, -1 and
/// -2.5 below the top (y up), gravity 10 down, density 1000, so
/// `b_i = rho |a| h_i S_i = 1e4 * (0, 1, 2.5) * S_i`, plus a point force on vertex 1.
/// Unloading (the opposite increment, the same "down") gives exactly the negative.
#[test]
fn hydrostatic_load_by_hand() {
    let pos = [[0.0, 0.0, 0.0], [3.0, -1.0, 0.0], [-1.0, -2.5, 2.0]];
    let s = [[0.5, 1.0, 0.0], [0.0, -2.0, 1.0], [1.5, 0.25, -4.0]];
    let force = [(1, [7.0, 0.0, -3.0])];
    let g = [0.0, -10.0, 0.0];
    let b = load_vector(3, &pos, &s, &Loads { acceleration: g, down: None, density: 1000.0, forces: &force })
        .unwrap();
    let h = [0.0, 1.0, 2.5];
    for i in 0..3 {
        for c in 0..3 {
            let mut expected = 1e4 * h[i] * s[i][c];
            if i == 1 {
                expected += force[0].1[c];
            }
            assert_eq!(b[c * 3 + i], expected, "vertex {i}, axis {c}");
        }
    }
    let unload = load_vector(
        3,
        &pos,
        &s,
        &Loads { acceleration: [0.0, 10.0, 0.0], down: Some(g), density: 1000.0, forces: &[] },
    )
    .unwrap();
    for i in 0..3 {
        for c in 0..3 {
            assert_eq!(unload[c * 3 + i], -1e4 * h[i] * s[i][c]);
        }
    }
    // Tilted gravity (3, -4, 0), |a| = 5: depth along (-0.6, 0.8, 0) from the top vertex.
    let tilted = load_vector(
        3,
        &pos,
        &s,
        &Loads { acceleration: [3.0, -4.0, 0.0], down: None, density: 2.0, forces: &[] },
    )
    .unwrap();
    let up = [-0.6, 0.8, 0.0];
    let height: Vec<f64> = pos.iter().map(|p| p[0] * up[0] + p[1] * up[1]).collect();
    let top = height.iter().copied().fold(f64::MIN, f64::max);
    for i in 0..3 {
        let expected = 2.0 * 5.0 * (top - height[i]) * s[i][1];
        assert!((tilted[3 + i] - expected).abs() <= 1e-12 * expected.abs().max(1.0), "vertex {i}");
    }
    // A force on a vertex the body does not have is an error, not a panic.
    assert!(load_vector(3, &pos, &s, &Loads { forces: &[(3, [1.0; 3])], ..Default::default() }).is_err());
}
