//! The sparse-grid FEM against FFM on the same surface: the unit icosphere of level 3 (642
//! vertices), fixed on its cap y > 0.8, under gravity.
//!
//! - `fem/{stage}/{resolution}` for resolutions 8, 16, 24, 32: `voxelize`
//!   ([`SparseGrid::from_surface`]), `assemble` (the stiffness with the clamp penalty) and
//!   `factor` (ordering, symbolic and numeric sparse Cholesky), `solve` (one
//!   [`FemBody::solve`]: the triangular solves, the residual and the surface interpolation).
//!   `FemBody::new` does assembly and factorization in one call and times each part itself
//!   ([`FemBody::stats`]); `assemble` and `factor` report those internal timings through
//!   criterion's `iter_custom`, so each builds whole bodies and keeps its own part.
//! - `ffm/{stage}`: `assemble` (`fibfluid_assembly::assemble`: the fiber stiffness of every
//!   pair, the border and the elimination of the fixed dofs; paper's sphere material),
//!   `factor` (the default backend, [`Structured`], f64), `solve` (one checked solve of a
//!   gravity step: triangular solves, Schur step, residual and refinement).
//!
//! FFM runs first. The bench prints each body's sizes and `/proc/loadavg` at the start and end.
//!
//! Run: `cargo bench -p fibfluid-fem --bench fem -- --warm-up-time 1 --measurement-time 3`.

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{BenchmarkId, Criterion, SamplingMode, criterion_group, criterion_main};
use fibfluid_assembly::{
    AssemblyOptions, Body, ConstraintMethod, Constraints, Material, PressureScaling, Selector, assemble,
    load_vector,
};
use fibfluid_fem::{FemBody, Loads, SparseGrid, Tissue};
use fibfluid_geometry::{FiberSet, icosphere};
use fibfluid_linalg::{FactorOptions, FactorizationExt, LinearSolver, Structured};

mod common;
use common::load;

fn fem(c: &mut Criterion) {
    let mesh = icosphere(3, 1.0);
    let pos = mesh.positions().to_vec();
    let tris = mesh.triangles().to_vec();
    let fixed: Vec<[bool; 3]> = pos.iter().map(|p| [p[1] > 0.8; 3]).collect();
    let tissue = Tissue::new(5e4, 0.45, 1000.0).unwrap();
    let gravity = Loads { gravity: [0.0, -9.81, 0.0], ..Default::default() };
    let mut group = c.benchmark_group("fem");
    group.sample_size(10).sampling_mode(SamplingMode::Flat);
    for resolution in [8, 16, 24, 32] {
        group.bench_with_input(BenchmarkId::new("voxelize", resolution), &resolution, |b, &r| {
            b.iter(|| SparseGrid::from_surface(black_box(&pos), &tris, r).unwrap())
        });
        let grid = SparseGrid::from_surface(&pos, &tris, resolution).unwrap();
        // Whole bodies are built; each bench keeps the time of its own part.
        let part = |b: &mut criterion::Bencher, seconds: fn(&FemBody) -> f64| {
            b.iter_custom(|iters| {
                let mut total = 0.0;
                for _ in 0..iters {
                    let body = FemBody::new(grid.clone(), &tissue, &fixed).unwrap();
                    total += seconds(black_box(&body));
                }
                Duration::from_secs_f64(total)
            })
        };
        group.bench_with_input(BenchmarkId::new("assemble", resolution), &resolution, |b, _| {
            part(b, |body| body.stats().assembly_seconds)
        });
        group.bench_with_input(BenchmarkId::new("factor", resolution), &resolution, |b, _| {
            part(b, |body| body.stats().factor_seconds)
        });
        let mut body = FemBody::new(grid.clone(), &tissue, &fixed).unwrap();
        println!("fem {resolution}: {:?}", body.stats());
        group.bench_with_input(BenchmarkId::new("solve", resolution), &resolution, |b, _| {
            b.iter(|| body.solve(black_box(&gravity)).unwrap())
        });
    }
    group.finish();
    println!("load: {}", load());
}

fn ffm(c: &mut Criterion) {
    // Both methods on the same threads (`FIBFLUID_THREADS`, default every core: faer's
    // global parallelism and rayon's pool), as the workspace's other benches run.
    let threads = fibfluid_linalg::threads::pin_threads();
    println!("threads: {threads}; load: {}", load());
    let mesh = icosphere(3, 1.0);
    let pos = mesh.positions();
    let n = pos.len();
    let areas = mesh.vertex_area_vectors();
    let edges = mesh.adjacency().edges();
    let fibers = FiberSet::all(n);
    let body = Body {
        axes: 3,
        positions: pos,
        vertex_areas: &areas,
        edges: &edges,
        fibers: &fibers,
        rest_positions: None,
    };
    let material = Material::default();
    let mut constraints = Constraints::new(n);
    constraints.fix_selected(&Selector::Above { axis: 1, value: 0.8 }, pos, [true; 3]).expect("a cap");
    let opts =
        AssemblyOptions { method: ConstraintMethod::Eliminate, pressure_scaling: PressureScaling::Auto };
    let sys = assemble(&body, &material, &constraints, &opts).expect("assemble");
    let loads = fibfluid_assembly::Loads {
        acceleration: [0.0, -9.81, 0.0],
        down: None,
        density: 1000.0,
        forces: &[],
    };
    let b = load_vector(3, pos, &areas, &loads).expect("loads");
    let rhs = sys.rhs(&b, 0.0, &areas, 1.0);
    let f64_opts = FactorOptions::default();
    let t = Instant::now();
    let factor = Structured.factorize(&sys.matrix, &f64_opts).expect("factorize");
    println!(
        "ffm: {n} vertices, {} fibers, dim {}, factor {:.3} s",
        fibers.kept(),
        sys.matrix.dim(),
        t.elapsed().as_secs_f64()
    );

    let mut group = c.benchmark_group("ffm");
    group.sample_size(10);
    group.bench_function("assemble", |b| {
        b.iter(|| black_box(assemble(&body, &material, &constraints, &opts).expect("assemble")))
    });
    group.bench_function("factor", |b| {
        b.iter(|| black_box(Structured.factorize(&sys.matrix, &f64_opts).expect("factorize")))
    });
    group.bench_function("solve", |b| b.iter(|| black_box(factor.solve(black_box(&rhs)).expect("solve"))));
    group.finish();
}

criterion_group!(benches, ffm, fem);
criterion_main!(benches);
