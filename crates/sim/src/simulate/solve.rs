//! The operator of a step (border refresh or refactorization), the volume correction and
//! the solves.

use std::time::Instant;

use fibfluid_assembly::{Loads, load_vector};
use fibfluid_geometry::Vec3;
use fibfluid_geometry::vec3::{add, dot, norm, scale};
use fibfluid_linalg::{FactorizationExt, PrescribedSet};

use super::core::Simulation;
use super::factored::*;
use crate::Result;
use crate::choices::Mode;
use crate::contact::Contact;
use crate::model::{VOLUME_NEWTON_ITERATIONS, VOLUME_TOLERANCE};
use crate::stages::names;

impl Simulation {
    /// Makes the factored operator describe shape `s` as the mode requires; returns the
    /// volume target for the last row.
    pub(super) fn prepare_operator(&mut self, s: &[Vec3]) -> Result<f64> {
        let mode = self.model.solver.mode;
        if mode == Mode::Paper {
            return Ok(0.0);
        }
        // The held and contact sets were built on the operator about to change.
        self.factored.held = Holds::default();
        self.factored.contact = PrescribedSet::new();
        let areas = self.log.time(names::AREAS, || self.body.boundary.vertex_area_vectors(s));
        match mode {
            Mode::Paper => unreachable!("handled above"),
            Mode::Refresh => {
                let f = &mut self.factored;
                let border = f.system.border_for(&areas);
                let start = Instant::now();
                f.system.matrix.set_border(&border);
                f.factorization.set_border(&border)?;
                if let Some(c) = &mut f.coupled {
                    let border = c.system.border_for(&areas);
                    c.factor.set_border(border.clone())?;
                    c.system.border = border;
                }
                // A dense backend refactors the whole matrix for a new border: say so.
                if f.factorization.border_update_refactors() {
                    self.counters.factorizations += 1;
                    self.log.add(names::FACTORIZATION, start.elapsed().as_secs_f64());
                } else {
                    self.log.add(names::BORDER, start.elapsed().as_secs_f64());
                }
            }
            Mode::Nonlinear => {
                let mut system =
                    self.log.time(names::REASSEMBLY, || assemble_on(&self.model, &self.body, s, &areas))?;
                let f = &mut self.factored;
                let start = Instant::now();
                f.factorization = f.solver.factorize_in_place(&mut system.matrix, &f.options)?;
                self.log.add(names::FACTORIZATION, start.elapsed().as_secs_f64());
                self.counters.factorizations += 1;
                f.system = system;
                if self.factored.coupled.is_some() {
                    self.refactor_coupled(s, &areas)?;
                }
            }
        }
        let start = Instant::now();
        let target = self.volume_target(s, &areas);
        self.log.add(names::VOLUME, start.elapsed().as_secs_f64());
        self.factored.border_areas = areas;
        Ok(target)
    }

    /// Nonlinear mode with projected fibers: the coupled operator assembled on shape `s`
    /// (its fibers' directions and lengths, its border `areas`) and factored again.
    pub(super) fn refactor_coupled(&mut self, s: &[Vec3], areas: &[Vec3]) -> Result<()> {
        // The old matrix and factor go first: the plan counts one of each.
        self.factored.coupled = None;
        let options = self.factored.options;
        let coupled =
            Coupled::build(&self.model, &self.body, (s, areas), &options, &mut self.log, names::REASSEMBLY)?;
        self.counters.factorizations += 1;
        self.factored.coupled = Some(coupled);
        Ok(())
    }

    /// The volume row's target on shape `s` with border `areas`: the row asks
    /// `sum S_i . u_i = t`, while the volume changes by `sum G_i . u_i` to first order with
    /// `G` the exact gradient, parallel to `S` (`G = S / (3C)` on a surface, `S / (2C)` on a
    /// polygon). So `t = (V0 - V) / r` with `r = sum |G_i| / sum |S_i|`.
    pub(super) fn volume_target(&self, s: &[Vec3], areas: &[Vec3]) -> f64 {
        let v = self.body.boundary.volume(s);
        let sum_g: f64 = self.body.boundary.volume_gradient(s).iter().map(|g| norm(*g)).sum();
        let sum_s: f64 = areas.iter().map(|a| norm(*a)).sum();
        let r = if sum_s > 0.0 && sum_g > 0.0 { sum_g / sum_s } else { 1.0 };
        (self.body.volume0 - v) / r
    }

    /// Pulls the volume back to V0 after a step (refresh and nonlinear modes) with one
    /// solve: the response `w` of the current factorization to a unit volume target (no
    /// load) is the direction every correction solve would move along, so the volume is
    /// restored by a scalar Newton iteration on `V(s + alpha w) = V0` (volume and gradient
    /// evaluations only, at most [`VOLUME_NEWTON_ITERATIONS`]), to [`VOLUME_TOLERANCE`].
    pub(super) fn correct_volume(&mut self) -> Result<()> {
        let v0 = self.body.volume0;
        if (self.volume() / v0 - 1.0).abs() <= VOLUME_TOLERANCE {
            return Ok(());
        }
        let open = self.log.begin(names::VOLUME_CORRECTION);
        let zero = vec![0.0; self.axes() * self.state.positions.len()];
        let solved = self.solve(&zero, 1.0, 0.0, false);
        self.log.end(open);
        let xw = solved?;
        let (w, pw) = self.factored.split(&xw);
        let start = self.state.positions.clone();
        let along = |alpha: f64| -> Vec<Vec3> {
            start.iter().zip(&w).map(|(p, d)| add(*p, scale(*d, alpha))).collect()
        };
        let mut alpha = 0.0;
        for _ in 0..VOLUME_NEWTON_ITERATIONS {
            let p = along(alpha);
            let f = self.body.boundary.volume(&p) - v0;
            if (f / v0).abs() <= VOLUME_TOLERANCE {
                break;
            }
            let slope: f64 =
                self.body.boundary.volume_gradient(&p).iter().zip(&w).map(|(g, d)| dot(*g, *d)).sum();
            if !(slope.abs() > 0.0) {
                break;
            }
            alpha -= f / slope;
        }
        self.state.positions = along(alpha);
        self.state.pressure += alpha * pw;
        Ok(())
    }

    /// Load increment on shape `s`: `rho (da . down) h_i S_i` plus the point-force
    /// increments, through [`load_vector`]. Paper mode keeps the rest border, so the load
    /// needs S of `s`; the other modes have just made the border describe `s`.
    pub(super) fn load_increment(
        &mut self,
        s: &[Vec3],
        da: Vec3,
        forces: &[(usize, Vec3)],
    ) -> Result<Vec<f64>> {
        let loads = Loads {
            acceleration: da,
            down: Some(self.model.load.gravity),
            density: self.model.material.density(),
            forces,
        };
        let computed;
        let areas: &[Vec3] = if self.model.solver.mode == Mode::Paper && loads.has_hydrostatic() {
            computed = self.log.time(names::AREAS, || self.body.boundary.vertex_area_vectors(s));
            &computed
        } else {
            &self.factored.border_areas
        };
        let axes = self.axes();
        Ok(self.log.time(names::LOADS, || load_vector(axes, s, areas, &loads))?)
    }

    /// One solve with the current factorization; with active contacts, under their
    /// constraints (`step`: each contact's vertex moves onto its plate; otherwise it
    /// keeps its normal position). The contacts' forces are not taken from the
    /// multipliers: see [`contact_forces`](Self::contact_forces).
    pub(super) fn solve(
        &mut self,
        b: &[f64],
        target: f64,
        prescribed_scale: f64,
        step: bool,
    ) -> Result<Vec<f64>> {
        if !self.contact.active.is_empty() {
            self.sync_contact_set()?;
        }
        let f = &self.factored;
        if let Some(c) = &f.coupled {
            let rhs = c.system.rhs(b, target, &f.border_areas, prescribed_scale);
            let start = Instant::now();
            let sol = c.factor.solve(&rhs)?;
            self.log.add(names::SOLVE, start.elapsed().as_secs_f64());
            self.counters.residual_max = self.counters.residual_max.max(sol.relative_residual);
            self.counters.refinement_steps_max = self.counters.refinement_steps_max.max(sol.refinement_steps);
            self.counters.solves += 1;
            return Ok(sol.x);
        }
        let rhs = f.system.rhs(b, target, &f.border_areas, prescribed_scale);
        let start = Instant::now();
        let x = if self.contact.active.is_empty() {
            let sol = f.factorization.solve(&rhs)?;
            self.counters.residual_max = self.counters.residual_max.max(sol.relative_residual);
            self.counters.refinement_steps_max = self.counters.refinement_steps_max.max(sol.refinement_steps);
            sol.x
        } else {
            // The set's order is its insertion order; the values follow it.
            let keys = f.contact.keys();
            let order: Vec<usize> = self
                .contact
                .active
                .iter()
                .map(|&(p, v)| keys.iter().position(|&k| k == Contact::key(p, v)).expect("synced"))
                .collect();
            let mut values = vec![0.0; keys.len()];
            if step {
                for (i, &j) in order.iter().enumerate() {
                    values[j] = self.contact.values[i];
                }
            }
            let sol = f.contact.solve(f.factorization.as_ref(), &rhs, &values)?;
            self.counters.residual_max = self.counters.residual_max.max(sol.relative_residual);
            sol.x
        };
        self.log.add(names::SOLVE, start.elapsed().as_secs_f64());
        self.counters.solves += 1;
        Ok(x)
    }
}
