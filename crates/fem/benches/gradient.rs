//! The adjoint gradient's cost against one Newton iteration of the forward run, on a
//! neo-Hookean sphere of radius 5 cm at resolution 16 (a few thousand cells), its cap
//! y > 4 cm fixed, a stiffer lower half (a region), under gravity, at its converged answer;
//! with each linear solver.
//!
//! - One Newton iteration of the forward run (the tangent's and residual's assembly, the
//!   numeric factorization or the multigrid's setup, the solve and the line search), as the
//!   forward solve's own timings count it ([`HyperStats`]: their sum over the iterations),
//!   the median of three solves: printed, not a criterion bench (a sample would be a whole
//!   solve).
//! - `gradient/adjoint_{n}/{solver}`: one [`HyperBody::objective_gradient`] with `n`
//!   parameters (the two Young's moduli; `adjoint_0` is its assembly, factorization and
//!   solve alone), also timed outside criterion (median of five) for the printed ratio to a
//!   Newton iteration.
//!
//! The bench prints `/proc/loadavg` at the start and end.
//!
//! Run: `cargo bench -p fibfluid-fem --bench gradient -- --warm-up-time 1 --measurement-time 3`.

use std::hint::black_box;
use std::time::Instant;

use criterion::{BenchmarkId, Criterion, SamplingMode, criterion_group, criterion_main};
use fibfluid_fem::hyper::{HyperBody, HyperSolution, HyperStats, NewtonSettings, Parameter};
use fibfluid_fem::{FemOptions, FemSolver, Loads, Region, RegionShape, Tissue, TissueModel};
use fibfluid_geometry::icosphere;

mod common;
use common::load;

/// Seconds of the Newton iterations of a solve, per iteration.
fn per_iteration(stats: &HyperStats) -> f64 {
    (stats.assembly_seconds + stats.factor_seconds + stats.solve_seconds)
        / stats.newton_iterations.max(1) as f64
}

/// The body, solved with `solver`.
fn solved(solver: FemSolver) -> (HyperBody, HyperSolution, Loads) {
    let mesh = icosphere(3, 0.05);
    let pos = mesh.positions().to_vec();
    let tris = mesh.triangles().to_vec();
    let fixed: Vec<[bool; 3]> = pos.iter().map(|p| [p[1] > 0.04; 3]).collect();
    let tissue = |young| Tissue::new(young, 0.45, 1000.0).unwrap().with_model(TissueModel::NeoHookean);
    let region = Region {
        shape: RegionShape::Box { min: [-1.0, -1.0, -1.0], max: [1.0, 0.0, 1.0] },
        tissue: tissue(15000.0),
    };
    let options = FemOptions { resolution: 16, ..FemOptions::default() };
    let settings = NewtonSettings { solver, ..NewtonSettings::default() };
    let mut body = HyperBody::from_surface(&pos, &tris, &tissue(5000.0), &fixed, &options)
        .unwrap()
        .with_regions(&[region])
        .unwrap()
        .with_settings(settings);
    let loads = Loads { gravity: [0.0, -9.81, 0.0], ..Default::default() };
    let solution = body.solve(&loads, &[]).unwrap();
    (body, solution, loads)
}

fn gradient(c: &mut Criterion) {
    println!("load: {}", load());
    let mut group = c.benchmark_group("gradient");
    group.sample_size(10).sampling_mode(SamplingMode::Flat);
    for solver in [FemSolver::Direct, FemSolver::Multigrid] {
        let name = format!("{solver:?}").to_lowercase();
        // The forward run's Newton iteration: the median over three solves.
        let mut newton: Vec<f64> = (0..3).map(|_| per_iteration(&solved(solver).1.stats)).collect();
        newton.sort_by(f64::total_cmp);
        let (mut body, solution, loads) = solved(solver);
        let s = &solution.stats;
        println!(
            "{name}: {} cells, {} unknowns, {} Newton iterations over {} load steps, {:.4} s each",
            body.grid().n_cells(),
            body.dofs(),
            s.newton_iterations,
            s.load_steps,
            newton[1]
        );
        let weights: Vec<[f64; 3]> =
            solution.surface_displacements.iter().map(|u| u.map(|x| 2.0 * x)).collect();
        let parameters = [Parameter::Young(0), Parameter::Young(1)];
        for n in 0..=2 {
            group.bench_function(BenchmarkId::new(format!("adjoint_{n}"), &name), |b| {
                b.iter(|| {
                    body.objective_gradient(black_box(&solution), &loads, &parameters[..n], &weights).unwrap()
                })
            });
            // The same, timed here for the ratio: the median of five calls.
            let mut seconds: Vec<f64> = (0..5)
                .map(|_| {
                    let start = Instant::now();
                    body.objective_gradient(&solution, &loads, &parameters[..n], &weights).unwrap();
                    start.elapsed().as_secs_f64()
                })
                .collect();
            seconds.sort_by(f64::total_cmp);
            println!(
                "{name}: adjoint_{n} {:.4} s, {:.2} Newton iterations",
                seconds[2],
                seconds[2] / newton[1]
            );
        }
    }
    group.finish();
    println!("load: {}", load());
}

criterion_group!(benches, gradient);
criterion_main!(benches);
