//! Units and the finite-element method through the library: a body declared in millimetres
//! and the same body in metres give the same physical answer, with either method; the FEM's
//! run honours its clamps and is refused from counts when it cannot fit.

use std::path::Path;

use fibfluid::geometry::{icosphere, write_obj};
use fibfluid::sim::Error as SimError;
use fibfluid::sim::fem_run::FemRun;
use fibfluid::{RunOptions, Scene, Simulation};

/// Agreement of the same physical problem declared in two units, relative to the largest
/// displacement (both runs are SI inside; only the reading scale differs, a few roundings).
const SAME_PHYSICS: f64 = 1e-9;

/// A sphere of radius 2 cm written in `unit` (`factor` file units per metre), hanging from
/// its top cap under gravity, run by `method`.
fn scene_in(dir: &Path, unit: &str, factor: f64, method: &str) -> Scene {
    let mesh = icosphere(2, 0.02 * factor);
    let obj = dir.join(format!("sphere-{unit}.obj"));
    write_obj(&obj, mesh.positions(), mesh.triangles()).unwrap();
    let toml = format!(
        "[mesh]\npath = \"{}\"\nunit = \"{unit}\"\n\n\
         [material]\nyoung = 3000.0\nsurface_tension = 0.0\n\n[fluid]\ndensity = 1000.0\n\n\
         [tissue]\nyoung = 4000.0\npoisson = 0.45\ndensity = 1050.0\n\n\
         [gravity]\nacceleration = [0.0, -9.81, 0.0]\n\n\
         [[fix]]\naxis = \"y\"\nabove = {}\n\n[solver]\nmethod = \"{method}\"\n",
        obj.display(),
        0.016 * factor
    );
    let path = dir.join(format!("sphere-{unit}-{method}.toml"));
    std::fs::write(&path, toml).unwrap();
    Scene::load(&path).unwrap()
}

fn largest(u: &[[f64; 3]]) -> f64 {
    u.iter().map(|d| (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()).fold(0.0, f64::max)
}

fn displacement(positions: &[[f64; 3]], rest: &[[f64; 3]]) -> Vec<[f64; 3]> {
    positions.iter().zip(rest).map(|(p, r)| [p[0] - r[0], p[1] - r[1], p[2] - r[2]]).collect()
}

fn difference(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    largest(&a.iter().zip(b).map(|(p, q)| [p[0] - q[0], p[1] - q[1], p[2] - q[2]]).collect::<Vec<_>>())
}

#[test]
fn a_body_in_millimetres_and_in_metres_gives_the_same_physical_answer() {
    let dir = tempfile::tempdir().unwrap();
    for method in ["ffm", "fem"] {
        let runs: Vec<Vec<[f64; 3]>> = [("m", 1.0), ("mm", 1000.0)]
            .iter()
            .map(|&(unit, factor)| {
                let scene = scene_in(dir.path(), unit, factor, method);
                // Inside, positions are metres whatever the file's unit.
                let size = largest(&scene.rest_positions());
                assert!((size - 0.02).abs() < 1e-12, "{method} {unit}: radius {size} m");
                if method == "fem" {
                    let run = FemRun::new(scene, None).unwrap();
                    displacement(&run.positions, &run.rest)
                } else {
                    let mut sim = Simulation::new(scene).unwrap();
                    sim.run(&RunOptions::default()).unwrap();
                    displacement(sim.positions(), sim.rest_positions())
                }
            })
            .collect();
        let scale = largest(&runs[0]);
        assert!(scale > 0.0, "{method}: nothing moved");
        let d = difference(&runs[0], &runs[1]);
        assert!(
            d <= SAME_PHYSICS * scale,
            "{method}: mm and m differ by {d:e} m (largest displacement {scale:e} m)"
        );
    }
}

#[test]
fn the_fem_holds_its_clamps_and_sags_under_gravity() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_in(dir.path(), "m", 1.0, "fem");
    let fixed = scene.constraints.fully_fixed_vertices(3);
    assert!(!fixed.is_empty());
    let run = FemRun::new(scene, None).unwrap();
    let u = displacement(&run.positions, &run.rest);
    let sag = largest(&u);
    // A soft 2 cm sphere: rho g R^2 / E = 1050 * 9.81 * 4e-4 / 4000 ~ 1 mm is the scale.
    assert!(sag > 1e-4 && sag < 1e-2, "sag {sag} m");
    // Every vertex moves down or not at all (gravity along -y, clamped on top).
    let mean_y = u.iter().map(|d| d[1]).sum::<f64>() / u.len() as f64;
    assert!(mean_y < 0.0);
    // Fixed vertices whose cell's nodes are all clamped stay exactly at rest.
    let worst_fixed = fixed.iter().map(|&v| largest(&[u[v]])).fold(0.0, f64::max);
    assert!(worst_fixed <= 0.05 * sag, "a fixed vertex moved {worst_fixed} m of a {sag} m sag");
    assert!(run.residual < 1e-10, "residual {}", run.residual);
}

#[test]
fn the_fem_is_refused_from_counts_when_it_cannot_fit() {
    let dir = tempfile::tempdir().unwrap();
    let mut scene = scene_in(dir.path(), "m", 1.0, "fem");
    scene.fem.resolution = 200;
    match FemRun::new(scene, Some(1 << 20)) {
        Err(SimError::TooLarge { needed, available, hint, .. }) => {
            assert!(needed > available && available == 1 << 20);
            assert!(hint.contains("[fem] resolution"));
        }
        other => panic!("expected a refusal, got {:?}", other.map(|r| r.stats)),
    }
}
