//! Shared helpers of the dense backends.

use std::time::Instant;

use crate::{BorderedMatrix, FactorCost, FactorOptions, Factorization, Precision, Result, lu_flops};

pub(crate) use crate::memory::{check_alloc, check_dense_memory};

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
    use crate::LinalgError;
    use crate::memory::{DENSE_WHAT, try_zeroed};

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
