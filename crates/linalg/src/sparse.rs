//! Sparse Cholesky `K = L L^T` of a symmetric positive definite matrix given by its lower
//! triangle in compressed columns (faer's supernodal or simplicial factorization, chosen by
//! faer from the symbolic structure).
//!
//! The work is split in two, so that a sequence of matrices on one sparsity pattern (the
//! tangent stiffness of a Newton iteration) pays the analysis once:
//!
//! - [`SparseSymbolic`]: the fill-reducing ordering (given, or faer's AMD), the elimination
//!   tree and the structure of `L`; it also keeps the pattern it was computed from. Shared
//!   between factors through an [`Arc`].
//! - [`SparseCholesky`]: the numeric values of `L` for one matrix on that pattern.
//!   [`SparseCholesky::refactor`] overwrites them for new values on the same pattern,
//!   reusing the buffer; a matrix on another pattern is refused
//!   ([`LinalgError::SparsePatternMismatch`]).

use std::sync::Arc;

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{LltError, LltRegularization};
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{
    LltRef, SymbolicCholesky, SymmetricOrdering, factorize_symbolic_cholesky,
};
use faer::sparse::{FaerError, SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Side};

use crate::{LinalgError, Result};

/// The fill-reducing ordering of a sparse Cholesky factorization.
#[derive(Clone, Copy, Debug)]
pub enum SparseOrdering<'a> {
    /// faer's approximate minimum degree ordering.
    Amd,
    /// A given permutation: `fwd[k]` is the column eliminated `k`-th and `inv` its inverse.
    Custom {
        /// `fwd[k]`: the column eliminated `k`-th.
        fwd: &'a [usize],
        /// The inverse permutation (`inv[fwd[k]] = k`).
        inv: &'a [usize],
    },
}

fn faer_error(e: FaerError, what: &'static str) -> LinalgError {
    match e {
        FaerError::IndexOverflow => LinalgError::SparseIndexOverflow { what },
        _ => LinalgError::SparseOutOfMemory { what },
    }
}

/// The symbolic analysis of a sparse Cholesky factorization for one lower-triangle
/// pattern and ordering (see the module docs).
#[derive(Debug)]
pub struct SparseSymbolic {
    symbolic: SymbolicCholesky<usize>,
    nrows: usize,
    col_ptr: Vec<usize>,
    col_nnz: Option<Vec<usize>>,
    row_idx: Vec<usize>,
}

impl SparseSymbolic {
    /// Analyses the pattern `k_lower` (the lower triangle, diagonal included, of a square
    /// symmetric matrix) with `ordering`. faer's failures are
    /// [`LinalgError::SparseOutOfMemory`] and [`LinalgError::SparseIndexOverflow`].
    ///
    /// # Panics
    /// If the matrix is not square or a custom ordering is not a permutation of its
    /// columns (programming errors).
    #[track_caller]
    pub fn new(k_lower: SymbolicSparseColMatRef<'_, usize>, ordering: SparseOrdering<'_>) -> Result<Self> {
        assert_eq!(k_lower.nrows(), k_lower.ncols(), "a square matrix");
        let ordering = match ordering {
            SparseOrdering::Amd => SymmetricOrdering::Amd,
            SparseOrdering::Custom { fwd, inv } => {
                SymmetricOrdering::Custom(PermRef::new_checked(fwd, inv, k_lower.ncols()))
            }
        };
        let symbolic = factorize_symbolic_cholesky(k_lower, Side::Lower, ordering, Default::default())
            .map_err(|e| faer_error(e, "the symbolic analysis"))?;
        Ok(Self {
            symbolic,
            nrows: k_lower.nrows(),
            col_ptr: k_lower.col_ptr().to_vec(),
            col_nnz: k_lower.col_nnz().map(<[usize]>::to_vec),
            row_idx: k_lower.row_idx().to_vec(),
        })
    }

    /// Number of rows (and columns) of the matrix.
    pub fn dim(&self) -> usize {
        self.nrows
    }

    /// Stored values of a factor on this analysis (its nonzeros, dense supernode blocks
    /// included).
    pub fn factor_len(&self) -> usize {
        self.symbolic.len_val()
    }

    /// Whether `k_lower` has exactly the analysed pattern: the same size, column pointers,
    /// column counts and row indices; otherwise [`LinalgError::SparsePatternMismatch`]
    /// naming the first difference.
    pub fn check_pattern(&self, k_lower: SymbolicSparseColMatRef<'_, usize>) -> Result<()> {
        let what = if k_lower.nrows() != self.nrows || k_lower.ncols() != self.nrows {
            Some("size")
        } else if k_lower.col_ptr() != self.col_ptr.as_slice() {
            Some("column pointers")
        } else if k_lower.col_nnz() != self.col_nnz.as_deref() {
            Some("column counts")
        } else if k_lower.row_idx() != self.row_idx.as_slice() {
            Some("row indices")
        } else {
            None
        };
        match what {
            Some(what) => Err(LinalgError::SparsePatternMismatch { what }),
            None => Ok(()),
        }
    }
}

/// The numeric sparse Cholesky factor of one matrix on a [`SparseSymbolic`] analysis.
#[derive(Debug)]
pub struct SparseCholesky {
    symbolic: Arc<SparseSymbolic>,
    values: Vec<f64>,
}

impl SparseCholesky {
    /// Analyses and factors `k_lower` in one call ([`SparseSymbolic::new`] then
    /// [`factor`](Self::factor)).
    pub fn new(k_lower: SparseColMatRef<'_, usize, f64>, ordering: SparseOrdering<'_>) -> Result<Self> {
        let symbolic = Arc::new(SparseSymbolic::new(k_lower.symbolic(), ordering)?);
        Self::factor(&symbolic, k_lower)
    }

    /// Factors `k_lower` (the lower triangle, diagonal included, of an SPD matrix on the
    /// pattern of `symbolic`). A matrix that is not numerically positive definite is
    /// [`LinalgError::SparseNotPositiveDefinite`]; another pattern
    /// [`LinalgError::SparsePatternMismatch`]; a refused allocation
    /// [`LinalgError::SparseOutOfMemory`].
    pub fn factor(symbolic: &Arc<SparseSymbolic>, k_lower: SparseColMatRef<'_, usize, f64>) -> Result<Self> {
        let len = symbolic.factor_len();
        let mut values = Vec::new();
        values
            .try_reserve_exact(len)
            .map_err(|_| LinalgError::SparseOutOfMemory { what: "the factor's values" })?;
        values.resize(len, 0.0);
        let mut out = Self { symbolic: Arc::clone(symbolic), values };
        out.refactor(k_lower)?;
        Ok(out)
    }

    /// Factors new values on the same pattern, reusing the analysis and the values buffer.
    /// Errors as [`factor`](Self::factor); after an error the factor must not be used for
    /// solves until a refactorization succeeds.
    pub fn refactor(&mut self, k_lower: SparseColMatRef<'_, usize, f64>) -> Result<()> {
        self.symbolic.check_pattern(k_lower.symbolic())?;
        let sym = &self.symbolic.symbolic;
        let par = crate::parallel::compute_par();
        let mut mem =
            MemBuffer::try_new(sym.factorize_numeric_llt_scratch::<f64>(par, Default::default()))
                .map_err(|_| LinalgError::SparseOutOfMemory { what: "the factorization's workspace" })?;
        sym.factorize_numeric_llt(
            &mut self.values,
            k_lower,
            Side::Lower,
            LltRegularization::default(),
            par,
            MemStack::new(&mut mem),
            Default::default(),
        )
        .map(|_| ())
        .map_err(|LltError::NonPositivePivot { index }| LinalgError::SparseNotPositiveDefinite {
            step: index,
        })
    }

    /// The shared symbolic analysis.
    pub fn symbolic(&self) -> &Arc<SparseSymbolic> {
        &self.symbolic
    }

    /// Stored values of the factor (its nonzeros, dense supernode blocks included).
    pub fn nonzeros(&self) -> usize {
        self.values.len()
    }

    /// Solves `K X = B` in place for every column of `rhs`.
    ///
    /// # Panics
    /// If `rhs` does not have [`SparseSymbolic::dim`] rows, or its workspace cannot be
    /// allocated.
    #[track_caller]
    pub fn solve_in_place(&self, rhs: MatMut<'_, f64>) {
        assert_eq!(rhs.nrows(), self.symbolic.nrows, "one row per unknown");
        let sym = &self.symbolic.symbolic;
        // A few right-hand sides read the factor once: split by its bytes; many are
        // matrix products.
        let par = if rhs.ncols() <= crate::triangular::MAX_STREAM_RHS {
            crate::parallel::stream_par(self.values.len() * 8)
        } else {
            crate::parallel::compute_par()
        };
        let mut mem = MemBuffer::new(sym.solve_in_place_scratch::<f64>(rhs.ncols(), par));
        crate::parallel::on_cores(|| {
            LltRef::new(sym, &self.values).solve_in_place_with_conj(
                Conj::No,
                rhs,
                par,
                MemStack::new(&mut mem),
            )
        });
    }
}
