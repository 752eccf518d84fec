//! The kept sparse Cholesky factor of K (faer's supernodal/simplicial LL^T, chosen by faer
//! from the symbolic structure) with a given fill-reducing ordering or faer's AMD.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::perm::PermRef;
use faer::sparse::SparseColMatRef;
use faer::sparse::linalg::cholesky::{
    LltRef, SymbolicCholesky, SymmetricOrdering, factorize_symbolic_cholesky,
};
use faer::{Conj, MatMut, Side, get_global_parallelism};

use crate::error::{FemError, Result};

/// `K = L L^T` of a symmetric positive definite matrix given by its lower triangle.
pub(crate) struct SparseCholesky {
    symbolic: SymbolicCholesky<usize>,
    values: Vec<f64>,
}

fn generic(e: impl std::fmt::Display) -> FemError {
    FemError::Factorization { reason: e.to_string() }
}

impl SparseCholesky {
    /// Factors `k_lower` (the lower triangle, diagonal included, of an SPD matrix).
    /// `permutation`: `(fwd, inv)` with `fwd[k]` the column eliminated `k`-th, or `None` for
    /// faer's AMD.
    pub(crate) fn new(
        k_lower: SparseColMatRef<'_, usize, f64>,
        permutation: Option<(&[usize], &[usize])>,
    ) -> Result<Self> {
        let ordering = match permutation {
            Some((fwd, inv)) => SymmetricOrdering::Custom(PermRef::new_checked(fwd, inv, fwd.len())),
            None => SymmetricOrdering::Amd,
        };
        let symbolic =
            factorize_symbolic_cholesky(k_lower.symbolic(), Side::Lower, ordering, Default::default())
                .map_err(generic)?;
        let mut values = Vec::new();
        values.try_reserve_exact(symbolic.len_val()).map_err(generic)?;
        values.resize(symbolic.len_val(), 0.0);
        let par = get_global_parallelism();
        let mut mem =
            MemBuffer::try_new(symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default()))
                .map_err(generic)?;
        let result = symbolic.factorize_numeric_llt(
            &mut values,
            k_lower,
            Side::Lower,
            LltRegularization::default(),
            par,
            MemStack::new(&mut mem),
            Default::default(),
        );
        if result.is_err() {
            // The only error of the numeric factorization is a non-positive pivot.
            return Err(FemError::NotPositiveDefinite);
        }
        Ok(Self { symbolic, values })
    }

    /// Stored values of the factor (its nonzeros, dense supernode blocks included).
    pub(crate) fn nonzeros(&self) -> usize {
        self.values.len()
    }

    /// Solves `K X = B` in place for every column of `rhs`.
    pub(crate) fn solve_in_place(&self, rhs: MatMut<'_, f64>) {
        let par = get_global_parallelism();
        let mut mem = MemBuffer::new(self.symbolic.solve_in_place_scratch::<f64>(rhs.ncols(), par));
        LltRef::new(&self.symbolic, &self.values).solve_in_place_with_conj(
            Conj::No,
            rhs,
            par,
            MemStack::new(&mut mem),
        );
    }
}
