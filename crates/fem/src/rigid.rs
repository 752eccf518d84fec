//! Rigid-body modes the constraints leave free, found from the constraints alone (before
//! anything is assembled or factored).
//!
//! A rigid motion of the body is `u(x) = t + w x (x - c)`: three translations and three
//! rotations about the centroid `c` of the surface. It costs no strain energy, so the
//! stiffness is singular along it unless a fixed degree of freedom forbids it. Fixing axis
//! `a` of vertex `v` asks `u(x_v)_a = 0`: one linear row in the six coefficients
//! `(t, w)`, with the rotations scaled by the body's size `L` so that all six columns have
//! the same unit. With `R` the rows of every fixed degree of freedom, the free rigid modes
//! span the null space of `G = R' R` (6 x 6, symmetric): its eigenvectors whose eigenvalue
//! is below [`RIGID_MODE_TOLERANCE`] times the largest (or all six with nothing fixed).
//! The eigenvalues come from faer's self-adjoint eigendecomposition.

use faer::{Mat, Side};
use fibfluid_geometry::Vec3;
use fibfluid_geometry::vec3::{cross, norm};

use crate::error::{FemError, Result};

/// An eigenvalue of `G` below this fraction of the largest counts as zero: the mode is
/// free. Points fixed on a line leave the rotation about it free exactly (0); a rotation
/// held only by a fixed point at distance `d` from its axis has `(d / L)^2` per point, so
/// the tolerance allows bodies with fixed patches down to about 1e-5 of their size.
pub const RIGID_MODE_TOLERANCE: f64 = 1e-10;

/// A rigid motion the constraints leave free.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RigidMode {
    /// A translation along a unit direction.
    Translation {
        /// The direction.
        direction: Vec3,
    },
    /// A rotation about an axis (unit direction) through a point.
    Rotation {
        /// The axis' direction.
        axis: Vec3,
        /// A point on the axis.
        through: Vec3,
    },
}

impl std::fmt::Display for RigidMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let v = |a: &Vec3| format!("({:.3}, {:.3}, {:.3})", a[0], a[1], a[2]);
        match self {
            RigidMode::Translation { direction } => write!(f, "a translation along {}", v(direction)),
            RigidMode::Rotation { axis, through } => {
                write!(f, "a rotation about the axis {} through {}", v(axis), v(through))
            }
        }
    }
}

/// The rigid modes that `fixed` (per vertex, the fixed axes) leaves free on a body with
/// rest positions `rest` (empty: the constraints hold the body). Length mismatches are a
/// programming error.
///
/// # Panics
/// If `fixed` and `rest` differ in length.
#[track_caller]
pub fn free_rigid_modes(rest: &[Vec3], fixed: &[[bool; 3]]) -> Vec<RigidMode> {
    assert_eq!(rest.len(), fixed.len(), "one entry of fixed axes per vertex");
    let (lo, hi) = fibfluid_geometry::bounding_box(rest);
    let size = fibfluid_geometry::vec3::dist(lo, hi).max(f64::MIN_POSITIVE);
    let held: Vec<usize> = (0..rest.len()).filter(|&v| fixed[v].iter().any(|&f| f)).collect();
    let centre_of = |vs: &mut dyn Iterator<Item = usize>| {
        let (mut c, mut n) = ([0.0; 3], 0.0);
        for v in vs {
            (0..3).for_each(|a| c[a] += rest[v][a]);
            n += 1.0;
        }
        if n > 0.0 { c.map(|x| x / n) } else { c }
    };
    let centre =
        if held.is_empty() { centre_of(&mut (0..rest.len())) } else { centre_of(&mut held.iter().copied()) };
    let mut g = Mat::<f64>::zeros(6, 6);
    for &v in &held {
        let d: Vec3 = std::array::from_fn(|a| (rest[v][a] - centre[a]) / size);
        for a in (0..3).filter(|&a| fixed[v][a]) {
            // u_a of each mode: translations e_k, rotations (e_k x d)_a.
            let mut row = [0.0; 6];
            row[a] = 1.0;
            for k in 0..3 {
                let mut e = [0.0; 3];
                e[k] = 1.0;
                row[3 + k] = cross(e, d)[a];
            }
            for i in 0..6 {
                for j in 0..6 {
                    g[(i, j)] += row[i] * row[j];
                }
            }
        }
    }
    free_modes_of(&g, centre, size)
}

/// The eigenvectors of `g` with a (relatively) zero eigenvalue, as rigid modes.
fn free_modes_of(g: &Mat<f64>, centre: Vec3, size: f64) -> Vec<RigidMode> {
    let Ok(eigen) = g.self_adjoint_eigen(Side::Lower) else {
        // faer's eigendecomposition of a finite 6 x 6 matrix does not fail; without it, no
        // mode is reported (the factorization's own check still stands).
        return vec![];
    };
    let values: Vec<f64> = (0..6).map(|i| eigen.S()[i]).collect();
    let largest = values.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    (0..6)
        .filter(|&i| largest == 0.0 || values[i] <= RIGID_MODE_TOLERANCE * largest)
        .map(|i| {
            let u = eigen.U();
            let t: Vec3 = std::array::from_fn(|a| u[(a, i)]);
            let w: Vec3 = std::array::from_fn(|a| u[(3 + a, i)]);
            if norm(w) >= norm(t) {
                // u = t + (w / L) x (x - c) vanishes on the axis through c + L (w x t) / |w|^2.
                let shift = cross(w, t).map(|x| size * x / (norm(w) * norm(w)));
                RigidMode::Rotation { axis: unit(w), through: std::array::from_fn(|a| centre[a] + shift[a]) }
            } else {
                RigidMode::Translation { direction: unit(t) }
            }
        })
        .collect()
}

/// Refuses constraints that leave a rigid mode free ([`FemError::RigidModeFree`]), naming
/// the first such mode.
pub fn check_rigid_modes(rest: &[Vec3], fixed: &[[bool; 3]]) -> Result<()> {
    match free_rigid_modes(rest, fixed).first() {
        None => Ok(()),
        Some(&mode) => {
            let fixed_vertices = fixed.iter().filter(|f| f.iter().any(|&x| x)).count();
            Err(FemError::RigidModeFree { mode, fixed_vertices })
        }
    }
}

fn unit(a: Vec3) -> Vec3 {
    let n = norm(a);
    if n > 0.0 { a.map(|x| x / n) } else { a }
}

/// The grid of a surface at `resolution`, after refusing (from the constraints alone, before
/// anything is built) a `fixed` that leaves a rigid motion free. A `fixed` of the wrong
/// length is left to the body's own check, which names it.
pub(crate) fn checked_grid(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    fixed: &[[bool; 3]],
    resolution: usize,
) -> crate::error::Result<crate::grid::SparseGrid> {
    if fixed.len() == positions.len() {
        check_rigid_modes(positions, fixed)?;
    }
    crate::grid::SparseGrid::from_surface(positions, triangles, resolution)
}
