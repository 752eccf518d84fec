//! The uncoupled compressible neo-Hookean energy at a point, with its first Piola–Kirchhoff
//! stress and its tangent.
//!
//! `W(F) = mu / 2 (J^(-2/3) I1 - 3) + U(J)`, `I1 = F : F`, `J = det F`,
//! `U(J) = kappa / 4 (J^2 - 1 - 2 ln J)` (the uncoupled neo-Hookean solid of FEBio, Maas et
//! al. 2012, and of Simo and Taylor 1991 for the split; this `U` is Simo and Miehe's, 1992,
//! convex for every `J > 0`, where `kappa / 2 (ln J)^2` softens past `J = e`). The isochoric part is evaluated here per Gauss point; the
//! volumetric part `U` is evaluated on a cell's mean dilatation (see [`super::cell`]).
//! At `F = I` the tangent is `mu (dev) + kappa (vol)`: the linear model with the same
//! `mu = E / (2 (1 + nu))`, `kappa = E / (3 (1 - 2 nu))`.

/// A 3 x 3 matrix, `m[i][j]`.
pub(crate) type M3 = [[f64; 3]; 3];

/// `det m`.
pub(crate) fn det(m: &M3) -> f64 {
    m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
}

/// The cofactor matrix `cof m = det(m) m^-T`.
pub(crate) fn cofactor(m: &M3) -> M3 {
    let c = |i: usize, j: usize| {
        let (i1, i2) = ((i + 1) % 3, (i + 2) % 3);
        let (j1, j2) = ((j + 1) % 3, (j + 2) % 3);
        m[i1][j1] * m[i2][j2] - m[i1][j2] * m[i2][j1]
    };
    std::array::from_fn(|i| std::array::from_fn(|j| c(i, j)))
}

/// The isochoric energy density `mu / 2 (J^(-2/3) I1 - 3)`, or `None` when `J <= 0`.
pub(crate) fn isochoric_energy(f: &M3, mu: f64) -> Option<f64> {
    let j = det(f);
    if !(j > 0.0) {
        return None;
    }
    let i1: f64 = f.iter().flatten().map(|x| x * x).sum();
    Some(0.5 * mu * (j.powf(-2.0 / 3.0) * i1 - 3.0))
}

/// The isochoric first Piola–Kirchhoff stress `P = mu J^(-2/3) (F - I1 / 3 F^-T)` and
/// tangent `A[iJ][kL] = dP_iJ / dF_kL` (flattened `3 i + J`), for `J > 0`.
pub(crate) fn isochoric_stress_tangent(f: &M3, mu: f64) -> (M3, [[f64; 9]; 9]) {
    let j = det(f);
    let cof = cofactor(f);
    let h: M3 = std::array::from_fn(|i| std::array::from_fn(|k| cof[i][k] / j));
    let i1: f64 = f.iter().flatten().map(|x| x * x).sum();
    let a = mu * j.powf(-2.0 / 3.0);
    let p = std::array::from_fn(|i| std::array::from_fn(|jj| a * (f[i][jj] - i1 / 3.0 * h[i][jj])));
    let mut t = [[0.0; 9]; 9];
    for i in 0..3 {
        for jj in 0..3 {
            for k in 0..3 {
                for l in 0..3 {
                    let delta = if i == k && jj == l { 1.0 } else { 0.0 };
                    t[3 * i + jj][3 * k + l] = a
                        * (delta - 2.0 / 3.0 * (h[k][l] * f[i][jj] + f[k][l] * h[i][jj])
                            + 2.0 / 9.0 * i1 * h[k][l] * h[i][jj]
                            + i1 / 3.0 * h[i][l] * h[k][jj]);
                }
            }
        }
    }
    (p, t)
}

/// The volumetric energy `U(theta) = kappa / 4 (theta^2 - 1 - 2 ln theta)` and its first two
/// derivatives (`kappa / 2 (theta - 1 / theta)`, `kappa / 2 (1 + theta^-2)`, positive: the
/// pressure rises with the dilatation at every `theta`), or `None` when `theta <= 0`.
pub(crate) fn volumetric(theta: f64, kappa: f64) -> Option<[f64; 3]> {
    if !(theta > 0.0) {
        return None;
    }
    let inv = 1.0 / theta;
    Some([
        0.25 * kappa * (theta * theta - 1.0 - 2.0 * theta.ln()),
        0.5 * kappa * (theta - inv),
        0.5 * kappa * (1.0 + inv * inv),
    ])
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
