//! The uncoupled compressible neo-Hookean law.
//!
//! `W(F) = mu / 2 (J^(-2/3) I1 - 3) + U(J)`, `I1 = F : F`, `J = det F`,
//! `U(J) = kappa / 4 (J^2 - 1 - 2 ln J)` (the uncoupled neo-Hookean solid of FEBio, Maas et
//! al. 2012, and of Simo and Taylor 1991 for the split; this `U` is Simo and Miehe's, 1992,
//! convex for every `J > 0`, where `kappa / 2 (ln J)^2` softens past `J = e`). The
//! isochoric part is evaluated per Gauss point; the volumetric part `U` on a cell's mean
//! dilatation. At `F = I` the tangent is `mu (dev) + kappa (vol)`: the linear law with the
//! same `mu = E / (2 (1 + nu))`, `kappa = E / (3 (1 - 2 nu))`.

use super::tensor::{M3, Tangent9, cofactor, det};
use super::{MaterialLaw, Moduli, PointState};

/// The compressible neo-Hookean law (see the module docs). Stateless.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct NeoHookean;

impl MaterialLaw for NeoHookean {
    fn name(&self) -> &'static str {
        "neo-hookean"
    }

    fn isochoric_energy(&self, f: &M3, moduli: &Moduli, _state: PointState<'_>) -> Option<f64> {
        isochoric_energy(f, moduli.mu)
    }

    fn isochoric_stress(&self, f: &M3, moduli: &Moduli, _state: PointState<'_>) -> (M3, Tangent9) {
        isochoric_stress_tangent(f, moduli.mu)
    }

    fn volumetric(&self, theta: f64, moduli: &Moduli, _state: PointState<'_>) -> Option<[f64; 3]> {
        volumetric(theta, moduli.kappa)
    }
}

/// The isochoric energy density `mu / 2 (J^(-2/3) I1 - 3)`, or `None` when `J <= 0`.
pub fn isochoric_energy(f: &M3, mu: f64) -> Option<f64> {
    let j = det(f);
    if !(j > 0.0) {
        return None;
    }
    let i1: f64 = f.iter().flatten().map(|x| x * x).sum();
    Some(0.5 * mu * (j.powf(-2.0 / 3.0) * i1 - 3.0))
}

/// The isochoric first Piola–Kirchhoff stress `P = mu J^(-2/3) (F - I1 / 3 F^-T)` and
/// tangent `A[iJ][kL] = dP_iJ / dF_kL` (flattened `3 i + J`), for `J > 0`.
pub fn isochoric_stress_tangent(f: &M3, mu: f64) -> (M3, Tangent9) {
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
pub fn volumetric(theta: f64, kappa: f64) -> Option<[f64; 3]> {
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
