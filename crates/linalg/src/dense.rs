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

/// Errors before allocating if `copies` dense dim x dim f64 matrices would not fit in
/// [`DENSE_MEMORY_FRACTION`] of the available memory (8 GiB when that is unknown). The dense
/// backends call it with `copies = 2` (the matrix and its factors) before forming the matrix;
/// the error says how much memory is needed and points to the `structured` backend.
pub fn check_dense_memory(dim: usize, copies: usize) -> Result<()> {
    let need = (dim as f64) * (dim as f64) * 8.0 * copies as f64;
    let limit = available_memory_bytes().map(|b| b as f64 * DENSE_MEMORY_FRACTION).unwrap_or(8.0 * GIB);
    if need > limit {
        return Err(LinalgError::TooLarge { dim, gib: need / GIB, limit_gib: limit / GIB });
    }
    Ok(())
}

const GIB: f64 = 1024.0 * 1024.0 * 1024.0;

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
