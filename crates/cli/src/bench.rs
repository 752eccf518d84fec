//! Synthetic systems of any size, for `fibfluid bench` and the criterion benches.

use fibfluid_assembly::{
    AssemblyOptions, Body, ConstraintMethod, Constraints, Material, PressureScaling, System, assemble,
};
use fibfluid_geometry::{FiberSet, Vec3};
use fibfluid_linalg::{Backend, FactorOptions, FactorizationExt};
use serde::Serialize;

use crate::Result;

/// One backend at one size, as `fibfluid bench` reports it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BenchRow {
    /// Backend.
    pub backend: Backend,
    /// Vertices N.
    pub n_vertices: usize,
    /// System size dN + 1.
    pub dim: usize,
    /// Median seconds of the warm factorizations.
    pub factor_seconds: f64,
    /// Median seconds of the warm solves.
    pub solve_seconds: f64,
    /// Model flops of the factorization over its median time, in GFLOP/s.
    pub factor_gflops: f64,
    /// Bytes the factorization holds.
    pub memory_bytes: usize,
    /// Largest componentwise backward error of the solves.
    pub residual: f64,
    /// Timed repeats (after one untimed warm-up run).
    pub repeats: usize,
}

/// Smallest and largest N `fibfluid bench` accepts.
pub const BENCH_SIZES: std::ops::RangeInclusive<usize> = 4..=20_000;

/// Times every compiled-in backend on the [`synthetic_system`] of size `n`: one untimed
/// warm-up factorization and solve, then `repeats` timed ones, reporting the medians (a
/// single cold run includes page faults and thread start-up and varies by 2x between
/// runs). A backend that cannot factor the system (too large for memory) is returned as
/// an error beside the rows.
pub fn bench_backends(
    n: usize,
    repeats: usize,
) -> Result<Vec<std::result::Result<BenchRow, (Backend, crate::Error)>>> {
    let system = synthetic_system(n, ConstraintMethod::Eliminate)?;
    let dim = system.matrix.dim();
    let rhs: Vec<f64> = (0..dim).map(|i| ((i * 7919) % 1000) as f64 / 1000.0 - 0.5).collect();
    let repeats = repeats.max(1);
    let mut rows = Vec::new();
    for backend in Backend::compiled() {
        let row = (|| -> Result<BenchRow> {
            let solver = backend.solver()?;
            let opts = FactorOptions::default();
            let warm = solver.factorize(&system.matrix, &opts)?;
            let mut residual = warm.solve(&rhs)?.relative_residual;
            let mut factor = Vec::with_capacity(repeats);
            let mut solve = Vec::with_capacity(repeats);
            let mut bytes = 0;
            for _ in 0..repeats {
                let start = std::time::Instant::now();
                let f = solver.factorize(&system.matrix, &opts)?;
                factor.push(start.elapsed().as_secs_f64());
                bytes = f.cost().bytes;
                let start = std::time::Instant::now();
                let sol = f.solve(&rhs)?;
                solve.push(start.elapsed().as_secs_f64());
                residual = residual.max(sol.relative_residual);
            }
            let factor_seconds = median(&mut factor);
            Ok(BenchRow {
                backend,
                n_vertices: n,
                dim,
                factor_seconds,
                solve_seconds: median(&mut solve),
                factor_gflops: warm.cost().flops / factor_seconds.max(1e-12) / 1e9,
                memory_bytes: bytes,
                residual,
                repeats,
            })
        })();
        rows.push(row.map_err(|e| (backend, e)));
    }
    Ok(rows)
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    if v.len() % 2 == 1 { v[m] } else { 0.5 * (v[m - 1] + v[m]) }
}

/// Environment variable read by [`pin_threads`].
pub const THREADS_ENV: &str = "FIBFLUID_THREADS";

/// Pins the thread count of a bench process through
/// [`set_threads`](fibfluid_linalg::threads::set_threads) (faer, rayon's global pool and,
/// when built, OpenBLAS at run time): the value of `FIBFLUID_THREADS` if it is set to a
/// positive integer, else every core the process may use. Returns the count. Call it
/// before anything builds rayon's global pool.
pub fn pin_threads() -> usize {
    let n = std::env::var(THREADS_ENV)
        .ok()
        .and_then(|v| v.trim().parse::<usize>().ok())
        .filter(|&n| n > 0)
        .unwrap_or_else(|| std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1));
    fibfluid_linalg::threads::set_threads(n);
    n
}

/// `n` points spread evenly over the unit sphere (Fibonacci lattice), y up.
pub fn fibonacci_sphere(n: usize) -> Vec<Vec3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - y * y).max(0.0).sqrt();
            let t = golden * i as f64;
            [r * t.cos(), y, r * t.sin()]
        })
        .collect()
}

/// The FFM system of a sphere sampled at `n` points: every pair a fiber (convex), vertex
/// area vectors `4 pi / n` along the normal, no surface fibers, the top 10 % fixed, with
/// the paper's material. Its K blocks are as dense and as conditioned as a real convex
/// body's, without needing a mesh of exactly `n` vertices.
pub fn synthetic_system(n: usize, method: ConstraintMethod) -> Result<System> {
    let pos = fibonacci_sphere(n);
    let w = 4.0 * std::f64::consts::PI / n as f64;
    let areas: Vec<Vec3> = pos.iter().map(|p| p.map(|c| c * w)).collect();
    let fibers = FiberSet::all(n);
    let body = Body {
        axes: 3,
        positions: &pos,
        vertex_areas: &areas,
        edges: &[],
        fibers: &fibers,
        rest_positions: None,
    };
    let material = Material { surface_tension: 0.0, ..Material::default() };
    let mut c = Constraints::new(n);
    for (i, p) in pos.iter().enumerate() {
        if p[1] > 0.8 {
            c.fix(i, [true; 3])?;
        }
    }
    let scaling =
        if method == ConstraintMethod::Eliminate { PressureScaling::Auto } else { PressureScaling::None };
    Ok(assemble(&body, &material, &c, &AssemblyOptions { method, pressure_scaling: scaling })?)
}

/// One line describing the thread settings of this process, for bench logs: the count
/// [`pin_threads`] set, and the OpenBLAS variables read when the library loads.
pub fn thread_note(threads: usize) -> String {
    let env = |k: &str| std::env::var(k).unwrap_or_else(|_| "unset".into());
    format!(
        "threads: {threads} for faer, rayon and OpenBLAS (set at run time); at load \
         OPENBLAS_NUM_THREADS = {}, OPENBLAS_CORETYPE = {}",
        env("OPENBLAS_NUM_THREADS"),
        env("OPENBLAS_CORETYPE")
    )
}

/// The benches' body: an icosphere of radius 1 at subdivision `level` with the paper's
/// material, the cap y > 0.8 fixed by elimination and gravity (0, -10, 0), one load step,
/// default solver options.
pub fn hanging_sphere(level: u32) -> Result<crate::Scene> {
    let mesh = fibfluid_geometry::icosphere(level, 1.0);
    let n = mesh.n_vertices();
    let path = format!("icosphere-{level}");
    let file = fibfluid_geometry::MeshFile::from_mesh(&path, mesh)
        .map_err(|source| fibfluid_geometry::GeometryError::Mesh { path: path.into(), source })?;
    let mut scene = crate::Scene::from_mesh(format!("sphere-{n}"), file, Material::default());
    let positions = scene.rest_positions();
    scene.constraints.fix_selected(
        &fibfluid_assembly::Selector::Above { axis: 1, value: 0.8 },
        &positions,
        [true; 3],
    )?;
    scene.gravity = [0.0, -10.0, 0.0];
    scene.solver.constraints = fibfluid_assembly::ConstraintKind::Eliminate;
    Ok(scene)
}
