//! Thread control for every backend.
//!
//! By default faer and rayon use every core. [`try_set_threads`] pins faer's global
//! parallelism, OpenBLAS's thread count (feature `openblas`) and, once, rayon's global pool
//! to `n` threads (`fibfluid --threads N` calls it). A count of 0 is an error; a count above
//! [`thread_cap`] (four per core, at most [`MAX_THREADS`]) is lowered to the cap, and the
//! returned [`ThreadSetting`] says so. OpenBLAS threads keep spinning for a while after a
//! call; compare backends in separate processes for clean timings.

use crate::{LinalgError, Result};

/// Threads allowed per available core before a request is clamped.
pub const MAX_THREADS_PER_CORE: usize = 4;

/// Upper bound of [`thread_cap`] on any machine.
pub const MAX_THREADS: usize = 1024;

/// The largest thread count [`try_set_threads`] uses: [`MAX_THREADS_PER_CORE`] times the
/// available cores, at most [`MAX_THREADS`]. More threads than that only add overhead (and a
/// request of 100,000 would spend minutes creating threads, or fail to).
pub fn thread_cap() -> usize {
    let cores = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    cores.saturating_mul(MAX_THREADS_PER_CORE).clamp(1, MAX_THREADS)
}

/// What [`try_set_threads`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ThreadSetting {
    /// The count asked for.
    pub requested: usize,
    /// The count in use (lower than `requested` when clamped to [`thread_cap`]).
    pub used: usize,
    /// Whether rayon's global pool was built with `used` threads (false: it already existed
    /// and keeps its size).
    pub pool_built: bool,
}

impl ThreadSetting {
    /// A one-line note when the request was clamped, for the user.
    pub fn note(&self) -> Option<String> {
        (self.used < self.requested).then(|| {
            format!(
                "--threads {} lowered to {} ({} per available core, at most {})",
                self.requested, self.used, MAX_THREADS_PER_CORE, MAX_THREADS
            )
        })
    }
}

/// Sets faer's parallelism to `n` threads (1 = sequential), OpenBLAS's thread count when
/// that backend is built, and, if it has not been built yet, rayon's global pool.
///
/// Errors: [`LinalgError::ZeroThreads`] for 0, [`LinalgError::ThreadPool`] when the pool's
/// threads cannot be started (nothing is changed then). Counts above [`thread_cap`] are
/// clamped (see [`ThreadSetting::note`]).
pub fn try_set_threads(n: usize) -> Result<ThreadSetting> {
    if n == 0 {
        return Err(LinalgError::ZeroThreads);
    }
    let used = n.min(thread_cap());
    let pool_built = match rayon::ThreadPoolBuilder::new().num_threads(used).build_global() {
        Ok(()) => true,
        // No source: the global pool already exists (it keeps its size). With a source: the
        // operating system refused a thread.
        Err(e) => match std::error::Error::source(&e) {
            None => false,
            Some(source) => {
                return Err(LinalgError::ThreadPool { threads: used, message: source.to_string() });
            }
        },
    };
    #[cfg(feature = "openblas")]
    crate::openblas_lu::set_openblas_threads(used);
    faer::set_global_parallelism(if used == 1 { faer::Par::Seq } else { faer::Par::rayon(used) });
    Ok(ThreadSetting { requested: n, used, pool_built })
}

/// [`try_set_threads`] for callers that need no report: 0 counts as 1, and a pool that
/// cannot be started leaves the defaults. Returns whether rayon's pool was built.
pub fn set_threads(n: usize) -> bool {
    try_set_threads(n.max(1)).map(|s| s.pool_built).unwrap_or(false)
}

/// The number of threads faer currently uses.
pub fn threads() -> usize {
    match faer::get_global_parallelism() {
        faer::Par::Seq => 1,
        faer::Par::Rayon(n) => n.get(),
    }
}

/// Environment variable read by [`pin_threads`].
pub const THREADS_ENV: &str = "FIBFLUID_THREADS";

/// Pins the thread count of a bench process through
/// [`set_threads`] (faer, rayon's global pool and,
/// when built, OpenBLAS at run time): the value of `FIBFLUID_THREADS` if it is set to a
/// positive integer, else every core the process may use. Returns the count. Call it
/// before anything builds rayon's global pool.
pub fn pin_threads() -> usize {
    let n = std::env::var(THREADS_ENV)
        .ok()
        .and_then(|v| v.trim().parse::<usize>().ok())
        .filter(|&n| n > 0)
        .unwrap_or_else(|| std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1));
    set_threads(n);
    n
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
