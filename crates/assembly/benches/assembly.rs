//! Assembly against a plain N x N distance computation (what SciPy's `cdist` does).
//!
//! Icospheres of level 4 and 5 (N = 2,562 and 10,242), every pair a fiber, the paper's
//! sphere material (Y = gamma = 3000), the cap y > 0.8 fixed by elimination, automatic
//! pressure scaling. `assemble` builds the shared K block (N x N, fresh), the border and
//! the elimination; `distances` fills a fresh N x N f64 matrix with `|s_i - s_j|`, rows in
//! parallel over the rayon pool, from contiguous coordinate arrays. Vertex areas, edges and
//! the fiber set are built outside the timing. Threads: `FIBFLUID_THREADS`, default every
//! core.
//!
//! Run: `cargo bench -p fibfluid-assembly --bench assembly`.

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use fibfluid_assembly::{
    AssemblyOptions, Body, ConstraintMethod, Constraints, Material, PressureScaling, Selector, assemble,
};
use fibfluid_geometry::{FiberSet, icosphere};
use rayon::prelude::*;

/// The 1-, 5- and 15-minute load averages.
fn load() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .unwrap_or_default()
        .split_whitespace()
        .take(3)
        .collect::<Vec<_>>()
        .join(" ")
}

/// A fresh N x N matrix of the distances between the points (x, y, z given as arrays).
fn distances(x: &[f64], y: &[f64], z: &[f64]) -> Vec<f64> {
    let n = x.len();
    let mut d = vec![0.0f64; n * n];
    d.par_chunks_mut(n).enumerate().for_each(|(i, row)| {
        let (xi, yi, zi) = (x[i], y[i], z[i]);
        for (((r, xj), yj), zj) in row.iter_mut().zip(x).zip(y).zip(z) {
            let (dx, dy, dz) = (xi - xj, yi - yj, zi - zj);
            *r = (dx * dx + dy * dy + dz * dz).sqrt();
        }
    });
    d
}

fn bench(c: &mut Criterion) {
    let threads = std::env::var("FIBFLUID_THREADS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1));
    fibfluid_linalg::threads::set_threads(threads);
    println!("threads: {threads}; load: {}", load());
    for level in [4, 5] {
        let mesh = icosphere(level, 1.0);
        let n = mesh.n_vertices();
        let pos = mesh.positions();
        let areas = mesh.vertex_area_vectors();
        let edges = mesh.adjacency().edges();
        let fibers = FiberSet::all(n);
        let mut constraints = Constraints::new(n);
        constraints.fix_selected(&Selector::Above { axis: 1, value: 0.8 }, pos, [true; 3]).expect("a cap");
        let body = Body {
            axes: 3,
            positions: pos,
            vertex_areas: &areas,
            edges: &edges,
            fibers: &fibers,
            rest_positions: None,
        };
        let material = Material::default();
        let opts =
            AssemblyOptions { method: ConstraintMethod::Eliminate, pressure_scaling: PressureScaling::Auto };
        let (x, y, z): (Vec<f64>, Vec<f64>, Vec<f64>) = (
            pos.iter().map(|p| p[0]).collect(),
            pos.iter().map(|p| p[1]).collect(),
            pos.iter().map(|p| p[2]).collect(),
        );
        let mut g = c.benchmark_group(format!("assembly/{n}"));
        g.sample_size(10).warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(3));
        g.bench_function("assemble", |b| {
            b.iter(|| black_box(assemble(&body, &material, &constraints, &opts).expect("assemble")))
        });
        g.bench_function("distances", |b| b.iter(|| black_box(distances(&x, &y, &z))));
        g.finish();
        println!("load after N = {n}: {}", load());
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
