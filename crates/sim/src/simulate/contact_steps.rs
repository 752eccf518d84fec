//! Plate contact inside a step: the active set, contact forces and plate records.

use std::time::Instant;

use fibfluid_assembly::{Loads, load_vector};
use fibfluid_geometry::Vec3;
use fibfluid_geometry::vec3::{dot, norm, scale, sub};

use super::core::Simulation;
use super::factored::*;
use crate::Result;
use crate::choices::{ForceTiming, Mode};
use crate::contact::{Contact, PENETRATION_TOLERANCE, TENSION_TOLERANCE};
use crate::stages::names;

impl Simulation {
    /// The contacts for the next solves: their constraint rows (free axes of the vertex,
    /// the plate's normal) and the normal displacement that puts each vertex on its
    /// plate at load factor `to`.
    pub(super) fn set_contacts(&mut self, active: &[Contact], to: f64) {
        self.contact.values = active
            .iter()
            .map(|c| -self.model.plates[c.plate].gap(self.state.positions[c.vertex], to))
            .collect();
        self.contact.active = active.iter().map(|c| (c.plate, c.vertex)).collect();
    }

    /// Sets each contact's force from the current state: the force on the body at the
    /// contact's vertex, `K u + P S - f` (u the displacement from rest, P the pressure, f
    /// the loads at the state), over the vertex's free axes, along the plate's normal.
    /// This is minus the reaction that holds the vertex on the plate, whatever path the
    /// steps took. `K` and `S` are the operator of the state as the mode defines it:
    /// paper mode's rest operator (the one it factors), refresh mode's rest `K` with `S`
    /// of the current shape, nonlinear mode's `K` and `S` assembled on the current shape.
    pub(super) fn contact_forces(&mut self, contacts: &mut [Contact]) -> Result<()> {
        if contacts.is_empty() {
            return Ok(());
        }
        let s = &self.state.positions;
        let (n, axes) = (s.len(), self.axes());
        let current = self.log.time(names::AREAS, || self.body.boundary.vertex_area_vectors(s));
        let reassembled = match self.model.solver.mode {
            Mode::Nonlinear => {
                Some(self.log.time(names::REASSEMBLY, || assemble_on(&self.model, &self.body, s, &current))?)
            }
            Mode::Paper | Mode::Refresh => None,
        };
        let (system, border) = match (self.model.solver.mode, &reassembled) {
            (Mode::Paper, _) => (&self.factored.system, &self.factored.border_areas),
            (_, Some(system)) => (system, &current),
            (_, None) => (&self.factored.system, &current),
        };
        let u: Vec<Vec3> = s.iter().zip(&self.body.rest).map(|(p, r)| sub(*p, *r)).collect();
        let (lambda, last) = (self.state.load_factor, self.state.last_forces);
        let forces: Vec<(usize, Vec3)> = self
            .model
            .load
            .forces
            .iter()
            .map(|f| {
                let k = match f.timing {
                    ForceTiming::Ramp => lambda,
                    ForceTiming::Last => last,
                };
                (f.vertex, scale(f.value, k))
            })
            .collect();
        let loads = Loads {
            acceleration: scale(self.model.load.gravity, lambda),
            down: Some(self.model.load.gravity),
            density: self.model.material.density(),
            forces: &forces,
        };
        let f = load_vector(axes, s, &current, &loads)?;
        let pressure = self.state.pressure;
        for c in contacts.iter_mut() {
            let normal = self.model.plates[c.plate].normal;
            c.force = (0..axes)
                .filter(|&a| self.model.constraints.get(c.vertex, a).is_none())
                .map(|a| {
                    let own = system.stiffness_force(c.vertex, a, &u) + pressure * border[c.vertex][a];
                    normal[a] * (own - f[a * n + c.vertex])
                })
                .sum();
        }
        Ok(())
    }

    /// The next active set after a step: contacts turned tensile are released, vertices
    /// through a plate join. Returns whether it changed, the new set and the released
    /// (plate, vertex) pairs.
    pub(super) fn update_active_set(
        &self,
        active: &[Contact],
        to: f64,
    ) -> (bool, Vec<Contact>, Vec<(usize, usize)>) {
        let largest = active.iter().map(|c| c.force.abs()).fold(0.0, f64::max);
        let (keep, drop): (Vec<Contact>, Vec<Contact>) =
            active.iter().partition(|c| c.force >= -TENSION_TOLERANCE * largest.max(f64::MIN_POSITIVE));
        let mut next = keep;
        let depth = PENETRATION_TOLERANCE * self.body.diagonal;
        let axes = self.axes();
        for (k, plate) in self.model.plates.iter().enumerate() {
            for (v, x) in self.state.positions.iter().enumerate() {
                let fully_fixed = (0..axes).all(|c| self.model.constraints.get(v, c).is_some());
                if fully_fixed || active.iter().any(|c| c.plate == k && c.vertex == v) {
                    continue;
                }
                if plate.gap(*x, to) < -depth {
                    next.push(Contact { plate: k, vertex: v, force: 0.0 });
                }
            }
        }
        let released: Vec<(usize, usize)> = drop.iter().map(|c| (c.plate, c.vertex)).collect();
        (next.len() != active.len() || !released.is_empty(), next, released)
    }

    /// Appends this step's force, contact area, contacts and gap to each plate's record.
    pub(super) fn record_plates(&mut self, iterations: usize) {
        let areas = self.body.boundary.vertex_area_vectors(&self.state.positions);
        let lambda = self.state.load_factor;
        let plates = &self.model.plates;
        for (k, plate) in plates.iter().enumerate() {
            let mine: Vec<&Contact> = self.state.contacts.iter().filter(|c| c.plate == k).collect();
            let gap = match crate::contact::gap_to_next_plate(plates, k, lambda) {
                Some(gap) => gap,
                None => {
                    let h: Vec<f64> = self.state.positions.iter().map(|x| dot(plate.normal, *x)).collect();
                    h.iter().copied().fold(f64::MIN, f64::max) - h.iter().copied().fold(f64::MAX, f64::min)
                }
            };
            let r = &mut self.contact.records[k];
            r.force.push(mine.iter().fold(0.0, |f, c| f + c.force));
            r.contact_area.push(mine.iter().fold(0.0, |a, c| a + norm(areas[c.vertex])));
            r.contact_vertices.push(mine.len());
            r.gap.push(gap);
            r.active_set_iterations.push(iterations);
        }
    }

    /// Makes the factorization's contact constraints those of the active contacts.
    pub(super) fn sync_contact_set(&mut self) -> Result<()> {
        let n = self.state.positions.len();
        let axes = self.axes();
        let wanted: Vec<u64> = self.contact.active.iter().map(|&(p, v)| Contact::key(p, v)).collect();
        let f = &mut self.factored;
        for key in f.contact.keys().to_vec().into_iter().filter(|k| !wanted.contains(k)) {
            f.contact.remove_key(key)?;
        }
        let start = Instant::now();
        let rows: Vec<(u64, Vec<(usize, f64)>)> = self
            .contact
            .active
            .iter()
            .map(|&(p, v)| {
                let normal = self.model.plates[p].normal;
                let row = (0..axes)
                    .filter(|&c| self.model.constraints.get(v, c).is_none())
                    .map(|c| (c * n + v, normal[c]))
                    .collect();
                (Contact::key(p, v), row)
            })
            .collect();
        f.contact.add_rows(f.factorization.as_ref(), &rows)?;
        self.log.add(names::CONTACT, start.elapsed().as_secs_f64());
        Ok(())
    }
}
