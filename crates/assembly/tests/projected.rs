//! The projected fiber model: rigid motions in the null space, symmetry, and the coupled
//! bordered solve.

use faer::Mat;
use fibfluid_assembly::{
    AssemblyOptions, Body, ConstraintMethod, Constraints, Loads, Material, PressureScaling, Selector,
    assemble, assemble_projected, load_vector, projected_stiffness,
};
use fibfluid_geometry::{FiberSet, TriMesh, VisibilityOptions, cull_fibers, icosphere, load_mesh};
use fibfluid_linalg::{CoupledCholesky, FactorOptions};

/// A body's data, owned.
struct Owned {
    pos: Vec<[f64; 3]>,
    s: Vec<[f64; 3]>,
    edges: Vec<[u32; 2]>,
    fibers: FiberSet,
}

impl Owned {
    fn of(mesh: &TriMesh, fibers: FiberSet) -> Self {
        Self {
            pos: mesh.positions().to_vec(),
            s: mesh.vertex_area_vectors(),
            edges: mesh.adjacency().edges(),
            fibers,
        }
    }

    fn body(&self) -> Body<'_> {
        Body {
            axes: 3,
            positions: &self.pos,
            vertex_areas: &self.s,
            edges: &self.edges,
            fibers: &self.fibers,
            rest_positions: None,
        }
    }
}

fn sphere() -> Owned {
    let m = icosphere(2, 1.0);
    let n = m.n_vertices();
    Owned::of(&m, FiberSet::all(n))
}

/// A concave body whose fibers are culled (liver.obj, N = 139).
fn liver() -> Owned {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meshes/liver.obj");
    let mesh = load_mesh(path).unwrap().mesh;
    let fibers = cull_fibers(&mesh, &VisibilityOptions::default()).0;
    assert!(fibers.kept() < fibers.total(), "liver.obj is concave");
    Owned::of(&mesh, fibers)
}

/// The six rigid motions of `pos` (axis-major): three translations, three infinitesimal
/// rotations `omega x (s_i - center)`.
fn rigid_motions(pos: &[[f64; 3]], center: [f64; 3]) -> Vec<Vec<f64>> {
    let n = pos.len();
    let mut out = Vec::new();
    for c in 0..3 {
        let mut r = vec![0.0; 3 * n];
        r[c * n..(c + 1) * n].fill(1.0);
        out.push(r);
    }
    for w in 0..3 {
        let mut omega = [0.0; 3];
        omega[w] = 1.0;
        let mut r = vec![0.0; 3 * n];
        for (i, p) in pos.iter().enumerate() {
            let d = [p[0] - center[0], p[1] - center[1], p[2] - center[2]];
            let v = [
                omega[1] * d[2] - omega[2] * d[1],
                omega[2] * d[0] - omega[0] * d[2],
                omega[0] * d[1] - omega[1] * d[0],
            ];
            for c in 0..3 {
                r[c * n + i] = v[c];
            }
        }
        out.push(r);
    }
    out
}

fn mul(k: &Mat<f64>, r: &[f64]) -> Vec<f64> {
    (0..k.nrows()).map(|i| (0..k.ncols()).map(|j| k[(i, j)] * r[j]).sum()).collect()
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

fn frobenius(k: &Mat<f64>) -> f64 {
    (0..k.ncols()).map(|j| k.col(j).iter().map(|x| x * x).sum::<f64>()).sum::<f64>().sqrt()
}

/// `|K r| / (|K|_F |r|)`.
fn relative_image(k: &Mat<f64>, r: &[f64]) -> f64 {
    norm(&mul(k, r)) / (frobenius(k) * norm(r))
}

/// Translations and rotations are in the null space of the unconstrained projected
/// stiffness, on a convex body with surface fibers and on a concave one (culled fibers).
#[test]
fn rigid_motions_cost_nothing() {
    for (name, owned, gamma) in [("sphere", sphere(), 3000.0), ("liver", liver(), 0.0)] {
        let k = projected_stiffness(&owned.body(), &Material::isotropic(3000.0, gamma, 1000.0)).unwrap();
        let n = owned.pos.len();
        assert_eq!((k.nrows(), k.ncols()), (3 * n, 3 * n));
        for i in 0..3 * n {
            for j in 0..i {
                assert_eq!(k[(i, j)].to_bits(), k[(j, i)].to_bits(), "{name}: K[{i}][{j}] not symmetric");
            }
        }
        for (m, r) in rigid_motions(&owned.pos, [0.3, -0.2, 0.1]).iter().enumerate() {
            let e = relative_image(&k, r);
            assert!(e < 1e-13, "{name}: rigid motion {m}: |K r| / (|K| |r|) = {e:e}");
        }
        // A stretch is not free.
        let stretch: Vec<f64> = (0..3 * n).map(|k| if k < n { owned.pos[k][0] } else { 0.0 }).collect();
        assert!(relative_image(&k, &stretch) > 1e-3);
    }
}

/// With vertex 0 fixed, a rotation about it is free for the projected fibers but not for
/// the paper's (per-axis Laplacians): the paper's K resists it at the order of |K| |r|.
#[test]
fn the_papers_fibers_resist_a_rotation() {
    let owned = sphere();
    let n = owned.pos.len();
    let mut constraints = Constraints::new(n);
    constraints.fix(0, [true; 3]).unwrap();
    let material = Material::isotropic(3000.0, 3000.0, 1000.0);
    let opts =
        AssemblyOptions { method: ConstraintMethod::Eliminate, pressure_scaling: PressureScaling::None };
    let projected = assemble_projected(&owned.body(), &material, &constraints, &opts).unwrap();
    let paper = assemble(&owned.body(), &material, &constraints, &opts).unwrap();
    for (m, r) in rigid_motions(&owned.pos, owned.pos[0]).iter().enumerate().skip(3) {
        // The rotation vanishes at vertex 0, so elimination does not change K r elsewhere.
        let e_projected = relative_image(&projected.stiffness, r);
        let kr_paper: Vec<f64> =
            (0..3).flat_map(|c| mul(paper.matrix.block(c), &r[c * n..(c + 1) * n])).collect();
        let k_paper = (0..3).map(|c| frobenius(paper.matrix.block(c)).powi(2)).sum::<f64>().sqrt();
        let e_paper = norm(&kr_paper) / (k_paper * norm(r));
        assert!(e_projected < 1e-13, "rotation {m}: projected {e_projected:e}");
        // Ten orders of magnitude above rounding (measured 1.6e-3 for the rotation about x).
        assert!(e_paper > 1e-4, "rotation {m}: paper {e_paper:e}");
    }
}

/// The coupled solve (Cholesky + Schur complement) satisfies the bordered system, with
/// either constraint method.
#[test]
fn the_coupled_solve_satisfies_the_bordered_system() {
    let owned = sphere();
    let n = owned.pos.len();
    let mut constraints = Constraints::new(n);
    constraints.fix_selected(&Selector::Above { axis: 1, value: 0.8 }, &owned.pos, [true; 3]).unwrap();
    let material = Material::isotropic(3000.0, 3000.0, 1000.0);
    let loads =
        Loads { acceleration: [0.0, -10.0, 0.0], down: None, density: 1000.0, forces: &[(3, [-300.0; 3])] };
    let b = load_vector(3, &owned.pos, &owned.s, &loads).unwrap();
    for method in [ConstraintMethod::Eliminate, ConstraintMethod::PAPER] {
        let opts = AssemblyOptions { method, pressure_scaling: PressureScaling::Auto };
        let sys = assemble_projected(&owned.body(), &material, &constraints, &opts).unwrap();
        let rhs = sys.rhs(&b, 0.0, &owned.s, 1.0);
        let k = sys.stiffness.clone();
        let factor =
            CoupledCholesky::factor(sys.stiffness.clone(), sys.border.clone(), &FactorOptions::default())
                .unwrap();
        let sol = factor.solve(&rhs).unwrap();
        assert!(sol.relative_residual < 1e-12, "{method:?}: {}", sol.relative_residual);
        let (u, p) = sys.split_solution(&sol.x);
        let x: Vec<f64> = (0..3).flat_map(|c| u.iter().map(move |v| v[c])).collect();
        let ku = mul(&k, &x);
        let r: Vec<f64> = (0..3 * n).map(|i| rhs[i] - ku[i] - sys.border[i] * p).collect();
        assert!(norm(&r) <= 1e-10 * norm(&rhs), "{method:?}: |r| = {:e}", norm(&r));
        let volume: f64 = sys.border.iter().zip(&x).map(|(s, v)| s * v).sum();
        assert!(volume.abs() <= 1e-12 * norm(&sys.border) * norm(&x), "{method:?}: S.u = {volume:e}");
        // Fixed vertices stay (to the penalty's 1 / big).
        let largest = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for i in (0..n).filter(|&i| owned.pos[i][1] > 0.8) {
            assert!(
                u[i].iter().all(|v| v.abs() < 1e-4 * largest),
                "{method:?}: vertex {i} moved: {:?}",
                u[i]
            );
        }
        // The body sags.
        assert!(u.iter().map(|v| v[1]).sum::<f64>() < 0.0);
    }
}

/// A new border on the kept factor (refresh mode) solves what a fresh factorization with
/// that border solves; a zero border is refused and leaves the factorization as it was.
#[test]
fn a_new_border_on_the_kept_factor_matches_a_fresh_factorization() {
    let owned = sphere();
    let n = owned.pos.len();
    let mut constraints = Constraints::new(n);
    constraints.fix_selected(&Selector::Above { axis: 1, value: 0.8 }, &owned.pos, [true; 3]).unwrap();
    let material = Material::isotropic(3000.0, 3000.0, 1000.0);
    let opts =
        AssemblyOptions { method: ConstraintMethod::Eliminate, pressure_scaling: PressureScaling::None };
    let sys = assemble_projected(&owned.body(), &material, &constraints, &opts).unwrap();
    // Another shape's area vectors: the sphere stretched along y.
    let other: Vec<[f64; 3]> = owned.s.iter().map(|a| [a[0] * 1.1, a[1] * 0.9, a[2] * 1.1]).collect();
    let border = sys.border_for(&other);
    let fixed = |k: usize| constraints.get(k % n, k / n).is_some();
    assert!((0..3 * n).all(|k| if fixed(k) { border[k] == 0.0 } else { border[k] == other[k % n][k / n] }));
    let mut kept =
        CoupledCholesky::factor(sys.stiffness.clone(), sys.border.clone(), &FactorOptions::default())
            .unwrap();
    let before = kept.schur();
    assert!(kept.set_border(vec![0.0; 3 * n]).is_err());
    assert_eq!(kept.schur(), before, "a refused border leaves the factorization as it was");
    kept.set_border(border.clone()).unwrap();
    let fresh = CoupledCholesky::factor(sys.stiffness.clone(), border, &FactorOptions::default()).unwrap();
    assert!((kept.schur() - fresh.schur()).abs() <= 1e-12 * fresh.schur());
    let rhs: Vec<f64> = (0..=3 * n)
        .map(|i| if fixed(i % (3 * n)) || i == 3 * n { 0.0 } else { ((i * 37) % 11) as f64 - 5.0 })
        .collect();
    let (a, b) = (kept.solve(&rhs).unwrap().x, fresh.solve(&rhs).unwrap().x);
    let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(
        a.iter().zip(&b).all(|(x, y)| (x - y).abs() <= 1e-10 * scale),
        "the kept factor with the new border differs"
    );
}

/// Too few constraints leave a rotation free: the factorization says the system is
/// singular instead of returning garbage.
#[test]
fn a_free_rotation_is_a_singular_system() {
    let owned = sphere();
    let n = owned.pos.len();
    let mut constraints = Constraints::new(n);
    constraints.fix(0, [true; 3]).unwrap();
    let material = Material::isotropic(3000.0, 0.0, 1000.0);
    let opts =
        AssemblyOptions { method: ConstraintMethod::Eliminate, pressure_scaling: PressureScaling::None };
    let sys = assemble_projected(&owned.body(), &material, &constraints, &opts).unwrap();
    let e = CoupledCholesky::factor(sys.stiffness, sys.border, &FactorOptions::default()).unwrap_err();
    assert!(matches!(e, fibfluid_linalg::LinalgError::SingularPivot { .. }), "{e:?}");
}
