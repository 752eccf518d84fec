//! Shared helpers of the dense backends.

use std::time::Instant;

use crate::{
    BorderedMatrix, FactorCost, FactorOptions, Factorization, LinalgError, Precision, Result, lu_flops,
};

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
        available_memory_bytes().map(|b| (b as f64 * DENSE_MEMORY_FRACTION) as u64).unwrap_or(8 * 1024 * 1024 * 1024)
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

pub(crate) fn dense_lu_cost(dim: usize, seconds: f64, word_bytes: usize) -> FactorCost {
    FactorCost { flops: lu_flops(dim), seconds, bytes: dim * dim * word_bytes }
}

/// A dense LU kernel: factors the dense form of a bordered matrix in one precision (and
/// checks its pivots) and solves with the factors. [`DenseFactorization`] adds what every
/// dense backend shares: the memory and finiteness checks, the timing, and refactoring
/// when the border changes.
pub(crate) trait DenseKernel: Sized + Send + Sync + 'static {
    /// Backend name.
    const NAME: &'static str;
    /// Factors `a` (checked finite, known to fit in memory) in `precision`.
    fn factor(a: &BorderedMatrix, precision: Precision) -> Result<Self>;
    /// One solve in place, in the kernel's precision.
    fn solve(&self, rhs: &mut [f64]);
}

/// A factorization made by a dense kernel.
pub(crate) struct DenseFactorization<K> {
    matrix: BorderedMatrix,
    opts: FactorOptions,
    kernel: K,
    cost: FactorCost,
}

impl<K: DenseKernel> DenseFactorization<K> {
    /// Factors `a` with kernel `K`.
    pub(crate) fn boxed(a: &BorderedMatrix, opts: &FactorOptions) -> Result<Box<dyn Factorization>> {
        let (kernel, cost) = Self::factor(a, opts.precision)?;
        // The factorization keeps a copy of the structured matrix (its blocks).
        let blocks = if a.is_shared() { 1 } else { a.axes() };
        let n = a.n_vertices();
        check_alloc::<f64>(n.saturating_mul(n).saturating_mul(blocks), "a copy of the stiffness blocks")?;
        Ok(Box::new(Self { matrix: a.clone(), opts: *opts, kernel, cost }))
    }

    fn factor(a: &BorderedMatrix, precision: Precision) -> Result<(K, FactorCost)> {
        let dim = a.dim();
        // Before anything touches the matrix: a system too large to hold densely fails at once.
        check_dense_memory(dim, 2)?;
        a.check_finite()?;
        let start = Instant::now();
        let kernel = K::factor(a, precision)?;
        let word = if precision == Precision::F64 { 8 } else { 4 };
        Ok((kernel, dense_lu_cost(dim, start.elapsed().as_secs_f64(), word)))
    }
}

impl<K: DenseKernel> Factorization for DenseFactorization<K> {
    fn backend(&self) -> &'static str {
        K::NAME
    }

    fn matrix(&self) -> &BorderedMatrix {
        &self.matrix
    }

    fn options(&self) -> &FactorOptions {
        &self.opts
    }

    fn cost(&self) -> FactorCost {
        self.cost
    }

    fn solve_unrefined(&self, rhs: &mut [f64]) {
        self.kernel.solve(rhs);
    }

    fn border_update_refactors(&self) -> bool {
        true
    }

    /// A dense factorization cannot reuse anything when the border changes: refactor.
    fn set_border(&mut self, border: &[Vec<f64>]) -> Result<FactorCost> {
        self.matrix.set_border(border);
        let (kernel, cost) = Self::factor(&self.matrix, self.opts.precision)?;
        self.kernel = kernel;
        self.cost = cost;
        Ok(cost)
    }
}

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
