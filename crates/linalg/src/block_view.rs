//! How one stiffness block of a [`BorderedMatrix`](crate::BorderedMatrix) is stored: the
//! view the matrix hands to the residual kernels and the structured factorization (its own
//! module, so that neither `matrix` nor `residual` imports the other in a circle).

use faer::Mat;

/// How one stiffness block is stored.
#[derive(Clone, Copy)]
pub(crate) enum BlockView<'a> {
    /// The whole symmetric block.
    Full(&'a Mat<f64>),
    /// `K`'s strict upper triangle in `upper` (its lower triangle holds a factor) and
    /// `K`'s diagonal.
    Upper { upper: &'a Mat<f64>, diagonal: &'a [f64] },
}

impl BlockView<'_> {
    /// `K_ij`.
    pub(crate) fn entry(&self, i: usize, j: usize) -> f64 {
        match *self {
            BlockView::Full(k) => k[(i, j)],
            BlockView::Upper { upper, diagonal } => match i.cmp(&j) {
                std::cmp::Ordering::Equal => diagonal[i],
                std::cmp::Ordering::Less => upper[(i, j)],
                std::cmp::Ordering::Greater => upper[(j, i)],
            },
        }
    }

    /// Column `j` of `K` (equal to row `j`) into `out`.
    pub(crate) fn column_into(&self, j: usize, out: &mut [f64]) {
        match *self {
            BlockView::Full(k) => out.copy_from_slice(k.col_as_slice(j)),
            BlockView::Upper { upper, diagonal } => {
                out[..j].copy_from_slice(&upper.col_as_slice(j)[..j]);
                out[j] = diagonal[j];
                for (i, o) in out.iter_mut().enumerate().skip(j + 1) {
                    *o = upper[(j, i)];
                }
            }
        }
    }
}
