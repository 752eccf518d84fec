//! Against an independent FEM: quadratic tetrahedra (scikit-fem on a TetGen mesh of the same
//! surface, same E, nu, rho, gravity and clamps; `tools/reference.py`, see
//! `tests/golden/README.md`). The relative L2 error of the surface displacement, no scaling.

use std::path::PathBuf;

use crate::common::*;
use fibfluid_fem::{DEFAULT_RESOLUTION, FemBody, FemOptions, Loads, Tissue};
use fibfluid_geometry::load_mesh;

struct Case {
    mesh: &'static str,
    golden: &'static str,
    /// Which vertices are fixed, from the rest positions.
    fixed: fn(&[V3]) -> Vec<[bool; 3]>,
}

const SPHERE: Case = Case {
    mesh: "icosphere-3.obj",
    golden: "sphere-gravity.txt",
    fixed: |pos| pos.iter().map(|p| [p[1] > 0.8; 3]).collect(),
};

const LIVER: Case = Case {
    mesh: "liver2.obj",
    golden: "liver2-hanging.txt",
    fixed: |pos| {
        let top = pos.iter().map(|p| p[1]).fold(f64::MIN, f64::max);
        pos.iter().map(|p| [p[1] >= top - 0.08; 3]).collect()
    },
};

const SPOT: Case = Case {
    mesh: "spot.obj",
    golden: "spot-standing.txt",
    fixed: |pos| {
        let bottom = pos.iter().map(|p| p[1]).fold(f64::MAX, f64::min);
        pos.iter().map(|p| [p[1] <= bottom + 0.08; 3]).collect()
    },
};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Relative L2 error of our surface displacement at `resolution` against the golden file.
fn error(case: &Case, resolution: usize) -> f64 {
    let file = load_mesh(root().join("../../fixtures/meshes").join(case.mesh)).unwrap();
    assert_eq!(file.file_vertex_count(), file.mesh.n_vertices(), "every file vertex is used");
    let dir = std::env::var("GOLDEN_DIR").map(PathBuf::from).unwrap_or_else(|_| root().join("tests/golden"));
    let golden: Vec<V3> = std::fs::read_to_string(dir.join(case.golden))
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            [v[0], v[1], v[2]]
        })
        .collect();
    let pos = file.mesh.positions();
    assert_eq!(golden.len(), pos.len());
    let tissue = Tissue::new(5e4, 0.45, 1000.0).unwrap();
    let opts = FemOptions { resolution, ..Default::default() };
    let mut body =
        FemBody::from_surface(pos, file.mesh.triangles(), &tissue, &(case.fixed)(pos), &opts).unwrap();
    let s = body.solve(&Loads { gravity: [0.0, -9.81, 0.0], ..Default::default() }).unwrap();
    // Our vertex i is file vertex from_file_index(i).
    let ours: Vec<V3> = (0..pos.len()).map(|i| s.surface_displacements[i]).collect();
    let theirs: Vec<V3> = (0..pos.len()).map(|i| golden[file.from_file_index(i).unwrap()]).collect();
    let e = rel_l2(&ours, &theirs, |_| true);
    let mean = |u: &[V3]| u.iter().map(|x| x[1]).sum::<f64>() / u.len() as f64;
    let st = body.stats();
    eprintln!(
        "{}: resolution {resolution}: relative L2 error {e:.4}, mean u_y ratio {:.3}, dofs {} factor {:.2}s",
        case.mesh,
        mean(&ours) / mean(&theirs),
        st.dofs,
        st.factor_seconds
    );
    e
}

/// The measurements behind `docs/fem.md` (slow: run with `--ignored --nocapture`).
#[test]
#[ignore]
fn measure_errors_against_reference() {
    let res: Vec<usize> = std::env::var("FEM_RES")
        .unwrap_or_else(|_| "8,12,16,20,24,32".into())
        .split(',')
        .map(|x| x.parse().unwrap())
        .collect();
    let which = std::env::var("FEM_CASES").unwrap_or_else(|_| "sphere,liver".into());
    for case in [&SPHERE, &LIVER, &SPOT] {
        if !which.contains(case.golden.split('-').next().unwrap()) {
            continue;
        }
        for &r in &res {
            error(case, r);
        }
    }
}

/// The sphere under gravity at resolutions 8, 16 and 24: the error against the reference
/// falls at each step (measured 0.43, 0.33, 0.19).
#[test]
fn sphere_error_falls_with_resolution() {
    let e: Vec<f64> = [8, 16, 24].iter().map(|&r| error(&SPHERE, r)).collect();
    assert!(e[1] < e[0] && e[2] < e[1], "{e:?}");
}

/// At the default resolution the errors are what `docs/fem.md` reports (sphere 0.33,
/// liver 0.47; the 15 % target is NOT met, these bounds only catch regressions), and
/// doubling the resolution is no worse (liver 0.47 -> 0.31; the sphere's doubling, 0.33 ->
/// 0.12, takes 14 s and is in `measure_errors_against_reference`).
#[test]
fn default_resolution_against_reference() {
    assert_eq!(DEFAULT_RESOLUTION, 16);
    let liver = error(&LIVER, DEFAULT_RESOLUTION);
    let liver2x = error(&LIVER, 2 * DEFAULT_RESOLUTION);
    assert!(liver < 0.5 && liver2x <= liver, "{liver} then {liver2x}");
    assert!(error(&SPHERE, DEFAULT_RESOLUTION) < 0.35);
}
