//! Held vertices by capacitance on the kept factor: targets met exactly, reactions
//! consistent with a plain solve, compliance columns cached; several loads in one pass.

use crate::common::*;
use fibfluid_fem::{FemBody, FemOptions, Loads, Tissue};
use fibfluid_geometry::icosphere;

fn sphere_body(resolution: usize) -> (Vec<V3>, FemBody) {
    let mesh = icosphere(2, 1.0);
    let pos = mesh.positions().to_vec();
    let fixed: Vec<[bool; 3]> = pos.iter().map(|p| [p[1] > 0.8; 3]).collect();
    let tissue = Tissue::new(3e3, 0.49, 1000.0).unwrap();
    let opts = FemOptions { resolution, ..Default::default() };
    let body = FemBody::from_surface(&pos, mesh.triangles(), &tissue, &fixed, &opts).unwrap();
    (pos, body)
}

/// Two vertices held under gravity: each moves to its target to 1e-9 relative; applying the
/// returned reactions as point forces in a plain solve reproduces the same surface
/// displacement (1e-8 relative), which it would not if a reaction were wrong in sign, size
/// or spreading.
#[test]
fn held_vertices_meet_targets_and_reactions_reproduce_them() {
    let (pos, mut body) = sphere_body(12);
    let lowest = (0..pos.len()).min_by(|&a, &b| pos[a][1].total_cmp(&pos[b][1])).unwrap();
    let side = (0..pos.len()).max_by(|&a, &b| pos[a][0].total_cmp(&pos[b][0])).unwrap();
    let held = [(lowest, [0.05, -0.1, 0.02]), (side, [0.1, 0.0, -0.03])];
    let gravity = Loads { gravity: [0.0, -10.0, 0.0], point_forces: vec![(7, [0.5, 0.0, 0.0])] };
    let r = body.respond_held(&gravity, &held).unwrap();
    assert_eq!(body.cached_holds(), 2);
    for (k, (v, target)) in held.iter().enumerate() {
        let got = r.surface_displacements[*v];
        let err = norm([0, 1, 2].map(|c| got[c] - target[c]));
        assert!(err <= 1e-9 * norm(*target), "vertex {v}: {got:?} vs {target:?}");
        assert!(norm(r.reactions[k]) > 0.0);
    }
    let mut forces = gravity.clone();
    forces.point_forces.extend(held.iter().zip(&r.reactions).map(|((v, _), f)| (*v, *f)));
    let plain = body.solve(&forces).unwrap();
    let diff = rel_l2(&plain.surface_displacements, &r.surface_displacements, |_| true);
    assert!(diff < 1e-8, "plain solve with the reactions differs by {diff:e}");
    // A second frame with one more vertex reuses the two cached columns.
    let more = [held[0], held[1], (3, [0.0, 0.0, 0.0])];
    let r2 = body.respond_held(&gravity, &more).unwrap();
    assert_eq!(body.cached_holds(), 3);
    assert!(norm(r2.surface_displacements[3]) <= 1e-12);
}

/// `solve_many` gives, column by column, what `solve` gives one load at a time.
#[test]
fn solve_many_matches_single_solves() {
    let (_, mut body) = sphere_body(10);
    let loads = vec![
        Loads { gravity: [0.0, -9.81, 0.0], ..Default::default() },
        Loads { point_forces: vec![(20, [1.0, 2.0, -1.0])], ..Default::default() },
        Loads { gravity: [1.0, 0.0, 0.0], point_forces: vec![(50, [0.0, 0.0, 3.0])] },
    ];
    let many = body.solve_many(&loads).unwrap();
    for (l, m) in loads.iter().zip(&many) {
        let one = body.solve(l).unwrap();
        assert!(rel_l2(&m.surface_displacements, &one.surface_displacements, |_| true) < 1e-12);
        assert!(m.residual < 1e-10);
    }
    let s = body.stats();
    assert!(s.dofs > 0 && s.nonzeros > s.dofs && s.factor_nonzeros >= s.nonzeros);
}

/// A patch of many vertices in few cells held at the targets of one rigid motion: its rows
/// are answered from the free dofs they touch (fewer columns than 3 per vertex, as
/// `cached_bytes` shows), every vertex meets its target to the holds' constraint tolerance (1e-9 m: the rows
/// are dependent, more vertices than nodes in a cell), and the reactions applied
/// as point forces in a plain solve reproduce the surface (1e-8).
#[test]
fn a_patch_is_held_from_the_dofs_it_touches() {
    let mesh = icosphere(3, 1.0);
    let pos = mesh.positions().to_vec();
    let fixed: Vec<[bool; 3]> = pos.iter().map(|p| [p[1] > 0.8; 3]).collect();
    let tissue = Tissue::new(3e3, 0.45, 1000.0).unwrap();
    let opts = FemOptions { resolution: 6, ..Default::default() };
    let mut body = FemBody::from_surface(&pos, mesh.triangles(), &tissue, &fixed, &opts).unwrap();
    let bottom = (0..pos.len()).min_by(|&a, &b| pos[a][1].total_cmp(&pos[b][1])).unwrap();
    let near = |v: usize| norm([0, 1, 2].map(|a| pos[v][a] - pos[bottom][a])) <= 0.35;
    let patch: Vec<usize> = (0..pos.len()).filter(|&v| near(v)).collect();
    assert!(patch.len() >= 10, "{} vertices", patch.len());
    let held: Vec<(usize, [f64; 3])> =
        patch.iter().map(|&v| (v, [0.01, 0.02 + 0.05 * pos[v][0], 0.0])).collect();
    let gravity = Loads { gravity: [0.0, -10.0, 0.0], point_forces: vec![] };
    let r = body.respond_held(&gravity, &held).unwrap();
    let dofs = body.stats().dofs;
    assert!(
        body.cached_bytes() < 8 * 3 * patch.len() * dofs,
        "{} bytes for {} vertices",
        body.cached_bytes(),
        patch.len()
    );
    for (v, target) in &held {
        let got = r.surface_displacements[*v];
        let err = norm([0, 1, 2].map(|c| got[c] - target[c]));
        // Dependent rows (more vertices than nodes in a cell) are met to the ridge's
        // rounding, within the holds' constraint tolerance (1e-9 m for targets below 1 m).
        assert!(err <= 1e-9, "vertex {v}: {err:e}");
    }
    let mut forces = gravity.clone();
    forces.point_forces.extend(held.iter().zip(&r.reactions).map(|((v, _), f)| (*v, *f)));
    let plain = body.solve(&forces).unwrap();
    let diff = rel_l2(&plain.surface_displacements, &r.surface_displacements, |_| true);
    assert!(diff < 1e-8, "plain solve with the reactions differs by {diff:e}");
}
