//! Frictionless rigid plates as unilateral contact on the embedded surface, sampled over
//! the surface's triangles (not at vertices only).
//!
//! Every surface triangle is sampled at most `h / 2` apart (the clamp's sampling,
//! [`crate::fixed_surface_samples`]), each sample standing for its share of the triangle's
//! area `a_s`. A sample at current position `x_s = X_s + sum_b w_b u_b` has the gap
//! `g_s = n . (x_s - p(t))` to a plate through `p(t)` with unit normal `n` (the body on the
//! side `g > 0`). Contact is an augmented Lagrangian (Uzawa) term per sample and plate:
//! `a_s / (2 beta) (max(0, lambda_s - beta g_s)^2 - lambda_s^2)` with
//! `beta = CONTACT_PENALTY * E / h` per unit area and `lambda_s` the contact pressure kept
//! from the previous augmentation. With `lambda = 0` it is a penalty; after each converged
//! solve `lambda_s <- max(0, lambda_s - beta g_s)`, which drives the penetration to zero.

use fibfluid_geometry::Vec3;
use fibfluid_geometry::vec3::{cross, dot, norm, sub};

use crate::clamp::{fixed_surface_samples, lattice_shares};
use crate::grid::SparseGrid;

/// The contact penalty, in units of `E / h` per unit area (as the clamp's,
/// [`crate::CLAMP_PENALTY`]); the augmentations remove the penetration it leaves.
pub const CONTACT_PENALTY: f64 = 100.0;

/// Augmentations stop when the deepest penetration is below this fraction of a cell...
pub const CONTACT_GAP_TOLERANCE: f64 = 1e-3;

/// ... or when an augmentation changes no plate's force by more than this fraction of the
/// largest. (A trilinear cell cannot flatten a curved surface onto a plane at every sample,
/// so on a curved body some samples keep a penetration the augmentations cannot remove;
/// the force has converged long before.)
pub const CONTACT_FORCE_TOLERANCE: f64 = 5e-3;

/// Augmentations at most (each one a converged Newton solve at the full load).
pub const MAX_AUGMENTATIONS: usize = 20;

/// A rigid, frictionless plane that moves with the load factor `t` from `start` (t = 0) to
/// `end` (t = 1); the body lies on the side its unit `normal` points to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidPlate {
    /// A point of the plane at load factor 0 (m).
    pub start: Vec3,
    /// The same point at load factor 1 (m).
    pub end: Vec3,
    /// Unit normal, pointing into the body's side.
    pub normal: Vec3,
    /// `Some(F)`: the plate is driven by a force, not by its travel: it moves along its
    /// normal (from `start`; `end` unused) so that its contact force on the body follows
    /// `F` (N, at least 0) times the load factor. Timed solves only
    /// ([`crate::HyperBody::solve_in_time`]).
    pub force: Option<f64>,
}

impl RigidPlate {
    /// The plane's point at load factor `t`.
    pub fn point_at(&self, t: f64) -> Vec3 {
        std::array::from_fn(|a| self.start[a] + t * (self.end[a] - self.start[a]))
    }

    /// The signed distance of `x` from the plane at load factor `t` (positive on the body's
    /// side).
    pub fn gap(&self, x: Vec3, t: f64) -> f64 {
        dot(self.normal, sub(x, self.point_at(t)))
    }
}

/// One surface sample: rest position, embedding and the area it stands for.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ContactSample {
    pub(crate) rest: Vec3,
    pub(crate) nodes: [usize; 8],
    pub(crate) weights: [f64; 8],
    pub(crate) area: f64,
    /// The surface triangle it samples (index into the grid's surface triangles).
    pub(crate) triangle: usize,
}

impl ContactSample {
    /// The sample's current position for node displacements `u`.
    pub(crate) fn position(&self, u: &[Vec3]) -> Vec3 {
        let mut x = self.rest;
        for b in 0..8 {
            for a in 0..3 {
                x[a] += self.weights[b] * u[self.nodes[b]][a];
            }
        }
        x
    }
}

/// The samples of every surface triangle of `grid` (see the module docs), except the
/// triangles held by the clamp (all three vertices fixed along some axis): the clamp holds
/// them, and their samples sitting on a support plate would switch in and out of contact
/// at every Newton iteration (the linear run leaves fixed vertices out of contact too).
pub(crate) fn surface_samples(grid: &SparseGrid, fixed: &[[bool; 3]]) -> Vec<ContactSample> {
    let pos = grid.surface_positions();
    let h = grid.cell_size();
    let mut out = Vec::new();
    for (triangle, t) in grid.surface_triangles().iter().enumerate() {
        if t.iter().all(|&v| fixed[v as usize].iter().any(|&f| f)) {
            continue;
        }
        let c = t.map(|v| pos[v as usize]);
        let area = 0.5 * norm(cross(sub(c[1], c[0]), sub(c[2], c[0])));
        let samples = fixed_surface_samples(c, h);
        let k = ((((8 * samples.len() + 1) as f64).sqrt() - 3.0) / 2.0).round() as usize;
        for (p, share) in samples.into_iter().zip(lattice_shares(k)) {
            if let Some(e) = grid.locate(p) {
                out.push(ContactSample {
                    rest: p,
                    nodes: e.nodes,
                    weights: e.weights,
                    area: share * area,
                    triangle,
                });
            }
        }
    }
    out
}

/// The smoothing of the contact law, in units of `E`: the pressure `max(0, x)` of
/// `x = lambda - beta g` is rounded to a quadratic over `|x| <= CONTACT_SMOOTHING * E`, so the
/// energy is twice differentiable and Newton converges quadratically when a sample sits at
/// the edge of the contact zone (a kinked law makes it chatter there). A sample just out of
/// contact then carries at most `CONTACT_SMOOTHING * E / 4`.
pub const CONTACT_SMOOTHING: f64 = 1e-2;

/// The augmented-Lagrangian contact law of one sample (see the module docs).
#[derive(Debug, Clone, Copy)]
pub(crate) struct ContactLaw {
    /// The penalty `beta`, per unit area (Pa/m).
    pub(crate) beta: f64,
    /// Half the width of the smoothed zone, in pressure (Pa).
    pub(crate) width: f64,
}

impl ContactLaw {
    /// `x = lambda - beta g` for a multiplier and a gap.
    pub(crate) fn argument(&self, multiplier: f64, gap: f64) -> f64 {
        multiplier - self.beta * gap
    }

    /// The contact pressure (Pa): the smoothed `max(0, x)`.
    pub(crate) fn pressure(&self, x: f64) -> f64 {
        let e = self.width;
        if x >= e {
            x
        } else if x > -e {
            (x + e) * (x + e) / (4.0 * e)
        } else {
            0.0
        }
    }

    /// `d pressure / dx`.
    pub(crate) fn slope(&self, x: f64) -> f64 {
        let e = self.width;
        if x >= e {
            1.0
        } else if x > -e {
            (x + e) / (2.0 * e)
        } else {
            0.0
        }
    }

    /// The energy of a sample of `area` (J): `area / (2 beta) (Q(x) - lambda^2)` with
    /// `Q' = 2 pressure`, so that its derivative along the gap is `-area * pressure`.
    pub(crate) fn energy(&self, area: f64, multiplier: f64, x: f64) -> f64 {
        let e = self.width;
        let q = if x >= e {
            x * x + e * e / 3.0
        } else if x > -e {
            (x + e).powi(3) / (6.0 * e)
        } else {
            0.0
        };
        area / (2.0 * self.beta) * (q - multiplier * multiplier)
    }
}

/// Refuses a plate with a non-finite position, end or normal ([`FemError::NonFinite`]).
pub(crate) fn check_plates(plates: &[RigidPlate]) -> crate::error::Result<()> {
    if plates.iter().any(|p| p.start.iter().chain(&p.end).chain(&p.normal).any(|v| !v.is_finite())) {
        return Err(crate::error::FemError::NonFinite { what: "plate" });
    }
    if plates.iter().filter_map(|p| p.force).any(|f| !(f.is_finite() && f >= 0.0)) {
        return Err(crate::error::FemError::NonFinite { what: "plate force (finite, at least 0 N)" });
    }
    Ok(())
}
