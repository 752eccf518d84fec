//! `fibfluid bench --fem-solvers SCENE --resolutions R,..`: the finite-element method's
//! direct and multigrid solvers on one scene over a list of resolutions, in one process:
//! time per Newton iteration, the whole run, peak memory, and how far the multigrid's
//! surface is from the direct one's.

use fibfluid::fem::FemSolver;
use fibfluid::sim::fem_run::FemRun;
use fibfluid::sim::{Method, Model};
use serde::Serialize;

use crate::Result;

/// One solver at one resolution, as `bench --fem-solvers` reports it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FemSolverRun {
    /// Cells along the longest side.
    pub resolution: usize,
    /// The solver.
    pub solver: FemSolver,
    /// Active cells.
    pub cells: usize,
    /// Unknowns.
    pub dofs: usize,
    /// Newton iterations (1 solve each; a linear tissue without contact takes 1 or 2).
    pub newton_iterations: usize,
    /// Conjugate-gradient iterations per multigrid solve (0 for the direct solver).
    pub iterations_per_solve: f64,
    /// Wall-clock seconds of the whole run (voxelization to answer).
    pub seconds: f64,
    /// The run's seconds over its Newton iterations.
    pub seconds_per_newton_iteration: f64,
    /// Peak resident memory of the run (bytes; `None` where the system does not say).
    pub peak_bytes: Option<u64>,
    /// Relative L2 distance of this run's surface displacement from the direct solver's at
    /// the same resolution (`None` for the direct run, or when it did not run).
    pub from_direct: Option<f64>,
}

/// Runs `model` with the FEM at each resolution, once per solver in `solvers`, the direct
/// solver first when both are asked (so the multigrid's surface is compared with it).
///
/// Errors: a run's (the scene's cause, or too large for memory at that resolution).
pub fn bench_fem_solvers(
    model: &Model,
    resolutions: &[usize],
    solvers: &[FemSolver],
) -> Result<Vec<FemSolverRun>> {
    let mut rows = Vec::new();
    for &resolution in resolutions {
        let mut direct: Option<Vec<[f64; 3]>> = None;
        for &solver in solvers {
            let mut m = model.clone();
            m.solver.method = Method::Fem;
            m.fem.resolution = resolution;
            m.fem.solver = solver;
            reset_peak_memory();
            let run = FemRun::new(m, None)?;
            let peak_bytes = peak_memory();
            let displacement: Vec<[f64; 3]> = run
                .positions
                .iter()
                .zip(&run.rest)
                .map(|(p, r)| std::array::from_fn(|a| p[a] - r[a]))
                .collect();
            let stats = run.newton.as_ref().map(|n| n.stats).unwrap_or_default();
            let newton_iterations = stats.newton_iterations.max(1);
            let from_direct = match (&direct, solver) {
                (Some(d), FemSolver::Multigrid | FemSolver::Auto) => {
                    Some(relative_distance(&displacement, d))
                }
                _ => None,
            };
            if solver == FemSolver::Direct {
                direct = Some(displacement);
            }
            rows.push(FemSolverRun {
                resolution,
                solver,
                cells: run.stats.cells,
                dofs: run.stats.dofs,
                newton_iterations,
                iterations_per_solve: stats.linear_iterations as f64 / stats.linear_solves.max(1) as f64,
                seconds: run.seconds,
                seconds_per_newton_iteration: run.seconds / newton_iterations as f64,
                peak_bytes,
                from_direct,
            });
        }
    }
    Ok(rows)
}

/// `|a - b| / |b|` over all components.
fn relative_distance(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    let (mut diff, mut norm) = (0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        for k in 0..3 {
            diff += (x[k] - y[k]).powi(2);
            norm += y[k] * y[k];
        }
    }
    (diff / norm.max(f64::MIN_POSITIVE)).sqrt()
}

/// Resets the process's peak resident memory (Linux: `5` to `/proc/self/clear_refs`), so
/// the next [`peak_memory`] is one run's; elsewhere nothing.
fn reset_peak_memory() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

/// The process's peak resident memory since the last reset (Linux `VmHWM`), in bytes.
fn peak_memory() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}
