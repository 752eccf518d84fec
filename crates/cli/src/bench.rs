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
