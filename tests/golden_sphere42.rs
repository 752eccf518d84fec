//! The independent golden case (`fixtures/golden/`, computed by a separate numpy
//! implementation of REFERENCE §1–4): a 42-vertex sphere under gravity in paper mode.

use fibfluid::geometry::load_mesh;
use fibfluid::{RunOptions, Scene, Simulation};

fn golden_positions() -> Vec<[f64; 3]> {
    // The deformed OBJ is read with the same reader; its faces equal the input's.
    let text = std::fs::read_to_string("fixtures/golden/sphere42-deformed.obj").unwrap();
    text.lines()
        .filter(|l| l.starts_with("v "))
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().skip(1).map(|t| t.parse().unwrap()).collect();
            [v[0], v[1], v[2]]
        })
        .collect()
}

#[test]
fn sphere42_matches_the_independent_computation_with_every_backend() {
    let expected = golden_positions();
    let rest = load_mesh("fixtures/golden/sphere42.obj").unwrap();
    let max_disp = expected
        .iter()
        .zip(&rest.file_positions)
        .map(|(a, b)| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt())
        .fold(0.0, f64::max);
    // README: largest displacement 0.8578067874.
    assert!((max_disp - 0.8578067874).abs() < 1e-9);
    for backend in fibfluid::Backend::compiled() {
        let mut scene = Scene::load("fixtures/golden/sphere42-gravity.toml").unwrap();
        scene.solver.backend = backend;
        let mut sim = Simulation::new(scene).unwrap();
        sim.run(&RunOptions::default()).unwrap();
        let file = match &sim.model().shape {
            fibfluid::Shape::Surface(m) => m.clone(),
            _ => unreachable!(),
        };
        let got = file.positions_in_file_order(sim.positions());
        let err = got
            .iter()
            .zip(&expected)
            .map(|(a, b)| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt())
            .fold(0.0, f64::max);
        // README: "match the deformed positions to about 1e-9 of the largest displacement".
        eprintln!("{backend}: {err:e}");
        assert!(err < 1e-9 * max_disp, "{backend}: max position error {err:e}");
        // README figures: P = 16197.00236, volume 3.658712209 -> 3.701233308.
        assert!((sim.pressure() - 16197.00236).abs() < 1e-4, "{backend}: P = {}", sim.pressure());
        assert!((sim.volume_initial() - 3.658712209).abs() < 1e-8);
        assert!((sim.volume() - 3.701233308).abs() < 1e-8, "{backend}: V = {}", sim.volume());
    }
}
