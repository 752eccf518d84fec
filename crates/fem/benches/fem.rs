//! Assembly, factorization and one solve of the sparse-grid FEM against resolution, on the
//! unit icosphere (642 vertices) fixed on its top cap, under gravity.

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use fibfluid_fem::{FemBody, Loads, SparseGrid, Tissue};
use fibfluid_geometry::icosphere;

fn bench(c: &mut Criterion) {
    let mesh = icosphere(3, 1.0);
    let pos = mesh.positions().to_vec();
    let tris = mesh.triangles().to_vec();
    let fixed: Vec<[bool; 3]> = pos.iter().map(|p| [p[1] > 0.8; 3]).collect();
    let tissue = Tissue::new(5e4, 0.45, 1000.0).unwrap();
    let gravity = Loads { gravity: [0.0, -9.81, 0.0], ..Default::default() };
    let mut group = c.benchmark_group("fem_sphere");
    group.sample_size(10);
    for resolution in [8, 16, 24, 32] {
        group.bench_with_input(BenchmarkId::new("voxelize", resolution), &resolution, |b, &r| {
            b.iter(|| SparseGrid::from_surface(black_box(&pos), &tris, r).unwrap())
        });
        let grid = SparseGrid::from_surface(&pos, &tris, resolution).unwrap();
        // Assembly and factorization are timed together by `FemBody::new`; the split is in
        // `FemBody::stats` (printed once per resolution).
        group.bench_with_input(BenchmarkId::new("assemble_and_factor", resolution), &resolution, |b, _| {
            b.iter(|| FemBody::new(grid.clone(), &tissue, &fixed).unwrap())
        });
        let mut body = FemBody::new(grid.clone(), &tissue, &fixed).unwrap();
        eprintln!("{:?}", body.stats());
        group.bench_with_input(BenchmarkId::new("solve", resolution), &resolution, |b, _| {
            b.iter(|| body.solve(black_box(&gravity)).unwrap())
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
