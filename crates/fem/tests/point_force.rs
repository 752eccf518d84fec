//! A point force on the sphere: the displacement away from the load converges.

use crate::common::*;
use fibfluid_fem::{FemBody, FemOptions, Loads, Tissue};
use fibfluid_geometry::icosphere;

/// The unit sphere (642 vertices) clamped on its cap y > 0.8, pulled down by 1 N at its
/// lowest vertex: the surface displacement at `resolution`, and the far-field mask (vertices
/// more than 0.5 from the load).
fn pulled(resolution: usize) -> (Vec<V3>, Vec<bool>) {
    let mesh = icosphere(3, 1.0);
    let pos = mesh.positions();
    let fixed: Vec<[bool; 3]> = pos.iter().map(|p| [p[1] > 0.8; 3]).collect();
    let tissue = Tissue::new(5e4, 0.45, 1000.0).unwrap();
    let opts = FemOptions { resolution, ..Default::default() };
    let mut body = FemBody::from_surface(pos, mesh.triangles(), &tissue, &fixed, &opts).unwrap();
    let low = (0..pos.len()).min_by(|&a, &b| pos[a][1].total_cmp(&pos[b][1])).unwrap();
    let s = body.solve(&Loads { point_forces: vec![(low, [0.0, -1.0, 0.0])], ..Default::default() }).unwrap();
    let far = pos.iter().map(|p| norm([0, 1, 2].map(|c| p[c] - pos[low][c])) > 0.5).collect();
    (s.surface_displacements, far)
}

/// The exact displacement under a point force is unbounded at the load (`~ 1 / r`), so the
/// surface displacement near it cannot converge: between resolutions 8, 16, 32 the vertices
/// within 0.5 of the load changed by 54 % then 49 % (order 0.16). Away from the load it
/// does: the far vertices changed by 4.9 % then 1.6 % (observed order 1.65, between Q1's
/// O(h) gradient and O(h^2) displacement rates, with the O(h) clamp slip and fill-fraction
/// geometry). Asserted: far-field order above 1.2 and the last change below 3 %.
#[test]
#[ignore = "long run: CI runs it with `cargo test --workspace -- --ignored long_`"]
fn long_point_force_far_field_converges() {
    let runs: Vec<(Vec<V3>, Vec<bool>)> = [8, 16, 32].iter().map(|&r| pulled(r)).collect();
    let far = &runs[0].1;
    let d1 = rel_l2(&runs[0].0, &runs[1].0, |i| far[i]);
    let d2 = rel_l2(&runs[1].0, &runs[2].0, |i| far[i]);
    let n1 = rel_l2(&runs[0].0, &runs[1].0, |i| !far[i]);
    let n2 = rel_l2(&runs[1].0, &runs[2].0, |i| !far[i]);
    eprintln!("far field: |u8-u16| {d1:.4}, |u16-u32| {d2:.4}, order {:.2}", (d1 / d2).log2());
    eprintln!("near load: |u8-u16| {n1:.4}, |u16-u32| {n2:.4}, order {:.2}", (n1 / n2).log2());
    assert!((d1 / d2).log2() > 1.2 && d2 < 0.03, "far field {d1} then {d2}");
}
