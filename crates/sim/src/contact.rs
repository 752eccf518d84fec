//! Rigid plates and frictionless unilateral contact with them.
//!
//! A [`Plate`] is a plane through `point` with a unit `normal` pointing towards the body;
//! it moves along its normal by `travel` over the load (`travel * lambda` at load factor
//! `lambda`). A vertex is in contact when it would pass through the plate: its normal
//! displacement is then prescribed so that it lies on the plate, while it slides freely
//! along it. A contact whose reaction turns tensile (the plate would have to pull) is
//! released. Each step iterates this active set until it no longer changes
//! ([`MAX_ACTIVE_SET_ITERATIONS`] at most).
//!
//! A contact's force is that of the state reached, not a sum of the steps' reactions:
//! `K u + P S - f` at the vertex (u the displacement from rest, P the pressure, f the
//! loads at the state), along the plate's normal, with the operator of the state as the
//! mode defines it (`docs/plates.md`).
//!
//! A change of the active set is a change of the constraints on the kept factorization:
//! one solve per new contact and a k x k refactor of the capacitance
//! ([`PrescribedSet`](fibfluid_linalg::PrescribedSet)), never a refactorization of the
//! stiffness blocks.

use fibfluid_geometry::Vec3;
use fibfluid_geometry::vec3::{add, dot, norm, scale, sub};
use serde::Serialize;

/// A rigid plate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plate {
    /// A point of the plate's plane at rest.
    pub point: Vec3,
    /// Unit normal pointing towards the body.
    pub normal: Vec3,
    /// Motion along the normal over the whole load (reached at load factor 1).
    pub travel: f64,
    /// `Some(F)`: driven by a force instead (N, at least 0; the finite-element method's
    /// timed runs): the plate moves along its normal so that its contact force on the body
    /// follows `F` times the load factor, and `travel` is 0.
    pub force: Option<f64>,
}

impl Plate {
    /// The plate with `normal` scaled to unit length; `None` for a zero or non-finite
    /// normal.
    pub fn new(point: Vec3, normal: Vec3, travel: f64) -> Option<Self> {
        let len = norm(normal);
        (len.is_finite() && len > 0.0 && point.iter().all(|c| c.is_finite()) && travel.is_finite())
            .then(|| Plate { point, normal: scale(normal, 1.0 / len), travel, force: None })
    }

    /// The plate at rest through `point` with unit `normal`, driven by a contact force of
    /// `force` N at the full load; `None` for a zero or non-finite normal or a force that
    /// is negative or not finite.
    pub fn driven_by(point: Vec3, normal: Vec3, force: f64) -> Option<Self> {
        let plate = Self::new(point, normal, 0.0)?;
        (force.is_finite() && force >= 0.0).then_some(Plate { force: Some(force), ..plate })
    }

    /// A point of the plane at load factor `lambda`.
    pub fn point_at(&self, lambda: f64) -> Vec3 {
        add(self.point, scale(self.normal, self.travel * lambda))
    }

    /// Signed distance of `x` from the plane at load factor `lambda`: positive on the
    /// body's side, negative through the plate.
    pub fn gap(&self, x: Vec3, lambda: f64) -> f64 {
        dot(self.normal, sub(x, self.point_at(lambda)))
    }
}

/// A vertex in contact with a plate, and the force the plate applies to it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Contact {
    /// Plate index.
    pub plate: usize,
    /// Vertex.
    pub vertex: usize,
    /// Force of the plate on the body along the plate's normal (positive: pushing the
    /// body), from the state: `K u + P S - f` at the vertex (see the module docs).
    pub force: f64,
}

impl Contact {
    /// The key of the contact's constraint in the kept factorization's constraint set.
    pub(crate) fn key(plate: usize, vertex: usize) -> u64 {
        ((plate as u64) << 40) | vertex as u64
    }
}

/// One plate's record over the steps (`report.json` `plates`).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct PlateRecord {
    /// Sum of the contact forces along the normal after each step (each the force of the
    /// state after the step, see [`Contact::force`]).
    pub force: Vec<f64>,
    /// Sum of the vertex areas |S_i| in contact after each step.
    pub contact_area: Vec<f64>,
    /// Vertices in contact after each step.
    pub contact_vertices: Vec<usize>,
    /// Distance to the next plate (or, for a single plate, the body's extent along the
    /// normal) after each step.
    pub gap: Vec<f64>,
    /// Active-set iterations of each step.
    pub active_set_iterations: Vec<usize>,
}

/// At most this many active-set iterations per step.
pub const MAX_ACTIVE_SET_ITERATIONS: usize = 50;

/// A vertex further than this fraction of the body's diagonal through a plate joins the
/// active set; no vertex ends further through a plate than this.
pub const PENETRATION_TOLERANCE: f64 = 1e-9;

/// A contact whose force is below minus this fraction of the largest contact force is
/// released (tensile).
pub const TENSION_TOLERANCE: f64 = 1e-9;

/// The rest-shape check of the plates against a body: `Err` names the first plate that
/// faces away from the body or already cuts it by more than `tolerance`.
pub fn check_plates(plates: &[Plate], rest: &[Vec3], tolerance: f64) -> Result<(), (usize, PlateProblem)> {
    let n = rest.len().max(1) as f64;
    let centroid = scale(rest.iter().fold([0.0; 3], |a, p| add(a, *p)), 1.0 / n);
    for (k, p) in plates.iter().enumerate() {
        if p.gap(centroid, 0.0) <= 0.0 {
            return Err((k, PlateProblem::FacesAway));
        }
        if let Some((v, g)) =
            rest.iter().enumerate().map(|(v, x)| (v, p.gap(*x, 0.0))).min_by(|a, b| a.1.total_cmp(&b.1))
            && g < -tolerance
        {
            return Err((k, PlateProblem::CutsBody { vertex: v, depth: -g }));
        }
    }
    Ok(())
}

/// Plates whose normals are opposite within this (the cosine of their angle below
/// `-1 + FACING_TOLERANCE`, about 2.5 degrees) face each other: the body lies in the slab
/// between them.
pub const FACING_TOLERANCE: f64 = 1e-3;

/// Two plates facing each other whose slab closes during the load: the body would have to
/// pass through one of them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlatesMeet {
    /// The first plate (0-based).
    pub first: usize,
    /// The second plate (0-based).
    pub second: usize,
    /// The load factor where the slab's width reaches zero.
    pub load_factor: f64,
    /// The slab's width at rest (m).
    pub gap: f64,
    /// How much the slab closes over the whole load (m).
    pub closing: f64,
}

/// The distance from plate `k` to the next plate (`k + 1`, cyclically) along `k`'s normal at
/// load factor `lambda`: the thickness a compression between them closes to (`report.json`
/// `gap`, `compression.png`); `None` for a single plate.
pub fn gap_to_next_plate(plates: &[Plate], k: usize, lambda: f64) -> Option<f64> {
    let (plate, other) = (&plates[k], plates.get((k + 1) % plates.len()).filter(|_| plates.len() > 1)?);
    Some(dot(plate.normal, sub(other.point_at(lambda), plate.point_at(lambda))).abs())
}

/// The first pair of plates facing each other ([`FACING_TOLERANCE`]) whose gap closes below
/// zero by load factor 1, from the plates alone: the slab's width is measured through
/// `centre` (the body's rest centroid) as the sum of its distances to both planes, linear in
/// the load factor.
pub fn plates_meet(plates: &[Plate], centre: Vec3) -> Option<PlatesMeet> {
    for (first, a) in plates.iter().enumerate() {
        for (second, b) in plates.iter().enumerate().skip(first + 1) {
            if dot(a.normal, b.normal) > -1.0 + FACING_TOLERANCE {
                continue;
            }
            let width = |lambda| a.gap(centre, lambda) + b.gap(centre, lambda);
            let (gap, end) = (width(0.0), width(1.0));
            if gap > 0.0 && end < 0.0 {
                let closing = gap - end;
                return Some(PlatesMeet { first, second, load_factor: gap / closing, gap, closing });
            }
        }
    }
    None
}

/// Refuses a model whose plates cross during the load ([`plates_meet`]), before anything is
/// built.
pub(crate) fn refuse_crossing_plates(model: &crate::Model) -> crate::Result<()> {
    if model.plates.len() < 2 {
        return Ok(());
    }
    let rest = model.rest_positions();
    let n = rest.len().max(1) as f64;
    let centre = scale(rest.iter().fold([0.0; 3], |a, p| add(a, *p)), 1.0 / n);
    match plates_meet(&model.plates, centre) {
        None => Ok(()),
        Some(m) => Err(crate::Error::PlatesMeet {
            scene: model.display_name(),
            first: m.first + 1,
            second: m.second + 1,
            load_factor: m.load_factor,
            gap: m.gap,
            closing: m.closing,
        }),
    }
}

/// What is wrong with a plate at rest.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PlateProblem {
    /// The body's centroid is behind the plate.
    FacesAway,
    /// A vertex is through the plate at rest.
    CutsBody {
        /// The deepest vertex.
        vertex: usize,
        /// How deep.
        depth: f64,
    },
}
