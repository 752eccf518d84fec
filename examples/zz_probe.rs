//! Temporary probe.
use fibfluid::assembly::{ConstraintMethod, Material, Selector};
use fibfluid::geometry::{MeshFile, icosphere};
use fibfluid::{Direction, Mode, Scene, Simulation};
use std::time::Instant;

fn main() {
    fibfluid::bench::pin_threads();
    let level: u32 = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(4);
    let mode = Mode::parse(&std::env::args().nth(2).unwrap_or("paper".into())).unwrap();
    let mesh = icosphere(level, 1.0);
    let n = mesh.n_vertices();
    let file = MeshFile {
        path: "x".into(),
        file_positions: mesh.positions().to_vec(),
        to_file: (0..n as u32).collect(),
        validation: Default::default(),
        notes: vec![],
        mesh,
    };
    let mut scene = Scene::from_mesh("s", file, Material::default());
    let p = scene.rest_positions();
    scene.constraints.fix_selected(&Selector::Above { axis: 1, value: 0.8 }, &p, [true; 3]).unwrap();
    scene.gravity = [0.0, -10.0, 0.0];
    scene.steps = 10;
    scene.solver.backend = "structured".into();
    scene.solver.mode = mode;
    scene.solver.constraints = ConstraintMethod::Eliminate;
    let mut sim = Simulation::new(scene).unwrap();
    let before: Vec<(String, f64, usize)> =
        sim.log().stages.iter().map(|s| (s.name.clone(), s.seconds, s.count)).collect();
    {
        use fibfluid::linalg::FactorizationExt;
        let f = sim.factorization();
        let dim = f.matrix().dim();
        let b: Vec<f64> = (0..dim).map(|i| ((i * 7919) % 1000) as f64 / 1000.0 - 0.5).collect();
        let mut bs = [f64::INFINITY; 4];
        let mut steps = 0;
        for _ in 0..10 {
            let s = Instant::now();
            let sol = f.solve(&b).unwrap();
            bs[0] = bs[0].min(s.elapsed().as_secs_f64());
            steps = sol.refinement_steps;
            let mut x = b.clone();
            let s = Instant::now();
            f.solve_unrefined(&mut x);
            bs[1] = bs[1].min(s.elapsed().as_secs_f64());
            let mut y = vec![0.0; dim];
            let s = Instant::now();
            f.matrix().apply(&x, &mut y);
            bs[2] = bs[2].min(s.elapsed().as_secs_f64());
            let s = Instant::now();
            f.matrix().apply_abs(&x, &mut y);
            bs[3] = bs[3].min(s.elapsed().as_secs_f64());
        }
        println!(
            "solve {:.4} (steps {steps}) unrefined {:.4} apply {:.4} apply_abs {:.4}",
            bs[0], bs[1], bs[2], bs[3]
        );
    }
    let mut best = f64::INFINITY;
    let t0 = Instant::now();
    for k in 0..10 {
        let s = Instant::now();
        sim.step(k, 10, Direction::Load).unwrap();
        best = best.min(s.elapsed().as_secs_f64());
    }
    let total = t0.elapsed().as_secs_f64();
    println!(
        "N={n} mode {} best step {:.4} mean {:.4} solves {} refinement max {}",
        mode.name(),
        best,
        total / 10.0,
        sim.solves(),
        sim.refinement_steps_max()
    );
    for s in &sim.log().stages {
        let (s0, c0) = before.iter().find(|b| b.0 == s.name).map(|b| (b.1, b.2)).unwrap_or((0.0, 0));
        println!("  {:<28} {:>9.4} s {:>4}", s.name, s.seconds - s0, s.count - c0);
    }
}
