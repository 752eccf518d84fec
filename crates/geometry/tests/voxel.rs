//! Lattice inside tests: exact answers on a cube whose faces pass through lattice lines and
//! points, the sphere's volume from the inside fraction, and agreement with an independent
//! generalized winding number (solid angles) on a concave fixture.

use crate::common::*;
use fibfluid_geometry::{PointLattice, icosphere, inside_lattice};

/// Generalized winding number by Van Oosterom & Strackee's solid angles: a second,
/// independent inside test (±1 inside, 0 outside).
fn winding(p: V3, pos: &[V3], tris: &[[u32; 3]]) -> f64 {
    let sub = |a: V3, b: V3| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let dot = |a: V3, b: V3| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let cross =
        |a: V3, b: V3| [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
    let mut total = 0.0;
    for t in tris {
        let [a, b, c] = t.map(|v| sub(pos[v as usize], p));
        let (la, lb, lc) = (dot(a, a).sqrt(), dot(b, b).sqrt(), dot(c, c).sqrt());
        let den = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb;
        total += 2.0 * dot(a, cross(b, c)).atan2(den);
    }
    total / (4.0 * std::f64::consts::PI)
}

/// The 12-triangle cube [0, 2]^3, outward.
fn cube() -> (Vec<V3>, Vec<[u32; 3]>) {
    let p: Vec<V3> = (0..8)
        .map(|b| [2.0 * (b & 1) as f64, 2.0 * ((b >> 1) & 1) as f64, 2.0 * ((b >> 2) & 1) as f64])
        .collect();
    let t = vec![
        [0, 2, 3],
        [0, 3, 1],
        [4, 5, 7],
        [4, 7, 6],
        [0, 1, 5],
        [0, 5, 4],
        [2, 6, 7],
        [2, 7, 3],
        [0, 4, 6],
        [0, 6, 2],
        [1, 3, 7],
        [1, 7, 5],
    ];
    (p, t)
}

/// Lattice lines run along the cube's faces, its edges and its face diagonals (where two
/// triangles meet): each point strictly inside is inside, each strictly outside is outside,
/// whatever the orientation of the surface. The points on the boundary get one consistent
/// answer per line (no double count), which shows as a strictly inside point never being
/// reported outside.
#[test]
fn cube_lines_through_edges_and_diagonals() {
    let (p, t) = cube();
    let lattice = PointLattice { origin: [-1.0, -1.0, -1.0], spacing: 0.5, dims: [9, 9, 9] };
    let flipped: Vec<[u32; 3]> = t.iter().map(|&[a, b, c]| [a, c, b]).collect();
    for tris in [&t, &flipped] {
        let inside = inside_lattice(&p, tris, &lattice).unwrap();
        for k in 0..9 {
            for j in 0..9 {
                for i in 0..9 {
                    let x = [i, j, k].map(|n| -1.0 + 0.5 * n as f64);
                    let strictly_in = x.iter().all(|&v| v > 0.0 && v < 2.0);
                    let strictly_out = x.iter().any(|&v| !(0.0..=2.0).contains(&v));
                    let got = inside[i + 9 * (j + 9 * k)];
                    if strictly_in {
                        assert!(got, "{x:?} is inside");
                    }
                    if strictly_out {
                        assert!(!got, "{x:?} is outside");
                    }
                }
            }
        }
    }
}

/// The inside fraction of a fine lattice over the unit sphere (icosphere level 4) matches
/// the polyhedron's exact volume to the lattice's resolution (1 % at 64 points across).
#[test]
fn sphere_volume_from_inside_fraction() {
    let m = icosphere(4, 1.0);
    let n = 64;
    let h = 2.0 / n as f64;
    let lattice = PointLattice { origin: [-1.0 + 0.5 * h; 3], spacing: h, dims: [n; 3] };
    let inside = inside_lattice(m.positions(), m.triangles(), &lattice).unwrap();
    let v = inside.iter().filter(|&&b| b).count() as f64 * h * h * h;
    let exact = m.volume();
    assert!((v - exact).abs() < 0.01 * exact, "lattice volume {v} vs polyhedron {exact}");
}

/// On the concave liver (SOFA's liver2), every lattice point gets the same answer as the
/// solid-angle winding number, away from the surface where that number is not near 1/2.
#[test]
fn liver_agrees_with_winding_number() {
    let f = load("liver2.obj");
    let (pos, tris) = (f.mesh.positions(), f.mesh.triangles());
    let (lo, hi) = fibfluid_geometry::bounding_box(pos);
    let n = 14;
    let h = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max) / n as f64;
    let lattice = PointLattice { origin: lo, spacing: h, dims: [n + 1; 3] };
    let inside = inside_lattice(pos, tris, &lattice).unwrap();
    let (mut checked, mut n_in) = (0, 0);
    for k in 0..=n {
        for j in 0..=n {
            for i in 0..=n {
                let x = [lo[0] + i as f64 * h, lo[1] + j as f64 * h, lo[2] + k as f64 * h];
                let w = winding(x, pos, tris);
                if (w.abs() - 0.5).abs() < 0.1 {
                    continue;
                }
                checked += 1;
                n_in += (w.abs() > 0.5) as usize;
                assert_eq!(inside[i + (n + 1) * (j + (n + 1) * k)], w.abs() > 0.5, "{x:?}: winding {w}");
            }
        }
    }
    assert!(checked > 3000 && n_in > 300, "{checked} points checked, {n_in} inside");
}

/// A triangle index out of range is an error, not a panic.
#[test]
fn bad_index_is_an_error() {
    let (p, mut t) = cube();
    t[3][1] = 99;
    let lattice = PointLattice { origin: [0.0; 3], spacing: 1.0, dims: [2, 2, 2] };
    assert!(inside_lattice(&p, &t, &lattice).is_err());
}
