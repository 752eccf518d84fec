//! The memory policy and fallible allocation: what a run may use, and allocations that
//! fail with an error instead of aborting.

use crate::{LinalgError, Result};

/// Fraction of the available memory a dense backend may use.
pub const DENSE_MEMORY_FRACTION: f64 = 0.5;

/// Bytes of memory currently available (Linux `MemAvailable`), if known.
pub fn available_memory_bytes() -> Option<u64> {
    meminfo_bytes("MemAvailable:")
}

/// Bytes of memory the machine has (Linux `MemTotal`), if known.
pub fn total_memory_bytes() -> Option<u64> {
    meminfo_bytes("MemTotal:")
}

fn meminfo_bytes(field: &str) -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with(field))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// The one memory policy of fibfluid: work is refused, before anything large is
/// allocated, when its estimated peak exceeds this many bytes. `limit` when given (a
/// `--max-memory` flag), else [`DENSE_MEMORY_FRACTION`] of the memory available now (8 GiB
/// when that is unknown). Plans, dense backends, the interactive precompute and the
/// ChainMail lattice all check against it.
pub fn memory_budget(limit: Option<u64>) -> u64 {
    limit.unwrap_or_else(|| {
        available_memory_bytes()
            .map(|b| (b as f64 * DENSE_MEMORY_FRACTION) as u64)
            .unwrap_or(8 * 1024 * 1024 * 1024)
    })
}

/// Errors before allocating if `copies` dense dim x dim f64 matrices would not fit in
/// [`DENSE_MEMORY_FRACTION`] of the available memory (8 GiB when that is unknown). The dense
/// backends call it with `copies = 2` (the matrix and its factors) before forming the matrix;
/// the error says how much memory is needed and points to the `structured` backend.
pub fn check_dense_memory(dim: usize, copies: usize) -> Result<()> {
    let need = (dim as f64) * (dim as f64) * 8.0 * copies as f64;
    let limit = memory_budget(None) as f64;
    if need > limit {
        return Err(LinalgError::TooLarge { dim, gib: need / GIB, limit_gib: limit / GIB });
    }
    Ok(())
}

const GIB: f64 = 1024.0 * 1024.0 * 1024.0;

/// Errors with [`LinalgError::OutOfMemory`] unless `len` values of `T` can be allocated now.
///
/// The reservation is made with `Vec::try_reserve_exact` and released at once: the caller
/// then makes the real allocation (zeroed pages from the system, not touched one by one).
/// An address-space limit (`ulimit -v`), a failing `mmap` or a size that overflows are caught
/// here as an error instead of an abort. (With memory overcommit, a system that runs out of
/// memory later, when pages are touched, can still kill the process: the size checks of the
/// callers, e.g. [`check_dense_memory`], are the guard against that.)
pub(crate) fn check_alloc<T>(len: usize, what: &'static str) -> Result<()> {
    let bytes = len.saturating_mul(std::mem::size_of::<T>());
    let oom = LinalgError::OutOfMemory { bytes, what };
    if bytes == usize::MAX || bytes > isize::MAX as usize {
        return Err(oom);
    }
    let mut probe: Vec<T> = Vec::new();
    probe.try_reserve_exact(len).map_err(|_| oom)
}

/// A zeroed `Vec<f64>` of `len` values, or [`LinalgError::OutOfMemory`] (see [`check_alloc`]).
pub(crate) fn try_zeroed(len: usize, what: &'static str) -> Result<Vec<f64>> {
    check_alloc::<f64>(len, what)?;
    Ok(vec![0.0; len])
}

/// Collects `len` values into a vector reserved fallibly (no reallocation while filling).
pub(crate) fn try_collect<T>(
    len: usize,
    values: impl Iterator<Item = T>,
    what: &'static str,
) -> Result<Vec<T>> {
    let bytes = len.saturating_mul(std::mem::size_of::<T>());
    let mut v = Vec::new();
    v.try_reserve_exact(len).map_err(|_| LinalgError::OutOfMemory { bytes, what })?;
    v.extend(values.take(len));
    Ok(v)
}

/// What the dense buffers are called in [`LinalgError::OutOfMemory`].
pub(crate) const DENSE_WHAT: &str = "the dense matrix";
/// The single-precision copy of the dense matrix (mixed precision).
pub(crate) const SINGLE_WHAT: &str = "the single-precision dense matrix";

#[cfg(test)]
mod tests {
    use super::*;

    /// Allocations no machine can make (2^60 f64 = 8 EiB, a size that overflows usize)
    /// come back as `OutOfMemory` naming the bytes, not as an abort.
    #[test]
    fn impossible_allocations_are_errors() {
        let n = 1usize << 60;
        assert_eq!(
            check_alloc::<f64>(n, DENSE_WHAT),
            Err(LinalgError::OutOfMemory { bytes: n * 8, what: DENSE_WHAT })
        );
        assert_eq!(
            try_zeroed(usize::MAX / 2, DENSE_WHAT),
            Err(LinalgError::OutOfMemory { bytes: usize::MAX, what: DENSE_WHAT })
        );
        let e = try_collect(n, std::iter::repeat(0f32), SINGLE_WHAT).unwrap_err();
        assert_eq!(e, LinalgError::OutOfMemory { bytes: n * 4, what: SINGLE_WHAT });
        assert!(
            e.to_string().starts_with(&format!("cannot allocate {} bytes (4294967296.00 GiB)", n * 4)),
            "{e}"
        );
        // A possible one works.
        assert_eq!(try_zeroed(10, DENSE_WHAT).unwrap(), vec![0.0; 10]);
        assert_eq!(try_collect(3, [1, 2, 3, 4].into_iter(), "x").unwrap(), vec![1, 2, 3]);
    }
}
