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
