//! Large deformation: the compressible neo-Hookean tissue on the same sparse grid and
//! embedding as the linear body, solved by Newton's method with load stepping.
//!
//! - Energy: [`crate::law`]'s laws (the linear and the uncoupled neo-Hookean `W = mu / 2 (J^(-2/3) I1 - 3) +
//!   kappa / 4 (J^2 - 1 - 2 ln J)`, or a law of the caller's), total Lagrangian, the volumetric part on each cell's mean
//!   dilatation (the nonlinear counterpart of the linear body's B-bar, [`cell`]).
//! - Loads: gravity and point forces are dead loads (fixed in direction and size) scaled by
//!   the load factor `t` in `[0, 1]`; [`RigidPlate`]s move with `t` (or, in a timed solve,
//!   are driven by a force: [`plate_drive`]); the clamp is the
//!   linear body's penalty on the fixed part of the surface (it holds the rest position);
//!   [`Grasp`]s move patches of the surface rigidly with `t` ([`grasp`]'s augmented Lagrangian);
//!   [`Pressure`]s push on faces of the surface, scaled by `t` ([`pressure`]).
//! - Tracking a moving tool ([`tracking`]): the body linearized at its latest state answers
//!   frames with held vertices exactly (a capacitance update of the tangent's factor); each
//!   new linearization at the last answer is one more Newton iteration.
//! - Newton: the consistent tangent (the energy's Hessian, symmetric), factored by the kept
//!   symbolic analysis (numeric refactorization only); a backtracking line search on the
//!   energy; load increments that halve when Newton fails and double after an easy step
//!   ([`NewtonSettings`]). A load that cannot be reached fails with the step, the load
//!   and the residual ([`crate::FemError::NotConverged`]).
//! - Sensitivities of an answer to the tissues' moduli, densities and gravity, forward and
//!   adjoint, with the tangent factored at the answer ([`sensitivity`]).

mod body;
mod cell;
mod contact;
mod dynamics;
mod grasp;
mod grasp_kkt;
mod linear_solve;
mod model;
mod newton;
mod plate_drive;
mod pressure;
mod sensitivity;
mod solve;
mod terms;
mod time;
mod tracking;

pub use body::{
    GRASP_COLUMNS_BYTES, HyperBody, HyperSolution, HyperStats, LoadStep, NewtonSettings, SUMMARY_FILL,
    StrainSummary, cell_states,
};
pub use cell::{CellMaterial, CellState, CellTangent, HyperCell};
pub use contact::{
    CONTACT_FORCE_TOLERANCE, CONTACT_GAP_TOLERANCE, CONTACT_PENALTY, CONTACT_SMOOTHING, MAX_AUGMENTATIONS,
    RigidPlate,
};
pub use grasp::{GRASP_PENALTY, GRASP_TOLERANCE, Grasp, GraspRecord};
pub use grasp_kkt::GRASP_NEWTON_ITERATIONS;
pub use plate_drive::{MAX_PLATE_FORCE_TRIALS, PLATE_FORCE_TOLERANCE};
pub use pressure::Pressure;
pub use sensitivity::{Parameter, Sensitivities};
pub use time::{LoadCurve, TimeFields, TimeSample, TimeSettings, TimeSolution};
pub use tracking::{
    CHORD_REACH, HOLD_PENALTIES, Linearization, MAX_RESTORE, MAX_STEP_HALVINGS, SHIFTS, SurfaceResponse,
    Tangent, TrackStep, TrackedResponse,
};
