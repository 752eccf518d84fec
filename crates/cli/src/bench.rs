//! `fibfluid bench`: every compiled-in backend timed on a synthetic system of any size.

use fibfluid::assembly::{ConstraintMethod, synthetic_system};
use fibfluid::linalg::{Backend, FactorOptions, FactorizationExt};
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

/// Times every compiled-in backend on the [`synthetic_system`](fibfluid::assembly::synthetic_system) of size `n`: one untimed
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

/// This machine's limits, measured in the same run as the stages they judge.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct MachineRates {
    /// Streaming read bandwidth of one thread over a buffer larger than the caches (bytes
    /// per second, the fastest of 5 passes).
    pub read_bytes_per_second: f64,
    /// Dense matrix product rate with the compute threads (flops per second, the fastest of 3
    /// products of 1024 x 1024 matrices): the rate a blocked factorization can reach.
    pub gemm_flops_per_second: f64,
}

/// One stage of a scene beside its limit on this machine.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StageBench {
    /// The stage.
    pub stage: &'static str,
    /// Measured seconds.
    pub seconds: f64,
    /// What the limit is.
    pub limit: String,
    /// Seconds at the limit.
    pub limit_seconds: f64,
    /// `seconds / limit_seconds`.
    pub ratio: f64,
}

/// Measures [`MachineRates`]; the read buffer is at least `bytes` (and 64 MiB, beyond the caches) long.
pub fn measure_machine(bytes: usize) -> MachineRates {
    let len = bytes.max(64 << 20) / 8;
    let buffer: Vec<f64> = (0..len).map(|i| (i % 7) as f64).collect();
    let mut read = f64::INFINITY;
    for _ in 0..5 {
        let start = std::time::Instant::now();
        // Eight independent sums, so the loop is bound by memory, not by the adds' latency.
        let mut lanes = [0.0f64; 8];
        for chunk in std::hint::black_box(&buffer).chunks_exact(8) {
            for (l, x) in lanes.iter_mut().zip(chunk) {
                *l += x;
            }
        }
        std::hint::black_box(lanes);
        read = read.min(start.elapsed().as_secs_f64());
    }
    drop(buffer);
    MachineRates {
        read_bytes_per_second: (len * 8) as f64 / read,
        gemm_flops_per_second: crate::scaling::measure_gemm_rate(1024),
    }
}

/// Seconds to compute the dense matrix of every pairwise distance of `points` in one thread
/// (what SciPy's `cdist` does): the work the assembly's fiber pairs cannot go below.
pub fn distance_matrix_seconds(points: &[fibfluid::geometry::Vec3]) -> f64 {
    let n = points.len();
    let mut d = vec![0.0f64; n * n];
    let start = std::time::Instant::now();
    for (row, p) in d.chunks_exact_mut(n).zip(points) {
        for (out, q) in row.iter_mut().zip(points) {
            let (x, y, z) = (p[0] - q[0], p[1] - q[1], p[2] - q[2]);
            *out = (x * x + y * y + z * z).sqrt();
        }
    }
    std::hint::black_box(&d);
    start.elapsed().as_secs_f64()
}

/// `fibfluid bench --stages SCENE`: the scene's assembly, factorization and one checked
/// solve (the median of `repeats`) beside their limits on this machine, measured in the
/// same run: every pairwise distance computed once in one thread (assembly), the
/// factorization's model flops at the matrix-product rate, and the factor streamed twice
/// (a forward and a backward substitution) at the read bandwidth.
pub fn bench_stages(scene: fibfluid::sim::Model, repeats: usize) -> Result<(MachineRates, Vec<StageBench>)> {
    use fibfluid::stages::names;
    let n = scene.n_vertices();
    let rest = scene.rest_positions();
    let sim = fibfluid::Simulation::new(scene)?;
    let seconds_of =
        |stage| sim.log().records().iter().filter(|r| r.name == stage).map(|r| r.seconds).sum::<f64>();
    let (assembly, factorization) = (seconds_of(names::ASSEMBLY), seconds_of(names::FACTORIZATION));
    let (system, factor) = sim.into_factored();
    let cost = factor.cost();
    let rhs: Vec<f64> = (0..system.matrix.dim()).map(|i| ((i * 7919) % 1000) as f64 / 1000.0 - 0.5).collect();
    let mut solves = Vec::with_capacity(repeats.max(1));
    for _ in 0..repeats.max(1) {
        let start = std::time::Instant::now();
        factor.solve(&rhs)?;
        solves.push(start.elapsed().as_secs_f64());
    }
    let solve = median(&mut solves);
    let rates = measure_machine(cost.bytes);
    let distances = distance_matrix_seconds(&rest);
    let row = |stage, seconds: f64, limit: String, limit_seconds: f64| StageBench {
        stage,
        seconds,
        limit,
        limit_seconds,
        ratio: seconds / limit_seconds.max(1e-300),
    };
    let stages = vec![
        row("assembly", assembly, format!("the {n} x {n} distances, one thread (SciPy's cdist)"), distances),
        row(
            "factorization",
            factorization,
            format!("{:.2e} model flops at the GEMM rate", cost.flops),
            cost.flops / rates.gemm_flops_per_second,
        ),
        row(
            "checked solve",
            solve,
            format!("the factor streamed twice ({:.0} MiB)", 2.0 * cost.bytes as f64 / 1048576.0),
            2.0 * cost.bytes as f64 / rates.read_bytes_per_second,
        ),
    ];
    Ok((rates, stages))
}

/// One thread count of a sweep: the count asked for, the count the compute stages used
/// (at most the cores), and the stages measured with it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SweepRow {
    /// Threads allowed (the pool's size and faer's parallelism).
    pub threads: usize,
    /// Threads the compute-bound stages used: `threads`, at most the cores.
    pub compute_threads: usize,
    /// The machine's rates with these threads.
    pub machine: MachineRates,
    /// The stages, as [`bench_stages`] measures them.
    pub stages: Vec<StageBench>,
}

/// `fibfluid bench --stages SCENE --threads-sweep 1,2,..`: [`bench_stages`] once per thread
/// count, each in a rayon pool of that size with faer's parallelism set to it (restored
/// afterwards), in one process so that the ratios compare like with like.
pub fn bench_stages_sweep(
    scene: &fibfluid::sim::Model,
    repeats: usize,
    threads: &[usize],
) -> Result<Vec<SweepRow>> {
    let before = faer::get_global_parallelism();
    let mut rows = Vec::with_capacity(threads.len());
    for &t in threads {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build()
            .map_err(|e| fibfluid::linalg::LinalgError::ThreadPool { threads: t, message: e.to_string() });
        let pool = match pool {
            Ok(p) => p,
            Err(e) => {
                faer::set_global_parallelism(before);
                return Err(e.into());
            }
        };
        faer::set_global_parallelism(fibfluid::linalg::parallel::par_of(t));
        let measured = pool.install(|| {
            let compute_threads = fibfluid::linalg::parallel::compute_threads();
            bench_stages(scene.clone(), repeats).map(|(machine, stages)| SweepRow {
                threads: t,
                compute_threads,
                machine,
                stages,
            })
        });
        faer::set_global_parallelism(before);
        rows.push(measured?);
    }
    Ok(rows)
}
