//! The smoother of a multigrid level: a Chebyshev iteration over the level's 3x3
//! node-block Jacobi (symmetric, so the V-cycle stays a valid preconditioner for
//! conjugate gradients, and parallel: one matrix product per degree), tuned by an estimate
//! of the largest eigenvalue of `D^-1 A` from a few Lanczos steps.

use rayon::prelude::*;

use super::block::{Block, BlockCsr, block_apply, block_inverse, dot};

/// Lanczos (conjugate-gradient) steps of the eigenvalue estimate.
const LANCZOS_STEPS: usize = 12;
/// The estimate is a lower bound of the largest eigenvalue: the smoothed interval reaches
/// this much above it.
const UPPER_SAFETY: f64 = 1.2;

/// A Chebyshev smoother over block Jacobi (see the module docs).
#[derive(Debug, Clone)]
pub(crate) struct Chebyshev {
    inverse_diagonal: Vec<Block>,
    /// The smoothed interval `[lower, upper]` of the spectrum of `D^-1 A`.
    lower: f64,
    upper: f64,
    degree: usize,
}

impl Chebyshev {
    /// The smoother of `a` with `degree` matrix products per application, damping the
    /// spectrum of `D^-1 A` from `upper / range` to `upper`.
    pub(crate) fn new(a: &BlockCsr, dead: &[bool], degree: usize, range: f64) -> Self {
        let inverse_diagonal: Vec<Block> = (0..a.nodes()).map(|i| block_inverse(&a.diagonal(i))).collect();
        let largest = largest_eigenvalue(a, &inverse_diagonal, dead);
        let upper = UPPER_SAFETY * largest;
        Self { inverse_diagonal, lower: upper / range, upper, degree: degree.max(1) }
    }

    /// `z = D^-1 r`.
    fn jacobi(&self, r: &[f64], z: &mut [f64]) {
        z.par_chunks_mut(3)
            .zip(r.par_chunks(3))
            .zip(self.inverse_diagonal.par_iter())
            .with_min_len(512)
            .for_each(|((zi, ri), d)| zi.copy_from_slice(&block_apply(d, ri)));
    }

    /// Smooths `x` towards `A x = b` (`x` may start at zero: `zero_start` saves a product).
    pub(crate) fn smooth(&self, a: &BlockCsr, b: &[f64], x: &mut [f64], zero_start: bool) {
        let n = x.len();
        let theta = 0.5 * (self.upper + self.lower);
        let delta = 0.5 * (self.upper - self.lower);
        let sigma = theta / delta;
        let mut rho_old = 1.0 / sigma;
        let mut r = vec![0.0; n];
        let mut z = vec![0.0; n];
        if zero_start {
            r.copy_from_slice(b);
        } else {
            a.residual(b, x, &mut r);
        }
        self.jacobi(&r, &mut z);
        let mut d: Vec<f64> = z.iter().map(|v| v / theta).collect();
        for k in 0..self.degree {
            x.par_iter_mut().zip(d.par_iter()).for_each(|(xi, di)| *xi += di);
            if k + 1 == self.degree {
                break;
            }
            a.residual(b, x, &mut r);
            self.jacobi(&r, &mut z);
            let rho = 1.0 / (2.0 * sigma - rho_old);
            let (c1, c2) = (rho * rho_old, 2.0 * rho / delta);
            d.par_iter_mut().zip(z.par_iter()).for_each(|(di, zi)| *di = c1 * *di + c2 * zi);
            rho_old = rho;
        }
    }
}

/// The largest eigenvalue of `D^-1 A` estimated from [`LANCZOS_STEPS`] steps of block
/// Jacobi–preconditioned conjugate gradients (the Lanczos tridiagonal of their
/// coefficients), from a fixed pseudo-random start on the live dofs.
fn largest_eigenvalue(a: &BlockCsr, inverse_diagonal: &[Block], dead: &[bool]) -> f64 {
    let n = 3 * a.nodes();
    // A fixed pseudo-random right-hand side (a linear congruential sequence).
    let mut seed = 0x9e37_79b9_7f4a_7c15_u64;
    let mut r: Vec<f64> = (0..n)
        .map(|i| {
            seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            if dead[i] { 0.0 } else { (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5 }
        })
        .collect();
    let jacobi = |r: &[f64], z: &mut [f64]| {
        for (i, d) in inverse_diagonal.iter().enumerate() {
            z[3 * i..3 * i + 3].copy_from_slice(&block_apply(d, &r[3 * i..3 * i + 3]));
        }
    };
    let mut z = vec![0.0; n];
    jacobi(&r, &mut z);
    let mut p = z.clone();
    let mut q = vec![0.0; n];
    let mut rz = dot(&r, &z);
    let (mut alphas, mut betas) = (Vec::new(), Vec::new());
    for _ in 0..LANCZOS_STEPS.min(n) {
        if !(rz > 0.0) {
            break;
        }
        a.mul(&p, &mut q);
        let pq = dot(&p, &q);
        if !(pq > 0.0) {
            break;
        }
        let alpha = rz / pq;
        r.iter_mut().zip(&q).for_each(|(ri, qi)| *ri -= alpha * qi);
        jacobi(&r, &mut z);
        let rz_new = dot(&r, &z);
        let beta = rz_new / rz;
        alphas.push(alpha);
        betas.push(beta);
        p.iter_mut().zip(&z).for_each(|(pi, zi)| *pi = zi + beta * *pi);
        rz = rz_new;
    }
    tridiagonal_largest(&alphas, &betas)
}

/// The largest eigenvalue of the Lanczos tridiagonal built from conjugate-gradient
/// coefficients (Saad, Iterative Methods, 6.7.3), by power iteration on it.
fn tridiagonal_largest(alphas: &[f64], betas: &[f64]) -> f64 {
    let m = alphas.len();
    if m == 0 {
        return 1.0;
    }
    let diagonal: Vec<f64> =
        (0..m).map(|j| 1.0 / alphas[j] + if j > 0 { betas[j - 1] / alphas[j - 1] } else { 0.0 }).collect();
    let off: Vec<f64> = (0..m.saturating_sub(1)).map(|j| betas[j].sqrt() / alphas[j]).collect();
    // Power iteration on the small tridiagonal (symmetric positive definite).
    let mut v = vec![1.0; m];
    let mut lambda = 0.0;
    for _ in 0..200 {
        let w: Vec<f64> = (0..m)
            .map(|j| {
                diagonal[j] * v[j]
                    + if j > 0 { off[j - 1] * v[j - 1] } else { 0.0 }
                    + if j + 1 < m { off[j] * v[j + 1] } else { 0.0 }
            })
            .collect();
        let norm = w.iter().map(|x| x * x).sum::<f64>().sqrt();
        if !(norm > 0.0) {
            break;
        }
        lambda = norm / v.iter().map(|x| x * x).sum::<f64>().sqrt();
        v = w.iter().map(|x| x / norm).collect();
    }
    lambda
}
