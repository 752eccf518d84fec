//! The nested-dissection ordering against faer's AMD: the same solution, less fill.

use crate::common::*;
use fibfluid_fem::{Element, FemBody, FemStats, Loads, Ordering, SparseGrid, Tissue};
use fibfluid_geometry::icosphere;

/// The unit sphere (642 vertices) clamped on its cap y > 0.8, at `resolution`, factored with
/// `ordering`; its stats and surface displacement under gravity.
fn sphere(resolution: usize, ordering: Ordering) -> (FemStats, Vec<V3>) {
    let mesh = icosphere(3, 1.0);
    let pos = mesh.positions();
    let fixed: Vec<[bool; 3]> = pos.iter().map(|p| [p[1] > 0.8; 3]).collect();
    let tissue = Tissue::new(5e4, 0.45, 1000.0).unwrap();
    let grid = SparseGrid::from_surface(pos, mesh.triangles(), resolution).unwrap();
    let mut body = FemBody::with_ordering(grid, &tissue, &fixed, Element::BBar, ordering).unwrap();
    let s = body.solve(&Loads { gravity: [0.0, -9.81, 0.0], ..Default::default() }).unwrap();
    (body.stats(), s.surface_displacements)
}

/// Resolution 16: both orderings give the same displacement (1e-10 relative) and nested
/// dissection stores fewer factor values than AMD.
#[test]
fn nested_dissection_matches_amd_with_less_fill() {
    let (nd, u_nd) = sphere(16, Ordering::NestedDissection);
    let (amd, u_amd) = sphere(16, Ordering::Amd);
    eprintln!("factor values: nested dissection {}, AMD {}", nd.factor_nonzeros, amd.factor_nonzeros);
    assert!(rel_l2(&u_nd, &u_amd, |_| true) < 1e-10);
    assert!(nd.factor_nonzeros < amd.factor_nonzeros);
}

/// The factor-time table of `docs/fem.md` (slow: run with `--ignored --nocapture`;
/// `FEM_RES` overrides the resolutions, e.g. `FEM_RES=16,24,32,48`).
#[test]
#[ignore]
fn measure_factor_time() {
    let res: Vec<usize> = std::env::var("FEM_RES")
        .unwrap_or_else(|_| "16,24,32".into())
        .split(',')
        .map(|x| x.parse().unwrap())
        .collect();
    for ordering in [Ordering::NestedDissection, Ordering::Amd] {
        for &r in &res {
            let (s, _) = sphere(r, ordering);
            eprintln!(
                "{ordering:?} resolution {r}: dofs {}, factor values {:.1} M, factor {:.2} s",
                s.dofs,
                s.factor_nonzeros as f64 * 1e-6,
                s.factor_seconds
            );
        }
    }
}
