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

use std::sync::Arc;

use crate::element::{CELL_DOFS, CellMatrix, gauss_points, gradients, unit_cell_matrices};
use crate::grid::{CellFill, Element};
use crate::law::state::POINTS_PER_CELL;
use crate::law::tensor::{M3, cofactor, det, symmetric_eigenvalues};
use crate::law::{CellLawState, PointState};
use crate::law::{MaterialLaw, Moduli};
use crate::tissue::Tissue;

/// A cell's constitutive law and moduli (a region's tissue, or a blend of tissues).
#[derive(Debug, Clone)]
pub struct CellMaterial {
    /// The law (shared by the cells of one tissue).
    pub law: Arc<dyn MaterialLaw>,
    /// Shear modulus `mu`, Pa.
    pub mu: f64,
    /// Bulk modulus `kappa`, Pa.
    pub kappa: f64,
}

impl PartialEq for CellMaterial {
    fn eq(&self, other: &Self) -> bool {
        self.law.name() == other.law.name() && self.mu == other.mu && self.kappa == other.kappa
    }
}

impl CellMaterial {
    /// `law` with the moduli `mu` and `kappa` (Pa).
    pub fn new(law: Arc<dyn MaterialLaw>, mu: f64, kappa: f64) -> Self {
        Self { law, mu, kappa }
    }

    /// The law and moduli of a tissue.
    pub fn of(tissue: &Tissue) -> Self {
        Self::new(tissue.law(), tissue.shear_modulus(), tissue.bulk_modulus())
    }

    /// The moduli the law is evaluated with.
    pub fn moduli(&self) -> Moduli {
        Moduli { mu: self.mu, kappa: self.kappa }
    }

    /// A cell's state at the law's initial state (`8 x state_len` values).
    fn initial_cell_state(&self) -> Vec<f64> {
        let len = self.law.state_len();
        let mut v = vec![0.0; POINTS_PER_CELL * len];
        if len > 0 {
            v.chunks_mut(len).for_each(|s| self.law.initial_state(s));
        }
        v
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

/// The fictitious material's bulk modulus is at most this multiple of its shear modulus
/// (that of Poisson's ratio 0.3). Integrated fully, a nearly incompressible fictitious
/// material would lock: at nu = 0.499 (`kappa = 500 mu`) the empty part of a cut cell
/// carried `5 mu` of locked volumetric stiffness, five times the tissue's shear modulus,
/// and the thick sphere under pressure came out 5-8 % too stiff.
pub const EMPTY_BULK_RATIO: f64 = 13.0 / 6.0;

/// The fictitious material's weight in a cell of `fill`.
fn empty_weight(fill: f64) -> f64 {
    EMPTY_STIFFNESS * (1.0 - fill).max(0.0)
}

/// The moduli the fictitious material's volumetric energy is evaluated with.
fn empty_moduli(moduli: &Moduli) -> Moduli {
    Moduli { mu: moduli.mu, kappa: moduli.kappa.min(EMPTY_BULK_RATIO * moduli.mu) }
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
    pub(crate) fn linear_matrix(&self, m: &CellMaterial, fill: f64) -> CellMatrix {
        let (dev, vol) = &*self.linear;
        let c = fill * self.h;
        std::array::from_fn(|r| std::array::from_fn(|s| c * (m.mu * dev[r][s] + m.kappa * vol[r][s])))
    }

    /// The cell's energy (J) at node displacements `u`, times `fill` (a fraction, or the
    /// fill by octant: [`CellFill`]), with its law at its initial state; `None` when a Gauss
    /// point or the cell has `J <= 0` (a nonlinear law).
    pub fn energy(&self, m: &CellMaterial, u: &[Vec3; 8], fill: impl Into<CellFill>) -> Option<f64> {
        self.energy_with(m, u, fill, CellLawState { values: &m.initial_cell_state(), dt: 0.0 })
    }

    /// [`HyperCell::energy`] with the cell's law state `state` (`8 x state_len` values).
    pub fn energy_with(
        &self,
        m: &CellMaterial,
        u: &[Vec3; 8],
        fill: impl Into<CellFill>,
        state: CellLawState<'_>,
    ) -> Option<f64> {
        let fill = fill.into();
        if m.law.is_linear() {
            let k = self.linear_matrix(m, fill.mean());
            let x: Vec<f64> = u.iter().flatten().copied().collect();
            return Some(
                0.5 * (0..CELL_DOFS)
                    .map(|r| x[r] * (0..CELL_DOFS).map(|c| k[r][c] * x[c]).sum::<f64>())
                    .sum::<f64>(),
            );
        }
        let (law, moduli, len) = (&*m.law, m.moduli(), m.law.state_len());
        let w = Weights::of(&fill, self.volume, 0.0);
        let (mut stored, mut theta) = (0.0, 0.0);
        for (p, g) in self.grads.iter().enumerate() {
            let f = deformation_gradient(u, g);
            let iso = law.isochoric_energy(&f, &moduli, state.point(len, p))?;
            let pointwise = law.volumetric(det(&f), &empty_moduli(&moduli), PointState::ELASTIC)?[0];
            stored += (w.tissue[p] + w.empty[p]) * iso + w.empty[p] * pointwise;
            theta += w.theta[p] * det(&f);
        }
        let [vol, _, _] = law.volumetric(theta, &moduli, state.point(len, 0))?;
        Some(stored + w.scale * vol)
    }

    /// The gradient and (with `hessian`) the Hessian of [`HyperCell::energy`]; `None` when
    /// a Gauss point or the cell has `J <= 0` (a nonlinear law).
    pub fn tangent(
        &self,
        m: &CellMaterial,
        u: &[Vec3; 8],
        fill: impl Into<CellFill>,
        hessian: bool,
    ) -> Option<CellTangent> {
        self.tangent_with(m, u, fill, hessian, CellLawState { values: &m.initial_cell_state(), dt: 0.0 })
    }

    /// [`HyperCell::tangent`] with the cell's law state `state` (`8 x state_len` values).
    pub fn tangent_with(
        &self,
        m: &CellMaterial,
        u: &[Vec3; 8],
        fill: impl Into<CellFill>,
        hessian: bool,
        state: CellLawState<'_>,
    ) -> Option<CellTangent> {
        let fill = fill.into();
        if m.law.is_linear() {
            let k = self.linear_matrix(m, fill.mean());
            let x: Vec<f64> = u.iter().flatten().copied().collect();
            let gradient = std::array::from_fn(|r| (0..CELL_DOFS).map(|c| k[r][c] * x[c]).sum());
            return Some(CellTangent { gradient, hessian: hessian.then(|| Box::new(k)) });
        }
        let fs: [M3; 8] = std::array::from_fn(|p| deformation_gradient(u, &self.grads[p]));
        let js = fs.map(|f| det(&f));
        if js.iter().any(|&j| !(j > 0.0)) {
            return None;
        }
        let mut weights = Weights::of(&fill, self.volume, 0.0);
        let theta: f64 = js.iter().zip(&weights.theta).map(|(j, w)| w * j).sum();
        let [_, du, ddu] = m.law.volumetric(theta, &m.moduli(), state.point(m.law.state_len(), 0))?;
        weights.du = du;
        let mut gradient = [0.0; CELL_DOFS];
        let mut dtheta = [0.0; CELL_DOFS];
        let mut k = hessian.then(|| Box::new([[0.0; CELL_DOFS]; CELL_DOFS]));
        for p in 0..8 {
            let point =
                Point { p, g: &self.grads[p], f: &fs[p], j: js[p], state: state.point(m.law.state_len(), p) };
            self.add_point(m, &point, &weights, &mut gradient, &mut dtheta, k.as_deref_mut())?;
        }
        for (gi, d) in gradient.iter_mut().zip(&dtheta) {
            *gi += weights.scale * du * d;
        }
        if let Some(k) = k.as_deref_mut() {
            for r in 0..CELL_DOFS {
                for s in 0..CELL_DOFS {
                    k[r][s] += weights.scale * ddu * dtheta[r] * dtheta[s];
                }
            }
        }
        Some(CellTangent { gradient, hessian: k })
    }

    /// One Gauss point's share of the gradient, of the dilatation's gradient and (with `k`)
    /// of the Hessian; `None` when the law's volumetric energy is undefined there.
    fn add_point(
        &self,
        m: &CellMaterial,
        point: &Point<'_>,
        w: &Weights,
        gradient: &mut [f64; CELL_DOFS],
        dtheta: &mut [f64; CELL_DOFS],
        k: Option<&mut CellMatrix>,
    ) -> Option<()> {
        let (g, moduli, p) = (point.g, m.moduli(), point.p);
        let (tissue, empty, theta, du) = (w.tissue[p], w.empty[p], w.theta[p], w.du);
        let cof = cofactor(point.f);
        let (stress, a) = m.law.isochoric_stress(point.f, &moduli, point.state);
        // The empty part's pointwise volumetric energy U(J) (see `EMPTY_STIFFNESS`).
        let [_, du_p, ddu_p] = m.law.volumetric(point.j, &empty_moduli(&moduli), PointState::ELASTIC)?;
        for b in 0..8 {
            for i in 0..3 {
                let dot = |m: &M3| (0..3).map(|jj| m[i][jj] * g[b][jj]).sum::<f64>();
                gradient[3 * b + i] += (tissue + empty) * dot(&stress) + empty * du_p * dot(&cof);
                dtheta[3 * b + i] += theta * dot(&cof);
            }
        }
        if let Some(k) = k {
            let mut c = a;
            for (r, row) in c.iter_mut().enumerate() {
                let (i, jj) = (r / 3, r % 3);
                for (s, v) in row.iter_mut().enumerate() {
                    let (kk, l) = (s / 3, s % 3);
                    let geometric = (cof[i][jj] * cof[kk][l] - cof[i][l] * cof[kk][jj]) / point.j;
                    let material = cof[i][jj] * cof[kk][l];
                    *v = (tissue + empty) * *v
                        + w.scale * theta * du * geometric
                        + empty * (du_p * geometric + ddu_p * material);
                }
            }
            add_gauss_point(k, &c, g, 1.0);
        }
        Some(())
    }

    /// The deformation gradient at each Gauss point for node displacements `u`.
    pub fn deformation_gradients(&self, u: &[Vec3; 8]) -> [M3; 8] {
        std::array::from_fn(|p| deformation_gradient(u, &self.grads[p]))
    }

    /// Strain, stress (of the cell's own law, at its initial state) and `J` of a deformed
    /// cell.
    pub fn state(&self, m: &CellMaterial, u: &[Vec3; 8]) -> CellState {
        self.state_with(m, u, CellLawState { values: &m.initial_cell_state(), dt: 0.0 })
    }

    /// [`HyperCell::state`] with the cell's law state (the centre reads point 0's).
    pub fn state_with(&self, m: &CellMaterial, u: &[Vec3; 8], state: CellLawState<'_>) -> CellState {
        let js: Vec<f64> = self.grads.iter().map(|g| det(&deformation_gradient(u, g))).collect();
        let theta: f64 = js.iter().map(|j| W * j).sum();
        let f = deformation_gradient(u, &self.centre);
        let green: M3 = std::array::from_fn(|i| {
            std::array::from_fn(|j| {
                0.5 * ((0..3).map(|k| f[k][i] * f[k][j]).sum::<f64>() - if i == j { 1.0 } else { 0.0 })
            })
        });
        let eig = symmetric_eigenvalues(&green);
        let von_mises = m.law.von_mises(&f, &m.moduli(), state.point(m.law.state_len(), 0));
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

/// One Gauss point's kinematics and law state.
struct Point<'a> {
    p: usize,
    g: &'a [[f64; 3]; 8],
    f: &'a M3,
    j: f64,
    state: PointState<'a>,
}

/// A cell's quadrature weights: each Gauss point's tissue volume (`V f_p / 8`) and empty
/// part's (`EMPTY_STIFFNESS V (1 - f_p) / 8`), its weight in the tissue's mean dilatation
/// (`f_p / sum f`), the tissue's volume `V mean(f)` that `U(theta)` is integrated over, and
/// `U'(theta)`.
struct Weights {
    tissue: [f64; 8],
    empty: [f64; 8],
    theta: [f64; 8],
    scale: f64,
    du: f64,
}

impl Weights {
    fn of(fill: &CellFill, volume: f64, du: f64) -> Self {
        let total: f64 = fill.points.iter().sum();
        Self {
            tissue: fill.points.map(|f| volume * f * W),
            empty: fill.points.map(|f| volume * empty_weight(f) * W),
            theta: fill.points.map(|f| if total > 0.0 { f / total } else { W }),
            scale: volume * fill.mean(),
            du,
        }
    }
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
