//! How many threads each stage uses: the work decides, the cores cap it.
//!
//! `--threads T` (faer's global parallelism and rayon's pool) is what the user allows, not
//! what every stage should use. Two rules keep more threads from ever being slower:
//!
//! - **Never more threads than cores.** A stage run with four threads per core spends its
//!   time switching and spinning (measured on 2 cores: the checked solve at 8 threads took
//!   10 times as long as at 2; the GEMM probe 3 times). [`compute_threads`] is the
//!   allowed count capped at [`cores`]; the factorizations and matrix products use it.
//! - **Memory-bound passes split by bytes, not by threads.** A triangular solve or a
//!   residual with a few right-hand sides reads the factor (or the matrix) once and does two
//!   flops per entry read: its speed is the memory's, and a thread is worth starting only
//!   for a share of at least [`MIN_TASK_BYTES`]. [`stream_tasks`] gives the number of
//!   shares for a pass over some bytes; it follows the work (the factor's size and
//!   blocking) and never exceeds the threads allowed.

use faer::Par;

/// Smallest share of a memory-bound pass worth a task of its own: 1 MiB, about 100 us of
/// reading at 10 GB/s, against a few microseconds to hand a task to a pool thread and
/// join it.
pub const MIN_TASK_BYTES: usize = 1 << 20;

/// The cores this process may run on (`std::thread::available_parallelism`, 1 when unknown).
pub fn cores() -> usize {
    std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1)
}

/// The threads the user allows: faer's global parallelism, or the current rayon pool's
/// size when that is smaller (a caller's own pool).
pub fn allowed_threads() -> usize {
    let faer = match faer::get_global_parallelism() {
        Par::Seq => 1,
        Par::Rayon(n) => n.get(),
    };
    faer.min(rayon::current_num_threads()).max(1)
}

/// Threads for compute-bound work (factorizations, matrix products): the allowed count,
/// at most [`cores`].
pub fn compute_threads() -> usize {
    allowed_threads().min(cores()).max(1)
}

/// [`compute_threads`] as faer's parallelism.
pub fn compute_par() -> Par {
    par_of(compute_threads())
}

/// Shares of a memory-bound pass over `bytes` with at most `threads` threads: one per
/// [`MIN_TASK_BYTES`], at least 1, at most `threads`. A pure function of the work and the
/// threads, so a small factor gets one thread on any machine.
pub fn stream_tasks(bytes: usize, threads: usize) -> usize {
    (bytes / MIN_TASK_BYTES).clamp(1, threads.max(1))
}

/// [`stream_tasks`] with [`compute_threads`].
pub fn stream_threads(bytes: usize) -> usize {
    stream_tasks(bytes, compute_threads())
}

/// [`stream_threads`] as faer's parallelism.
pub fn stream_par(bytes: usize) -> Par {
    par_of(stream_threads(bytes))
}

/// Runs `op` where its parallel parts get no more pool threads than cores: directly when
/// the current rayon pool is no larger than [`cores`], else on a pool of [`cores`] threads
/// (built once). With four threads per core, the idle threads of a pool searching for
/// work took the cores from the two tasks of a memory-bound pass: the checked solve at
/// N = 10,242 took 1.4 times as long at 8 threads as at 2 on this project's 2-core machine.
pub fn on_cores<R: Send>(op: impl FnOnce() -> R + Send) -> R {
    static CORE_POOL: std::sync::OnceLock<Option<rayon::ThreadPool>> = std::sync::OnceLock::new();
    if rayon::current_num_threads() <= cores() {
        return op();
    }
    let pool = CORE_POOL.get_or_init(|| rayon::ThreadPoolBuilder::new().num_threads(cores()).build().ok());
    match pool {
        Some(pool) => pool.install(op),
        None => op(),
    }
}

/// `Par::Seq` for 1, else `Par::rayon(n)`.
pub fn par_of(n: usize) -> Par {
    if n <= 1 { Par::Seq } else { Par::rayon(n) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stream_tasks_follow_the_bytes_not_the_threads() {
        // A 100 x 100 f64 factor (80 kB) is one task however many threads are allowed.
        for threads in [1, 2, 16, 64] {
            assert_eq!(stream_tasks(100 * 100 * 8, threads), 1);
        }
        // 3.5 MiB: three shares of at least 1 MiB, whether 4 or 64 threads are allowed.
        assert_eq!(stream_tasks(7 << 19, 4), 3);
        assert_eq!(stream_tasks(7 << 19, 64), 3);
        // A large factor takes every thread allowed, and never more.
        assert_eq!(stream_tasks(1 << 30, 2), 2);
        assert_eq!(stream_tasks(1 << 30, 16), 16);
        assert_eq!(stream_tasks(0, 0), 1);
    }

    #[test]
    fn compute_threads_never_exceed_the_cores() {
        assert!(compute_threads() <= cores());
        assert!(compute_threads() >= 1);
    }
}
