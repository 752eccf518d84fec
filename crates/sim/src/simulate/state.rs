//! The data of a simulation: options, the body, the state that steps change, counters.

use crate::contact::PlateRecord;
use fibfluid_geometry::{Boundary, FiberSet, Vec3};
use fibfluid_linalg::FactorOptions;
use serde::Serialize;

use crate::contact::Contact;

/// Options that are not part of a scene.
#[derive(Clone, Default)]
pub struct RunOptions {
    /// Called after each step with (step, total).
    pub progress: Option<std::sync::Arc<dyn Fn(usize, usize) + Send + Sync>>,
    /// Asked before each load step (fixed or adaptive): `true` stops the run with
    /// [`crate::Error::Cancelled`], the simulation left at the last step it finished (an
    /// interrupt from the user, a deadline).
    pub cancel: Option<std::sync::Arc<dyn Fn() -> bool + Send + Sync>>,
}

impl RunOptions {
    /// Whether the caller asked the run to stop.
    pub fn cancelled(&self) -> bool {
        self.cancel.as_ref().is_some_and(|c| c())
    }
}

impl std::fmt::Debug for RunOptions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RunOptions")
            .field("progress", &self.progress.is_some())
            .field("cancel", &self.cancel.is_some())
            .finish()
    }
}

/// How a simulation is set up, besides the scene.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SetupOptions {
    /// Factorization options (the precision is taken from the scene).
    pub factor: FactorOptions,
    /// Refuse the scene when its plan needs more bytes than this (default: the machine's
    /// total memory).
    pub max_memory: Option<u64>,
}

/// Where a run of steps takes the load: from 0 to the full load, or back.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    /// Apply the loads (load factor 0 -> 1).
    Load,
    /// Remove them again (load factor 1 -> 0, the same steps with the opposite sign).
    Unload,
}

/// The body being simulated: its boundary, kept fibers and rest shape.
#[derive(Clone, Debug)]
pub struct BodyShape {
    /// Triangles or polygon.
    pub boundary: Boundary,
    /// Mesh edges (surface fibers).
    pub edges: Vec<[u32; 2]>,
    /// Kept bulk fibers.
    pub fibers: FiberSet,
    /// Whether the body was found convex.
    pub convex: bool,
    /// Rest positions.
    pub rest: Vec<Vec3>,
    /// Rest volume (area for a polygon).
    pub volume0: f64,
    /// Diagonal of the rest shape's bounding box (the body's size).
    pub diagonal: f64,
}

/// The state that load steps change.
#[derive(Clone, Debug, PartialEq)]
pub struct State {
    /// Current positions.
    pub positions: Vec<Vec3>,
    /// Accumulated pressure change.
    pub pressure: f64,
    /// Fraction of the scene's load applied (0 at rest, 1 after [`Simulation::run`](crate::Simulation::run)).
    pub load_factor: f64,
    /// Fraction of the forces applied at the last step (`at = "last"`) now acting.
    pub last_forces: f64,
    /// Vertices in contact with a plate, and the plates' forces on them.
    pub contacts: Vec<Contact>,
}

/// What the solves cost and how accurate they were.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Counters {
    /// Factorizations made (a dense backend's refactorization for a new border counts).
    pub factorizations: usize,
    /// Linear solves made.
    pub solves: usize,
    /// Largest componentwise backward error of any solve.
    pub residual_max: f64,
    /// Largest number of refinement steps of any solve.
    pub refinement_steps_max: usize,
}

/// Load steps so far.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct StepStats {
    /// Steps taken (accepted).
    pub taken: usize,
    /// Adaptive steps rejected (undone, halved and retried).
    pub rejected: usize,
    /// Steps skipped because their load did not change (no solve needed).
    pub skipped: usize,
    /// Sum of the accepted adaptive steps' error estimates (largest vertex distance
    /// between the Euler and Heun evaluations), in length units.
    pub error_estimate: f64,
}

/// The increments of one step.
#[derive(Clone)]
pub(super) struct Increment {
    pub(super) da: Vec3,
    pub(super) forces: Vec<(usize, Vec3)>,
    pub(super) prescribed: f64,
    /// Load factor after the step.
    pub(super) to: f64,
    /// Fraction of the last-step forces applied after the step.
    pub(super) last_to: f64,
}

/// One evaluation of a step from the current shape.
pub(super) struct Evaluation {
    /// Displacement increments.
    pub(super) du: Vec<Vec3>,
    /// Pressure increment.
    pub(super) dp: f64,
    /// Euler/Heun difference, when estimated.
    pub(super) estimate: Option<f64>,
}

/// What a step did.
pub(super) struct StepOutcome {
    /// Euler/Heun difference, when estimated.
    pub(super) estimate: Option<f64>,
}

/// Smallest adaptive step (a fraction of the load) before the stepper gives up.
#[doc(alias = "tolerance")]
pub const MIN_ADAPTIVE_STEP: f64 = 1e-6;

/// The static response of a factored body to forces and held vertices.
#[derive(Clone, Debug, PartialEq)]
pub struct Response {
    /// Displacement of every vertex.
    pub displacements: Vec<Vec3>,
    /// Pressure change.
    pub pressure: f64,
    /// The force each held vertex needs to stay where it is held, in the order given.
    pub reactions: Vec<(usize, Vec3)>,
}

/// Plate contact, the contact stage's state: the contacts of the current solves, (plate,
/// vertex) with the step's normal motion onto the plate, and each plate's record after every
/// step.
#[derive(Clone, Debug, Default)]
pub(super) struct PlateContact {
    pub(super) active: Vec<(usize, usize)>,
    pub(super) values: Vec<f64>,
    pub(super) records: Vec<PlateRecord>,
}
