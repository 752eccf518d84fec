//! The small-strain linear law: `W = mu |dev eps|^2 + kappa / 2 (theta - 1)^2`,
//! `eps = sym(F) - I`.
//!
//! The hyperelastic cell does not evaluate it point by point: [`MaterialLaw::is_linear`]
//! tells it to use the linear B-bar element's matrices (the same energy, integrated
//! exactly once), so a linear answer is one solve and equals the linear body's. The
//! pointwise functions below are that energy's, for laws and tools that ask at a point.

use super::tensor::{M3, Tangent9};
use super::{MaterialLaw, Moduli, PointState};

/// Small-strain isotropic linear elasticity (see the module docs). Stateless.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LinearLaw;

/// `dev sym(F - I)`.
fn deviatoric_strain(f: &M3) -> M3 {
    let eps: M3 = std::array::from_fn(|i| {
        std::array::from_fn(|k| 0.5 * (f[i][k] + f[k][i]) - if i == k { 1.0 } else { 0.0 })
    });
    let mean = (eps[0][0] + eps[1][1] + eps[2][2]) / 3.0;
    std::array::from_fn(|i| std::array::from_fn(|k| eps[i][k] - if i == k { mean } else { 0.0 }))
}

impl MaterialLaw for LinearLaw {
    fn name(&self) -> &'static str {
        "linear"
    }

    fn is_linear(&self) -> bool {
        true
    }

    fn isochoric_energy(&self, f: &M3, moduli: &Moduli, _state: PointState<'_>) -> Option<f64> {
        let e = deviatoric_strain(f);
        Some(moduli.mu * e.iter().flatten().map(|x| x * x).sum::<f64>())
    }

    fn isochoric_stress(&self, f: &M3, moduli: &Moduli, _state: PointState<'_>) -> (M3, Tangent9) {
        let e = deviatoric_strain(f);
        let p = e.map(|row| row.map(|x| 2.0 * moduli.mu * x));
        let delta = |a: usize, b: usize| if a == b { 1.0 } else { 0.0 };
        let t = std::array::from_fn(|r| {
            std::array::from_fn(|s| {
                let (i, j, k, l) = (r / 3, r % 3, s / 3, s % 3);
                moduli.mu * (delta(i, k) * delta(j, l) + delta(i, l) * delta(j, k))
                    - 2.0 * moduli.mu / 3.0 * delta(i, j) * delta(k, l)
            })
        });
        (p, t)
    }

    fn volumetric(&self, theta: f64, moduli: &Moduli, _state: PointState<'_>) -> Option<[f64; 3]> {
        let d = theta - 1.0;
        Some([0.5 * moduli.kappa * d * d, moduli.kappa * d, moduli.kappa])
    }

    /// `2 mu |dev eps|` scaled to von Mises (`sqrt(3/2) |s|`), defined at any `F`.
    fn von_mises(&self, f: &M3, moduli: &Moduli, _state: PointState<'_>) -> f64 {
        let e = deviatoric_strain(f);
        let dev2: f64 = e.iter().flatten().map(|x| x * x).sum();
        2.0 * moduli.mu * (1.5 * dev2).sqrt()
    }
}
