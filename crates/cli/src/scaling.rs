//! What `plan` says about size on this machine: the run's estimated time from the measured
//! matrix-product rate, and where the dense method stops being practical, with the FEM's
//! figures for the same body beside it.
//!
//! The FFM's memory grows as N^2 (dense N x N stiffness blocks and their factors) and its
//! factorization as N^3, so both limits are extrapolated from the scene's own plan: the N
//! at which the peak memory reaches the budget is `N sqrt(budget / memory)`, the N at which
//! the plan's flops take [`PRACTICAL_SECONDS`] at the measured rate is
//! `N cbrt(PRACTICAL_SECONDS rate / flops)`. The FEM's cost follows its grid, not N.

use fibfluid::sim::{Model, Plan};
use serde::Serialize;

/// A run longer than this (estimated, one core set) is called impractical: minutes per
/// solve is the end of interactive planning.
pub const PRACTICAL_SECONDS: f64 = 60.0;

/// Order of the square matrices of the rate probe: about 30 ms on two cores, large enough
/// for the blocked kernels to reach their rate.
pub const RATE_PROBE_ORDER: usize = 768;

/// One method's cost on this machine.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MethodCost {
    /// Peak memory in bytes (the plan's).
    pub memory_bytes: u64,
    /// Floating-point operations (the plan's).
    pub flops: f64,
    /// `flops` at the measured matrix-product rate, in seconds: a lower bound, since only
    /// the factorizations run at that rate.
    pub seconds: f64,
}

/// What `plan` prints under its table.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Scaling {
    /// Matrix-product rate measured now, with the threads this run will use, in flops/s.
    pub gemm_flops_per_second: f64,
    /// The FFM at the scene's N (absent for a FEM scene of a polygon).
    pub ffm: Option<MethodCost>,
    /// The FFM's N at which the memory reaches the budget.
    pub ffm_n_at_memory_limit: Option<f64>,
    /// The FFM's N at which the run takes [`PRACTICAL_SECONDS`].
    pub ffm_n_at_time_limit: Option<f64>,
    /// The FEM on the same body at the scene's `[fem]` settings.
    pub fem: Option<MethodCost>,
}

/// The dense product rate with the threads this process will use (best of 3).
pub fn measure_gemm_rate(order: usize) -> f64 {
    let n = order.max(16);
    let a = faer::Mat::<f64>::from_fn(n, n, |i, j| ((i * 31 + j * 17) % 13) as f64 - 6.0);
    let mut c = faer::Mat::<f64>::zeros(n, n);
    let mut best = f64::INFINITY;
    for _ in 0..3 {
        let start = std::time::Instant::now();
        let par = fibfluid::linalg::parallel::compute_par();
        faer::linalg::matmul::matmul(c.as_mut(), faer::Accum::Replace, a.as_ref(), a.as_ref(), 1.0, par);
        std::hint::black_box(&c);
        best = best.min(start.elapsed().as_secs_f64());
    }
    2.0 * (n as f64).powi(3) / best.max(1e-12)
}

/// The cost of `plan` at `rate` flops/s.
fn cost(plan: &Plan, rate: f64) -> MethodCost {
    MethodCost { memory_bytes: plan.memory_bytes, flops: plan.flops, seconds: plan.flops / rate }
}

/// The scaling figures of `scene` under a memory budget of `budget` bytes, at `rate`
/// flops/s. The scene's own method and the other one are both planned from counts.
pub fn scaling(scene: &Model, budget: u64, rate: f64) -> Scaling {
    let mut ffm_scene = scene.clone();
    ffm_scene.solver.method = fibfluid::Method::Ffm;
    let mut fem_scene = scene.clone();
    fem_scene.solver.method = fibfluid::Method::Fem;
    let ffm = cost(&Plan::from_counts(&ffm_scene), rate);
    let n = scene.n_vertices() as f64;
    let memory_limit = (ffm.memory_bytes > 0).then(|| n * (budget as f64 / ffm.memory_bytes as f64).sqrt());
    let time_limit = (ffm.flops > 0.0).then(|| n * (PRACTICAL_SECONDS * rate / ffm.flops).cbrt());
    let fem = matches!(scene.shape, fibfluid::Shape::Surface(_))
        .then(|| cost(&Plan::from_counts(&fem_scene), rate));
    Scaling {
        gemm_flops_per_second: rate,
        ffm: Some(ffm),
        ffm_n_at_memory_limit: memory_limit,
        ffm_n_at_time_limit: time_limit,
        fem,
    }
}

/// The lines `plan` prints.
pub fn scaling_lines(s: &Scaling, budget: u64) -> Vec<String> {
    let gib = |b: u64| b as f64 / (1u64 << 30) as f64;
    let mut out = vec![format!(
        "  on this machine ({:.1} GFLOP/s matrix-product rate, {} threads for compute):",
        s.gemm_flops_per_second / 1e9,
        fibfluid::linalg::parallel::compute_threads()
    )];
    if let Some(f) = &s.ffm {
        out.push(format!(
            "    FFM: {:.3} GiB, {:.3e} flops, at least {:.2} s",
            gib(f.memory_bytes),
            f.flops,
            f.seconds
        ));
    }
    if let (Some(m), Some(t)) = (s.ffm_n_at_memory_limit, s.ffm_n_at_time_limit) {
        let (limit, why) = if m <= t {
            (m, format!("its memory reaches the budget of {:.1} GiB", gib(budget)))
        } else {
            (t, format!("a run takes {PRACTICAL_SECONDS:.0} s"))
        };
        out.push(format!(
            "    FFM stops being practical near N = {:.0} vertices ({why}; memory grows as N^2, time as N^3)",
            limit
        ));
    }
    if let Some(f) = &s.fem {
        out.push(format!(
            "    FEM (this body at its [fem] settings): {:.3} GiB, {:.3e} flops, at least {:.2} s",
            gib(f.memory_bytes),
            f.flops,
            f.seconds
        ));
    }
    out
}
