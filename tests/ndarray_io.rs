//! The facade's ndarray conversions (feature `ndarray`): a test target of its own, so that
//! `cargo test --workspace` (the feature off) does not build it and CI's
//! `cargo test --workspace --features fibfluid/ndarray --test ndarray_io` rebuilds only the
//! facade.

use fibfluid::{RunOptions, Scene, Simulation};

/// `fibfluid::ndarray_io` (feature `ndarray`) against the slice forms it converts: N x 3
/// positions and triangles both ways, in standard and column-major layout; the displacement
/// field of a run against `positions - rest_positions` taken from the slices; a mesh built
/// from arrays equal to the scene's own; and the shape and index errors.
#[test]
fn ndarray_arrays_match_the_slice_forms() {
    use fibfluid::Shape;
    use fibfluid::ndarray_io::ndarray::{Array2, ShapeBuilder};
    use fibfluid::ndarray_io::{
        ArrayError, displacements, mesh_file_from_arrays, positions_array, scene_from_arrays,
        triangles_array, triangles_from_array, vec3s_from_array,
    };

    let scene = Scene::load("fixtures/scenes/sphere.toml").expect("bundled sphere scene");
    let Shape::Surface(file) = &scene.shape else { panic!("the sphere scene is a surface") };
    let (rest, tris) = (file.mesh.positions().to_vec(), file.mesh.triangles().to_vec());
    let mut sim = Simulation::new(scene.clone()).expect("setup");
    sim.run(&RunOptions::default()).expect("run");
    let x = sim.positions();

    let a = positions_array(x);
    assert_eq!(a.dim(), (x.len(), 3));
    assert!(x.iter().enumerate().all(|(i, p)| (0..3).all(|c| a[[i, c]] == p[c])));
    assert_eq!(vec3s_from_array(a.view()).unwrap(), x);
    let mut column_major = Array2::<f64>::zeros((x.len(), 3).f());
    column_major.assign(&a);
    assert_eq!(vec3s_from_array(column_major.view()).unwrap(), x);
    assert_eq!(vec3s_from_array(a.t()), Err(ArrayError::Shape { what: "positions", rows: 3, cols: x.len() }));

    let u = displacements(&sim);
    let rest_now = sim.rest_positions();
    let mut largest = 0.0f64;
    for (i, (p, r)) in x.iter().zip(rest_now).enumerate() {
        for c in 0..3 {
            assert_eq!(u[[i, c]], p[c] - r[c], "vertex {i}, axis {c}");
            largest = largest.max(u[[i, c]].abs());
        }
    }
    assert!(largest > 1e-3, "gravity moves the sphere: the field is not trivially zero");

    let t = triangles_array(&tris);
    assert_eq!(triangles_from_array(t.view()).unwrap(), tris);
    let t64 = t.mapv(i64::from);
    let built = mesh_file_from_arrays("arrays", positions_array(&rest).view(), t64.view()).unwrap();
    assert_eq!(built.mesh, file.mesh);
    assert!(!built.validation.flipped);
    let mut inward = t64.clone();
    inward.column_mut(1).assign(&t64.column(2));
    inward.column_mut(2).assign(&t64.column(1));
    let flipped = mesh_file_from_arrays("arrays", positions_array(&rest).view(), inward.view()).unwrap();
    assert!(flipped.validation.flipped, "an inward surface is turned outward");
    assert_eq!(flipped.mesh, file.mesh);
    let from_arrays =
        scene_from_arrays("arrays", positions_array(&rest).view(), t.view(), scene.material.clone()).unwrap();
    assert_eq!(from_arrays.rest_positions(), rest);

    let mut bad = t64.clone();
    bad[[5, 1]] = -1;
    assert_eq!(triangles_from_array(bad.view()), Err(ArrayError::Index { row: 5, value: "-1".into() }));
    bad[[5, 1]] = rest.len() as i64;
    assert!(matches!(
        mesh_file_from_arrays("arrays", positions_array(&rest).view(), bad.view()),
        Err(ArrayError::Mesh(_))
    ));
}
