//! Thread control for every backend.
//!
//! By default faer and rayon use every core. [`set_threads`] pins faer's global
//! parallelism (and, once, rayon's global pool) to `n` threads; OpenBLAS reads
//! `OPENBLAS_NUM_THREADS` when it loads, so set that variable in the environment of a
//! process that compares backends (`fibfluid --threads 1` does all of this).

/// Sets faer's parallelism to `n` threads (1 = sequential) and, if it has not been built
/// yet, rayon's global pool. Returns false when rayon's pool already existed.
pub fn set_threads(n: usize) -> bool {
    let n = n.max(1);
    faer::set_global_parallelism(if n == 1 { faer::Par::Seq } else { faer::Par::rayon(n) });
    rayon::ThreadPoolBuilder::new().num_threads(n).build_global().is_ok()
}

/// The number of threads faer currently uses.
pub fn threads() -> usize {
    match faer::get_global_parallelism() {
        faer::Par::Seq => 1,
        faer::Par::Rayon(n) => n.get(),
    }
}
