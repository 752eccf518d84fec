//! Synthetic systems of any size, for `fibfluid bench` and the criterion benches.

use fibfluid_assembly::{
    AssemblyOptions, Body, ConstraintMethod, Constraints, Material, PressureScaling, System, assemble,
};
use fibfluid_geometry::{FiberSet, Vec3};

use crate::Result;

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
