//! Linear backends over the system size.
//!
//! For every backend compiled into the build (`fibfluid::linalg::all_backends()`) and
//! N = 100, 250, 500, 1000, 2000 vertices (dense size n = 3N + 1), the factorization and
//! the checked solve (`FactorizationExt::solve`: a solve, the residual and `|A| |x|`, and
//! a refinement step when the backward error is above its target; the count is printed)
//! are timed separately; the system is assembled outside the timing by
//! `fibfluid::assembly::synthetic_system` (elimination of the fixed degrees of freedom). The
//! factorization groups carry `Throughput::Elements(model flops)`, so criterion's
//! "elem/s" reads as FLOP/s (the dense LU counts (2/3) n^3). A faer GEMM of the same n
//! (2 n^3 flops) runs in the same process as the machine's practical peak, and the
//! structured backend's re-solve after a border change (`set_border` + one solve) is timed
//! apart from its factorization. Before the timings, the bytes held by the structured
//! factorization at N = 3000 are printed next to the dense matrix size.
//!
//! nalgebra-lu is skipped at N = 2000: its unblocked LU of the 6001^2 matrix takes minutes
//! per factorization and criterion needs at least 11 of them.
//!
//! Groups run backend by backend (GEMM first, OpenBLAS last: its threads keep spinning
//! after a call). Threads: `FIBFLUID_THREADS` (default every core) for faer, rayon and
//! OpenBLAS (`fibfluid::linalg::threads::pin_threads`). OpenBLAS picks its kernels when it loads
//! (`OPENBLAS_CORETYPE` overrides the choice); both settings are printed.
//!
//! Run: `cargo bench --features openblas --bench backends`.

use std::hint::black_box;
use std::time::Duration;

use criterion::{
    BatchSize, BenchmarkGroup, BenchmarkId, Criterion, SamplingMode, Throughput, criterion_group,
    criterion_main, measurement::WallTime,
};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::lu::partial_pivoting::factor::{lu_in_place, lu_in_place_scratch};
use faer::linalg::matmul::matmul;
use faer::{Accum, Mat};
use fibfluid::assembly::synthetic_system;
use fibfluid::assembly::{ConstraintMethod, System};
use fibfluid::geometry::fibonacci_sphere;
use fibfluid::linalg::threads::pin_threads;
use fibfluid::linalg::{FactorOptions, FactorizationExt, LinearSolver, all_backends, lu_flops};

/// Vertex counts N (dense size 3N + 1).
const SIZES: [usize; 5] = [100, 250, 500, 1000, 2000];
/// Vertex count of the memory comparison.
const MEMORY_N: usize = 3000;

/// Backends left out at a size, with the reason printed once.
fn skipped(backend: &str, n: usize) -> Option<&'static str> {
    (backend == "nalgebra-lu" && n >= 2000)
        .then_some("unblocked LU of the 6001^2 matrix: minutes per factorization, 11 needed")
}

struct Case {
    n: usize,
    system: System,
    rhs: Vec<f64>,
    /// Two physical borders (perturbed area vectors) for the re-solve bench.
    borders: [Vec<Vec<f64>>; 2],
}

fn case(n: usize) -> Case {
    let system = synthetic_system(n, ConstraintMethod::Eliminate).expect("synthetic system");
    let dim = system.matrix.dim();
    let rhs = (0..dim).map(|i| ((i * 7919) % 1000) as f64 / 1000.0 - 0.5).collect();
    let w = 4.0 * std::f64::consts::PI / n as f64;
    let pos = fibonacci_sphere(n);
    let areas = |amp: f64| -> Vec<[f64; 3]> {
        pos.iter()
            .enumerate()
            .map(|(i, p)| {
                let f = w * (1.0 + amp * (i as f64 * 0.37).sin());
                [p[0] * f, p[1] * f, p[2] * f]
            })
            .collect()
    };
    let borders = [system.border_for(&areas(0.01)), system.border_for(&areas(-0.01))];
    Case { n, system, rhs, borders }
}

/// Sampling for one measurement of about `seconds`: linear sampling for short ones, one
/// run per sample (criterion's minimum of 10 samples) for long ones.
fn configure(group: &mut BenchmarkGroup<'_, WallTime>, seconds: f64) {
    group.sample_size(10);
    if seconds > 0.15 {
        group.sampling_mode(SamplingMode::Flat);
        group.warm_up_time(Duration::from_millis(10));
        group.measurement_time(Duration::from_secs_f64((10.0 * seconds).max(1.0)));
    } else {
        group.sampling_mode(SamplingMode::Auto);
        group.warm_up_time(Duration::from_millis(500));
        group.measurement_time(Duration::from_secs(2));
    }
}

/// Rough seconds of a dense LU of size `dim` on this class of machine (for sampling only).
fn dense_estimate(backend: &str, dim: usize) -> f64 {
    let rate = if backend == "nalgebra-lu" { 2e9 } else { 4e10 };
    lu_flops(dim) / rate
}

fn memory_report() {
    let system = synthetic_system(MEMORY_N, ConstraintMethod::Eliminate).expect("synthetic system");
    let held_before = vm_kib("VmRSS");
    let reset = std::fs::write("/proc/self/clear_refs", "5").is_ok();
    let solver = fibfluid::Backend::Structured.solver().expect("structured backend");
    let f = solver.factorize(&system.matrix, &FactorOptions::default()).expect("factorization");
    let peak = vm_kib("VmHWM");
    let cost = f.cost();
    let dense = system.matrix.dense_bytes();
    println!(
        "memory N = {MEMORY_N}: structured FactorCost.bytes = {:.1} MiB, dense (3N+1)^2 f64 = {:.1} MiB, \
         ratio = {:.4}",
        cost.bytes as f64 / 1048576.0,
        dense as f64 / 1048576.0,
        cost.bytes as f64 / dense as f64
    );
    if let (true, Some(before), Some(peak)) = (reset, held_before, peak) {
        println!(
            "memory N = {MEMORY_N}: measured peak RSS during the structured factorization = {:.1} MiB above \
             the {:.1} MiB held before (assembled system included), ratio to dense = {:.4}",
            (peak.saturating_sub(before)) as f64 / 1024.0,
            before as f64 / 1024.0,
            (peak.saturating_sub(before)) as f64 * 1024.0 / dense as f64
        );
    }
    drop(f);
}

/// A `/proc/self/status` field in KiB.
fn vm_kib(field: &str) -> Option<u64> {
    let text = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = text.lines().find(|l| l.starts_with(field))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

fn backends(c: &mut Criterion) {
    let threads = pin_threads();
    println!("{}", fibfluid::linalg::threads::thread_note(threads));
    memory_report();
    let cases: Vec<Case> = SIZES.iter().map(|&n| case(n)).collect();
    let opts = FactorOptions::default();

    // The practical peak: a faer GEMM of each dense size.
    let mut group = c.benchmark_group("gemm/faer");
    for case in &cases {
        let dim = case.system.matrix.dim();
        let a = Mat::<f64>::from_fn(dim, dim, |i, j| ((i * 31 + j * 17) % 97) as f64 / 97.0 - 0.5);
        let b = Mat::<f64>::from_fn(dim, dim, |i, j| ((i * 13 + j * 29) % 89) as f64 / 89.0 - 0.5);
        let mut out = Mat::<f64>::zeros(dim, dim);
        let flops = 2.0 * (dim as f64).powi(3);
        configure(&mut group, flops / 8e10);
        group.throughput(Throughput::Elements(flops as u64));
        group.bench_with_input(BenchmarkId::from_parameter(dim), &dim, |bench, _| {
            bench.iter(|| {
                matmul(
                    out.as_mut(),
                    Accum::Replace,
                    a.as_ref(),
                    b.as_ref(),
                    1.0,
                    faer::get_global_parallelism(),
                );
                black_box(out[(0, 0)])
            })
        });
    }
    group.finish();

    // faer's LU kernel alone (in place on a copy made outside the timing): the backend's
    // factorization minus its conversion to the dense form and its bookkeeping.
    let mut group = c.benchmark_group("lu-kernel/faer");
    for case in &cases {
        let dim = case.system.matrix.dim();
        let dense = case.system.matrix.to_dense();
        configure(&mut group, dense_estimate("faer-lu", dim));
        group.throughput(Throughput::Elements(lu_flops(dim) as u64));
        let mut perm = vec![0usize; dim];
        let mut perm_inv = vec![0usize; dim];
        group.bench_with_input(BenchmarkId::new(format!("N={}", case.n), dim), &dense, |bench, dense| {
            bench.iter_batched(
                || dense.clone(),
                |mut a| {
                    let par = faer::get_global_parallelism();
                    let mut mem =
                        MemBuffer::new(lu_in_place_scratch::<usize, f64>(dim, dim, par, Default::default()));
                    lu_in_place(
                        a.as_mut(),
                        &mut perm,
                        &mut perm_inv,
                        par,
                        MemStack::new(&mut mem),
                        Default::default(),
                    );
                    a
                },
                BatchSize::PerIteration,
            )
        });
    }
    group.finish();

    for backend in all_backends() {
        let name = backend.name();
        for case in &cases {
            if let Some(why) = skipped(name, case.n) {
                println!("{name} at N = {}: skipped ({why})", case.n);
            }
        }
        factorize_and_solve(c, backend.as_ref(), &cases, &opts);
        if name == "structured" {
            resolve_with_new_border(c, backend.as_ref(), &cases, &opts);
        }
    }
}

fn factorize_and_solve(c: &mut Criterion, backend: &dyn LinearSolver, cases: &[Case], opts: &FactorOptions) {
    let name = backend.name();
    let structured = name == "structured";
    let mut group = c.benchmark_group(format!("factorize/{name}"));
    for case in cases.iter().filter(|c| skipped(name, c.n).is_none()) {
        let dim = case.system.matrix.dim();
        let probe = backend.factorize(&case.system.matrix, opts).expect("factorization");
        let flops = probe.cost().flops;
        drop(probe);
        let estimate = if structured { flops / 2e10 } else { dense_estimate(name, dim) };
        configure(&mut group, estimate);
        group.throughput(Throughput::Elements(flops as u64));
        group.bench_with_input(BenchmarkId::new(format!("N={}", case.n), dim), case, |bench, case| {
            // Each factorization is dropped after its timing, as the LU kernel's outputs are.
            bench.iter_batched(
                || (),
                |()| backend.factorize(black_box(&case.system.matrix), opts).expect("factorize"),
                BatchSize::PerIteration,
            )
        });
    }
    group.finish();

    let mut group = c.benchmark_group(format!("solve/{name}"));
    for case in cases.iter().filter(|c| skipped(name, c.n).is_none()) {
        let dim = case.system.matrix.dim();
        let f = backend.factorize(&case.system.matrix, opts).expect("factorization");
        let once = f.solve(&case.rhs).expect("solve");
        println!(
            "{name} N = {}: the checked solve refines {} time(s), backward error {:.1e}",
            case.n, once.refinement_steps, once.relative_residual
        );
        configure(&mut group, 0.0);
        group.bench_with_input(BenchmarkId::new(format!("N={}", case.n), dim), case, |bench, case| {
            bench.iter(|| black_box(f.solve(black_box(&case.rhs)).expect("solve")))
        });
    }
    group.finish();
}

fn resolve_with_new_border(
    c: &mut Criterion,
    backend: &dyn LinearSolver,
    cases: &[Case],
    opts: &FactorOptions,
) {
    let mut group = c.benchmark_group(format!("border-resolve/{}", backend.name()));
    for case in cases {
        let dim = case.system.matrix.dim();
        let mut f = backend.factorize(&case.system.matrix, opts).expect("factorization");
        configure(&mut group, 0.0);
        let mut which = 0;
        group.bench_with_input(BenchmarkId::new(format!("N={}", case.n), dim), case, |bench, case| {
            bench.iter(|| {
                which ^= 1;
                f.set_border(&case.borders[which]).expect("set_border");
                black_box(f.solve(black_box(&case.rhs)).expect("solve"))
            })
        });
    }
    group.finish();
}

criterion_group!(benches, backends);
criterion_main!(benches);
