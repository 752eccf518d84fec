//! Lattice construction: box counts, voxelization of closed surfaces, errors.

use fibfluid_chainmail::{ChainmailError, Lattice};

/// Closed axis-aligned box surface (12 triangles, outward orientation).
fn box_mesh(lo: [f64; 3], hi: [f64; 3], pos: &mut Vec<[f64; 3]>, tris: &mut Vec<[u32; 3]>) {
    let b = pos.len() as u32;
    for k in 0..8 {
        pos.push([
            if k & 1 == 0 { lo[0] } else { hi[0] },
            if k & 2 == 0 { lo[1] } else { hi[1] },
            if k & 4 == 0 { lo[2] } else { hi[2] },
        ]);
    }
    let quads = [
        [0, 2, 3, 1], // z = lo
        [4, 5, 7, 6], // z = hi
        [0, 1, 5, 4], // y = lo
        [2, 6, 7, 3], // y = hi
        [0, 4, 6, 2], // x = lo
        [1, 3, 7, 5], // x = hi
    ];
    for q in quads {
        tris.push([b + q[0], b + q[1], b + q[2]]);
        tris.push([b + q[0], b + q[2], b + q[3]]);
    }
}

/// UV sphere of radius `r`.
fn sphere_mesh(r: f64, seg: usize, rings: usize) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let mut pos = vec![[0.0, 0.0, r], [0.0, 0.0, -r]];
    for i in 1..rings {
        let th = std::f64::consts::PI * i as f64 / rings as f64;
        for j in 0..seg {
            let ph = 2.0 * std::f64::consts::PI * j as f64 / seg as f64;
            pos.push([r * th.sin() * ph.cos(), r * th.sin() * ph.sin(), r * th.cos()]);
        }
    }
    let v = |i: usize, j: usize| (2 + (i - 1) * seg + j % seg) as u32;
    let mut tris = Vec::new();
    for j in 0..seg {
        tris.push([0, v(1, j), v(1, j + 1)]);
        tris.push([1, v(rings - 1, j + 1), v(rings - 1, j)]);
        for i in 1..rings - 1 {
            tris.push([v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
            tris.push([v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
        }
    }
    (pos, tris)
}

/// Box [3, 4, 5] with spacing 0.5: 60 elements; links 2*4*5 + 3*3*5 + 3*4*4 = 133;
/// 2*3*4 = 24 full cells, 144 tets, rest volume 24 * 0.125 = 3.
#[test]
fn box_counts() {
    let l = Lattice::new_box([3, 4, 5], 0.5, [1.0, 2.0, 3.0]).unwrap();
    assert_eq!(l.len(), 60);
    assert_eq!(l.links().count(), 133);
    assert_eq!(l.tets().len(), 144);
    assert!((l.rest_volume() - 3.0).abs() < 1e-12);
    assert!((l.volume() - 3.0).abs() < 1e-12);
    let e = l.element_at([2, 3, 4]).unwrap();
    assert_eq!(l.grid_coords(e).unwrap(), [2, 3, 4]);
    assert_eq!(l.rest_positions()[e], [2.0, 3.5, 5.0]);
    assert_eq!(l.neighbors(e).unwrap().len(), 3);
    let inner = l.element_at([1, 1, 1]).unwrap();
    assert_eq!(l.neighbors(inner).unwrap().len(), 6);
    assert!(l.element_at([3, 0, 0]).is_none());
    // Every rest offset of a link is one spacing along one axis.
    for (a, b) in l.links() {
        let (pa, pb) = (l.rest_positions()[a], l.rest_positions()[b]);
        let d: f64 = (0..3).map(|k| (pb[k] - pa[k]).abs()).sum();
        assert!((d - 0.5).abs() < 1e-12);
    }
    // Every tet is positively oriented with volume h^3 / 6.
    for t in l.tets() {
        let p: Vec<[f64; 3]> = t.iter().map(|&i| l.rest_positions()[i]).collect();
        let a = [p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]];
        let b = [p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]];
        let c = [p[3][0] - p[0][0], p[3][1] - p[0][1], p[3][2] - p[0][2]];
        let v = (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
            + a[2] * (b[0] * c[1] - b[1] * c[0]))
            / 6.0;
        assert!((v - 0.125 / 6.0).abs() < 1e-12);
    }
}

/// Unit cube at spacing 0.25: 4 cells per axis, centres 0.125 .. 0.875, all inside:
/// 64 elements, 27 full cells, rest volume 27 / 64.
#[test]
fn voxelized_cube() {
    let (mut pos, mut tris) = (Vec::new(), Vec::new());
    box_mesh([0.0; 3], [1.0; 3], &mut pos, &mut tris);
    let l = Lattice::from_surface(&pos, &tris, 0.25).unwrap();
    assert_eq!(l.dims(), [4, 4, 4]);
    assert_eq!(l.len(), 64);
    assert!((l.rest_volume() - 27.0 / 64.0).abs() < 1e-12);
    assert_eq!(l.origin(), [0.125; 3]);
    // Reversed orientation gives the same lattice.
    let flipped: Vec<[u32; 3]> = tris.iter().map(|t| [t[0], t[2], t[1]]).collect();
    assert_eq!(Lattice::from_surface(&pos, &flipped, 0.25).unwrap().len(), 64);
}

/// Union of two overlapping boxes (an L): 24 + 24 - 8 = 40 elements at spacing 0.5.
#[test]
fn voxelized_l_shape() {
    let (mut pos, mut tris) = (Vec::new(), Vec::new());
    box_mesh([0.0; 3], [3.0, 1.0, 1.0], &mut pos, &mut tris);
    box_mesh([0.0; 3], [1.0, 3.0, 1.0], &mut pos, &mut tris);
    let l = Lattice::from_surface(&pos, &tris, 0.5).unwrap();
    assert_eq!(l.len(), 40);
    for p in l.rest_positions() {
        assert!(p[0] < 1.0 || p[1] < 1.0, "{p:?} outside the L");
    }
}

/// Sphere of radius 1 at spacing 0.2: every element lies inside the circumscribed sphere,
/// and every cell centre well inside the inscribed one is an element.
#[test]
fn voxelized_sphere() {
    let (pos, tris) = sphere_mesh(1.0, 32, 16);
    let l = Lattice::from_surface(&pos, &tris, 0.2).unwrap();
    assert_eq!(l.dims(), [10, 10, 10]);
    for p in l.rest_positions() {
        assert!(p[0] * p[0] + p[1] * p[1] + p[2] * p[2] < 1.0);
    }
    let mut expected_inside = 0;
    for k in 0..10 {
        for j in 0..10 {
            for i in 0..10 {
                let p = [-0.9 + 0.2 * i as f64, -0.9 + 0.2 * j as f64, -0.9 + 0.2 * k as f64];
                if p[0] * p[0] + p[1] * p[1] + p[2] * p[2] < 0.95 * 0.95 {
                    expected_inside += 1;
                    assert!(l.element_at([i, j, k]).is_some(), "{p:?} missing");
                }
            }
        }
    }
    assert!(l.len() >= expected_inside);
}

#[test]
fn construction_errors() {
    assert_eq!(Lattice::new_box([0, 3, 3], 1.0, [0.0; 3]).unwrap_err(), ChainmailError::EmptyLattice);
    for h in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            Lattice::new_box([2, 2, 2], h, [0.0; 3]),
            Err(ChainmailError::InvalidParameter { .. })
        ));
    }
    assert!(matches!(
        Lattice::new_box([2, 2, 2], 1.0, [f64::NAN, 0.0, 0.0]),
        Err(ChainmailError::InvalidParameter { .. })
    ));
    assert!(matches!(
        Lattice::new_box([1 << 12, 1 << 12, 1 << 12], 1.0, [0.0; 3]),
        Err(ChainmailError::LatticeTooLarge { .. })
    ));
    let (mut pos, mut tris) = (Vec::new(), Vec::new());
    box_mesh([0.0; 3], [1.0; 3], &mut pos, &mut tris);
    assert_eq!(Lattice::from_surface(&pos, &[], 0.1).unwrap_err(), ChainmailError::EmptyLattice);
    assert!(matches!(
        Lattice::from_surface(&pos, &[[0, 1, 99]], 0.1),
        Err(ChainmailError::IndexOutOfRange { index: 99, len: 8 })
    ));
    let mut nan = pos.clone();
    nan[3][1] = f64::NAN;
    assert_eq!(Lattice::from_surface(&nan, &tris, 0.1).unwrap_err(), ChainmailError::NonFinite { index: 3 });
    assert!(matches!(Lattice::from_surface(&pos, &tris, 1e-9), Err(ChainmailError::LatticeTooLarge { .. })));
    // A flat (open, zero-volume) surface encloses no cell centre.
    let flat = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    assert_eq!(Lattice::from_surface(&flat, &[[0, 1, 2]], 0.1).unwrap_err(), ChainmailError::EmptyLattice);
}

#[test]
fn accessor_errors() {
    let mut l = Lattice::new_box([2, 2, 2], 1.0, [0.0; 3]).unwrap();
    assert!(matches!(l.grid_coords(8), Err(ChainmailError::IndexOutOfRange { index: 8, len: 8 })));
    assert!(l.neighbors(9).is_err());
    assert!(l.inverse_mass(8).is_err());
    assert!(l.set_inverse_mass(8, 1.0).is_err());
    assert!(l.set_inverse_mass(0, -1.0).is_err());
    assert!(l.set_inverse_mass(0, f64::NAN).is_err());
    assert!(l.set_stiffness(0, -2.0).is_err());
    assert!(l.set_stiffness(0, 2.0).is_ok());
    l.set_inverse_mass(1, 0.0).unwrap();
    assert_eq!(l.inverse_mass(1).unwrap(), 0.0);
}

/// Embedding a sphere: every vertex is interpolated from eight distinct elements with
/// weights summing to 1; the rest surface comes back exactly; an affine map of the lattice
/// (here a shear plus a translation) moves the surface by the same map, since trilinear
/// interpolation reproduces affine functions exactly (independent of the code: a property
/// of the interpolant).
#[test]
fn embedded_sphere_follows_affine_maps_exactly() {
    let (pos, tris) = sphere_mesh(1.0, 16, 10);
    let (mut lattice, emb) = Lattice::embed_surface(&pos, &tris, 0.3).unwrap();
    assert_eq!(emb.len(), pos.len());
    let rest = emb.positions(&lattice);
    for v in 0..pos.len() {
        let mut e = emb.elements(v).unwrap().to_vec();
        e.sort_unstable();
        e.dedup();
        assert_eq!(e.len(), 8, "vertex {v}");
        let w = emb.weights(v).unwrap();
        assert!(w.iter().all(|&x| (0.0..=1.0).contains(&x)));
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        for c in 0..3 {
            assert!((rest[v][c] - pos[v][c]).abs() < 1e-12, "vertex {v}: {:?} vs {:?}", rest[v], pos[v]);
        }
    }
    let map = |p: [f64; 3]| [p[0] + 0.2 * p[1] + 0.5, 0.9 * p[1] - 0.1 * p[2], p[2] + 0.3 * p[0] - 1.0];
    let moved: Vec<[f64; 3]> = lattice.rest_positions().iter().map(|&p| map(p)).collect();
    lattice.set_positions(&moved).unwrap();
    let now = emb.positions(&lattice);
    for v in 0..pos.len() {
        let want = map(pos[v]);
        for c in 0..3 {
            assert!((now[v][c] - want[c]).abs() < 1e-12, "vertex {v}");
        }
    }
    assert!(matches!(Lattice::embed_surface(&pos, &tris, 0.0), Err(ChainmailError::InvalidParameter { .. })));
    assert_eq!(
        lattice.set_positions(&moved[1..]),
        Err(ChainmailError::LengthMismatch { expected: moved.len(), found: moved.len() - 1 })
    );
}
