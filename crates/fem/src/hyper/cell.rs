//! One cell's hyperelastic energy, its gradient (internal forces) and Hessian (tangent).
//!
//! Mean dilatation (Simo, Taylor and Pister 1985; the nonlinear counterpart of B-bar): the
//! isochoric energy is integrated with the 2x2x2 Gauss points; the volumetric energy is
//! `V U(theta)` with `theta = v / V` the cell's current over its rest volume, itself the
//! exact Gauss integral of `J` (a trilinear cell's `J` is of degree 2 per axis). One
//! volumetric constraint per cell, so it does not lock as nu -> 0.5, and the discrete
//! energy is a potential: the tangent is symmetric. A partly filled cell scales its energy
//! by its fill fraction, as the linear element does.

use fibfluid_geometry::Vec3;

use super::material::{M3, cofactor, det, isochoric_energy, isochoric_stress_tangent, volumetric};
use crate::element::{CELL_DOFS, CellMatrix, gauss_points, gradients, unit_cell_matrices};
use crate::grid::Element;
use crate::tissue::{Tissue, TissueModel};

/// A cell's constitutive law and moduli (a region's tissue, or a blend of tissues).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CellMaterial {
    /// Linear (the B-bar element's quadratic energy) or neo-Hookean.
    pub model: TissueModel,
    /// Shear modulus `mu`, Pa.
    pub mu: f64,
    /// Bulk modulus `kappa`, Pa.
    pub kappa: f64,
}

impl CellMaterial {
    /// The law and moduli of a tissue.
    pub fn of(tissue: &Tissue) -> Self {
        Self { model: tissue.model(), mu: tissue.shear_modulus(), kappa: tissue.bulk_modulus() }
    }
}

/// The empty part of a partly filled neo-Hookean cell is a fictitious material of this
/// fraction of the tissue's moduli (the finite-cell method's), integrated fully (the
/// volumetric energy `U(J)` at each Gauss point, not on the mean dilatation). A
/// mean-dilatation hexahedron under a large pressure can buckle in spurious modes; the
/// empty part of a boundary cell, held only by the tissue part's energy (scaled by its
/// fill), did (the Newton iterations stalled with an indefinite tangent). The fictitious
/// material is rotation-invariant, so it resists no rigid turn of the cell, and a cell that
/// is half empty gains 0.5 % of its stiffness.
pub const EMPTY_STIFFNESS: f64 = 1e-2;

/// The fictitious material's weight in a cell of `fill`.
fn empty_weight(fill: f64) -> f64 {
    EMPTY_STIFFNESS * (1.0 - fill).max(0.0)
}

/// Gauss weight of each of the eight points (fractions of the cell's volume).
const W: f64 = 1.0 / 8.0;

/// One cubic cell of the hyperelastic body: moduli, size and shape-function gradients.
/// Corner `b` sits at `(b & 1, (b >> 1) & 1, (b >> 2) & 1) * h`; `u[b]` is its displacement.
#[derive(Debug, Clone)]
pub struct HyperCell {
    h: f64,
    volume: f64,
    /// The linear element's unit-cube, unit-moduli matrices `(deviatoric, volumetric)`.
    linear: Box<(CellMatrix, CellMatrix)>,
    /// Physical gradients `grad N_b` at each Gauss point (1/m).
    grads: [[[f64; 3]; 8]; 8],
    /// Physical gradients at the cell's centre.
    centre: [[f64; 3]; 8],
}

/// A cell's gradient (internal forces on its 24 local dofs) and, when asked, its Hessian.
pub struct CellTangent {
    /// `dE / du` on the local dofs `3 b + a` (corner `b`, axis `a`), N.
    pub gradient: [f64; CELL_DOFS],
    /// `d2E / du2` (N/m), when asked for.
    pub hessian: Option<Box<CellMatrix>>,
}

/// Per-cell measures of a deformed cell, at its centre (strain, stress) and over its Gauss
/// points (J).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CellState {
    /// Smallest `J = det F` over the Gauss points.
    pub j_min: f64,
    /// Largest `J` over the Gauss points.
    pub j_max: f64,
    /// The cell's mean dilatation `theta` (current over rest volume).
    pub dilatation: f64,
    /// Largest principal Green–Lagrange strain at the centre.
    pub max_principal_strain: f64,
    /// Largest absolute principal Green–Lagrange strain at the centre.
    pub strain_magnitude: f64,
    /// Von Mises equivalent of the Cauchy stress at the centre, Pa.
    pub von_mises: f64,
}

fn deformation_gradient(u: &[Vec3; 8], g: &[[f64; 3]; 8]) -> M3 {
    std::array::from_fn(|i| {
        std::array::from_fn(|jj| {
            (if i == jj { 1.0 } else { 0.0 }) + (0..8).map(|b| u[b][i] * g[b][jj]).sum::<f64>()
        })
    })
}

impl HyperCell {
    /// The element of edge `h` (m).
    pub fn new(h: f64) -> Self {
        let scale = |g: [[f64; 3]; 8]| g.map(|v| v.map(|x| x / h));
        let points = gauss_points();
        Self {
            h,
            linear: Box::new(unit_cell_matrices(Element::BBar)),
            volume: h * h * h,
            grads: std::array::from_fn(|p| scale(gradients(points[p]))),
            centre: scale(gradients([0.5; 3])),
        }
    }

    /// The linear element's stiffness `h (mu D + kappa V)` times `fill`.
    fn linear_matrix(&self, m: &CellMaterial, fill: f64) -> CellMatrix {
        let (dev, vol) = &*self.linear;
        let c = fill * self.h;
        std::array::from_fn(|r| std::array::from_fn(|s| c * (m.mu * dev[r][s] + m.kappa * vol[r][s])))
    }

    /// The cell's energy (J) at node displacements `u`, times `fill`; `None` when a
    /// neo-Hookean Gauss point or cell has `J <= 0`.
    pub fn energy(&self, m: &CellMaterial, u: &[Vec3; 8], fill: f64) -> Option<f64> {
        if m.model == TissueModel::Linear {
            let k = self.linear_matrix(m, fill);
            let x: Vec<f64> = u.iter().flatten().copied().collect();
            return Some(
                0.5 * (0..CELL_DOFS)
                    .map(|r| x[r] * (0..CELL_DOFS).map(|c| k[r][c] * x[c]).sum::<f64>())
                    .sum::<f64>(),
            );
        }
        let mut iso = 0.0;
        let mut theta = 0.0;
        let mut pointwise = 0.0;
        for g in &self.grads {
            let f = deformation_gradient(u, g);
            iso += W * isochoric_energy(&f, m.mu)?;
            theta += W * det(&f);
            pointwise += W * volumetric(det(&f), m.kappa)?[0];
        }
        let [vol, _, _] = volumetric(theta, m.kappa)?;
        let empty = empty_weight(fill) * self.volume;
        Some(fill * self.volume * (iso + vol) + empty * (iso + pointwise))
    }

    /// The gradient and (with `hessian`) the Hessian of [`HyperCell::energy`]; `None` when
    /// a neo-Hookean Gauss point or cell has `J <= 0`.
    pub fn tangent(&self, m: &CellMaterial, u: &[Vec3; 8], fill: f64, hessian: bool) -> Option<CellTangent> {
        if m.model == TissueModel::Linear {
            let k = self.linear_matrix(m, fill);
            let x: Vec<f64> = u.iter().flatten().copied().collect();
            let gradient = std::array::from_fn(|r| (0..CELL_DOFS).map(|c| k[r][c] * x[c]).sum());
            return Some(CellTangent { gradient, hessian: hessian.then(|| Box::new(k)) });
        }
        let scale = fill * self.volume;
        let empty = empty_weight(fill) * self.volume;
        let fs: [M3; 8] = std::array::from_fn(|p| deformation_gradient(u, &self.grads[p]));
        let js = fs.map(|f| det(&f));
        if js.iter().any(|&j| !(j > 0.0)) {
            return None;
        }
        let theta: f64 = js.iter().map(|j| W * j).sum();
        let [_, du, ddu] = volumetric(theta, m.kappa)?;
        let mut gradient = [0.0; CELL_DOFS];
        let mut dtheta = [0.0; CELL_DOFS];
        let mut k = hessian.then(|| Box::new([[0.0; CELL_DOFS]; CELL_DOFS]));
        for p in 0..8 {
            let g = &self.grads[p];
            let cof = cofactor(&fs[p]);
            let (stress, a) = isochoric_stress_tangent(&fs[p], m.mu);
            // The empty part's pointwise volumetric energy U(J) (see `EMPTY_STIFFNESS`).
            let [_, du_p, ddu_p] = volumetric(js[p], m.kappa)?;
            for b in 0..8 {
                for i in 0..3 {
                    let dot = |m: &M3| (0..3).map(|jj| m[i][jj] * g[b][jj]).sum::<f64>();
                    gradient[3 * b + i] += (scale + empty) * W * dot(&stress) + empty * W * du_p * dot(&cof);
                    dtheta[3 * b + i] += W * dot(&cof);
                }
            }
            if let Some(k) = k.as_deref_mut() {
                let mut c = a;
                for (r, row) in c.iter_mut().enumerate() {
                    let (i, jj) = (r / 3, r % 3);
                    for (s, v) in row.iter_mut().enumerate() {
                        let (kk, l) = (s / 3, s % 3);
                        let geometric = (cof[i][jj] * cof[kk][l] - cof[i][l] * cof[kk][jj]) / js[p];
                        let material = cof[i][jj] * cof[kk][l];
                        *v = W
                            * ((scale + empty) * *v
                                + scale * du * geometric
                                + empty * (du_p * geometric + ddu_p * material));
                    }
                }
                add_gauss_point(k, &c, g, 1.0);
            }
        }
        for (gi, d) in gradient.iter_mut().zip(&dtheta) {
            *gi += scale * du * d;
        }
        if let Some(k) = k.as_deref_mut() {
            for r in 0..CELL_DOFS {
                for s in 0..CELL_DOFS {
                    k[r][s] += scale * ddu * dtheta[r] * dtheta[s];
                }
            }
        }
        Some(CellTangent { gradient, hessian: k })
    }

    /// Strain, stress (of the cell's own law) and `J` of a deformed cell.
    pub fn state(&self, m: &CellMaterial, u: &[Vec3; 8]) -> CellState {
        let js: Vec<f64> = self.grads.iter().map(|g| det(&deformation_gradient(u, g))).collect();
        let theta: f64 = js.iter().map(|j| W * j).sum();
        let f = deformation_gradient(u, &self.centre);
        let green: M3 = std::array::from_fn(|i| {
            std::array::from_fn(|j| {
                0.5 * ((0..3).map(|k| f[k][i] * f[k][j]).sum::<f64>() - if i == j { 1.0 } else { 0.0 })
            })
        });
        let eig = super::material::symmetric_eigenvalues(&green);
        let von_mises = match m.model {
            TissueModel::Linear => linear_von_mises(&f, m.mu),
            TissueModel::NeoHookean if det(&f) > 0.0 => isochoric_von_mises(&f, m.mu),
            TissueModel::NeoHookean => f64::NAN,
        };
        CellState {
            j_min: js.iter().copied().fold(f64::INFINITY, f64::min),
            j_max: js.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            dilatation: theta,
            max_principal_strain: eig[2],
            strain_magnitude: eig[2].abs().max(eig[0].abs()),
            von_mises,
        }
    }
}

/// The von Mises stress of the small-strain stress `2 mu dev eps` (`eps` the symmetric
/// part of `F - I`).
fn linear_von_mises(f: &M3, mu: f64) -> f64 {
    let eps: M3 = std::array::from_fn(|i| {
        std::array::from_fn(|k| 0.5 * (f[i][k] + f[k][i]) - if i == k { 1.0 } else { 0.0 })
    });
    let mean = (eps[0][0] + eps[1][1] + eps[2][2]) / 3.0;
    let dev2: f64 = (0..9)
        .map(|r| {
            let (i, k) = (r / 3, r % 3);
            (eps[i][k] - if i == k { mean } else { 0.0 }).powi(2)
        })
        .sum();
    2.0 * mu * (1.5 * dev2).sqrt()
}

/// The von Mises stress of the Cauchy stress `sigma = P F^T / J` (the volumetric part is a
/// pressure and drops out).
fn isochoric_von_mises(f: &M3, mu: f64) -> f64 {
    let j = det(f);
    let (p, _) = isochoric_stress_tangent(f, mu);
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

/// `K[(b, i)][(c, k)] += scale * sum_JL grad N_b,J C[iJ][kL] grad N_c,L` for one Gauss point.
fn add_gauss_point(k: &mut CellMatrix, c: &[[f64; 9]; 9], g: &[[f64; 3]; 8], scale: f64) {
    for cn in 0..8 {
        for kk in 0..3 {
            // t[iJ] = sum_L C[iJ][kL] grad N_c,L
            let t: [f64; 9] = std::array::from_fn(|r| (0..3).map(|l| c[r][3 * kk + l] * g[cn][l]).sum());
            let col = 3 * cn + kk;
            for b in 0..8 {
                for i in 0..3 {
                    k[3 * b + i][col] += scale * (0..3).map(|jj| g[b][jj] * t[3 * i + jj]).sum::<f64>();
                }
            }
        }
    }
}
