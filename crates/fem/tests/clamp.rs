//! The clamp's penalty: its stated slip bound.

use fibfluid_fem::{CLAMP_PENALTY, FemBody, FemOptions, Loads, Tissue, fixed_surface_samples};
use fibfluid_geometry::icosphere;
use fibfluid_geometry::vec3::{cross, norm, sub};

/// The penalty forces carry the whole load, so the area-weighted mean slip of the clamped
/// surface along the load is `W h / (CLAMP_PENALTY * E * A)` for weight `W` and clamp area
/// `A` (see `CLAMP_PENALTY`). Checked on the sphere hanging from its cap y > 0.8 at
/// resolution 16 by integrating the computed displacement over the fixed triangles with a
/// finer rule than the penalty's (so to 5 %), and the slip is small against the sag.
#[test]
fn clamp_slip_matches_its_bound() {
    let mesh = icosphere(3, 1.0);
    let (pos, tris) = (mesh.positions(), mesh.triangles());
    let fixed: Vec<[bool; 3]> = pos.iter().map(|p| [p[1] > 0.8; 3]).collect();
    let tissue = Tissue::new(5e4, 0.45, 1000.0).unwrap();
    let opts = FemOptions { resolution: 16, ..Default::default() };
    let mut body = FemBody::from_surface(pos, tris, &tissue, &fixed, &opts).unwrap();
    let g = 9.81;
    let s = body.solve(&Loads { gravity: [0.0, -g, 0.0], ..Default::default() }).unwrap();
    let grid = body.grid();
    let h = grid.cell_size();
    let (mut area, mut integral) = (0.0, 0.0);
    for t in tris.iter().filter(|t| t.iter().all(|&v| fixed[v as usize][1])) {
        let c = t.map(|v| pos[v as usize]);
        let a = 0.5 * norm(cross(sub(c[1], c[0]), sub(c[2], c[0])));
        let samples = fixed_surface_samples(c, h / 8.0);
        // A point in a cell with no inside sample and no vertex is off the grid (rare).
        for e in samples.iter().filter_map(|p| grid.locate(*p)) {
            let uy: f64 = (0..8).map(|b| e.weights[b] * s.node_displacements[e.nodes[b]][1]).sum();
            integral += a / samples.len() as f64 * uy;
        }
        area += a;
    }
    let weight = tissue.density() * g * grid.filled_volume();
    let predicted = weight * h / (CLAMP_PENALTY * tissue.young() * area);
    let slip = -integral / area;
    let sag = -s.surface_displacements.iter().map(|u| u[1]).sum::<f64>() / pos.len() as f64;
    eprintln!("clamp slip {slip:.4e}, predicted {predicted:.4e}, mean sag {sag:.4e}");
    assert!((slip / predicted - 1.0).abs() < 0.05, "slip {slip}, predicted {predicted}");
    assert!(slip < 0.1 * sag);
}
