//! Embedding fibfluid without a scene file: build a body in code, factor once, then apply
//! a new point force each "frame" and read the displacements (the interactive use the
//! paper claims). Run: `cargo run --release --example embed`.

use fibfluid::assembly::{Material, Selector};
use fibfluid::geometry::{MeshFile, icosphere};
use fibfluid::{Scene, Simulation};

fn main() -> Result<(), fibfluid::Error> {
    // A level-3 icosphere (642 vertices) of radius 5 cm.
    let mesh = icosphere(3, 0.05);
    let n = mesh.n_vertices();
    let file = MeshFile::from_mesh("icosphere-3", mesh).expect("the icosphere is a closed surface");
    let material = Material::isotropic(800.0, 40.0, 1000.0);
    let mut scene = Scene::from_mesh("embedded sphere", file, material);
    // Hold the bottom cap (within 1 cm of the lowest point).
    let positions = scene.rest_positions();
    let held =
        scene.constraints.fix_selected(&Selector::Bottom { axis: 1, within: 0.01 }, &positions, [true; 3])?;
    println!("{n} vertices, {held} held");
    scene.solver.backend = fibfluid::Backend::Structured;

    // Factor once.
    let mut sim = Simulation::new(scene)?;
    let top = (0..n).max_by(|&a, &b| positions[a][1].total_cmp(&positions[b][1])).unwrap_or(0);

    // Each frame: a new push on the top vertex, one solve with the kept factorization.
    for frame in 0..5 {
        let push = -0.5 * (frame + 1) as f64;
        let start = std::time::Instant::now();
        let (u, p) = sim.respond(&[(top, [0.0, push, 0.0])])?;
        let us = start.elapsed().as_micros();
        println!(
            "frame {frame}: force {push:5.1} N -> top moves {:8.5} m, pressure {p:8.3}, {us} us",
            u[top][1]
        );
    }
    Ok(())
}
