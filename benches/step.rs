//! One load step with the factorization kept, per backend and mode.
//!
//! The scene is built in code: an icosphere of radius 1 at level 3 or 4 (N = 642, 2562),
//! the paper's sphere material (Y = gamma = 3000, rho = 1000), the vertices with y > 0.8
//! fixed (elimination), gravity (0, -10, 0) ramped over 10 steps. `Simulation::new`
//! (assembly and the first factorization) runs outside the timing; the timing covers
//! `sim.step_load((k + 1) / 10)`: in paper mode the load increment, the right-hand
//! side, the checked solve and the position update; refresh mode adds the new border and
//! volume target (triangular solves for the structured backend, a refactorization for the
//! dense ones) and the volume correction that follows the step (one solve for its
//! direction, then scalar Newton steps until the relative volume error is below
//! `VOLUME_TOLERANCE`; the count of solves is printed). After each tenth load step the ten unload steps run
//! untimed, so the body stays within the scene's load range however many steps criterion
//! asks for (steps that take over 0.15 s run about 11 times in all and are not rewound).
//!
//! nalgebra-lu is skipped at N = 2562 (n = 7687): its unblocked LU would take minutes for
//! the first factorization alone, and refresh mode refactors every step.
//!
//! Threads: `FIBFLUID_THREADS` (default every core) for faer, rayon and OpenBLAS
//! (`fibfluid::linalg::threads::pin_threads`); backends run one after the other, OpenBLAS last.
//!
//! Run: `cargo bench --features openblas --bench step`.

use std::time::{Duration, Instant};

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use fibfluid::linalg::threads::pin_threads;
use fibfluid::{Backend, Direction, Mode, Model, RunOptions, Simulation};

const STEPS: usize = 10;

fn scene(level: u32, backend: Backend, mode: Mode) -> Model {
    let mut scene = fibfluid::sim::samples::hanging_sphere(level).expect("the icosphere is a closed surface");
    scene.load.steps = STEPS;
    scene.solver.backend = backend;
    scene.solver.mode = mode;
    scene
}

/// Why a case is left out, if it is.
fn skipped(backend: Backend, n: usize) -> Option<&'static str> {
    (backend == Backend::NalgebraLu && n > 1000).then_some("unblocked LU of the 7687^2 matrix takes minutes")
}

fn step(c: &mut Criterion) {
    let threads = pin_threads();
    println!("{}", fibfluid::linalg::threads::thread_note(threads));
    // Backend by backend (OpenBLAS last: its threads keep spinning after a call).
    for backend in Backend::compiled() {
        for mode in [Mode::Paper, Mode::Refresh] {
            let mut group = c.benchmark_group(format!("step/{}/{backend}", mode));
            // Criterion switches to one step per sample (flat sampling) by itself when a
            // step is long.
            group
                .sample_size(10)
                .warm_up_time(Duration::from_millis(500))
                .measurement_time(Duration::from_secs(2));
            for level in [3, 4] {
                let n = 10 * 4usize.pow(level) + 2;
                if let Some(why) = skipped(backend, n) {
                    println!("step/{}/{backend} at N = {n}: skipped ({why})", mode);
                    continue;
                }
                // Built on first use, so a criterion filter skips the setup of other cases.
                let mut state: Option<(Simulation, bool)> = None;
                let mut k = 0;
                group.bench_function(BenchmarkId::from_parameter(n), |b| {
                    let (sim, rewind) = state.get_or_insert_with(|| prepare(level, backend, mode));
                    b.iter_custom(|iters| {
                        let mut timed = Duration::ZERO;
                        for _ in 0..iters {
                            let start = Instant::now();
                            sim.step_load((k + 1) as f64 / STEPS as f64).expect("load step");
                            timed += start.elapsed();
                            k += 1;
                            if k == STEPS && *rewind {
                                sim.run_steps(STEPS, Direction::Unload, &RunOptions::default())
                                    .expect("unload steps");
                            }
                            k %= STEPS;
                        }
                        timed
                    })
                });
                if let Some((sim, _)) = &state {
                    println!(
                        "step/{}/{backend} N = {n}: {} solves, largest residual {:.1e}, at most {} refinement steps",
                        mode,
                        sim.counters().solves,
                        sim.counters().residual_max,
                        sim.counters().refinement_steps_max
                    );
                }
            }
            group.finish();
        }
    }
}

/// The simulation (assembly and first factorization untimed), after one untimed load and
/// unload step; the flag says whether steps are short enough to rewind the load.
fn prepare(level: u32, backend: Backend, mode: Mode) -> (Simulation, bool) {
    let scene = scene(level, backend, mode);
    let n = scene.n_vertices();
    let start = Instant::now();
    let mut sim = Simulation::new(scene).expect("simulation");
    let setup = start.elapsed().as_secs_f64();
    let start = Instant::now();
    sim.step_load(1.0 / STEPS as f64).expect("step");
    let one = start.elapsed().as_secs_f64();
    sim.step_load(0.0).expect("step");
    println!(
        "step/{}/{backend} N = {n}: setup (assembly + factorization) {setup:.3} s, first step {one:.4} s",
        mode
    );
    // Long steps run about 11 times in all: no rewinding (12 load steps are 1.2 times the
    // scene's load, still in range).
    (sim, one <= 0.15)
}

criterion_group!(benches, step);
criterion_main!(benches);
