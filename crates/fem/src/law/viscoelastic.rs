//! Quasi-linear viscoelasticity in Fung's sense (FEBio's coupled viscoelastic material): the
//! second Piola–Kirchhoff stress is the elastic law's convolved with the reduced relaxation
//! function `G(t) = 1 - sum_i g_i (1 - exp(-t / tau_i))`:
//!
//! ```text
//! S(t) = (1 - sum g_i) S_e(t) + sum_i g_i H_i(t),   H_i(t) = int exp(-(t - s) / tau_i) dS_e/ds ds
//! ```
//!
//! integrated with the usual recursive update, exact for a stress linear in time over a
//! step: `H_i <- e_i H_i + c_i (S_e,n+1 - S_e,n)`, `e_i = exp(-dt / tau_i)`,
//! `c_i = (1 - e_i) / (dt / tau_i)`. Over a step the stress is then
//! `S = alpha S_e(F) + beta` with `alpha = 1 - sum g_i (1 - c_i)` and
//! `beta = sum g_i (e_i H_i - c_i S_e,n)`, the derivative of the incremental energy
//! `alpha W_e(F) + beta : E(F)` (`E` the Green–Lagrange strain): each step stays a
//! minimization, so Newton's line search applies. The cell's volumetric part relaxes the
//! same way on its mean dilatation (`p = alpha U'(theta) + beta_v`, energy
//! `alpha U + beta_v theta`), kept in its first point's state, so for held displacements
//! every reaction follows `G(t)` exactly.
//!
//! A point's state is `[S_e,n (6), H_1 (6), ..., H_n (6), U'_n, h_1, ..., h_n]` (symmetric
//! tensors as `xx, yy, zz, yz, xz, xy`); without state (or with `dt = 0`) the law answers
//! as its elastic law (`G(0) = 1`).

use std::sync::Arc;

use super::tensor::{M3, Tangent9, cofactor, det};
use super::{MaterialLaw, Moduli, PointState};
use crate::error::{FemError, Result};

/// One Prony term of the reduced relaxation function.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PronyTerm {
    /// The fraction of the instantaneous modulus that relaxes with this term, `0 < g < 1`.
    pub g: f64,
    /// Its relaxation time, s (`> 0`).
    pub tau: f64,
}

/// An elastic law made viscoelastic by Prony terms (see the module docs).
#[derive(Debug, Clone)]
pub struct Viscoelastic {
    elastic: Arc<dyn MaterialLaw>,
    terms: Vec<PronyTerm>,
}

/// The symmetric tensor components kept, in order.
const SYM: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1)];

fn unpack(v: &[f64]) -> M3 {
    let mut m = [[0.0; 3]; 3];
    for (k, &(i, j)) in SYM.iter().enumerate() {
        m[i][j] = v[k];
        m[j][i] = v[k];
    }
    m
}

/// The coefficients `(e, c)` of a term over a step of `dt` seconds.
fn coefficients(term: &PronyTerm, dt: f64) -> (f64, f64) {
    let x = dt / term.tau;
    let e = (-x).exp();
    let c = if x < 1e-8 { 1.0 - 0.5 * x } else { (1.0 - e) / x };
    (e, c)
}

impl Viscoelastic {
    /// `elastic` (a stateless law) relaxing by `terms`.
    ///
    /// Errors ([`FemError::InvalidRelaxation`]): no term, a `g` not in (0, 1) or a `tau`
    /// not finite and > 0, `sum g >= 1` (nothing would remain at equilibrium), an elastic
    /// law that keeps state of its own.
    pub fn new(elastic: Arc<dyn MaterialLaw>, terms: Vec<PronyTerm>) -> Result<Self> {
        let bad = |reason: String| Err(FemError::InvalidRelaxation { reason });
        if terms.is_empty() {
            return bad("no Prony term".into());
        }
        for (k, t) in terms.iter().enumerate() {
            if !(t.g > 0.0 && t.g < 1.0) {
                return bad(format!("term {}: g = {} must lie in (0, 1)", k + 1, t.g));
            }
            if !(t.tau.is_finite() && t.tau > 0.0) {
                return bad(format!("term {}: tau = {} s must be finite and > 0", k + 1, t.tau));
            }
        }
        let total: f64 = terms.iter().map(|t| t.g).sum();
        if total >= 1.0 {
            return bad(format!("the terms' g add up to {total}, which must stay below 1"));
        }
        if elastic.state_len() > 0 {
            return bad(format!("the elastic law {} keeps state of its own", elastic.name()));
        }
        Ok(Self { elastic, terms })
    }

    /// The reduced relaxation function `G(t)`.
    pub fn relaxation(&self, t: f64) -> f64 {
        1.0 - self.terms.iter().map(|p| p.g * (1.0 - (-t / p.tau).exp())).sum::<f64>()
    }

    /// The Prony terms.
    pub fn terms(&self) -> &[PronyTerm] {
        &self.terms
    }

    /// Where the volumetric history starts in a point's state.
    fn volumetric_offset(&self) -> usize {
        6 * (self.terms.len() + 1)
    }

    /// `alpha` and the isochoric `beta` over the step (`None`: elastic, no state or no time).
    fn isochoric_step(&self, state: PointState<'_>) -> Option<(f64, M3)> {
        if state.values.is_empty() || state.dt == 0.0 {
            return None;
        }
        let previous = unpack(&state.values[0..6]);
        let mut alpha = 1.0;
        let mut beta = [[0.0; 3]; 3];
        for (k, term) in self.terms.iter().enumerate() {
            let (e, c) = coefficients(term, state.dt);
            alpha -= term.g * (1.0 - c);
            let h = unpack(&state.values[6 * (k + 1)..6 * (k + 2)]);
            for i in 0..3 {
                for j in 0..3 {
                    beta[i][j] += term.g * (e * h[i][j] - c * previous[i][j]);
                }
            }
        }
        Some((alpha, beta))
    }

    /// `alpha` and the volumetric `beta_v` over the step (`None`: elastic).
    fn volumetric_step(&self, state: PointState<'_>) -> Option<(f64, f64)> {
        if state.values.is_empty() || state.dt == 0.0 {
            return None;
        }
        let v = &state.values[self.volumetric_offset()..];
        let mut alpha = 1.0;
        let mut beta = 0.0;
        for (k, term) in self.terms.iter().enumerate() {
            let (e, c) = coefficients(term, state.dt);
            alpha -= term.g * (1.0 - c);
            beta += term.g * (e * v[k + 1] - c * v[0]);
        }
        Some((alpha, beta))
    }

    /// The elastic second Piola–Kirchhoff stress `F^-1 P_e` at `f`.
    fn elastic_pk2(&self, f: &M3, moduli: &Moduli) -> M3 {
        let (p, _) = self.elastic.isochoric_stress(f, moduli, PointState::ELASTIC);
        let (cof, j) = (cofactor(f), det(f));
        // F^-1 = cof(F)^T / J.
        std::array::from_fn(|i| {
            std::array::from_fn(|jj| (0..3).map(|k| cof[k][i] * p[k][jj]).sum::<f64>() / j)
        })
    }
}

impl MaterialLaw for Viscoelastic {
    fn name(&self) -> &'static str {
        "viscoelastic"
    }

    fn state_len(&self) -> usize {
        7 * (self.terms.len() + 1)
    }

    fn isochoric_energy(&self, f: &M3, moduli: &Moduli, state: PointState<'_>) -> Option<f64> {
        let elastic = self.elastic.isochoric_energy(f, moduli, PointState::ELASTIC)?;
        let Some((alpha, beta)) = self.isochoric_step(state) else { return Some(elastic) };
        let mut beta_e = 0.0;
        for i in 0..3 {
            for j in 0..3 {
                let c: f64 = (0..3).map(|k| f[k][i] * f[k][j]).sum();
                beta_e += beta[i][j] * 0.5 * (c - if i == j { 1.0 } else { 0.0 });
            }
        }
        Some(alpha * elastic + beta_e)
    }

    fn isochoric_stress(&self, f: &M3, moduli: &Moduli, state: PointState<'_>) -> (M3, Tangent9) {
        let (p, a) = self.elastic.isochoric_stress(f, moduli, PointState::ELASTIC);
        let Some((alpha, beta)) = self.isochoric_step(state) else { return (p, a) };
        let stress = std::array::from_fn(|i| {
            std::array::from_fn(|jj| alpha * p[i][jj] + (0..3).map(|k| f[i][k] * beta[k][jj]).sum::<f64>())
        });
        let tangent = std::array::from_fn(|r| {
            std::array::from_fn(|s| {
                let (i, jj, k, l) = (r / 3, r % 3, s / 3, s % 3);
                alpha * a[r][s] + if i == k { beta[l][jj] } else { 0.0 }
            })
        });
        (stress, tangent)
    }

    fn volumetric(&self, theta: f64, moduli: &Moduli, state: PointState<'_>) -> Option<[f64; 3]> {
        let [u, du, ddu] = self.elastic.volumetric(theta, moduli, PointState::ELASTIC)?;
        let Some((alpha, beta)) = self.volumetric_step(state) else { return Some([u, du, ddu]) };
        Some([alpha * u + beta * theta, alpha * du + beta, alpha * ddu])
    }

    fn commit_state(&self, f: &M3, moduli: &Moduli, state: &mut [f64], dt: f64) {
        if state.len() < self.state_len() || !(det(f) > 0.0) {
            return;
        }
        let now = self.elastic_pk2(f, moduli);
        for (k, term) in self.terms.iter().enumerate() {
            let (e, c) = coefficients(term, dt);
            for (m, &(i, j)) in SYM.iter().enumerate() {
                let previous = state[m];
                let h = &mut state[6 * (k + 1) + m];
                *h = e * *h + c * (now[i][j] - previous);
            }
        }
        for (m, &(i, j)) in SYM.iter().enumerate() {
            state[m] = now[i][j];
        }
    }

    fn commit_volumetric(&self, theta: f64, moduli: &Moduli, state: &mut [f64], dt: f64) {
        let offset = self.volumetric_offset();
        if state.len() < self.state_len() {
            return;
        }
        let Some([_, now, _]) = self.elastic.volumetric(theta, moduli, PointState::ELASTIC) else { return };
        let v = &mut state[offset..];
        for (k, term) in self.terms.iter().enumerate() {
            let (e, c) = coefficients(term, dt);
            v[k + 1] = e * v[k + 1] + c * (now - v[0]);
        }
        v[0] = now;
    }
}
