//! Compression between rigid plates: frictionless unilateral contact, checked on a sphere
//! squeezed between two symmetric plates in every mode and stepping scheme.

use fibfluid::contact::{MAX_ACTIVE_SET_ITERATIONS, PENETRATION_TOLERANCE};
use fibfluid::geometry::vec3::norm;
use fibfluid::{Error, Mode, RunOptions, Scene, SceneProblem, Simulation, Stepping};

/// The unit sphere (162 vertices) between plates at y = +-1 closing by `travel` each.
/// By symmetry the equator (y = 0) stays in its plane, and the vertices on the x and z
/// axes stay on them: those are the only constraints (frictionless plates hold nothing
/// sideways).
fn sphere_scene(travel: f64, extra: &str) -> (tempfile::TempDir, std::path::PathBuf) {
    let mesh = std::fs::canonicalize("fixtures/meshes/icosphere-2.obj").unwrap();
    let text = format!(
        r#"
[mesh]
path = "{}"
[material]
young = 3000.0
surface_tension = 3000.0
[load]
steps = 6
[[fix]]
box = [[-2.0, -1e-9, -2.0], [2.0, 1e-9, 2.0]]
dofs = ["y"]
[[fix]]
box = [[-1e-9, -1e-9, -2.0], [1e-9, 1e-9, 2.0]]
dofs = ["x"]
[[fix]]
box = [[-2.0, -1e-9, -1e-9], [2.0, 1e-9, 1e-9]]
dofs = ["z"]
[[plate]]
point = [0.0, 1.0, 0.0]
normal = [0.0, -1.0, 0.0]
travel = {travel}
[[plate]]
point = [0.0, -1.0, 0.0]
normal = [0.0, 1.0, 0.0]
travel = {travel}
{extra}
"#,
        mesh.display()
    );
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sphere-plates.toml");
    std::fs::write(&path, text).unwrap();
    (dir, path)
}

#[test]
fn a_sphere_between_symmetric_plates() {
    for mode in [Mode::Paper, Mode::Refresh, Mode::Nonlinear] {
        for stepping in [Stepping::Euler, Stepping::Heun] {
            let (_dir, path) = sphere_scene(0.3, "");
            let mut scene = Scene::load(&path).unwrap();
            scene.solver.mode = mode;
            scene.solver.stepping = stepping;
            let plates = scene.plates.clone();
            let mut sim = Simulation::new(scene).unwrap();
            sim.run(&RunOptions::default()).unwrap();
            let tag = format!("{mode} {stepping}");
            let diag = sim.body().diagonal;
            // No vertex through a plate.
            for (k, p) in plates.iter().enumerate() {
                for (v, x) in sim.positions().iter().enumerate() {
                    let g = p.gap(*x, 1.0);
                    assert!(
                        g >= -10.0 * PENETRATION_TOLERANCE * diag,
                        "{tag}: vertex {v} is {g:e} through plate {k}"
                    );
                }
            }
            // Every contact pushes, and sits on its plate.
            let contacts = &sim.state().contacts;
            assert!(!contacts.is_empty(), "{tag}: no contact");
            for c in contacts {
                assert!(c.force >= 0.0, "{tag}: contact {c:?} pulls");
                let g = plates[c.plate].gap(sim.positions()[c.vertex], 1.0);
                assert!(g.abs() <= 1e-9 * diag, "{tag}: contact {c:?} is {g:e} off its plate");
            }
            let records = sim.plate_records();
            for r in records {
                // The active set settled in every step, and the force grows as the plates close.
                assert!(r.active_set_iterations.iter().all(|&i| i < MAX_ACTIVE_SET_ITERATIONS), "{tag}");
                assert!(r.force.windows(2).all(|w| w[1] > w[0]), "{tag}: force {:?}", r.force);
                assert!(r.gap.windows(2).all(|w| w[1] < w[0]), "{tag}: gap {:?}", r.gap);
            }
            // Both plates carry the same force, and the shape stays mirror-symmetric.
            let (f0, f1) = (records[0].force.last().unwrap(), records[1].force.last().unwrap());
            assert!((f0 - f1).abs() <= 1e-9 * f0.abs(), "{tag}: plate forces {f0} and {f1}");
            let rest = sim.rest_positions();
            for (i, p) in rest.iter().enumerate() {
                let j = (0..rest.len())
                    .min_by(|&a, &b| {
                        let d = |k: usize| norm([rest[k][0] - p[0], rest[k][1] + p[1], rest[k][2] - p[2]]);
                        d(a).total_cmp(&d(b))
                    })
                    .unwrap();
                let (a, b) = (sim.positions()[i], sim.positions()[j]);
                let asym = norm([a[0] - b[0], a[1] + b[1], a[2] - b[2]]);
                assert!(
                    asym <= 1e-9 * diag,
                    "{tag}: vertices {i} and {j} differ by {asym:e} from mirror images"
                );
            }
            // The volume as the mode keeps it.
            let drift = (sim.volume() / sim.volume_initial() - 1.0).abs();
            let limit = if mode == Mode::Paper { 0.05 } else { 1e-9 };
            assert!(drift <= limit, "{tag}: volume drift {drift:e}");
        }
    }
}

/// Plates that cannot be: a zero or non-finite normal, a plate facing away from the body,
/// a plate already cutting it; each is a scene error naming the plate.
#[test]
fn bad_plates_are_scene_errors() {
    let cases = [
        ("normal = [0.0, 0.0, 0.0]", "[[plate]] #3.normal: must be finite and non-zero"),
        ("normal = [nan, 1.0, 0.0]", "[[plate]] #3.normal: must be finite and non-zero"),
        ("normal = [0.0, -1.0, 0.0]", "[[plate]] #3: the plate faces away from the body"),
        ("normal = [0.0, 1.0, 0.0]\npoint_is_below = 1", "unknown field `point_is_below`"),
    ];
    for (normal, fragment) in cases {
        let (_dir, path) = sphere_scene(0.3, &format!("[[plate]]\npoint = [0.0, -2.0, 0.0]\n{normal}"));
        let e = Scene::load(&path).unwrap_err();
        assert!(e.to_string().contains(fragment), "{normal}: {e}");
    }
    let (_dir, path) = sphere_scene(0.3, "[[plate]]\npoint = [0.0, -0.5, 0.0]\nnormal = [0.0, 1.0, 0.0]");
    match Scene::load(&path) {
        Err(Error::Scene(e)) => {
            assert!(matches!(e.problem, SceneProblem::PlateCutsBody { .. }), "{e}");
            assert!(e.to_string().contains("[[plate]] #3: the plate already cuts the body at rest"), "{e}");
        }
        other => panic!("a plate through the body at rest must be refused: {other:?}"),
    }
}
