//! Bodies with cavities: a hollow sphere of two icospheres is one body with one cavity;
//! disjoint bodies, crossing cavities and a body inside a cavity are refused.

use fibfluid_geometry::{MeshError, PointLattice, TriMesh, icosphere, inside_lattice};

/// Two icospheres, radii `outer` and `inner` (the inner one reversed when `reverse`,
/// shifted by `shift`), as one mesh.
fn two_spheres(outer: f64, inner: f64, shift: [f64; 3], reverse: bool) -> TriMesh {
    let a = icosphere(2, outer);
    let b = icosphere(2, inner);
    let mut positions = a.positions().to_vec();
    let n = positions.len() as u32;
    positions.extend(b.positions().iter().map(|p| [p[0] + shift[0], p[1] + shift[1], p[2] + shift[2]]));
    let mut triangles = a.triangles().to_vec();
    triangles.extend(b.triangles().iter().map(|t| {
        let t = t.map(|v| v + n);
        if reverse { [t[0], t[2], t[1]] } else { t }
    }));
    TriMesh::new(positions, triangles).unwrap()
}

#[test]
fn hollow_sphere_is_one_body_with_a_cavity() {
    let inner_volume = icosphere(2, 1.0).volume();
    let outer_volume = icosphere(2, 2.0).volume();
    for reverse in [true, false] {
        let mut m = two_spheres(2.0, 1.0, [0.0; 3], reverse);
        let v = m.validate().unwrap();
        assert_eq!(v.cavities.len(), 1);
        assert!((v.cavities[0] - inner_volume).abs() < 1e-12 * inner_volume);
        assert_eq!(v.genus, 0);
        assert!(!v.flipped);
        // A cavity faced into the material is flipped with a warning.
        assert_eq!(v.warnings.len(), usize::from(!reverse), "{:?}", v.warnings);
        assert!((m.volume() - (outer_volume - inner_volume)).abs() < 1e-12 * outer_volume);
        let shells = m.shells();
        assert!(shells[0].volume > 0.0 && shells[1].volume < 0.0);
        assert_eq!(m.cavity_volumes(), v.cavities);
    }
    // The whole mesh inverted: both flipped.
    let mut m = two_spheres(2.0, 1.0, [0.0; 3], false);
    let t: Vec<[u32; 3]> = m.triangles().iter().map(|t| [t[0], t[2], t[1]]).collect();
    m = TriMesh::new(m.positions().to_vec(), t).unwrap();
    let v = m.validate().unwrap();
    assert!(v.flipped);
    assert!(m.shells()[1].volume < 0.0);
}

#[test]
fn the_cavity_is_outside_for_the_voxelizer() {
    let mut m = two_spheres(2.0, 1.0, [0.0; 3], true);
    m.validate().unwrap();
    // Points along x from -2.5 to 2.5 every 0.25.
    let lattice = PointLattice { origin: [-2.5, 0.01, 0.02], spacing: 0.25, dims: [21, 1, 1] };
    let inside = inside_lattice(m.positions(), m.triangles(), &lattice).unwrap();
    for (i, flag) in inside.iter().enumerate() {
        let r = (-2.5 + 0.25 * i as f64).abs();
        // The icospheres' chords sit within 2 % of the radii.
        if (r - 1.0).abs() > 0.05 && (r - 2.0).abs() > 0.1 {
            assert_eq!(*flag, r > 1.0 && r < 2.0, "x = {r}");
        }
    }
}

#[test]
fn disjoint_bodies_and_crossing_cavities_are_refused() {
    let err = |mut m: TriMesh| m.validate().unwrap_err();
    assert_eq!(err(two_spheres(2.0, 1.0, [5.0, 0.0, 0.0], true)), MeshError::DisjointBodies { component: 1 });
    assert_eq!(
        err(two_spheres(2.0, 1.0, [1.5, 0.0, 0.0], true)),
        MeshError::CavityCrossesOuter { cavity: 1 }
    );
    let message = err(two_spheres(2.0, 1.0, [5.0, 0.0, 0.0], true)).to_string();
    assert!(message.contains("two disjoint bodies") && !message.contains('\n'), "{message}");
    // Three nested spheres: the innermost floats in the cavity.
    let mut m = two_spheres(3.0, 2.0, [0.0; 3], true);
    let c = icosphere(2, 1.0);
    let n = m.n_vertices() as u32;
    let mut positions = m.positions().to_vec();
    positions.extend_from_slice(c.positions());
    let mut triangles = m.triangles().to_vec();
    triangles.extend(c.triangles().iter().map(|t| t.map(|v| v + n)));
    m = TriMesh::new(positions.clone(), triangles.clone()).unwrap();
    assert_eq!(err(m), MeshError::CavityInCavity { inner: 2, outer: 1 });
    // Two cavities that overlap.
    let mut m = two_spheres(3.0, 1.0, [0.5, 0.0, 0.0], true);
    let n = m.n_vertices() as u32;
    let mut positions = m.positions().to_vec();
    positions.extend(c.positions().iter().map(|p| [p[0] - 0.37, p[1] + 0.01, p[2]]));
    let mut triangles = m.triangles().to_vec();
    triangles.extend(c.triangles().iter().map(|t| [t[0] + n, t[2] + n, t[1] + n]));
    m = TriMesh::new(positions, triangles).unwrap();
    assert_eq!(err(m), MeshError::CavitiesCross { a: 1, b: 2 });
}
