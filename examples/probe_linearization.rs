//! What the probe's linearization costs in accuracy: a grab's linear answer (the precomputed
//! response about the rest shape) against the nonlinear answer of `fibfluid run` for the
//! same force.
//!
//! The body is the paper's sphere (fixtures/scenes/sphere.toml: icosphere level 2, Y = gamma
//! = 3000, the cap y > 0.8 fixed, elimination) with its own loads removed, so only the tool
//! acts. For each grab size s the bottom vertex (file vertex 36, y = -1) is grabbed to a
//! displacement (0, -s, 0); the probe gives the reaction r and the linear surface. The
//! reference applies r as a point force, ramped over 40 Heun steps, in nonlinear mode
//! (K, S and the loads re-assembled on the current shape every step, volume corrected) and
//! in refresh mode (K kept, border and volume refreshed). Reported, for each: the largest
//! vertex distance between the linear and the reference surface over the reference's
//! largest displacement, and how far the reference leaves the grabbed vertex from where the
//! tool holds it, over s. The last column is the linear surface's volume change |V/V0 - 1|.
//! The reference's own stepping error is bounded by repeating the largest grab with 80
//! steps.
//!
//! Run: `cargo run --release --example probe_linearization`.

use fibfluid::geometry::{Vec3, volume};
use fibfluid::interact::Interactive;
use fibfluid::interact::{ProbeOptions, build_body};
use fibfluid::{ForceTiming, Mode, PointForce, RunOptions, Scene, Shape, Simulation, Stepping};

fn dist(a: Vec3, b: Vec3) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

fn reference(
    scene: &Scene,
    v: usize,
    r: Vec3,
    mode: Mode,
    steps: usize,
) -> Result<Vec<Vec3>, fibfluid::Error> {
    let mut s = scene.clone();
    s.solver.mode = mode;
    s.solver.stepping = Stepping::Heun;
    s.load.steps = steps;
    s.load.forces.push(PointForce { vertex: v, value: r, timing: ForceTiming::Ramp });
    let mut sim = Simulation::new(s)?;
    sim.run(&RunOptions::default())?;
    Ok(sim.positions().to_vec())
}

fn main() -> Result<(), fibfluid::Error> {
    let mut scene = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/fixtures/scenes/sphere.toml"))?;
    scene.load.gravity = [0.0; 3];
    scene.load.forces.clear();
    scene.solver.constraints = fibfluid::ConstraintKind::Eliminate;
    let Shape::Surface(file) = &scene.shape else { unreachable!("the sphere is a surface") };
    let triangles = file.mesh.triangles().to_vec();
    let v = file.from_file_index(36).expect("vertex 36 is used");
    let mut body = build_body(&scene, &ProbeOptions::default())?.body;
    let rest = body.rest_positions().to_vec();
    let v0 = volume(&rest, &triangles);
    println!(
        "| grab s | reaction |r| | nonlinear: surface diff / max|u| | nonlinear: grabbed vertex miss / s | refresh: surface diff / max|u| | refresh: miss / s | linear |V/V0 - 1| |"
    );
    println!("|---|---|---|---|---|---|---|");
    let mut last = None;
    for s in [0.01, 0.02, 0.05, 0.1, 0.2, 0.3] {
        let d = [0.0, -s, 0.0];
        body.release_all();
        body.grab(v, d).map_err(fibfluid::interact::ProbeError::from)?;
        let r = body.update().map_err(fibfluid::interact::ProbeError::from)?[0].1;
        let lin = body.positions().to_vec();
        let held = [rest[v][0] + d[0], rest[v][1] + d[1], rest[v][2] + d[2]];
        let mut cells = Vec::new();
        for mode in [Mode::Nonlinear, Mode::Refresh] {
            let nl = reference(&scene, v, r, mode, 40)?;
            let umax = nl.iter().zip(&rest).map(|(p, q)| dist(*p, *q)).fold(0.0, f64::max);
            let diff = lin.iter().zip(&nl).map(|(p, q)| dist(*p, *q)).fold(0.0, f64::max);
            cells.push(format!("{:.2e}", diff / umax));
            cells.push(format!("{:.2e}", dist(nl[v], held) / s));
        }
        let dv = (volume(&lin, &triangles) / v0 - 1.0).abs();
        let rn = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
        println!("| {s} | {rn:.1} | {} | {dv:.2e} |", cells.join(" | "));
        last = Some((s, r));
    }
    if let Some((s, r)) = last {
        let a = reference(&scene, v, r, Mode::Nonlinear, 40)?;
        let b = reference(&scene, v, r, Mode::Nonlinear, 80)?;
        let umax = b.iter().zip(&rest).map(|(p, q)| dist(*p, *q)).fold(0.0, f64::max);
        let diff = a.iter().zip(&b).map(|(p, q)| dist(*p, *q)).fold(0.0, f64::max);
        println!(
            "\nnonlinear reference, grab {s}: 40 vs 80 Heun steps differ by {:.2e} of max|u|",
            diff / umax
        );
    }
    Ok(())
}
