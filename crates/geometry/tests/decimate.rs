//! Decimation: volume-preserving edge collapses keep a valid closed surface and its volume,
//! on spheres, a torus, and every surface of the phantom label image.

use std::time::Instant;

use fibfluid_geometry::{
    DecimateError, LabelSelection, MeshError, SurfaceError, SurfaceOptions, TriMesh, decimate,
    extract_surface, icosphere, read_nifti, self_intersections,
};

use crate::common::{load, volume_independent};

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// Decimates `mesh` to `target` and checks the result: at most `target` vertices, one valid
/// closed surface of the same genus, not flipped, not crossing itself, positive volume. Returns the result and its volume relative error against the
/// input's, both computed by the tests' own volume formula.
fn decimated(mesh: &TriMesh, target: usize) -> (TriMesh, f64) {
    let mut input = mesh.clone();
    let before = input.validate().expect("a valid input");
    let (p, t) = decimate(mesh, target).unwrap_or_else(|e| panic!("decimating to {target}: {e}"));
    let mut out = TriMesh::new(p, t).expect("in range and finite");
    let after = out.validate().unwrap_or_else(|e| panic!("the decimated surface is invalid: {e}"));
    assert!(out.n_vertices() <= target, "{} vertices for a target of {target}", out.n_vertices());
    assert!(!after.flipped, "the decimated surface came out inward");
    assert_eq!(after.genus, before.genus);
    assert_eq!(self_intersections(&out), vec![], "the decimated surface crosses itself");
    let v_in = volume_independent(mesh.positions(), mesh.triangles());
    let v_out = volume_independent(out.positions(), out.triangles());
    assert!(v_out > 0.0);
    (out, rel(v_out, v_in))
}

#[test]
fn a_decimated_sphere_keeps_its_volume_and_stays_valid() {
    let sphere = icosphere(4, 0.02);
    for target in [1000, 300, 100, 20] {
        let (out, error) = decimated(&sphere, target);
        eprintln!("icosphere 2562 -> {} vertices: volume error {:.2e}", out.n_vertices(), error);
        // Every collapse keeps the volume exactly, so only rounding is left.
        assert!(error < 1e-9, "{error}");
    }
    // A target at or above the vertex count: the input, unchanged.
    for target in [2562, 5000] {
        let (p, t) = decimate(&sphere, target).unwrap();
        assert_eq!((p.as_slice(), t.as_slice()), (sphere.positions(), sphere.triangles()));
    }
}

#[test]
fn unreachable_targets_and_open_surfaces_are_errors() {
    let sphere = icosphere(2, 1.0);
    for target in [0, 3] {
        match decimate(&sphere, target) {
            Err(DecimateError::TargetTooSmall { target: t, reached }) => {
                assert_eq!(t, target);
                assert!((4..162).contains(&reached), "{reached}");
            }
            other => panic!("target {target}: {other:?}"),
        }
    }
    // The tetrahedron cannot lose a vertex; 4 is reachable from the sphere.
    let (out, _) = decimated(&sphere, 4);
    assert_eq!(out.n_vertices(), 4);
    let mut open = sphere.triangles().to_vec();
    open.pop();
    let open = TriMesh::new(sphere.positions().to_vec(), open).unwrap();
    assert!(matches!(decimate(&open, 50), Err(DecimateError::Mesh(MeshError::OpenBoundary { .. }))));
}

#[test]
fn a_decimated_torus_keeps_its_genus_and_volume() {
    let torus = load("torus2_for_collision.obj").mesh;
    let n = torus.n_vertices();
    for target in [n / 2, n / 5] {
        let (out, error) = decimated(&torus, target);
        eprintln!("torus {n} -> {} vertices: volume error {:.2e}", out.n_vertices(), error);
        assert!(error < 0.01, "{error}");
    }
}

#[test]
#[ignore = "long run: CI runs it with `cargo test --workspace -- --ignored long_`"]
fn long_a_large_surface_decimates_quickly() {
    let sphere = icosphere(6, 1.0);
    let start = Instant::now();
    let (p, _) = decimate(&sphere, 2000).unwrap();
    let seconds = start.elapsed().as_secs_f64();
    eprintln!("icosphere {} -> {} vertices in {seconds:.3} s", sphere.n_vertices(), p.len());
    let (_, error) = decimated(&sphere, 2000);
    assert!(error < 0.01, "{error}");
}

/// Every surface of the phantom, decimated to 600 and 300 vertices, against the
/// full-resolution surface's volume.
#[test]
fn every_phantom_surface_decimates_within_one_percent_of_its_volume() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/images/phantom.nii.gz");
    let image = read_nifti(path).unwrap();
    let mut selections = vec![(LabelSelection::NonZero, false)];
    selections.extend(image.labels_present().into_iter().map(|l| (LabelSelection::Label(l), true)));
    for (selection, fill_cavities) in selections {
        for smooth in [false, true] {
            let base = SurfaceOptions { selection, smooth, fill_cavities, target_vertices: None };
            let full = extract_surface(&image, &base).unwrap();
            let reference = volume_independent(full.mesh.positions(), full.mesh.triangles());
            for target in [600, 300] {
                let start = Instant::now();
                let s = extract_surface(&image, &SurfaceOptions { target_vertices: Some(target), ..base })
                    .unwrap_or_else(|e| panic!("{selection}, smooth {smooth}, {target}: {e}"));
                let seconds = start.elapsed().as_secs_f64();
                let mut mesh =
                    TriMesh::new(s.mesh.positions().to_vec(), s.mesh.triangles().to_vec()).unwrap();
                let validation = mesh.validate().unwrap();
                assert!(!validation.flipped && validation.genus == full.validation.genus);
                assert_eq!(self_intersections(&mesh), vec![], "{selection}: the surface crosses itself");
                let volume = volume_independent(mesh.positions(), mesh.triangles());
                let error = rel(volume, reference);
                eprintln!(
                    "phantom {selection}, smooth {smooth}: {} -> {} vertices (target {target}) in {seconds:.3} s, \
                     volume error {:.2e}",
                    full.mesh.n_vertices(),
                    mesh.n_vertices(),
                    error
                );
                assert!(mesh.n_vertices() <= target);
                assert!(s.block == 1 && s.voxels == full.voxels);
                assert!(error < 0.01, "{selection}, smooth {smooth}, target {target}: volume error {error}");
                assert!(rel(s.volume, volume) < 1e-9);
            }
        }
    }
    let tiny = SurfaceOptions { target_vertices: Some(3), ..SurfaceOptions::default() };
    assert!(matches!(extract_surface(&image, &tiny), Err(SurfaceError::TargetTooSmall { target: 3, .. })));
}
