//! A bordered system whose stiffness couples the axes:
//!
//! ```text
//! [ K   S ] [u]   [f]
//! [ S'  0 ] [P] = [t]
//! ```
//!
//! with `K` a dense, symmetric positive definite dN x dN matrix (the projected fibers of
//! `fibfluid-assembly`, whose 3x3 blocks `k d d'` couple x, y and z) and `S` one border
//! vector of length dN. The per-axis structure of [`BorderedMatrix`](crate::BorderedMatrix)
//! does not hold, so [`CoupledCholesky`] factors `K` whole (faer's dense Cholesky,
//! `(dN)^3 / 3` flops, against `d N^3 / 3` for d independent blocks, or `N^3 / 3` for a
//! shared one) and treats the border by its Schur complement `s = S' K^-1 S`:
//! `P = (S' K^-1 f - t) / s`, `u = K^-1 f - P K^-1 S`. Every solve is checked by the
//! componentwise backward error of the whole bordered system and refined in f64.

use std::time::Instant;

use faer::linalg::solvers::{Llt, SolveCore};
use faer::{Conj, Mat, MatMut, Side};

use crate::memory::check_alloc;
use crate::{
    FactorCost, FactorOptions, LinalgError, Result, Solution, check_dense_memory, cholesky_flops,
    componentwise_backward_error,
};

/// The dense Cholesky factor of a coupled stiffness `K` and the Schur complement of its
/// border (see the module docs).
pub struct CoupledCholesky {
    k: Mat<f64>,
    llt: Llt<f64>,
    border: Vec<f64>,
    kinv_s: Vec<f64>,
    schur: f64,
    opts: FactorOptions,
    cost: FactorCost,
}

impl std::fmt::Debug for CoupledCholesky {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CoupledCholesky").field("dim", &self.dim()).field("schur", &self.schur).finish()
    }
}

impl CoupledCholesky {
    /// Factors `K` (square, symmetric: only its lower triangle is read by the factorization,
    /// the whole matrix by the residual checks) with the border `S` (length of K's side).
    /// The factor is an f64 copy of K's size (checked against the memory budget before it
    /// is allocated); `K` is kept for the residuals. A non-finite entry, a pivot that is not
    /// positive or is negligible against its diagonal entry (the rigid motions the
    /// constraints leave free) and a zero border are errors.
    pub fn factor(k: Mat<f64>, border: Vec<f64>, opts: &FactorOptions) -> Result<Self> {
        let m = k.nrows();
        assert_eq!(k.ncols(), m, "K must be square");
        assert_eq!(border.len(), m, "border length");
        for j in 0..m {
            if let Some(i) = k.col(j).iter().position(|v| !v.is_finite()) {
                return Err(LinalgError::NonFinite { row: i, col: j });
            }
        }
        if let Some(i) = border.iter().position(|v| !v.is_finite()) {
            return Err(LinalgError::NonFinite { row: i, col: m });
        }
        check_dense_memory(m, 1)?;
        check_alloc::<f64>(m.saturating_mul(m), "the Cholesky factor of the coupled stiffness")?;
        let start = Instant::now();
        let llt = k.llt(Side::Lower).map_err(|e| match e {
            faer::linalg::cholesky::llt::factor::LltError::NonPositivePivot { index } => {
                LinalgError::SingularPivot { index, pivot: f64::NAN }
            }
        })?;
        let l = llt.L();
        let tolerance = m as f64 * f64::EPSILON;
        for i in 0..m {
            let pivot = l[(i, i)] * l[(i, i)];
            if !(pivot > tolerance * k[(i, i)].abs()) {
                return Err(LinalgError::SingularPivot { index: i, pivot });
            }
        }
        let (kinv_s, schur) = schur_of(&llt, &border)?;
        let cost = FactorCost {
            flops: cholesky_flops(m),
            seconds: start.elapsed().as_secs_f64(),
            bytes: 2 * m * m * 8,
        };
        Ok(Self { k, llt, border, kinv_s, schur, opts: *opts, cost })
    }

    /// Replaces the border S (refresh mode: the current shape's area vectors) keeping K's
    /// factor: one solve for `K^-1 S` and the new Schur complement. A non-finite or zero
    /// border is an error and leaves the factorization as it was.
    pub fn set_border(&mut self, border: Vec<f64>) -> Result<()> {
        let m = self.k.nrows();
        assert_eq!(border.len(), m, "border length");
        if let Some(i) = border.iter().position(|v| !v.is_finite()) {
            return Err(LinalgError::NonFinite { row: i, col: m });
        }
        let (kinv_s, schur) = schur_of(&self.llt, &border)?;
        (self.border, self.kinv_s, self.schur) = (border, kinv_s, schur);
        Ok(())
    }

    /// Size of the bordered system, dN + 1.
    pub fn dim(&self) -> usize {
        self.k.nrows() + 1
    }

    /// The stiffness K it factors.
    pub fn matrix(&self) -> &Mat<f64> {
        &self.k
    }

    /// The border S.
    pub fn border(&self) -> &[f64] {
        &self.border
    }

    /// The Schur complement `S' K^-1 S`.
    pub fn schur(&self) -> f64 {
        self.schur
    }

    /// What the factorization cost (flops of the Cholesky; bytes of K and its factor).
    pub fn cost(&self) -> FactorCost {
        self.cost
    }

    /// The options of its solves.
    pub fn options(&self) -> &FactorOptions {
        &self.opts
    }

    /// One solve of the bordered system in place (`rhs = [f; t]` becomes `[u; P]`),
    /// without refinement or checks.
    pub fn solve_unrefined(&self, rhs: &mut [f64]) {
        let m = self.k.nrows();
        assert_eq!(rhs.len(), m + 1, "rhs length");
        let (f, t) = rhs.split_at_mut(m);
        llt_solve(&self.llt, f);
        let p = (dot(&self.border, f) - t[0]) / self.schur;
        for (u, w) in f.iter_mut().zip(&self.kinv_s) {
            *u -= p * w;
        }
        t[0] = p;
    }

    /// The residual `b - A x` of the bordered system and `|A| |x|`, in `r` and `denom`.
    pub fn residual(&self, x: &[f64], b: &[f64], r: &mut [f64], denom: &mut [f64]) {
        let m = self.k.nrows();
        let (u, p) = (&x[..m], x[m]);
        r[..m].copy_from_slice(&b[..m]);
        denom[..m].fill(0.0);
        for (j, &uj) in u.iter().enumerate() {
            let col = self.k.col(j).try_as_col_major().expect("contiguous column").as_slice();
            let (dst, abs) = (&mut r[..m], &mut denom[..m]);
            for ((ri, di), kij) in dst.iter_mut().zip(abs.iter_mut()).zip(col) {
                *ri -= kij * uj;
                *di += (kij * uj).abs();
            }
        }
        for i in 0..m {
            r[i] -= self.border[i] * p;
            denom[i] += (self.border[i] * p).abs();
        }
        r[m] = b[m] - dot(&self.border, u);
        denom[m] = self.border.iter().zip(u).map(|(s, v)| (s * v).abs()).sum();
    }

    /// Solves the bordered system for `b = [f; t]`, refining until the componentwise
    /// backward error reaches the options' target, and errors when it stays above their
    /// limit or anything is not finite. The solution's last entry is the physical P.
    pub fn solve(&self, b: &[f64]) -> Result<Solution> {
        let dim = self.dim();
        assert_eq!(b.len(), dim, "rhs length");
        if let Some(i) = b.iter().position(|v| !v.is_finite()) {
            return Err(LinalgError::NonFiniteRhs { index: i });
        }
        let mut x = b.to_vec();
        self.solve_unrefined(&mut x);
        let (mut r, mut denom) = (vec![0.0; dim], vec![0.0; dim]);
        let mut steps = 0;
        let rel = loop {
            if let Some(i) = x.iter().position(|v| !v.is_finite()) {
                return Err(LinalgError::NonFiniteSolution { index: i });
            }
            self.residual(&x, b, &mut r, &mut denom);
            let rel = componentwise_backward_error(&r, &denom, b);
            if rel <= self.opts.target_for(dim) || steps >= self.opts.max_refinement_steps {
                break rel;
            }
            self.solve_unrefined(&mut r);
            x.iter_mut().zip(&r).for_each(|(xi, di)| *xi += di);
            steps += 1;
        };
        if !(rel <= self.opts.max_residual) {
            return Err(LinalgError::ResidualTooLarge { residual: rel, limit: self.opts.max_residual });
        }
        Ok(Solution { x, relative_residual: rel, refinement_steps: steps })
    }
}

/// `K^-1 S` and the Schur complement `S' K^-1 S` of a border; a zero border or a Schur
/// complement that is not positive is an error.
fn schur_of(llt: &Llt<f64>, border: &[f64]) -> Result<(Vec<f64>, f64)> {
    let mut kinv_s = border.to_vec();
    llt_solve(llt, &mut kinv_s);
    let schur = dot(border, &kinv_s);
    if !(schur > 0.0) || border.iter().all(|v| *v == 0.0) {
        return Err(LinalgError::SingularPivot { index: border.len(), pivot: schur });
    }
    Ok((kinv_s, schur))
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// `K^-1 v` in place with K's Cholesky factor.
fn llt_solve(llt: &Llt<f64>, v: &mut [f64]) {
    let m = v.len();
    llt.solve_in_place_with_conj(Conj::No, MatMut::from_column_major_slice_mut(v, m, 1));
}
