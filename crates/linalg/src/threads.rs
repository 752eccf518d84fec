//! Thread control for every backend.
//!
//! By default faer and rayon use every core. [`set_threads`] pins faer's global
//! parallelism, OpenBLAS's thread count (feature `openblas`) and, once, rayon's global pool
//! to `n` threads (`fibfluid --threads 1` calls it). OpenBLAS threads keep spinning for a
//! while after a call; compare backends in separate processes for clean timings.

/// Sets faer's parallelism to `n` threads (1 = sequential), OpenBLAS's thread count when
/// that backend is built, and, if it has not been built yet, rayon's global pool. Returns
/// false when rayon's pool already existed.
pub fn set_threads(n: usize) -> bool {
    let n = n.max(1);
    #[cfg(feature = "openblas")]
    crate::openblas_lu::set_openblas_threads(n);
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
