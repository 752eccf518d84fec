//! The structured backend against the hardware limits it is bound by.
//!
//! - `solve/{N}` (N = 2,562 and 10,242, icospheres of level 4 and 5; the paper's sphere
//!   material, cap y > 0.8 fixed by elimination, automatic pressure scaling; a gravity load
//!   step as right-hand side): one checked solve (`FactorizationExt::solve`: triangular
//!   solves, residual, refinement while the backward error is above its target) in f64 and
//!   with the f32 factor (`Precision::Mixed`), against reading an N x N f64 buffer (the
//!   factor's size) twice: summed with eight accumulators on one thread, and split over
//!   the rayon pool.
//! - `factorize/1000`: the structured factorization against faer-lu (dense (3N+1)^2 LU)
//!   on the same system (N = 1,000 points of a Fibonacci sphere, every pair a fiber).
//!
//! Setup (assembly, factorizations) stays out of the timings. Threads: `FIBFLUID_THREADS`,
//! default every core. Before the timings, the bench prints the refinement steps of the
//! timed solves and `uptime`'s load.
//!
//! Run: `cargo bench -p fibfluid-linalg --bench structured`.

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use fibfluid_assembly::{
    AssemblyOptions, Body, ConstraintMethod, Constraints, Loads, Material, PressureScaling, Selector, System,
    assemble, load_vector,
};
use fibfluid_geometry::{FiberSet, Vec3, icosphere};
use fibfluid_linalg::{FactorOptions, FactorizationExt, LinearSolver, Precision, Structured};
use rayon::prelude::*;

fn pin_threads() -> usize {
    let n = std::env::var("FIBFLUID_THREADS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1));
    fibfluid_linalg::threads::set_threads(n);
    println!("threads: {n}; load: {}", load());
    n
}

/// The 1-, 5- and 15-minute load averages.
fn load() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .unwrap_or_default()
        .split_whitespace()
        .take(3)
        .collect::<Vec<_>>()
        .join(" ")
}

/// System of a body with every pair a fiber, cap y > 0.8 fixed, and a gravity step.
fn system(pos: &[Vec3], areas: &[Vec3], edges: &[[u32; 2]], gamma: f64) -> (System, Vec<f64>) {
    let n = pos.len();
    let fibers = FiberSet::all(n);
    let body =
        Body { axes: 3, positions: pos, vertex_areas: areas, edges, fibers: &fibers, rest_positions: None };
    let mut material = Material::default();
    material.set_surface_tension(gamma).unwrap();
    let mut c = Constraints::new(n);
    c.fix_selected(&Selector::Above { axis: 1, value: 0.8 }, pos, [true; 3]).expect("a cap");
    let opts =
        AssemblyOptions { method: ConstraintMethod::Eliminate, pressure_scaling: PressureScaling::Auto };
    let sys = assemble(&body, &material, &c, &opts).expect("assemble");
    let loads = Loads { acceleration: [0.0, -1.0, 0.0], down: None, density: 1000.0, forces: &[] };
    let b = load_vector(3, pos, areas, &loads).expect("loads");
    let rhs = sys.rhs(&b, 0.0, areas, 1.0);
    (sys, rhs)
}

fn sphere(level: u32) -> (System, Vec<f64>) {
    let mesh = icosphere(level, 1.0);
    let edges = mesh.adjacency().edges();
    system(mesh.positions(), &mesh.vertex_area_vectors(), &edges, 3000.0)
}

/// N points spread over the unit sphere, with area vectors of equal size.
fn fibonacci(n: usize) -> (System, Vec<f64>) {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let pos: Vec<Vec3> = (0..n)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - y * y).sqrt();
            let t = golden * i as f64;
            [r * t.cos(), y, r * t.sin()]
        })
        .collect();
    let w = 4.0 * std::f64::consts::PI / n as f64;
    let areas: Vec<Vec3> = pos.iter().map(|p| p.map(|c| c * w)).collect();
    system(&pos, &areas, &[], 0.0)
}

/// Sums `buf` twice with eight accumulators (vectorized, bound by memory).
fn stream_twice(buf: &[f64]) -> f64 {
    let mut acc = [0.0f64; 8];
    for _ in 0..2 {
        for chunk in black_box(buf).chunks_exact(8) {
            for (a, x) in acc.iter_mut().zip(chunk) {
                *a += x;
            }
        }
    }
    acc.iter().sum()
}

/// Prints the median of a few timed runs of each stage of a checked solve.
fn breakdown(sys: &System, f: &dyn fibfluid_linalg::Factorization, rhs: &[f64]) {
    let time = |what: &str, run: &mut dyn FnMut()| {
        let mut t: Vec<f64> = (0..7)
            .map(|_| {
                let s = std::time::Instant::now();
                run();
                s.elapsed().as_secs_f64() * 1e3
            })
            .collect();
        t.sort_by(f64::total_cmp);
        println!("  {what}: {:.2} ms", t[3]);
    };
    let a = &sys.matrix;
    let mut x = rhs.to_vec();
    f.solve_unrefined(&mut x);
    let (mut r, mut w) = (vec![0.0; x.len()], vec![0.0; x.len()]);
    time("triangular solves + Schur step", &mut || {
        let mut y = rhs.to_vec();
        f.solve_unrefined(&mut y);
    });
    time("fused residual and |A||x|", &mut || a.residual(&x, rhs, &mut r, &mut w));
    time("apply", &mut || a.apply(&x, &mut r));
    time("apply_abs", &mut || a.apply_abs(&x, &mut w));
}

fn solve(c: &mut Criterion) {
    pin_threads();
    let max_level = std::env::var("FIBFLUID_BENCH_MAX_LEVEL").ok().and_then(|v| v.parse().ok()).unwrap_or(5);
    for level in (4..=max_level).filter(|l| *l <= 5) {
        let (sys, rhs) = sphere(level);
        let n = sys.matrix.n_vertices();
        let f64_opts = FactorOptions::default();
        let mixed_opts = FactorOptions { precision: Precision::Mixed, ..f64_opts };
        let f = Structured.factorize(&sys.matrix, &f64_opts).expect("factorize");
        let fm = Structured.factorize(&sys.matrix, &mixed_opts).expect("factorize mixed");
        for (name, f) in [("f64", &f), ("mixed", &fm)] {
            let s = f.solve(&rhs).expect("solve");
            println!(
                "N = {n}, {name}: {} refinement steps, backward error {:.2e}",
                s.refinement_steps, s.relative_residual
            );
        }
        breakdown(&sys, f.as_ref(), &rhs);
        let buffer = vec![1.0f64; n * n];
        let mut g = c.benchmark_group(format!("solve/{n}"));
        g.sample_size(10).warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(3));
        g.bench_function("checked solve f64", |b| {
            b.iter(|| black_box(f.solve(black_box(&rhs)).expect("solve")))
        });
        g.bench_function("checked solve mixed", |b| {
            b.iter(|| black_box(fm.solve(black_box(&rhs)).expect("solve")))
        });
        g.bench_function("unrefined solve f64", |b| {
            b.iter(|| {
                let mut x = rhs.clone();
                f.solve_unrefined(&mut x);
                black_box(x)
            })
        });
        g.bench_function("stream factor twice, 1 thread", |b| b.iter(|| black_box(stream_twice(&buffer))));
        g.bench_function("stream factor twice, pool", |b| {
            b.iter(|| black_box(buffer.par_chunks(1 << 16).map(stream_twice).sum::<f64>()))
        });
        g.finish();
        println!("load after N = {n}: {}", load());
    }
}

fn factorize(c: &mut Criterion) {
    let (sys, _) = fibonacci(1000);
    let mut g = c.benchmark_group("factorize/1000");
    g.sample_size(20).warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(3));
    let opts = FactorOptions::default();
    g.bench_function("structured", |b| {
        b.iter(|| black_box(Structured.factorize(&sys.matrix, &opts).expect("factor")))
    });
    g.bench_function("faer-lu", |b| {
        b.iter(|| black_box(fibfluid_linalg::FaerLu.factorize(&sys.matrix, &opts).expect("factor")))
    });
    g.finish();
    println!("load after factorize/1000: {}", load());
}

criterion_group!(benches, factorize, solve);
criterion_main!(benches);
