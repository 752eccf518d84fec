//! Step guards: checks after every load step that say when a run goes wrong, and the
//! likely cause of a numeric failure in the user's terms.
//!
//! Each guard compares one measure of the step with a limit (a scene key of `[guards]`):
//!
//! | guard | measure | default limit |
//! |---|---|---|
//! | `volume` | `|V/V0 - 1|` after the step | 0.05 in paper mode (its drift is first order), 1e-6 in refresh and nonlinear modes (they correct the volume to 1e-12) |
//! | `increment` | largest `|du|` of the step over the bounding-box diagonal | 0.25 |
//! | `inverted` | faces whose normal turned against the rest shape's | 0 |
//! | `residual` | largest componentwise backward error of the step's solves | 1e-10 |
//!
//! `on_failure = "warn"` (default) records a [`GuardWarning`] and goes on;
//! `on_failure = "error"` stops the run with [`Error::Guard`](crate::Error::Guard).

use fibfluid_geometry::{Boundary, Vec3};
use fibfluid_linalg::{Choice, impl_choice};
use serde::Serialize;

use crate::choices::Mode;

/// Which guard fired.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Guard {
    /// The volume changed more than the mode promises.
    Volume,
    /// One step moved a vertex by more than a fraction of the body's size.
    Increment,
    /// Faces turned inside out against the rest shape.
    Inverted,
    /// A solve's backward error grew past the limit.
    Residual,
}

impl Choice for Guard {
    const WHAT: &'static str = "guard";
    const ALL: &'static [Self] = &[Guard::Volume, Guard::Increment, Guard::Inverted, Guard::Residual];
    fn name(self) -> &'static str {
        match self {
            Guard::Volume => "volume",
            Guard::Increment => "increment",
            Guard::Inverted => "inverted",
            Guard::Residual => "residual",
        }
    }
}
impl_choice!(Guard);

/// What a run does when a guard fires.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum OnFailure {
    /// Record a warning (stderr and `report.json`) and go on.
    #[default]
    Warn,
    /// Stop with an error; nothing is written.
    Error,
}

impl Choice for OnFailure {
    const WHAT: &'static str = "guard policy";
    const ALL: &'static [Self] = &[OnFailure::Warn, OnFailure::Error];
    fn name(self) -> &'static str {
        match self {
            OnFailure::Warn => "warn",
            OnFailure::Error => "error",
        }
    }
}
impl_choice!(OnFailure);

/// The guard limits of a scene (`[guards]`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Guards {
    /// What to do when a guard fires.
    pub on_failure: OnFailure,
    /// Largest `|V/V0 - 1|` (default: [`Guards::volume_default`] of the mode).
    pub volume: Option<f64>,
    /// Largest `|du|` of one step over the bounding-box diagonal.
    pub increment: Option<f64>,
    /// Most faces inverted against the rest shape.
    pub inverted: Option<usize>,
    /// Largest backward error of a step's solves.
    pub residual: Option<f64>,
}

/// Default limit of the `increment` guard.
pub const INCREMENT_DEFAULT: f64 = 0.25;
/// Default limit of the `residual` guard.
pub const RESIDUAL_DEFAULT: f64 = 1e-10;

impl Guards {
    /// The volume limit a mode promises: paper mode drifts to first order per step, the
    /// others correct the volume to 1e-12.
    pub fn volume_default(mode: Mode) -> f64 {
        match mode {
            Mode::Paper => 0.05,
            Mode::Refresh | Mode::Nonlinear => 1e-6,
        }
    }

    /// The limit of `guard` in `mode`.
    pub fn limit(&self, guard: Guard, mode: Mode) -> f64 {
        match guard {
            Guard::Volume => self.volume.unwrap_or(Self::volume_default(mode)),
            Guard::Increment => self.increment.unwrap_or(INCREMENT_DEFAULT),
            Guard::Inverted => self.inverted.unwrap_or(0) as f64,
            Guard::Residual => self.residual.unwrap_or(RESIDUAL_DEFAULT),
        }
    }
}

/// A guard that fired after a step.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct GuardWarning {
    /// The step (1-based, counting accepted steps).
    pub step: usize,
    /// The guard.
    pub guard: Guard,
    /// The measured value.
    pub value: f64,
    /// The limit it passed.
    pub limit: f64,
}

impl std::fmt::Display for GuardWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let what = match self.guard {
            Guard::Volume => "the volume changed by",
            Guard::Increment => "one step moved a vertex by (of the body's diagonal)",
            Guard::Inverted => "faces turned inside out:",
            Guard::Residual => "a solve's backward error grew to",
        };
        let hint = match self.guard {
            Guard::Volume => "use mode = \"refresh\", or more load steps",
            Guard::Increment | Guard::Inverted => {
                "the material may be too soft for this load: raise fiber_modulus, or take more steps ([load] steps or tolerance)"
            }
            Guard::Residual => {
                "the system is ill-conditioned: use constraints = \"eliminate\" and precision = \"f64\""
            }
        };
        write!(
            f,
            "step {}: guard `{}`: {what} {:.3e}, limit {:.3e}; {hint}",
            self.step, self.guard, self.value, self.limit
        )
    }
}

/// Faces of `boundary` turned inside out between `rest` and `now`: the angle between their
/// normal and their neighbourhood's grew by more than a right angle (edges of a polygon
/// likewise), so a body that only rotated, however far, has none
/// ([`fibfluid_geometry::faces_turned_inside_out`]).
pub fn inverted_faces(boundary: &Boundary, rest: &[Vec3], now: &[Vec3]) -> usize {
    match boundary {
        Boundary::Surface { triangles } => fibfluid_geometry::faces_turned_inside_out(triangles, rest, now),
        Boundary::Polygon => fibfluid_geometry::edges_turned_inside_out(rest, now),
    }
}
