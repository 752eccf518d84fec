//! Fiber culling on the fixture meshes.
//!
//! `cull/bvh` times `cull_fibers` (convexity check, exit test, BVH-accelerated crossing
//! test) on spot.obj (2930 vertices), liver2.obj (1170) and liver-smooth.obj (2194).
//! `cull-vs-brute/*` compares it on small meshes (liver.obj, 181 vertices; the torus, 200)
//! with a brute-force culling that runs the same exit test and then
//! `crosses_surface_brute_force` (every face) for each remaining fiber; both are
//! parallel over rows with rayon and both keep the same fibers (checked before timing).
//!
//! Run: `cargo bench --features openblas --bench culling`.

use std::hint::black_box;
use std::path::PathBuf;
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, SamplingMode, criterion_group, criterion_main};
use fibfluid::geometry::{
    EXIT_TOLERANCE, FiberSet, TriMesh, VisibilityOptions, crosses_surface_brute_force, cull_fibers,
    load_mesh,
    vec3::{dot, norm, sub},
};
use fibfluid::linalg::threads::pin_threads;
use rayon::prelude::*;

fn mesh(name: &str) -> TriMesh {
    let path: PathBuf = [env!("CARGO_MANIFEST_DIR"), "fixtures", "meshes", name].iter().collect();
    load_mesh(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display())).mesh
}

/// The reference culling: the exit test at both ends, then every face for the crossing.
fn cull_brute_force(mesh: &TriMesh) -> FiberSet {
    let n = mesh.n_vertices();
    let pos = mesh.positions();
    let areas = mesh.face_area_vectors();
    let adj = mesh.adjacency();
    let exits = |i: usize, j: usize| {
        let d = sub(pos[j], pos[i]);
        let ld = norm(d);
        adj.faces_of(i).iter().any(|&k| {
            let a = areas[k as usize];
            dot(a, d) > EXIT_TOLERANCE * norm(a) * ld
        })
    };
    let rows: Vec<Vec<u32>> = (0..n)
        .into_par_iter()
        .map(|i| {
            (i + 1..n)
                .filter(|&j| !exits(i, j) && !exits(j, i) && !crosses_surface_brute_force(mesh, i, j))
                .map(|j| j as u32)
                .collect()
        })
        .collect();
    FiberSet::from_rows(n, &rows)
}

fn culling(c: &mut Criterion) {
    let threads = pin_threads();
    println!("threads: rayon {threads}");
    let opts = VisibilityOptions::default();

    let mut group = c.benchmark_group("cull/bvh");
    group
        .sample_size(10)
        .sampling_mode(SamplingMode::Flat)
        .warm_up_time(Duration::from_millis(10))
        .measurement_time(Duration::from_secs(5));
    for name in ["spot.obj", "liver2.obj", "liver-smooth.obj"] {
        let m = mesh(name);
        let (set, report) = cull_fibers(&m, &opts);
        println!(
            "{name}: {} vertices, {} faces, convex {}, kept {} of {} fibers (exit {}, crossing {})",
            m.n_vertices(),
            m.n_faces(),
            report.convex,
            set.kept(),
            set.total(),
            report.removed_by_exit,
            report.removed_by_crossing
        );
        group.bench_with_input(BenchmarkId::new(name, m.n_vertices()), &m, |b, m| {
            b.iter(|| black_box(cull_fibers(m, &opts)))
        });
    }
    group.finish();

    for name in ["liver.obj", "torus2_for_collision.obj"] {
        let m = mesh(name);
        // Same kept fibers, or the comparison would be meaningless. The torus is not convex,
        // so both run every test.
        let forced = VisibilityOptions { force_tests: true, ..opts };
        let (fast, _) = cull_fibers(&m, &forced);
        let brute = cull_brute_force(&m);
        assert_eq!(fast, brute, "{name}: the accelerated and brute-force cullings differ");
        println!(
            "{name}: {} vertices, {} faces, kept {} of {}",
            m.n_vertices(),
            m.n_faces(),
            fast.kept(),
            fast.total()
        );
        let mut group = c.benchmark_group(format!("cull-vs-brute/{name}"));
        group
            .sample_size(10)
            .warm_up_time(Duration::from_millis(300))
            .measurement_time(Duration::from_secs(3));
        group.bench_function("bvh", |b| b.iter(|| black_box(cull_fibers(&m, &forced))));
        group.bench_function("brute-force", |b| b.iter(|| black_box(cull_brute_force(&m))));
        group.finish();
    }
}

criterion_group!(benches, culling);
criterion_main!(benches);
