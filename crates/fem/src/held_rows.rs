//! Constraint rows of held surface vertices: how a vertex is held ([`FemHold`]), its rows
//! over the free dofs of its cell ([`constraint_rows`]), and what every way of answering
//! them shares (the surface-only answer, the refined multipliers of a ridged capacitance,
//! the check that dependent rows are met).

use fibfluid_geometry::Vec3;
use fibfluid_linalg::RowCapacitance;

use crate::assemble::FIXED;
use crate::error::{FemError, Result};
use crate::grid::Embedded;

/// A target below this (relative to the largest target, or absolute when all are 0) counts
/// as 0 on an axis whose nodes are all fixed.
const ZERO_TARGET: f64 = 1e-12;

/// How a vertex is held.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FemHold {
    /// Moved exactly to this displacement (every axis).
    At(Vec3),
    /// Frictionless contact: the displacement along the unit `normal` is `along`; the
    /// vertex is free across the normal and its reaction is along it.
    Along {
        /// Unit direction.
        normal: Vec3,
        /// Displacement along `normal`.
        along: f64,
    },
}

impl FemHold {
    /// The rows of the hold: (direction, target).
    pub(crate) fn rows(&self) -> Vec<(Vec3, f64)> {
        match *self {
            FemHold::At(d) => (0..3)
                .map(|a| {
                    let mut e = [0.0; 3];
                    e[a] = 1.0;
                    (e, d[a])
                })
                .collect(),
            FemHold::Along { normal, along } => vec![(normal, along)],
        }
    }

    pub(crate) fn values(&self) -> Vec<f64> {
        match *self {
            FemHold::At(d) => d.to_vec(),
            FemHold::Along { normal, along } => vec![normal[0], normal[1], normal[2], along],
        }
    }
}

/// Refinements of a ridged capacitance solve against the matrix without the ridge. A
/// ridge `delta` leaves a fraction `delta / mu` of a consistent gap along an eigenvalue
/// `mu` of the capacitance: about 1e-6 when the tangent carries a strong hold penalty
/// (its held compliance is small), nanometres on a millimetre gap; each refinement
/// multiplies it by that fraction again.
pub(crate) const RIDGE_REFINEMENTS: usize = 3;

/// Largest constraint residual (relative to the largest target, at least 1) accepted after
/// the ridge: above it the holds contradict each other.
pub(crate) const CONSTRAINT_TOLERANCE: f64 = 1e-9;

/// One constraint row: a held vertex's displacement along a direction as a combination of
/// free dofs.
pub(crate) struct Row {
    pub(crate) vertex: usize,
    pub(crate) direction: Vec3,
    pub(crate) target: f64,
    pub(crate) entries: Vec<(usize, f64)>,
}

impl Row {
    /// The row's identity.
    pub(crate) fn key(&self) -> RowKey {
        (self.vertex, self.direction.map(f64::to_bits))
    }
}

/// A constraint row's identity: its vertex and direction (bit for bit).
pub(crate) type RowKey = (usize, [u64; 3]);

/// The surface-only solution of a held system (`crate::held_system::HeldSystem::solve_surface`).
pub(crate) struct SurfaceSolve {
    /// Displacement of every surface vertex added to the base state.
    pub(crate) surface: Vec<Vec3>,
    /// Per hold (in the order given), the force its holder puts on the body.
    pub(crate) reactions: Vec<Vec3>,
    /// Penalized rows that no hold covers (their springs stay in the answer).
    pub(crate) uncovered: usize,
}

/// The multipliers of `capacitance r = gap`; a ridged capacitance's refined
/// [`RIDGE_REFINEMENTS`] times against the matrix without the ridge.
pub(crate) fn refined_multipliers(capacitance: &RowCapacitance, ridged: bool, gap: &[f64]) -> Vec<f64> {
    capacitance.refined_multipliers(gap, if ridged { RIDGE_REFINEMENTS } else { 0 })
}

/// Checks that the values `met` the rows take after a ridged update equal their targets
/// (else the holds contradict each other).
pub(crate) fn check_met(rows: &[Row], met: &[f64]) -> Result<()> {
    let scale = rows.iter().fold(1.0_f64, |a, r| a.max(r.target.abs()));
    match rows.iter().zip(met).find(|(r, m)| (*m - r.target).abs() > CONSTRAINT_TOLERANCE * scale) {
        Some((r, _)) => Err(FemError::DependentHolds { vertex: r.vertex }),
        None => Ok(()),
    }
}

/// The constraint rows of `holds`, skipping rows carried only by fixed nodes (whose
/// target must then be 0).
pub(crate) fn constraint_rows(
    embedding: &[Embedded],
    free: &[usize],
    holds: &[(usize, FemHold)],
) -> Result<Vec<Row>> {
    let scale = holds.iter().flat_map(|h| h.1.values()).fold(0.0_f64, |a, b| a.max(b.abs()));
    let mut rows = Vec::new();
    for (k, &(v, hold)) in holds.iter().enumerate() {
        let e =
            embedding.get(v).ok_or(FemError::VertexOutOfRange { vertex: v, vertices: embedding.len() })?;
        if hold.values().iter().any(|x| !x.is_finite()) {
            return Err(FemError::NonFinite { what: "held displacement" });
        }
        if holds[..k].iter().any(|h| h.0 == v) {
            return Err(FemError::DependentHolds { vertex: v });
        }
        for (direction, target) in hold.rows() {
            let mut entries: Vec<(usize, f64)> = Vec::new();
            for b in (0..8).filter(|&b| e.weights[b] > 0.0) {
                for a in (0..3).filter(|&a| direction[a] != 0.0) {
                    let dof = free[3 * e.nodes[b] + a];
                    if dof != FIXED {
                        entries.push((dof, e.weights[b] * direction[a]));
                    }
                }
            }
            if entries.is_empty() {
                if target.abs() > ZERO_TARGET * scale.max(1.0) {
                    let axis = (0..3).max_by(|&a, &b| direction[a].abs().total_cmp(&direction[b].abs()));
                    return Err(FemError::HeldOnFixed { vertex: v, axis: axis.unwrap_or(0) });
                }
                continue;
            }
            rows.push(Row { vertex: v, direction, target, entries });
        }
    }
    Ok(rows)
}
