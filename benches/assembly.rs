//! Assembly of the bordered system on icospheres of level 2, 3 and 4 (N = 162, 642, 2562).
//!
//! `assemble/structured` times `fibfluid::assembly::assemble` (the K block, the border and
//! the elimination of the fixed degrees of freedom) for the paper's sphere material
//! (Y = gamma = 3000, rho = 1000; the vertices with y > 0.8 fixed); `assemble/to-dense`
//! times the conversion of that system to the dense (3N+1)^2 faer matrix, and
//! `assemble/to-dense-col-major` the column-major `Vec` the dense backends factor in
//! place. Vertex areas, edges and the fiber set (every pair: the sphere is convex) are
//! built outside the timing.
//!
//! Run: `cargo bench --features openblas --bench assembly`.

use std::hint::black_box;
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use fibfluid::assembly::{
    AssemblyOptions, Body, ConstraintMethod, Constraints, Material, PressureScaling, Selector, assemble,
};
use fibfluid::geometry::{FiberSet, TriMesh, icosphere};
use fibfluid::linalg::threads::pin_threads;

struct Sphere {
    mesh: TriMesh,
    areas: Vec<[f64; 3]>,
    edges: Vec<[u32; 2]>,
    fibers: FiberSet,
    constraints: Constraints,
}

impl Sphere {
    /// The body the assembly sees.
    fn body(&self) -> Body<'_> {
        Body {
            axes: 3,
            positions: self.mesh.positions(),
            vertex_areas: &self.areas,
            edges: &self.edges,
            fibers: &self.fibers,
            rest_positions: None,
        }
    }
}

fn sphere(level: u32) -> Sphere {
    let mesh = icosphere(level, 1.0);
    let n = mesh.n_vertices();
    let areas = mesh.vertex_area_vectors();
    let edges = mesh.adjacency().edges();
    let fibers = FiberSet::all(n);
    let mut constraints = Constraints::new(n);
    constraints
        .fix_selected(&Selector::Above { axis: 1, value: 0.8 }, mesh.positions(), [true; 3])
        .expect("the top cap exists");
    Sphere { mesh, areas, edges, fibers, constraints }
}

fn assembly(c: &mut Criterion) {
    let threads = pin_threads();
    println!("threads: faer/rayon {threads}");
    let material = Material::default();
    let opts =
        AssemblyOptions { method: ConstraintMethod::Eliminate, pressure_scaling: PressureScaling::Auto };
    let spheres: Vec<Sphere> = [2, 3, 4].into_iter().map(sphere).collect();

    let mut group = c.benchmark_group("assemble/structured");
    group.sample_size(10).warm_up_time(Duration::from_millis(500)).measurement_time(Duration::from_secs(3));
    for s in &spheres {
        let n = s.mesh.n_vertices();
        group.throughput(Throughput::Elements(s.fibers.kept() as u64));
        group.bench_with_input(BenchmarkId::from_parameter(n), s, |b, s| {
            let body = s.body();
            b.iter(|| black_box(assemble(&body, &material, &s.constraints, &opts).expect("assemble")))
        });
    }
    group.finish();

    let mut group = c.benchmark_group("assemble/to-dense");
    let mut dense_systems = Vec::new();
    group.sample_size(10).warm_up_time(Duration::from_millis(500)).measurement_time(Duration::from_secs(3));
    for s in &spheres {
        let n = s.mesh.n_vertices();
        let body = s.body();
        let system = assemble(&body, &material, &s.constraints, &opts).expect("assemble");
        group.throughput(Throughput::Bytes(system.matrix.dense_bytes() as u64));
        group.bench_with_input(BenchmarkId::from_parameter(n), &system, |b, system| {
            b.iter(|| black_box(system.matrix.to_dense()))
        });
        dense_systems.push(system);
    }
    group.finish();

    let mut group = c.benchmark_group("assemble/to-dense-col-major");
    group.sample_size(10).warm_up_time(Duration::from_millis(500)).measurement_time(Duration::from_secs(3));
    for system in &dense_systems {
        group.throughput(Throughput::Bytes(system.matrix.dense_bytes() as u64));
        group.bench_with_input(
            BenchmarkId::from_parameter(system.matrix.n_vertices()),
            system,
            |b, system| b.iter(|| black_box(system.matrix.to_dense_col_major())),
        );
    }
    group.finish();
}

criterion_group!(benches, assembly);
criterion_main!(benches);
