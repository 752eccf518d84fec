//! The [`Simulation`] and what it lets a caller read.

use std::time::Instant;

use fibfluid_assembly::System;
use fibfluid_geometry::{FiberSet, Vec3};
use fibfluid_linalg::Factorization;

use super::factored::*;
use super::state::*;
use crate::contact::PlateRecord;
use crate::guards::GuardWarning;
use crate::model::Model;
use crate::plan::Plan;
use crate::stages::StageLog;

/// A scene being simulated.
pub struct Simulation {
    pub(super) model: Model,
    pub(super) plan: Plan,
    pub(super) body: BodyShape,
    pub(super) state: State,
    pub(super) factored: Factored,
    pub(super) counters: Counters,
    pub(super) stats: StepStats,
    pub(super) warnings: Vec<GuardWarning>,
    /// Plate contact: the active contacts of the current solves and each plate's record.
    pub(super) contact: PlateContact,
    pub(super) calibration: Option<crate::fit::Calibration>,
    pub(super) log: StageLog,
    pub(super) started: Instant,
}

impl Simulation {
    /// The calibration of the fiber modulus against the FEM, when the scene asked for one
    /// (it gave only `[tissue]`).
    pub fn calibration(&self) -> Option<&crate::fit::Calibration> {
        self.calibration.as_ref()
    }

    /// The model being simulated.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The plan this simulation follows.
    pub fn plan(&self) -> &Plan {
        &self.plan
    }

    /// The body: boundary, fibers, rest shape.
    pub fn body(&self) -> &BodyShape {
        &self.body
    }

    /// The current state: positions, pressure, load factor.
    pub fn state(&self) -> &State {
        &self.state
    }

    /// Current positions.
    pub fn positions(&self) -> &[Vec3] {
        &self.state.positions
    }

    /// Rest positions.
    pub fn rest_positions(&self) -> &[Vec3] {
        &self.body.rest
    }

    /// Accumulated pressure change.
    pub fn pressure(&self) -> f64 {
        self.state.pressure
    }

    /// Volume (area for a polygon) of the rest shape.
    pub fn volume_initial(&self) -> f64 {
        self.body.volume0
    }

    /// Volume of the current shape.
    pub fn volume(&self) -> f64 {
        self.body.boundary.volume(&self.state.positions)
    }

    /// The kept fibers.
    pub fn fibers(&self) -> &FiberSet {
        &self.body.fibers
    }

    /// Whether the body was found convex.
    pub fn convex(&self) -> bool {
        self.body.convex
    }

    /// The assembled system currently factored. With projected fibers this is the paper's
    /// per-axis operator on the same body, not the coupled one the steps solve.
    pub fn system(&self) -> &System {
        &self.factored.system
    }

    /// The current factorization (with projected fibers: of [`system`](Self::system), the
    /// paper's operator).
    pub fn factorization(&self) -> &dyn Factorization {
        self.factored.factorization.as_ref()
    }

    /// Ends the simulation and keeps its assembled system and factorization, for a caller
    /// that solves on with them (the interactive body's compliance columns are computed
    /// with the factorization of the base solve, not a second one). Everything else (the
    /// state, the fibers, the held and contact sets) is dropped. With projected fibers
    /// these are the paper's operator: callers must refuse such scenes.
    pub fn into_factored(self) -> (System, Box<dyn Factorization>) {
        (self.factored.system, self.factored.factorization)
    }

    /// What the solves cost so far.
    pub fn counters(&self) -> &Counters {
        &self.counters
    }

    /// Stage times so far.
    pub fn log(&self) -> &StageLog {
        &self.log
    }

    /// Seconds since the simulation was created.
    pub fn elapsed(&self) -> f64 {
        self.started.elapsed().as_secs_f64()
    }

    /// Number of axes (2 for a polygon).
    pub fn axes(&self) -> usize {
        self.body.boundary.axes()
    }
    /// Guard warnings so far.
    pub fn warnings(&self) -> &[GuardWarning] {
        &self.warnings
    }

    /// Steps taken, rejected and skipped, and the error estimate of adaptive steps.
    pub fn step_stats(&self) -> &StepStats {
        &self.stats
    }

    /// Each plate's force, contact area, contacts and gap after every step.
    pub fn plate_records(&self) -> &[PlateRecord] {
        &self.contact.records
    }

    /// The result guards of the current answer ([`crate::result_guards`]: volume and
    /// displacement; the step guards watch inverted faces and residuals); a non-finite
    /// position is [`crate::Error::NonFiniteAnswer`].
    pub fn answer_guards(&self) -> crate::Result<Vec<crate::result_guards::ResultWarning>> {
        let checks = crate::result_guards::ResultChecks { inverted: false, residual: None, linear: false };
        crate::result_guards::check_answer(
            &self.body.boundary,
            &self.body.rest,
            &self.state.positions,
            checks,
        )
        .map_err(|e| crate::Error::NonFiniteAnswer {
            scene: self.model.display_name(),
            method: crate::Method::Ffm,
            vertex: e.vertex,
        })
    }
}
