//! 3 x 3 tensor helpers the laws and the cell share.

/// A 3 x 3 matrix, `m[i][j]`.
pub type M3 = [[f64; 3]; 3];

/// A fourth-order tensor `A[iJ][kL]` flattened to 9 x 9 (`3 i + J`).
pub type Tangent9 = [[f64; 9]; 9];

/// `det m`.
pub fn det(m: &M3) -> f64 {
    m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
}

/// The cofactor matrix `cof m = det(m) m^-T`.
pub fn cofactor(m: &M3) -> M3 {
    let c = |i: usize, j: usize| {
        let (i1, i2) = ((i + 1) % 3, (i + 2) % 3);
        let (j1, j2) = ((j + 1) % 3, (j + 2) % 3);
        m[i1][j1] * m[i2][j2] - m[i1][j2] * m[i2][j1]
    };
    std::array::from_fn(|i| std::array::from_fn(|j| c(i, j)))
}

/// The symmetric 3 x 3 matrix's eigenvalues, ascending (closed form, trigonometric).
pub(crate) fn symmetric_eigenvalues(m: &M3) -> [f64; 3] {
    let p1 = m[0][1] * m[0][1] + m[0][2] * m[0][2] + m[1][2] * m[1][2];
    let q = (m[0][0] + m[1][1] + m[2][2]) / 3.0;
    let p2 = (m[0][0] - q).powi(2) + (m[1][1] - q).powi(2) + (m[2][2] - q).powi(2) + 2.0 * p1;
    let p = (p2 / 6.0).sqrt();
    if p <= 1e-300 {
        return [q; 3];
    }
    let b: M3 =
        std::array::from_fn(|i| std::array::from_fn(|j| (m[i][j] - if i == j { q } else { 0.0 }) / p));
    let r = (det(&b) / 2.0).clamp(-1.0, 1.0);
    let phi = r.acos() / 3.0;
    let hi = q + 2.0 * p * phi.cos();
    let lo = q + 2.0 * p * (phi + 2.0 * std::f64::consts::PI / 3.0).cos();
    [lo, 3.0 * q - hi - lo, hi]
}

/// The von Mises equivalent of the Cauchy stress `sigma = P F^T / J` of a first
/// Piola–Kirchhoff stress `p` at `f` with `j = det f`.
pub(crate) fn cauchy_von_mises(p: &M3, f: &M3, j: f64) -> f64 {
    let sigma: M3 =
        std::array::from_fn(|i| std::array::from_fn(|k| (0..3).map(|l| p[i][l] * f[k][l]).sum::<f64>() / j));
    let mean = (sigma[0][0] + sigma[1][1] + sigma[2][2]) / 3.0;
    let mut s2 = 0.0;
    for i in 0..3 {
        for k in 0..3 {
            let d = sigma[i][k] - if i == k { mean } else { 0.0 };
            s2 += d * d;
        }
    }
    (1.5 * s2).sqrt()
}
