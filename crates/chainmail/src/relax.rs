//! Position-based volume and strain-energy conservation (Eq. 15–17) and release.

use crate::error::{ChainmailError, Result};
use crate::lattice::{Lattice, cross, dot, norm, sub, tet_volume};
use crate::material::Material;

const NONE: u32 = u32::MAX;

/// Options of [`Lattice::relax`] and [`Lattice::release`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RelaxOptions {
    /// Upper bound on the number of Gauss–Seidel sweeps (default 200).
    pub max_iterations: usize,
    /// Stop when the largest single position correction of a sweep is below
    /// `tolerance * spacing` (default `1e-6`).
    pub tolerance: f64,
    /// Apply the volume constraint `C = V(tet) − V0` (Eq. 16) (default true).
    pub volume: bool,
    /// Apply the strain-energy constraint (Eq. 17) (default true).
    pub energy: bool,
    /// Scale in `[0, 1]` of each volume correction (default 1: the full Eq. 15 step).
    pub volume_stiffness: f64,
    /// Scale in `[0, 1]` of each energy correction (default 1: the full Eq. 15 step).
    pub energy_stiffness: f64,
    /// After the volume and energy projections of each sweep, project every violated link
    /// back onto its CBR, splitting the correction by inverse mass (default true).
    pub enforce_cbr: bool,
}

impl Default for RelaxOptions {
    fn default() -> Self {
        Self {
            max_iterations: 200,
            tolerance: 1e-6,
            volume: true,
            energy: true,
            volume_stiffness: 1.0,
            energy_stiffness: 1.0,
            enforce_cbr: true,
        }
    }
}

/// What one call of [`Lattice::relax`] did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RelaxReport {
    /// Sweeps performed.
    pub iterations: usize,
    /// Whether the tolerance was met within `max_iterations`.
    pub converged: bool,
    /// Largest single position correction of the last sweep.
    pub max_correction: f64,
    /// [`Lattice::relative_volume_change`] at the end.
    pub relative_volume_change: f64,
}

fn check_unit(name: &'static str, v: f64) -> Result<()> {
    if !(v.is_finite() && (0.0..=1.0).contains(&v)) {
        return Err(ChainmailError::InvalidParameter { name, reason: format!("{v} is not in [0, 1]") });
    }
    Ok(())
}

/// Applies `Δp_k = −s w_k C / (Σ_j w_j |∇_j C|²) ∇_k C` (Eq. 15); returns the largest
/// correction length.
fn project(pos: &mut [[f64; 3]], t: &[usize; 4], w: [f64; 4], c: f64, grad: [[f64; 3]; 4], s: f64) -> f64 {
    let denom: f64 = (0..4).map(|k| w[k] * dot(grad[k], grad[k])).sum();
    if denom.is_nan() || denom <= 1e-300 || !c.is_finite() {
        return 0.0;
    }
    let lambda = s * c / denom;
    let mut largest = 0.0_f64;
    for k in 0..4 {
        let f = lambda * w[k];
        let d = [-f * grad[k][0], -f * grad[k][1], -f * grad[k][2]];
        largest = largest.max(norm(d));
        let p = &mut pos[t[k]];
        for a in 0..3 {
            p[a] += d[a];
        }
    }
    largest
}

impl Lattice {
    /// Relaxation: Gauss–Seidel sweeps of the paper's position-based corrections (Eq. 15)
    /// for the volume constraint (Eq. 16) and the strain-energy constraint (Eq. 17) of every
    /// tetrahedron, optionally followed in each sweep by a CBR projection of every link.
    /// Elements listed in `held` (e.g. the pushed region) and elements with zero inverse
    /// mass do not move. Stops after `max_iterations` sweeps or when the largest correction
    /// of a sweep is below `tolerance * spacing`.
    ///
    /// Errors: invalid material or options, a held index out of range.
    pub fn relax<M: Material + ?Sized>(
        &mut self,
        material: &M,
        held: &[usize],
        options: &RelaxOptions,
    ) -> Result<RelaxReport> {
        material.validate(self.len())?;
        check_unit("volume_stiffness", options.volume_stiffness)?;
        check_unit("energy_stiffness", options.energy_stiffness)?;
        if !(options.tolerance.is_finite() && options.tolerance >= 0.0) {
            return Err(ChainmailError::InvalidParameter {
                name: "tolerance",
                reason: format!("{} is not finite and >= 0", options.tolerance),
            });
        }
        let mut w = self.inv_mass.clone();
        for &e in held {
            self.check_index(e)?;
            w[e] = 0.0;
        }
        let tol = options.tolerance * self.spacing();
        let mut report = RelaxReport::default();
        for _ in 0..options.max_iterations {
            report.iterations += 1;
            let mut largest = 0.0_f64;
            if options.energy {
                largest = largest.max(self.energy_sweep(&w, options.energy_stiffness));
            }
            if options.volume {
                largest = largest.max(self.volume_sweep(&w, options.volume_stiffness));
            }
            if options.enforce_cbr {
                largest = largest.max(self.cbr_sweep(material, &w)?);
            }
            report.max_correction = largest;
            if largest <= tol {
                report.converged = true;
                break;
            }
        }
        report.relative_volume_change = self.relative_volume_change();
        Ok(report)
    }

    /// Release: the external push is removed (nothing is held any more) and the model
    /// relaxes under its volume and strain-energy constraints, which pull it back toward
    /// its rest shape. Same as [`Lattice::relax`] with no held element; elements with zero
    /// inverse mass stay fixed (they are what pins the rigid motion).
    pub fn release<M: Material + ?Sized>(
        &mut self,
        material: &M,
        options: &RelaxOptions,
    ) -> Result<RelaxReport> {
        self.relax(material, &[], options)
    }

    fn volume_sweep(&mut self, w: &[f64], s: f64) -> f64 {
        let mut largest = 0.0_f64;
        for (t, &v0) in self.tets.iter().zip(&self.tet_rest_volume) {
            let p = [self.pos[t[0]], self.pos[t[1]], self.pos[t[2]], self.pos[t[3]]];
            let c = tet_volume(p) - v0;
            let (e1, e2, e3) = (sub(p[1], p[0]), sub(p[2], p[0]), sub(p[3], p[0]));
            let g1 = cross(e2, e3);
            let g2 = cross(e3, e1);
            let g3 = cross(e1, e2);
            let mut grad = [[0.0; 3], g1, g2, g3];
            for k in 1..4 {
                for a in 0..3 {
                    grad[k][a] /= 6.0;
                    grad[0][a] -= grad[k][a];
                }
            }
            let wt = [w[t[0]], w[t[1]], w[t[2]], w[t[3]]];
            largest = largest.max(project(&mut self.pos, t, wt, c, grad, s));
        }
        largest
    }

    fn energy_sweep(&mut self, w: &[f64], s: f64) -> f64 {
        let mut largest = 0.0_f64;
        for (t, l) in self.tets.iter().zip(&self.tet_rest_dist) {
            let p = [self.pos[t[0]], self.pos[t[1]], self.pos[t[2]], self.pos[t[3]]];
            let mut centre = [0.0; 3];
            for q in &p {
                for a in 0..3 {
                    centre[a] += 0.25 * q[a];
                }
            }
            let mut c = 0.0;
            let mut ken = [[0.0; 3]; 4];
            let mut mean = [0.0; 3];
            for k in 0..4 {
                let v = sub(p[k], centre);
                let d = norm(v);
                let kk = self.stiffness[t[k]];
                let e = d - l[k];
                c += 0.5 * kk * e * e;
                if d > 0.0 {
                    for a in 0..3 {
                        ken[k][a] = kk * e * v[a] / d;
                        mean[a] += 0.25 * ken[k][a];
                    }
                }
            }
            let mut grad = ken;
            for g in &mut grad {
                for a in 0..3 {
                    g[a] -= mean[a];
                }
            }
            let wt = [w[t[0]], w[t[1]], w[t[2]], w[t[3]]];
            largest = largest.max(project(&mut self.pos, t, wt, c, grad, s));
        }
        largest
    }

    fn cbr_sweep<M: Material + ?Sized>(&mut self, material: &M, w: &[f64]) -> Result<f64> {
        let mut largest = 0.0_f64;
        for a in 0..self.len() {
            let nb = self.neighbors[a];
            for b in nb {
                if b == NONE || (b as usize) < a {
                    continue;
                }
                let b = b as usize;
                let (wa, wb) = (w[a], w[b]);
                if wa + wb == 0.0 {
                    continue;
                }
                let cbr = material.cbr(a, b, self.rest_offset(a, b))?;
                let rel = sub(self.pos[b], self.pos[a]);
                if cbr.violation(rel) <= 0.0 {
                    continue;
                }
                let corr = sub(cbr.clamp(rel), rel);
                let (fa, fb) = (wa / (wa + wb), wb / (wa + wb));
                for ax in 0..3 {
                    self.pos[a][ax] -= fa * corr[ax];
                    self.pos[b][ax] += fb * corr[ax];
                }
                largest = largest.max(norm(corr));
            }
        }
        Ok(largest)
    }
}
